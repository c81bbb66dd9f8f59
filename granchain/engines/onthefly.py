"""On-the-fly observables of the fixed-step blocks (``kernels.run_blocks`` with observe):
the rules of ``granchain.obsrules``, which ``granchain.observables`` (``peak``,
``peak_final``, ``wall_peak``, ``energy_ledger``) applies to a sampled record, applied to
the samples as they are taken, with the same floating-point operations, so that the
results equal those of the summariser on the sampled record. Array slots:
``engines.obscodes``.
"""
from __future__ import annotations

import math

from numba import njit

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True)

from .. import obsrules  # noqa: E402
from ..stoprule import PLATEAU_SAMPLES  # noqa: E402
from .codes import E_LEN, L_VEL  # noqa: E402
from .compose import compiled  # noqa: E402
from .integrators import _wall_force_l  # noqa: E402
from .obscodes import (BAL_E0, BAL_MAX, OF_AFTER, OF_BEFORE, OF_MAX, OF_RECENT,  # noqa: E402
                       OI_AFTER_OPEN, OI_ARGMAX, OI_NAN, OI_NEAR_AFTER, OI_NEAR_BEFORE, OI_PASSED,
                       OI_RING_COUNT, OI_RING_HEAD, OI_RING_OVERFLOW, OUT_MAX_SAMPLE, OUT_PLATEAU,
                       OUT_T_FRONT, OUT_T_PEAK, OUT_VMAX, WF_AFTER, WF_BEFORE, WF_MAX, WF_PREV,
                       WI_ARGMAX, WI_NAN, WI_PASSED)

_near, _near_level, _pass_level, _passed, _front_level, _plateau, _vertex, _crossing = (
    compiled(r) for r in (obsrules.near, obsrules.near_level, obsrules.pass_level,
                          obsrules.passed, obsrules.front_level, obsrules.plateau,
                          obsrules.vertex, obsrules.crossing))


@njit(cache=True)
def _obs_velocity(k, y, of, oi, rk, rv):
    """Sample k of one particle's velocity y into its running peak state (of, oi) and its
    record samples (rk: sample index, rv: (previous sample, sample)): the samples that set a
    new maximum, which are the only candidates for a first crossing of a level below the
    final maximum; those below the pass level of the running maximum are dropped (a level
    the summariser crosses is at least half the final maximum)."""
    if oi[OI_NAN] != 0:
        return
    if y != y:
        oi[OI_NAN] = 1
        return
    cap = rk.shape[0]
    if k == 0:
        of[OF_MAX] = y
        oi[OI_ARGMAX] = 0
        oi[OI_NEAR_BEFORE] = 0
        oi[OI_NEAR_AFTER] = 0
        oi[OI_AFTER_OPEN] = 1
        oi[OI_PASSED] = 0
        oi[OI_RING_OVERFLOW] = 0
        rk[0] = 0
        rv[0, 0] = y
        rv[0, 1] = y
        oi[OI_RING_HEAD] = 0
        oi[OI_RING_COUNT] = 1
    elif y > of[OF_MAX]:
        prev = of[OF_RECENT + (k - 1) % PLATEAU_SAMPLES]
        of[OF_MAX] = y
        of[OF_BEFORE] = prev
        oi[OI_ARGMAX] = k
        thr = _near_level(y)
        bwd = 0
        for d in range(1, PLATEAU_SAMPLES + 1):
            if k - d < 0 or not (of[OF_RECENT + (k - d) % PLATEAU_SAMPLES] >= thr):
                break
            bwd += 1
        oi[OI_NEAR_BEFORE] = bwd
        oi[OI_NEAR_AFTER] = 0
        oi[OI_AFTER_OPEN] = 1
        oi[OI_PASSED] = 0
        head = oi[OI_RING_HEAD]
        count = oi[OI_RING_COUNT]
        half = _pass_level(y)
        while count > 0 and rv[head, 1] < half:
            head = (head + 1) % cap
            count -= 1
        if count == cap:
            oi[OI_RING_OVERFLOW] = 1
            head = (head + 1) % cap
            count -= 1
        s = (head + count) % cap
        rk[s] = k
        rv[s, 0] = prev
        rv[s, 1] = y
        oi[OI_RING_HEAD] = head
        oi[OI_RING_COUNT] = count + 1
    else:
        top = of[OF_MAX]
        if k == oi[OI_ARGMAX] + 1:
            of[OF_AFTER] = y
        if oi[OI_AFTER_OPEN] != 0:
            if _near(y, top):
                if oi[OI_NEAR_AFTER] < PLATEAU_SAMPLES:
                    oi[OI_NEAR_AFTER] += 1
            else:
                oi[OI_AFTER_OPEN] = 0
        if _passed(y, top):
            oi[OI_PASSED] = 1
    of[OF_RECENT + k % PLATEAU_SAMPLES] = y


@njit(cache=True)
def _obs_crossing(level, oi, rk, rv, sdt):
    """``observables._crossing`` from the record samples: the first sample at or above
    ``level``, linearly interpolated from the sample before it (times k * sdt)."""
    cap = rk.shape[0]
    head = oi[OI_RING_HEAD]
    for q in range(oi[OI_RING_COUNT]):
        s = (head + q) % cap
        if rv[s, 1] >= level:
            j = rk[s]
            if j == 0:
                return 0.0
            y0 = rv[s, 0]
            y1 = rv[s, 1]
            return _crossing(float(j - 1) * sdt, float(j) * sdt, y0, y1, level)
    return math.nan


