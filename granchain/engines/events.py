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

- groove stick/slip: a trial step inside which a sphere's groove trial force
  k_g xi + gamma_g u crosses the Coulomb cap (beyond a band of the tolerance times the
  cap) is retried up to the crossing, located the same way. The contact and rolling
  friction's transitions are not located: the error control takes them.

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
the velocity stays within PEAK_TOL of v_max from the first crossing of (1 - PEAK_TOL)
v_max until the end of the near-peak run for longer than PLATEAU_SAMPLES sample
intervals (the sampled rule of ``granchain.observables`` in continuous time); t_peak, the
time of the maximum, or for a plateau the first crossing of (1 - PEAK_TOL) v_max. The
energy balance error is the largest |balance| / E0 over all step ends.

With a trace asked for, the state is also interpolated (quintic Hermite for displacements
and velocities, cubic Hermite for the other components) onto the usual sample grid.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..stoprule import PASS_FRACTION, PEAK_TOL
from . import kernels
from .codes import DEFAULT_PAIR, PAIRS, RB_C, RB_H, RB_LEN, RB_MAX, RB_SIZE, RB_T0  # noqa: F401
from .compose import locate
from .hermite import hermite_root as _hermite_root, hermite3 as _hermite3
from .kernels import energies, forces, project

MAX_TRIES = 60
PI_BETA = 0.04


@njit(cache=True, inline="always")
def _poly_v(c, tau):
    return c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * c[4])))


@njit(cache=True, inline="always")
def _poly_dv(c, tau):
    return c[1] + tau * (2.0 * c[2] + tau * (3.0 * c[3] + tau * 4.0 * c[4]))


@njit(cache=True)
def _vcoef(x0, v0, a0, x1, v1, a1, h, c):
    """Coefficients of v(tau), tau in [0, 1], the derivative of the quintic Hermite
    interpolant of x (values, first and second derivatives at both ends)."""
    V0 = h * v0
    A0 = h * h * a0
    R0 = (x1 - x0) - V0 - 0.5 * A0
    R1 = h * v1 - V0 - A0
    R2 = h * h * a1 - A0
    c3 = 10.0 * R0 - 4.0 * R1 + 0.5 * R2
    c4 = -15.0 * R0 + 7.0 * R1 - R2
    c5 = 6.0 * R0 - 3.0 * R1 + 0.5 * R2
    c[0] = v0
    c[1] = A0 / h
    c[2] = 3.0 * c3 / h
    c[3] = 4.0 * c4 / h
    c[4] = 5.0 * c5 / h


@njit(cache=True)
def _x_interp(x0, v0, a0, x1, v1, a1, h, tau):
    """(x, v) of the quintic Hermite interpolant at tau."""
    V0 = h * v0
    A0 = h * h * a0
    R0 = (x1 - x0) - V0 - 0.5 * A0
    R1 = h * v1 - V0 - A0
    R2 = h * h * a1 - A0
    c3 = 10.0 * R0 - 4.0 * R1 + 0.5 * R2
    c4 = -15.0 * R0 + 7.0 * R1 - R2
    c5 = 6.0 * R0 - 3.0 * R1 + 0.5 * R2
    x = x0 + tau * (V0 + tau * (0.5 * A0 + tau * (c3 + tau * (c4 + tau * c5))))
    v = (V0 + tau * (A0 + tau * (3.0 * c3 + tau * (4.0 * c4 + tau * 5.0 * c5)))) / h
    return x, v


@njit(cache=True, inline="always")
def _v_bound(c):
    """An upper bound of v(tau) on [0, 1] (each term c_k tau^k at most max(0, c_k)), above
    any value ``_poly_v`` computes there: its margin, 1e-12 of the coefficients' magnitude,
    is far above their rounding errors (a few 1e-16)."""
    ub = c[0]
    mag = abs(c[0])
    for k in range(1, 5):
        ub += max(0.0, c[k])
        mag += abs(c[k])
    return ub + 1e-12 * mag


@njit(cache=True)
def _turn(c, lo, hi):
    """Root of dv/dtau on [lo, hi], where it changes sign (bisection)."""
    glo = _poly_dv(c, lo)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        gm = _poly_dv(c, mid)
        if (gm > 0.0) == (glo > 0.0):
            lo, glo = mid, gm
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True)
def _first_cross(c, level, lo, up):
    """First tau in [lo, 1] where v crosses ``level`` (upwards if up, else downwards);
    -1 if none is found on a 32-point scan."""
    M = 32
    sgn = 1.0 if up else -1.0
    a = lo
    fa = sgn * (_poly_v(c, a) - level)
    if fa >= 0.0:
        return a
    for k in range(1, M + 1):
        b = lo + (1.0 - lo) * k / M
        fb = sgn * (_poly_v(c, b) - level)
        if fb >= 0.0:
            for _ in range(60):
                mid = 0.5 * (a + b)
                if sgn * (_poly_v(c, mid) - level) >= 0.0:
                    b = mid
                else:
                    a = mid
            return 0.5 * (a + b)
        a = b
    return -1.0


