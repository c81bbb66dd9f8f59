"""Guards on a scene before it runs: sampling accuracy and physics warnings (the cost
guard, which needs the run plan, is ``granchain.costmodel.check_cost``).

No numba or scipy, so ``granchain validate`` stays light. The solitary wave comes from
``granchain.analytic``.

* :func:`max_sample_dt`: the coarsest sampling that resolves the pulse.
* :func:`overlaps`: the static and peak Hertz overlap of every contact and the wall, each
  with its own materials and radii; :func:`check_overlaps` refuses a scene beyond
  HARD_OVERLAP_RATIO of R* (scene validation calls it).
* :func:`physics_warnings`: where the scene leaves the model's range (a Hertz overlap
  above MAX_OVERLAP_RATIO of R*) or ends before its wave arrives.
* :func:`require_resolved`: what needs the step refuses a scene still at method auto.
* :func:`check_run`: the whole run (every member of an ensemble or sweep, a grid, a
  workflow job) refused in one line when its estimated steps or memory
  (``granchain.costmodel.run_estimate``) exceed a limit.
* :func:`result_limits`: the physical bounds a chain's results must meet after the run,
  and the scene key to blame when one does not (``granchain.observables.bounded``
  applies them to every result of either engine).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .analytic import nesterenko_speed, pulse_width

# Fewest samples per solitary-wave width a scene's output.sample_dt may give (v_max at
# 25 samples per width is off by 6e-4, at 400 by 3e-8).
MIN_SAMPLES_PER_PULSE = 20
# Hertz theory holds for overlaps small against the contact's R* (contact radius
# a = sqrt(R* delta) small against R*): warn above this overlap / R* at any contact ...
MAX_OVERLAP_RATIO = 1e-2
# ... and refuse a scene above this one (a = 0.32 R*: far outside the model)
HARD_OVERLAP_RATIO = 0.1


def require_resolved(scene, who: str) -> None:
    """Raise ValueError if the scene's method is still auto (a program error: the step
    comes from the run plan, ``granchain.runplan.plan_run``, which every run makes first)."""
    if scene.method == "auto":
        raise ValueError(f"{who}: scene '{scene.name}' has integrator method auto; resolve "
                         "it first: run granchain.runplan.plan_run(scene).scene")


def max_sample_dt(scene) -> float | None:
    """The longest output.sample_dt that resolves the pulse of the fastest striker."""
    vmax = max(scene.striker_velocities)
    if vmax <= 0:
        return None
    return scene.pulse_width(0.64 * vmax) / MIN_SAMPLES_PER_PULSE


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


@dataclass(frozen=True)
class Overlap:
    """The overlaps of one contact of a scene (or of the alike contacts it stands for) at
    one striker speed, in m. ``static``: at rest under the dead load, (F0/K)^(2/3);
    ``peak``: a bound on the largest, the static one plus the overlap that stores the
    striker's whole kinetic energy (1/2) m_1 v^2 in this contact, (5 E / (2 K))^(2/5).
    The chain conserves energy and dissipation only removes it, and compressing a contact
    from its static overlap takes at least the energy that compressing it from zero does,
    so no contact can overlap more (for the striker's own contact with sphere 2 the
    bound is 2^0.4 = 1.32 x the two-sphere collision's overlap, measured 1.00-1.02 x in a
    chain)."""
    index: int          # the contact of spheres index+1, index+2 (0-based); n-1: the wall
    r_star: float       # the contact's R* (m); the wall's: R_n
    K: float            # its Hertz constant (N/m^1.5)
    static: float
    peak: float

    @property
    def static_ratio(self) -> float:
        return self.static / self.r_star

    @property
    def peak_ratio(self) -> float:
        return self.peak / self.r_star


def contact_name(scene, index: int) -> str:
    """'contact 3-4 (ptfe-ss440c)', 'the contacts 2-3 to 14-15' (alike spheres), 'sphere 15
    on the wall (ss440c on rigid)': the words for contact ``index`` of :func:`overlaps`."""
    n, mats = scene.n, scene.materials
    if index == n - 1:
        return f"sphere {n} on the wall ({mats[-1].name} on {scene.wall.name})"
    if not scene.uniform:
        return f"contact {index + 1}-{index + 2} ({mats[index].name}-{mats[index + 1].name})"
    if index == 0 or n == 3:
        return f"contact {index + 1}-{index + 2}"
    return f"the contacts 2-3 to {n - 1}-{n}"


