"""The in-repo reference engine: batched numba integration of a scene.

``run(scene, gaps, v_striker)`` integrates B chains (one row of ``gaps`` and one striker
speed each) and yields a :class:`~granchain.trajectory.Trajectory` per chain, in order.
Chains are processed in chunks (bounded memory) and, inside a chunk, in parallel over
chains with numba's prange; each chain advances window by window of samples until it
stops (t_end reached, or with t_end auto once the wave has left the whole chain: the
stop rule of ``granchain.stoprule``).
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..stoprule import arrival_speed, last_detached
from ..effects import MODULES, SPECS, Terms, chain as chain_mod, physics_terms
from ..guards import gap_total, require_resolved, result_limits
from ..runplan import RunPlan, SpeedPlan, plan_run, step_grid
from ..scene import Scene
from ..trajectory import OnTheFly, RunInfo, Trajectory
from . import backend
from . import chunks
from . import codes
from . import forked
from . import obscodes

M_EVENT = 3
METHOD_CODES = {"rk4": codes.M_RK4, "verlet": codes.M_VERLET, "adaptive": codes.M_DOP853,
                "event": M_EVENT}
STATUS_NAMES = {codes.S_DONE: "done", codes.S_PASSED: "passed", codes.S_TIMEOUT: "timeout",
                codes.S_NONFINITE: "nonfinite", codes.S_STEPFAIL: "stepfail",
                codes.S_RUNNING: "timeout"}
WINDOW = 2048                    # samples per kernel call (adaptive method)
BLOCK_WINDOW = 256               # samples per kernel call (fixed-step blocks)
BLOCKED = ("rk4", "verlet")      # the methods that step chains in blocks, in lockstep
EVENT_LANES = 16                 # chains per block of the event method (``run_events_lanes``)


@dataclass(frozen=True)
class Layout:
    """Offsets of each block of a chain's state vector (-1: block absent)."""
    LO: np.ndarray
    ny: int

    @classmethod
    def of(cls, terms: Terms) -> "Layout":
        n = terms.n
        off = 0
        LO = np.full(codes.L_LEN, -1, dtype=np.int64)

        def take(slot, size):
            nonlocal off
            LO[slot] = off
            off += size
        take(codes.L_DISP, n)
        take(codes.L_VEL, n)
        # the effects' blocks, then one work entry per effect that does work, in
        # registry order (granchain.effects.MODULES)
        on = [spec for name, spec in SPECS.items() if terms.has(name)]
        for spec in on:
            for slot, per in spec.state:
                take(getattr(codes, slot), n if per == "particle" else n - 1)
        for spec in on:
            if spec.work_slot:
                take(getattr(codes, spec.work_slot), 1)
        LO[codes.L_STATE_SIZE] = off
        return cls(LO, off)


def pack(terms: Terms) -> tuple[np.ndarray, np.ndarray]:
    """Parameter vector P and flag vector FL of the kernels, from the effect definitions."""
    P = np.zeros(codes.P_LEN)
    FL = np.zeros(codes.F_LEN, dtype=np.int64)
    P[codes.P_N_SPHERES], P[codes.P_RADIUS], P[codes.P_MASS] = terms.n, terms.R, terms.m
    for mod, term in [(chain_mod, terms.chain)] + [(m, getattr(terms, m.SPEC.name))
                                                   for m in MODULES]:
        if term is not None:
            params, flags = mod.kernel(term)
            for slot, value in params.items():
                P[getattr(codes, slot)] = value
            for slot, value in flags.items():
                FL[getattr(codes, slot)] = value
    return P, FL


def chain_rows(terms: Terms, gaps: np.ndarray, scene: Scene | None = None,
               radii: np.ndarray | None = None) -> np.ndarray:
    """The kernels' per-chain array G (B, G_LEN * n) of chains with physical gaps
    (B, n-1): the kernel gaps, then each sphere's and contact's rows from the chain and
    the enabled effects (``codes.G_*``; rows no effect fills stay 0). With ``radii``
    (B, n), each chain's rows come from ``scene`` with that chain's radii (a member of a
    radius spread)."""
    if radii is not None:
        return np.concatenate([chain_rows(physics_terms(scene.with_radii(r)), g[None, :])
                               for r, g in zip(np.atleast_2d(radii), np.atleast_2d(gaps))])
    n = terms.n
    gaps = np.atleast_2d(gaps)
    G = np.zeros((gaps.shape[0], codes.G_LEN * n))
    G[:, :n] = terms.chain.kernel_gaps(gaps)
    rows = dict(chain_mod.rows(terms.chain))
    for mod in MODULES:
        term = getattr(terms, mod.SPEC.name)
        if term is not None and hasattr(mod, "rows"):
            rows.update(mod.rows(term, terms.chain))
    for slot, values in rows.items():
        o = getattr(codes, slot) * n
        G[:, o:o + n] = values
    return G


