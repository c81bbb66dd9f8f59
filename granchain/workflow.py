"""The workflow's logic: configuration -> preset -> study scenes -> job batches -> tables.

The Snakemake rules (workflow/rules/*.smk) and their scripts only call this module.

Configuration (config/config.yaml, schema workflow/schemas/config.schema.yaml): a
``preset`` name and ``presets``; each preset has ``materials``, ``base`` (the chain and
integrator shared by every study), ``studies`` and ``batch``. A study expands into
*study scenes* (one :class:`~granchain.scene.Scene` per material and gap setting, built
with :func:`granchain.scene.scene_from_dict`, so a bad value gets the scene's own one-line
message); a scene's *members* are (striker speed x gap realisation), as in
:func:`granchain.simulate.members`. Realisation r of a scene draws its gaps from
``rng([seed, r])`` (:func:`granchain.gaps.realise`), so any member re-runs alone and
reproduces bit for bit (:func:`rerun_member`).

Batches: many members per job. The members of a study (per engine) are cut into
``ceil(members / batch.members_per_job)`` jobs of about equal *estimated cost* (integration
steps, which grow like gap / v_striker), in whole realisations of a scene, so a job calls
:func:`granchain.simulate.run_scene` with ``realisations=[...]`` once per scene it holds.

Studies (chapter figure in brackets):
- packed_sweep  [5.1b, 5.1c] packed chain, striker-speed sweep, per material
- packed_trace  [5.1a] packed chain at one speed, per material; also saves v(t)
- gap_profile   [5.3b] random gaps of one mean, one speed, R realisations
- gap_sweep     [5.3c] mean gaps x striker speeds x R realisations, per material
- extra_length  [5.4b] chains longer than packed by L_extra (gaps from_length)
- lammps_check  both engines on the same members (LAMMPS cross-validation)
"""
from __future__ import annotations

import contextlib
import copy
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import analytic, tables
from .errors import GranchainError
from .scene import RANDOM_GAPS, Scene, scene_from_dict
from .simulate import members as scene_members
from .simulate import run_scene, trajectories

STUDIES = ("packed_sweep", "packed_trace", "gap_profile", "gap_sweep", "extra_length",
           "lammps_check")
FIGURES = {"packed_sweep": "chapter Fig. 5.1b, 5.1c", "packed_trace": "chapter Fig. 5.1a",
           "gap_profile": "chapter Fig. 5.3b", "gap_sweep": "chapter Fig. 5.3c",
           "extra_length": "chapter Fig. 5.4b", "lammps_check": "LAMMPS cross-validation"}
ENGINE_ORDER = ("reference", "lammps")
# Rough cost of one integration step of one chain on one core (s), per engine: used only
# to balance batches and to declare runtimes, never for results.
STEP_SECONDS = {"reference": 2.0e-6, "lammps": 1.5e-5}   # LAMMPS: dump writing and reading dominate
JOB_OVERHEAD_S = 5.0       # interpreter start, imports, numba cache load


class ConfigError(GranchainError):
    """The workflow configuration is invalid (one line: where, what, and the fix)."""


# ---------------------------------------------------------------------------------------
# configuration
# ---------------------------------------------------------------------------------------
def config_error_message(exc: BaseException) -> str:
    """One line for a failed ``snakemake.utils.validate``: config path, problem, hint."""
    import jsonschema
    err, seen = exc, 0
    while err is not None and not isinstance(err, jsonschema.ValidationError) and seen < 10:
        err, seen = err.__cause__ or err.__context__, seen + 1   # validate() raises from it
    if err is None:
        return f"invalid configuration: {exc}"
    where = ".".join(str(p) for p in err.absolute_path) or "<top level>"
    hint = err.schema.get("description") if isinstance(err.schema, dict) else None
    msg = f"invalid configuration at '{where}': {err.message}"
    return msg + (f"; {hint}" if hint else "")


SCHEMA = Path(__file__).resolve().parent.parent / "workflow" / "schemas" / "config.schema.yaml"


def validate_config(config: dict, schema=SCHEMA) -> dict:
    """Check ``config`` against the workflow's JSON schema and fill its defaults (in place),
    as ``snakemake.utils.validate`` does in the Snakefile; one-line ConfigError if bad."""
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import validate
    if not Path(schema).is_file():
        raise ConfigError(f"workflow schema '{schema}' not found: run from a checkout "
                          "installed with pip install -e .")
    try:
        validate(config, str(schema))
    except WorkflowError as exc:
        raise ConfigError(config_error_message(exc)) from None
    return config


