"""The stop rule: how a run samples, when it stops, and which peaks it has measured; one
rule for both engines and the observables.

Sampling: ``sample_interval`` (the scene's, or 400 samples per solitary-wave width).
Run length: ``expected_duration`` (what a chain is expected to need) and ``auto_t_max``
(the cap of a ``t_end: auto`` run). A run computes the sampling and the expected length
once, in its run plan (``granchain.runplan.RunPlan``).

A particle has *seen the wave* once its velocity exceeds ``ARRIVAL_FRACTION * v_s``.
Its peak velocity is *final* (a measured maximum, inside the run) when:

- for every particle but the last: after its peak, its velocity fell below
  ``PASS_FRACTION`` of that peak, i.e. the wave has passed it;
- for the last particle: it has seen the wave and its contact with its neighbour is open
  (Hertz overlap <= 0). Nothing pushes it any more: it has taken the wave and flies off,
  and the peak is the moment the contact opened. (It never slows the way an inner
  particle does, so the half-peak rule cannot apply to it.)

With ``t_end: auto`` a chain stops at the first sample at which its last particle's peak
is final: the wave has left the whole chain, so every particle's peak lies inside the
run (the chapter's Fig. 5.3b plots every particle). A peak that is not final (a fixed
``t_end`` cut it off, or an auto run hit its time cap) is reported as NaN with the
particle flagged, never as a number.

A law that holds contacts closed beyond their touching overlap (an effect with the
``bond`` hook of ``effects.spec.HOOKS``: adhesion) makes the rule wait, besides, until
every contact's outcome is decided: no contact held closed with the energy of its
spheres' relative motion enough to part it (``BOND_UNDECIDED``; a JKR contact held in
tension at an open overlap is one). A free end also stops when its last particle, having
seen the wave, is bound to its neighbour (``BOND_CAPTURED``: that energy below the work
the law takes from it to open the contact) and that pair is alone (two spheres, or the
contact before it open and not held and no sphere behind it faster than the pair's
centre of mass, so none closes on it again): a captured pair. A last particle bound to
its neighbour has not left while their contact is held in tension (at an open overlap).
A chain that never settles (a chain bound as a whole) stops at its cap, status timeout,
its unmeasured peaks NaN. Laws without the hook (Hertz, damping, Thornton's) leave the
rule and its stop times as they were.

The rules are written once, in ``granchain.obsrules`` (with their constants): the
reference kernels (``engines.kernels``, ``engines.events``), the LAMMPS engine's per-chain
cut (``engines/lammps.auto_stop``) and ``observables.peak_final`` apply them; the LAMMPS
deck states the stop rule again in its own language (``fix halt`` on ``compute
contact/atom``, ``lammps/deck.py``). A deck with a law that holds contacts closed has no
halt (it cannot test the held contacts): it runs to its cap, and the LAMMPS engine cuts
each record at :func:`settled_sample`, the reference kernels' rule (``kernels._settled``)
on the sampled record.
"""
from __future__ import annotations

import math

import numpy as np

from . import analytic, obsrules
from .effects import acts_on_normal, bond, separation
from .effects.spec import BOND_CAPTURED, BOND_UNDECIDED
from .guards import crossing_time, require_resolved
# the observable rules' constants (``granchain.obsrules``)
from .obsrules import ARRIVAL_FRACTION, PASS_FRACTION, PEAK_TOL, PLATEAU_SAMPLES  # noqa: F401

SAMPLES_PER_PULSE = 400    # auto sampling: samples per solitary-wave width


def sample_interval(scene, v_striker: float) -> float:
    """Sample interval (s) of a chain: the scene's ``output.sample_dt``, or
    SAMPLES_PER_PULSE per width of the solitary wave at 0.64 v_s (both engines, and the
    cost estimate, use this grid)."""
    if scene.sample_dt is not None:
        return scene.sample_dt
    v = max(v_striker, 1e-6)
    return scene.pulse_width(0.64 * v) / SAMPLES_PER_PULSE


def auto_t_max(scene, gaps, v_striker: float) -> float:
    """Generous cap on the duration of a t_end: auto run, which lasts until the wave has
    left the whole chain (a run that hits the cap is flagged ``timeout``). A damped chain
    against an end wall may lose the energy to bring its last sphere back behind its
    start (the wall's stop rule, ``wall_left``) and then runs to the cap: its cap is
    tighter, 3 passages instead of 20 (its peaks are long final by then; measured: the
    wall peak of a damped 15-sphere chain at 1.1e-5 s, the 20-passage cap 2.5e-4 s)."""
    n = scene.n
    vs = analytic.nesterenko_speed(scene.material, 0.5 * v_striker)
    travel = (n - 1) * 2.0 * scene.radius / vs
    flight = float(np.sum(gaps[: n - 1])) / v_striker
    k_travel, k_flight = ((3.0, 5.0) if scene.wall is not None
                          and acts_on_normal(scene.effects) else (20.0, 50.0))
    return k_travel * travel + k_flight * flight + 10.0 * analytic.pulse_width(
        scene.material, scene.radius, 0.5 * v_striker)


def arrival_speed(v_striker):
    """Velocity (m/s) above which a particle has seen the wave (``obsrules.arrival``)."""
    return obsrules.arrival(v_striker)


