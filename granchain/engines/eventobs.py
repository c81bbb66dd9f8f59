"""The event method's on-the-fly observables (``engines.events``): per particle the running
maximum of its velocity and its time, the record-setting steps' velocity interpolants
(``engines.hermite``), when its near-peak run ended, the step in which the velocity rose
back to the near level after a dip below it (the climb to a later maximum) and whether
the wave has passed it; ``finalize`` turns them into v_max, t_peak, t_front and the
plateau flag. The levels are ``granchain.obsrules``' (the sampled rules of
``granchain.observables`` in continuous time; see ``engines.events`` for the method).

The plateau is the sampled rule's: the run within PEAK_TOL of the maximum that holds the
maximum. A velocity with two maxima within PEAK_TOL of each other and a dip below the
near level between them has that run start after the dip, where the velocity climbs
back through the near level; that crossing may lie in a step that set no record (the
velocity still below the first maximum), so the step of the climb is kept
(``CLIMB``: slot 0 the climb to the running maximum, slot 1 the latest climb since the
run of the running maximum ended, both in the record buffer's layout ``RB_*``, t0 -1
where none). Not followed: a dip that does not reach below the near level of the running
maximum of its time but does below that of the final one (a band of PEAK_TOL times their
difference), and a dip and a new record inside one step.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True)

from .. import obsrules  # noqa: E402
from .codes import L_DISP, L_VEL, RB_C, RB_H, RB_MAX, RB_T0  # noqa: E402
from .compose import compiled  # noqa: E402
from .hermite import (first_cross, last_cross_up, poly_dv, poly_v, turn, v_bound,  # noqa: E402
                      vcoef)

_near_level, _pass_level, _front_level, _grid_samples, _plateau = (
    compiled(r) for r in (obsrules.near_level, obsrules.pass_level, obsrules.front_level,
                          obsrules.grid_samples, obsrules.plateau))


@njit(cache=True, error_model="numpy", boundscheck=False)
def _peak_inside(y, ynew, K0, K1, LO, n, h, VMAX, lane_b, land, c, act, tau):
    """Per lane l of a block with act[l]: tau[l], the first tau in (0, 1) of a
    record-setting velocity maximum inside the lane's step of length h[l], more than
    ``land`` above both step ends; -1 if none (-1 in every other lane). VMAX[lane_b[l]]:
    the running maxima of lane l's chain. Where an acceleration turns from + to - is
    found over all lanes at once; the maximum is examined only in those lanes."""
    ov = LO[L_VEL]
    L = y.shape[1]
    for l in range(L):
        tau[l] = -1.0
    for i in range(n):
        for l in range(L):
            turns = (K0[ov + i, l] > 0.0) & (K1[ov + i, l] < 0.0)
            tau[l] = 1.0 if turns else tau[l]
    for l in range(L):
        if tau[l] > 0.0 and act[l]:
            tau[l] = _peak_lane(y, ynew, K0, K1, LO, n, h[l], VMAX, lane_b[l], land, c, l)
        else:
            tau[l] = -1.0


@njit(cache=True)
def _peak_lane(y, ynew, K0, K1, LO, n, h, VMAX, bc, land, c, l):
    """``_peak_inside`` in lane l (chain bc)."""
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    best = 2.0
    for i in range(n):
        a0 = K0[ov + i, l]
        a1 = K1[ov + i, l]
        if not (a0 > 0.0 and a1 < 0.0):
            continue
        vcoef(y[ox + i, l], y[ov + i, l], a0, ynew[ox + i, l], ynew[ov + i, l], a1, h, c)
        ub = v_bound(c)
        if ub <= VMAX[bc, i] or ub - max(y[ov + i, l], ynew[ov + i, l]) <= land:
            continue          # no maximum inside the step can pass either test
        tau = turn(c, 0.0, 1.0)
        vp = poly_v(c, tau)
        if vp > VMAX[bc, i] and vp - max(y[ov + i, l], ynew[ov + i, l]) > land and tau < best:
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
    v1 = poly_v(c1, 1.0)
    a1 = poly_dv(c1, 1.0) / h1
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
def _keep_step(slot, t0, h, vmx, c):
    """Store a step (start t0, length h, its largest velocity vmx, coefficients c of its
    velocity) in a row of the record buffer's layout."""
    slot[RB_T0] = t0
    slot[RB_H] = h
    slot[RB_MAX] = vmx
    for q in range(5):
        slot[RB_C + q] = c[q]


