"""Progress bars (granchain.progress): shown on a terminal's stderr for an ensemble
(``granchain run``), the inference's grid (``granchain infer``) and the warm-up; nothing
when stderr is not a terminal or with --no-progress; and no change to any result or
output file."""
from __future__ import annotations

import io
import json
import sys

import pytest

from granchain.cli import main
from granchain.engines import warmup

ENSEMBLE = """name: ens
material: ss440c
chain: {n: 6}
probes: [2, 5]
striker: {velocity: [0.05, 0.1]}
gaps: {distribution: uniform, mean: 20.0e-9}
ensemble: {realisations: 3}
"""
BASE = "name: base\nmaterial: ss440c\nchain: {n: 6}\nprobes: [2, 5]\n"
ROWS = "v_striker_m_s,dt_front_s,dt_err_s\n0.05,6.0e-06,2.0e-07\n0.035,7.0e-06,2.0e-07\n"


class Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def run_argv():
    """granchain run of a 6-chain ensemble, in the working directory."""
    with open("ens.yaml", "w") as f:
        f.write(ENSEMBLE)
    return ["run", "ens.yaml", "--out", "run.json"]


def infer_argv():
    """granchain infer on a 12-chain grid, in the working directory."""
    for name, text in (("m.csv", ROWS), ("base.yaml", BASE)):
        with open(name, "w") as f:
            f.write(text)
    return ["infer", "m.csv", "--scene", "base.yaml", "--gap-points", "3", "--gap-max-nm",
            "60", "--realisations", "2", "--out", "infer.json", "--cache-dir", "cache"]


def without_wall_times(path) -> dict:
    """A run's JSON without its wall-clock times (they differ between any two runs)."""
    doc = json.loads(path.read_text())
    for r in doc["runs"]:
        del r["wall_s"], r["batch_wall_s"]
    return doc


def test_progress_changes_no_output_file(tmp_path, monkeypatch):
    """With a bar on a terminal and with --no-progress, granchain run and granchain infer
    write the same files (a run's JSON up to its wall times; the inference's JSON and
    its grid cache byte for byte), and only the first writes a bar."""
    files = {}
    for label, flag in (("bar", []), ("quiet", ["--no-progress"])):
        err = Terminal()
        monkeypatch.setattr(sys, "stderr", err)
        d = tmp_path / label
        d.mkdir()
        monkeypatch.chdir(d)
        assert main(run_argv() + flag) == 0
        assert main(infer_argv() + flag) == 0
        shown = err.getvalue()
        if label == "bar":
            assert "ens: chains" in shown and "/6 [" in shown, shown
            assert "base: inference grid" in shown and "/12 [" in shown, shown
        else:
            assert shown == ""
        files[label] = (without_wall_times(d / "run.json"), (d / "infer.json").read_bytes(),
                        {p.name: p.read_bytes() for p in (d / "cache").iterdir()})
    assert len(files["bar"][2]) == 3
    assert files["bar"] == files["quiet"]


def test_nothing_from_progress_when_stderr_is_not_a_terminal(tmp_path, monkeypatch, capsys):
    """Pipes, logs and tests (stderr not a terminal) get no bar, and not the engine's own
    progress line either."""
    monkeypatch.chdir(tmp_path)
    assert main(run_argv()) == 0
    assert main(infer_argv()) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out.startswith("scene ens")


@pytest.fixture
def stub_runs(monkeypatch):
    """The warm-up's kernel runs replaced by nothing (what is tested is the bar around
    them, not the compile)."""
    def runs(runs=warmup.RUNS, done=None):
        for _ in runs:
            if done is not None:
                done(1)
    monkeypatch.setattr(warmup, "_warm_up_runs", runs)


@pytest.mark.parametrize("terminal, progress, bar", [(True, None, True), (True, False, False),
                                                     (False, None, False)])
def test_warm_up_progress(monkeypatch, stub_runs, terminal, progress, bar):
    """The warm-up counts its runs on a terminal's stderr (its log lines go around the
    bar); nothing off a terminal or with progress off."""
    err = Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    lines = []
    assert warmup.build(log=lines.append, aot=False, progress=progress) is None
    assert len(lines) == 1 and lines[0].startswith("granchain warm-up: JIT kernels")
    shown = err.getvalue()
    assert ("granchain warm-up" in shown and f"/{len(warmup.RUNS)} [" in shown) if bar \
        else shown == ""


def test_warm_up_command_passes_no_progress(monkeypatch):
    seen = []
    monkeypatch.setattr(warmup, "build", lambda **kw: seen.append(kw["progress"]))
    assert main(["warm-up", "--no-progress"]) == 0
    assert main(["warm-up"]) == 0
    assert seen == [False, None]


def test_a_run_off_a_terminal_does_not_load_tqdm():
    """Off a terminal the bar is a silent stand-in that takes a bar's calls: the process
    never imports tqdm and writes nothing."""
    import subprocess
    code = ("import sys\nfrom granchain.progress import bar\n"
            "with bar(3, 'x') as b:\n    b.update(2)\n"
            "    with b.external_write_mode(file=sys.stderr):\n        pass\n"
            "print('tqdm' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False", out
    assert out.stderr == ""
