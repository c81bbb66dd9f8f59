"""What the effects add to a LAMMPS deck: every registered effect's one hook,
``lammps(term, deck)`` (an ``effects.spec.DeckPart``), called in registry order with the
effect's record (None while it is off), and their sum as the deck writer reads it."""
from __future__ import annotations

from dataclasses import dataclass

from granchain.effects import MODULES
from granchain.effects.spec import DeckPart, pair_words
from granchain.lammps.field import WALL_X


@dataclass(frozen=True)
class Deck:
    """What an effect's hook may read of the deck: its first chain's terms, each chain's
    terms under a radius spread (else None), the number of chains and the x (um) of the
    end wall's plane (chain b's sphere i is atom b*n + i)."""
    terms: object
    members: list | None = None
    n_chains: int = 1
    wall_x: float = WALL_X


class Parts:
    """The effects' parts of one deck, added up: later entries of ``pair``, ``notes`` and
    ``contact`` replace earlier ones, the rest are collected in registry order."""

    def __init__(self, terms, members=None, n_chains: int = 1):
        deck = Deck(terms, members, n_chains)
        self.all: list[DeckPart] = [m.lammps(getattr(terms, m.SPEC.name), deck) for m in MODULES]
        self.pair: dict = {}
        self.notes: dict = {}
        for p in self.all:
            self.pair.update(p.pair)
            self.notes.update(p.notes)
        self.contact = [p.contact for p in self.all if p.contact][-1]
        self.integrator = next(p.integrator for p in self.all if p.integrator)

    def words(self, E: float, nu: float, unlike=None) -> list[str]:
        """The pair_coeff sub-model words of a pair of materials of modulus E (Pa) and
        Poisson's ratio nu; ``unlike``: (a, b), the materials of an unlike pair, whose own
        entries (``DeckPart.unlike``) replace the one-material ones."""
        pair = dict(self.pair)
        if unlike is not None:
            for p in self.all:
                if p.unlike is not None:
                    pair.update(p.unlike(*unlike))
        return pair_words(pair, E, nu)

    def collect(self, name: str) -> list:
        """Every part's (non-empty) field ``name``, in registry order."""
        return [v for p in self.all if (v := getattr(p, name))]

    @property
    def has_fix(self) -> bool:
        """Does the deck have fix groove/drag (an effect has a part of its arguments)?"""
        return bool(self.collect("fix"))

    @property
    def plugin(self) -> bool:
        """Does the deck load the granchain plugin (fix groove/drag, or an effect's lines of
        its other styles)?"""
        return self.has_fix or bool(self.collect("plugin_lines"))
