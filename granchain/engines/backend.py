"""Where the reference engine's compiled kernels come from: numba's JIT, or a module compiled
ahead of time for this machine.

The kernels (``engines/kernels.py``, ``engines/events.py``, ``engines/eventlanes.py``, the
modules they import, and the effects' laws they compile) are numba code.
Calling them through numba's JIT costs about half a second per process before the first
step, however small the run: numba sets up its compiler and target context even when it
loads the machine code from its cache. A one-chain ``granchain run`` would spend most of its
time there. So the same kernel functions are also compiled ahead of time (``numba.pycc``)
into an extension module for this machine's CPU, which imports in milliseconds and needs no
numba at run time.

- ``engines.warmup.build`` (``granchain warm-up``, the workflow's ``aot_kernels`` rule)
  records the argument types a few small runs call every entry point with (compiling
  nothing for them), then compiles the entry points with those types ahead of time into
  ``<cache>/aot/`` with the machine's CPU as target (the cold compile, once per machine).
- :func:`kernels` gives the compiled entry points: the ahead-of-time ones when built for
  exactly the current kernel sources, numba and CPU, else numba's JIT ones (parallel over
  chains with prange). The engine calls the module's directly for a serial call, and cuts
  a parallel call's loop between forked processes on more threads (``engines.forked``).
  Both are compiled from the same functions without fast-math, so they give
  bit-identical results (tested).

The cache directory is ``granchain.fileio.cache_dir()``. The module's name carries a hash of everything it was compiled
from (:func:`kernel_sources`: the package's modules the kernels import, transitively, found
from their import statements, so the effects' laws, ``codes`` and ``stoprule`` included;
the Runge-Kutta tableaux they embed as constants, by value, whatever file they are read
from; Python, numpy and numba versions; CPU model and flags): a stale module is never
loaded; it is simply not found. Without ``numba.pycc`` (it is
scheduled for removal from numba) the warm-up still warms the JIT cache and says so.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import platform
import sys
from functools import lru_cache
from pathlib import Path

from ..fileio import cache_dir, source_hash

# The kernels' entry points that the engines call (:func:`kernels`), by module.
ENTRY_POINTS = {"run_adaptive": "kernels", "run_blocks": "kernels", "energies": "kernels",
                "run_events": "events", "run_events_lanes": "eventlanes",
                "finalize": "events"}
# The modules that define the entry points; every module of the package they import,
# transitively, is compiled into them (:func:`kernel_sources`).
_ENTRY_MODULES = tuple(sorted({f"granchain.engines.{m}" for m in ENTRY_POINTS.values()}))
_PKG = Path(__file__).resolve().parents[1]


def _module_file(module: str) -> Path | None:
    """The source file of a module of the package (``granchain.x.y``), or None."""
    parts = module.split(".")
    if parts[0] != _PKG.name:
        return None
    base = _PKG.joinpath(*parts[1:])
    for f in (base / "__init__.py", base.with_suffix(".py")):
        if f.is_file():
            return f
    return None


def _imports(module: str, path: Path) -> set[str]:
    """The package's modules that ``module`` (source ``path``) imports, anywhere in it
    (``from . import x`` may name a submodule: it counts if one exists)."""
    import ast
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_bytes(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names)
    return {m for m in out if _module_file(m) is not None}


@lru_cache(maxsize=1)
def kernel_sources() -> tuple[str, ...]:
    """Every source file the compiled kernels are made of, relative to the package: the
    entry points' modules and every module of the package they import, transitively,
    with the packages' ``__init__.py`` that importing them runs.

    Parsing the modules for their imports costs a few tenths of a second, which every
    process would pay before its first step; the list is kept in the cache directory under
    the hash of the whole package's sources (any edit anywhere finds no entry and parses
    again)."""
    entry = cache_dir() / "kernel-sources" / f"{source_hash()[:24]}.txt"
    try:
        listed = tuple(entry.read_text().split())
        if listed and all((_PKG / f).is_file() for f in listed):
            return listed
    except OSError:
        pass
    found = _kernel_sources()
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp = entry.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text("\n".join(found) + "\n")
        os.replace(tmp, entry)           # atomic: a concurrent reader sees all or nothing
    except OSError:
        pass
    return found


def _kernel_sources() -> tuple[str, ...]:
    """:func:`kernel_sources`, found from the import statements."""
    seen: set[str] = set()
    todo = list(_ENTRY_MODULES)
    while todo:
        mod = todo.pop()
        parts = mod.split(".")
        parents = [".".join(parts[:k]) for k in range(1, len(parts))]
        for m in [mod] + parents:
            if m not in seen:
                seen.add(m)
                todo.extend(_imports(m, _module_file(m)))
    return tuple(sorted(str(_module_file(m).relative_to(_PKG)) for m in seen))


def _tableaux() -> bytes:
    """The Runge-Kutta tableaux the kernels embed, by value (the DOP853 coefficients are
    read from scipy's file, outside the package's sources)."""
    import numpy as np

    from . import codes
    out = []
    for name in sorted(codes.PAIRS):
        out.append(name.encode())
        for x in codes.PAIRS[name]:
            a = np.asarray(x, dtype=np.float64)
            out += [repr(a.shape).encode(), a.tobytes()]
    return b"".join(out)


def _cpu() -> str:
    """CPU model and feature flags (what the machine code is specialised for)."""
    try:
        with open("/proc/cpuinfo") as fh:
            lines = [ln for ln in fh.read().splitlines()
                     if ln.startswith(("model name", "flags"))]
        return "\n".join(sorted(set(lines)))
    except OSError:
        return platform.machine() + platform.processor()


def _versions() -> str:
    from importlib.metadata import PackageNotFoundError, version
    out = [sys.version]
    for dist in ("numpy", "numba", "llvmlite"):
        try:
            out.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            out.append(f"{dist} -")
    return "\n".join(out)


def _sources_hash() -> "hashlib._Hash":
    """sha256 of what the kernels are made of: their sources and the tableaux by value."""
    h = hashlib.sha256(source_hash(*kernel_sources()).encode())
    h.update(_tableaux())
    return h


@lru_cache(maxsize=1)
def module_name() -> str:
    """``granchain_kernels_<hash>``: the hash of everything the module is compiled from."""
    h = _sources_hash()
    h.update(_versions().encode())
    h.update(_cpu().encode())
    return "granchain_kernels_" + h.hexdigest()[:20]


@lru_cache(maxsize=1)
def jit_cache_dir() -> Path:
    """Where numba caches the JIT kernels: a folder named by :func:`_sources_hash`.

    numba keys its cache by the stamp of the file that defines each kernel only, but the
    kernels inline the effects' laws and freeze ``codes`` and ``stoprule`` constants from
    other files: an edit there would otherwise load machine code of the old physics. The
    folder sits in the package's ``__pycache__`` (kept across test sessions and runs),
    under ``$NUMBA_CACHE_DIR`` if the user set one, else in :func:`cache_dir` when the
    package is not writable. numba itself keys the entries by Python, numba and CPU."""
    tag = "granchain-jit-" + _sources_hash().hexdigest()[:20]
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        return Path(user) / tag
    pyc = _PKG / "engines" / "__pycache__"
    try:
        pyc.mkdir(exist_ok=True)
        if os.access(pyc, os.W_OK):
            return pyc / tag
    except OSError:
        pass
    return cache_dir() / "jit" / tag


def use_jit_cache() -> None:
    """Point numba's cache at :func:`jit_cache_dir`; called before any kernel is defined
    (numba reads ``config.CACHE_DIR`` when a ``cache=True`` function is decorated)."""
    from numba.core import config
    config.CACHE_DIR = str(jit_cache_dir())


# The ahead-of-time module's parts: where the warm-up has more than one process, each
# process builds parts of their own (``engines.warmup``), each a module of these entry
# points named ``<module_name()>_p<k>``; one process builds them all as one module.
AOT_PARTS = (("run_events", "run_events_lanes", "finalize"),
             ("run_blocks", "run_adaptive", "energies"))


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    except ImportError:
        return None
    return mod


@lru_cache(maxsize=1)
def aot_module():
    """The ahead-of-time module for the current sources and machine (one module, or a
    module holding the entry points of all of :data:`AOT_PARTS`), or None."""
    d = cache_dir() / "aot"
    name = module_name()
    if not d.is_dir():
        return None
    files = {f.name.split(".")[0]: f for f in d.iterdir()
             if f.name.startswith(name) and f.suffix in (".so", ".pyd")}
    if name in files:
        mod = _load(name, files[name])
    else:
        parts = [f"{name}_p{k}" for k in range(len(AOT_PARTS))]
        if not all(p in files for p in parts):
            return None
        loaded = [_load(p, files[p]) for p in parts]
        if any(m is None for m in loaded):
            return None
        mod = type(sys)(name, "the ahead-of-time module's parts")
        for m, entries in zip(loaded, AOT_PARTS):
            for e in entries:
                setattr(mod, e, getattr(m, e, None))
    if mod is None or not all(getattr(mod, e, None) is not None for e in ENTRY_POINTS):
        return None
    return mod


def aot_available() -> bool:
    return aot_module() is not None


def jit_entry(name: str):
    import importlib
    return getattr(importlib.import_module(f"{__package__}.{ENTRY_POINTS[name]}"), name)


class Kernels:
    """The entry points as attributes (``kernels(serial).run_blocks(...)``)."""

    def __init__(self, aot):
        self._aot = aot

    def __getattr__(self, name: str):
        if name not in ENTRY_POINTS:
            raise AttributeError(name)
        return getattr(self._aot, name) if self._aot is not None else jit_entry(name)


def kernels(serial: bool) -> Kernels:
    """The compiled entry points for one call: ahead of time when ``serial`` (nothing to run
    in parallel) and built for this machine, else numba's JIT (parallel over chains)."""
    return Kernels(aot_module() if serial else None)


def num_threads() -> int:
    """The threads numba's parallel kernels use (without importing numba if it is not
    loaded yet: $NUMBA_NUM_THREADS, else the CPUs this process may use)."""
    if "numba" in sys.modules:
        import numba
        return numba.get_num_threads()
    env = os.environ.get("NUMBA_NUM_THREADS")
    if env and env.isdigit():
        return max(1, int(env))
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
               else (os.cpu_count() or 1))
