"""The ahead-of-time kernels (engines.backend): built for this machine, used for one-chain
runs without importing numba, and bit-identical to numba's JIT kernels."""
import os
import subprocess
import sys

import numpy as np
import pytest

from granchain.engines import backend, reference, warmup
from granchain.scene import load_scene

SCENES = "granchain/scenes"
METHODS = ({"method": "rk4", "dt": 1e-9}, {"method": "verlet", "dt": 1e-9},
           {"method": "adaptive", "tolerance": 1e-8}, {"method": "event", "tolerance": 1e-6})


@pytest.fixture(scope="module")
def aot_cache(tmp_path_factory):
    d = tmp_path_factory.mktemp("gc-cache")
    old = os.environ.get("GRANCHAIN_CACHE_DIR")
    os.environ["GRANCHAIN_CACHE_DIR"] = str(d)
    backend.aot_module.cache_clear()
    try:
        path = warmup.build(log=lambda msg: None)
        assert path is not None and path.exists(), "numba.pycc did not build the module"
        yield d
    finally:
        if old is None:
            del os.environ["GRANCHAIN_CACHE_DIR"]
        else:
            os.environ["GRANCHAIN_CACHE_DIR"] = old
        backend.aot_module.cache_clear()


def _run(scene, gaps, serial, monkeypatch):
    real = backend.kernels
    monkeypatch.setattr(backend, "kernels", lambda serial_=None, **kw: real(serial))
    try:
        return list(reference.run(scene, gaps, np.full(gaps.shape[0], 0.1), progress=False,
                                  trace=scene.method == "event"))
    finally:
        monkeypatch.setattr(backend, "kernels", real)


@pytest.mark.parametrize("integ", METHODS, ids=lambda i: i["method"])
def test_aot_kernels_bit_identical_to_jit(aot_cache, integ, monkeypatch):
    scene = load_scene(f"{SCENES}/gaps-20nm-440c.yaml").derive(
        integrator=integ, effects=["hertz", "groove_friction", "air_drag", "rotation",
                                   "particle_friction", "rolling_friction"],
        rolling={"k_roll": 1e3})
    gaps = np.random.default_rng(3).uniform(0, 40e-9, (1, scene.n - 1))
    assert backend.aot_available()
    assert isinstance(backend.kernels(serial=True)._aot, type(sys)), "AOT module not used"
    (a,), (b,) = _run(scene, gaps, True, monkeypatch), _run(scene, gaps, False, monkeypatch)
    assert a.status == b.status == "passed"
    assert a.steps == b.steps and a.force_evaluations == b.force_evaluations
    assert np.array_equal(a.v, b.v) and np.array_equal(a.energy, b.energy)


def test_one_chain_run_imports_no_numba(aot_cache):
    code = ("import sys, io, contextlib\n"
            "from granchain.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    rc = main(['run', '{SCENES}/packed-440c.yaml', '--json'])\n"
            "print(rc, 'numba' in sys.modules)\n")
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(aot_cache))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout.split()
    assert out == ["0", "False"]


def test_stale_module_is_not_loaded(aot_cache, tmp_path, monkeypatch):
    # a module built from other sources has another name: it is simply not found
    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path))
    (tmp_path / "aot").mkdir()
    for f in (aot_cache / "aot").iterdir():
        (tmp_path / "aot" / f.name.replace(backend.module_name(), "granchain_kernels_0000")
         ).write_bytes(f.read_bytes())
    backend.aot_module.cache_clear()
    try:
        assert not backend.aot_available()
        assert backend.kernels(serial=True)._aot is None
    finally:
        backend.aot_module.cache_clear()


def test_warm_up_again_with_the_module_built(aot_cache):
    # a second warm-up (another workflow run, a new process) finds the module built: its
    # small runs must still compile the JIT kernels for ensembles, and it must succeed
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(aot_cache))
    out = subprocess.run([sys.executable, "-m", "granchain.cli", "warm-up"], capture_output=True,
                         text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert "already built" in out.stderr
