"""Outputs never clobber inputs or each other: before any work, every command refuses an
output path that is one of its inputs (the scene, the measurement CSV, a table it reads)
or another of its outputs (--out, --plot, the files of a kept --workdir), with or without
--force, comparing files through symlinks and hard links; --force replaces only an earlier
output of the same kind."""
from __future__ import annotations

import contextlib
import importlib
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from granchain.cli import main
from granchain.fileio import same_file

from conftest import REPO, SCENES, refused

ENTRIES = [("granchain.simulate", "run_scene"), ("granchain.simulate", "trajectories"),
           ("granchain.compare", "compare"), ("granchain.engines.reference", "run"),
           ("granchain.engines.lammps", "run"),
           # where the fits call them
           ("granchain.inference.gapfit", "simulate_grid"),
           ("granchain.inference.jointfit", "simulate_joint_grid")]


@pytest.fixture
def no_work(monkeypatch):
    """Every way into a simulation fails the test: the refusal must come first."""
    def boom(*a, **k):
        raise AssertionError("computed before refusing an output path")
    for module, attr in ENTRIES:
        monkeypatch.setattr(importlib.import_module(module), attr, boom)


@pytest.fixture
def files(tmp_path, monkeypatch):
    """A scene, a base scene and a measurement CSV in a working directory, with a symlink
    and a hard link to the CSV."""
    monkeypatch.chdir(tmp_path)
    for src, dst in ((SCENES / "packed-440c.yaml", "s.yaml"),
                     (REPO / "measurements" / "example_synthetic.yaml", "base.yaml"),
                     (REPO / "measurements" / "example_synthetic.csv", "m.csv")):
        (tmp_path / dst).write_bytes(src.read_bytes())
    (tmp_path / "link.csv").symlink_to(tmp_path / "m.csv")
    os.link(tmp_path / "m.csv", tmp_path / "hard.csv")
    return {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}


def unchanged(files) -> bool:
    return all(Path(name).read_bytes() == data for name, data in files.items())


INFER = ["infer", "m.csv", "--scene", "base.yaml", "--no-cache", "--no-progress"]


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_infer_out_and_plot_on_one_file_is_refused_before_the_grid(files, capsys, no_work,
                                                                   force):
    """Fails on a build that ran the whole inference, wrote the JSON, then failed on its
    own file (or with --force replaced the JSON by the PNG)."""
    refused(capsys, INFER + ["--out", "x.png", "--plot", "x.png", *force], "--plot", "--out")
    assert not Path("x.png").exists() and unchanged(files)


def test_infer_cache_dir_that_is_a_file_is_refused_before_the_grid(files, capsys, no_work):
    """Fails on a build that simulated the first grid point, then raised FileExistsError
    (a traceback) making the cache directory."""
    argv = ["infer", "m.csv", "--scene", "base.yaml", "--no-progress", "--cache-dir"]
    refused(capsys, argv + ["m.csv"], "--cache-dir", "not a directory")
    refused(capsys, argv + ["m.csv/sub"], "--cache-dir", "cannot create")
    assert unchanged(files)


@pytest.mark.parametrize("target", ["m.csv", "link.csv", "hard.csv", "./sub/../m.csv",
                                    "base.yaml"])
@pytest.mark.parametrize("option", ["--out", "--plot"])
def test_infer_never_writes_over_its_inputs_even_with_force(files, capsys, no_work, target,
                                                            option):
    """Fails on a build where --out m.csv --force destroyed the measurements."""
    Path("sub").mkdir()
    name = target if option == "--out" else target + ".png"
    if option == "--plot":
        Path(name).parent.mkdir(exist_ok=True)
        (Path(name).parent / Path(name).name).symlink_to(Path("m.csv").resolve())
    err = refused(capsys, INFER + [option, name, "--force"], option, "even with --force")
    assert ("measurement file" in err) or ("scene file" in err)
    assert unchanged(files)


def test_force_replaces_only_an_earlier_output_of_the_same_kind(files, capsys, no_work):
    """A copy of the measurements, a scene or another command's JSON is not an earlier
    infer result: --force leaves it alone."""
    Path("copy.csv").write_bytes(files["m.csv"])
    Path("run.json").write_text('{"scene": "s", "scene_hash": "0", "v_striker": 0.1}')
    Path("not.png").write_text("a text file")
    for argv, needle in ((["--out", "copy.csv"], "infer JSON"),
                         (["--out", "run.json"], "infer JSON"),
                         (["--plot", "not.png"], "image")):
        refused(capsys, INFER + argv + ["--force"], argv[0], needle)
    assert Path("copy.csv").read_bytes() == files["m.csv"]
    # an earlier run JSON may be replaced by run --force, not by compare --force
    refused(capsys, ["compare", "s.yaml", "--out", "run.json", "--force"], "compare JSON")
    Path("s2.yaml").write_bytes(files["s.yaml"])
    refused(capsys, ["run", "s.yaml", "--out", "s2.yaml", "--force"], "run JSON")
    assert Path("s2.yaml").read_bytes() == files["s.yaml"]


