"""The kernels on several cores without numba: the ahead-of-time module's entry points
(compiled for this machine, serial) in forked worker processes, each on its contiguous
share of the call's chains, blocks or queues.

numba's JIT runs the chains in parallel threads, but a process that calls it pays for
importing numba and loading its target context and cached machine code (about a second on
the 2-core machines, longer than the kernels of a thousand chains take), and the machine
pays for compiling the parallel drivers once besides the module. The ahead-of-time module
imports in milliseconds and holds the same functions, compiled from the same source (its
``prange`` a plain loop). A chain's result depends on nothing but its own lane
(``engines.chunks``) or its own queue, so cutting a call's parallel loop between processes
gives the JIT's results bit for bit (tested): the arrays a call writes are placed in memory
shared with the workers, each worker (the calling process one of them) runs its share, and
the shares are numba's own static schedule, equal contiguous runs of the loop
(:func:`shares`).

Each parallel entry point declares its cut (:data:`CUTS`): the arguments sliced with the
parallel loop (per item: the loop runs over their first axis), those sliced per chain of a
block of lanes (``run_blocks``: item k holds chains k*L .. k*L+L-1), and those the kernel
writes. A written argument that is not sliced (``run_events_lanes``: the queues name the
chains they write) is shared whole; the workers write disjoint chains of it.
"""
from __future__ import annotations

import mmap
import os
import sys
from dataclasses import dataclass

import numpy as np

# The entry points' arguments, by name, in order (``engines.kernels``, ``engines.events``,
# ``engines.eventlanes``; a test checks them against the kernels' signatures).
_BLOCK_CHAIN = ("YF", "T", "NS", "STEPS", "STATUS", "VTHR", "NT", "Vout", "Eout", "counts",
                "OF", "OI", "RK", "RV", "WF", "WI", "BAL", "OUT", "WOUT")
_EVENT_OBS = ("VMAX", "TPK", "PASSED", "RUNEND", "CLIMB", "RB", "RBN", "DROP", "VINIT", "E0",
              "BAL")
ARGS = {
    "run_blocks": ("method", "Y", "ACC", "YF", "T", "NS", "STEPS", "STATUS", "VTHR", "gaps",
                   "P", "FL", "LO", "dt", "every", "NT", "auto_stop", "Vout", "Eout",
                   "counts", "observe", "sample_dt", "wall_static", "OF", "OI", "RK", "RV",
                   "WF", "WI", "BAL", "OUT", "WOUT"),
    "run_adaptive": ("method", "Y", "ACC", "T", "H", "NS", "STEPS", "REJ", "NEV", "STATUS",
                     "VTHR", "gaps", "P", "FL", "LO", "scale_abs", "rel", "rtol", "dt", "every",
                     "sample_dt", "NT", "auto_stop", "Vout", "Eout", "counts"),
    "run_events": ("Y", "KST", "T", "H", "ERROLD", "STEPS", "REJ", "NEV", "STATUS", "FIN",
                   "INIT", "VTHR", "gaps", "P", "FL", "LO", "scale_abs", "rel", "rtol",
                   "band", "land", "A", "Bw", "E5", "E3", "qexp", "dopnorm", "t_stop",
                   "auto_stop", *_EVENT_OBS, "trace", "sdt", "NT", "NS", "YP", "KP", "TP",
                   "Vout", "Eout", "counts"),
    "run_events_lanes": ("Y", "QUEUE", "QLEN", "L", "T", "H", "ERROLD", "STEPS", "REJ", "NEV",
                         "STATUS", "VTHR", "gaps", "P", "FL", "LO", "scale_abs", "rel",
                         "rtol", "band", "land", "A", "Bw", "E5", "E3", "qexp", "dopnorm",
                         "t_stop", "auto_stop", *_EVENT_OBS),
}


@dataclass(frozen=True)
class Cut:
    """How a parallel entry point's loop is cut: ``items`` are sliced [a:b] (the loop runs
    over the first axis of the first of them), ``lanes`` [a*L:b*L] with L the lanes of a
    block (the last axis of the first item), and ``written`` are the ones the kernel
    writes."""
    items: tuple[str, ...]
    written: tuple[str, ...]
    lanes: tuple[str, ...] = ()


_ADAPTIVE_CHAIN = ("Y", "ACC", "T", "H", "NS", "STEPS", "REJ", "NEV", "STATUS", "VTHR", "gaps",
                   "NT", "Vout", "Eout", "counts")
_EVENT_CHAIN = ("Y", "KST", "T", "H", "ERROLD", "STEPS", "REJ", "NEV", "STATUS", "FIN", "INIT",
                "VTHR", "gaps", "t_stop", *_EVENT_OBS, "NT", "NS", "YP", "KP", "TP", "Vout",
                "Eout", "counts")
