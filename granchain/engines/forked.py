"""The fixed-step block kernel on several cores without numba: the ahead-of-time module's
``run_blocks`` (compiled for this machine, serial) in forked worker processes, each on
its contiguous share of the blocks.

numba's JIT runs the blocks in parallel threads, but a process that calls it pays for
importing numba and loading its target context and cached machine code (about a second on
the 2-core machines, longer than the kernels of a thousand chains take). The ahead-of-time
module imports in milliseconds and holds the same function, compiled from the same source
(its ``prange`` a plain loop). A chain's result depends on nothing but its own lane
(``engines.chunks``), so cutting the blocks between processes gives the JIT's results bit
for bit (tested): the arrays a call writes are placed in memory shared with the workers,
each worker (the calling process one of them) runs its share, and the shares are numba's
own static schedule, equal contiguous runs of blocks (``chunks.deal_blocks`` orders the
blocks for it).

Used for the kernel calls that run every chain of a chunk to its end in one call (the
on-the-fly observables): the calls that return records window by window would fork once
per window.
"""
from __future__ import annotations

import mmap
import os
import sys

import numpy as np

# run_blocks' arguments, by position: per block (first axis nblk), per chain (first axis
# nblk * lanes), and which of them the kernel writes
_PER_BLOCK = (1, 2, 9)                       # Y, ACC, gaps
_PER_CHAIN = (3, 4, 5, 6, 7, 8, 15, 17, 18, 19, 23, 24, 25, 26, 27, 28, 29, 30, 31)
_WRITTEN = (1, 2, 3, 4, 5, 6, 7, 17, 18, 19, 23, 24, 25, 26, 27, 28, 29, 30, 31)
_OBSERVE = 20


def usable(aot, workers: int, nblk: int) -> bool:
    """Can this call run forked: an ahead-of-time module, more than one worker and block,
    a platform with fork, and no numba threads started in this process (a fork copies
    only the calling thread; numba's pools would be left broken in the child)."""
    if aot is None or workers < 2 or nblk < 2 or not hasattr(os, "fork"):
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


def shares(nblk: int, workers: int) -> list[tuple[int, int]]:
    """numba's static schedule of ``range(nblk)`` over ``workers`` threads: equal
    contiguous runs, one more block for each of the first ``nblk % workers``."""
    out, a = [], 0
    for t in range(workers):
        b = a + nblk // workers + (t < nblk % workers)
        if b > a:
            out.append((a, b))
        a = b
    return out


def run_blocks(aot, args: tuple, lanes: int, workers: int) -> bool:
    """``aot.run_blocks(*args)`` with the blocks cut between ``workers`` processes; the
    written arrays of ``args`` hold the results as after one call. Returns False (args
    untouched) if a worker failed, for the caller to run the call another way."""
    assert args[_OBSERVE], "forked calls run every chain to its end"
    nblk = args[1].shape[0]
    live = list(args)
    for i in _WRITTEN:
        live[i] = _shared(args[i])
    parts = shares(nblk, workers)
    pids = []

    def call(a, b):
        own = list(live)
        for i in _PER_BLOCK:
            own[i] = live[i][a:b]
        for i in _PER_CHAIN:
            own[i] = live[i][a * lanes:b * lanes]
        aot.run_blocks(*own)

    ok = True
    try:
        for a, b in parts[1:]:
            pid = os.fork()
            if pid == 0:                                 # the worker: its share, then out
                code = 1
                try:
                    call(a, b)
                    code = 0
                finally:
                    os._exit(code)
            pids.append(pid)
        try:
            call(*parts[0])
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
        for i in _WRITTEN:
            args[i][...] = live[i]
    return ok