def _energy_overlap(energy: float, K: float) -> float:
    """The overlap (m) of a Hertz contact K that stores ``energy`` (J): (2/5) K d^(5/2)."""
    try:
        return (2.5 * energy / K) ** 0.4
    except (OverflowError, ZeroDivisionError):
        return math.inf


def overlaps(scene, v_striker: float) -> list[Overlap]:
    """The static and peak overlaps (:class:`Overlap`) of every distinct contact of a scene
    and of its wall, each with its own spheres' materials and radii, for the striker at
    ``v_striker`` (m/s)."""
    ms, rs, ks = scene.masses, scene.radii, scene.contact_k
    try:
        energy = 0.5 * ms[0] * float(v_striker) ** 2
    except OverflowError:
        energy = math.inf
    F0 = scene.precompression
    out = []
    for i in scene.distinct_contacts:
        static = (F0 / ks[i]) ** (2.0 / 3.0) if F0 > 0.0 and i > 0 else 0.0
        out.append(Overlap(i, rs[i] * rs[i + 1] / (rs[i] + rs[i + 1]), ks[i], static,
                           static + _energy_overlap(energy, ks[i])))
    if scene.wall is not None:
        K = scene.wall_k
        static = (F0 / K) ** (2.0 / 3.0) if F0 > 0.0 else 0.0
        out.append(Overlap(scene.n - 1, rs[-1], K, static, static + _energy_overlap(energy, K)))
    return out


def check_overlaps(scene) -> None:
    """Refuse (SceneError naming the key to change) a scene in which a contact or the wall
    overlaps by more than HARD_OVERLAP_RATIO of its R*: at rest under the dead load
    (``precompression.force``), or at the bound of :func:`overlaps` for the fastest striker
    (``striker.velocity``)."""
    from .errors import SceneError
    v = max(scene.striker_velocities)
    found = overlaps(scene, v)
    worst = max(found, key=lambda o: o.static_ratio)
    if worst.static_ratio > HARD_OVERLAP_RATIO:
        # the largest load every contact takes within the limit: K (0.1 R*)^(3/2)
        limit = min(o.K * (HARD_OVERLAP_RATIO * o.r_star) ** 1.5 for o in found if o.static)
        raise SceneError(
            "precompression.force", f"{scene.precompression:g} N presses "
            f"{contact_name(scene, worst.index)} {worst.static:.3g} m = "
            f"{worst.static_ratio:.3g} R* deep at rest, beyond the "
            f"{HARD_OVERLAP_RATIO:g} R* where Hertz contact theory holds",
            f"give precompression.force <= {floor_sig(limit):.2g} N (stiffer or larger "
            "spheres and wall take more)")
    worst = max(found, key=lambda o: o.peak_ratio)
    if worst.peak_ratio > HARD_OVERLAP_RATIO:
        # the fastest striker whose energy stays within the limit at every contact
        m1 = scene.masses[0]
        limit = min(math.sqrt(0.8 * o.K * max(HARD_OVERLAP_RATIO * o.r_star - o.static, 0.0)
                              ** 2.5 / m1) for o in found)
        raise SceneError(
            "striker.velocity", f"a striker at {v:g} m/s can press "
            f"{contact_name(scene, worst.index)} up to {worst.peak:.3g} m = "
            f"{worst.peak_ratio:.3g} R* deep (its whole kinetic energy "
            f"in that contact), beyond the {HARD_OVERLAP_RATIO:g} R* where Hertz contact "
            "theory holds", f"give striker speeds <= {floor_sig(limit):.2g} m/s"
            + (" or a lower precompression.force" if worst.static else ""))


