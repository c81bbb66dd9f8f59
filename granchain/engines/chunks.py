"""How the reference engine cuts a group of chains into chunks and deals their blocks to
the threads.

A chunk is what one kernel call holds: as many chains as a memory budget
(``CHUNK_BYTES``, and at most ``CHUNK_CHAINS``) allows, in whole multiples of ``LANES``.
The fixed-step methods run a chunk in blocks of consecutive chains (``LANES``, or
``WIDE`` for a chunk of chains of like lengths: :func:`block_cap`; fewer in a chunk too
small to fill them on every thread: :func:`width`), and numba hands each thread an equal
contiguous share of the blocks; the chains come sorted by expected length, so a chunk's
full blocks are dealt to the threads' shares back and forth (0, 1, .., T-1, T-1, .., 0,
..) and every thread gets long and short blocks alike. A chain's result does not depend
on its block or lane, nor on its chunk.
"""
from __future__ import annotations

import numpy as np

from . import backend

CHUNK_BYTES = 256 * 2**20        # memory budget of one chunk of chains' samples
CHUNK_CHAINS = 512               # at most this many chains in a chunk
LANES = 32                       # most chains per block of the fixed-step kernels
# A block steps all its lanes until its last chain stops. Wider blocks step each lane for
# less (128 lanes: 15-20 % less per chain step than 32, one thread, benchmarks/lanes.py
# --wide), but a block of chains of unlike lengths steps its finished lanes longer. A
# chunk whose chains' expected lengths would leave WIDE-lane blocks stepping finished
# lanes for WASTE more of the chunk's chain steps than LANES-lane blocks does keeps LANES.
WIDE = 128
WASTE = 0.05


def split(group, per_chain: float, blocked: bool, observe: bool, lengths=None):
    """Yield the chunks of ``group`` (chain indices, sorted by expected length) whose
    chains hold ``per_chain`` bytes each. ``blocked``: the fixed-step methods' blocks of
    up to :func:`block_cap` chains (``lengths``: the group's chains' expected run
    lengths, in its order; None: LANES), whole multiples of LANES chains per chunk, dealt
    to the threads (:func:`deal_blocks`); with ``observe`` (their on-the-fly observables,
    the same size whatever a chain's length) as few chunks as the limits allow, as even
    as multiples of LANES make them, else as many blocks of LANES on every thread. Each
    chunk comes with the most lanes per block it was dealt for (None: not ``blocked``),
    which the kernel call is to cut its blocks by (:func:`width`)."""
    size = int(max(1, min(len(group), CHUNK_BYTES // per_chain, CHUNK_CHAINS)))
    threads = backend.num_threads()
    if blocked and observe and size < len(group):
        # whole blocks; as few chunks as the limits allow, as even as blocks make them
        parts = -(-len(group) // max(LANES, size // LANES * LANES))
        size = -(-len(group) // (parts * LANES)) * LANES
    elif blocked and size < len(group):
        # whole blocks, as many on every thread
        unit = LANES * threads
        size = max(LANES, size // unit * unit)
    for i in range(0, len(group), size):
        chunk = group[i:i + size]
        if blocked:
            cap = LANES if lengths is None else block_cap(lengths[i:i + size])
            yield deal_blocks(chunk, threads, cap), cap
        else:
            yield chunk, None


def block_cap(lengths) -> int:
    """The most lanes per block for a chunk of chains of expected run lengths ``lengths``
    (any order): WIDE, unless blocks of WIDE chains of like length (the lengths sorted)
    would step finished lanes for more than WASTE of the chunk's chain steps beyond what
    blocks of LANES would (each block steps until its longest chain ends), else LANES."""
    x = np.sort(np.asarray(lengths, dtype=float))
    total = float(np.sum(x))
    if x.size <= LANES:
        return LANES
    if not total > 0.0:                 # no lengths to tell apart: no lane waits for another
        return WIDE

    def idle(w):
        pad = -x.size % w
        top = np.concatenate([x, np.full(pad, x[-1])]).reshape(-1, w).max(axis=1)
        return float(np.sum(top) * w - pad * x[-1] - total)

    return WIDE if idle(WIDE) - idle(LANES) <= WASTE * total else LANES


def width(chains: int, threads: int, cap: int = LANES) -> int:
    """Lanes per block of a chunk of ``chains`` chains on ``threads`` threads, blocks of
    at most ``cap`` lanes (:func:`block_cap`): as few blocks as ``cap`` lanes allow, but
    one per thread while there are chains for it, each ceil(chains / blocks) wide, so
    that no block steps lanes that hold no chain beyond the rounding (which can leave a
    thread without a block: 4 chains on 3 threads make 2 blocks of 2). Beyond LANES,
    blocks a whole number per thread, and for a chunk of a whole multiple of LANES whole
    blocks where such a number of them, at least LANES wide, divides it. A block's step
    costs about as much as its lanes, padding lanes included (``benchmarks/lanes.py``):
    one chain in a block of LANES lanes would cost as much as LANES chains. A chunk of
    LANES chains per thread or more gets LANES (or up to ``cap``)."""
    threads = max(1, threads)
    nblk = max(-(-chains // cap), min(max(1, chains), threads))
    if cap > LANES:
        if nblk > threads:
            nblk = -(-nblk // threads) * threads
        if chains % LANES == 0:
            for k in range(nblk, chains // LANES + 1, threads if nblk >= threads else 1):
                if chains % k == 0:
                    nblk = k
                    break
    return max(1, -(-chains // nblk))


def deal_blocks(chunk, threads, cap: int = LANES):
    """``chunk`` with its full blocks (of :func:`width` lanes, at most ``cap``) reordered
    so that numba's contiguous split of the blocks over ``threads`` gives each thread
    blocks dealt back and forth from the sorted order; a partial block stays last (the
    padding lanes follow it)."""
    lanes = width(len(chunk), threads, cap)
    full = len(chunk) // lanes
    if threads < 2 or full <= threads:
        return chunk
    # numba's static schedule of range(nblk): equal contiguous shares, one more for each
    # of the first nblk % threads threads
    nblk = -(-len(chunk) // lanes)
    share = [nblk // threads + (t < nblk % threads) for t in range(threads)]
    share[-1] -= nblk - full                      # the partial block stays last
    shares = [[] for _ in range(threads)]
    turn = list(range(threads)) + list(range(threads - 1, -1, -1))
    k = 0
    for blk in range(full):
        while True:
            t = turn[k % len(turn)]
            k += 1
            if len(shares[t]) < share[t]:
                break
        shares[t].append(blk)
    order = [b for s in shares for b in s]
    blocks = chunk[:full * lanes].reshape(full, lanes)[order].reshape(-1)
    return np.concatenate([blocks, chunk[full * lanes:]])
