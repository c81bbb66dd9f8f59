"""The event method (``engines.events``) across chains, in SIMD lanes.

Blocks of L lanes, each lane one chain, stepped in lock step. Each lane keeps its own step
size, its own trial and its own acceptance; a step that one lane rejects (error control,
an event located inside it) is simply that lane's next trial while its neighbours go on. A
lane whose chain stops takes the next chain of its block's queue. The force evaluations
and the Runge-Kutta stages of all lanes run together (``integrators.forces_block``, lanes
innermost: vectorised across chains), and so do the event tests (``events._predict``,
``events._straddle``, ``compose.locate``, ``eventobs._peak_inside``: over all lanes at
once, without a branch per lane; a root is found only in the lanes where something
crosses); the observables are updated lane by lane (``eventobs._observe``). These are the
functions ``events.run_events`` calls on a block of one lane, and a lane's arithmetic is
that of ``run_events`` operation for operation, so a chain's result does not depend on
its lane, its block or its neighbours (bit for bit; tested against ``run_events``).

A lane keeps its chain's counters, time and step size to itself while the chain runs
(written back when it stops), and each block its own copies of the run's small arrays:
chains of two threads would otherwise write to, and count references on, the same cache
lines at every trial.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import kernels
from .codes import RB_T0
from .compose import locate
from .eventobs import _observe, _peak_inside
from .events import MAX_TRIES, PI_BETA, _predict, _straddle

_PH_BEGIN, _PH_TRIAL, _PH_EMPTY = 0, 1, 2


@njit(cache=True, inline="always")
def _combine(Kf, coef, nq, af, idx):
    """af[m] = sum_{q < nq} coef[q] Kf[q, m] over the whole block (af: the flat (ny * L)
    view), the terms in the stages' order. Terms of a zero coefficient are left out (for
    finite K the sum is the same to the last bit: it starts from +0.0 and a +-0.0 term
    leaves it unchanged), and up to four terms are added in one pass over the block, each
    entry's additions in order, so the block is read and written once per four stages."""
    cnt = 0
    for q in range(nq):
        if coef[q] != 0.0:
            idx[cnt] = q
            cnt += 1
    M = af.shape[0]
    af[:] = 0.0
    g = 0
    while g < cnt:
        k = min(4, cnt - g)
        q0 = idx[g]
        a0 = coef[q0]
        if k == 4:
            q1, q2, q3 = idx[g + 1], idx[g + 2], idx[g + 3]
            a1, a2, a3 = coef[q1], coef[q2], coef[q3]
            for m in range(M):
                af[m] = (((af[m] + a0 * Kf[q0, m]) + a1 * Kf[q1, m]) + a2 * Kf[q2, m]
                         + a3 * Kf[q3, m])
        elif k == 3:
            q1, q2 = idx[g + 1], idx[g + 2]
            a1, a2 = coef[q1], coef[q2]
            for m in range(M):
                af[m] = ((af[m] + a0 * Kf[q0, m]) + a1 * Kf[q1, m]) + a2 * Kf[q2, m]
        elif k == 2:
            q1 = idx[g + 1]
            a1 = coef[q1]
            for m in range(M):
                af[m] = (af[m] + a0 * Kf[q0, m]) + a1 * Kf[q1, m]
        else:
            for m in range(M):
                af[m] += a0 * Kf[q0, m]
        g += k


@njit(cache=True, inline="always")
def _stage_lanes(yf, hf, Kf, coef, nq, af, outf, idx):
    """out = y + h_l sum_{q < nq} coef[q] K_q on every lane l (the sum: ``_combine``), on
    the flat views of the block (hf: each lane's step, repeated for every component), in
    one loop over the whole block."""
    _combine(Kf, coef, nq, af, idx)
    for m in range(af.shape[0]):
        outf[m] = yf[m] + hf[m] * af[m]