def physics_warnings(scene, v_striker: float) -> list[str]:
    """Warnings (one line each, without ';' or ',' so that tables can join them) for one
    striker speed of a scene; [] when none."""
    out = []
    v = float(v_striker)
    worst = max(overlaps(scene, v), key=lambda o: o.peak_ratio)
    if worst.peak_ratio > MAX_OVERLAP_RATIO:
        static = (f" ({worst.static_ratio:.2g} R* of it at rest under precompression.force)"
                  if worst.static else "")
        out.append(f"v_s = {v:g} m/s: the Hertz overlap of {contact_name(scene, worst.index)}"
                   f" can reach ~{worst.peak_ratio:.2g} R*{static} and exceeds "
                   f"{MAX_OVERLAP_RATIO:g} R* where Hertz contact theory holds (results are "
                   "outside the model's range)")
    if v <= 0:
        return out
    if scene.t_end is not None:
        arrive = far_probe_arrival(scene, v)
        if scene.t_end < arrive:
            out.append(f"v_s = {v:g} m/s: t_end = {scene.t_end:g} s ends before the wave can "
                       f"reach probe {scene.probes[-1]} (~{arrive:.3g} s): use t_end: auto or a "
                       "longer t_end")
    return out


def run_size(scene, realisations: int | None = None,
             realisations_key: str = "ensemble.realisations") -> str:
    """'8 chains: 2 striker speeds (striker.velocity) x 4 realisations
    (ensemble.realisations) of 15 spheres (chain.n)': the factors of a run's size,
    each with the key that sets it."""
    reals = scene.realisations if realisations is None else int(realisations)
    nv = len(scene.striker_velocities)
    return (f"{nv * reals} chains: {nv} striker speed{'s' if nv != 1 else ''} "
            f"(striker.velocity) x {reals} realisation{'s' if reals != 1 else ''} "
            f"({realisations_key}) of {scene.n} spheres (chain.n)")


def _duration(seconds: float) -> str:
    for unit, s in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * s:
            return f"{seconds / s:.2g} {unit}"
    return f"{seconds:.2g} s"


def _raise_to(x: float) -> str:
    """x rounded up to 2 significant digits, as text: a limit that accepts x."""
    if not (x > 0 and math.isfinite(x)):
        return f"{x:g}"
    e = math.floor(math.log10(x)) - 1
    return f"{math.ceil(round(x / 10.0**e, 9)) * 10.0**e:.2g}"


def _raise_limit(option: str, value: str) -> str:
    """How to raise a limit: a command-line option is passed, a configuration key raised."""
    return f"pass {option} {value}" if option.startswith("--") else f"raise {option} to {value}"


def check_run(what: str, est: dict, *, size: str, fix: str, max_total_steps: float,
              max_memory_gb: float, steps_option: str | None = "--max-total-steps",
              memory_option: str = "--max-memory-gb", memory_unit: str = "GB",
              steps_key: str | None = None) -> None:
    """Refuse (GranchainError, one line) a whole run whose estimate ``est``
    (``costmodel.run_estimate``) needs more than ``max_total_steps`` integration steps or
    ``max_memory_gb`` GB. ``what`` names the run ("scene 'x'"), ``size`` its factors and
    their keys (:func:`run_size`), ``fix`` what to lower; ``steps_option`` and
    ``memory_option`` (a command-line option or a configuration key, whose value is in
    ``memory_unit``, GB or MB) are the limits to raise; with ``steps_option`` None the step
    limit cannot be raised and the message starts with ``steps_key``, the key to lower."""
    from .errors import GranchainError
    steps_key = steps_key or steps_option
    if not (max_total_steps > 0) or not (max_memory_gb > 0):
        raise GranchainError(f"{steps_key} / {memory_option}: limits must be > 0 (got "
                             f"{max_total_steps:g}, {max_memory_gb:g}); give positive numbers")
    gb = est["bytes"] / 1e9
    if gb > max_memory_gb:
        held = f"{est['result_bytes'] / 1e9:.2g} GB of results"
        if est["record_bytes"]:
            held += f" and {est['record_bytes'] / 1e9:.2g} GB of sample records"
        scale = {"GB": 1.0, "MB": 1e3}[memory_unit]
        need = _raise_to(gb * scale)
        if memory_unit == "MB":                 # a whole number of MB, as the key takes
            need = str(math.ceil(float(need)))
        raise GranchainError(
            f"{memory_option}: {what} would hold an estimated {gb:.3g} GB over its whole run "
            f"({size}; {held}), above the limit {max_memory_gb * scale:g} {memory_unit}; "
            f"{fix}, or {_raise_limit(memory_option, need)} if the machine "
            "has the memory")
    if est["steps"] > max_total_steps:
        how = (f", or {_raise_limit(steps_option, _raise_to(est['steps']))} if you mean it"
               if steps_option else "")
        raise GranchainError(
            f"{steps_key}: {what} needs an estimated {est['steps']:.3g} integration steps "
            f"over its whole run ({size}; ~{_duration(est['seconds'])} on one core), above the "
            f"limit {max_total_steps:.3g}; {fix}{how}")