@njit(cache=True)
def _observe(t0, h, y, ynew, K0, K1, LO, n, bc, l, VMAX, TPK, PASSED, RUNEND, CLIMB, RB, RBN,
             DROP, c):
    """Update the running per-particle observables of chain bc (row bc of VMAX ... DROP)
    with one accepted step, lane l of the block (y, ynew, K0, K1: (ny, L))."""
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    for i in range(n):
        v0 = y[ov + i, l]
        v1 = ynew[ov + i, l]
        a0 = K0[ov + i, l]
        a1 = K1[ov + i, l]
        built = False
        # largest velocity inside the step
        vmx = v1
        tmx = 1.0
        if v0 > vmx:
            vmx = v0
            tmx = 0.0
        if a0 > 0.0 and a1 < 0.0:
            vcoef(y[ox + i, l], v0, a0, ynew[ox + i, l], v1, a1, h, c)
            built = True
            # a maximum that cannot set a record leaves every result below unchanged
            # (without it, vmx > VMAX[bc, i] only if an end of the step is above VMAX[bc, i])
            if v_bound(c) > VMAX[bc, i]:
                tau = turn(c, 0.0, 1.0)
                vp = poly_v(c, tau)
                if vp > vmx:
                    vmx = vp
                    tmx = tau
        tafter = 0.0
        record = vmx > VMAX[bc, i]
        if record:
            if not built:
                vcoef(y[ox + i, l], v0, a0, ynew[ox + i, l], v1, a1, h, c)
                built = True
            if RUNEND[bc, i] >= 0.0:
                # the velocity fell below the near level of the last maximum since it: this
                # maximum's run starts at the climb back through it, in this step if it
                # starts below the level, else in the latest climb step
                if v0 < _near_level(VMAX[bc, i]) or CLIMB[bc, i, 1, RB_T0] < 0.0:
                    _keep_step(CLIMB[bc, i, 0], t0, h, vmx, c)
                else:
                    CLIMB[bc, i, 0, :] = CLIMB[bc, i, 1, :]
            CLIMB[bc, i, 1, RB_T0] = -1.0
            VMAX[bc, i] = vmx
            TPK[bc, i] = t0 + tmx * h
            PASSED[bc, i] = 0
            RUNEND[bc, i] = -1.0
            tafter = tmx
            # drop record steps that cannot hold the half-peak crossing any more
            m = RBN[bc, i]
            keep = 0
            while keep < m and RB[bc, i, keep, RB_MAX] < _front_level(vmx):
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
            lo_run = _near_level(VMAX[bc, i])
            lo_pass = _pass_level(VMAX[bc, i])
            vmn = min(v1, v0 if tafter == 0.0 else v1)
            interior = a0 < 0.0 and a1 > 0.0
            if vmn < lo_run or interior:
                if not built:
                    vcoef(y[ox + i, l], v0, a0, ynew[ox + i, l], v1, a1, h, c)
                    built = True
                if RUNEND[bc, i] < 0.0:
                    tau = first_cross(c, lo_run, tafter, False)
                    if tau >= 0.0:
                        RUNEND[bc, i] = t0 + tau * h
                if PASSED[bc, i] == 0:
                    tau = first_cross(c, lo_pass, tafter, False)
                    if tau >= 0.0:
                        PASSED[bc, i] = 1
        # after a dip below the near level: the latest step that climbs back through it
        if not record and RUNEND[bc, i] >= 0.0:
            lev = _near_level(VMAX[bc, i])
            if v1 >= lev:
                climbs = v0 < lev or RUNEND[bc, i] >= t0
                dips = not climbs and a0 < 0.0 and a1 > 0.0    # a minimum inside
                if (climbs or dips) and not built:
                    vcoef(y[ox + i, l], v0, a0, ynew[ox + i, l], v1, a1, h, c)
                if dips:
                    climbs = poly_v(c, turn(c, 0.0, 1.0)) < lev
                if climbs:
                    _keep_step(CLIMB[bc, i, 1], t0, h, vmx, c)


@njit(cache=True)
def finalize(VMAX, TPK, RUNEND, CLIMB, RB, RBN, DROP, VINIT, t_last, sample_dt):
    """Per particle (v_max, t_peak, t_front, plateau) of one chain from its running
    observables (module docstring); v_max 0 and NaN times for a particle that never moved
    forward. A plateau: the near-peak run that holds the maximum, from its start
    (:func:`_run_start`) to its end (or t_last), holds more than PLATEAU_SAMPLES instants
    of the sample grid of interval sample_dt (``obsrules.grid_samples``,
    ``obsrules.plateau``): the sampled records' rule, applied to the run in continuous
    time. A plateau's t_peak is the first crossing of the near level, as the sampled
    rule's (``observables.peak``)."""
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
        t_near = _level_time(RB[i], RBN[i], DROP[i], VINIT[i], _near_level(top))
        t_half = _level_time(RB[i], RBN[i], DROP[i], VINIT[i], _front_level(top))
        end = RUNEND[i] if RUNEND[i] >= 0.0 else t_last
        start = _run_start(CLIMB[i, 0], RB[i], RBN[i], _near_level(top), t_near)
        plat[i] = _plateau(_grid_samples(start, end, sample_dt))
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
            tau = first_cross(rb[q, RB_C:RB_C + 5], level, 0.0, True)
            if tau < 0.0:
                return np.nan
            return rb[q, RB_T0] + tau * rb[q, RB_H]
    return np.nan


@njit(cache=True)
def _run_start(climb, rb, m, level, t_near):
    """Start of the run at or above ``level`` that holds the maximum: t_near (the first
    crossing) without a dip before the maximum; else its climb back through the level after
    the last dip: in the climb step if it ends at or above the level, else in the first
    record step after it (its start, if that step begins above the level: the crossing
    then lies in a step between them, not kept)."""
    if climb[RB_T0] < 0.0:
        return t_near
    cc = climb[RB_C:RB_C + 5]
    if poly_v(cc, 1.0) >= level:
        tau = last_cross_up(cc, level)
        return climb[RB_T0] + (tau if tau > 0.0 else 0.0) * climb[RB_H]
    t_end = climb[RB_T0] + climb[RB_H]
    for q in range(m):
        if rb[q, RB_T0] + 0.5 * rb[q, RB_H] > t_end and rb[q, RB_MAX] >= level:
            tau = first_cross(rb[q, RB_C:RB_C + 5], level, 0.0, True)
            if tau < 0.0:
                return t_near
            return rb[q, RB_T0] + tau * rb[q, RB_H]
    return t_near
