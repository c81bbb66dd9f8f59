"""Compile the reference engine's kernels for this machine (``granchain warm-up``; the
workflow's ``jit_cache`` rule, then its ``aot_kernels`` rule): numba's JIT cache, then the
ahead-of-time module that ``engines.backend`` loads for serial calls."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from .backend import ENTRY_POINTS, aot_module, jit_entry, aot_available, cache_dir, module_name

# The warm-up runs: (method, trace). Each compiles (or loads) the entry points it reaches:
# the fixed-step blocks, the adaptive method's window, the event method in lanes, and with
# a trace the event method's one-chain kernel.
RUNS = (("rk4", False), ("verlet", False), ("adaptive", False), ("event", True),
        ("event", False))
# The runs as the worker processes take them (:func:`warm_jit`): each worker takes the
# next task no other has taken as it comes free, the longest compiles first, so that the
# workers end close together whatever the shares. rk4 and verlet are one task: the block
# driver compiles both methods at once (verlet after rk4 costs nothing).
TASKS = ((("event", False),), (("event", True),), (("rk4", False), ("verlet", False)),
         (("adaptive", False),))


def warm_up_scene(method: str):
    """The scene of a warm-up run of ``method``: a small gapped chain with every registered
    effect on but those whose module sets ``WARM_UP_APART`` (the reason it cannot act with
    the others); the sections an effect needs given come from its ``WARM_UP`` (beside the
    damping model every other effect allows). The composed kernels hold every effect's law
    whichever effects a scene turns on (their flags switch them at run time), so the
    effects left apart are compiled all the same."""
    from ..effects import MODULES
    from ..scene import scene_from_dict
    raw = {"name": "warm-up", "material": "ss440c", "chain": {"n": 4, "radius": 150e-6},
           "striker": {"velocity": 0.1}, "gaps": {"distribution": "fixed", "mean": 5e-9},
           "effects": [m.SPEC.name for m in MODULES if not hasattr(m, "WARM_UP_APART")],
           "rolling": {"k_roll": 1e3}, "damping": {"model": "viscoelastic", "eta": 1e3},
           "probes": [2, 3], "t_end": 2e-7,
           **{m.SECTION: dict(m.WARM_UP) for m in MODULES if hasattr(m, "WARM_UP")}}
    integ = {"method": method, "dt": 1e-9}
    if method not in ("rk4", "verlet"):
        integ["tolerance"] = 1e-6
    return scene_from_dict({**raw, "integrator": integ})


def _warm_up_run(method: str, trace: bool) -> None:
    """Two small chains of :func:`warm_up_scene` through the reference engine."""
    import numpy as np

    from . import reference
    scene = warm_up_scene(method)
    # two chains: a call over one chain (or on one thread) runs the ahead-of-time module
    # if it is built, and the JIT kernels would stay uncompiled
    gaps = np.full((2, scene.n - 1), 5e-9)
    list(reference.run(scene, gaps, np.array([0.1, 0.1]), progress=False, trace=trace))


def _warm_up_runs(runs=RUNS, done=None) -> None:
    """The warm-up runs (:func:`_warm_up_run`); ``done(1)`` after each, if given."""
    for method, trace in runs:
        _warm_up_run(method, trace)
        if done is not None:
            done(1)


class _Recorded(Exception):
    """Raised by :class:`_Recorder` once a warm-up run has reached its last entry point."""


# The entry points after which a recording run goes on to the others it calls (the event
# method in lanes, then energies and finalize per chain); any other call ends it.
_GO_ON = ("run_events_lanes", "energies")


class _Recorder:
    """Stands in for ``backend.kernels(...)`` during :func:`record_signatures`: each call of
    an entry point records the numba types of its arguments and runs nothing. A driver of
    :data:`_GO_ON` finds its chains stopped (its ``STATUS`` argument set to done), so the
    run goes on to the entry points it calls next; any other call ends the run."""

    def __init__(self, seen: dict):
        self._seen = seen

    def __getattr__(self, name: str):
        from .backend import ENTRY_POINTS, jit_entry
        if name not in ENTRY_POINTS:
            raise AttributeError(name)
        import inspect

        from numba import typeof

        from . import codes
        params = list(inspect.signature(jit_entry(name).py_func).parameters)

        def call(*args):
            self._seen.setdefault(name, set()).add(tuple(typeof(a) for a in args))
            if name not in _GO_ON:
                raise _Recorded(name)
            if "STATUS" in params:
                args[params.index("STATUS")][...] = codes.S_DONE
        return call


def record_signatures(runs=RUNS) -> dict:
    """The argument types each entry point of ``backend.ENTRY_POINTS`` is called with by
    the warm-up runs, found without compiling any of them: the runs go through the engine
    with :class:`_Recorder` in place of the kernels. Returns {entry point: argument types};
    refuses (RuntimeError) an entry point called with two sets of types or never called
    (the ahead-of-time module exports one signature of each)."""
    from . import backend
    seen: dict = {}
    real = backend.kernels
    backend.kernels = lambda serial: _Recorder(seen)
    try:
        for method, trace in runs:
            try:
                _warm_up_run(method, trace)
            except _Recorded:
                pass
    finally:
        backend.kernels = real
    bad = {e: len(seen.get(e, ())) for e in backend.ENTRY_POINTS if len(seen.get(e, ())) != 1}
    if bad:
        raise RuntimeError(f"the warm-up runs called the entry points {bad} times with "
                           "different types; the engine must call each with one set of types")
    return {e: next(iter(seen[e])) for e in backend.ENTRY_POINTS}


# The task of building the ahead-of-time module, the first the workers take when they build
# it beside the JIT kernels (:func:`warm_jit` with ``aot``).
AOT = "aot"


def _tasks(aot: bool) -> tuple:
    """The workers' tasks: :data:`TASKS`, after :data:`AOT` with ``aot``."""
    return (AOT,) + TASKS if aot else TASKS


