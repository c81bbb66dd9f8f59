"""Physical effects of chapter Eq. 5.1: one module each, and the registry that adds them up.

Each effect module (``hertz``, ``rotation``, ``groove_friction``, ``air_drag``,
``particle_friction``, ``rolling_friction``, ``contact_damping``, ``adhesion``,
``plastic_contact``) declares, once:
- ``SPEC`` (:class:`~granchain.effects.spec.EffectSpec`): its parameter and flag slots,
  per-sphere and per-contact rows, state blocks, its work column in the energy ledger and
  results tables, and what LAMMPS reports of it;
- its parameter record (a frozen dataclass, SI units) and ``build(scene)``, and for an
  effect with parameters its scene section (``SECTION``, ``DEFAULTS``, ``KEYS`` declaring
  each key's unit, bounds and meaning, and ``settings``, which validates the section);
- its kernel parameters and flags by slot name (``kernel(term)``), its per-sphere and
  per-contact rows (``rows(term, chain)``), and for an effect with a history the error
  scale the adaptive method judges it on (``error_scale``);
- its law, as plain functions marked ``spec.compiled``: the scalar laws, and the parts of
  ``spec.HOOKS`` it needs (its normal force on a contact, its forces and torques on the
  spheres with its history and work rates, its history projection, its energy, its
  switches for the event method). The engines compile them with numba and compose the
  kernels from them in registry order (``granchain.engines.compose``); every integrator
  and the return mapping use the same law;
- its part of a LAMMPS deck, through one hook, ``lammps(term, deck)`` (an
  ``spec.DeckPart``), which the deck writer calls for every effect (``granchain.lammps``).

``physics_terms(scene)`` returns a :class:`Terms` holding one record per enabled effect.
Both engines take the physics from here; no engine reads scene fields for physics.

Conventions: z along the chain, theta the rotation about the horizontal axis
perpendicular to it (LAMMPS: x and omega_y); a sphere rolling forward has omega > 0. Slip
at the groove: u = v - s R omega. Slip at the contact of spheres k, k+1:
w = R (omega_k + omega_{k+1}).

The kernels' numbering (P, FL, G, LO, the energy columns) is generated from the SPECs
(``slots``). To add an effect: a module here with these parts and its entry in
``MODULES`` (``Terms`` gets its field from there); docs/tutorials/add-a-physical-effect.md
walks through one.
"""
from __future__ import annotations

import dataclasses

from . import (adhesion, air_drag, chain, contact_damping, groove_friction, hertz,
               particle_friction, plastic_contact, rolling_friction, rotation, slots)
from .chain import Chain
from .air_drag import AirDrag
from .groove_friction import GrooveFriction
from .hertz import Hertz
from .particle_friction import ParticleFriction
from .rolling_friction import RollingFriction
from .rotation import Rotation
from .spec import BOND_CAPTURED, BOND_NONE, BOND_UNDECIDED, EffectSpec

# Registry order is the order of the state blocks and of the work columns.
MODULES = (hertz, rotation, groove_friction, air_drag, particle_friction, rolling_friction,
           contact_damping, adhesion, plastic_contact)
SPECS: dict[str, EffectSpec] = {m.SPEC.name: m.SPEC for m in MODULES}

# Energy ledger columns, in the order engines store them: the mechanical energies, then the
# work done ON the particles by each effect that does work, accumulated from t = 0, then
# the work of the dead load (precompression: F0 times particle 2's displacement).
ENERGY_COLUMNS = ("kinetic_translational", "kinetic_rotational", "hertz_potential") + tuple(
    s.work for s in SPECS.values() if s.work) + (chain.SPEC.work,)
# the kernels' numbering of every declared slot (``slots``)
slots.number((chain.SPEC,) + tuple(SPECS.values()), ENERGY_COLUMNS)


def acts_on_normal(effects) -> bool:
    """Does one of these effects (names) act on the contacts' normal force after the
    elastic law (its ``contact_normal``: contact damping)? The force then depends on the
    closing speed, and a chain against a wall may lose the energy to leave it."""
    laws = [m for m in MODULES if hasattr(m, "contact_normal")]
    return any(m.SPEC.name in effects for m in laws[1:])


def may_hold_wave(effects) -> bool:
    """Can one of these effects (names) keep a chain running to its cap? An effect with a
    ``normal`` hook after the elastic law's (damping, yielding, adhesion) takes the wave's
    energy or holds contacts closed: the wave may stall before the chain's end, or the
    chain stay bound as a whole."""
    laws = [m for m in MODULES if hasattr(m, "normal")]
    return any(m.SPEC.name in effects for m in laws[1:])


def switching(effects) -> tuple[str, ...]:
    """The effects among these (names) whose law switches (a jump or a kink of a force:
    the groove's stick and slip, adhesion's touch and pull-off, yielding's onset and
    unloading), those with a ``locate`` hook, in registry order. A fixed step loses its
    order at each switch; the event method ends a step on each one."""
    return tuple(m.SPEC.name for m in MODULES if hasattr(m, "locate") and m.SPEC.name in effects)