def load_config(path, preset: str | None = None) -> tuple[str, dict]:
    """(name, validated preset) of a workflow configuration file, e.g. config/config.yaml."""
    from snakemake.common.configfile import load_configfile
    config = load_configfile(str(path))
    if preset is not None:
        config["preset"] = preset
    validate_config(config)
    return check_config(config)


def select_preset(config: dict) -> tuple[str, dict]:
    """(name, preset mapping) chosen by ``config['preset']``."""
    name = config.get("preset", "default")
    presets = config.get("presets") or {}
    if name not in presets:
        known = ", ".join(sorted(presets)) or "none"
        raise ConfigError(f"invalid configuration at 'preset': unknown preset '{name}'; "
                          f"use --config preset=NAME with one of: {known}")
    return str(name), presets[name]


def check_config(config: dict) -> tuple[str, dict]:
    """Select the preset and build every study scene and batch of it, so a bad value fails
    now (with the scene's one-line message), before anything runs."""
    name, preset = select_preset(config)
    for study in STUDIES:
        try:
            batches(preset, study)
        except ConfigError as exc:
            raise ConfigError(str(exc).replace("at 'studies.", f"at 'presets.{name}.studies.", 1)) \
                from None
    return name, preset


# ---------------------------------------------------------------------------------------
# study scenes
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StudyScene:
    """One scene of a study: a material and a gap setting, with its striker speeds and
    realisations; ``raw`` is the scene mapping it was built from."""
    study: str
    index: int
    material: str
    gap_mean_nm: float          # nominal mean gap (0: packed)
    extra_length_um: float      # NaN unless the gaps come from an extra chain length
    engines: tuple[str, ...]
    scene: Scene
    raw: dict

    @property
    def meta(self) -> dict:
        return {"study": self.study, "material": self.material,
                "gap_distribution": self.scene.gap_distribution,
                "gap_mean_nm": self.gap_mean_nm, "extra_length_um": self.extra_length_um,
                "seed": self.scene.gap_seed, "scene_hash": self.scene.hash}

    @property
    def members(self) -> int:
        return len(self.scene.striker_velocities) * self.scene.realisations


def _as_list(x):
    return list(x) if isinstance(x, (list, tuple)) else [x]


def _fmt_num(x: float) -> str:
    return f"{x:g}".replace("+", "")


def _study_materials(preset: dict, spec: dict) -> list[str]:
    if "material" in spec:
        return [spec["material"]]
    return list(spec.get("materials") or preset["materials"])


def _raw_scene(preset: dict, spec: dict, name: str, material: str, velocities, gaps: dict,
               realisations: int) -> dict:
    base = preset["base"]
    raw = {
        "name": name,
        "material": material,
        "chain": {"n": base["n"], "radius": base["radius"]},
        "striker": {"velocity": list(velocities) if len(velocities) > 1 else velocities[0]},
        # the seed only where gaps are drawn at random (elsewhere it has no effect)
        "gaps": dict(gaps, seed=base["seed"]) if gaps.get("distribution") in RANDOM_GAPS
        else dict(gaps),
        "effects": list(base["effects"]),
        "integrator": {"method": spec.get("method", base["method"]),
                       "dt": spec.get("dt", base["dt"])},
        "ensemble": {"realisations": int(realisations)},
    }
    if raw["integrator"]["method"] == "auto" and "dt" not in spec:
        del raw["integrator"]["dt"]          # auto chooses its own step
    if "probes" in base:
        raw["probes"] = list(base["probes"])
    from .scene import apply_overrides
    return apply_overrides(raw, list(base.get("overrides", [])) + list(spec.get("overrides", [])))


def _build(study: str, raw: dict, where: str) -> Scene:
    try:
        return scene_from_dict(raw)
    except GranchainError as exc:
        raise ConfigError(f"invalid configuration at '{where}' (scene {raw['name']}): {exc}") \
            from None