def record_width(terms: Terms) -> int:
    """Columns of a chain's velocity record: the n velocities, and the wall force (N)
    with an end wall."""
    return terms.n + (1 if terms.chain.K_wall is not None else 0)



def run(scene: Scene, gaps: np.ndarray, v_striker: np.ndarray, *, method: str | None = None,
        dt: float | None = None, tolerance: float | None = None, progress: bool | None = None,
        trace: bool | None = None, pair: str | None = None,
        radii: np.ndarray | None = None, lanes: bool = True, plan: RunPlan | None = None):
    """Yield one Trajectory per chain. gaps: (B, n-1) m; v_striker: (B,) m/s; radii: (B, n)
    m, each chain's own (a radius spread, ``gaps.member_radii``), or None (the scene's).
    The scene's method must not be auto (``simulate`` resolves it).

    The adaptive method always records the sampled trajectory. The event method measures
    the observables on the fly and records only the initial and final states, unless
    ``trace`` asks for the sampled trajectory (its dense output on the usual sample grid).
    The fixed-step methods (rk4, verlet) record it unless ``trace`` is False: then they
    too measure the observables on the fly (``Trajectory.observed``, equal to the
    summariser's on the record) and keep only the first and last samples. ``pair``: the event method's Runge-Kutta pair
    (``events.PAIRS``; default ``events.DEFAULT_PAIR``). ``lanes``: without a trace, the
    event method runs its chains in SIMD lanes (``eventlanes.run_events_lanes``); False runs
    one chain per thread (``events.run_events``), with the same result bit for bit.
    ``plan``: the run plan of ``scene`` (``granchain.runplan.plan_run``; planned here if
    None), whose striker speeds give each chain its sample interval, sample count and
    expected duration (``RunPlan.speed``); the engine computes none of them."""
    require_resolved(scene, "reference engine")
    terms = physics_terms(scene)
    gaps = np.ascontiguousarray(np.atleast_2d(np.asarray(gaps, dtype=float)))
    vs = np.broadcast_to(np.asarray(v_striker, dtype=float), (gaps.shape[0],)).copy()
    method = method or scene.method
    dt = dt if dt is not None else scene.dt
    rtol = tolerance if tolerance is not None else (scene.tolerance or 1e-8)
    if progress is None:
        progress = sys.stderr.isatty() and gaps.shape[0] > 1
    plan = plan_run(scene) if plan is None else plan
    own = {v: plan.speed(v) for v in set(vs.tolist())}
    sps = [own[v] for v in vs.tolist()]
    # Chains with the same sample interval run together; normally all of them. Inside
    # that, ordered by striker speed and total gap (the flight time that sets the length
    # of a t_end auto run), so that chains of similar length share a chunk and a block.
    keys = np.array([sp.sample_dt for sp in sps])
    order = np.lexsort((np.arange(len(vs)), gaps.sum(axis=1), vs, keys))
    done_total = 0
    out: dict[int, Trajectory] = {}
    next_to_yield = 0
    start = 0
    while start < len(order):
        key = keys[order[start]]
        stop = start
        while stop < len(order) and keys[order[stop]] == key:
            stop += 1
        group = order[start:stop]
        lengths = (_expected_lengths(scene, gaps[group], vs[group], [sps[i] for i in group])
                   if method in BLOCKED else None)
        for chunk, cap in _chunks(group, scene, terms, key, method, trace is False, plan,
                                  samples=method != "event" or bool(trace), lengths=lengths):
            rc = None if radii is None else np.atleast_2d(radii)[chunk]
            csp = [sps[i] for i in chunk]
            if method == "event":
                it = _run_chunk_events(scene, terms, gaps[chunk], vs[chunk], csp, dt, rtol,
                                       key, bool(trace), pair or codes.DEFAULT_PAIR, rc, lanes)
            else:
                it = _run_chunk(scene, terms, gaps[chunk], vs[chunk], csp, method, dt, rtol,
                                key, rc, trace is not False, cap)
            for idx, traj in zip(chunk, it):
                out[int(idx)] = traj
            done_total += len(chunk)
            if progress:
                print(f"\r[granchain] {scene.name}: {done_total}/{len(vs)} chains", end="",
                      file=sys.stderr, flush=True)
            while next_to_yield in out:
                yield out.pop(next_to_yield)
                next_to_yield += 1
        start = stop
    if progress:
        print(file=sys.stderr)
    while next_to_yield in out:
        yield out.pop(next_to_yield)
        next_to_yield += 1


