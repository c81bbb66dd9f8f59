"""One-line checks of scene values: every problem is a
:class:`~granchain.errors.SceneError` naming the field and the fix. Shared by the scene
parser (``granchain.scene``) and the effects, which validate their own scene sections
(``granchain.effects``). Each scene key is declared once, as a :class:`Key` beside its
default: the checks read its bounds and choices, and the reference page of the scene keys
(``granchain.scenekeys``) is written from the same declarations."""
from __future__ import annotations

import datetime
import difflib
import math
import re
from dataclasses import dataclass

from .errors import SceneError


# How deep short() looks into nested lists and mappings, and how many of their entries
# it shows: the summary of any value costs a bounded amount of work.
SHORT_DEPTH = 2
SHORT_ITEMS = 6
# An integer with more decimal digits than this is shown by its size, not its digits.
SHORT_DIGITS = 30
# types whose repr is short whatever the value (YAML's dates and timestamps)
_SMALL_REPR = {datetime.date.__repr__, datetime.datetime.__repr__}


def short(value, limit: int = 60) -> str:
    """A one-line summary of a value for a message: about ``limit`` characters, and a
    value's length after a cut (at most ``limit`` + 30 in all).

    Bounded work whatever the value: a string is cut before it is quoted, an integer of
    many digits is shown by its number of digits, a list or mapping shows its first
    entries to SHORT_DEPTH levels (deeper ones as ``[...]``) and its length. A value that
    contains itself, or shares parts through YAML aliases, costs no more than any other."""
    text = _summary(value, limit, 0)
    return text if len(text) <= limit + 30 else text[:limit + 27] + "..."


def _summary(value, budget: int, depth: int) -> str:
    if value is None or isinstance(value, (bool, float)):
        return repr(value)
    if isinstance(value, int):
        bits = value.bit_length()
        if bits <= 3.33 * SHORT_DIGITS:
            return repr(value)
        return f"<an integer of ~{int(bits * 0.30103) + 1} digits>"
    if isinstance(value, (str, bytes)):
        cut = value[:budget + 1]
        text = repr(cut)
        return text if len(cut) == len(value) else text + f"... ({len(value)} characters)"
    if isinstance(value, (list, tuple, set, frozenset, dict)):
        is_map = isinstance(value, dict)
        opening, closing = ("{", "}") if is_map else ("(", ")") if isinstance(value, tuple) \
            else ("[", "]")
        if depth >= SHORT_DEPTH:
            return f"{opening}...{closing}" if len(value) else opening + closing
        parts, used = [], 2
        for i, item in enumerate(value.items() if is_map else value):
            room = budget - used
            if is_map:
                part = (_summary(item[0], room, depth + 1) + ": "
                        + _summary(item[1], room, depth + 1))
            else:
                part = _summary(item, room, depth + 1)
            if i >= SHORT_ITEMS or (parts and len(part) > room):
                parts.append("...")
                break
            parts.append(part)
            used += len(part) + 2
        text = opening + ", ".join(parts) + closing
        if parts and parts[-1] == "...":
            text += f" ({len(value)} entries)"
        return text
    if type(value).__repr__ in _SMALL_REPR:
        return repr(value)
    return f"<{type(value).__name__}>"



def number(node, field: str, *, positive=False, nonneg=False, integer=False,
           allow_none=False, lo=None, hi=None, fix=None):
    """A number (``field`` names it in errors) checked against the given bounds."""
    if node is None and allow_none:
        return None
    given = node
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        # YAML 1.1 reads "1e-9" (no dot) as a string: accept numeric strings.
        try:
            node = float(node) if isinstance(node, str) else None
        except (TypeError, ValueError, OverflowError):
            node = None
        if node is None:
            raise SceneError(field, f"expected a number, got {short(given)}",
                             fix or "give a number in SI units")
    try:
        value = float(node)
    except OverflowError:
        value = math.inf
    if not math.isfinite(value):
        raise SceneError(field, f"{short(given)} is not a finite number",
                         fix or "give a finite number")
    if integer and value != int(value):
        raise SceneError(field, f"{value} is not a whole number", fix or "give an integer")
    if positive and value <= 0:
        raise SceneError(field, f"{value:g} must be > 0", fix or "give a positive value")
    if nonneg and value < 0:
        raise SceneError(field, f"{value:g} must be >= 0", fix or "give a value >= 0")
    if lo is not None and value < lo:
        raise SceneError(field, f"{value:g} is below {lo:g}", fix or f"give a value >= {lo:g}")
    if hi is not None and value > hi:
        raise SceneError(field, f"{value:g} is above {hi:g}", fix or f"give a value <= {hi:g}")
    return int(value) if integer else value


def choice(value, field, options, what):
    """A value that must be one of ``options``, with a 'did you mean' on a typo."""
    if isinstance(value, str) and value in options:
        return value
    close = difflib.get_close_matches(str(value), options, n=1) if isinstance(value, str) else []
    hint = f"did you mean '{close[0]}'?" if close else f"use one of {', '.join(options)}"
    raise SceneError(field, f"unknown {what} {short(value)}", hint)