@pytest.mark.parametrize("cmd", ["run", "compare"])
def test_run_and_compare_never_write_over_the_scene(files, capsys, no_work, cmd):
    Path("alias.yaml").symlink_to(Path("s.yaml").resolve())
    for target in ("s.yaml", "alias.yaml"):
        refused(capsys, [cmd, "s.yaml", "--out", target, "--force"], "--out", "scene file")
    assert unchanged(files)


@pytest.mark.parametrize("cmd", ["run", "compare"])
def test_out_is_not_a_file_of_the_kept_workdir(files, capsys, no_work, cmd):
    Path("wd").mkdir()
    extra = ["--engine", "lammps"] if cmd == "run" else []
    for name in ("log.lammps", "deck.lmp", "traj.bin"):
        refused(capsys, [cmd, "s.yaml", *extra, "--workdir", "wd", "--force", "--out",
                         f"wd/{name}"], "--out", "--workdir")
    # and the scene is not one of them either
    Path("wd/chain.data").write_bytes(files["s.yaml"])
    refused(capsys, [cmd, "wd/chain.data", *extra, "--workdir", "wd", "--force"],
            "--workdir", "scene file")
    assert Path("wd/chain.data").read_bytes() == files["s.yaml"]


@pytest.mark.parametrize("cmd", ["run", "compare"])
def test_force_replaces_no_file_of_the_users_in_the_kept_workdir(files, capsys, no_work, cmd):
    """Each file a run writes into its --workdir: one of the user's under that name is
    refused with --force, before any work, and left as it was. Fails on a build that
    checked deck.lmp and chain.data alone (the log, the dumps and the ledgers were
    replaced)."""
    from granchain.lammps.deck import WORKDIR_FILES
    extra = ["--engine", "lammps"] if cmd == "run" else []
    for name in WORKDIR_FILES:
        wd = Path(f"wd-{name}")
        wd.mkdir()
        (wd / name).write_text("my notes\n")
        refused(capsys, [cmd, "s.yaml", *extra, "--workdir", str(wd), "--force"],
                "--workdir", name, "earlier output of the same kind")
        assert (wd / name).read_text() == "my notes\n"
    Path("wd-x").mkdir()
    Path("wd-x/keep.txt").write_text("x")
    refused(capsys, [cmd, "s.yaml", *extra, "--workdir", "wd-x"], "--workdir", "not empty")
    # a directory in the place of a file the run writes: the fix names the workdir
    Path("wd-d").mkdir()
    Path("wd-d/traj.bin").mkdir()
    refused(capsys, [cmd, "s.yaml", *extra, "--workdir", "wd-d", "--force"], "--workdir",
            "'wd-d/traj.bin' is a directory where this command writes its file traj.bin",
            "move that directory away or choose another directory")
    # a file as the workdir: refused before the reference run of compare, not after it
    refused(capsys, [cmd, "s.yaml", *extra, "--workdir", "m.csv", "--force"], "--workdir",
            "not a directory")
    assert unchanged(files)


@pytest.mark.lammps
def test_force_replaces_an_earlier_run_and_never_writes_through_a_link(files, capsys):
    """A kept --workdir of an earlier run is replaced with --force; a file of the run's
    name that is a symlink is replaced as a link, so the file it points to (here another
    LAMMPS log) is left as it was."""
    argv = ["run", "s.yaml", "--engine", "lammps", "--workdir", "wd", "--set", "t_end=1e-6",
            "--no-progress"]
    assert main(argv) == 0
    Path("other").mkdir()
    kept = Path("wd/log.lammps").read_bytes()
    Path("other/log.lammps").write_bytes(kept)
    Path("wd/log.lammps").unlink()
    Path("wd/log.lammps").symlink_to(Path("other/log.lammps").resolve())
    assert main(argv + ["--force"]) == 0
    capsys.readouterr()
    assert Path("other/log.lammps").read_bytes() == kept
    assert not Path("wd/log.lammps").is_symlink()
    assert Path("wd/log.lammps").read_bytes().startswith(b"LAMMPS (")