@njit(cache=True)
def _obs_finish(S, of, oi, rk, rv, sdt, out):
    """``observables.peak`` of one particle after its S samples, into out (R_*)."""
    top = of[OF_MAX]
    if oi[OI_NAN] != 0 or not top > 0.0:
        out[OUT_VMAX] = 0.0
        out[OUT_T_PEAK] = math.nan
        out[OUT_T_FRONT] = math.nan
        out[OUT_PLATEAU] = 0.0
        out[OUT_MAX_SAMPLE] = math.nan if oi[OI_NAN] != 0 else top
        return
    j = oi[OI_ARGMAX]
    plateau = _plateau(oi[OI_NEAR_BEFORE] + 1 + oi[OI_NEAR_AFTER])
    if not plateau and 0 < j < S - 1:
        off, vmax = _vertex(of[OF_BEFORE], top, of[OF_AFTER])
        h = float(j + 1) * sdt - float(j) * sdt
        tpk = float(j) * sdt + off * h
    elif not plateau:
        vmax = top
        tpk = float(j) * sdt
    else:
        vmax = top
        tpk = _obs_crossing(_near_level(top), oi, rk, rv, sdt)
    out[OUT_VMAX] = vmax
    out[OUT_T_PEAK] = tpk
    out[OUT_T_FRONT] = _obs_crossing(_front_level(vmax), oi, rk, rv, sdt)
    out[OUT_MAX_SAMPLE] = top
    out[OUT_PLATEAU] = 1.0 if plateau else 0.0


@njit(cache=True)
def _obs_wall(k, F, wf, wi):
    """Sample k of the end wall's dynamic force F into its running peak state."""
    if wi[WI_NAN] != 0:
        return
    if F != F:
        wi[WI_NAN] = 1
        return
    if k == 0:
        wf[WF_MAX] = F
        wi[WI_ARGMAX] = 0
        wi[WI_PASSED] = 0
    elif F > wf[WF_MAX]:
        wf[WF_MAX] = F
        wf[WF_BEFORE] = wf[WF_PREV]
        wi[WI_ARGMAX] = k
        wi[WI_PASSED] = 0
    else:
        if k == wi[WI_ARGMAX] + 1:
            wf[WF_AFTER] = F
        if _passed(F, wf[WF_MAX]):
            wi[WI_PASSED] = 1
    wf[WF_PREV] = F


@njit(cache=True)
def _obs_wall_finish(S, wf, wi, sdt, wout):
    """``observables.wall_peak`` after S samples, into wout (F_max, t_peak, final)."""
    top = wf[WF_MAX]
    if wi[WI_NAN] != 0 or not (top > 0.0 and wi[WI_PASSED] != 0):
        wout[0] = math.nan
        wout[1] = math.nan
        wout[2] = 0.0
        return
    j = wi[WI_ARGMAX]
    tpk = float(j) * sdt
    if 0 < j < S - 1:
        off, top = _vertex(wf[WF_BEFORE], top, wf[WF_AFTER])
        tpk += off * (float(j + 1) * sdt - float(j) * sdt)
    wout[0] = top
    wout[1] = tpk
    wout[2] = 1.0


@njit(cache=True)
def _obs_balance(k, ebuf, l, bal):
    """Sample k of the energy balance of lane l: |E_mech - E_mech(0) - sum of works|, its
    running maximum (NaN once NaN, as np.max), summed in ``observables.energy_ledger``'s
    order."""
    total = ebuf[0, l] + ebuf[1, l] + ebuf[2, l]
    work = 0.0
    for e in range(3, ebuf.shape[0]):
        work += ebuf[e, l]
    if k == 0:
        bal[BAL_E0] = total
    a = abs(total - bal[BAL_E0] - work)
    if k == 0 or a != a:
        bal[BAL_MAX] = a
    elif a > bal[BAL_MAX]:
        bal[BAL_MAX] = a


@njit(cache=True)
def _sample_lane(c, k, y, g, ebuf, l, b, n, LO, P, FL, observe, wall_static, Vout, Eout,
                 OF, OI, RK, RV, WF, WI, BAL):
    """Sample k of the chain in lane l (chain b): into row c of its record, or with
    observe into its on-the-fly observables (row 0 of Vout/Eout keeps sample 0, row 1 the
    latest sample)."""
    ov = LO[L_VEL]
    r = c if not observe else (0 if k == 0 else 1)
    for i in range(n):
        Vout[b, r, i] = y[ov + i, l]
    wall = Vout.shape[2] > n
    if wall:
        Vout[b, r, n] = _wall_force_l(y, g, n, LO, P, FL, l)
    for e in range(E_LEN):
        Eout[b, r, e] = ebuf[e, l]
    if observe:
        for i in range(n):
            _obs_velocity(k, y[ov + i, l], OF[b, i], OI[b, i], RK[b, i], RV[b, i])
        if wall:
            _obs_wall(k, Vout[b, r, n] - wall_static, WF[b], WI[b])
        _obs_balance(k, ebuf, l, BAL[b])


@njit(cache=True)
def _finish_lane(b, n, NS, sdt, observe, OF, OI, RK, RV, WF, WI, OUT, WOUT, wall):
    """On-the-fly observables of chain b once it has stopped (after NS[b] samples)."""
    if not observe:
        return
    S = NS[b]
    for i in range(n):
        _obs_finish(S, OF[b, i], OI[b, i], RK[b, i], RV[b, i], sdt, OUT[b, i])
    if wall:
        _obs_wall_finish(S, WF[b], WI[b], sdt, WOUT[b])