def number_text(x) -> str:
    """A bound as the scene file would write it: 1e6, not 1e+06."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + m.group(1).lstrip("+") + m.group(2),
                  f"{x:g}")


@dataclass(frozen=True)
class Fit:
    """What makes a scalar scene key fittable by ``granchain infer --fit gap_mean,KEY``,
    declared on its :class:`Key`: the prior range [lo, hi] of the joint fit's grid and
    posterior, the grid's number of nodes over it, and how results and messages name the
    parameter.

    lo, hi: the prior range (the key's unit). Uniform on it, or log-uniform (``log``) when
        it spans a decade or more: a parameter known to within decades is a scale.
    points: grid nodes over the range (``linspace``, or ``geomspace`` when ``log``).
    name: the results' name of the parameter (the JSON keys ``name``, ``name_ci95``,
        ``name_grid``; ``--fit gap_mean,name`` is an alias of the key).
    symbol, label: the parameter in a formula and in words, for the summary.
    models: the section's ``model`` values with which the key can be fitted (empty: any).
    example: the section a base scene gives to fit the key (any value of it: the
        inference sets it), for the refusal of a base scene without it.
    """
    lo: float
    hi: float
    points: int
    name: str
    symbol: str
    label: str
    models: tuple[str, ...] = ()
    example: str = ""

    @property
    def log(self) -> bool:
        """Is the prior log-uniform (the range spans a decade or more)?"""
        return self.lo > 0 and self.hi / self.lo >= 10.0


@dataclass(frozen=True)
class Key:
    """The declaration of one scene key, beside its default (``granchain.scenekeys.DEFAULTS``,
    an effect module's ``DEFAULTS``).

    path: the dotted key, e.g. ``groove.mu``.
    unit: the SI unit of a number; ``1`` for a dimensionless number, ``-`` for a value
        that is not a number (a name, a choice, a mapping).
    doc: what the key sets and when it counts (Markdown, one paragraph).
    positive, nonneg, integer, lo, hi: the bounds :meth:`number` checks.
    choices: the values :meth:`choice` accepts.
    allowed: what else the key takes, or a rule the bounds cannot state (it may depend
        on other keys), e.g. "or `auto`".
    fit: the prior range of a key the inference can fit (:class:`Fit`), None if it cannot.
    """
    path: str
    unit: str
    doc: str
    positive: bool = False
    nonneg: bool = False
    integer: bool = False
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    allowed: str = ""
    fit: Fit | None = None

    @property
    def name(self) -> str:
        """The key's own name, the last part of its path."""
        return self.path.rpartition(".")[2]

    @property
    def bounded(self) -> bool:
        """Does :meth:`number` check bounds (beyond being a finite number)?"""
        return self.positive or self.nonneg or self.lo is not None or self.hi is not None

    def number(self, value, *, field: str | None = None, allow_none: bool = False,
               fix: str | None = None):
        """``value`` checked by :func:`number` against the key's bounds; ``field`` names
        it in errors (default: the key's path; e.g. ``chain.radius[3]`` for a list entry)."""
        return number(value, field or self.path, positive=self.positive, nonneg=self.nonneg,
                      integer=self.integer, lo=self.lo, hi=self.hi, allow_none=allow_none,
                      fix=fix)

    def choice(self, value, what: str, *, field: str | None = None):
        """``value`` checked by :func:`choice` against the key's choices."""
        return choice(value, field or self.path, self.choices, what)

    @property
    def range_text(self) -> str:
        """The values the key takes, in words: its choices or bounds, then ``allowed``."""
        parts = []
        if self.choices:
            parts.append(", ".join(f"`{c}`" for c in self.choices))
        fmt = str if self.integer else number_text
        lower = ("<", "0") if self.positive else ("<=", "0") if self.nonneg else \
            ("<=", fmt(self.lo)) if self.lo is not None else None
        if lower and self.hi is not None:
            cond = f"{lower[1]} {lower[0]} {self.name} <= {fmt(self.hi)}"
        elif lower:
            cond = f"{self.name} {'>' if lower[0] == '<' else '>='} {lower[1]}"
        else:
            cond = f"{self.name} <= {fmt(self.hi)}" if self.hi is not None else ""
        if cond or self.integer:
            parts.append(", ".join(filter(None, ("a whole number" if self.integer else "",
                                                  f"`{cond}`" if cond else ""))))
        if self.allowed:
            parts.append(self.allowed)
        if self.fit is not None:
            f = self.fit
            parts.append(f"fittable (`granchain infer --fit gap_mean,{self.path}`): prior "
                         f"{'log-uniform' if f.log else 'uniform'} on "
                         f"[{number_text(f.lo)}, {number_text(f.hi)}]")
        return "; ".join(parts)

    def physical_ends(self) -> tuple[bool, bool]:
        """Is each end of the fit's prior range a bound of the key itself (e = 1), not a
        grid end? Posterior weight at a physical end is no sign of a range too short."""
        f = self.fit
        low = (self.lo is not None and f.lo <= self.lo) or (
            f.lo <= 0 and (self.positive or self.nonneg))
        return bool(low), bool(self.hi is not None and f.hi >= self.hi)