_READ = ("VTHR", "gaps", "NT", "t_stop")
CUTS = {
    "run_blocks": Cut(items=("Y", "ACC", "gaps"), lanes=_BLOCK_CHAIN,
                      written=("Y", "ACC") + tuple(a for a in _BLOCK_CHAIN if a not in _READ)),
    "run_adaptive": Cut(items=_ADAPTIVE_CHAIN,
                        written=tuple(a for a in _ADAPTIVE_CHAIN if a not in _READ)),
    "run_events": Cut(items=_EVENT_CHAIN,
                      written=tuple(a for a in _EVENT_CHAIN if a not in _READ)),
    "run_events_lanes": Cut(items=("QUEUE", "QLEN"),
                            written=("Y", "T", "H", "ERROLD", "STEPS", "REJ", "NEV", "STATUS",
                                     *_EVENT_OBS)),
}


def usable(workers: int, items: int) -> bool:
    """Can a call run forked: more than one worker and item, a platform with fork, and no
    numba threads started in this process (a fork copies only the calling thread; numba's
    pools would be left broken in the child)."""
    if workers < 2 or items < 2 or not hasattr(os, "fork"):
        return False
    numba = sys.modules.get("numba")
    if numba is None:
        return True
    try:
        from numba.np.ufunc import parallel
        return not parallel._is_initialized
    except (ImportError, AttributeError):
        return False


def _shared(a: np.ndarray) -> np.ndarray:
    """A copy of ``a`` in anonymous memory shared with the processes forked after it."""
    buf = mmap.mmap(-1, max(a.nbytes, 1))
    out = np.frombuffer(buf, dtype=a.dtype, count=a.size).reshape(a.shape)
    out[...] = a
    return out


def shares(items: int, workers: int) -> list[tuple[int, int]]:
    """numba's static schedule of ``range(items)`` over ``workers`` threads: equal
    contiguous runs, one more item for each of the first ``items % workers``."""
    out, a = [], 0
    for t in range(workers):
        b = a + items // workers + (t < items % workers)
        if b > a:
            out.append((a, b))
        a = b
    return out


def items(name: str, args: tuple) -> int:
    """The length of ``name``'s parallel loop in a call with ``args``."""
    return args[ARGS[name].index(CUTS[name].items[0])].shape[0]


def call(name: str, fn, args: tuple, workers: int) -> bool:
    """``fn(*args)`` (``fn``: the entry point ``name`` of the ahead-of-time module) with its
    parallel loop cut between ``workers`` processes; the written arrays of ``args`` hold
    the results as after one call. Returns False (args untouched) if a worker failed, for
    the caller to run the call another way."""
    cut, names = CUTS[name], ARGS[name]
    at = {a: names.index(a) for a in names}
    live = list(args)
    for a in cut.written:
        live[at[a]] = _shared(args[at[a]])
    first = args[at[cut.items[0]]]
    lanes = first.shape[-1] if cut.lanes else 0
    parts = shares(first.shape[0], workers)
    pids = []

    def run(a, b):
        own = list(live)
        for x in cut.items:
            own[at[x]] = live[at[x]][a:b]
        for x in cut.lanes:
            own[at[x]] = live[at[x]][a * lanes:b * lanes]
        fn(*own)

    ok = True
    try:
        for a, b in parts[1:]:
            pid = os.fork()
            if pid == 0:                                 # the worker: its share, then out
                code = 1
                try:
                    run(a, b)
                    code = 0
                finally:
                    os._exit(code)
            pids.append(pid)
        try:
            run(*parts[0])
        except Exception:
            ok = False
        while pids:
            _, status = os.waitpid(pids[0], 0)
            pids.pop(0)
            ok = ok and os.waitstatus_to_exitcode(status) == 0
    finally:
        for pid in pids:                                 # interrupted: no worker outlives it
            os.kill(pid, 9)
            os.waitpid(pid, 0)
    if ok:
        for a in cut.written:
            args[at[a]][...] = live[at[a]]
    return ok


class Kernels:
    """The ahead-of-time module's entry points as attributes, its parallel ones
    (:data:`CUTS`) cut between ``workers`` forked processes; a call that cannot fork
    (numba's threads already running in this process) or whose worker failed runs numba's
    JIT kernel instead (``engines.backend.jit_entry``), which gives the same results."""

    def __init__(self, aot, workers: int):
        self._aot = aot
        self._workers = workers

    def __getattr__(self, name: str):
        fn = getattr(self._aot, name)
        if name not in CUTS:
            return fn
        workers = self._workers

        def parallel(*args):
            n = items(name, args)
            if n < 2:
                return fn(*args)                  # nothing to cut
            if usable(workers, n) and call(name, fn, args, workers):
                return None
            from .backend import jit_entry
            return jit_entry(name)(*args)
        return parallel
