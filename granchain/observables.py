"""Observables of a chain, engine-neutral: they read a Trajectory, whatever produced it.

Peak of particle i: v_max,i = max_t v_i(t), refined below the sample spacing:
- a sharp peak (at most PLATEAU_SAMPLES samples within PEAK_TOL of the maximum) is
  refined by the vertex of the parabola through the three samples around the maximum;
- a plateau (a particle flying freely across a gap keeps its velocity, so many samples
  lie within PEAK_TOL of the maximum) has an ill-defined maximum: its peak time is the
  start of the plateau, the first crossing of (1 - PEAK_TOL) v_max, linearly interpolated.
Arrival (front) time of particle i: first crossing of v_max,i / 2 on the rising edge,
linearly interpolated. It is defined whether the peak is sharp or a plateau.

A peak is reported only when it is *final* (``granchain.schedule``: the wave has passed
an inner particle, the last particle has left): otherwise v_max, t_peak and t_front of
that particle are NaN and ``final`` is False for it. A maximum at the end of the record
is not a peak.

The chapter's observables: v_max,1 and v_max,2 are the peaks of the two probes (particles
2 and 13 by default), dt_peak the time between their peak times, and
v_g = (p2 - p1)(2R + gbar)/dt_peak with gbar the mean gap over the p2 - p1 contacts
between the probes (11 for the chapter's probes). ``v_g`` uses peak times, as the
chapter does; ``v_g_front`` uses arrival (half-peak) times and is the robust choice
for gapped chains; both are always reported, with ``plateau`` flags per particle. They
need both probes' peaks to be final; ``wave_arrived`` says whether they are.
"""
from __future__ import annotations

import math

import numpy as np

from . import schedule
from .trajectory import ENERGY_COLUMNS, Trajectory

PEAK_TOL = 1e-4
PLATEAU_SAMPLES = 5


def _crossing(t, y, level, stop):
    """First time y crosses up through ``level`` at or before index ``stop``."""
    idx = np.flatnonzero(y[: stop + 1] >= level)
    if idx.size == 0:
        return math.nan
    j = int(idx[0])
    if j == 0:
        return float(t[0])
    y0, y1 = y[j - 1], y[j]
    return float(t[j - 1] + (level - y0) / (y1 - y0) * (t[j] - t[j - 1]))


def peak(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, bool]:
    """(v_max, t_peak, t_front, plateau) of one sampled velocity history."""
    j = int(np.argmax(y))
    top = float(y[j])
    if not top > 0.0:
        return 0.0, math.nan, math.nan, False
    near = y >= (1.0 - PEAK_TOL) * top
    # contiguous run of near-maximum samples containing j
    lo = j
    while lo > 0 and near[lo - 1]:
        lo -= 1
    hi = j
    while hi < len(y) - 1 and near[hi + 1]:
        hi += 1
    plateau = (hi - lo + 1) > PLATEAU_SAMPLES
    if not plateau and 0 < j < len(y) - 1:
        y0, y1, y2 = float(y[j - 1]), top, float(y[j + 1])
        den = y0 - 2.0 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den < 0.0 else 0.0
        off = min(max(off, -0.5), 0.5)
        vmax = y1 - 0.25 * (y0 - y2) * off
        h = float(t[j + 1] - t[j])
        tpk = float(t[j]) + off * h
    elif not plateau:
        vmax, tpk = top, float(t[j])
    else:
        vmax = top
        tpk = _crossing(t, y, (1.0 - PEAK_TOL) * top, j)
    tfront = _crossing(t, y, 0.5 * vmax, j)
    return float(vmax), float(tpk), tfront, bool(plateau)


def peak_final(traj: Trajectory, i: int) -> bool:
    """Is the peak of particle i (0-based) inside the record? (``granchain.schedule``)"""
    y = traj.v[:, i]
    j = int(np.argmax(y))
    top = float(y[j])
    if not top > schedule.arrival_speed(traj.v_striker):
        return False            # the wave never reached it
    if i == traj.n - 1:
        return bool(schedule.last_detached(y[-1], traj.last_overlap, traj.v_striker))
    return schedule.inner_passed(y[j + 1:], top)


def peaks(traj: Trajectory):
    """(v_max, t_peak, t_front, plateau, final) of every particle; NaN where not final."""
    cols = [peak(traj.t, traj.v[:, i]) for i in range(traj.n)]
    v_max, t_peak, t_front, plateau = (np.array(c, dtype=float) for c in zip(*cols))
    final = np.array([peak_final(traj, i) for i in range(traj.n)], dtype=bool)
    for a in (v_max, t_peak, t_front):
        a[~final] = math.nan
    return v_max, t_peak, t_front, plateau.astype(bool), final


def energy_ledger(traj: Trajectory) -> dict:
    """Energy ledger: final values, work by each effect, and the balance error.

    balance(t) = [E_kin,trans + E_kin,rot + E_hertz](t) - E(0) - sum of work done on the
    particles by the dissipative effects up to t; balance_error = max_t |balance| / E(0).
    """
    e = traj.energy
    total = e[:, 0] + e[:, 1] + e[:, 2]
    work = e[:, 3:].sum(axis=1)
    e0 = float(total[0])
    bal = total - e0 - work
    out = {name: float(e[-1, i]) for i, name in enumerate(ENERGY_COLUMNS)}
    out["initial"] = e0
    out["final_mechanical"] = float(total[-1])
    out["balance_error"] = float(np.max(np.abs(bal)) / e0) if e0 > 0 else 0.0
    return out


def summarize(traj: Trajectory, probes=(2, 13)) -> dict:
    """All observables of one chain as plain Python (JSON-ready) values."""
    v_max, t_peak, t_front, plateau, final = peaks(traj)
    p1, p2 = probes[0], probes[1]
    i1, i2 = p1 - 1, p2 - 1
    gbar = float(np.mean(traj.gaps[p1 - 1:p2 - 1])) if p2 > p1 else 0.0
    span = (p2 - p1) * (2.0 * traj.radius + gbar)
    # both probes' peaks measured, by a run that did not fail numerically
    arrived = bool(traj.v_striker > 0 and final[i1] and final[i2]
                   and traj.status in ("passed", "done", "timeout"))
    dt_peak = float(t_peak[i2] - t_peak[i1]) if arrived else math.nan
    dt_front = float(t_front[i2] - t_front[i1]) if arrived else math.nan
    v_g = span / dt_peak if arrived and dt_peak > 0 else math.nan
    v_g_front = span / dt_front if arrived and dt_front > 0 else math.nan
    return {
        "v_striker": traj.v_striker,
        "wave_arrived": bool(arrived),
        "status": traj.status,
        "v_max": v_max.tolist(),
        "t_peak": t_peak.tolist(),
        "t_front": t_front.tolist(),
        "plateau": plateau.tolist(),
        "final": final.tolist(),
        "not_final": [i + 1 for i in range(traj.n) if not final[i]],
        "probes": list(probes),
        "v_max_1": float(v_max[i1]),
        "v_max_2": float(v_max[i2]),
        "dt_peak": dt_peak,
        "dt_front": dt_front,
        "gap_mean_probes": gbar,
        "v_g": v_g,
        "v_g_front": v_g_front,
        "energy": energy_ledger(traj),
        "steps": traj.steps,
        "rejected_steps": traj.rejected,
        "wall_s": traj.wall_s,
        "t_end": float(traj.t[-1]),
        "samples": int(traj.t.size),
    }
