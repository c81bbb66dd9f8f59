"""The event method (``engines.events``) across chains, in SIMD lanes.

Blocks of L lanes, each lane one chain, stepped in lock step. Each lane keeps its own step
size, its own trial and its own acceptance; a step that one lane rejects (error control,
an event located inside it) is simply that lane's next trial while its neighbours go on. A
lane whose chain stops takes the next chain of its block's queue. The force evaluations
and the Runge-Kutta stages of all lanes run together (``integrators.forces_block``, lanes
innermost: vectorised across chains); the per-lane decisions (event prediction and
location, peaks, observables) run the same functions as ``events.run_events`` on a copy
of the lane. A lane's arithmetic is that of ``run_events`` operation for operation, so a
chain's result does not depend on its lane, its block or its neighbours (bit for bit;
tested against ``run_events``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import kernels
from .compose import locate
from .eventobs import _observe, _peak_inside
from .events import MAX_TRIES, PI_BETA, _detached, _predict, _straddle

_PH_BEGIN, _PH_TRIAL, _PH_EMPTY = 0, 1, 2


@njit(cache=True, inline="always")
def _stage_lanes(y, hl, Kf, coef, nq, af, acc, out):
    """out = y + h_l sum_{q < nq} coef[q] K_q on every lane l: the sum over the whole block
    at a time (af, the flat view of acc), in the stages' order."""
    ny, L = y.shape
    af[:] = 0.0
    for q in range(nq):
        a = coef[q]
        for m in range(af.shape[0]):
            af[m] += a * Kf[q, m]
    for j in range(ny):
        for l in range(L):
            out[j, l] = y[j, l] + hl[l] * acc[j, l]


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
    for s in range(1, S):
        _stage_lanes(y, hl, Kf, A[s], s, af, acc, tmp)
        kernels.forces_block(tmp, g, P, FL, LO, 0.0, Kb[s], f)
    _stage_lanes(y, hl, Kf, Bw, S, af, acc, ynew)
    kernels.forces_block(ynew, g, P, FL, LO, 0.0, Kb[S], f)
    # the error estimates: acc the 5th-order one, tmp the 3rd-order one
    af[:] = 0.0
    tf[:] = 0.0
    for q in range(S + 1):
        c5 = E5[q]
        c3 = E3[q]
        for m in range(M):
            af[m] += c5 * Kf[q, m]
            tf[m] += c3 * Kf[q, m]
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


@njit(cache=True, inline="always")
def _lane_out(a, l, out):
    for j in range(out.shape[0]):
        out[j] = a[j, l]


@njit(cache=True, inline="always")
def _stage_out(Kb, s, l, out):
    for j in range(out.shape[0]):
        out[j] = Kb[s, j, l]