def scene_warnings(scene) -> list[str]:
    """Warnings of every striker speed of a scene, in order, without repeats."""
    out: list[str] = []
    for v in scene.striker_velocities:
        for w in physics_warnings(scene, v):
            if w not in out:
                out.append(w)
    return out


@dataclass(frozen=True)
class Limits:
    """The physical bounds of a chain's results (:func:`result_limits`), which
    ``granchain.observables.bounded`` checks after every run of either engine.

    sound_speed: the bar speed c = sqrt(E/rho) (m/s) of ``material``, the stiffest of the
    chain's spheres. A wave along a chain of spheres is slower than along a rod of their
    material: a preloaded Hertz chain's long-wave speed c0 = 2R sqrt(k2/m) reaches c only
    at a static overlap of about 1.9 R, and the solitary wave only at a particle speed
    near c, both far outside Hertz theory. A group velocity above c is therefore an
    impossible number, not a fast wave. (The bar speed, not the higher dilatational speed
    of the bulk material, because it is the tighter bound that still holds.)
    fast, order, nonfinite: the scene key most likely at fault, and what to do, for a
    group velocity above c, a delay between the probes that is not positive, and a
    non-finite value."""
    sound_speed: float
    material: str
    fast: str
    order: str
    nonfinite: str


def result_limits(scene) -> Limits:
    """The :class:`Limits` of a scene's chains."""
    mats = scene.materials or (scene.material,)
    stiff = max(mats, key=lambda m: m.bar_speed)
    load = ("precompression.force (the preload squeezes the contacts far beyond Hertz "
            "theory: lower it)") if scene.precompression > 0.0 else None
    step = ("integrator.dt (lower it or use method adaptive)"
            if scene.method in ("rk4", "verlet") else "integrator.tolerance (lower it)")
    return Limits(
        sound_speed=stiff.bar_speed, material=stiff.name,
        fast=load or "striker.velocity (lower it) or the material's E and rho",
        order=load or step,
        nonfinite=_stiff_effect(scene) or load or step)


def _stiff_effect(scene) -> str | None:
    """The keys of an effect whose own time scale (an effect module's ``time_scale``, e.g.
    a contact dashpot's m_eff/eta) is shorter than the scene's shortest collision: the
    likely source of a non-finite run."""
    from .effects import MODULES
    vmax = max(scene.striker_velocities)
    if not vmax > 0:
        return None
    try:
        tc = scene.contact_time(vmax)
    except (ArithmeticError, ValueError):
        return None
    for m in MODULES:
        if not (scene.has(m.SPEC.name) and hasattr(m, "time_scale")):
            continue
        tau, what = m.time_scale(scene, vmax)
        if tau < tc:
            # the section's numeric settings that are set (the dashpot's eta or e)
            st = scene.setting(m.SPEC.name)
            keys = [f"{m.SECTION}.{f.name}" for f in dataclasses.fields(st)
                    if isinstance(getattr(st, f.name), (int, float))
                    and not isinstance(getattr(st, f.name), bool)]
            return (f"{' or '.join(keys) or m.SECTION} ({what} is {tau:.2g} s at "
                    f"{vmax:g} m/s: shorter than the collision time {tc:.2g} s)")
    return None