def _expected_lengths(scene: Scene, gaps, vs, sps: list[SpeedPlan]) -> np.ndarray:
    """Each chain's expected run length (s), by which the fixed-step methods choose how
    wide a chunk's blocks may be (``chunks.block_cap``): t_end, or the planned duration
    at its striker speed (``SpeedPlan.duration_s``: the wave's travel plus the flight over
    the scene's expected gaps) with the flight over its own gaps instead."""
    if scene.t_end is not None:
        return np.full(len(vs), float(scene.t_end))
    v = np.maximum(np.asarray(vs, dtype=float), 1e-6)
    planned = np.array([sp.duration_s for sp in sps], dtype=float)
    travel = np.maximum(planned - gap_total(scene, scene.n - 1) / v, 0.0)
    return travel + np.asarray(gaps, dtype=float).sum(axis=1) / v


def _chunks(group, scene, terms, sample_dt, method, observe=False, plan=None, samples=True,
            lengths=None):
    """Split chains into chunks whose memory fits in ``chunks.CHUNK_BYTES`` (and
    ``chunks.CHUNK_CHAINS``; ``chunks.split``): the recorded samples of each chain or, for
    the fixed-step methods measuring on the fly (``observe``), their observables' arrays
    (a chain keeps its first and last samples and a ring of RECORD_RING record samples
    per particle, whatever its length), or for the event method without a trace (not
    ``samples``: it records none) its state, stages, rows and on-the-fly observables.
    ``plan``: the run plan of ``scene`` (planned here if None), whose expected durations
    size a chain's record. ``lengths``: the chains' expected run lengths
    (:func:`_expected_lengths`, in the order of ``group``), from which each chunk's
    blocks get their width (``chunks.block_cap``); None: ``chunks.LANES``. Yields each
    chunk with the most lanes per block it was dealt for (None: not in blocks)."""
    blocked = method in BLOCKED
    if method == "event" and not samples:
        n = terms.n
        per_chain = 8 * ((codes.NST + 4) * Layout.of(terms).ny + codes.G_LEN * n
                         + n * ((codes.RB_SIZE + 2) * codes.RB_LEN + 8))
    elif blocked and observe:
        n = terms.n
        per_chain = 8 * (n * (3 * RECORD_RING + obscodes.OBS_F + obscodes.OBS_I + obscodes.OBS_R
                              + 2 * codes.G_LEN)
                         + 2 * (record_width(terms) + codes.E_LEN) + obscodes.OBS_WF
                         + obscodes.OBS_WI + obscodes.OBS_WOUT + 5 * Layout.of(terms).ny)
    else:
        if scene.t_end is not None:
            t_est = scene.t_end
        else:
            # the slowest striker's expected run, x4: a realisation's gaps can run longer
            # than their mean (a striker at rest: as at 1e-6 m/s)
            plan = plan_run(scene) if plan is None else plan
            v = float(np.min(scene.striker_velocities))
            t_est = 4.0 * plan.speed(max(v, 1e-6)).duration_s
        window = BLOCK_WINDOW if blocked else WINDOW
        per_chain = (t_est / sample_dt + window) * (terms.n + codes.E_LEN) * 8
    yield from chunks.split(group, per_chain, blocked, observe, lengths)


def _kernels(chains: int):
    """The compiled kernels of a call over ``chains`` chains (``engines.backend``): the
    ahead-of-time module, if built, called directly when the call runs no chains in
    parallel (one chain, or one thread), its parallel loops cut between forked processes
    on more threads (``engines.forked``); numba's JIT kernels, parallel over chains, where
    the module is not built."""
    workers = 1 if chains == 1 else backend.num_threads()
    kern = backend.kernels(serial=True)
    if workers == 1:
        return kern
    aot = getattr(kern, "_aot", None)
    return backend.kernels(serial=False) if aot is None else forked.Kernels(aot, workers)


