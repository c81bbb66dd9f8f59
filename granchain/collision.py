"""The two-sphere collision (a scene of ``chain.n: 2``, the restitution experiment):
how it ended and its measured coefficient of restitution.

The striker (particle 1) closes on particle 2, at rest, at v_s. At the end of the run
(the last sample, where ``ChainResult.v_final`` is read) the pair is in one of these
states, ``collision``:

- ``separated``: their contact is open (its overlap at or below the one at which the
  normal law opens it: 0, or JKR's pull-off distance) and they move apart. The measured
  restitution is e = -(v2' - v1') / (v2 - v1) = (v2' - v1') / v_s, from the final
  velocities (effects that act in free flight, air drag and groove friction, change the
  velocities before and after the contact as well).
- ``captured``: their contact is closed and the energy of their relative motion,
  (1/2) m* (v2' - v1')^2, is less than the energy the law's force takes from it on the
  way to the contact's opening (``effects.bond``, ``effects.separation``): the pair stays
  bound (no adhesive contact parts without that energy; damping only takes more). Only a
  law that holds contacts closed (``adhesion``) can capture.
- ``unfinished``: neither: the striker has not reached particle 2 yet, or their contact
  is still closed with the energy to open, or open while they still close on each other.
  The run ended before the collision did: a longer ``t_end`` finishes it. A ``t_end:
  auto`` run, which lasts until the collision is ``separated`` or ``captured``
  (``granchain.stoprule``), is unfinished when it reaches its cap first (status timeout),
  whatever its last sample shows, and so is a run that failed.
- ``no_impact``: the striker does not move (v_s = 0).

The restitution is NaN in every state but ``separated``. A contact is closed at the end
when its overlap is positive, or between the opening overlap and 0 once particle 2 has
been struck (it moves; a JKR contact held closed in tension parts only at its pull-off
distance, and a pair of two spheres that parted does not meet again).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .effects import bond, physics_terms, separation
from .effects.spec import BOND_CAPTURED

OUTCOMES = ("separated", "captured", "unfinished", "no_impact")


@dataclass(frozen=True)
class Collision:
    """How a two-sphere collision ended (``collision``, one of ``OUTCOMES``), whether the
    pair was captured, and the measured restitution (NaN unless separated)."""
    collision: str
    captured: bool
    restitution: float


def measure(v_striker: float, v_final, overlap: float, terms,
            ended: bool = True) -> Collision:
    """The outcome of the collision of a two-sphere chain whose final velocities (m/s)
    are ``v_final`` and whose contact's overlap at the end is ``overlap`` (m; > 0 in
    contact); ``terms``: its physics (``effects.physics_terms``). ``ended``: False when
    the run did not end by its length or its stop rule (a t_end auto run that hit its
    cap, or a failed run): the collision is then unfinished."""
    if not v_striker > 0.0:
        return Collision("no_impact", False, math.nan)
    if not ended:
        return Collision("unfinished", False, math.nan)
    v1, v2 = float(v_final[0]), float(v_final[1])
    w = v2 - v1                                # > 0: moving apart
    d_open, _ = separation(terms, 0, overlap)
    struck = v2 != 0.0
    closed = overlap > 0.0 or (struck and overlap > d_open)
    if not closed:
        if struck and w >= 0.0:
            return Collision("separated", False, w / v_striker)
        return Collision("unfinished", False, math.nan)
    if bond(terms, 0, overlap, -w, True) == BOND_CAPTURED:
        return Collision("captured", True, math.nan)
    return Collision("unfinished", False, math.nan)


def terms_of(scene, traj):
    """The physics a two-sphere scene's trajectory ran with (a member's own radii under a
    radius spread), for ``observables.summarize``; None for a chain of more spheres."""
    if scene.n != 2:
        return None
    return physics_terms(scene.with_radii(traj.radii) if traj.radii is not None else scene)