@njit(cache=True)
def _predict(y, dy, gaps, LO, n, band, dscale):
    """Time to the first predicted crossing of 0 by a pair's overlap (inf if none); for
    a pair on its onset, the time to close by the overlap scale dscale."""
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    best = math.inf
    for k in range(n - 1):
        d = y[ox + k] - y[ox + k + 1] - gaps[k]
        w = y[ov + k] - y[ov + k + 1]
        if abs(d) <= band:
            # on the onset or release: a first step into the contact no longer than
            # the time to close to the overlap scale at the pair's speed
            if w > 0.0 and dscale / w < best:
                best = dscale / w
            continue
        a = dy[ov + k] - dy[ov + k + 1]
        # 0.5 a s^2 + w s + d = 0, smallest positive root
        qa = 0.5 * a
        s = math.inf
        if qa == 0.0:
            if w != 0.0:
                r = -d / w
                if r > 0.0:
                    s = r
        else:
            disc = w * w - 4.0 * qa * d
            if disc >= 0.0:
                sq = math.sqrt(disc)
                q = -0.5 * (w + (sq if w >= 0.0 else -sq))
                if q != 0.0:
                    r1 = q / qa
                    r2 = d / q
                    if r1 > 0.0 and r1 < s:
                        s = r1
                    if r2 > 0.0 and r2 < s:
                        s = r2
        if s < best:
            best = s
    return best


@njit(cache=True)
def _straddle(y, ynew, gaps, LO, n, band, h):
    """After a trial step: the first tau in (0, 1) at which a pair's overlap crosses its
    band (onset or release inside the step), or -1 if none does."""
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    best = 2.0
    for k in range(n - 1):
        d0 = y[ox + k] - y[ox + k + 1] - gaps[k]
        d1 = ynew[ox + k] - ynew[ox + k + 1] - gaps[k]
        w0 = y[ov + k] - y[ov + k + 1]
        w1 = ynew[ov + k] - ynew[ov + k + 1]
        tau = -1.0
        if d0 < -band and (d1 > band or (w0 > 0.0 and w1 < 0.0)):
            tau = _hermite_root(d0, w0, d1, w1, h, 0.0, True)
        elif d0 > band and d1 < -band:
            tau = _hermite_root(d0, w0, d1, w1, h, 0.0, False)
        if tau > 0.0 and tau < best:
            best = tau
    return best if best < 1.0 else -1.0


@njit(cache=True)
def _peak_inside(y, ynew, K0, K1, LO, n, h, VMAX, bc, land, c):
    """First tau in (0, 1) of a record-setting velocity maximum inside the step, more
    than ``land`` above both step ends; -1 if none. VMAX[bc]: the chain's running maxima."""
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    best = 2.0
    for i in range(n):
        a0 = K0[ov + i]
        a1 = K1[ov + i]
        if not (a0 > 0.0 and a1 < 0.0):
            continue
        _vcoef(y[ox + i], y[ov + i], a0, ynew[ox + i], ynew[ov + i], a1, h, c)
        ub = _v_bound(c)
        if ub <= VMAX[bc, i] or ub - max(y[ov + i], ynew[ov + i]) <= land:
            continue          # no maximum inside the step can pass either test
        tau = _turn(c, 0.0, 1.0)
        vp = _poly_v(c, tau)
        if vp > VMAX[bc, i] and vp - max(y[ov + i], ynew[ov + i]) > land and tau < best:
            best = tau
    return best if best < 1.0 else -1.0