def binding(effects) -> tuple[str, ...]:
    """The effects among these (names) whose law can hold contacts closed (a ``bond``
    hook: adhesion), in registry order. A chain such a law binds as a whole keeps every
    contact active until its cap."""
    return tuple(m.SPEC.name for m in MODULES if hasattr(m, "bond") and m.SPEC.name in effects)


def residual_work(effects) -> tuple[str, ...]:
    """Work columns LAMMPS cannot report for these effects (the balance residual there)."""
    return tuple(SPECS[e].work for e in SPECS if e in effects and SPECS[e].work
                 and not SPECS[e].lammps_reports_work)


def separation(terms, k: int, d: float) -> tuple[float, float]:
    """(d_open, Phi) of contact k at overlap d (m), by the normal law in force: the overlap
    at which the contact opens, and the work its force does on the relative motion of its
    spheres on the way there (J; negative: the energy they need to part). From the last
    enabled effect in registry order whose module has ``separation`` (hertz's otherwise;
    an effect without it adds no attraction)."""
    for m in reversed(MODULES):
        if hasattr(m, "separation") and (m is hertz or terms.has(m.SPEC.name)):
            return m.separation(getattr(terms, m.SPEC.name), terms.chain, k, d)
    raise AssertionError("hertz has separation")


def holds_contacts(terms) -> bool:
    """Does a law in force hold contacts closed (an enabled effect with a ``bond`` hook,
    ``spec.HOOKS``)? Only then can a contact be captured, or held closed at an open
    overlap, and the t_end auto stop rule asks each contact's :func:`bond`."""
    return any(hasattr(m, "bond") and terms.has(m.SPEC.name) for m in MODULES)


def bond(terms, k: int, d: float, w: float, held: bool) -> int:
    """The ``bond`` hook's state (``spec.BOND_*``) of contact k (spheres k+1, k+2) at
    overlap d (m) and closing speed w (m/s), from the laws in force: ``held`` whether the
    law held it closed just before (its touch history). BOND_NONE unless
    :func:`holds_contacts` and the contact is closed (d > 0, or held and d above its
    opening overlap); then BOND_CAPTURED when (1/2) m* w^2 + Phi < 0 (:func:`separation`),
    BOND_UNDECIDED otherwise. The engines' compiled hooks decide the same way."""
    if not holds_contacts(terms):
        return BOND_NONE
    d_open, phi = separation(terms, k, d)
    if not (d > 0.0 or (held and d > d_open)):
        return BOND_NONE
    m1, m2 = terms.chain.masses[k], terms.chain.masses[k + 1]
    return BOND_CAPTURED if 0.5 * m1 * m2 / (m1 + m2) * w * w + phi < 0.0 else BOND_UNDECIDED


def touch_energy(terms) -> float:
    """The most energy (J) the contacts' laws can give the spheres' motion beyond what
    the striker brings (the work their attraction does from first touch to the bottom of
    their well): the sum of each enabled effect's ``touch_energy`` (0 for a law without
    attraction)."""
    return sum(m.touch_energy(getattr(terms, m.SPEC.name), terms.chain) for m in MODULES
               if hasattr(m, "touch_energy") and terms.has(m.SPEC.name))


def _has(self, name: str) -> bool:
    return getattr(self, name) is not None


def _overlap_scale(self, v: float) -> float:
    """The peak overlap (m) of a head-on collision of two beads at closing speed v (m/s),
    by the normal law (``hertz.peak_overlap``)."""
    return hertz.peak_overlap(self.m / 2.0, self.hertz.K, v)


def _dissipative(self) -> tuple[str, ...]:
    """Effects that do work on the particles (each gets a work entry in the ledger)."""
    return tuple(n for n, s in SPECS.items() if s.work and self.has(n))


# The physics of one scene: n, a bead's radius R (m) and mass m (kg), the chain (each
# sphere's: ``Chain``), and one field per registered effect holding its parameter record
# (``build(scene)``), None when the scene leaves it off.
Terms = dataclasses.make_dataclass(
    "Terms", [("n", int), ("R", float), ("m", float), ("hertz", Hertz),
              ("chain", Chain, dataclasses.field(default=None))]
    + [(m.SPEC.name, object, dataclasses.field(default=None)) for m in MODULES if m is not hertz],
    frozen=True, namespace={"has": _has, "dissipative": property(_dissipative),
                            "overlap_scale": _overlap_scale,
                            "__doc__": "The physics of one scene: the chain and its enabled "
                                       "effects (one field per registered effect)."})
Terms.__module__ = __name__


def physics_terms(scene) -> Terms:
    kw = {m.SPEC.name: m.build(scene) for m in MODULES if scene.has(m.SPEC.name)}
    kw["hertz"] = hertz.build(scene)
    return Terms(n=scene.n, R=scene.radius, m=scene.mass, chain=chain.build(scene), **kw)


__all__ = ["MODULES", "SPECS", "ENERGY_COLUMNS", "EffectSpec", "Terms", "physics_terms",
           "residual_work", "acts_on_normal", "separation", "touch_energy", "holds_contacts",
           "bond", "Chain", "Hertz", "AirDrag", "GrooveFriction",
           "Rotation", "ParticleFriction", "RollingFriction"]
