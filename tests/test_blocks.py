"""The fixed-step kernels step blocks of chains in lockstep (``kernels.run_blocks``): a
chain's trajectory, sample record, step count and status must not depend on the block or
the lane it lands in, nor on its neighbours stopping earlier or later."""
import numpy as np
import pytest

from granchain.engines import kernels
from granchain.engines import chunks, reference
from granchain.scene import load_scene

from conftest import SCENES

ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"


def _scene(method, **over):
    sets = [f"integrator.method={method}", f"effects={ALL}", "rolling.k_roll=1000.0",
            "striker.velocity=[0.0, 0.07, 0.1]"]
    return load_scene(SCENES / "gaps-20nm-440c.yaml",
                      sets + [f"{k}={v}" for k, v in over.items()])


def _members(n_chains, n):
    """Gaps of very different totals (so that the chains stop at different samples) and
    striker speeds that include a chain at rest (one sample, status done)."""
    rng = np.random.default_rng(7)
    gaps = rng.uniform(0.0, 40e-9, (n_chains, n - 1)) * rng.uniform(0.2, 2.0, (n_chains, 1))
    gaps[3] = 0.0                                   # a packed member
    vs = np.array([[0.1, 0.07, 0.0][i % 3] for i in range(n_chains)])
    return gaps, vs


def _key(t):
    return (t.v, t.energy, t.t, t.steps, t.status, t.last_overlap)


def _same(a, b):
    for x, y in zip(_key(a), _key(b)):
        if isinstance(x, np.ndarray):
            if not np.array_equal(x, y):
                return False
        elif x != y:
            return False
    return True


@pytest.mark.parametrize("method", ["rk4", "verlet"])
def test_member_alone_and_in_any_lane_is_bit_identical(method, monkeypatch):
    sc = _scene(method)
    gaps, vs = _members(11, sc.n)
    monkeypatch.setattr(chunks, "LANES", 4)       # 11 chains: 3 blocks, one padded
    monkeypatch.setattr(chunks, "WIDE", 4)
    batch = list(reference.run(sc, gaps, vs, progress=False, trace=True))
    statuses = {t.status for t in batch}
    assert "passed" in statuses and "done" in statuses   # stopped and at-rest chains
    assert len({t.steps for t in batch}) > 3              # neighbours stop at other times
    # reversed order: every member in another lane and block
    rev = list(reference.run(sc, gaps[::-1], vs[::-1], progress=False, trace=True))[::-1]
    # alone: lane 0 of a block padded with chains at rest; and one chain per block
    monkeypatch.setattr(chunks, "LANES", 1)
    monkeypatch.setattr(chunks, "WIDE", 1)
    one = list(reference.run(sc, gaps, vs, progress=False, trace=True))
    monkeypatch.setattr(chunks, "LANES", 4)
    monkeypatch.setattr(chunks, "WIDE", 4)
    for i, t in enumerate(batch):
        assert _same(t, rev[i]), i
        assert _same(t, one[i]), i
    # a run of that chain alone: one moving and gapped, one at rest, the packed one, the
    # one that shares its block with padding
    for i in (0, 2, 3, 10):
        alone = next(reference.run(sc, gaps[i:i + 1], vs[i:i + 1], progress=False, trace=True))
        assert _same(batch[i], alone), i
    # the comparison can fail: another gap in one member changes its trajectory
    g2 = gaps.copy()
    g2[0, 5] *= 1.0 + 1e-12
    other = next(reference.run(sc, g2[:1], vs[:1], progress=False, trace=True))
    assert not _same(batch[0], other)


@pytest.mark.parametrize("method", ["rk4", "verlet"])
def test_blocks_agree_with_the_per_chain_window(method):
    """run_blocks (vectorised lanes) and run_window (the per-chain routines, one lane)
    give the same samples bit for bit, with t_end and the stop rule off: a vector body
    and a scalar loop that rounded differently (fused multiply-add, reassociation) would
    show here."""
    sc = _scene(method, t_end=3.0e-6)
    gaps, vs = _members(9, sc.n)
    terms = reference.physics_terms(sc)
    lay = reference.Layout.of(terms)
    P, FL = reference.pack(terms)
    n, ny, B = sc.n, lay.ny, len(vs)
    G = reference.chain_rows(terms, gaps)      # the kernels' per-chain rows
    every, samples = 10, 300
    code = reference.METHOD_CODES[method]
    # per chain
    Y = np.zeros((B, ny))
    Y[:, lay.LO[kernels.L_VEL]] = vs
    NS, STEPS, REJ = (np.zeros(B, dtype=np.int64) for _ in range(3))
    STATUS = np.zeros(B, dtype=np.int64)
    counts = np.zeros(B, dtype=np.int64)
    V1 = np.full((B, samples, n), np.nan)
    E1 = np.full((B, samples, kernels.E_LEN), np.nan)
    kernels.run_window(code, Y, np.zeros((B, ny)), np.zeros(B), np.full(B, sc.dt), NS, STEPS, REJ,
                       np.zeros(B, dtype=np.int64), STATUS, np.full(B, 1e-4), G, P, FL, lay.LO,
                       np.ones(ny), np.ones(ny, dtype=np.int64), 1e-8, sc.dt, every, every * sc.dt,
                       np.full(B, samples, dtype=np.int64), False, V1, E1, counts)
    # blocks of 4 lanes
    L = 4
    nblk = -(-B // L)
    YB = np.zeros((nblk, ny, L))
    GB = np.zeros((nblk, G.shape[1], L))
    GB[:, :, :] = G[0][None, :, None]        # padding lanes: the first chain's rows, at rest
    for b in range(B):
        YB[b // L, lay.LO[kernels.L_VEL], b % L] = vs[b]
        GB[b // L, :, b % L] = G[b]
    Bp = nblk * L
    STATUS2 = np.full(Bp, kernels.S_DONE, dtype=np.int64)
    STATUS2[:B] = kernels.S_RUNNING
    NT = np.ones(Bp, dtype=np.int64)
    NT[:B] = samples
    NS2, STEPS2, counts2 = (np.zeros(Bp, dtype=np.int64) for _ in range(3))
    V2 = np.full((Bp, samples, n), np.nan)
    E2 = np.full((Bp, samples, kernels.E_LEN), np.nan)
    YF = np.zeros((Bp, ny))
    kernels.run_blocks(code, YB, np.zeros_like(YB), YF, np.zeros(Bp), NS2, STEPS2, STATUS2,
                       np.full(Bp, 1e-4), GB, P, FL, lay.LO, sc.dt, every, NT, False, V2, E2,
                       counts2, False, every * sc.dt, 0.0,
                       *reference._Observed(Bp, n, n, observe=False).args())
    assert np.array_equal(counts, counts2[:B]) and counts.max() == samples
    assert np.array_equal(STEPS, STEPS2[:B])
    assert np.array_equal(V1, V2[:B]) and np.array_equal(E1, E2[:B])
    for b in range(B):
        assert np.array_equal(Y[b], YB[b // L, :, b % L])
    assert np.abs(V1[:, -1, 1:]).max() > 0.01          # the waves did travel