@njit(cache=True, error_model="numpy", boundscheck=False)
def _rk_trial_lanes(y, hl, g, P, FL, LO, Kb, ynew, tmp, f, acc, scale_abs, rel, rtol,
                    A, Bw, E5, E3, dopnorm, err):
    """``kernels.rk_trial`` on every lane of a block at once, lane l with step hl[l]:
    leaves ynew, Kb[S] = f(ynew) and err[l], the scaled error norm of lane l. Each sum over
    the stages runs over the whole block at a time (stage outermost, every component of
    every lane innermost: one long vectorised loop), in the stages' order, so every
    component gets the operations of ``rk_trial`` in its order. acc: (ny, L) scratch."""
    ny, L = y.shape
    S = Bw.shape[0]
    M = ny * L
    af = acc.reshape(M)
    tf = tmp.reshape(M)
    Kf = Kb.reshape((S + 1, M))
    yf = y.reshape(M)
    idx = np.empty(S + 1, dtype=np.int64)
    hf = np.empty(M)
    for j in range(ny):
        for l in range(L):
            hf[j * L + l] = hl[l]
    for s in range(1, S):
        _stage_lanes(yf, hf, Kf, A[s], s, af, tf, idx)
        kernels.forces_block(tmp, g, P, FL, LO, 0.0, Kb[s], f)
    _stage_lanes(yf, hf, Kf, Bw, S, af, ynew.reshape(M), idx)
    kernels.forces_block(ynew, g, P, FL, LO, 0.0, Kb[S], f)
    # the error estimates: acc the 5th-order one, tmp the 3rd-order one
    _combine(Kf, E5, S + 1, af, idx)
    _combine(Kf, E3, S + 1, tf, idx)
    e5 = np.zeros(L)
    e3 = np.zeros(L)
    for j in range(ny):
        base = rtol * scale_abs[j]
        for l in range(L):
            sc = base
            if rel[j] != 0:
                sc += rtol * max(abs(y[j, l]), abs(ynew[j, l]))
            if sc > 0.0:
                e5[l] += (acc[j, l] / sc) ** 2
                e3[l] += (tmp[j, l] / sc) ** 2
    for l in range(L):
        err[l] = kernels.error_norm(e5[l], e3[l], hl[l], ny, dopnorm)


