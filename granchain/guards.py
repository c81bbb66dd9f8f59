"""Guards on a scene before it runs: sampling accuracy and physics warnings (the cost
guard, which needs the run plan, is ``granchain.schedule.check_cost``).

No numba or scipy, so ``granchain validate`` stays light. The solitary wave comes from
``granchain.analytic``.

* :func:`max_sample_dt`: the coarsest sampling that resolves the pulse.
* :func:`physics_warnings`: where the scene leaves the model's range (Hertz overlap) or
  ends before its wave arrives.
* :func:`require_resolved`: what needs the step refuses a scene still at method auto.
"""
from __future__ import annotations

import math

from .analytic import nesterenko_speed, pulse_width

# Fewest samples per solitary-wave width a scene's output.sample_dt may give (v_max at
# 25 samples per width is off by 6e-4, at 400 by 3e-8).
MIN_SAMPLES_PER_PULSE = 20
# Hertz theory holds for small overlaps: warn above this peak overlap / radius
MAX_OVERLAP_RATIO = 1e-2


def require_resolved(scene, who: str) -> None:
    """Raise ValueError if the scene's method is still auto (a program error: the step
    comes from ``granchain.costmodel.resolve_auto``, which every run applies first)."""
    if scene.method == "auto":
        raise ValueError(f"{who}: scene '{scene.name}' has integrator method auto; resolve "
                         "it first with granchain.costmodel.resolve_auto")


def max_sample_dt(scene) -> float | None:
    """The longest output.sample_dt that resolves the pulse of the fastest striker."""
    vmax = max(scene.striker_velocities)
    if vmax <= 0:
        return None
    return float(pulse_width(scene.material, scene.radius, 0.64 * vmax)) / MIN_SAMPLES_PER_PULSE


def floor_sig(x: float, digits: int = 2) -> float:
    """x rounded down to ``digits`` significant digits: a limit shown to the user that
    the user can paste back and have accepted."""
    if not (x > 0 and math.isfinite(x)):
        return x
    from decimal import ROUND_FLOOR, Decimal
    d = Decimal(repr(float(x)))
    return float(d.quantize(Decimal(1).scaleb(d.adjusted() - digits + 1), rounding=ROUND_FLOOR))


def gap_total(scene, contacts: int) -> float:
    """Expected sum of the first ``contacts`` gaps (m)."""
    contacts = max(0, min(contacts, scene.n - 1))
    dist = scene.gap_distribution
    if dist == "none":
        return 0.0
    if dist == "list":
        return float(sum(scene.gap_values[:contacts]))
    if dist == "from_length":
        return scene.gap_extra_length * contacts / (scene.n - 1)
    return contacts * (scene.gap_mean or 0.0)


def crossing_time(scene, v: float, contacts: int, v_m: float) -> float:
    """Estimated time (s) for the wave of a striker at v to cross the first ``contacts``
    contacts: their diameters at the solitary-wave speed V_N(v_m), plus the flight over
    their expected gaps at v."""
    travel = contacts * 2.0 * scene.radius / float(nesterenko_speed(scene.material, v_m))
    return travel + gap_total(scene, contacts) / v


def far_probe_arrival(scene, v: float) -> float:
    """Estimated time at which the wave reaches the far probe p2 (s)."""
    return crossing_time(scene, v, scene.probes[-1] - 1, 0.64 * v)


def physics_warnings(scene, v_striker: float) -> list[str]:
    """Warnings (one line each, without ';' or ',' so that tables can join them) for one
    striker speed of a scene; [] when none."""
    out = []
    v = float(v_striker)
    if v <= 0:
        return out
    mu = scene.mass / 2.0
    delta_m = (5.0 * mu * v * v / (4.0 * scene.hertz_k)) ** 0.4
    ratio = delta_m / scene.radius
    if ratio > MAX_OVERLAP_RATIO:
        out.append(f"v_s = {v:g} m/s: peak Hertz overlap ~{ratio:.2g} R exceeds "
                   f"{MAX_OVERLAP_RATIO:g} R, where Hertz contact theory no longer holds "
                   "(results are outside the model's range)")
    if scene.t_end is not None:
        arrive = far_probe_arrival(scene, v)
        if scene.t_end < arrive:
            out.append(f"v_s = {v:g} m/s: t_end = {scene.t_end:g} s ends before the wave can "
                       f"reach probe {scene.probes[-1]} (~{arrive:.3g} s): use t_end: auto or a "
                       "longer t_end")
    return out


def scene_warnings(scene) -> list[str]:
    """Warnings of every striker speed of a scene, in order, without repeats."""
    out: list[str] = []
    for v in scene.striker_velocities:
        for w in physics_warnings(scene, v):
            if w not in out:
                out.append(w)
    return out
