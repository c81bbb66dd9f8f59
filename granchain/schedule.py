"""How a run samples, when it stops, and which peaks it has measured: one rule for both
engines and the observables.

Sampling: ``sample_interval`` (the scene's, or 400 samples per solitary-wave width).

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

The reference kernels (``engines/kernels.py``, ``run_window``), the LAMMPS deck
(``fix halt`` on ``compute contact/atom``, ``lammps/deck.py``), the LAMMPS engine's
per-chain cut (``engines/lammps.auto_stop``) and ``observables.peak_final`` implement
these definitions with the constants below.
"""
from __future__ import annotations

import numpy as np

from . import analytic

SAMPLES_PER_PULSE = 400    # auto sampling: samples per solitary-wave width
ARRIVAL_FRACTION = 1e-3    # a particle has seen the wave once v > ARRIVAL_FRACTION * v_s
PASS_FRACTION = 0.5        # the wave has passed an inner particle once v < this * its peak


def sample_interval(scene, v_striker: float) -> float:
    """Sample interval (s) of a chain: the scene's ``output.sample_dt``, or
    SAMPLES_PER_PULSE per width of the solitary wave at 0.64 v_s (both engines, and the
    cost estimate, use this grid)."""
    if scene.sample_dt is not None:
        return scene.sample_dt
    v = max(v_striker, 1e-6)
    return float(analytic.pulse_width(scene.material, scene.radius, 0.64 * v)) / SAMPLES_PER_PULSE


def auto_t_max(scene, gaps, v_striker: float) -> float:
    """Generous cap on the duration of a t_end: auto run, which lasts until the wave has
    left the whole chain (a run that hits the cap is flagged ``timeout``)."""
    n = scene.n
    vs = analytic.nesterenko_speed(scene.material, 0.5 * v_striker)
    travel = (n - 1) * 2.0 * scene.radius / vs
    flight = float(np.sum(gaps[: n - 1])) / v_striker
    return 20.0 * travel + 50.0 * flight + 10.0 * analytic.pulse_width(
        scene.material, scene.radius, 0.5 * v_striker)


def arrival_speed(v_striker: float) -> float:
    """Velocity (m/s) above which a particle has seen the wave."""
    return ARRIVAL_FRACTION * v_striker


def last_detached(v_last, overlap_last, v_striker):
    """Has the last particle taken the wave and left? (elementwise on arrays)

    v_last: velocity of particle n (m/s); overlap_last: Hertz overlap of contact n-1, n
    (m, > 0 in contact)."""
    return (np.asarray(v_last) > arrival_speed(v_striker)) & (np.asarray(overlap_last) <= 0.0)


def inner_passed(v_after_peak: np.ndarray, v_peak: float) -> bool:
    """Has the wave passed an inner particle? v_after_peak: its samples after the peak."""
    return bool(np.any(np.asarray(v_after_peak) < PASS_FRACTION * v_peak))