@njit(parallel=True, cache=True, error_model="numpy")
def run_events_lanes(Y, QUEUE, QLEN, L, T, H, ERROLD, STEPS, REJ, NEV, STATUS, VTHR, gaps, P,
                     FL, LO, scale_abs, rel, rtol, band, land, A, Bw, E5, E3, qexp, dopnorm,
                     t_stop, auto_stop, VMAX, TPK, PASSED, RUNEND, CLIMB, RB, RBN, DROP, VINIT,
                     E0, BAL):
    """The event method without a trace, in lanes: advance every chain until it stops.

    Chains are indexed b as in ``run_events`` (Y[b] the initial state on entry, the final
    state on return; gaps[b] its rows; the per-chain counters and running observables the
    same). Block k of QUEUE.shape[0] runs the chains QUEUE[k, :QLEN[k]] in order on L
    lanes, a lane taking the next chain of the queue when its chain stops. Every chain
    ends with STATUS[b] set (kernels.S_*), exactly as ``run_events`` leaves it.
    """
    nblk = QUEUE.shape[0]
    n = int(P[kernels.P_N_SPHERES])
    ny = Y.shape[1]
    ng = gaps.shape[1]
    S = Bw.shape[0]
    ov = LO[kernels.L_VEL]
    ox = LO[kernels.L_DISP]
    dscale = scale_abs[ox]
    for blk in prange(nblk):
        if QLEN[blk] == 0:
            continue
        Pb, FLb, LOb, sab, relb = P.copy(), FL.copy(), LO.copy(), scale_abs.copy(), rel.copy()
        Ab, Bwb, E5b, E3b = A.copy(), Bw.copy(), E5.copy(), E3.copy()
        y = np.zeros((ny, L))
        ynew = np.zeros((ny, L))
        tmp = np.zeros((ny, L))
        Z = np.zeros((ny, L))
        Kz = np.zeros((ny, L))
        Kb = np.zeros((S + 1, ny, L))
        f = np.zeros((n, L))
        g = np.zeros((ng, L))
        ebuf = np.zeros((kernels.E_LEN, L))
        acc = np.zeros((ny, L))
        err = np.zeros(L)
        hl = np.zeros(L)
        tau = np.zeros(L)
        lane_b = np.full(L, -1, dtype=np.int64)
        phase = np.full(L, _PH_EMPTY, dtype=np.int64)
        fresh = np.zeros(L, dtype=np.bool_)
        tries = np.zeros(L, dtype=np.int64)
        clipped = np.zeros(L, dtype=np.bool_)
        rejected = np.zeros(L, dtype=np.bool_)
        accepted = np.zeros(L, dtype=np.bool_)
        ok = np.zeros(L, dtype=np.bool_)
        same = np.zeros(L, dtype=np.bool_)
        refresh = np.zeros(L, dtype=np.bool_)
        t_old = np.zeros(L)
        fin = np.zeros(L, dtype=np.int64)
        # the lane's chain's time, step size, last error and counters
        tl = np.zeros(L)
        Hl = np.zeros(L)
        eol = np.zeros(L)
        stl = np.zeros(L, dtype=np.int64)
        rjl = np.zeros(L, dtype=np.int64)
        nvl = np.zeros(L, dtype=np.int64)
        c = np.empty(5)
        # empty lanes hold the rows of the block's first chain (positive masses), at rest
        b0 = QUEUE[blk, 0]
        for l in range(L):
            for r in range(ng):
                g[r, l] = gaps[b0, r]
        qpos = 0
        while True:
            # lanes without a running step: stop finished chains, refill
            while True:
                for l in range(L):
                    if phase[l] == _PH_EMPTY and qpos < QLEN[blk]:
                        b = QUEUE[blk, qpos]
                        qpos += 1
                        lane_b[l] = b
                        for j in range(ny):
                            y[j, l] = Y[b, j]
                        for r in range(ng):
                            g[r, l] = gaps[b, r]
                        tl[l] = T[b]
                        Hl[l] = H[b]
                        eol[l] = ERROLD[b]
                        stl[l] = STEPS[b]
                        rjl[l] = REJ[b]
                        nvl[l] = NEV[b]
                        fin[l] = kernels.S_RUNNING
                        fresh[l] = True
                        phase[l] = _PH_BEGIN
                any_fresh = False
                for l in range(L):
                    any_fresh = any_fresh or fresh[l]
                if any_fresh:
                    # the new chains' first derivative and energies (run_events' INIT)
                    kernels.forces_block(y, g, Pb, FLb, LOb, 0.0, Kz, f)
                    kernels.energies_block(y, g, Pb, FLb, LOb, ebuf)
                    for l in range(L):
                        if not fresh[l]:
                            continue
                        fresh[l] = False
                        b = lane_b[l]
                        for j in range(ny):
                            Kb[0, j, l] = Kz[j, l]
                        nvl[l] += 1
                        E0[b] = (ebuf[kernels.E_KIN_TRANS, l] + ebuf[kernels.E_KIN_ROT, l]
                                 + ebuf[kernels.E_POT, l])
                        for i in range(n):
                            VINIT[b, i] = y[ov + i, l]
                            VMAX[b, i] = y[ov + i, l]
                            TPK[b, i] = 0.0
                            RUNEND[b, i] = -1.0
                            CLIMB[b, i, :, RB_T0] = -1.0
                        if t_stop[b] <= 0.0:
                            fin[l] = kernels.S_DONE
                again = False
                for l in range(L):
                    if phase[l] != _PH_BEGIN:
                        continue
                    b = lane_b[l]
                    if fin[l] == kernels.S_RUNNING and tl[l] >= t_stop[b] * (1.0 - 1e-14):
                        fin[l] = kernels.S_DONE
                    if fin[l] != kernels.S_RUNNING:
                        STATUS[b] = fin[l]
                        T[b] = tl[l]
                        H[b] = Hl[l]
                        ERROLD[b] = eol[l]
                        STEPS[b] = stl[l]
                        REJ[b] = rjl[l]
                        NEV[b] = nvl[l]
                        for j in range(ny):
                            Y[b, j] = y[j, l]
                            y[j, l] = 0.0
                            Kb[0, j, l] = 0.0
                        for r in range(ng):
                            g[r, l] = gaps[b0, r]
                        lane_b[l] = -1
                        phase[l] = _PH_EMPTY
                        hl[l] = 0.0
                        if qpos < QLEN[blk]:
                            again = True
                if not again:
                    break
            # the lanes that begin a step: its size, clipped at the first predicted
            # contact event (every lane at once)
            _predict(y, Kb[0], g, LOb, n, band, dscale, tau)
            busy = False
            for l in range(L):
                if phase[l] == _PH_BEGIN:
                    b = lane_b[l]
                    t = tl[l]
                    h = min(Hl[l], t_stop[b] - t)
                    clipped[l] = h < Hl[l]
                    if tau[l] < h:
                        h = tau[l]
                        clipped[l] = True
                    hl[l] = h
                    t_old[l] = t
                    tries[l] = 0
                    rejected[l] = False
                    phase[l] = _PH_TRIAL
                busy = busy or phase[l] == _PH_TRIAL
            if not busy:
                break
            _rk_trial_lanes(y, hl, g, Pb, FLb, LOb, Kb, ynew, tmp, f, acc, sab, relb, rtol,
                            Ab, Bwb, E5b, E3b, dopnorm, err)
            # error control, lane by lane; ok: the lanes whose error passes
            any_ok = False
            for l in range(L):
                accepted[l] = False
                ok[l] = False
                if phase[l] != _PH_TRIAL:
                    continue
                tries[l] += 1
                nvl[l] += S
                h = hl[l]
                e = err[l]
                if not math.isfinite(e):
                    rjl[l] += 1
                    rejected[l] = True
                    h = 0.1 * h
                    Hl[l] = h
                    clipped[l] = False
                    if h < 1e-22:
                        fin[l] = kernels.S_NONFINITE
                        phase[l] = _PH_BEGIN
                elif e > 1.0:
                    rjl[l] += 1
                    rejected[l] = True
                    h = h * max(0.2, 0.9 * e ** (-qexp))
                    Hl[l] = h
                    clipped[l] = False
                    if h < 1e-22:
                        fin[l] = kernels.S_STEPFAIL
                        phase[l] = _PH_BEGIN
                else:
                    ok[l] = True
                    any_ok = True
                hl[l] = h
            # the events inside the step, every lane at once, in run_events' order: a
            # lane with one is retried up to it
            if any_ok:
                _straddle(y, ynew, g, LOb, n, band, hl, ok, tau)
                any_ok = _retry(tau, hl, ok, rjl, clipped, 1e-22)
            if any_ok:
                locate(y, ynew, Kb[0], Kb[S], g, Pb, FLb, LOb, n, hl, rtol, ok, tau)
                any_ok = _retry(tau, hl, ok, rjl, clipped, 1e-22)
            if any_ok:
                _peak_inside(y, ynew, Kb[0], Kb[S], LOb, n, hl, VMAX, lane_b, land, c, ok,
                             tau)
                any_ok = _retry(tau, hl, ok, rjl, clipped, 0.0)
            for l in range(L):
                if ok[l]:
                    b = lane_b[l]
                    accepted[l] = True
                    h = hl[l]
                    eo = max(eol[l], 1e-4)
                    ec = max(err[l], 1e-10)
                    fac = min(10.0, 0.9 * ec ** (-(qexp - 0.75 * PI_BETA)) * eo ** PI_BETA)
                    eol[l] = ec
                    if rejected[l]:
                        fac = min(1.0, fac)
                    if not clipped[l]:
                        Hl[l] = h * fac
                    _observe(t_old[l], h, y, ynew, Kb[0], Kb[S], LOb, n, b, l, VMAX, TPK,
                             PASSED, RUNEND, CLIMB, RB, RBN, DROP, c)
                elif phase[l] == _PH_TRIAL and tries[l] >= MAX_TRIES:
                    fin[l] = kernels.S_STEPFAIL
                    phase[l] = _PH_BEGIN
            if not any_ok:
                continue
            # the accepted lanes take their new states: the return mapping, the derivative
            # at the new state (the last stage's unless the mapping moved the state), the
            # time, the energy balance and the stop rules
            for j in range(ny):
                for l in range(L):
                    Z[j, l] = ynew[j, l] if accepted[l] else 0.0
            kernels.project_block(Z, g, Pb, FLb, LOb, f)
            for l in range(L):
                same[l] = True
            for j in range(ny):
                for l in range(L):
                    same[l] = same[l] & (Z[j, l] == ynew[j, l])
                    y[j, l] = Z[j, l] if accepted[l] else y[j, l]
            any_refresh = False
            for l in range(L):
                refresh[l] = accepted[l] and not same[l]
                same[l] = accepted[l] and same[l]
                any_refresh = any_refresh or refresh[l]
            for j in range(ny):
                for l in range(L):
                    Kb[0, j, l] = Kb[S, j, l] if same[l] else Kb[0, j, l]
            if any_refresh:
                kernels.forces_block(Z, g, Pb, FLb, LOb, 0.0, Kz, f)
                for j in range(ny):
                    for l in range(L):
                        Kb[0, j, l] = Kz[j, l] if refresh[l] else Kb[0, j, l]
                for l in range(L):
                    if refresh[l]:
                        nvl[l] += 1
            kernels.energies_block(Z, g, Pb, FLb, LOb, ebuf)
            # same[l]: lane l's new state is finite
            for l in range(L):
                same[l] = True
            for j in range(ox, ov + n):
                for l in range(L):
                    same[l] = same[l] & (abs(y[j, l]) < math.inf)
            for l in range(L):
                if not accepted[l]:
                    continue
                b = lane_b[l]
                tl[l] = t_old[l] + hl[l]
                stl[l] += 1
                tot = (ebuf[kernels.E_KIN_TRANS, l] + ebuf[kernels.E_KIN_ROT, l]
                       + ebuf[kernels.E_POT, l])
                work = ebuf[kernels.E_POT + 1, l]
                for q in range(kernels.E_POT + 2, kernels.E_LEN):
                    work += ebuf[q, l]
                bal = abs(tot - E0[b] - work)
                if bal > BAL[b]:
                    BAL[b] = bal
                if not same[l]:
                    fin[l] = kernels.S_NONFINITE
                elif auto_stop and kernels._settled(y, g, Pb, FLb, LOb, n, l, VTHR[b], False):
                    fin[l] = kernels.S_PASSED
                phase[l] = _PH_BEGIN


@njit(cache=True, inline="always")
def _retry(tau, hl, ok, rjl, clipped, hmin):
    """The lanes of ok with an event at tau[l] > 0 inside their step are retried up to it
    (step tau h, at least hmin); returns whether any lane of ok is left."""
    left = False
    for l in range(ok.shape[0]):
        if ok[l] and tau[l] > 0.0:
            rjl[l] += 1
            hl[l] = max(tau[l] * hl[l], hmin) if hmin > 0.0 else tau[l] * hl[l]
            clipped[l] = True
            ok[l] = False
        left = left or ok[l]
    return left