@njit(cache=True)
def _merge_oldest(rb, m, DROP, i):
    """Make room in a full record-step buffer: merge the two adjacent steps (contiguous
    in time, in its older half) of shortest combined length into one, interpolated by
    the cubic Hermite of v and its slope at the outer ends; if no two are contiguous,
    the oldest step is lost (DROP: its crossings are unknown). Returns the new count."""
    best = -1
    blen = math.inf
    for q in range(max(1, m // 2)):
        t_end = rb[q, RB_T0] + rb[q, RB_H]
        if abs(t_end - rb[q + 1, RB_T0]) <= 1e-9 * rb[q, RB_H]:
            L = rb[q, RB_H] + rb[q + 1, RB_H]
            if L < blen:
                blen = L
                best = q
    if best < 0:
        DROP[i] = max(DROP[i], rb[0, RB_MAX])
        for q in range(1, m):
            rb[q - 1, :] = rb[q, :]
        return m - 1
    q = best
    h0 = rb[q, RB_H]
    h1 = rb[q + 1, RB_H]
    Hm = h0 + h1
    v0 = rb[q, RB_C]
    a0 = rb[q, RB_C + 1] / h0
    c1 = rb[q + 1, RB_C:RB_C + 5]
    v1 = _poly_v(c1, 1.0)
    a1 = _poly_dv(c1, 1.0) / h1
    dv = v1 - v0
    rb[q, RB_H] = Hm
    rb[q, RB_MAX] = max(rb[q, RB_MAX], rb[q + 1, RB_MAX])
    rb[q, RB_C] = v0
    rb[q, RB_C + 1] = Hm * a0
    rb[q, RB_C + 2] = 3.0 * dv - 2.0 * Hm * a0 - Hm * a1
    rb[q, RB_C + 3] = -2.0 * dv + Hm * a0 + Hm * a1
    rb[q, RB_C + 4] = 0.0
    for k in range(q + 2, m):
        rb[k - 1, :] = rb[k, :]
    return m - 1


@njit(cache=True)
def _observe(t0, h, y, ynew, K0, K1, LO, n, bc, VMAX, TPK, PASSED, RUNEND, RB, RBN, DROP, c):
    """Update the running per-particle observables of chain bc (row bc of VMAX ... DROP)
    with one accepted step."""
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    for i in range(n):
        v0 = y[ov + i]
        v1 = ynew[ov + i]
        a0 = K0[ov + i]
        a1 = K1[ov + i]
        built = False
        # largest velocity inside the step
        vmx = v1
        tmx = 1.0
        if v0 > vmx:
            vmx = v0
            tmx = 0.0
        if a0 > 0.0 and a1 < 0.0:
            _vcoef(y[ox + i], v0, a0, ynew[ox + i], v1, a1, h, c)
            built = True
            # a maximum that cannot set a record leaves every result below unchanged
            # (without it, vmx > VMAX[bc, i] only if an end of the step is above VMAX[bc, i])
            if _v_bound(c) > VMAX[bc, i]:
                tau = _turn(c, 0.0, 1.0)
                vp = _poly_v(c, tau)
                if vp > vmx:
                    vmx = vp
                    tmx = tau
        tafter = 0.0
        if vmx > VMAX[bc, i]:
            if not built:
                _vcoef(y[ox + i], v0, a0, ynew[ox + i], v1, a1, h, c)
                built = True
            VMAX[bc, i] = vmx
            TPK[bc, i] = t0 + tmx * h
            PASSED[bc, i] = 0
            RUNEND[bc, i] = -1.0
            tafter = tmx
            # drop record steps that cannot hold the half-peak crossing any more
            m = RBN[bc, i]
            keep = 0
            while keep < m and RB[bc, i, keep, RB_MAX] < 0.5 * vmx:
                keep += 1
            if keep > 0:
                for q in range(keep, m):
                    RB[bc, i, q - keep, :] = RB[bc, i, q, :]
                m -= keep
            if m == RB.shape[2]:
                m = _merge_oldest(RB[bc, i], m, DROP[bc], i)
            RB[bc, i, m, RB_T0] = t0
            RB[bc, i, m, RB_H] = h
            RB[bc, i, m, RB_MAX] = vmx
            for q in range(5):
                RB[bc, i, m, RB_C + q] = c[q]
            RBN[bc, i] = m + 1
        # after the peak: end of the near-peak run, and the pass rule
        if VMAX[bc, i] > 0.0 and (RUNEND[bc, i] < 0.0 or PASSED[bc, i] == 0):
            lo_run = (1.0 - PEAK_TOL) * VMAX[bc, i]
            lo_pass = PASS_FRACTION * VMAX[bc, i]
            vmn = min(v1, v0 if tafter == 0.0 else v1)
            interior = a0 < 0.0 and a1 > 0.0
            if vmn < lo_run or interior:
                if not built:
                    _vcoef(y[ox + i], v0, a0, ynew[ox + i], v1, a1, h, c)
                    built = True
                if RUNEND[bc, i] < 0.0:
                    tau = _first_cross(c, lo_run, tafter, False)
                    if tau >= 0.0:
                        RUNEND[bc, i] = t0 + tau * h
                if PASSED[bc, i] == 0:
                    tau = _first_cross(c, lo_pass, tafter, False)
                    if tau >= 0.0:
                        PASSED[bc, i] = 1


@njit(cache=True)
def _dense(yp, kp, y1, k1, h, tau, LO, n, out):
    """State at t0 + tau h inside the step yp -> y1 (derivatives kp, k1)."""
    ny = yp.shape[0]
    ox = LO[kernels.L_DISP]
    ov = LO[kernels.L_VEL]
    for j in range(ny):
        out[j] = _hermite3(yp[j], kp[j], y1[j], k1[j], h, tau)
    for i in range(n):
        x, v = _x_interp(yp[ox + i], yp[ov + i], kp[ov + i], y1[ox + i], y1[ov + i],
                         k1[ov + i], h, tau)
        out[ox + i] = x
        out[ov + i] = v


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
        _dense(YP[b], KP[b], y, k1, hp, tau, LO, n, tmp)
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
               t_stop, auto_stop, VMAX, TPK, PASSED, RUNEND, RB, RBN, DROP, VINIT,
               E0, BAL, trace, sdt, NT, NS, YP, KP, TP, Vout, Eout, counts):
    """Advance every running chain until it stops (without trace), or until its window
    of Vout.shape[1] trace samples is full.

    Per chain b: Y[b] state, KST[b, 0] its derivative, T[b] time, H[b] proposed step,
    STEPS/REJ/NEV steps, rejected trials (error control and event location) and force
    evaluations, STATUS[b] (kernels.S_*; a stopped chain keeps S_RUNNING with its final
    status in FIN[b] until its last trace samples are out), INIT[b] 0 before the first
    call. A chain stops at t_stop[b] (S_DONE) or, with auto_stop, at the first step end
    at which its last particle has taken the wave and left (S_PASSED,
    ``stoprule.last_detached``).
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
            s_ev = _predict(y, Kst[0], g, LO, n, band, dscale)
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
                tau = _straddle(y, ynew, g, LO, n, band, h)
                if tau > 0.0:
                    REJ[b] += 1
                    h = max(tau * h, 1e-22)
                    clipped = True
                    continue
                tau = locate(y, ynew, Kst[0], Kst[S], g, P, FL, LO, n, h, rtol)
                if tau > 0.0:
                    REJ[b] += 1
                    h = max(tau * h, 1e-22)
                    clipped = True
                    continue
                tau = _peak_inside(y, ynew, Kst[0], Kst[S], LO, n, h, VMAX, b, land, c)
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
            _observe(t, h, y, ynew, Kst[0], Kst[S], LO, n, b, VMAX, TPK, PASSED, RUNEND, RB,
                     RBN, DROP, c)
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
            elif auto_stop and y[ov + n - 1] > VTHR[b] and \
                    y[ox + n - 2] - y[ox + n - 1] - g[n - 2] <= 0.0:
                FIN[b] = kernels.S_PASSED


@njit(cache=True)
def finalize(VMAX, TPK, RUNEND, RB, RBN, DROP, VINIT, t_last, plateau_span):
    """Per particle (v_max, t_peak, t_front, plateau) of one chain from its running
    observables (module docstring); v_max 0 and NaN times for a particle that never moved
    forward."""
    n = VMAX.shape[0]
    vmax = np.zeros(n)
    tpk = np.full(n, np.nan)
    tfr = np.full(n, np.nan)
    plat = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        top = VMAX[i]
        if not top > 0.0:
            continue
        vmax[i] = top
        t_near = _level_time(RB[i], RBN[i], DROP[i], VINIT[i], (1.0 - PEAK_TOL) * top)
        t_half = _level_time(RB[i], RBN[i], DROP[i], VINIT[i], 0.5 * top)
        end = RUNEND[i] if RUNEND[i] >= 0.0 else t_last
        plat[i] = (end - t_near) > plateau_span
        tpk[i] = t_near if plat[i] else TPK[i]
        tfr[i] = t_half
    return vmax, tpk, tfr, plat


@njit(cache=True)
def _level_time(rb, m, drop, vinit, level):
    """First time the velocity reached ``level`` (NaN if that step was not kept)."""
    if vinit >= level:
        return 0.0
    if drop >= level:
        return np.nan
    for q in range(m):
        if rb[q, RB_MAX] >= level:
            tau = _first_cross(rb[q, RB_C:RB_C + 5], level, 0.0, True)
            if tau < 0.0:
                return np.nan
            return rb[q, RB_T0] + tau * rb[q, RB_H]
    return np.nan


# The event method across chains: blocks of L lanes, each lane one chain, stepped in lock
# step. Each lane keeps its own step size, its own trial and its own acceptance; a step
# that one lane rejects (error control, an event located inside it) is simply that lane's
# next trial while its neighbours go on. A lane whose chain stops takes the next chain of
# its block's queue. The force evaluations and the Runge-Kutta stages of all lanes run
# together (``kernels.forces_block``, lanes innermost: vectorised across chains); the
# per-lane decisions (event prediction and location, peaks, observables) run the same
# functions as ``run_events`` on a copy of the lane. A lane's arithmetic is that of
# ``run_events`` operation for operation, so a chain's result does not depend on its lane,
# its block or its neighbours (bit for bit; tested against ``run_events``).
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
                elif auto_stop and y[ov + n - 1, l] > VTHR[b] and \
                        y[ox + n - 2, l] - y[ox + n - 1, l] - g[n - 2, l] <= 0.0:
                    fin[l] = kernels.S_PASSED
                phase[l] = _PH_BEGIN