def study_scenes(preset: dict, study: str) -> list[StudyScene]:
    """The scenes of one study of a preset, in table order."""
    if study not in STUDIES:
        raise ConfigError(f"unknown study '{study}'; use one of {', '.join(STUDIES)}")
    spec = preset["studies"][study]
    where = f"studies.{study}"
    dist = preset["base"]["gap_distribution"]
    out: list[StudyScene] = []

    def add(material, velocities, gaps, realisations, gap_nm, extra_um, suffix, engines):
        name = f"{study}-{material}" + (f"-{suffix}" if suffix else "")
        raw = _raw_scene(preset, spec, name, material, velocities, gaps, realisations)
        out.append(StudyScene(study, len(out), material, float(gap_nm), float(extra_um),
                              tuple(engines), _build(study, raw, where), raw))

    engines = ("reference",)
    if study == "lammps_check":
        engines = tuple(e for e in ENGINE_ORDER if e in spec["engines"])
    for material in _study_materials(preset, spec):
        v = _as_list(spec["v_striker"])
        if study in ("packed_sweep", "packed_trace"):
            add(material, v, {"distribution": "none"}, 1, 0.0, math.nan, "", engines)
        elif study in ("gap_profile", "gap_sweep", "lammps_check"):
            for g in _as_list(spec["gap_mean_nm"]):
                gaps = {"distribution": "none"} if g == 0 else \
                    {"distribution": dist, "mean": float(g) * 1e-9}
                reals = 1 if g == 0 else spec["realisations"]
                if study != "lammps_check":
                    add(material, v, gaps, reals, g, math.nan, f"gap{_fmt_num(g)}nm", engines)
                    continue
                # One scene per striker speed: a LAMMPS run samples all its chains on the
                # grid of its fastest one, so one speed per run keeps both engines on the
                # same grid (each chain's own) whatever the batching.
                for vi in v:
                    add(material, [vi], gaps, reals, g, math.nan,
                        f"gap{_fmt_num(g)}nm-v{_fmt_num(vi)}", engines)
        elif study == "extra_length":
            n = preset["base"]["n"]
            for L in _as_list(spec["extra_length_um"]):
                gaps = {"distribution": "from_length", "extra_length": float(L) * 1e-6}
                add(material, v, gaps, spec["realisations"], float(L) * 1e3 / (n - 1), L,
                    f"extra{_fmt_num(L)}um", engines)
    return out


# ---------------------------------------------------------------------------------------
# batches
# ---------------------------------------------------------------------------------------
def estimated_steps(scene: Scene, v: float, gap_mean: float) -> float:
    """Rough number of integration steps of one chain (for balancing batches only)."""
    if v <= 0:
        return 1.0
    p = scene.probes[-1]
    travel = (p + 2) * 2.0 * scene.radius / float(analytic.nesterenko_speed(scene.material, 0.64 * v))
    flight = (p - 1) * gap_mean / (0.7 * v)
    return (travel + flight) / scene.dt


def _gap_mean_m(ss: StudyScene) -> float:
    s = ss.scene
    if s.gap_distribution == "none":
        return 0.0
    if s.gap_distribution == "from_length":
        return s.gap_extra_length / (s.n - 1)
    if s.gap_distribution == "list":
        return float(np.mean(s.gap_values))
    return s.gap_mean or 0.0


def realisation_cost(ss: StudyScene, engine: str) -> float:
    """Estimated seconds of one realisation (all striker speeds) of a study scene."""
    g = _gap_mean_m(ss)
    steps = sum(estimated_steps(ss.scene, v, g) for v in ss.scene.striker_velocities)
    return steps * STEP_SECONDS[engine]


@dataclass(frozen=True)
class Batch:
    """One job: consecutive realisations of one or more scenes of a study, one engine."""
    study: str
    engine: str
    index: int
    units: tuple[tuple[int, tuple[int, ...]], ...]   # (scene index, realisations)
    members: int
    est_seconds: float
    hashes: tuple[str, ...] = ()                      # scene hash of each unit

    @property
    def name(self) -> str:
        return f"{self.engine}_{self.index:03d}"

    def key(self) -> str:
        """Its scenes (hash: any change of physics, speeds, seed...) and realisations: a
        Snakemake param, so a changed plan or scene re-runs the job."""
        parts = []
        for (i, reals), h in zip(self.units, self.hashes):
            lo, hi = reals[0], reals[-1]
            parts.append(f"{h}:r{lo}-{hi}" if len(reals) > 1 else f"{h}:r{lo}")
        return f"{self.study}/{self.name}[" + ",".join(parts) + "]"