def _take_tasks(claims: str, aot: bool = False) -> None:
    """A warm-up worker: the tasks of :func:`_tasks` in turn that no other worker has taken
    (a worker takes task k by creating ``claims/k.taken``, which only one can), each
    marked ``claims/k.done`` once run (the :data:`AOT` task's log line in
    ``claims/aot.log``)."""
    for k, task in enumerate(_tasks(aot)):
        try:
            os.close(os.open(os.path.join(claims, f"{k}.taken"),
                             os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            continue
        if task == AOT:
            _build_aot(Path(claims, "aot.log").write_text, _pycc(), lambda k: None)
        else:
            _warm_up_runs(task)
        Path(claims, f"{k}.done").touch()


def warm_jit(workers: int = 1, done=None, aot: bool = False) -> str | None:
    """Compile the JIT kernels into numba's cache (or load them from it): with workers > 1,
    that many processes at once take the tasks of :func:`_tasks` as they come free (each
    compiles what its runs reach; numba writes each cache entry atomically), then this
    process loads them all from the cache. With ``aot`` (and workers > 1) the first task
    builds the ahead-of-time module (:func:`_build_aot`), whose log line is returned.
    ``done(k)`` as k of :data:`RUNS` are compiled, and 1 for the module (a progress bar's
    ``update``), if given."""
    import subprocess
    import tempfile
    if workers <= 1:
        _warm_up_runs(done=done)
        return None
    tasks = _tasks(aot)
    with tempfile.TemporaryDirectory(prefix="granchain-warm-up-") as claims:
        code = (f"from granchain.engines.warmup import _take_tasks; "
                f"_take_tasks({claims!r}, {bool(aot)!r})")
        procs = [subprocess.Popen([sys.executable, "-c", code])
                 for _ in range(min(workers, len(tasks)))]
        counted = set()
        while True:
            alive = any(p.poll() is None for p in procs)
            for k, task in enumerate(tasks):
                if k not in counted and Path(claims, f"{k}.done").exists():
                    counted.add(k)
                    if done is not None:
                        done(1 if task == AOT else len(task))
            if not alive:
                break
            time.sleep(0.2)
        bad = [p.returncode for p in procs]
        logged = Path(claims, "aot.log").read_text() if aot and not any(bad) else None
    if any(bad) or len(counted) < len(tasks):
        raise RuntimeError(f"a warm-up process failed (exit codes {bad})")
    aot_module.cache_clear()
    _warm_up_runs()
    return logged


def _pycc():
    """numba.pycc's CC, or None where numba no longer has it."""
    try:
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from numba.pycc import CC
    except ImportError:
        return None
    return CC


def build(log=print, workers: int = 1, aot: bool = True, progress: bool | None = None,
          jit: bool | None = None) -> Path | None:
    """With ``aot``, compile the ahead-of-time module for this machine; with ``jit``, warm
    numba's JIT cache (in ``workers`` processes at once, :func:`warm_jit`). Returns the
    module's path (None if numba.pycc is not available or ``aot`` is off).

    The ahead-of-time module runs every call that does not run chains in parallel (one
    chain, or one thread: ``backend.kernels``), so only a process that runs on more threads
    needs the JIT kernels: ``jit`` None warms them when ``workers`` > 1, or when there is
    no numba.pycc. The module is built from the types the warm-up runs call the entry
    points with (:func:`record_signatures`, nothing compiled for them). Without the JIT
    kernels it is all the warm-up compiles; with them on ``workers`` > 1 it is the first
    task the worker processes take (:func:`warm_jit`), the JIT kernels the others.

    ``progress``: a bar on stderr counting the warm-up runs and the ahead-of-time module
    (``granchain.progress``; None: when stderr is a terminal); ``log``'s lines are written
    around it."""
    from ..progress import bar
    cc = _pycc() if aot else None
    if jit is None:
        jit = workers > 1 or cc is None
    with bar((len(RUNS) if jit else 0) + (1 if aot else 0), "granchain warm-up", unit="step",
             enabled=progress) as shown:
        def say(msg):
            with shown.external_write_mode(file=sys.stderr):
                log(msg)
        path = None
        if aot and jit and workers > 1 and cc is not None and not aot_available():
            # the module beside the JIT kernels: the first task the workers take
            t0 = time.perf_counter()
            say(warm_jit(workers, shown.update, aot=True))
            say(f"granchain warm-up: the ahead-of-time module and the JIT kernels in "
                f"{time.perf_counter() - t0:.1f} s ({workers} processes)")
            return _aot_path()
        if aot:
            path = _build_aot(say, cc, shown.update)
        if jit:
            t0 = time.perf_counter()
            warm_jit(workers, shown.update)
            say(f"granchain warm-up: JIT kernels compiled or loaded from numba's cache in "
                f"{time.perf_counter() - t0:.1f} s "
                f"({workers} process{'es' if workers > 1 else ''})")
        return path


def _aot_path() -> Path:
    """The ahead-of-time module's file (built for the current sources and machine)."""
    return next(p for p in (cache_dir() / "aot").iterdir() if p.name.startswith(module_name()))


def _build_aot(log, CC, done) -> Path | None:
    """The ahead-of-time module of :func:`build` (``CC``: numba.pycc's, or None), with
    ``done(1)`` once it is built or found."""
    if CC is None:
        log("granchain warm-up: numba.pycc is not available; runs use the JIT kernels only")
        done(1)
        return None
    if aot_available():
        done(1)
        log(f"granchain warm-up: ahead-of-time kernels already built for this machine "
            f"({cache_dir() / 'aot'}, {module_name()})")
        return _aot_path()
    # the argument types the engine calls each entry point with (the return types follow)
    sigs = record_signatures()
    out = cache_dir() / "aot"
    out.mkdir(parents=True, exist_ok=True)
    name = module_name()
    t1 = time.perf_counter()
    tmp = out / f".build-{os.getpid()}"
    tmp.mkdir(exist_ok=True)
    cc = CC(name)
    cc.output_dir = str(tmp)
    cc.target_cpu = "host"
    cc.verbose = False
    for e in ENTRY_POINTS:
        cc.export(e, sigs[e])(jit_entry(e).py_func)
    cc.compile()
    built = next(tmp.iterdir())
    final = out / built.name
    os.replace(built, final)            # atomic: a concurrent build or reader sees old or new
    tmp.rmdir()
    aot_module.cache_clear()
    done(1)
    log(f"granchain warm-up: ahead-of-time kernels compiled in {time.perf_counter() - t1:.1f} s "
        f"-> {final}")
    return final