@njit(parallel=True, cache=True, error_model="numpy")
def run_events_lanes(Y, QUEUE, QLEN, L, T, H, ERROLD, STEPS, REJ, NEV, STATUS, VTHR, gaps, P,
                     FL, LO, scale_abs, rel, rtol, band, land, A, Bw, E5, E3, qexp, dopnorm,
                     t_stop, auto_stop, VMAX, TPK, PASSED, RUNEND, RB, RBN, DROP, VINIT,
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
        lane_b = np.full(L, -1, dtype=np.int64)
        phase = np.full(L, _PH_EMPTY, dtype=np.int64)
        fresh = np.zeros(L, dtype=np.bool_)
        tries = np.zeros(L, dtype=np.int64)
        clipped = np.zeros(L, dtype=np.bool_)
        rejected = np.zeros(L, dtype=np.bool_)
        accepted = np.zeros(L, dtype=np.bool_)
        refresh = np.zeros(L, dtype=np.bool_)
        t_old = np.zeros(L)
        fin = np.zeros(L, dtype=np.int64)
        y1 = np.empty(ny)
        yn1 = np.empty(ny)
        k01 = np.empty(ny)
        ks1 = np.empty(ny)
        g1 = np.empty(ng)
        c = np.empty(5)
        # empty lanes hold the rows of the block's first chain (positive masses), at rest
        b0 = QUEUE[blk, 0]
        for l in range(L):
            for r in range(ng):
                g[r, l] = gaps[b0, r]
        qpos = 0
        while True:
            # lanes without a running step: stop finished chains, refill, start steps
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
                        fin[l] = kernels.S_RUNNING
                        fresh[l] = True
                        phase[l] = _PH_BEGIN
                any_fresh = False
                for l in range(L):
                    any_fresh = any_fresh or fresh[l]
                if any_fresh:
                    # the new chains' first derivative and energies (run_events' INIT)
                    kernels.forces_block(y, g, P, FL, LO, 0.0, Kz, f)
                    kernels.energies_block(y, g, P, FL, LO, ebuf)
                    for l in range(L):
                        if not fresh[l]:
                            continue
                        fresh[l] = False
                        b = lane_b[l]
                        for j in range(ny):
                            Kb[0, j, l] = Kz[j, l]
                        NEV[b] += 1
                        E0[b] = (ebuf[kernels.E_KIN_TRANS, l] + ebuf[kernels.E_KIN_ROT, l]
                                 + ebuf[kernels.E_POT, l])
                        for i in range(n):
                            VINIT[b, i] = y[ov + i, l]
                            VMAX[b, i] = y[ov + i, l]
                            TPK[b, i] = 0.0
                            RUNEND[b, i] = -1.0
                        if t_stop[b] <= 0.0:
                            fin[l] = kernels.S_DONE
                again = False
                for l in range(L):
                    if phase[l] != _PH_BEGIN:
                        continue
                    b = lane_b[l]
                    if fin[l] == kernels.S_RUNNING and T[b] >= t_stop[b] * (1.0 - 1e-14):
                        fin[l] = kernels.S_DONE
                    if fin[l] != kernels.S_RUNNING:
                        STATUS[b] = fin[l]
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
                        continue
                    t = T[b]
                    h = min(H[b], t_stop[b] - t)
                    clipped[l] = h < H[b]
                    _lane_out(y, l, y1)
                    _stage_out(Kb, 0, l, k01)
                    for r in range(ng):
                        g1[r] = g[r, l]
                    s_ev = _predict(y1, k01, g1, LO, n, band, dscale)
                    if s_ev < h:
                        h = s_ev
                        clipped[l] = True
                    hl[l] = h
                    t_old[l] = t
                    tries[l] = 0
                    rejected[l] = False
                    phase[l] = _PH_TRIAL
                if not again:
                    break
            busy = False
            for l in range(L):
                if phase[l] == _PH_TRIAL:
                    busy = True
            if not busy:
                break
            _rk_trial_lanes(y, hl, g, P, FL, LO, Kb, ynew, tmp, f, acc, scale_abs, rel, rtol,
                            A, Bw, E5, E3, dopnorm, err)
            any_acc = False
            for l in range(L):
                accepted[l] = False
                if phase[l] != _PH_TRIAL:
                    continue
                b = lane_b[l]
                tries[l] += 1
                NEV[b] += S
                h = hl[l]
                e = err[l]
                if not math.isfinite(e):
                    REJ[b] += 1
                    rejected[l] = True
                    h = 0.1 * h
                    H[b] = h
                    clipped[l] = False
                    if h < 1e-22:
                        fin[l] = kernels.S_NONFINITE
                        phase[l] = _PH_BEGIN
                elif e > 1.0:
                    REJ[b] += 1
                    rejected[l] = True
                    h = h * max(0.2, 0.9 * e ** (-qexp))
                    H[b] = h
                    clipped[l] = False
                    if h < 1e-22:
                        fin[l] = kernels.S_STEPFAIL
                        phase[l] = _PH_BEGIN
                else:
                    _lane_out(y, l, y1)
                    _lane_out(ynew, l, yn1)
                    for r in range(ng):
                        g1[r] = g[r, l]
                    tau = _straddle(y1, yn1, g1, LO, n, band, h)
                    if tau > 0.0:
                        REJ[b] += 1
                        h = max(tau * h, 1e-22)
                        clipped[l] = True
                    else:
                        _stage_out(Kb, 0, l, k01)
                        _stage_out(Kb, S, l, ks1)
                        tau = locate(y1, yn1, k01, ks1, g1, P, FL, LO, n, h, rtol)
                        if tau > 0.0:
                            REJ[b] += 1
                            h = max(tau * h, 1e-22)
                            clipped[l] = True
                        else:
                            tau = _peak_inside(y1, yn1, k01, ks1, LO, n, h, VMAX, b, land, c)
                            if tau > 0.0:
                                REJ[b] += 1
                                h = tau * h
                                clipped[l] = True
                            else:
                                accepted[l] = True
                                any_acc = True
                                eo = max(ERROLD[b], 1e-4)
                                ec = max(e, 1e-10)
                                fac = min(10.0, 0.9 * ec ** (-(qexp - 0.75 * PI_BETA))
                                          * eo ** PI_BETA)
                                ERROLD[b] = ec
                                if rejected[l]:
                                    fac = min(1.0, fac)
                                if not clipped[l]:
                                    H[b] = h * fac
                                _observe(t_old[l], h, y1, yn1, k01, ks1, LO, n, b, VMAX,
                                         TPK, PASSED, RUNEND, RB, RBN, DROP, c)
                hl[l] = h
                if phase[l] == _PH_TRIAL and not accepted[l] and tries[l] >= MAX_TRIES:
                    fin[l] = kernels.S_STEPFAIL
                    phase[l] = _PH_BEGIN
            if not any_acc:
                continue
            # the accepted lanes take their new states: the return mapping, the derivative
            # at the new state (the last stage's unless the mapping moved the state), the
            # time, the energy balance and the stop rules
            for j in range(ny):
                for l in range(L):
                    Z[j, l] = ynew[j, l] if accepted[l] else 0.0
            kernels.project_block(Z, g, P, FL, LO, f)
            any_refresh = False
            for l in range(L):
                refresh[l] = False
                if not accepted[l]:
                    continue
                same = True
                for j in range(ny):
                    if Z[j, l] != ynew[j, l]:
                        same = False
                    y[j, l] = Z[j, l]
                if same:
                    for j in range(ny):
                        Kb[0, j, l] = Kb[S, j, l]
                else:
                    refresh[l] = True
                    any_refresh = True
            if any_refresh:
                kernels.forces_block(Z, g, P, FL, LO, 0.0, Kz, f)
                for l in range(L):
                    if refresh[l]:
                        NEV[lane_b[l]] += 1
                        for j in range(ny):
                            Kb[0, j, l] = Kz[j, l]
            kernels.energies_block(Z, g, P, FL, LO, ebuf)
            for l in range(L):
                if not accepted[l]:
                    continue
                b = lane_b[l]
                T[b] = t_old[l] + hl[l]
                STEPS[b] += 1
                tot = (ebuf[kernels.E_KIN_TRANS, l] + ebuf[kernels.E_KIN_ROT, l]
                       + ebuf[kernels.E_POT, l])
                work = ebuf[kernels.E_POT + 1, l]
                for q in range(kernels.E_POT + 2, kernels.E_LEN):
                    work += ebuf[q, l]
                bal = abs(tot - E0[b] - work)
                if bal > BAL[b]:
                    BAL[b] = bal
                finite = True
                for j in range(ox, ov + n):
                    if not math.isfinite(y[j, l]):
                        finite = False
                if not finite:
                    fin[l] = kernels.S_NONFINITE
                elif auto_stop and _detached(y[ov + n - 1, l],
                                             y[ox + n - 2, l] - y[ox + n - 1, l] - g[n - 2, l],
                                             VTHR[b]):
                    fin[l] = kernels.S_PASSED
                phase[l] = _PH_BEGIN