def members_per_job(preset: dict) -> int:
    return int(preset["batch"]["members_per_job"])


def batches(preset: dict, study: str, engine: str | None = None) -> list[Batch]:
    """Job batches of a study (every engine, or one), balanced by estimated cost."""
    scenes = study_scenes(preset, study)
    engs = [e for e in ENGINE_ORDER if any(e in s.engines for s in scenes)]
    if engine is not None:
        engs = [e for e in engs if e == engine]
    k = members_per_job(preset)
    out: list[Batch] = []
    for eng in engs:
        units = []          # (scene index, realisation, members, cost)
        for ss in scenes:
            if eng not in ss.engines:
                continue
            c = realisation_cost(ss, eng)
            nv = len(ss.scene.striker_velocities)
            units += [(ss.index, r, nv, c) for r in range(ss.scene.realisations)]
        total_members = sum(u[2] for u in units)
        total_cost = sum(u[3] for u in units)
        njobs = max(1, math.ceil(total_members / k))
        target = total_cost / njobs
        bins: list[list] = [[] for _ in range(njobs)]
        cum = 0.0
        for u in units:
            j = min(njobs - 1, int((cum + 0.5 * u[3]) / target)) if target > 0 else 0
            bins[j].append(u)
            cum += u[3]
        index = 0
        for b in bins:
            if not b:
                continue
            grouped: dict[int, list[int]] = {}
            for si, r, _, _ in b:
                grouped.setdefault(si, []).append(r)
            out.append(Batch(study, eng, index,
                             tuple((si, tuple(rs)) for si, rs in grouped.items()),
                             sum(u[2] for u in b), sum(u[3] for u in b),
                             tuple(scenes[si].scene.hash for si in grouped)))
            index += 1
    return out


def plan(preset: dict) -> dict[str, list[Batch]]:
    return {study: batches(preset, study) for study in STUDIES}


def find_batch(preset: dict, study: str, name: str) -> Batch:
    for b in batches(preset, study):
        if b.name == name:
            return b
    raise GranchainError(f"study '{study}' has no batch '{name}' in this configuration")


def runtime_minutes(seconds: float, threads: int = 1) -> int:
    """A generous wall-clock limit (minutes) for a job estimated at ``seconds`` on 1 core."""
    return int(max(10, math.ceil(3.0 * (JOB_OVERHEAD_S + seconds / max(1, threads)) / 60.0)))


# ---------------------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------------------
def set_threads(threads: int | None) -> None:
    """Threads for the numba kernels of this process (a job's ``threads``)."""
    if not threads:
        return
    import numba
    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


@contextlib.contextmanager
def log_to(path):
    """Send this process's stderr (progress, warnings) to a job's log file."""
    if path is None:
        yield
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f, contextlib.redirect_stderr(f):
        yield


def _runs_to_rows(ss: StudyScene, runs: list[dict]) -> list[dict]:
    return [tables.member_row(ss.meta, r, ss.scene.n) for r in runs]


def engine_options(engine: str, threads: int | None) -> dict:
    """Keyword arguments of ``run_scene`` for an engine in a job with ``threads`` cores:
    LAMMPS gets that many MPI ranks; the reference engine's numba threads are set per
    process (``set_threads``)."""
    return {"nprocs": max(1, int(threads or 1))} if engine == "lammps" else {}


def member_rows(ss: StudyScene, runs: list[dict]) -> pd.DataFrame:
    """Table rows of a study scene's runs, with the Eq. 5.4 bound from its packed chain
    (run here for the speeds these runs have: a few cheap chains)."""
    df = tables.study_table(_runs_to_rows(ss, runs), ss.scene.n)
    speeds = sorted({float(r["v_striker"]) for r in runs})
    return tables.add_eq54_bound(df, packed_reference([ss], velocities=speeds), ss.scene.radius)