def _run_chunk(scene: Scene, terms: Terms, gaps, vs, sps: list[SpeedPlan], method, dt, rtol,
               sample_dt, radii=None, trace=True, cap=None):
    """The fixed-step and adaptive methods on a chunk of chains. The fixed-step methods
    without ``trace`` measure the observables on the fly (``kernels.run_blocks`` with
    observe: ``Trajectory.observed``, t, v and energy of the first and last samples only);
    a chain whose record samples overflowed the kernel's ring is run again with its trace
    (the same chain alone gives the same samples), and its observables are then the
    summariser's on that trace. ``sps``: each chain's speed plan (its sample count);
    ``cap``: the most lanes per block the chunk was dealt for (``_chunks``; None: LANES)."""
    kern = _kernels(gaps.shape[0])
    layout = Layout.of(terms)
    P, FL = pack(terms)
    B, n, ny = gaps.shape[0], terms.n, layout.ny
    G = chain_rows(terms, gaps, scene, radii)
    nv = record_width(terms)
    Y = np.zeros((B, ny))
    Y[:, layout.LO[codes.L_VEL]] = vs            # particle 1 (index 0) is the striker
    ACC = np.zeros((B, ny))
    T = np.zeros(B)
    H = np.full(B, dt)
    NS = np.zeros(B, dtype=np.int64)
    STEPS = np.zeros(B, dtype=np.int64)
    REJ = np.zeros(B, dtype=np.int64)
    NEV = np.zeros(B, dtype=np.int64)
    STATUS = np.zeros(B, dtype=np.int64)
    VTHR = arrival_speed(vs)
    mcode = METHOD_CODES[method]
    every, sdt = (1, sample_dt) if mcode == codes.M_DOP853 else step_grid(sample_dt, dt)
    auto = scene.t_end is None
    NT = np.array([sp.sample_count(gaps[b], sdt) for b, sp in enumerate(sps)], dtype=np.int64)
    scale_abs, rel = _error_scales(scene, terms, layout, max(float(vs.max()), 1e-9))
    observe = mcode != codes.M_DOP853 and not trace
    V_parts = [[] for _ in range(B)]
    E_parts = [[] for _ in range(B)]
    counts = np.zeros(B, dtype=np.int64)
    obs = None
    t0 = time.perf_counter()
    if mcode == codes.M_DOP853:
        Vbuf = np.empty((B, WINDOW, nv))
        Ebuf = np.empty((B, WINDOW, codes.E_LEN))
        while np.any(STATUS == codes.S_RUNNING):
            kern.run_adaptive(mcode, Y, ACC, T, H, NS, STEPS, REJ, NEV, STATUS, VTHR, G, P,
                              FL, layout.LO, scale_abs, rel, rtol, dt, every, sdt, NT, auto,
                              Vbuf, Ebuf, counts)
            _collect(counts, Vbuf, Ebuf, V_parts, E_parts)
    else:
        Y, T, STEPS, STATUS, obs = _run_blocks(
            mcode, Y, G, nv, VTHR, P, FL, layout, dt, every, NT, auto, V_parts, E_parts,
            observe, sdt, _wall_static(terms), cap or chunks.LANES)
        NS = obs.NS if observe else NS
    wall = time.perf_counter() - t0
    eff = tuple(sorted(scene.effects))
    limits = result_limits(scene)
    ox, ov = layout.LO[codes.L_DISP], layout.LO[codes.L_VEL]
    ovf = obs.overflow() if observe else np.zeros(B, dtype=bool)
    redo = {}
    if ovf.any():
        idx = np.flatnonzero(ovf)
        rr = None if radii is None else radii[idx]
        redo = dict(zip(idx.tolist(), _run_chunk(scene, terms, gaps[idx], vs[idx],
                                                 [sps[i] for i in idx], method, dt, rtol,
                                                 sample_dt, rr, trace=True, cap=cap)))
    for b in range(B):
        if b in redo:
            yield redo[b]
            continue
        status = STATUS[b]
        if auto and status == codes.S_DONE and vs[b] > 0:
            status = codes.S_TIMEOUT      # t_end auto hit its cap before the wave left the chain
        last_overlap = float(Y[b, ox + n - 2] - Y[b, ox + n - 1] - gaps[b, n - 2])
        observed = None
        if observe:
            S = int(NS[b])
            rows = min(S, 2)
            rec = obs.V[b, :rows]
            e = obs.E[b, :rows].copy()
            t = np.array([0, S - 1][2 - rows:]) * sdt
            observed = obs.observed(b, vs[b], float(Y[b, ov + n - 1]), last_overlap,
                                    terms.chain.K_wall is not None, S)
        else:
            rec = np.concatenate(V_parts[b])
            e = np.concatenate(E_parts[b])
            t = np.arange(rec.shape[0]) * sdt
        v = rec[:, :n].copy() if observe else rec[:, :n]
        if mcode == codes.M_RK4:
            nev = 4 * int(STEPS[b])
        elif mcode == codes.M_VERLET:
            nev = int(STEPS[b]) + 1                  # + the setup call
        else:
            # each DOP853 trial evaluates f(y), 11 stages and f(ynew) (kernels.dop853_try),
            # a step with a sample inside it 3 more (its dense output)
            nev = int(NEV[b])
        yield Trajectory(t=t, v=v, energy=e, gaps=gaps[b].copy(), radius=scene.radius,
                         v_striker=float(vs[b]), effects=eff, steps=int(STEPS[b]),
                         rejected=int(REJ[b]), status=STATUS_NAMES[int(status)],
                         wall_s=wall / B, last_overlap=last_overlap, force_evaluations=nev,
                         observed=observed,
                         info=RunInfo(method, dt, sdt, rtol, trace=not observe),
                         limits=limits,
                         **_chain_fields(terms, rec, None if radii is None else radii[b]))


