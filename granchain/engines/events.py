"""Event-driven adaptive integration of the reference engine (scene method ``event``).

An embedded Runge-Kutta pair with FSAL (Dormand-Prince 8(5,3), the tableau of
``kernels``, or Dormand-Prince 5(4)) with error control, whose steps are not tied to an
output grid, plus event location:

- contact onset and release: the Hertz force K d^1.5 is not smooth at d = 0, so no step
  may carry a contact across it. Before a step, the overlap d of every pair is predicted
  from its relative velocity and acceleration (d + w s + a s^2 / 2) and the step is
  clipped at the first predicted crossing of 0; after a trial step, a pair whose overlap
  went from below -band to above +band (or back), or whose overlap rose above +band
  inside the step (a whole contact inside one step), makes the step be retried up to the
  first root of the cubic Hermite of d(t) on the trial step. ``band`` is the relative
  tolerance times the overlap scale: a step may end anywhere within the band.
- record peaks: a step inside which a particle's velocity reaches a new maximum (its
  acceleration changes sign from + to -) by more than the tolerance above both step ends
  is retried up to the interpolated peak time, so the peak lies on a step end.

- an effect's own switches (``locate``, ``engines.compose``): a trial step inside which
  one happens (the groove's stick/slip: its trial force k_g xi + gamma_g u crosses the
  Coulomb cap, beyond a band of the tolerance times the cap; a plastic contact's yield,
  largest overlap and plastic overlap; an adhesive contact's jumps of force, each
  crossed in a short step of its own) is retried up to it, located the same way.
  Switches an effect does not locate (the contact and rolling friction's) are left to
  the error control.

Observables are computed on the fly (no output grid caps the step). Per step and
particle, the velocity between the step ends is the derivative of the quintic Hermite
interpolant of the displacement (displacement, velocity and acceleration at both ends).
Per particle the engine keeps the running maximum (v_max and its time), the steps that
set a record (their interpolants; steps whose maximum is below half the running maximum
are dropped, since the half-peak level can only rise; when RB_SIZE are kept, the two
shortest adjacent ones of the older half are merged into one cubic Hermite), whether the velocity has fallen
below PASS_FRACTION of the running maximum after it (the wave has passed:
``granchain.stoprule``) and when it first fell below (1 - PEAK_TOL) of it (end of the
near-peak run). At the end, ``finalize`` gives per particle: v_max; the front time
t_front, the first crossing of v_max / 2 (found in the first record step whose maximum
reaches it: before that step the velocity never exceeded it); the plateau flag, set when
the run within PEAK_TOL of v_max that holds the maximum (from the first crossing of
(1 - PEAK_TOL) v_max, or from the velocity's climb back through it after a dip below it
before the maximum, ``eventobs``) until the end of the near-peak run, holds more than
PLATEAU_SAMPLES instants of the sample grid (``obsrules.grid_samples``: the sampled rule of ``granchain.observables``, which
counts the near-peak samples, applied to the continuous run); t_peak, the
time of the maximum, or for a plateau the first crossing of (1 - PEAK_TOL) v_max. The
energy balance error is the largest |balance| / E0 over all step ends.

With a trace asked for, the state is also interpolated (quintic Hermite for displacements
and velocities, cubic Hermite for the other components) onto the usual sample grid.

Here: the event location and ``run_events`` (one chain per thread); the observables are in
``engines.eventobs``, the interpolants in ``engines.hermite``, the same method in SIMD
lanes in ``engines.eventlanes``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import kernels
from .codes import DEFAULT_PAIR, PAIRS, RB_C, RB_H, RB_LEN, RB_MAX, RB_SIZE, RB_T0  # noqa: F401
from .compose import locate
from .eventobs import _observe, _peak_inside, finalize  # noqa: F401
from .hermite import dense, hermite_root
from .integrators import _col
from .kernels import energies, forces, project

MAX_TRIES = 60
PI_BETA = 0.04


@njit(cache=True, error_model="numpy", boundscheck=False)
def _predict(y, dy, gaps, LO, n, band, dscale, best):
    """Per lane l of a block (y, dy (ny, L), gaps (ng, L)): best[l], the time to the
    first predicted crossing of 0 by a pair's overlap (inf if none); for a pair on its
    onset, the time to close by the overlap scale dscale.

    Every lane at once, without a branch per lane: each candidate time is computed and
    the one that applies selected (a division by zero gives a value that is not
    selected), so that the loops over the lanes vectorise."""
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    L = y.shape[1]
    for l in range(L):
        best[l] = math.inf
    for k in range(n - 1):
        for l in range(L):
            d = y[ox + k, l] - y[ox + k + 1, l] - gaps[k, l]
            w = y[ov + k, l] - y[ov + k + 1, l]
            a = dy[ov + k, l] - dy[ov + k + 1, l]
            # on the onset or release: a first step into the contact no longer than
            # the time to close to the overlap scale at the pair's speed
            s_on = dscale / w if w > 0.0 else math.inf
            # else 0.5 a s^2 + w s + d = 0, smallest positive root
            qa = 0.5 * a
            r = -d / w
            s_lin = r if (w != 0.0) & (r > 0.0) else math.inf
            disc = w * w - 4.0 * qa * d
            sq = math.sqrt(max(disc, 0.0))
            q = -0.5 * (w + (sq if w >= 0.0 else -sq))
            r1 = q / qa
            r2 = d / q
            s_q = r1 if (r1 > 0.0) & (r1 < math.inf) else math.inf
            s_q = r2 if (r2 > 0.0) & (r2 < s_q) else s_q
            s_q = s_q if (disc >= 0.0) & (q != 0.0) else math.inf
            s = s_on if abs(d) <= band else (s_lin if qa == 0.0 else s_q)
            best[l] = s if s < best[l] else best[l]


@njit(cache=True, error_model="numpy", boundscheck=False)
def _straddle(y, ynew, gaps, LO, n, band, h, act, tau):
    """After a trial step, per lane l of a block with act[l]: tau[l], the first tau in
    (0, 1) at which a pair's overlap crosses its band (onset or release inside the lane's
    step of length h[l]), or -1 if none does (-1 in every other lane). The test runs over
    all lanes at once; the root is found only in the lanes where an overlap crosses."""
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    L = y.shape[1]
    for l in range(L):
        tau[l] = -1.0
    for k in range(n - 1):
        for l in range(L):
            d0 = y[ox + k, l] - y[ox + k + 1, l] - gaps[k, l]
            d1 = ynew[ox + k, l] - ynew[ox + k + 1, l] - gaps[k, l]
            w0 = y[ov + k, l] - y[ov + k + 1, l]
            w1 = ynew[ov + k, l] - ynew[ov + k + 1, l]
            cross = (((d0 < -band) & ((d1 > band) | ((w0 > 0.0) & (w1 < 0.0))))
                     | ((d0 > band) & (d1 < -band)))
            tau[l] = 1.0 if cross else tau[l]
    for l in range(L):
        if tau[l] > 0.0 and act[l]:
            tau[l] = _straddle_lane(y, ynew, gaps, ox, ov, n, band, h[l], l)
        else:
            tau[l] = -1.0


@njit(cache=True)
def _straddle_lane(y, ynew, gaps, ox, ov, n, band, h, l):
    """``_straddle`` in lane l: the first crossing inside its step, -1 if none."""
    best = 2.0
    for k in range(n - 1):
        d0 = y[ox + k, l] - y[ox + k + 1, l] - gaps[k, l]
        d1 = ynew[ox + k, l] - ynew[ox + k + 1, l] - gaps[k, l]
        w0 = y[ov + k, l] - y[ov + k + 1, l]
        w1 = ynew[ov + k, l] - ynew[ov + k + 1, l]
        tau = -1.0
        if d0 < -band and (d1 > band or (w0 > 0.0 and w1 < 0.0)):
            tau = hermite_root(d0, w0, d1, w1, h, 0.0, True)
        elif d0 > band and d1 < -band:
            tau = hermite_root(d0, w0, d1, w1, h, 0.0, False)
        if tau > 0.0 and tau < best:
            best = tau
    return best if best < 1.0 else -1.0


@njit(cache=True)
def _mech_balance(y, gaps, P, FL, LO, ebuf, e0):
    energies(y, gaps, P, FL, LO, ebuf)
    tot = ebuf[kernels.E_KIN_TRANS] + ebuf[kernels.E_KIN_ROT] + ebuf[kernels.E_POT]
    # every work column (they follow the mechanical energies, codes.E_SLOTS)
    work = ebuf[kernels.E_POT + 1]
    for c in range(kernels.E_POT + 2, kernels.E_LEN):
        work += ebuf[c]
    return abs(tot - e0 - work)


@njit(cache=True)
def _flush(b, y, k1, g, P, FL, LO, n, sdt, NT, NS, YP, KP, TP, T, Vout, Eout, counts,
           tmp, ebuf):
    """Trace samples due inside the last step, while the window has room."""
    W = Vout.shape[1]
    ov = LO[kernels.L_VEL]
    hp = T[b] - TP[b]
    while (counts[b] < W and NS[b] < NT[b] and hp > 0.0
           and NS[b] * sdt <= T[b] * (1.0 + 1e-13)):
        tau = min(1.0, max(0.0, (NS[b] * sdt - TP[b]) / hp))
        dense(YP[b], KP[b], y, k1, hp, tau, LO, n, tmp)
        cc = counts[b]
        for i in range(n):
            Vout[b, cc, i] = tmp[ov + i]
        energies(tmp, g, P, FL, LO, ebuf)
        Eout[b, cc, :] = ebuf
        counts[b] = cc + 1
        NS[b] += 1


@njit(parallel=True, cache=True)
def run_events(Y, KST, T, H, ERROLD, STEPS, REJ, NEV, STATUS, FIN, INIT, VTHR, gaps, P, FL, LO,
               scale_abs, rel, rtol, band, land, A, Bw, E5, E3, qexp, dopnorm,
               t_stop, auto_stop, VMAX, TPK, PASSED, RUNEND, CLIMB, RB, RBN, DROP, VINIT,
               E0, BAL, trace, sdt, NT, NS, YP, KP, TP, Vout, Eout, counts):
    """Advance every running chain until it stops (without trace), or until its window
    of Vout.shape[1] trace samples is full.

    Per chain b: Y[b] state, KST[b, 0] its derivative, T[b] time, H[b] proposed step,
    STEPS/REJ/NEV steps, rejected trials (error control and event location) and force
    evaluations, STATUS[b] (kernels.S_*; a stopped chain keeps S_RUNNING with its final
    status in FIN[b] until its last trace samples are out), INIT[b] 0 before the first
    call. A chain stops at t_stop[b] (S_DONE) or, with auto_stop, at the first step end
    at which the stop rule holds (S_PASSED, ``kernels._settled``: its last particle has
    taken the wave and left, ``stoprule.last_detached``, and no contact is held closed
    undecided).
    """
    B = Y.shape[0]
    n = int(P[kernels.P_N_SPHERES])
    ny = Y.shape[1]
    S = Bw.shape[0]
    ov = LO[kernels.L_VEL]
    ox = LO[kernels.L_DISP]
    W = Vout.shape[1]
    dscale = scale_abs[ox]
    for b in prange(B):
        counts[b] = 0
        if STATUS[b] != kernels.S_RUNNING:
            continue
        y = Y[b]
        Kst = KST[b]
        g = gaps[b]
        f = np.zeros(n)
        ynew = np.empty(ny)
        tmp = np.empty(ny)
        ebuf = np.empty(kernels.E_LEN)
        c = np.empty(5)
        # the lane functions' arguments for a block of one lane: this chain
        yc, ync, gc, K0c, KSc = _col(y), _col(ynew), _col(g), _col(Kst[0]), _col(Kst[S])
        hv = np.empty(1)
        tv = np.empty(1)
        act = np.ones(1, dtype=np.bool_)
        lane_b = np.full(1, b, dtype=np.int64)
        if INIT[b] == 0:
            INIT[b] = 1
            forces(y, g, P, FL, LO, 0.0, Kst[0], f)
            NEV[b] += 1
            energies(y, g, P, FL, LO, ebuf)
            E0[b] = ebuf[kernels.E_KIN_TRANS] + ebuf[kernels.E_KIN_ROT] + ebuf[kernels.E_POT]
            for i in range(n):
                VINIT[b, i] = y[ov + i]
                VMAX[b, i] = y[ov + i]
                TPK[b, i] = 0.0
                RUNEND[b, i] = -1.0
                CLIMB[b, i, :, RB_T0] = -1.0
            if trace:
                for i in range(n):
                    Vout[b, 0, i] = y[ov + i]
                Eout[b, 0, :] = ebuf
                counts[b] = 1
                NS[b] = 1
                for j in range(ny):
                    YP[b, j] = y[j]
                    KP[b, j] = Kst[0, j]
                TP[b] = 0.0
            if t_stop[b] <= 0.0:
                FIN[b] = kernels.S_DONE
        while True:
            if trace:
                _flush(b, y, Kst[0], g, P, FL, LO, n, sdt, NT, NS, YP, KP, TP, T, Vout,
                       Eout, counts, tmp, ebuf)
                if counts[b] >= W:
                    break
            if FIN[b] != kernels.S_RUNNING:
                STATUS[b] = FIN[b]
                break
            t = T[b]
            if t >= t_stop[b] * (1.0 - 1e-14):
                FIN[b] = kernels.S_DONE
                continue
            h = min(H[b], t_stop[b] - t)
            clipped = h < H[b]
            _predict(yc, K0c, gc, LO, n, band, dscale, tv)
            s_ev = tv[0]
            if s_ev < h:
                h = s_ev
                clipped = True
            tries = 0
            accepted = False
            rejected = False
            while tries < MAX_TRIES:
                tries += 1
                err = kernels.rk_trial(y, h, g, P, FL, LO, Kst, ynew, tmp, f, scale_abs, rel,
                                       rtol, A, Bw, E5, E3, dopnorm)
                NEV[b] += S
                if not math.isfinite(err):
                    # a trial step far too long (into a stiff contact): shrink hard
                    REJ[b] += 1
                    rejected = True
                    h = 0.1 * h
                    H[b] = h
                    clipped = False
                    if h < 1e-22:
                        FIN[b] = kernels.S_NONFINITE
                        break
                    continue
                if err > 1.0:
                    REJ[b] += 1
                    rejected = True
                    h = h * max(0.2, 0.9 * err ** (-qexp))
                    H[b] = h
                    clipped = False
                    if h < 1e-22:
                        FIN[b] = kernels.S_STEPFAIL
                        break
                    continue
                hv[0] = h
                _straddle(yc, ync, gc, LO, n, band, hv, act, tv)
                tau = tv[0]
                if tau > 0.0:
                    REJ[b] += 1
                    h = max(tau * h, 1e-22)
                    clipped = True
                    continue
                locate(yc, ync, K0c, KSc, gc, P, FL, LO, n, hv, rtol, act, tv)
                tau = tv[0]
                if tau > 0.0:
                    REJ[b] += 1
                    h = max(tau * h, 1e-22)
                    clipped = True
                    continue
                _peak_inside(yc, ync, K0c, KSc, LO, n, hv, VMAX, lane_b, land, c, act, tv)
                tau = tv[0]
                if tau > 0.0:
                    REJ[b] += 1
                    h = tau * h
                    clipped = True
                    continue
                accepted = True
                # PI step control (Gustafsson; beta = PI_BETA): steadier at the stability
                # limit of a stiff mode than the plain err^(-1/q) rule
                eo = max(ERROLD[b], 1e-4)
                ec = max(err, 1e-10)
                fac = min(10.0, 0.9 * ec ** (-(qexp - 0.75 * PI_BETA)) * eo ** PI_BETA)
                ERROLD[b] = ec
                if rejected:
                    # no growth right after a rejection: at the stability limit of a
                    # stiff mode (groove stick, a resting contact) growth-and-reject
                    # would alternate step after step
                    fac = min(1.0, fac)
                if not clipped:
                    H[b] = h * fac
                break
            if not accepted:
                if FIN[b] == kernels.S_RUNNING:
                    FIN[b] = kernels.S_STEPFAIL
                continue
            _observe(t, h, yc, ync, K0c, KSc, LO, n, b, 0, VMAX, TPK, PASSED, RUNEND, CLIMB,
                     RB, RBN, DROP, c)
            if trace:
                for j in range(ny):
                    YP[b, j] = y[j]
                    KP[b, j] = Kst[0, j]
                TP[b] = t
            for j in range(ny):
                y[j] = ynew[j]
            project(y, g, P, FL, LO, f)
            same = True
            for j in range(ny):
                if y[j] != ynew[j]:
                    same = False
                    break
            if same:
                for j in range(ny):
                    Kst[0, j] = Kst[S, j]
            else:
                forces(y, g, P, FL, LO, 0.0, Kst[0], f)
                NEV[b] += 1
            T[b] = t + h
            STEPS[b] += 1
            bal = _mech_balance(y, g, P, FL, LO, ebuf, E0[b])
            if bal > BAL[b]:
                BAL[b] = bal
            if not kernels._finite(y, LO, n):
                FIN[b] = kernels.S_NONFINITE
            elif auto_stop and kernels._settled(_col(y), _col(g), P, FL, LO, n, 0, VTHR[b],
                                                False):
                FIN[b] = kernels.S_PASSED