def test_deck_force_replaces_only_a_deck_granchain_wrote(files, capsys, tmp_path):
    Path("d").mkdir()
    Path("d/deck.lmp").write_text("# my own hand-written deck\n")
    refused(capsys, ["deck", "s.yaml", "-o", "d", "--force"], "deck", "granchain wrote")
    assert Path("d/deck.lmp").read_text() == "# my own hand-written deck\n"
    Path("d/deck.lmp").unlink()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["deck", "s.yaml", "-o", "d"]) == 0
        assert main(["deck", "s.yaml", "-o", "d", "--force"]) == 0     # its own: replaced
    # the scene file inside the deck directory, under a deck file's name
    Path("e").mkdir()
    Path("e/chain.data").write_bytes(files["s.yaml"])
    refused(capsys, ["deck", "e/chain.data", "-o", "e", "--force"], "-o/--output", "scene file")
    assert Path("e/chain.data").read_bytes() == files["s.yaml"]


def test_same_file_sees_through_symlinks_and_hard_links(tmp_path):
    a = tmp_path / "a"
    a.write_text("x")
    (tmp_path / "s").symlink_to(a)
    os.link(a, tmp_path / "h")
    (tmp_path / "b").write_text("x")
    assert same_file(a, tmp_path / "s") and same_file(a, tmp_path / "h")
    assert same_file(tmp_path / "new", tmp_path / "." / "new")
    assert not same_file(a, tmp_path / "b") and not same_file(a, tmp_path / "new")


def py(*argv, cwd):
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True, cwd=cwd,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))


def one_line_refusal(p, *needles):
    assert p.returncode == 2, (p.stdout, p.stderr)
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
    for n in needles:
        assert n in p.stderr, p.stderr


def test_accuracy_cli_outputs_never_clobber_its_inputs(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text("scene,method\n")
    (tmp_path / "t.provenance.json").write_text("{}")
    one_line_refusal(py("-m", "granchain.accuracy", "figure", str(table), str(tmp_path / "f.png"),
                        str(tmp_path / "f.png"), cwd=tmp_path), "pdf")
    one_line_refusal(py("-m", "granchain.accuracy", "figure", str(table), str(table),
                        cwd=tmp_path), "timing table")
    one_line_refusal(py("-m", "granchain.accuracy", "model", str(table), "--out", str(table),
                        "--force", cwd=tmp_path), "--out", "timing table")
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    one_line_refusal(py("-m", "granchain.accuracy", "model", str(table), "--out", str(other),
                        "--force", cwd=tmp_path), "--out", "cost model")
    assert other.read_text() == "a,b\n1,2\n" and table.read_text() == "scene,method\n"
    one_line_refusal(py("-m", "granchain.accuracy", "measure", "--cost-json", "{}",
                        "--table", str(tmp_path / "x.csv"), "--timing", str(tmp_path / "x.csv"),
                        cwd=tmp_path), "--timing", "--table")


def test_figure_and_thesis_mains_never_clobber_their_tables(tmp_path):
    from granchain import figures, thesis
    table = tmp_path / "packed.png"
    table.write_text("not really a png: a table the figure would read")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert figures.main(["fig5_1b", "--packed-sweep", str(table),
                             "--out", str(tmp_path / "packed")]) == 2
        assert thesis.main(["--packed-sweep", str(table), "--out-csv", str(table),
                            "--out-md", str(tmp_path / "t.md")]) == 2
        assert thesis.main(["--packed-sweep", str(table), "--out-csv", str(tmp_path / "t"),
                            "--out-md", str(tmp_path / "t")]) == 2
    lines = err.getvalue().splitlines()
    assert len(lines) == 3 and "--out" in lines[0] and "--out-csv" in lines[1] \
        and "--out-md" in lines[2]
    assert table.read_text() == "not really a png: a table the figure would read"


@pytest.mark.parametrize("script, base", [("make_example_measurements.py", "example_synthetic"),
                                          ("make_example_restitution.py", "example_restitution")])
def test_example_scripts_never_replace_their_scene_or_a_measurement(tmp_path, script, base):
    # copies of the script and its base scene: a regression would destroy the copies
    for part in ("scripts", "measurements"):
        (tmp_path / part).mkdir()
    for name in (script, "_synthetic.py"):
        (tmp_path / "scripts" / name).write_bytes((REPO / "scripts" / name).read_bytes())
    scene = tmp_path / "measurements" / f"{base}.yaml"
    scene.write_bytes((REPO / "measurements" / f"{base}.yaml").read_bytes())
    s = str(tmp_path / "scripts" / script)
    before = scene.read_bytes()
    one_line_refusal(py(s, "--out", str(scene), "--force", cwd=tmp_path), "--out", "base scene")
    assert scene.read_bytes() == before
    real = tmp_path / "lab.csv"
    real.write_text("v_striker_m_s,dt_front_s\n0.1,2e-5\n")
    one_line_refusal(py(s, "--out", str(real), "--force", cwd=tmp_path), "--out", "SYNTHETIC")
    assert real.read_text() == "v_striker_m_s,dt_front_s\n0.1,2e-5\n"