def _run_chunk_events(scene: Scene, terms: Terms, gaps, vs, sps: list[SpeedPlan], dt, rtol,
                      sample_dt, trace, pair, radii=None, lanes=True):
    """The event method (``engines.events``) on a chunk of chains (``sps``: each one's
    speed plan)."""
    kern = _kernels(gaps.shape[0])
    layout = Layout.of(terms)
    P, FL = pack(terms)
    LO = layout.LO
    B, n, ny = gaps.shape[0], terms.n, layout.ny
    G = chain_rows(terms, gaps, scene, radii)
    A, Bw, _nodes, E5, E3, qexp, dopnorm = codes.PAIRS[pair]   # no step uses the nodes
    S = Bw.shape[0]
    Y = np.zeros((B, ny))
    Y[:, LO[codes.L_VEL]] = vs
    KST = np.zeros((B, S + 1, ny))
    T = np.zeros(B)
    H = np.full(B, dt)
    ERROLD = np.full(B, 1e-4)
    STEPS = np.zeros(B, dtype=np.int64)
    REJ = np.zeros(B, dtype=np.int64)
    NEV = np.zeros(B, dtype=np.int64)
    STATUS = np.zeros(B, dtype=np.int64)
    FIN = np.zeros(B, dtype=np.int64)
    INIT = np.zeros(B, dtype=np.int64)
    VTHR = arrival_speed(vs)
    auto = scene.t_end is None
    NT = np.array([sp.sample_count(gaps[b], sample_dt) for b, sp in enumerate(sps)],
                  dtype=np.int64)
    t_stop = (NT - 1) * sample_dt
    scale_abs, rel = _error_scales(scene, terms, layout, max(float(vs.max()), 1e-9))
    band = rtol * scale_abs[LO[codes.L_DISP]]           # overlap band of the contact events
    land = rtol * scale_abs[LO[codes.L_VEL]]           # peak landing threshold
    VMAX = np.zeros((B, n))
    TPK = np.zeros((B, n))
    PASSED = np.zeros((B, n), dtype=np.int64)
    RUNEND = np.full((B, n), -1.0)
    CLIMB = np.full((B, n, 2, codes.RB_LEN), -1.0)
    RB = np.zeros((B, n, codes.RB_SIZE, codes.RB_LEN))
    RBN = np.zeros((B, n), dtype=np.int64)
    DROP = np.full((B, n), -np.inf)
    VINIT = np.zeros((B, n))
    E0 = np.zeros(B)
    BAL = np.zeros(B)
    NS = np.zeros(B, dtype=np.int64)
    W = WINDOW if trace else 0
    YP = np.zeros((B, ny) if trace else (B, 1))
    KP = np.zeros_like(YP)
    TP = np.zeros(B)
    Vbuf = np.empty((B, W, n))
    Ebuf = np.empty((B, W, codes.E_LEN))
    counts = np.zeros(B, dtype=np.int64)
    V_parts = [[] for _ in range(B)]
    E_parts = [[] for _ in range(B)]
    t0 = time.perf_counter()
    in_lanes = lanes and not trace
    if in_lanes:
        # in lanes (``eventlanes.run_events_lanes``): the chunk's chains, longest run first
        # (their time caps: a chain's run scales with them), dealt round-robin to one queue
        # per thread, so that the queues cost alike and short chains fill the lanes that
        # free up at the end
        nq = max(1, min(backend.num_threads(), B))
        width = max(1, min(EVENT_LANES, -(-B // nq)))
        QUEUE = np.full((nq, -(-B // nq)), -1, dtype=np.int64)
        QLEN = np.zeros(nq, dtype=np.int64)
        for k, b in enumerate(np.argsort(-t_stop, kind="stable")):
            QUEUE[k % nq, QLEN[k % nq]] = b
            QLEN[k % nq] += 1
        kern.run_events_lanes(Y, QUEUE, QLEN, width, T, H, ERROLD, STEPS, REJ, NEV, STATUS,
                              VTHR, G, P, FL, LO, scale_abs, rel, rtol, band, land, A, Bw, E5,
                              E3, qexp, dopnorm, t_stop, auto, VMAX, TPK, PASSED, RUNEND,
                              CLIMB, RB, RBN, DROP, VINIT, E0, BAL)
    while not in_lanes and np.any(STATUS == codes.S_RUNNING):
        kern.run_events(Y, KST, T, H, ERROLD, STEPS, REJ, NEV, STATUS, FIN, INIT, VTHR, G, P, FL, LO,
                      scale_abs, rel, rtol, band, land, A, Bw, E5, E3, qexp, dopnorm,
                      t_stop, auto, VMAX, TPK, PASSED, RUNEND, CLIMB, RB, RBN, DROP, VINIT,
                      E0, BAL, trace, sample_dt, NT, NS, YP, KP, TP, Vbuf, Ebuf, counts)
        for b in range(B):
            c = counts[b]
            if c:
                V_parts[b].append(Vbuf[b, :c].copy())
                E_parts[b].append(Ebuf[b, :c].copy())
    wall = time.perf_counter() - t0
    eff = tuple(sorted(scene.effects))
    limits = result_limits(scene)
    ox, ov = LO[codes.L_DISP], LO[codes.L_VEL]
    ebuf = np.empty(codes.E_LEN)
    for b in range(B):
        status = STATUS[b]
        if auto and status == codes.S_DONE and vs[b] > 0:
            status = codes.S_TIMEOUT
        last_overlap = float(Y[b, ox + n - 2] - Y[b, ox + n - 1] - gaps[b, n - 2])
        y_end = Y[b]
        kern.energies(y_end, G[b], P, FL, LO, ebuf)
        e_end = ebuf.copy()
        if trace:
            v = np.concatenate(V_parts[b])
            e = np.concatenate(E_parts[b])
            t = np.arange(v.shape[0]) * sample_dt
        else:
            y0 = np.zeros(ny)
            y0[ov] = vs[b]
            kern.energies(y0, G[b], P, FL, LO, ebuf)
            t = np.array([0.0, float(T[b])])
            v = np.stack([y0[ov:ov + n], y_end[ov:ov + n]])
            e = np.stack([ebuf.copy(), e_end])
        vmax, tpk, tfr, plat = kern.finalize(VMAX[b], TPK[b], RUNEND[b], CLIMB[b], RB[b],
                                             RBN[b], DROP[b], VINIT[b], float(T[b]),
                                             sample_dt)
        final = np.zeros(n, dtype=bool)
        seen = vmax > arrival_speed(vs[b])
        final[:n - 1] = seen[:n - 1] & (PASSED[b, :n - 1] != 0)
        final[n - 1] = bool(seen[n - 1] and last_detached(y_end[ov + n - 1], last_overlap, vs[b]))
        for a in (vmax, tpk, tfr):
            a[~final] = math.nan
        e0 = float(E0[b])
        obs = OnTheFly(v_max=vmax, t_peak=tpk, t_front=tfr, plateau=plat.astype(bool),
                       final=final, balance_error=float(BAL[b] / e0) if e0 > 0 else 0.0)
        yield Trajectory(t=t, v=v, energy=e, gaps=gaps[b].copy(), radius=scene.radius,
                         v_striker=float(vs[b]), effects=eff, steps=int(STEPS[b]),
                         rejected=int(REJ[b]), status=STATUS_NAMES[int(status)],
                         wall_s=wall / B, last_overlap=last_overlap,
                         force_evaluations=int(NEV[b]), observed=obs,
                         info=RunInfo("event", dt, sample_dt, rtol, trace=bool(trace),
                                      pair=pair, t_last=float(T[b])),
                         limits=limits,
                         **_chain_fields(terms, None, None if radii is None else radii[b]))


def _collect(counts, Vbuf, Ebuf, V_parts, E_parts):
    for b in np.flatnonzero(counts):
        c = counts[b]
        V_parts[b].append(Vbuf[b, :c].copy())
        E_parts[b].append(Ebuf[b, :c].copy())


RECORD_RING = 512      # record samples kept per particle by the on-the-fly observables


class _Observed:
    """The on-the-fly observables of a chunk's fixed-step blocks (``kernels.run_blocks``
    with observe): the kernel's arrays, per chain b (padding lanes after the chunk's)."""

    def __init__(self, Bp, n, nv, observe):
        m = Bp if observe else 1
        k = n if observe else 1
        ring = RECORD_RING if observe else 1
        self.V = np.zeros((Bp, 2, nv)) if observe else None
        self.E = np.zeros((Bp, 2, codes.E_LEN)) if observe else None
        self.OF = np.zeros((m, k, obscodes.OBS_F))
        self.OI = np.zeros((m, k, obscodes.OBS_I), dtype=np.int64)
        self.RK = np.zeros((m, k, ring), dtype=np.int64)
        self.RV = np.zeros((m, k, ring, 2))
        self.WF = np.zeros((m, obscodes.OBS_WF))
        self.WI = np.zeros((m, obscodes.OBS_WI), dtype=np.int64)
        self.BAL = np.zeros((m, 2))
        self.OUT = np.zeros((m, k, obscodes.OBS_R))
        self.WOUT = np.zeros((m, obscodes.OBS_WOUT))
        self.NS = None

    def args(self):
        return (self.OF, self.OI, self.RK, self.RV, self.WF, self.WI, self.BAL, self.OUT,
                self.WOUT)

    def overflow(self) -> np.ndarray:
        """Chains whose record ring overflowed for some particle."""
        return np.any(self.OI[:, :, obscodes.OI_RING_OVERFLOW] != 0, axis=1)

    def observed(self, b, v_striker, v_last, last_overlap, walled, samples) -> OnTheFly:
        """Chain b's observables, with ``observables.peak_final``'s rule for which peaks
        are final."""
        out = self.OUT[b]
        top = out[:, obscodes.OUT_MAX_SAMPLE]
        vmax, tpk, tfr = (out[:, obscodes.OUT_VMAX].copy(), out[:, obscodes.OUT_T_PEAK].copy(),
                          out[:, obscodes.OUT_T_FRONT].copy())
        final = (top > arrival_speed(v_striker)) & (self.OI[b, :, obscodes.OI_PASSED] != 0)
        if not walled:
            final[-1] = bool(top[-1] > arrival_speed(v_striker)
                             and last_detached(v_last, last_overlap, v_striker))
        for a in (vmax, tpk, tfr):
            a[~final] = math.nan
        e0, bmax = float(self.BAL[b, obscodes.BAL_E0]), self.BAL[b, obscodes.BAL_MAX]
        wall = {}
        if walled:
            wall = {"wall_force_max": float(self.WOUT[b, 0]),
                    "t_wall_peak": float(self.WOUT[b, 1]),
                    "wall_peak_final": bool(self.WOUT[b, 2] != 0.0)}
        return OnTheFly(v_max=vmax, t_peak=tpk, t_front=tfr,
                        plateau=out[:, obscodes.OUT_PLATEAU] != 0.0, final=final,
                        balance_error=float(bmax / e0) if e0 > 0 else 0.0,
                        samples=int(samples), **wall)


def _wall_static(terms: Terms) -> float:
    """Static force (N) of the end wall (its preload; 0 without a wall)."""
    if terms.chain.K_wall is None:
        return 0.0
    return float(terms.chain.K_wall * terms.chain.wall_overlap ** 1.5)


def _run_blocks(mcode, Y0, gaps, nv, VTHR, P, FL, layout, dt, every, NT, auto, V_parts,
                E_parts, observe=False, sample_dt=0.0, wall_static=0.0, cap=chunks.LANES):
    """Fixed-step methods: the chains in blocks of ``chunks.width`` lanes, at most ``cap``
    (as ``chunks.split`` dealt them; consecutive chains share a block, the last padded with
    lanes at rest that record nothing), stepped in lockstep by ``kernels.run_blocks``. Returns
    each chain's final state, time, steps, status and the ``_Observed`` arrays (``observe``:
    on-the-fly observables and NS, the sample counts; else the records go to V_parts, E_parts)."""
    kern = _kernels(gaps.shape[0])
    B, ny = Y0.shape
    ng = gaps.shape[1]
    n = int(P[codes.P_N_SPHERES])
    Lb = chunks.width(B, backend.num_threads(), cap)
    nblk = -(-B // Lb)
    Bp = nblk * Lb
    Yp = np.zeros((Bp, ny))
    Yp[:B] = Y0
    Gp = np.zeros((Bp, ng))
    Gp[:B] = gaps
    # padding lanes hold the first chain's rows (positive masses), at rest
    Gp[B:] = gaps[0]
    # (nblk, ny, L): chains innermost
    YB = np.ascontiguousarray(Yp.reshape(nblk, Lb, ny).transpose(0, 2, 1))
    GB = np.ascontiguousarray(Gp.reshape(nblk, Lb, ng).transpose(0, 2, 1))
    ACC = np.zeros_like(YB)
    YF = np.zeros((Bp, ny))
    T = np.zeros(Bp)
    NS = np.zeros(Bp, dtype=np.int64)
    STEPS = np.zeros(Bp, dtype=np.int64)
    STATUS = np.full(Bp, codes.S_DONE, dtype=np.int64)
    STATUS[:B] = codes.S_RUNNING
    VT = np.zeros(Bp)
    VT[:B] = VTHR
    NTp = np.ones(Bp, dtype=np.int64)
    NTp[:B] = NT
    obs = _Observed(Bp, n, nv, observe)
    if observe:
        Vbuf, Ebuf = obs.V, obs.E
    else:
        Vbuf = np.empty((Bp, BLOCK_WINDOW, nv))
        Ebuf = np.empty((Bp, BLOCK_WINDOW, codes.E_LEN))
    counts = np.zeros(Bp, dtype=np.int64)
    while np.any(STATUS[:B] == codes.S_RUNNING):
        kern.run_blocks(mcode, YB, ACC, YF, T, NS, STEPS, STATUS, VT, GB, P, FL, layout.LO, dt,
                        every, NTp, auto, Vbuf, Ebuf, counts, observe, float(sample_dt),
                        float(wall_static), *obs.args())
        if not observe:
            _collect(counts[:B], Vbuf, Ebuf, V_parts, E_parts)
    obs.NS = NS[:B]
    return YF[:B], T[:B], STEPS[:B], STATUS[:B], obs


def _chain_fields(terms: Terms, rec: np.ndarray, radii=None) -> dict:
    """Trajectory fields of a heterogeneous or walled chain: each sphere's radius (the
    member's own under a radius spread), and the wall force (N) from the record's last
    column (the event method, which has no record here, runs no walled scene) with its
    static part (the preload K_w w_0^(3/2), which is F0)."""
    out = {}
    if terms.chain.heterogeneous:
        out["radii"] = np.asarray(terms.chain.radii if radii is None else radii, dtype=float)
    if terms.chain.K_wall is not None:
        out["wall_force"] = rec[:, terms.n].copy()
        out["wall_static"] = float(terms.chain.K_wall * terms.chain.wall_overlap ** 1.5)
    return out


def _error_scales(scene, terms, layout, v):
    """Absolute error scales per state component for the adaptive method."""
    LO, n = layout.LO, terms.n
    scale = np.zeros(layout.ny)
    rel = np.ones(layout.ny, dtype=np.int64)
    delta = terms.overlap_scale(v)
    e0 = 0.5 * terms.m * v * v
    # displacements: judged on the overlap scale only (their size grows in free flight)
    scale[LO[codes.L_DISP]:LO[codes.L_DISP] + n] = delta
    rel[LO[codes.L_DISP]:LO[codes.L_DISP] + n] = 0
    scale[LO[codes.L_VEL]:LO[codes.L_VEL] + n] = v
    # each effect's history blocks, on the scale the effect declares; its work on E0
    for mod in MODULES:
        term = getattr(terms, mod.SPEC.name)
        if term is None:
            continue
        for slot, per in mod.SPEC.state:
            o = LO[getattr(codes, slot)]
            scale[o:o + (n if per == "particle" else n - 1)] = mod.error_scale(term, terms, delta, v)
        if mod.SPEC.work_slot:
            scale[LO[getattr(codes, mod.SPEC.work_slot)]] = e0
    return scale, rel