def last_detached(v_last, overlap_last, v_striker):
    """Has the last particle taken the wave and left? (elementwise on arrays;
    ``obsrules.detached``)

    v_last: velocity of particle n (m/s); overlap_last: the overlap of contact n-1, n
    (m, > 0 in contact)."""
    return obsrules.detached(np.asarray(v_last), np.asarray(overlap_last),
                             arrival_speed(v_striker))


def wall_left(v_last, x_last, v_striker):
    """Has the wave left a chain that ends on a wall? (elementwise on arrays;
    ``obsrules.wall_left``)

    v_last: velocity of particle n (m/s); x_last: its displacement from its initial
    (static) position (m)."""
    return obsrules.wall_left(np.asarray(v_last), np.asarray(x_last), arrival_speed(v_striker))


def held_record(terms, overlaps) -> np.ndarray:
    """Which contacts the laws in force hold closed at each sample of a record (S, n-1
    overlaps, m; > 0 in contact), read from the overlaps alone: closed at d > 0, and
    after that down to the contact's opening overlap (``effects.separation``: 0, or
    JKR's pull-off distance), until a sample at or beyond it."""
    ov = np.asarray(overlaps, dtype=float)
    d_open = np.array([separation(terms, k, 0.0)[0] for k in range(ov.shape[1])])
    idx = np.arange(ov.shape[0])[:, None]
    touch = np.maximum.accumulate(np.where(ov > 0.0, idx, -1), axis=0)
    broke = np.maximum.accumulate(np.where(ov <= d_open, idx, -1), axis=0)
    return (ov > 0.0) | (touch > broke)


def settled_sample(terms, v_striker: float, v, overlaps, last_disp=None) -> int | None:
    """The first sample after t = 0 of a record at which the t_end auto stop rule holds
    when a law in force holds contacts closed (``effects.holds_contacts``), as the
    reference kernels apply it (``engines.kernels._settled``), or None: no contact held
    closed with the energy to part (``effects.bond`` BOND_UNDECIDED), and the wave has
    left the chain (:func:`last_detached`, :func:`wall_left`; at a free end with the last
    contact not held bound) or, at a free end, the last particle, faster than the arrival
    speed, is held bound to its neighbour (BOND_CAPTURED) and that pair is alone (two
    spheres, or the contact before it open and not held and no sphere behind it faster
    than the pair's centre of mass).

    v: (S, n) velocities (m/s); overlaps: (S, n-1) the sphere contacts' overlaps (m);
    last_disp: with an end wall, the last sphere's displacement (m) from its start."""
    v = np.asarray(v, dtype=float)
    ov = np.asarray(overlaps, dtype=float)
    n = v.shape[1]
    vthr = arrival_speed(v_striker)
    held = held_record(terms, ov)
    wall = last_disp is not None

    def state(s, k):
        return bond(terms, k, float(ov[s, k]), float(v[s, k] - v[s, k + 1]), bool(held[s, k]))

    m = np.asarray(terms.chain.masses, dtype=float)
    moving = v[1:, -1] < -vthr if wall else v[1:, -1] > vthr
    for s in np.flatnonzero(moving) + 1:
        bound = not wall and state(s, n - 2) == BOND_CAPTURED
        if wall:
            left = bool(wall_left(v[s, -1], last_disp[s], v_striker))
        else:
            left = not bound and bool(last_detached(v[s, -1], ov[s, -1], v_striker))
        if not left:
            if not bound:
                continue
            if n > 2 and (ov[s, n - 3] > 0.0 or held[s, n - 3]):
                continue
            vcm = (m[n - 2] * v[s, n - 2] + m[n - 1] * v[s, n - 1]) / (m[n - 2] + m[n - 1])
            if np.any(v[s, :n - 2] > vcm):
                continue
        if all(state(s, k) != BOND_UNDECIDED for k in range(n - 1)):
            return int(s)
    return None


def wall_passed(f_after_peak: np.ndarray, f_peak: float) -> bool:
    """Has the end wall's dynamic force passed its peak? f_after_peak: its samples
    after the peak, one of which must fall below the pass level (``obsrules.passed``)."""
    return bool(np.any(obsrules.passed(np.asarray(f_after_peak), f_peak)))


def inner_passed(v_after_peak: np.ndarray, v_peak: float) -> bool:
    """Has the wave passed an inner particle? v_after_peak: its samples after the peak
    (``obsrules.passed``)."""
    return bool(np.any(obsrules.passed(np.asarray(v_after_peak), v_peak)))


# ---------------------------------------------------------------------------------------
# what a run will cost, estimated before it starts
# ---------------------------------------------------------------------------------------
def expected_duration(scene, v: float) -> float:
    """Simulated time of one chain: t_end, or with t_end auto the time for the wave to
    leave the whole chain: n-1 contacts at V_N(0.5 v) plus the flight over all gaps at v;
    against an end wall the run lasts until the reflected wave has left the last sphere,
    counted as one more solitary-wave width (the last sphere turns back at the wave's
    reflection)."""
    if scene.t_end is not None:
        return scene.t_end
    if v <= 0:
        return 0.0
    t = crossing_time(scene, v, scene.n - 1, 0.5 * v)
    if scene.wall is not None:
        t += scene.pulse_width(0.5 * v)
    return t
