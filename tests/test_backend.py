"""The ahead-of-time kernels (engines.backend): built for this machine, used for one-chain
runs without importing numba, and bit-identical to numba's JIT kernels."""
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from granchain.engines import backend, reference, warmup
from granchain.scene import load_scene

SCENES = "granchain/scenes"
METHODS = ({"method": "rk4", "dt": 1e-9}, {"method": "verlet", "dt": 1e-9},
           {"method": "adaptive", "tolerance": 1e-8}, {"method": "event", "tolerance": 1e-6})


@pytest.fixture(scope="module")
def aot_cache(tmp_path_factory):
    """A cache directory of its own with the ahead-of-time module built into it (the
    build compiles every entry point: slow)."""
    d = tmp_path_factory.mktemp("gc-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("GRANCHAIN_CACHE_DIR", str(d))
        backend.aot_module.cache_clear()
        try:
            path = warmup.build(log=lambda msg: None)
            assert path is not None and path.exists(), "numba.pycc did not build the module"
            yield d
        finally:
            backend.aot_module.cache_clear()
    backend.aot_module.cache_clear()


def _run(scene, gaps, serial, monkeypatch):
    real = backend.kernels
    monkeypatch.setattr(backend, "kernels", lambda serial_=None, **kw: real(serial))
    try:
        return list(reference.run(scene, gaps, np.full(gaps.shape[0], 0.1), progress=False,
                                  trace=scene.method == "event"))
    finally:
        monkeypatch.setattr(backend, "kernels", real)


@pytest.mark.slow
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


@pytest.mark.slow
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


# --- the module's name: a hash of everything the kernels are compiled from -------------
PKG = Path(backend.__file__).resolve().parents[1]
# scipy's file of Dormand-Prince 8(5,3) coefficients, where engines/codes.py reads DOP853 from
SCIPY = Path(importlib.util.find_spec("scipy").origin).parent
DOP853_FILE = Path("integrate", "_ivp", "dop853_coefficients.py")
# (file, text in it, replacement): one change of what the kernels compute, per source
EDITS = {
    "kernel": ("engines/kernels.py", "if wall else _detached(v_last, overlap_last, vthr)\n",
               "if wall else _detached(v_last, -overlap_last, vthr)\n"),
    "effect": ("effects/hertz.py", "return K * d * math.sqrt(d) if d > 0.0",
               "return 0.5 * K * d * math.sqrt(d) if d > 0.0"),
    "codes": ("engines/codes.py", "RB_SIZE = 48 ", "RB_SIZE = 47 "),
    "obsrules": ("obsrules.py", "PEAK_TOL = 1e-4 ", "PEAK_TOL = 2e-4 "),
    "compose": ("engines/compose.py", '"        best[l] = -1.0"', '"        best[l] = -2.0"'),
}


def _copy_package(root: Path) -> Path:
    shutil.copytree(PKG, root / "granchain", ignore=shutil.ignore_patterns("__pycache__"))
    return root / "granchain"


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert text.count(old) == 1, (path, old)
    path.write_text(text.replace(old, new))


def _in_copy(code: str, *pythonpath: Path) -> list[str]:
    """Run ``code`` in a new interpreter that imports granchain from ``pythonpath`` (run
    there: ``python -c`` puts its working directory first on sys.path)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(map(str, pythonpath)))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       cwd=pythonpath[0])
    assert p.returncode == 0, p.stderr
    return p.stdout.split()


def _module_name_in(*pythonpath: Path) -> str:
    where, name = _in_copy("import granchain\nfrom granchain.engines import backend\n"
                           "print(granchain.__file__, backend.module_name())", *pythonpath)
    assert Path(where).parent == pythonpath[0] / "granchain", where
    return name


@pytest.mark.parametrize("what", list(EDITS))
def test_module_name_and_jit_cache_folder_change_with_every_compiled_source(what, tmp_path):
    # a module built from other sources has another name: it is simply not found. And
    # numba keys its cache by the stamp of the kernel's own file only: the kernels inline
    # the effects' laws and freeze codes/obsrules constants, so an edit in any of them
    # must move the JIT cache to another folder, or old machine code would run
    rel, old, new = EDITS[what]
    pkg = _copy_package(tmp_path)
    code = ("import granchain\nfrom granchain.engines import backend\n"
            "print(granchain.__file__, backend.module_name(), backend.jit_cache_dir().name)")
    where, name, folder = _in_copy(code, tmp_path)
    assert Path(where).parent == pkg, where
    _edit(pkg / rel, old, new)
    _, name2, folder2 = _in_copy(code, tmp_path)
    assert name2 != name
    assert folder2 != folder and folder2.startswith("granchain-jit-")


def test_the_jit_kernels_cache_into_the_hashed_folder():
    from granchain.engines import compose, events, kernels
    folder = str(backend.jit_cache_dir())
    # the composed physics and an effect's compiled law too
    law = next(iter(compose._DISPATCHERS.values()))
    for disp in (kernels.forces, kernels.run_blocks, compose.effect_forces, law,
                 events.run_events):
        assert disp._cache._cache_path.startswith(folder + os.sep), disp


def test_module_name_changes_with_the_dop853_tableau(tmp_path):
    # the coefficients come from scipy's file: a scipy whose file differs by one
    # coefficient gives another module
    pkg, fake = tmp_path / "pkg", tmp_path / "scipy-root"
    _copy_package(pkg)
    before = _module_name_in(pkg)
    dst = fake / "scipy" / DOP853_FILE
    dst.parent.mkdir(parents=True)
    (fake / "scipy" / "__init__.py").write_text("")
    dst.write_bytes((SCIPY / DOP853_FILE).read_bytes())
    _edit(dst, "A[1, 0] = 5.26001519587677318785587544488e-2", "A[1, 0] = 5.26e-2")
    a10, = _in_copy("from granchain.engines import codes\nprint(float(codes.DOP_A[1, 0]))",
                    pkg, fake)
    assert float(a10) == 5.26e-2         # the engine reads the changed file
    assert _module_name_in(pkg, fake) != before


def test_module_name_ignores_code_the_kernels_do_not_import(tmp_path):
    pkg = _copy_package(tmp_path)
    before = _module_name_in(tmp_path)
    _edit(pkg / "figures" / "style.py", '"savefig.dpi": 150,', '"savefig.dpi": 151,')
    assert _module_name_in(tmp_path) == before


def test_module_name_changes_with_every_module_the_kernels_load(tmp_path):
    # every module of the package that importing the kernels runs, changed in turn (a line
    # appended) in a copy of the package, gives another name
    pkg = _copy_package(tmp_path)
    code = """
import sys
from pathlib import Path
import granchain.engines.kernels, granchain.engines.events
from granchain import fileio
from granchain.engines import backend
loaded = sorted(m.__file__ for m in list(sys.modules.values())
                if m.__name__.split(".")[0] == "granchain" and m.__name__ not in
                ("granchain.engines.backend", "granchain.fileio"))
base = backend.module_name()
for f in loaded:
    text = Path(f).read_text()
    Path(f).write_text(text + "\\n# changed\\n")
    for cached in (backend.module_name, backend.kernel_sources, fileio.source_hash):
        if hasattr(cached, "cache_clear"):
            cached.cache_clear()
    print(Path(f).relative_to(Path(granchain.__file__).parent), base != backend.module_name())
    Path(f).write_text(text)
"""
    out = _in_copy(code, tmp_path)
    changed = dict(zip(out[::2], out[1::2]))
    assert {"engines/kernels.py", "engines/events.py", "engines/codes.py",
            "effects/hertz.py", "stoprule.py"} <= set(changed)
    assert [f for f, c in changed.items() if c != "True"] == []


def test_kept_list_of_kernel_sources_follows_an_added_import(tmp_path, monkeypatch):
    """The list of the kernels' sources kept between processes is the parsed one, and a
    kernel module that gains an import of another module of the package gets a list with
    that module in the next process (the kept list is not reused)."""
    pkg = _copy_package(tmp_path)
    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path / "cache"))
    code = ("from granchain.engines import backend\n"
            "kept = backend.kernel_sources()\n"
            "print(int(kept == backend._kernel_sources()), int('progress.py' in kept))")
    assert _in_copy(code, tmp_path) == ["1", "0"]
    assert _in_copy(code, tmp_path) == ["1", "0"]           # read back from the kept list
    assert len(list((tmp_path / "cache" / "kernel-sources").iterdir())) == 1
    text = (pkg / "engines" / "codes.py").read_text()
    (pkg / "engines" / "codes.py").write_text(text + "\nfrom .. import progress  # noqa\n")
    assert _in_copy(code, tmp_path) == ["1", "1"]


@pytest.mark.parametrize("method", sorted({m for m, _ in warmup.RUNS}))
def test_every_warm_up_scene_is_valid_with_every_effect_it_can_hold(method):
    """Each warm-up run's scene validates, with every registered effect on but those set
    apart (the kernels compile their laws all the same). Fails on a build whose warm-up
    turned on every registered effect, which a law that refuses another made impossible."""
    from granchain.effects import MODULES
    scene = warmup.warm_up_scene(method)
    apart = {m.SPEC.name for m in MODULES if hasattr(m, "WARM_UP_APART")}
    assert set(scene.effects) == {m.SPEC.name for m in MODULES} - apart
    assert scene.method == method and len(apart) < len(MODULES) // 2


_ONE_THREAD_RUN = r"""
import json, pickle, sys
import numpy as np
from granchain.engines import reference
from granchain.scene import load_scene
inp = np.load(sys.argv[1])
out = []
for integ in json.loads(sys.argv[4]):
    scene = load_scene(sys.argv[2]).derive(integrator=integ, effects=json.loads(sys.argv[5]),
                                           rolling={"k_roll": 1e3})
    out.append([(t.status, t.steps, t.v, t.energy) for t in
                reference.run(scene, inp["gaps"], inp["vs"], progress=False, trace=False)])
pickle.dump((out, "numba" in sys.modules), open(sys.argv[3], "wb"))
"""


@pytest.mark.slow
def test_a_run_on_one_thread_takes_the_module_bit_identical_to_jit_threads(aot_cache, tmp_path,
                                                                          monkeypatch):
    """Six chains of every method on one thread (NUMBA_NUM_THREADS=1) run the ahead-of-time
    module (numba never imported) and give numba's parallel JIT kernels' results in this
    process bit for bit."""
    import pickle
    scene_file = f"{SCENES}/gaps-20nm-440c.yaml"
    effects = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction",
               "rolling_friction"]
    base = load_scene(scene_file)
    gaps = np.random.default_rng(9).uniform(0, 40e-9, (6, base.n - 1))
    vs = np.linspace(0.05, 0.3, 6)
    np.savez(tmp_path / "in.npz", gaps=gaps, vs=vs)
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(aot_cache), NUMBA_NUM_THREADS="1")
    subprocess.run([sys.executable, "-c", _ONE_THREAD_RUN, str(tmp_path / "in.npz"), scene_file,
                    str(tmp_path / "out.pkl"), json.dumps(METHODS), json.dumps(effects)],
                   env=env, check=True)
    got, numba_loaded = pickle.loads((tmp_path / "out.pkl").read_bytes())
    assert not numba_loaded
    real = backend.kernels
    monkeypatch.setattr(backend, "kernels", lambda serial: real(False))     # the JIT's threads
    from granchain.engines import forked
    monkeypatch.setattr(forked, "usable", lambda *a: False)
    for integ, a in zip(METHODS, got):
        scene = base.derive(integrator=integ, effects=effects, rolling={"k_roll": 1e3})
        b = list(reference.run(scene, gaps, vs, progress=False, trace=False))
        assert len(a) == len(b) == 6
        for x, y in zip(a, b):
            assert x[0] == y.status and x[1] == y.steps, integ
            assert np.array_equal(x[2], y.v) and np.array_equal(x[3], y.energy), integ


@pytest.mark.slow
def test_warm_up_again_with_the_module_built(aot_cache):
    # a second warm-up (another workflow run, a new process) finds the module built and
    # succeeds without compiling anything: the module runs ensembles too (forked)
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(aot_cache))
    out = subprocess.run([sys.executable, "-m", "granchain.cli", "warm-up"], capture_output=True,
                         text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert "already built" in out.stderr and "JIT" not in out.stderr, out.stderr


@pytest.mark.slow
def test_warm_up_in_two_processes_builds_the_module_in_parts(tmp_path):
    """On two threads the warm-up builds the module's parts in two processes at once; the
    engine loads them as one module and a run takes it without importing numba."""
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(tmp_path), NUMBA_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-m", "granchain.cli", "warm-up"], capture_output=True,
                         text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert "(2 processes)" in out.stderr and "JIT" not in out.stderr, out.stderr
    built = sorted(p.name.split(".")[0].rsplit("_", 1)[1] for p in (tmp_path / "aot").iterdir()
                   if p.suffix == ".so")
    assert built == [f"p{k}" for k in range(len(backend.AOT_PARTS))], built
    code = ("import sys\n"
            "from granchain.engines import backend\n"
            "m = backend.aot_module()\n"
            "print(sorted(e for e in backend.ENTRY_POINTS if callable(getattr(m, e, None))) =="
            " sorted(backend.ENTRY_POINTS), 'numba' in sys.modules)\n")
    got = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout.split()
    assert got == ["True", "False"]


@pytest.mark.slow
def test_warm_up_in_two_processes_covers_every_entry_point(tmp_path):
    """The JIT warm-up's tasks (where no ahead-of-time module is built), taken by two
    processes at once, reach every entry point between them: a numba cache filled only by
    them holds an entry for each, and this process then loads each one from it with a
    single signature, the argument types ``warmup.record_signatures`` finds without
    compiling (what the ahead-of-time module is built from).
    A cold compile: about 3 minutes on 2 busy cores."""
    assert sorted(r for t in warmup.TASKS for r in t) == sorted(warmup.RUNS)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               GRANCHAIN_CACHE_DIR=str(tmp_path / "granchain"), NUMBA_NUM_THREADS="2")
    code = ("from granchain.engines import warmup, backend\n"
            "warmup.warm_jit(2)\n"
            "print(backend.aot_available())\n"
            "print(sorted(e for e in backend.ENTRY_POINTS\n"
            "             if len(backend.jit_entry(e).nopython_signatures) != 1))\n"
            "rec = warmup.record_signatures()\n"
            "print(sorted(e for e in backend.ENTRY_POINTS\n"
            "             if rec[e] != backend.jit_entry(e).nopython_signatures[0].args))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    # one signature of each, and the types recorded without compiling (what the
    # ahead-of-time module is built from) are those numba compiled
    assert out.stdout.split("\n")[:3] == ["False", "[]", "[]"]
    cached = {p.name.split(".")[1].split("-")[0] for p in (tmp_path / "numba").rglob("*.nbi")}
    assert set(backend.ENTRY_POINTS) <= cached, set(backend.ENTRY_POINTS) - cached


# --- the kernels' parallel loops in forked workers ----------------------------------------
def test_forked_cuts_name_the_kernels_own_arguments():
    """Each parallel entry point's argument names (what its cut is written in) are the
    kernel's own, in order; the cut names only them, and never writes what it only
    reads."""
    import inspect

    from granchain.engines import forked
    assert set(forked.CUTS) == set(forked.ARGS) == {
        e for e in backend.ENTRY_POINTS if e.startswith("run_")}
    for name, names in forked.ARGS.items():
        assert names == tuple(inspect.signature(backend.jit_entry(name).py_func).parameters)
        cut = forked.CUTS[name]
        assert set(cut.items + cut.lanes + cut.written) <= set(names), name
        assert not {"VTHR", "gaps", "NT", "t_stop", "P", "FL", "LO"} & set(cut.written), name


def _fake_args(name, items, lanes=4, chains=None):
    """``name``'s arguments with the shapes of a call whose parallel loop has ``items``
    items: item arrays (items, 3, lanes) for the block kernel, else (items, 2); per-lane
    arrays (items * lanes, 2); the rest (chains, 2) (``run_events_lanes``'s queues name
    rows of them), or one zero."""
    from granchain.engines import forked
    cut = forked.CUTS[name]
    args = []
    for a in forked.ARGS[name]:
        if a == "QUEUE":
            args.append(np.full((items, chains), -1, dtype=np.int64))
        elif a == "QLEN":
            args.append(np.zeros(items, dtype=np.int64))
        elif a in cut.items:
            args.append(np.zeros((items, 3, lanes) if cut.lanes else (items, 2)))
        elif a in cut.lanes:
            args.append(np.zeros((items * lanes, 2)))
        elif a in cut.written:
            args.append(np.zeros((chains or 1, 2)))
        else:
            args.append(np.zeros(1))
    if name == "run_events_lanes":          # chain b in queue b % items
        at = forked.ARGS[name].index
        Q, QL = args[at("QUEUE")], args[at("QLEN")]
        for b in range(chains):
            Q[b % items, QL[b % items]] = b
            QL[b % items] += 1
    return tuple(args)


class _Marks:
    """A stand-in module whose entry points mark every item, lane or queued chain they
    were given with the process that ran them (and fail in the workers when told to)."""
    def __init__(self, fail_in_worker=False):
        self.parent, self.fail = os.getpid(), fail_in_worker

    def __getattr__(self, name):
        from granchain.engines import forked
        cut, at = forked.CUTS[name], forked.ARGS[name].index

        def run(*a):
            if self.fail and os.getpid() != self.parent:
                raise RuntimeError("worker failed")
            if name == "run_events_lanes":
                Q, QL = a[at("QUEUE")], a[at("QLEN")]
                rows = [int(b) for k in range(Q.shape[0]) for b in Q[k, :QL[k]]]
            for x in cut.written:
                if x in cut.items or x in cut.lanes:
                    a[at(x)][...] = os.getpid()
                else:
                    a[at(x)][rows] = os.getpid()
        return run


@pytest.mark.parametrize("name", ["run_blocks", "run_adaptive", "run_events",
                                  "run_events_lanes"])
def test_forked_calls_cover_every_item_once_in_numbas_schedule(name):
    from granchain.engines import forked
    cut, at = forked.CUTS[name], forked.ARGS[name].index
    for items, workers in ((2, 2), (5, 2), (16, 2), (7, 3)):
        args = _fake_args(name, items, chains=3 * items + 1)
        assert forked.call(name, _Marks().__getattr__(name), args, workers)
        if name == "run_events_lanes":
            Y = args[at("Y")][:, 0]
            Q = args[at("QUEUE")]
            owner = [Y[Q[k, 0]] for k in range(items)]
        else:
            owner = args[at(cut.items[0])].reshape(items, -1)[:, 0]
        pids = list(dict.fromkeys(owner))
        assert len(pids) == min(workers, items) and os.getpid() == pids[0]
        # contiguous shares, one more item for each of the first items % workers
        sizes = [int(sum(o == p for o in owner)) for p in pids]
        assert sizes == [items // workers + (t < items % workers) for t in range(workers)]
        for x in cut.written:                   # each written by its item's process
            got = args[at(x)].reshape(args[at(x)].shape[0], -1)[:, 0]
            if x in cut.items:
                assert np.array_equal(got, owner), (name, x)
            elif x in cut.lanes:
                assert np.array_equal(got, np.repeat(owner, 4)), (name, x)
            else:
                assert np.array_equal(got, [owner[b % items] for b in range(len(got))])
        for x in set(cut.items + cut.lanes) - set(cut.written) - {"QUEUE", "QLEN"}:
            assert not args[at(x)].any(), (name, x)        # read, not written back


@pytest.mark.parametrize("name", ["run_blocks", "run_events_lanes"])
def test_a_failed_worker_leaves_the_arrays_untouched(name):
    from granchain.engines import forked
    args = _fake_args(name, 4, chains=9)
    assert not forked.call(name, _Marks(fail_in_worker=True).__getattr__(name), args, 2)
    at = forked.ARGS[name].index
    assert not any(args[at(x)].any() for x in forked.CUTS[name].written)


_FORKED_RUN = """
import json, sys, pickle
import numpy as np
from granchain.engines import forked, reference
from granchain.scene import load_scene
taken = []
real = forked.call
def call(name, *a):
    taken.append((name, real(name, *a)))
    return taken[-1][1]
forked.call = call
d = np.load(sys.argv[1])
out = []
for integ, trace in json.loads(sys.argv[4]):
    scene = load_scene(sys.argv[2]).derive(
        integrator=integ, rolling={"k_roll": 1e3},
        effects=["hertz", "groove_friction", "air_drag", "rotation", "particle_friction",
                 "rolling_friction"])
    out.append([(t.status, t.steps, t.v, t.energy)
                + ((t.observed.v_max, t.observed.t_peak, t.observed.t_front)
                   if t.observed is not None else ())
                for t in reference.run(scene, d["gaps"], d["vs"], progress=False, trace=trace)])
pickle.dump((out, taken, "numba" in sys.modules), open(sys.argv[3], "wb"))
"""


@pytest.mark.slow
def test_forked_kernels_bit_identical_to_jit_threads(aot_cache, tmp_path, monkeypatch):
    """Chains of every effect by every method, traced and measured on the fly, in a process
    that has not loaded numba: the ahead-of-time kernels in two forked workers (the path
    taken, numba never imported) give numba's two threads' results in this process bit
    for bit."""
    import pickle
    scene_file = f"{SCENES}/gaps-20nm-440c.yaml"
    runs = [(m, trace) for m in METHODS for trace in (False, True)]
    gaps = np.random.default_rng(5).uniform(0, 40e-9, (70, load_scene(scene_file).n - 1))
    vs = np.where(np.arange(70) < 40, 0.1, 0.2)    # two sample intervals, each > 1 block
    np.savez(tmp_path / "in.npz", gaps=gaps, vs=vs)
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(aot_cache), NUMBA_NUM_THREADS="2")
    subprocess.run([sys.executable, "-c", _FORKED_RUN, str(tmp_path / "in.npz"), scene_file,
                    str(tmp_path / "out.pkl"), json.dumps(runs)], env=env, check=True)
    got, taken, numba_loaded = pickle.loads((tmp_path / "out.pkl").read_bytes())
    assert not numba_loaded and all(ok for _, ok in taken)
    assert {n for n, _ in taken} == {"run_blocks", "run_adaptive", "run_events",
                                     "run_events_lanes"}
    monkeypatch.setattr(backend, "num_threads", lambda: 2)
    from granchain.engines import forked
    monkeypatch.setattr(forked, "usable", lambda *a: False)     # numba's threads here
    for (integ, trace), a in zip(runs, got):
        scene = load_scene(scene_file).derive(
            integrator=integ, rolling={"k_roll": 1e3},
            effects=["hertz", "groove_friction", "air_drag", "rotation", "particle_friction",
                     "rolling_friction"])
        b = list(reference.run(scene, gaps, vs, progress=False, trace=trace))
        assert len(a) == len(b) == 70
        for x, y in zip(a, b):
            assert x[0] == y.status == "passed" and x[1] == y.steps, (integ, trace)
            assert np.array_equal(x[2], y.v) and np.array_equal(x[3], y.energy), (integ, trace)
            obs = () if y.observed is None else (y.observed.v_max, y.observed.t_peak,
                                                 y.observed.t_front)
            assert len(x[4:]) == len(obs)
            for u, f in zip(x[4:], obs):
                assert np.array_equal(u, f, equal_nan=True), (integ, trace)


@pytest.mark.slow
def test_many_chain_run_on_two_cores_imports_no_numba(aot_cache):
    code = ("import sys, io, contextlib\n"
            "from granchain.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    rc = main(['run', '{SCENES}/gaps-20nm-440c.yaml', '--json', '--set',"
            " 'ensemble.realisations=80', '--set', 'integrator.method=verlet'])\n"
            "print(rc, 'numba' in sys.modules)\n")
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(aot_cache), NUMBA_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout.split()
    assert out == ["0", "False"]


def test_a_one_thread_job_runs_one_thread_without_importing_numba():
    """A workflow job's ``threads: 1`` (``workflow.set_threads``) reaches the engine as one
    thread before numba is loaded, so its calls take the ahead-of-time module."""
    code = ("import sys\n"
            "from granchain.workflow.run import set_threads\n"
            "from granchain.engines import backend\n"
            "set_threads(1)\n"
            "print(backend.num_threads(), 'numba' in sys.modules)\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout.split()
    assert out == ["1", "False"]
