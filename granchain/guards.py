"""Guards on a scene before it runs: sampling accuracy, cost, physics warnings.

No numba or scipy, so ``granchain validate`` stays light. The solitary wave comes from
``granchain.analytic``, the sample grid from ``granchain.schedule``.

* :func:`cost_estimate` / :func:`check_cost`: integration steps per chain and memory of
  one chain's sample record, refused above limits the caller can raise (``granchain run
  --max-steps / --max-memory-gb``).
* :func:`physics_warnings`: where the scene leaves the model's range (Hertz overlap) or
  ends before its wave arrives.
* :func:`require_resolved`: what needs the step refuses a scene still at method auto.
"""
from __future__ import annotations

import math

from .analytic import nesterenko_speed, pulse_width
from .errors import GranchainError
from .schedule import sample_interval

# Fewest samples per solitary-wave width a scene's output.sample_dt may give (v_max at
# 25 samples per width is off by 6e-4, at 400 by 3e-8).
MIN_SAMPLES_PER_PULSE = 20
# Hertz theory holds for small overlaps: warn above this peak overlap / radius
MAX_OVERLAP_RATIO = 1e-2
# default cost limits (per chain)
DEFAULT_MAX_STEPS = 1e8
DEFAULT_MAX_MEMORY_GB = 4.0
# columns of a chain's sample record besides the n velocities (kernels.E_LEN)
RECORD_EXTRA_COLUMNS = 8


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


def _gap_total(scene, contacts: int) -> float:
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


def expected_duration(scene, v: float) -> float:
    """Simulated time of one chain: t_end, or with t_end auto the time for the wave to
    leave the whole chain: n-1 contacts at V_N(0.5 v) plus the flight over all gaps at v."""
    if scene.t_end is not None:
        return scene.t_end
    if v <= 0:
        return 0.0
    travel = (scene.n - 1) * 2.0 * scene.radius / float(nesterenko_speed(scene.material, 0.5 * v))
    return travel + _gap_total(scene, scene.n - 1) / v


def cost_estimate(scene, v: float) -> dict:
    """Estimated duration (s), integration steps, samples and record bytes of one chain
    (of a resolved scene: method auto has no step yet)."""
    require_resolved(scene, "cost_estimate")
    dur = expected_duration(scene, v)
    sdt = sample_interval(scene, v)
    samples = dur / sdt + 1.0 if (v > 0 or scene.t_end is not None) else 1.0
    if scene.method == "adaptive":
        steps = samples                 # at least one step per sample
    else:
        steps = dur / scene.dt
    return {"duration_s": dur, "steps": steps, "samples": samples,
            "record_bytes": samples * (scene.n + RECORD_EXTRA_COLUMNS) * 8.0}


def check_cost(scene, max_steps: float = DEFAULT_MAX_STEPS,
               max_memory_gb: float = DEFAULT_MAX_MEMORY_GB) -> None:
    """Refuse (one line) a scene whose chains exceed the step or memory limit."""
    if not (max_steps > 0) or not (max_memory_gb > 0):
        raise GranchainError(f"--max-steps / --max-memory-gb: limits must be > 0 (got "
                             f"{max_steps:g}, {max_memory_gb:g}); give positive numbers")
    worst = max((cost_estimate(scene, v) for v in scene.striker_velocities),
                key=lambda c: (c["steps"], c["record_bytes"]))
    how = ("t_end" if scene.t_end is not None else
           "t_end auto: until the wave has left particle n")
    if worst["steps"] > max_steps:
        step = (f"dt = {scene.dt:g} s" if scene.method != "adaptive"
                else "one adaptive step per sample")
        raise GranchainError(
            f"--max-steps: scene '{scene.name}' needs an estimated {worst['steps']:.3g} "
            f"integration steps per chain ({worst['duration_s']:.3g} s simulated, {how}; {step}), "
            f"above the limit {max_steps:.3g}; pass --max-steps {_ceil_sig(worst['steps'])} "
            "if you mean it, or shorten the run (t_end, gaps, chain.n)")
    gb = worst["record_bytes"] / 1e9
    if gb > max_memory_gb:
        raise GranchainError(
            f"--max-memory-gb: scene '{scene.name}' needs an estimated {gb:.3g} GB per chain "
            f"for its sample record ({worst['samples']:.3g} samples x {scene.n + RECORD_EXTRA_COLUMNS} "
            f"values), above the limit {max_memory_gb:g} GB; pass --max-memory-gb "
            f"{_ceil_sig(gb)} if you mean it, or sample less often (output.sample_dt) or "
            "shorten the run (t_end, chain.n)")


def _ceil_sig(x: float) -> str:
    """x rounded up to 2 significant digits, as text (a limit that accepts x)."""
    if not (x > 0 and math.isfinite(x)):
        return f"{x:g}"
    e = math.floor(math.log10(x)) - 1
    return f"{math.ceil(x / 10.0**e) * 10.0**e:.2g}"


def far_probe_arrival(scene, v: float) -> float:
    """Estimated time at which the wave reaches the far probe p2 (s)."""
    p2 = scene.probes[-1]
    travel = (p2 - 1) * 2.0 * scene.radius / float(nesterenko_speed(scene.material, 0.64 * v))
    return travel + _gap_total(scene, p2 - 1) / v


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
