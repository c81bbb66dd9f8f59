"""How the reference engine splits chains into chunks (``reference._chunks``): every chain
once, whole blocks of consecutive (sorted) chains dealt to the threads' shares, chunks
sized by what a chain holds (its sample record, or with observables measured on the fly
its ring of record samples), and a chain's result the same whatever chunk, block, lane or
thread it lands in."""
import math

import numpy as np
import pytest

from granchain.effects import physics_terms
from granchain.engines import chunks, reference
from granchain.observables import summarize
from granchain.scene import load_scene
from granchain.stoprule import sample_interval

from conftest import SCENES

ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction]"


def _scene(method="verlet", **over):
    sets = [f"integrator.method={method}", f"effects={ALL}"]
    return load_scene(SCENES / "gaps-20nm-440c.yaml", sets + [f"{k}={v}" for k, v in over.items()])


def _chunks(sc, n_chains, observe, method="verlet"):
    terms = physics_terms(sc)
    key = sample_interval(sc, float(sc.striker_velocities[0]))
    return [c for c, _ in reference._chunks(np.arange(n_chains), sc, terms, key, method,
                                            observe)]


def _shares(chunk, threads):
    """The blocks (first chain of each) that numba's static schedule gives each thread."""
    L = chunks.width(len(chunk), threads)
    firsts = [int(chunk[i]) for i in range(0, len(chunk), L)]
    nblk = len(firsts)
    out, i = [], 0
    for t in range(threads):
        k = nblk // threads + (t < nblk % threads)
        out.append(firsts[i:i + k])
        i += k
    return out


@pytest.mark.parametrize("observe", [False, True])
@pytest.mark.parametrize("threads", [1, 2, 3, 4])
@pytest.mark.parametrize("n_chains", [1, 31, 64, 200, 1000, 1283])
def test_chunks_hold_every_chain_once_in_whole_sorted_blocks(monkeypatch, observe, threads,
                                                             n_chains):
    monkeypatch.setattr(reference.backend, "num_threads", lambda: threads)
    sc = _scene()
    parts = _chunks(sc, n_chains, observe)
    flat = np.concatenate(parts)
    assert sorted(flat.tolist()) == list(range(n_chains))
    for c in parts:
        assert len(c) <= chunks.CHUNK_CHAINS
        L = chunks.width(len(c), threads)
        blocks = [c[i:i + L] for i in range(0, len(c), L)]
        # each block: consecutive chains of the sorted group; only the last may be partial
        for b in blocks:
            assert np.array_equal(b, np.arange(b[0], b[0] + len(b)))
        assert all(len(b) == L for b in blocks[:-1])
        if len(c) < n_chains and c is not parts[-1]:
            assert L == chunks.LANES and len(c) % L == 0
        if threads > 1 and len(c) // L > threads:
            # dealt back and forth: every thread's blocks lie within one block per thread
            # of the same mean position
            means = [np.mean(s) for s in _shares(c, threads) if s]
            full = [s for s in _shares(c, threads) if s]
            assert max(means) - min(means) <= L * threads, (means, full)
    if observe:
        # as few chunks as CHUNK_CHAINS allows (1000: 512 + 488, not 192-chain chunks)
        assert len(parts) == math.ceil(n_chains / chunks.CHUNK_CHAINS)


