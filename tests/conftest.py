"""Shared fixtures, and what every test session sets up before anything runs:

- one temporary cache directory (``GRANCHAIN_CACHE_DIR``) for the session: the compiled
  kernels' ahead-of-time module and the LAMMPS plugin go there, never to ~/.cache;
  subprocesses (snakemake, its jobs, SLURM jobs) inherit it. numba's JIT cache stays in
  the package's ``__pycache__`` (warm from earlier sessions).
- markers by what a test runs, from the fixtures it uses (``END_TO_END``): a test cannot
  use a snakemake run without being deselected by ``-m "not workflow"``.
"""
import dataclasses
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from granchain.scene import load_scene, scene_from_dict
from granchain.simulate import run_scene

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "granchain" / "scenes"

# fixture -> the markers every test using it (directly or through another fixture) gets
END_TO_END = {
    "tiny_run": ("workflow", "lammps", "slow"),          # tiny runs lammps_check on LAMMPS too
    "tiny_lammps_run": ("workflow", "lammps", "slow"),
    "slurm_cluster": ("slurm", "slow"),
}
_SESSION_CACHE = "_granchain_session_cache"


def pytest_configure(config):
    """Point GRANCHAIN_CACHE_DIR at a fresh directory for this session, before any test
    module is imported or anything is built."""
    d = tempfile.mkdtemp(prefix="granchain-test-cache-")
    setattr(config, _SESSION_CACHE, (d, os.environ.get("GRANCHAIN_CACHE_DIR")))
    os.environ["GRANCHAIN_CACHE_DIR"] = d


def pytest_unconfigure(config):
    d, old = getattr(config, _SESSION_CACHE, (None, None))
    if d is None:
        return
    if old is None:
        os.environ.pop("GRANCHAIN_CACHE_DIR", None)
    else:
        os.environ["GRANCHAIN_CACHE_DIR"] = old
    shutil.rmtree(d, ignore_errors=True)


def pytest_collection_modifyitems(config, items):
    for item in items:
        have = {m.name for m in item.iter_markers()}
        for fixture, marks in END_TO_END.items():
            if fixture in getattr(item, "fixturenames", ()):
                for m in marks:
                    if m not in have:
                        item.add_marker(m)
                        have.add(m)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    # the running test's markers, for helpers that start snakemake or SLURM runs
    import slurm_support
    slurm_support.RUNNING_TEST_MARKS = {m.name for m in item.iter_markers()}


def pytest_runtest_teardown(item):
    import slurm_support
    slurm_support.RUNNING_TEST_MARKS = None


@pytest.fixture(scope="session")
def session_cache_dir():
    """This session's GRANCHAIN_CACHE_DIR."""
    return Path(os.environ["GRANCHAIN_CACHE_DIR"])


@pytest.fixture(scope="session")
def repo():
    return REPO


def packed(**over):
    """The chapter's packed 440C chain, Hertz only, with overrides as dotted keys."""
    raw = {"name": "t", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
           "striker": {"velocity": 0.1}, "effects": ["hertz"], "probes": [2, 13],
           "integrator": {"method": "rk4", "dt": 1e-9}}
    from granchain.scene import apply_overrides
    if "chain.materials" in over:
        del raw["material"]                  # the list gives every sphere's material
    return scene_from_dict(apply_overrides(raw, [f"{k}={v}" for k, v in over.items()]))


def pair(**over):
    """Two spheres, for kernel-level tests. A scene needs n >= 3 (the striker and two
    probes from 2 to n), so this is a valid 3-sphere scene cut to its first two spheres,
    with probes (1, 2) that no scene may give."""
    sc = packed(**{"chain.n": 3, "probes": "[2, 3]", **over})
    return dataclasses.replace(sc, n=2, probes=(1, 2), radii=sc.radii[:2],
                               materials=sc.materials[:2])


def run1(scene, **kw):
    return run_scene(scene, **kw)[0]


def write(tmp_path: Path, text: str, name: str = "s.yaml") -> str:
    """Write ``text`` to ``tmp_path / name``; its path."""
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def refused(capsys, argv, *needles) -> str:
    """Run the CLI: exit 2, exactly one line on stderr holding every needle (e.g. the
    field it names), no traceback; that line."""
    from granchain.cli import main
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err
