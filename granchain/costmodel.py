"""The packaged cost model (what ``integrator.method: auto`` chooses from) and what a chain
and a run cost: steps, sample records, wall time, the cost guards.

numpy only (no pandas, numba or scipy), so ``granchain validate`` can show what auto
resolves to.

The cost model (``granchain/data/cost_model.csv``, provenance beside it) holds one row per
(scene class, setting): class ``packed`` (no realisation has a gap) or ``gapped``; a setting
is rk4 or verlet at N steps per contact time, or adaptive or event at a tolerance; the
errors are the largest measured over the class's scenes, the wall time their mean. It is written by
``python -m granchain.accuracy model`` from a measurement (``granchain.accuracy``).

dt is stored as N steps per contact time: under Hertz scaling the error of a setting at
given N transfers across striker speeds, materials and radii (the auto sample interval is
a fixed fraction of the contact time t_c).

Method auto's choice from the model, and the run plan around it, are ``granchain.runplan``'s.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
from collections import Counter
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from .errors import GranchainError
from .scenekeys import TOLERANCE_METHODS
from .guards import require_resolved
from .effects import ENERGY_COLUMNS, SPECS, slots
from .stoprule import expected_duration, sample_interval

# default cost limits (per chain), raised with granchain run --max-steps / --max-memory-gb
DEFAULT_MAX_STEPS = 1e8
DEFAULT_MAX_MEMORY_GB = 4.0
# columns of a chain's sample record besides the n velocities: the energy ledger's and time
RECORD_EXTRA_COLUMNS = len(ENERGY_COLUMNS) + 1

SCENE_METHODS = ("rk4", "verlet", "adaptive", "event")   # what ``method: auto`` may resolve to
# 'damped': an effect on makes the contact force depend on the closing speed
# (``EffectSpec.normal_speed``); its errors are the worst over every measured scene
DAMPED = "damped"
SCENE_CLASSES = ("packed", "gapped", DAMPED)
MODEL_FILE = "data/cost_model.csv"
MODEL_PROVENANCE = "data/cost_model.provenance.json"
MODEL_COLUMNS = ("scene_class", "method", "steps_per_contact", "tolerance", "wall_s_per_chain",
                 "err_v_max_2", "err_v_g", "err_v_g_front", "balance_error",
                 "ref_uncertainty_v_max_2", "ref_uncertainty_v_g", "ref_uncertainty_v_g_front")
_TEXT_COLUMNS = ("scene_class", "method")
NA_TEXT = "NaN"                                  # how the tables write a missing number


@dataclass(frozen=True)
class CostModel:
    """The cost model's columns (``MODEL_COLUMNS``: text columns as object arrays, the
    others float64 with NaN where missing) and its provenance."""
    columns: dict
    provenance: dict
    # envelope() per (observable, scene class), computed once: the columns never change
    _envelopes: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)

    def __len__(self) -> int:
        return len(self.columns["method"])

    @property
    def classes(self) -> frozenset:
        """The scene classes the model has rows of."""
        return frozenset(str(c) for c in self.columns["scene_class"])

    def envelope(self, observable: str = "v_g", scene_class: str | None = None) -> list[dict]:
        """Per setting over the rows of ``scene_class`` (all rows if None), grouped by
        method in order of first appearance and ordered finest first (more steps per
        contact, tighter tolerance): method, steps_per_contact (None for adaptive),
        tolerance (None for fixed steps), wall_s_per_chain (mean over the rows), err (the
        largest over the rows; NaN read as inf), envelope (the largest err of this and
        every finer setting of its method), ref_uncertainty (the largest; NaN read as 0)."""
        key = (observable, scene_class)
        if key not in self._envelopes:
            self._envelopes[key] = self._envelope(observable, scene_class)
        return [dict(r) for r in self._envelopes[key]]

    def _envelope(self, observable: str, scene_class: str | None) -> list[dict]:
        c = self.columns
        err_col = "balance_error" if observable == "balance" else f"err_{observable}"
        unc_col = None if observable == "balance" else f"ref_uncertainty_{observable}"
        groups: dict[tuple, list[int]] = {}
        for i in range(len(self)):
            if scene_class is None or c["scene_class"][i] == scene_class:
                spc, tol = c["steps_per_contact"][i], c["tolerance"][i]
                key = (str(c["method"][i]), None if math.isnan(spc) else int(spc),
                       None if math.isnan(tol) else float(tol))
                groups.setdefault(key, []).append(i)

        def largest(col, rows):
            vals = [c[col][i] for i in rows if not math.isnan(c[col][i])]
            return max(vals) if vals else math.nan

        out = []
        for m in dict.fromkeys(k[0] for k in groups):
            keys = [k for k in groups if k[0] == m]
            keys.sort(key=(lambda k: k[2]) if m in TOLERANCE_METHODS else (lambda k: -k[1]))
            err = np.array([largest(err_col, groups[k]) for k in keys], dtype=float)
            err = np.where(np.isnan(err), np.inf, err)
            env = np.maximum.accumulate(err) if len(err) else err
            for k, e, v in zip(keys, err, env):
                rows = groups[k]
                unc = largest(unc_col, rows) if unc_col else 0.0
                out.append({"method": m, "steps_per_contact": k[1], "tolerance": k[2],
                            "wall_s_per_chain": sum(float(c["wall_s_per_chain"][i])
                                                    for i in rows) / len(rows),
                            "err": float(e), "envelope": float(v),
                            "ref_uncertainty": 0.0 if math.isnan(unc) else float(unc)})
        return out

    def cheapest(self, tol: float, observable: str = "v_g", *, methods=None,
                 scene_class: str | None = None, work: dict | None = None) -> dict | None:
        """The least wall time per chain among settings whose envelope and reference
        uncertainty are <= ``tol`` (ties: by method name, then envelope order); None if
        none is. method, steps_per_contact, tolerance, wall_s_per_chain, err, envelope.
        ``work`` (method -> factor): rank on the measured wall time times the factor of
        its method (the wall time carried to another scene, :func:`work_ratio`)."""
        env = [r for r in self.envelope(observable, scene_class)
               if (methods is None or r["method"] in methods)
               and r["envelope"] <= tol and r["ref_uncertainty"] <= tol]
        if not env:
            return None
        w = work or {}
        best = min(range(len(env)), key=lambda k: (env[k]["wall_s_per_chain"]
                                                   * w.get(env[k]["method"], 1.0),
                                                   env[k]["method"], k))
        return {k: v for k, v in env[best].items() if k != "ref_uncertainty"}

    @property
    def threads(self) -> int:
        """The threads its wall times were measured on (its cost block's, else 1): a
        chain's seconds on one core are about its wall time times these."""
        return int(self.provenance.get("cost", {}).get("threads", 1))

    def measured_effects(self) -> frozenset:
        """The effects on in the scenes the model measured: its base's, and where it has
        the damped class the laws that class stands for (``EffectSpec.normal_speed``)."""
        on = set(self.provenance["base"]["effects"])
        if DAMPED in self.classes:
            on |= {e for e, spec in SPECS.items() if spec.normal_speed}
        return frozenset(on)

    def work(self, scene_class: str) -> dict:
        """Method -> mean :func:`chain_work` of the measurement's scenes of the class (the
        work behind the model's wall times)."""
        scenes = [s for k, s in self.provenance["scenes"].items()
                  if self.provenance["scene_class"][k] == scene_class]
        return {m: sum(float(s["work"][m]) for s in scenes) / len(scenes)
                for m in SCENE_METHODS}

    def setting_seconds(self, method: str, scene_class: str, *,
                        steps_per_contact: float | None = None,
                        tolerance: float | None = None) -> float:
        """Wall time per chain of the model's scenes of ``scene_class`` at a setting of
        ``method``: at a measured setting its mean wall time (what :meth:`cheapest` ranks);
        between measured settings interpolated log-log in steps per contact (rk4, verlet)
        or in tolerance (adaptive, event); beyond the finest or coarsest step in proportion
        to the steps; beyond the measured tolerances the nearest one's."""
        rows = [r for r in self.envelope("v_g", scene_class) if r["method"] == method]
        if not rows:
            raise GranchainError(f"cost model granchain/data/cost_model.csv has no {method} "
                                 f"rows for {scene_class} chains; re-measure it with "
                                 "'python -m granchain.accuracy model'")
        fixed = method not in TOLERANCE_METHODS
        x = steps_per_contact if fixed else tolerance
        key = "steps_per_contact" if fixed else "tolerance"
        pts = sorted((math.log(float(r[key])), math.log(r["wall_s_per_chain"])) for r in rows)
        xs, ys = [p[0] for p in pts], [p[1] for p in pts]
        lx = math.log(float(x))
        if fixed and lx > xs[-1]:
            return math.exp(ys[-1] + lx - xs[-1])
        if fixed and lx < xs[0]:
            return math.exp(ys[0] + lx - xs[0])
        return float(math.exp(np.interp(lx, xs, ys)))

    def event_max_n(self) -> int:
        """The longest chain the model measured the event method on."""
        return int(self.provenance["base"]["n"])

    def achievable(self, observable: str = "v_g", *, methods=None,
                   scene_class: str | None = None) -> float:
        """The tightest tolerance some setting meets that the reference can verify."""
        env = [r for r in self.envelope(observable, scene_class)
               if methods is None or r["method"] in methods]
        if not env:
            return math.inf
        return max(min(r["envelope"] for r in env), max(r["ref_uncertainty"] for r in env))



# ---------------------------------------------------------------------------------------
# what one chain needs: steps, samples, record; the per-chain cost guard
# ---------------------------------------------------------------------------------------
def cost_estimate(scene, v: float, *, duration: float | None = None,
                  sample_dt: float | None = None) -> dict:
    """Estimated duration (s), integration steps, samples and record bytes of one chain
    (of a resolved scene: method auto has no step yet). ``duration`` and ``sample_dt``:
    :func:`~granchain.stoprule.expected_duration` and
    :func:`~granchain.stoprule.sample_interval` at v, if already known (neither
    depends on the integrator)."""
    require_resolved(scene, "cost_estimate")
    dur = expected_duration(scene, v) if duration is None else duration
    sdt = sample_interval(scene, v) if sample_dt is None else sample_dt
    samples = dur / sdt + 1.0 if (v > 0 or scene.t_end is not None) else 1.0
    if scene.method == "adaptive":
        steps = samples                 # about one step per sample at tight tolerances, fewer
                                        # at loose ones (its steps follow its tolerance)
    elif scene.method == "event":
        steps = samples                 # bounded by the adaptive method's count
    else:
        steps = dur / scene.dt
    return {"duration_s": dur, "steps": steps, "samples": samples,
            "record_bytes": samples * (scene.n + RECORD_EXTRA_COLUMNS) * 8.0}


def check_cost(scene, max_steps: float = DEFAULT_MAX_STEPS,
               max_memory_gb: float = DEFAULT_MAX_MEMORY_GB, estimates=None) -> None:
    """Refuse (one line) a scene whose chains exceed the step or memory limit;
    ``estimates``: the :func:`cost_estimate` of each striker speed, if already known (a
    run plan's)."""
    if not (max_steps > 0) or not (max_memory_gb > 0):
        raise GranchainError(f"--max-steps / --max-memory-gb: limits must be > 0 (got "
                             f"{max_steps:g}, {max_memory_gb:g}); give positive numbers")
    if estimates is None:
        estimates = [cost_estimate(scene, v) for v in scene.striker_velocities]
    worst = max(estimates, key=lambda c: (c["steps"], c["record_bytes"]))
    how = ("t_end" if scene.t_end is not None else
           "t_end auto: until the wave has left particle n")
    if worst["steps"] > max_steps:
        step = (f"dt = {scene.dt:g} s" if scene.method not in ("adaptive", "event")
                else "about one adaptive step per sample")
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


def read_model_csv(path) -> dict:
    """The columns of a cost-model CSV (``MODEL_COLUMNS``, in any order)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    missing = [c for c in MODEL_COLUMNS if c not in head]
    if missing:
        raise GranchainError(f"cost model {path}: columns {', '.join(missing)} are missing")
    cols = {}
    for c in MODEL_COLUMNS:
        j = head.index(c)
        if c in _TEXT_COLUMNS:
            cols[c] = np.array([r[j] for r in body], dtype=object)
        else:
            cols[c] = np.array([math.nan if r[j] in (NA_TEXT, "") else float(r[j])
                                for r in body], dtype=float)
    return cols


@lru_cache(maxsize=1)
def load_model() -> CostModel:
    """The packaged cost model and its provenance."""
    root = resources.files("granchain")
    if not root.joinpath(MODEL_FILE).is_file():
        raise GranchainError("integrator.method auto: the cost model granchain/data/cost_model.csv "
                             "is missing; run 'python -m granchain.accuracy model' or choose a method")
    with resources.as_file(root.joinpath(MODEL_FILE)) as p:
        cols = read_model_csv(p)
    return CostModel(cols, json.loads(root.joinpath(MODEL_PROVENANCE).read_text()))


def is_packed(scene) -> bool:
    """True if no realisation of the scene has a gap (the cost model's class 'packed')."""
    d = scene.gap_distribution
    return (d == "none" or (d in ("fixed", "uniform", "exponential") and not scene.gap_mean)
            or (d == "list" and not any(scene.gap_values))
            or (d == "from_length" and not scene.gap_extra_length))


def fixed_step(scene, steps_per_contact: int) -> float:
    """The step of N steps per contact time on the scene's sample grid: t_c / N (t_c at
    the fastest striker) snapped down to sample_dt / k (k steps per sample) or, for a step
    longer than the auto sample interval, to k sample_dt (a sample every step, on the
    grid). Under Hertz scaling sample_dt / t_c is the same for every scene (auto sampling:
    400 samples per solitary-wave width, t_c / 163), so a given N gives the same dt / t_c
    and the same sampling everywhere: the measurement and method auto
    (``granchain.runplan.auto_setting``) both use it."""
    v = max(scene.striker_velocities)
    dt = scene.contact_time(v) / steps_per_contact
    sdt = sample_interval(scene, v)
    if scene.sample_dt is not None or dt < sdt:
        return sdt / math.ceil(sdt / dt * (1.0 - 1e-12))
    return sdt * math.floor(dt / sdt * (1.0 + 1e-12))


def speed_work(scene, method: str, v: float, duration: float | None = None) -> float:
    """The share of striker speed ``v`` in :func:`chain_work` (``duration``: its
    ``stoprule.expected_duration`` if already known)."""
    if not v > 0:
        return 0.0
    if method == "event":
        return float(scene.n - 1)
    dur = expected_duration(scene, v) if duration is None else duration
    if method == "adaptive":
        return dur / scene.contact_time(v)
    return dur / scene.contact_time(max(scene.striker_velocities))


def chain_work(scene, method: str, durations: dict | None = None) -> float:
    """Relative work of one realisation of ``scene`` (all its striker speeds) under
    ``method``: what carries the model's wall times from its measurement scenes to
    another scene. Fixed steps (t_c / N at the fastest striker) and the adaptive method
    (its steps set by its tolerance on the contacts' time scale t_c) cost the simulated time
    (``stoprule.expected_duration``: wave travel plus flight over the gaps) over the
    contact time. The event method's steps follow the contacts and skip the flight:
    within a factor of about 5 the same per contact over 20 nm to 1 um gaps and 0.01 to
    0.1 m/s (benchmarks/gapped.py), so its work is the n - 1 contacts per speed.
    ``durations``: striker speed -> expected duration, if already known. The sum over
    speeds of :func:`speed_work`."""
    vs = [float(v) for v in scene.striker_velocities if v > 0]
    if not vs:
        return 1.0
    d = durations or {}
    return sum(speed_work(scene, method, v, d.get(v)) for v in vs)


def work_ratio(scene, model: CostModel, scene_class: str, durations: dict | None = None
               ) -> dict:
    """Method -> the work of ``scene`` over that of the model's scenes of its class."""
    ref = model.work(scene_class)
    return {m: chain_work(scene, m, durations) / ref[m] for m in SCENE_METHODS}


def scene_class(scene, model: CostModel | None = None) -> str:
    """The cost model's class of a scene: 'damped' when an effect on makes its contact
    force depend on the closing speed (``EffectSpec.normal_speed``: velocity Verlet is
    then first order, RK4 loses order at each contact's start and end) and the model
    (default: the packaged one) measured such chains; else 'packed' or 'gapped'
    (:func:`is_packed`)."""
    if any(SPECS[e].normal_speed for e in scene.effects if e in SPECS):
        if DAMPED in (model or load_model()).classes:
            return DAMPED
    return "packed" if is_packed(scene) else "gapped"


# The cost model measures the reference engine only. A LAMMPS run's cost per chain and
# integration step (s), dump writing and reading included: measured 8e-6 on a 40-chain
# run at 0.1 m/s, 1.5e-5 for small runs, whose process start is shared by fewer chains.
LAMMPS_STEP_SECONDS = 1.5e-5


def member_seconds(scene, v: float, engine: str = "reference", model: CostModel | None = None,
                   *, duration: float | None = None, steps: float | None = None) -> float:
    """Estimated wall time (s) of one chain of a resolved scene at striker speed ``v``:
    the one cost estimate of a member, behind auto's choice, the workflow's batches and
    the cost guard's time. Reference engine: the cost model's wall time per chain at the
    scene's setting (:meth:`CostModel.setting_seconds`; a fixed step dt is
    t_c(fastest striker) / dt steps per contact) times the member's work over the
    model's scenes' (:func:`speed_work`, the per-speed share of :func:`work_ratio`), times
    the scene's laws' :func:`step_cost`: at a setting auto picked, the cost auto ranked it
    by times that factor, which is the same for every setting. LAMMPS:
    ``LAMMPS_STEP_SECONDS`` per integration step (``steps``: the
    ``costmodel.cost_estimate`` steps). ``duration``: ``stoprule.expected_duration``, if
    already known."""
    require_resolved(scene, "member_seconds")
    if not v > 0:
        return 0.0
    if engine == "lammps":
        if steps is None:
            steps = cost_estimate(scene, v)["steps"]
        return steps * LAMMPS_STEP_SECONDS
    model = model or load_model()
    cls = scene_class(scene, model)
    m = scene.method
    if m in TOLERANCE_METHODS:
        wall = model.setting_seconds(m, cls, tolerance=scene.tolerance)
    else:
        n_tc = scene.contact_time(max(scene.striker_velocities)) / scene.dt
        wall = model.setting_seconds(m, cls, steps_per_contact=n_tc)
    return wall * speed_work(scene, m, v, duration) / model.work(cls)[m] * step_cost(scene)


def held_seconds(scene, v: float, run_length: float, model: CostModel | None = None
                 ) -> float:
    """Estimated wall time (s) of one chain of a resolved scene under a method with a
    tolerance (adaptive, event) at striker speed ``v`` that keeps every contact active
    for ``run_length`` (s): a chain bound as a whole by a law that holds contacts closed
    (``effects.binding``) vibrates in all its contacts until its cap. The event method
    then follows every contact as the adaptive method follows the chain: the adaptive
    method's time at the scene's tolerance over that time. The event method's own
    estimate counts one passage per contact (:func:`speed_work`); bound JKR chains ran
    2.9-5.3x over it scaled to the cap, and at 0.27-0.46 of this (``benchmarks/estimates.py
    --method event``, 316 at 190 nm and 1 J/m^2, 440C at 47 nm and 2 J/m^2, 1e-6)."""
    require_resolved(scene, "held_seconds")
    if scene.method not in TOLERANCE_METHODS:
        raise GranchainError(f"held_seconds: a method with a tolerance, not {scene.method!r}")
    return member_seconds(dataclasses.replace(scene, method="adaptive"), v, model=model,
                          duration=run_length)


def step_cost(scene) -> float:
    """A particle-step's cost for the scene's laws over the cost model's chain's: the
    largest ``EffectSpec.step_cost`` of the effects on (JKR's contact radius and
    Thornton's history cost more than the laws the model measured)."""
    return max((SPECS[e].step_cost for e in scene.effects if e in SPECS), default=1.0)


# ---------------------------------------------------------------------------------------
# what a whole run costs: every member (striker speed x realisation) of a scene
# ---------------------------------------------------------------------------------------
# Bytes a run holds per member until it ends, besides its sample record: the ChainResult
# (tuples of n per-particle values; tracemalloc: 4.4 kB at n = 15, 7.4 kB at n = 40), its
# Member and its row of gaps.
MEMBER_BYTES = 3000.0
MEMBER_BYTES_PER_PARTICLE = 110.0
# and, in the reference engine, its row of the kernels' per-chain array G (G_LEN * n
# floats, every registered effect's rows included)
DEFAULT_MAX_TOTAL_STEPS = 1e11      # whole run, raised with --max-total-steps
# The reference engine's chunks (engines.chunks: CHUNK_BYTES, CHUNK_CHAINS; the samples
# per kernel call, engines.reference: WINDOW, BLOCK_WINDOW): while a chunk's records are
# joined their pieces are held as well, and each chain of a chunk has its window of
# samples and, under the event method, its peak-tracking buffers (tracemalloc: ~3.7 kB per
# particle).
RECORD_CHUNK_BYTES = 256 * 2**20
CHUNK_CHAINS = 512
WINDOW_SAMPLES = {"rk4": 256, "verlet": 256, "adaptive": 2048, "event": 2048}
EVENT_BYTES_PER_PARTICLE = 3700.0
# The fixed-step methods measuring on the fly (no trace): per particle a ring of
# RING_SAMPLES record samples (an index and two floats each), and the chain's state, rows
# and running observables (~640 bytes a particle, tracemalloc), for every lane of the
# chunk's blocks of BLOCK_LANES chains (engines.chunks.LANES).
RING_SAMPLES = 512
OBSERVE_BYTES_PER_PARTICLE = 24.0 * RING_SAMPLES + 640.0
BLOCK_LANES = 32


def holds_records(scene, engine: str = "reference", trace: bool = False) -> bool:
    """Does a run keep each member's sample record until it ends? LAMMPS reads back the
    dump of all its chains at once. The reference engine yields chains in member order
    but runs them ordered by sampling and total gap, so a chain may wait for every other
    one; it records the sampled trajectory only on request (``trace``, or a measured
    scene: ``vibrometer.needs_trace``) or under the adaptive method, which has no
    on-the-fly observables (the event and fixed-step methods measure them as they go)."""
    if engine == "lammps":
        return True
    return scene.method == "adaptive" or trace or scene.measurement is not None


def run_estimate(scene, realisations=None, engine: str = "reference", *,
                 trace: bool = False, speeds_apart: bool = False) -> dict:
    """Estimated cost of a whole run of a resolved scene: every striker speed x
    ``realisations`` (a count or the realisation indices; the scene's own count if None);
    ``speeds_apart``: one run per striker speed, each freeing its records before the next
    (``workflow.run_members`` on LAMMPS).
    members; steps (integration steps, all members); worst_chain_steps; record_bytes
    (sample records held, :func:`holds_records`); result_bytes (per-member results);
    bytes (their sum); seconds (wall time on one core, :func:`member_seconds`). A run
    plan (:meth:`granchain.runplan.RunPlan.estimate`) gives the same from its own
    estimates."""
    per_v = [cost_estimate(scene, v) for v in scene.striker_velocities]
    secs = [member_seconds(scene, v, engine, duration=c["duration_s"], steps=c["steps"])
            for v, c in zip(scene.striker_velocities, per_v)]
    return estimate_run(scene, per_v, secs, realisations, engine, trace=trace,
                        speeds_apart=speeds_apart)


def estimate_run(scene, per_v: list[dict], seconds: list[float], realisations=None,
                 engine: str = "reference", *, trace: bool = False,
                 speeds_apart: bool = False) -> dict:
    """:func:`run_estimate` from each striker speed's ``costmodel.cost_estimate``
    (``per_v``) and :func:`member_seconds` (``seconds``) on ``engine``."""
    if realisations is None:
        reals = scene.realisations
    elif isinstance(realisations, (int, np.integer)):
        reals = int(realisations)
    else:
        reals = len(realisations)
    reals = max(0, reals)
    members = reals * len(per_v)
    steps = reals * sum(c["steps"] for c in per_v)
    rec = [c["record_bytes"] for c in per_v]
    held = max(rec, default=0.0) if speeds_apart else sum(rec)
    recorded = holds_records(scene, engine, trace)
    records = reals * held if recorded else 0.0
    if engine == "reference":
        window = WINDOW_SAMPLES.get(scene.method, 256) if recorded else 0
        per_chain = window * (scene.n + RECORD_EXTRA_COLUMNS) * 8.0
        chains = min(members, CHUNK_CHAINS)
        if scene.method == "event":
            per_chain += EVENT_BYTES_PER_PARTICLE * scene.n
        elif not recorded:
            per_chain += OBSERVE_BYTES_PER_PARTICLE * scene.n
            # a chunk holds the chains of one sample interval (the speeds that share it)
            share = Counter(sample_interval(scene, v) for v in scene.striker_velocities)
            chains = min(reals * max(share.values(), default=1), CHUNK_CHAINS)
            chains = -(-chains // BLOCK_LANES) * BLOCK_LANES
        records += min(records, RECORD_CHUNK_BYTES) + chains * per_chain
    per_member = MEMBER_BYTES + MEMBER_BYTES_PER_PARTICLE * scene.n
    if engine == "reference":
        per_member += 8.0 * slots.G_LEN * scene.n
    results = members * per_member
    return {"members": members, "steps": steps,
            "worst_chain_steps": max((c["steps"] for c in per_v), default=0.0),
            "record_bytes": records, "result_bytes": results, "bytes": records + results,
            "seconds": reals * sum(seconds)}


def add_estimates(*ests: dict) -> dict:
    """The cost of runs made one after another in one process holding all their results
    (e.g. both engines of a comparison): sums, and the worst chain of any."""
    out = {k: sum(e[k] for e in ests) for k in ("members", "steps", "record_bytes",
                                                  "result_bytes", "bytes", "seconds")}
    out["worst_chain_steps"] = max((e["worst_chain_steps"] for e in ests), default=0.0)
    return out