@pytest.mark.parametrize("threads", [1, 2, 3, 4])
def test_block_width_leaves_no_block_of_empty_lanes(threads):
    """A block steps all its lanes, padding included: a chunk too small to fill LANES
    lanes on every thread gets narrower blocks, spread over the threads, padded by less
    than one lane per block; a large chunk gets LANES."""
    for chains in range(1, 3 * chunks.LANES * threads + 2):
        L = chunks.width(chains, threads)
        nblk = -(-chains // L)
        assert 1 <= L <= chunks.LANES, (chains, L)
        assert nblk * L - chains < nblk, (chains, L)          # less than a lane per block
        # the busiest thread steps at most twice the lanes of an even split
        assert -(-nblk // threads) * L <= 2 * -(-chains // threads), (chains, L)
        if chains >= chunks.LANES * threads:
            assert L == chunks.LANES or nblk == -(-chains // chunks.LANES), (chains, L)
    assert chunks.width(1, threads) == 1
    assert chunks.width(1000, threads) == chunks.LANES


@pytest.mark.parametrize("threads", [1, 2, 3, 4])
def test_wide_blocks_are_whole_and_dealt_evenly(threads):
    """Blocks up to WIDE lanes: never wider, never a block of padding only, a whole number
    per thread beyond one each, and whole blocks at least LANES wide for a chunk of a
    whole multiple of LANES on 1, 2 or 4 threads."""
    W = chunks.WIDE
    for n in range(1, chunks.CHUNK_CHAINS + 1):
        L = chunks.width(n, threads, W)
        nblk = -(-n // L)
        assert 1 <= L <= W and nblk * L - n < nblk, (n, L)
        assert -(-nblk // threads) * L <= 2 * -(-n // threads), (n, L)
        if nblk > threads:
            assert nblk % threads == 0, (n, L)
        if n >= W * threads:
            assert L > W // 2, (n, L)
        if n % chunks.LANES == 0 and threads in (1, 2, 4):
            assert n % L == 0 and L >= min(chunks.LANES, n // threads), (n, L)
        assert L >= chunks.width(n, threads) or n < chunks.LANES * threads, (n, L)
    assert chunks.width(chunks.CHUNK_CHAINS, 2, W) == W


def test_block_cap_keeps_narrow_blocks_for_chains_of_unlike_lengths():
    """WIDE lanes for chains of like lengths (an ensemble's realisations: lengths within
    a few per cent), LANES where wide blocks would step finished lanes for more than
    WASTE of the chunk's chain steps beyond narrow ones (mean gaps spread tenfold), and
    for a chunk no larger than LANES."""
    rng = np.random.default_rng(4)
    like = 15e-6 + 0.4e-6 * rng.standard_normal(512)
    unlike = 12e-6 + rng.uniform(0.0, 28e-6, 512)
    assert chunks.block_cap(like) == chunks.WIDE
    assert chunks.block_cap(unlike) == chunks.LANES
    assert chunks.block_cap(np.full(512, 2e-5)) == chunks.WIDE        # t_end: all equal
    assert chunks.block_cap(like[:chunks.LANES]) == chunks.LANES
    # the order does not matter: split and the kernel call decide alike
    assert chunks.block_cap(like[::-1]) == chunks.block_cap(like)
    # the threshold, on lengths spread evenly over [1, 1 + s]: a block of w chains idles
    # for about w s w / (2 N), all N / w of them for w s / 2, so wide blocks add
    # (WIDE - LANES) s / 2 against WASTE N (1 + s / 2): s* = WASTE N / ((WIDE - LANES) / 2
    # - WASTE N / 2)
    N = 512
    s_star = chunks.WASTE * N / ((chunks.WIDE - chunks.LANES) / 2 - chunks.WASTE * N / 2)
    assert chunks.block_cap(np.linspace(1.0, 1.0 + 1.1 * s_star, N)) == chunks.LANES
    assert chunks.block_cap(np.linspace(1.0, 1.0 + 0.9 * s_star, N)) == chunks.WIDE


def test_an_ensemble_runs_in_wide_blocks_and_a_spread_of_gaps_in_narrow_ones(monkeypatch):
    """A scene's realisations at one speed (like lengths) run in blocks wider than LANES,
    chains whose mean gaps differ tenfold in blocks of LANES; the results are the same bit
    for bit as in blocks of LANES."""
    sc = load_scene(SCENES / "gaps-20nm-440c.yaml", ["integrator.method=verlet",
                                                      "effects=[hertz]"])
    monkeypatch.setattr(reference.backend, "num_threads", lambda: 2)
    widths = []
    real = chunks.width

    def spy(n, threads, cap=chunks.LANES):
        widths.append(real(n, threads, cap))
        return widths[-1]

    monkeypatch.setattr(chunks, "width", spy)
    rng = np.random.default_rng(8)
    like = rng.uniform(0.0, 40e-9, (chunks.CHUNK_CHAINS, sc.n - 1))      # one chunk
    unlike = like * rng.uniform(0.0, 10.0, (chunks.CHUNK_CHAINS, 1))
    wide = list(reference.run(sc, like, 0.1, progress=False, trace=False))
    assert max(widths) > chunks.LANES, widths
    # dealt and run by the same width (one chunk of whole blocks)
    assert set(widths) == {chunks.WIDE}, widths
    widths.clear()
    narrow = list(reference.run(sc, unlike, 0.1, progress=False, trace=False))
    assert widths and max(widths) <= chunks.LANES, widths
    monkeypatch.setattr(chunks, "WIDE", chunks.LANES)
    widths.clear()
    ref = list(reference.run(sc, like, 0.1, progress=False, trace=False))
    assert max(widths) <= chunks.LANES
    for a, b in zip(wide, ref):
        assert a.steps == b.steps and a.status == b.status
        assert _json(summarize(a, sc.probes)) == _json(summarize(b, sc.probes))
    assert len(narrow) == chunks.CHUNK_CHAINS


def test_observed_chunks_are_sized_by_the_ring_not_the_record():
    """A slow striker's long run: its record would fill a chunk with few chains; the
    on-the-fly observables hold the same per chain whatever the length of the run."""
    slow = _scene(**{"striker.velocity": 0.005, "gaps.mean": 1.9e-7})
    rec = _chunks(slow, 1000, observe=False)
    obs = _chunks(slow, 1000, observe=True)
    assert len(rec[0]) < len(obs[0]) == chunks.CHUNK_CHAINS
    assert len(obs) == math.ceil(1000 / chunks.CHUNK_CHAINS)
    # the event and adaptive methods keep their sizing
    for method in ("event", "adaptive"):
        a = [c for c, _ in reference._chunks(np.arange(1000), slow, physics_terms(slow),
                                             sample_interval(slow, 0.005), method, False)]
        b = [c for c, _ in reference._chunks(np.arange(1000), slow, physics_terms(slow),
                                             sample_interval(slow, 0.005), method, True)]
        assert [x.tolist() for x in a] == [x.tolist() for x in b]
        assert np.array_equal(np.concatenate(a), np.arange(1000))


def test_the_event_method_without_a_trace_is_chunked_by_what_it_holds(monkeypatch):
    """Without a trace the event method records no samples: a slow striker's long run
    fills its chunks up to CHUNK_CHAINS (as the cost model assumes), not to the size of a
    record it does not keep; with a trace, the record sizes them."""
    slow = _scene("event", **{"striker.velocity": 0.005, "gaps.mean": 1.9e-7})
    seen = []

    def record(scene, terms, gaps, vs, *args, **kw):
        seen.append(len(vs))
        return iter(())

    monkeypatch.setattr(reference, "_run_chunk_events", record)
    gaps = np.random.default_rng(0).uniform(0.0, 3.8e-7, (1000, slow.n - 1))
    for trace in (None, False):
        seen.clear()
        list(reference.run(slow, gaps, 0.005, progress=False, trace=trace))
        assert seen == [chunks.CHUNK_CHAINS, 1000 - chunks.CHUNK_CHAINS], (trace, seen)
    seen.clear()
    list(reference.run(slow, gaps, 0.005, progress=False, trace=True))
    assert sum(seen) == 1000 and max(seen) < chunks.CHUNK_CHAINS, seen


def _members(n_chains, n):
    """Gaps of very different totals, so that the chains stop at different samples, and
    striker speeds that include a chain at rest."""
    rng = np.random.default_rng(11)
    gaps = rng.uniform(0.0, 40e-9, (n_chains, n - 1)) * rng.uniform(0.2, 2.0, (n_chains, 1))
    vs = np.array([[0.1, 0.07, 0.0, 0.1][i % 4] for i in range(n_chains)])
    return gaps, vs


def _json(run):
    d = run.to_json()
    d.pop("wall_s")
    return json_safe(d)


def json_safe(x):
    if isinstance(x, float) and math.isnan(x):
        return "nan"
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list):
        return [json_safe(v) for v in x]
    return x


@pytest.mark.parametrize("method", ["rk4", "verlet"])
def test_a_chains_result_does_not_depend_on_its_chunk_block_or_thread(method, monkeypatch):
    """On the fly, in large dealt chunks of small blocks, against each chain's trace run
    with one chain per block in chunks of one block (no dealing), summarised in Python."""
    sc = _scene(method, **{"striker.velocity": "[0.0, 0.07, 0.1]"})
    gaps, vs = _members(15, sc.n)
    monkeypatch.setattr(chunks, "LANES", 3)            # 15 chains: 5 blocks
    monkeypatch.setattr(chunks, "WIDE", 3)
    monkeypatch.setattr(reference.backend, "num_threads", lambda: 4)
    dealt = list(reference.run(sc, gaps, vs, progress=False, trace=False))
    assert all(t.observed is not None for t in dealt)
    assert len({t.steps for t in dealt}) > 5 and {t.status for t in dealt} >= {"passed", "done"}
    monkeypatch.setattr(chunks, "CHUNK_CHAINS", 6)     # chunks of 2 blocks of 3, and 1
    small = list(reference.run(sc, gaps, vs, progress=False, trace=False))
    monkeypatch.setattr(chunks, "LANES", 1)
    monkeypatch.setattr(chunks, "WIDE", 1)
    monkeypatch.setattr(chunks, "CHUNK_CHAINS", 1)
    monkeypatch.setattr(reference.backend, "num_threads", lambda: 1)
    alone = list(reference.run(sc, gaps, vs, progress=False, trace=True))
    assert all(t.observed is None for t in alone)
    for i in range(len(vs)):
        want = _json(summarize(alone[i], sc.probes))
        assert _json(summarize(dealt[i], sc.probes)) == want, i
        assert _json(summarize(small[i], sc.probes)) == want, i