def run_batch(preset: dict, study: str, name: str, threads: int | None = None
              ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run one batch: (its rows, complete with the Eq. 5.4 bound; timing rows)."""
    batch = find_batch(preset, study, name)
    scenes = study_scenes(preset, study)
    rows, timing = [], []
    for si, reals in batch.units:
        ss = scenes[si]
        t0 = time.perf_counter()
        runs = run_scene(ss.scene, engine=batch.engine, realisations=list(reals),
                         **engine_options(batch.engine, threads))
        wall = time.perf_counter() - t0
        rows.append(member_rows(ss, runs))
        timing.append({"study": study, "engine": batch.engine, "batch": batch.name,
                       "scene_hash": ss.scene.hash, "members": len(runs),
                       "steps": int(sum(r["steps"] for r in runs)), "wall_s": wall,
                       "wall_per_member_s": wall / max(1, len(runs))})
        print(f"[granchain] {study} {batch.name}: {ss.scene.name} {len(runs)} members "
              f"in {wall:.2f} s", file=sys.stderr, flush=True)
    return pd.concat(rows, ignore_index=True), tables.timing_table(timing)


def write_batch(preset: dict, study: str, name: str, out_csv, timing_csv,
                threads: int | None = None) -> None:
    df, timing = run_batch(preset, study, name, threads)
    tables.write_csv(timing, timing_csv)
    tables.write_csv(df, out_csv)


def trace_scene(ss: StudyScene) -> Scene:
    """The packed_trace scene with t_end long enough for the pulse to cross all n spheres
    (1.5x the Nesterenko travel time of n + 1 diameters at 0.64 v_s, the chapter's v_max)."""
    sc = ss.scene
    v = float(sc.striker_velocities[0])
    travel = (sc.n + 1) * 2.0 * sc.radius / float(analytic.nesterenko_speed(sc.material, 0.64 * v))
    raw = copy.deepcopy(ss.raw)
    raw["t_end"] = 1.5 * travel
    return _build("packed_trace", raw, "studies.packed_trace")


def run_traces(preset: dict, trace_paths: dict[str, str], out_csv, timing_csv) -> None:
    """packed_trace: each material's row, and its v(t) trace as .npz
    (t_s (S,), v_m_s (S, n), v_striker_m_s, material)."""
    scenes = study_scenes(preset, "packed_trace")
    rows, timing = [], []
    for ss in scenes:
        t0 = time.perf_counter()
        runs = run_scene(ss.scene)
        rows.append(member_rows(ss, runs))
        # The table row stops once the wave has left the chain (t_end auto); the trace
        # for Fig. 5.1a runs for a fixed 1.5x the crossing time, the same for every speed.
        (m, traj), = list(trajectories(trace_scene(ss), scene_members(ss.scene)))
        tables.write_npz(trace_paths[ss.material], t_s=traj.t, v_m_s=traj.v,
                         v_striker_m_s=np.float64(m.v_striker), material=np.str_(ss.material))
        wall = time.perf_counter() - t0
        timing.append({"study": "packed_trace", "engine": "reference", "batch": ss.material,
                       "scene_hash": ss.scene.hash, "members": len(runs),
                       "steps": int(sum(r["steps"] for r in runs)), "wall_s": wall,
                       "wall_per_member_s": wall / max(1, len(runs))})
    tables.write_csv(tables.timing_table(timing), timing_csv)
    tables.write_csv(pd.concat(rows, ignore_index=True), out_csv)


# ---------------------------------------------------------------------------------------
# gathering
# ---------------------------------------------------------------------------------------
def packed_scene(ss: StudyScene) -> Scene:
    """The packed chain of a study scene: same physics, striker speeds, method and dt."""
    raw = copy.deepcopy(ss.raw)
    raw["name"] = f"{ss.study}-{ss.material}-packed"
    raw["gaps"] = {"distribution": "none"}
    raw["ensemble"] = {"realisations": 1}
    return scene_from_dict(raw)


def packed_reference(scenes: list[StudyScene], velocities=None) -> pd.DataFrame:
    """Group velocity of the packed chain (reference engine, arrival-time definition
    ``v_g_front``) per (material, striker speed): the v_g(no gaps) of chapter Eq. 5.4.

    ``velocities`` restricts the speeds (e.g. to re-run one member alone).
    """
    rows, done = [], set()
    for ss in scenes:
        ps = packed_scene(ss)
        if velocities is not None:
            raw = copy.deepcopy(ps.spec)
            raw["striker"]["velocity"] = [float(v) for v in velocities]
            ps = scene_from_dict(raw, check_unused=False)
        if ps.hash in done:
            continue
        done.add(ps.hash)
        for r in run_scene(ps):
            rows.append({"material": ss.material, "v_striker_m_s": float(r["v_striker"]),
                         "v_g_packed_m_s": float(r["v_g_front"])})
    return pd.DataFrame(rows, columns=["material", "v_striker_m_s", "v_g_packed_m_s"]) \
        .drop_duplicates(["material", "v_striker_m_s"]).reset_index(drop=True)


def _order(df: pd.DataFrame, scenes: list[StudyScene]) -> pd.DataFrame:
    """Table order: scene (config order), engine, striker speed (config order), realisation."""
    by_hash = {ss.scene.hash: ss for ss in scenes}
    unknown = set(df["scene_hash"]) - set(by_hash)
    if unknown:
        raise GranchainError(f"batch tables hold scenes {sorted(unknown)} that the configuration "
                             "does not define; delete the study's work folder and re-run")
    si = df["scene_hash"].map(lambda h: by_hash[h].index)
    vi = [by_hash[h].scene.striker_velocities.index(v)
          for h, v in zip(df["scene_hash"], df["v_striker_m_s"])]
    ei = df["engine"].map(ENGINE_ORDER.index)
    keyed = df.assign(_s=si.to_numpy(), _e=ei.to_numpy(), _v=vi, _r=df["realisation"].to_numpy())
    keyed = keyed.sort_values(["_s", "_e", "_v", "_r"], kind="stable")
    dup = keyed.duplicated(["_s", "_e", "_v", "_r"])
    if dup.any():
        raise GranchainError("batch tables overlap (a member appears twice); delete the "
                             "study's work folder and re-run")
    return keyed.drop(columns=["_s", "_e", "_v", "_r"]).reset_index(drop=True)


def study_provenance(preset_name: str, preset: dict, study: str, df: pd.DataFrame) -> dict:
    scenes = study_scenes(preset, study)
    return {
        "preset": preset_name,
        "study": study,
        "config_hash": tables.config_hash(preset),
        "scene_hashes": {ss.scene.name: ss.scene.hash for ss in scenes},
        "seeds": sorted({int(s) for s in df["seed"]}),
        "gap_seeding": "realisation r of a scene draws its gaps from numpy "
                       "default_rng([seed, r])",
        "engines": [e for e in ENGINE_ORDER if e in set(df["engine"])],
        "methods": sorted(set(df["method"])),
        "dt_s": sorted({float(x) for x in df["dt_s"]}),
        "rows": int(len(df)),
        "eq54_bound": "v_g_bound_eq54_m_s: (2R + gbar)/v = 2R/v_g_packed + gbar/v_s with gbar "
                      "the row's mean gap between the probes and v_g_packed the arrival-time "
                      "group velocity of the packed chain (reference engine, same scene)",
    }


def describe(preset_name: str, preset: dict, study: str) -> dict:
    """Sizes of a study for the report's table captions (workflow/report/*.rst)."""
    scenes = study_scenes(preset, study)
    s0 = scenes[0].scene
    speeds = sorted({v for ss in scenes for v in ss.scene.striker_velocities})
    gaps = sorted({ss.gap_mean_nm for ss in scenes})
    extra = sorted({ss.extra_length_um for ss in scenes if not math.isnan(ss.extra_length_um)})
    if extra:
        gap_text = f"gaps from an extra chain length of {', '.join(f'{x:g}' for x in extra)} um"
    elif gaps == [0.0]:
        gap_text = "packed (no gaps)"
    else:
        gap_text = (f"{s0.gap_distribution if s0.gap_distribution != 'none' else preset['base']['gap_distribution']} "
                    f"gaps of mean {', '.join(f'{g:g}' for g in gaps)} nm")
    engines = [e for e in ENGINE_ORDER if any(e in ss.engines for ss in scenes)]
    return {"preset": preset_name, "figure": FIGURES[study], "scenes": len(scenes),
            "materials": ", ".join(dict.fromkeys(ss.material for ss in scenes)),
            "v_striker": ", ".join(f"{v:g}" for v in speeds),
            "gaps": gap_text if study != "lammps_check" else ", ".join(f"{g:g}" for g in gaps),
            "members": sum(ss.members * len(ss.engines) for ss in scenes),
            "jobs": len(batches(preset, study)), "engines": engines,
            "method": ", ".join(dict.fromkeys(ss.scene.method for ss in scenes)),
            "dt_s": f"{s0.dt:g}", "seed": s0.gap_seed, "probes": list(s0.probes[:2])}


def gather(preset_name: str, preset: dict, study: str, batch_csvs, timing_csvs,
           out_table, out_summary, out_provenance, out_timing) -> pd.DataFrame:
    """Concatenate a study's batch tables into its table, summary, provenance and timing
    (pure table work: the batches' rows are complete)."""
    scenes = study_scenes(preset, study)
    parts = [tables.read_csv(p) for p in batch_csvs]
    df = pd.concat(parts, ignore_index=True) if parts else \
        tables.study_table([], scenes[0].scene.n)
    df = _order(df, scenes)
    expected = sum(ss.members * len(ss.engines) for ss in scenes)
    if len(df) != expected:
        raise GranchainError(f"study '{study}' has {len(df)} rows, the configuration "
                             f"{expected}; delete its work folder and re-run")
    df = df[tables.columns(scenes[0].scene.n)]
    timing = pd.concat([tables.read_csv(p) for p in timing_csvs], ignore_index=True) \
        if timing_csvs else tables.timing_table([])
    tables.write_csv(timing, out_timing)
    tables.write_csv(tables.summary_table(df), out_summary)
    tables.write_provenance(out_provenance, lammps="lammps" in set(df["engine"]),
                            **study_provenance(preset_name, preset, study, df))
    tables.write_csv(df, out_table)
    return df


# ---------------------------------------------------------------------------------------
# one member alone
# ---------------------------------------------------------------------------------------
def rerun_member(preset: dict, study: str, *, material: str, v_striker: float, realisation: int,
                 engine: str = "reference", gap_mean_nm: float | None = None,
                 extra_length_um: float | None = None) -> dict:
    """Re-run one member of a study alone and return its table row (with the Eq. 5.4
    bound): a chain with only this striker speed and only this gap realisation."""
    cands = [ss for ss in study_scenes(preset, study) if ss.material == material
             and v_striker in ss.scene.striker_velocities
             and (gap_mean_nm is None or ss.gap_mean_nm == gap_mean_nm)
             and (extra_length_um is None or ss.extra_length_um == extra_length_um)]
    if len(cands) != 1:
        raise GranchainError(f"{len(cands)} scenes of study '{study}' match; give its "
                             "material, v_striker and gap_mean_nm or extra_length_um")
    ss = cands[0]
    raw = copy.deepcopy(ss.scene.spec)
    raw["striker"]["velocity"] = float(v_striker)
    alone = scene_from_dict(raw, check_unused=False)
    run, = run_scene(alone, engine=engine, realisations=[int(realisation)])
    return member_rows(ss, [run]).iloc[0].to_dict()


# ---------------------------------------------------------------------------------------
# LAMMPS vs reference
# ---------------------------------------------------------------------------------------
COMPARISON_META = ("scene_hash", "compared_scene_hash", "chains", "dt", "sample_dt", "nprocs",
                   "lammps_version", "balance", "tolerances")


def engine_comparison(preset: dict, threads: int | None = None) -> tuple[pd.DataFrame, list]:
    """granchain.compare.compare on every lammps_check scene: per member and quantity both
    engines' values, the difference, its tolerance, ok and why; plus each scene's meta
    (wall times and temporary paths left out, so the table is deterministic)."""
    from . import compare as cmp
    frames, metas = [], []
    for ss in study_scenes(preset, "lammps_check"):
        c = cmp.compare(ss.scene, nprocs=max(1, int(threads or 1)))
        df = c.rows.copy()
        df.insert(0, "study", "lammps_check")
        df.insert(1, "material", ss.material)
        df.insert(2, "gap_mean_nm", ss.gap_mean_nm)
        df.insert(3, "scene_hash", ss.scene.hash)
        df = df.rename(columns={"v_striker": "v_striker_m_s"})
        frames.append(df)
        metas.append({k: c.meta.get(k) for k in COMPARISON_META} | {"scene": ss.scene.name,
                                                                   "ok": c.ok})
    return pd.concat(frames, ignore_index=True), metas


def write_engine_comparison(preset_name: str, preset: dict, out_csv, out_provenance,
                            threads: int | None = None) -> pd.DataFrame:
    df, metas = engine_comparison(preset, threads)
    tables.write_provenance(out_provenance, lammps=True, preset=preset_name,
                            study="lammps_check", config_hash=tables.config_hash(preset),
                            comparisons=metas, all_ok=all(m["ok"] for m in metas))
    tables.write_csv(df, out_csv)
    return df
