"""Compile the reference engine's kernels for this machine (``granchain warm-up``; the
workflow's ``aot_kernels`` rule): the ahead-of-time module that ``engines.backend`` loads
for every call (serial, or cut between forked processes: ``engines.forked``), or numba's
JIT kernels where it cannot be built or a process cannot fork."""
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


def _tasks(kind: str) -> tuple:
    """The tasks the warm-up's worker processes share: ``"jit"``, the runs of
    :data:`TASKS`; ``"aot"``, the indices of ``backend.AOT_PARTS``."""
    from .backend import AOT_PARTS
    return TASKS if kind == "jit" else tuple(range(len(AOT_PARTS)))


def _take_tasks(claims: str, kind: str) -> None:
    """A warm-up worker: the tasks of :func:`_tasks` in turn that no other worker has
    taken (a worker takes task k by creating ``claims/k.taken``, which only one can), each
    marked ``claims/k.done`` once run (a JIT task's runs, or the ahead-of-time part it
    names built: :func:`_build_part`)."""
    for k, task in enumerate(_tasks(kind)):
        try:
            os.close(os.open(os.path.join(claims, f"{k}.taken"),
                             os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            continue
        if kind == "jit":
            _warm_up_runs(task)
        else:
            _build_part(task)
        Path(claims, f"{k}.done").touch()


def _in_processes(kind: str, workers: int, done=None) -> None:
    """The tasks of :func:`_tasks` (``kind``) taken by ``workers`` processes at once as they
    come free; ``done(k)`` as each ends (k: its runs, for a JIT task; 0 for a part)."""
    import subprocess
    import tempfile
    tasks = _tasks(kind)
    with tempfile.TemporaryDirectory(prefix="granchain-warm-up-") as claims:
        code = (f"from granchain.engines.warmup import _take_tasks; "
                f"_take_tasks({claims!r}, {kind!r})")
        procs = [subprocess.Popen([sys.executable, "-c", code])
                 for _ in range(min(workers, len(tasks)))]
        counted = set()
        while True:
            alive = any(p.poll() is None for p in procs)
            for k, task in enumerate(tasks):
                if k not in counted and Path(claims, f"{k}.done").exists():
                    counted.add(k)
                    if done is not None:
                        done(len(task) if kind == "jit" else 0)
            if not alive:
                break
            time.sleep(0.2)
        bad = [p.returncode for p in procs]
    if any(bad) or len(counted) < len(tasks):
        raise RuntimeError(f"a warm-up process failed (exit codes {bad})")


def warm_jit(workers: int = 1, done=None) -> None:
    """Compile the JIT kernels into numba's cache (or load them from it): with workers > 1,
    that many processes at once take the tasks of :data:`TASKS` as they come free (each
    compiles what its runs reach; numba writes each cache entry atomically), then this
    process loads them all from the cache. ``done(k)`` as k of :data:`RUNS` are compiled
    (a progress bar's ``update``), if given. The runs reach the JIT kernels only where
    the engine runs them: no ahead-of-time module, or no fork (``engines.reference``)."""
    if workers > 1:
        _in_processes("jit", workers, done)
        done = None
    _warm_up_runs(done=done)


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

    The ahead-of-time module runs every call: directly where it runs no chains in
    parallel, its parallel loop cut between forked processes on more threads
    (``engines.forked``). So the JIT kernels are needed only where the module cannot be
    built (no numba.pycc) or a process cannot fork: ``jit`` None warms them there alone.
    The module is built from the types the warm-up runs call the entry points with
    (:func:`record_signatures`, nothing compiled for them).

    ``progress``: a bar on stderr counting the warm-up runs and the ahead-of-time module
    (``granchain.progress``; None: when stderr is a terminal); ``log``'s lines are written
    around it."""
    from ..progress import bar
    cc = _pycc() if aot else None
    if jit is None:
        jit = cc is None or not hasattr(os, "fork")
    with bar((len(RUNS) if jit else 0) + (1 if aot else 0), "granchain warm-up", unit="step",
             enabled=progress) as shown:
        def say(msg):
            with shown.external_write_mode(file=sys.stderr):
                log(msg)
        path = _build_aot(say, cc, shown.update, workers) if aot else None
        if jit:
            t0 = time.perf_counter()
            warm_jit(workers, shown.update)
            say(f"granchain warm-up: JIT kernels compiled or loaded from numba's cache in "
                f"{time.perf_counter() - t0:.1f} s "
                f"({workers} process{'es' if workers > 1 else ''})")
        return path


def _aot_path() -> Path:
    """The ahead-of-time module's file, or its first part's (built for the current sources
    and machine)."""
    return min(p for p in (cache_dir() / "aot").iterdir() if p.name.startswith(module_name()))


def _compile(CC, name: str, entries, sigs: dict) -> Path:
    """numba.pycc's module ``name`` of the entry points ``entries`` (argument types
    ``sigs``; numba infers the return types) into ``<cache>/aot/``, built in a folder of its
    own and moved in atomically (a concurrent build or reader sees old or new)."""
    out = cache_dir() / "aot"
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".build-{os.getpid()}-{name}"
    tmp.mkdir(exist_ok=True)
    cc = CC(name)
    cc.output_dir = str(tmp)
    cc.target_cpu = "host"
    cc.verbose = False
    for e in entries:
        cc.export(e, sigs[e])(jit_entry(e).py_func)
    cc.compile()
    built = next(tmp.iterdir())
    final = out / built.name
    os.replace(built, final)
    tmp.rmdir()
    return final


def _build_part(k: int) -> Path:
    """Part k of the ahead-of-time module (``backend.AOT_PARTS``), in a warm-up worker."""
    from .backend import AOT_PARTS
    return _compile(_pycc(), f"{module_name()}_p{k}", AOT_PARTS[k], record_signatures())


def _build_aot(log, CC, done, workers: int = 1) -> Path | None:
    """The ahead-of-time module of :func:`build` (``CC``: numba.pycc's, or None), with
    ``done(1)`` once it is built or found: one module in this process, or with ``workers``
    > 1 the parts of ``backend.AOT_PARTS`` in that many processes at once (each compiles
    the laws its part reaches; the benchmarks page gives the times)."""
    if CC is None:
        log("granchain warm-up: numba.pycc is not available; runs use the JIT kernels only")
        done(1)
        return None
    if aot_available():
        done(1)
        log(f"granchain warm-up: ahead-of-time kernels already built for this machine "
            f"({cache_dir() / 'aot'}, {module_name()})")
        return _aot_path()
    t1 = time.perf_counter()
    if workers > 1:
        _in_processes("aot", workers)
    else:
        # the argument types the engine calls each entry point with
        _compile(CC, module_name(), ENTRY_POINTS, record_signatures())
    aot_module.cache_clear()
    if not aot_available():
        raise RuntimeError("the ahead-of-time module was built but does not load")
    final = _aot_path()
    done(1)
    log(f"granchain warm-up: ahead-of-time kernels compiled in {time.perf_counter() - t1:.1f} s "
        f"({workers if workers > 1 else 1} process{'es' if workers > 1 else ''}) -> {final}")
    return final
