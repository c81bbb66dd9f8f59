"""The reference engine's drivers of the fixed-step and adaptive methods: each advances
many chains in parallel (numba's prange), window by window of samples, and stops each
chain by the stop rule.

- ``run_blocks``: rk4 and verlet on blocks of L chains (``integrators.rk4_block``,
  ``verlet_block``; chains in SIMD lanes), recording the samples or measuring the
  observables on the fly (``engines.onthefly``);
- ``run_window``: one chain per thread, rk4, verlet or the adaptive DOP853; the engine
  runs the adaptive method by ``run_adaptive``, its copy without the fixed-step branches.
The event method's drivers are in ``engines.events``. The integrators and the physics
they call: ``engines.integrators``, ``engines.compose``.
"""
from __future__ import annotations

import math
import types

import numpy as np
from numba import njit, prange

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True): a cache keyed by every source compiled in

from .. import obsrules  # noqa: E402
# the kernels' numbering of parameters, flags, layout blocks, methods, energy columns,
# statuses, and the DOP853 tableau (numba-free, shared with the engines' Python side)
from . import codes  # noqa: E402
from .codes import (DENSE_POWER, E_LEN, F_END_WALL, G_MASS, L_DISP, L_VEL,  # noqa: E402
                    M_RK4, M_VERLET, NST, NST_DENSE, P_N_SPHERES, S_DONE, S_NONFINITE,
                    S_PASSED, S_RUNNING, S_STEPFAIL)
from ..effects.spec import BOND_CAPTURED, BOND_NONE, BOND_UNDECIDED  # noqa: E402
from .compose import INLINED, compiled, contact_bond, overlap as _overlap_l  # noqa: E402
# the integrators (and their per-chain entry points, which the tests call through here)
from .integrators import (_col, _wall_force, dense_state, dop853_dense,  # noqa: E402,F401
                          dop853_try, energies, energies_block, error_norm, forces,
                          forces_block, project, project_block, rk4_block, rk4_step, rk_trial,
                          verlet_block, verlet_step)
from .onthefly import _finish_lane, _sample_lane  # noqa: E402

# every numbered slot as an attribute here too (callers index the kernels' arrays by them)
globals().update(codes.NAMES)
_detached, _wall_left = compiled(obsrules.detached), compiled(obsrules.wall_left)


# run_window compiles its fixed-step branches while this is on; ``run_adaptive``, its copy
# with it off, compiles the adaptive method alone (numba drops a branch on a constant
# before it types the code, so neither the RK4 nor the Verlet step is compiled into it)
_FIXED_STEP = True


@njit(cache=True)
def _finite(y, LO, n):
    for j in range(LO[L_DISP], LO[L_VEL] + n):
        if not math.isfinite(y[j]):
            return False
    return True


@njit(parallel=True, cache=True)
def run_window(method, Y, ACC, T, H, NS, STEPS, REJ, NEV, STATUS, VTHR, gaps, P, FL, LO,
               scale_abs, rel, rtol, dt, every, sample_dt, NT, auto_stop, Vout, Eout, counts):
    """Advance every running chain by up to Vout.shape[1] samples.

    Per chain b: Y[b] state, ACC[b] last derivative (Verlet), T[b] time, H[b] adaptive
    step, NS[b] samples recorded so far, STEPS/REJ counters, NEV[b] force evaluations,
    STATUS[b] (S_*), VTHR[b] the arrival speed of chain b (``obsrules.arrival``). A
    sample is taken every ``every`` fixed steps (rk4, verlet) or every ``sample_dt``
    (dop853: the method takes the steps its tolerance allows, and a sample inside a step
    is the step's 7th-order dense output, its histories projected as a step's end is; a
    step ends no later than the window's last sample, so that no step outlives a call).
    A chain stops after NT[b] samples, or (auto_stop) at the first sample at which the
    stop rule holds (:func:`_settled`: its last particle has taken the wave and left,
    ``obsrules.detached``: velocity above VTHR[b], contact with its neighbour open; and
    no contact is held closed undecided), with status S_PASSED; Y[b] and T[b] are then
    the state and time of its last sample.
    """
    B = Y.shape[0]
    W = Vout.shape[1]
    n = int(P[P_N_SPHERES])
    ny = Y.shape[1]
    ov = LO[L_VEL]
    for b in prange(B):
        counts[b] = 0
        if STATUS[b] != S_RUNNING:
            continue
        y = Y[b]
        g = gaps[b]
        f = np.zeros(n)
        k1 = np.empty(ny)
        k2 = np.empty(ny)
        k3 = np.empty(ny)
        k4 = np.empty(ny)
        tmp = np.empty(ny)
        Kst = np.empty((NST_DENSE, ny))
        ynew = np.empty(ny)
        yold = np.empty(ny)
        ys = np.empty(ny)
        Fd = np.empty((DENSE_POWER, ny))
        told = 0.0
        hd = 0.0
        dense = False       # Fd holds the dense output of the last step (yold -> y)
        rejected = False    # the last trial step was rejected
        ebuf = np.empty(E_LEN)
        if NS[b] == 0:
            if _FIXED_STEP and method == M_VERLET:
                forces(y, g, P, FL, LO, 0.0, ACC[b], f)
                NEV[b] += 1
            for i in range(n):
                Vout[b, 0, i] = y[ov + i]
            if Vout.shape[2] > n:
                Vout[b, 0, n] = _wall_force(y, g, n, LO, P, FL)
            energies(y, g, P, FL, LO, ebuf)
            Eout[b, 0, :] = ebuf
            counts[b] = 1
            NS[b] = 1
            if NT[b] <= 1:
                STATUS[b] = S_DONE
        while counts[b] < W and STATUS[b] == S_RUNNING:
            if NS[b] >= NT[b]:
                STATUS[b] = S_DONE
                break
            at = y           # the state of this sample
            inside = False   # ys, inside the last step
            if _FIXED_STEP and method == M_RK4:
                for _ in range(every):
                    rk4_step(y, dt, g, P, FL, LO, k1, k2, k3, k4, tmp, f)
                STEPS[b] += every
                NEV[b] += 4 * every
                T[b] += every * dt
            elif _FIXED_STEP and method == M_VERLET:
                for _ in range(every):
                    verlet_step(y, ACC[b], dt, g, P, FL, LO, f)
                STEPS[b] += every
                NEV[b] += every
                T[b] += every * dt
            else:
                t_target = NS[b] * sample_dt
                # the last sample this call can take: no step goes past it
                t_last = (min(NS[b] + W - counts[b], NT[b]) - 1) * sample_dt
                while T[b] < t_target * (1.0 - 1e-14):
                    h = min(H[b], t_last - T[b])
                    clipped = h < H[b]
                    err = dop853_try(y, h, g, P, FL, LO, Kst, ynew, tmp, f, scale_abs, rel, rtol)
                    NEV[b] += NST + 1
                    if err <= 1.0:
                        for j in range(ny):
                            yold[j] = y[j]
                            y[j] = ynew[j]
                        project(y, g, P, FL, LO, f)
                        told = T[b]
                        hd = h
                        dense = False
                        T[b] = t_last if clipped else T[b] + h
                        STEPS[b] += 1
                        fac = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** (-1.0 / 8.0))
                        if rejected:
                            # no growth right after a rejection (scipy's, Hairer's rule)
                            fac = min(fac, 1.0)
                        rejected = False
                        if not clipped:
                            H[b] = h * fac
                    else:
                        REJ[b] += 1
                        rejected = True
                        H[b] = h * max(0.2, 0.9 * err ** (-1.0 / 8.0))
                        if H[b] < 1e-22:
                            STATUS[b] = S_STEPFAIL
                            break
                    if not math.isfinite(err):
                        STATUS[b] = S_NONFINITE
                        break
                if STATUS[b] != S_RUNNING:
                    break
                if T[b] > t_target * (1.0 + 1e-14):
                    # inside the last step: its dense output (ynew and Kst are still the
                    # step's), histories projected as at a step's end
                    if not dense:
                        dop853_dense(yold, ynew, hd, g, P, FL, LO, Kst, tmp, f, Fd)
                        NEV[b] += NST_DENSE - NST - 1
                        dense = True
                    dense_state(yold, Fd, (t_target - told) / hd, ys)
                    project(ys, g, P, FL, LO, f)
                    at = ys
                    inside = True
            c = counts[b]
            for i in range(n):
                Vout[b, c, i] = at[ov + i]
            if Vout.shape[2] > n:
                Vout[b, c, n] = _wall_force(at, g, n, LO, P, FL)
            energies(at, g, P, FL, LO, ebuf)
            Eout[b, c, :] = ebuf
            counts[b] = c + 1
            NS[b] += 1
            if not _finite(at, LO, n):
                STATUS[b] = S_NONFINITE
                break
            if auto_stop and _settled(_col(at), _col(g), P, FL, LO, n, 0, VTHR[b],
                                      FL[F_END_WALL] != 0):
                STATUS[b] = S_PASSED
                if inside:
                    # the chain ends at this sample
                    for j in range(ny):
                        y[j] = ys[j]
                    T[b] = t_target


def _adaptive_only(window):
    """The dispatcher of a copy of ``window`` (:func:`run_window`) over this module's
    namespace with ``_FIXED_STEP`` off: the driver the engine runs the adaptive method
    with (the fixed-step methods run in blocks, :func:`run_blocks`)."""
    fn = window.py_func
    ns = dict(globals(), _FIXED_STEP=False)
    copy = types.FunctionType(fn.__code__, ns, "run_adaptive", fn.__defaults__, fn.__closure__)
    # numba's cache tells compiled functions apart by their qualified names
    copy.__qualname__ = "run_adaptive"
    copy.__doc__ = ("``run_window`` for the adaptive method (``method`` M_DOP853) alone: the "
                    "fixed-step branches are not compiled.")
    copy.__module__ = fn.__module__
    return njit(parallel=True, cache=True)(copy)


@njit(cache=True, **INLINED)
def _left(v_last, overlap_last, x_last, vthr, wall):
    """Has the wave left the chain? Free end: ``obsrules.detached``; end wall:
    ``obsrules.wall_left`` (x_last: the last sphere's displacement from its start)."""
    return _wall_left(v_last, x_last, vthr) if wall else _detached(v_last, overlap_last, vthr)


@njit(cache=True, **INLINED)
def _settled(y, G, P, FL, LO, n, l, vthr, wall):
    """The t_end auto stop rule of the chain in lane l (``granchain.stoprule``): no
    contact that an effect's law holds closed with the energy to part (``contact_bond``
    BOND_UNDECIDED), and the wave has left the chain (:func:`_left`, at a free end with
    the last contact not held bound) or, at a free end, the last particle, faster than
    vthr, is held bound to its neighbour (BOND_CAPTURED) and that pair is alone (two
    spheres, or the contact before it open and not held and no sphere behind it faster
    than the pair's centre of mass). Inlined by LLVM (typed and lowered once; it
    allocates nothing, so no reference counting): its first test, which ends it at nearly
    every sample, costs no call; the rest, the effects' bond laws, is
    :func:`_bonds_settled`."""
    ox = LO[L_DISP]
    v_last = y[LO[L_VEL] + n - 1, l]
    left = _left(v_last, _overlap_l(y, ox, G, n - 2, l), y[ox + n - 1, l], vthr, wall)
    if not left and (wall or not v_last > vthr):
        return False
    return _bonds_settled(y, G, P, FL, LO, n, l, vthr, wall, left)


# compiled once and called (not inlined) by the four drivers that test the stop rule:
# inlined it compiled every effect's bond law three times over in each of them
@njit(cache=True)
def _bonds_settled(y, G, P, FL, LO, n, l, vthr, wall, left):
    """The bond tests of :func:`_settled` once the wave has left the chain (``left``) or
    the last particle is faster than the arrival speed at a free end."""
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    v_last = y[ov + n - 1, l]
    bound = (not wall) and contact_bond(y, G, P, FL, LO, n, n - 2, l) == BOND_CAPTURED
    if bound or not left:
        if wall or not v_last > vthr:
            return False
        if not bound:
            return False
        if n > 2 and (_overlap_l(y, ox, G, n - 3, l) > 0.0
                      or contact_bond(y, G, P, FL, LO, n, n - 3, l) != BOND_NONE):
            return False
        ma = G[G_MASS * n + n - 2, l]
        mb = G[G_MASS * n + n - 1, l]
        vcm = (ma * y[ov + n - 2, l] + mb * v_last) / (ma + mb)
        for i in range(n - 2):
            if y[ov + i, l] > vcm:
                return False
    for k in range(n if wall else n - 1):
        if contact_bond(y, G, P, FL, LO, n, k, l) == BOND_UNDECIDED:
            return False
    return True


@njit(cache=True)
def _stop_lane(y, acc, l, YF, b, status, STATUS):
    """Chain b in lane l stops: its final state goes to YF[b], its lane is set to rest
    (a resting chain stays exactly at rest, costs nothing special and keeps no stale
    values in the block while its neighbours run on)."""
    STATUS[b] = status
    for j in range(y.shape[0]):
        YF[b, j] = y[j, l]
        y[j, l] = 0.0
        acc[j, l] = 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def run_blocks(method, Y, ACC, YF, T, NS, STEPS, STATUS, VTHR, gaps, P, FL, LO, dt, every,
               NT, auto_stop, Vout, Eout, counts, observe, sample_dt, wall_static, OF, OI, RK,
               RV, WF, WI, BAL, OUT, WOUT):
    """Advance every running chain of fixed-step blocks (rk4, verlet) by up to
    Vout.shape[1] samples, or with ``observe`` until every chain has stopped.

    Y (nblk, ny, L): the states of nblk blocks of L chains (chains innermost), ACC the
    same for the last derivative (Verlet), gaps (nblk, n-1, L). Per-chain arrays are
    indexed b = block * L + lane: T time, NS samples recorded so far, STEPS, STATUS (S_*),
    VTHR the arrival speed, NT the sample limit, YF (.., ny) the state at which the chain
    stopped. A lane that does not hold a chain starts with a status other than S_RUNNING
    and a zero state. The chains of a block step in lockstep (they share NS while they
    run); each one records its samples and stops exactly as in ``run_window``: after
    NT[b] samples (S_DONE), or (auto_stop) at the first sample at which the stop rule
    holds (:func:`_settled`; S_PASSED), or on a non-finite state.

    Without ``observe`` the samples go to rows 0.. of Vout/Eout (counts[b] of them in
    this call). With ``observe`` (Vout/Eout of 2 rows: sample 0, then the latest sample)
    each sample updates the chain's on-the-fly observables (samples k * sample_dt apart;
    the wall force less ``wall_static``), and a chain that stops gets them: per particle
    OUT[b, i] (R_*: the ``observables.peak`` values) and OI[b, i, OI_PASSED] (the wave has
    passed it), the wall's WOUT[b] (``observables.wall_peak``), BAL[b, BAL_E0] and
    BAL[b, BAL_MAX] (the energy balance of ``observables.energy_ledger``), and
    OI[b, i, OI_RING_OVERFLOW] set where a particle had more record samples than RK.shape[2] (its
    crossing times are then not the summariser's). The observe arrays are not read
    without ``observe``.
    """
    nblk, ny, L = Y.shape
    W = Vout.shape[1] if not observe else 2**62
    n = int(P[P_N_SPHERES])
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    wall = Vout.shape[2] > n
    for blk in prange(nblk):
        base = blk * L
        ns = -1
        for l in range(L):
            counts[base + l] = 0
            if STATUS[base + l] == S_RUNNING:
                ns = NS[base + l]
        if ns < 0:
            continue
        # the block's own copies of its state and rows and of the run's vectors, the state
        # written back at the end: the kernels reference-count their array arguments, and
        # counting on arrays that every thread shares (views of Y, the one P) would move
        # their cache lines from core to core at every call
        y = Y[blk].copy()
        acc = ACC[blk].copy()
        g = gaps[blk].copy()
        Pb = P.copy()
        FLb = FL.copy()
        LOb = LO.copy()
        f = np.zeros((n, L))
        k1 = np.empty((ny, L))
        k2 = np.empty((ny, L))
        k3 = np.empty((ny, L))
        k4 = np.empty((ny, L))
        tmp = np.empty((ny, L))
        ebuf = np.empty((E_LEN, L))
        c = 0
        if ns == 0:
            if method == M_VERLET:
                forces_block(y, g, Pb, FLb, LOb, 0.0, acc, f)
            energies_block(y, g, Pb, FLb, LOb, ebuf)
            for l in range(L):
                b = base + l
                if STATUS[b] != S_RUNNING:
                    continue
                _sample_lane(0, 0, y, g, ebuf, l, b, n, LOb, Pb, FLb, observe, wall_static,
                             Vout, Eout, OF, OI, RK, RV, WF, WI, BAL)
                counts[b] = 1
                NS[b] = 1
                if NT[b] <= 1:
                    _stop_lane(y, acc, l, YF, b, S_DONE, STATUS)
                    _finish_lane(b, n, NS, sample_dt, observe, OF, OI, RK, RV, WF, WI, OUT,
                                 WOUT, wall)
            c = 1
        while c < W:
            running = False
            for l in range(L):
                b = base + l
                if STATUS[b] == S_RUNNING:
                    if NS[b] >= NT[b]:
                        _stop_lane(y, acc, l, YF, b, S_DONE, STATUS)
                        _finish_lane(b, n, NS, sample_dt, observe, OF, OI, RK, RV, WF, WI,
                                     OUT, WOUT, wall)
                    else:
                        running = True
            if not running:
                break
            if method == M_RK4:
                for _ in range(every):
                    rk4_block(y, dt, g, Pb, FLb, LOb, k1, k2, k3, k4, tmp, f)
            else:
                for _ in range(every):
                    verlet_block(y, acc, dt, g, Pb, FLb, LOb, f)
            energies_block(y, g, Pb, FLb, LOb, ebuf)
            for l in range(L):
                b = base + l
                if STATUS[b] != S_RUNNING:
                    continue
                STEPS[b] += every
                T[b] += every * dt
                _sample_lane(c, NS[b], y, g, ebuf, l, b, n, LOb, Pb, FLb, observe, wall_static,
                             Vout, Eout, OF, OI, RK, RV, WF, WI, BAL)
                counts[b] = c + 1
                NS[b] += 1
                finite = True
                for j in range(ox, ov + n):
                    if not math.isfinite(y[j, l]):
                        finite = False
                if not finite:
                    _stop_lane(y, acc, l, YF, b, S_NONFINITE, STATUS)
                    _finish_lane(b, n, NS, sample_dt, observe, OF, OI, RK, RV, WF, WI, OUT,
                                 WOUT, wall)
                elif auto_stop and _settled(y, g, Pb, FLb, LOb, n, l, VTHR[b],
                                            FLb[F_END_WALL] != 0):
                    _stop_lane(y, acc, l, YF, b, S_PASSED, STATUS)
                    _finish_lane(b, n, NS, sample_dt, observe, OF, OI, RK, RV, WF, WI, OUT,
                                 WOUT, wall)
            c += 1
        Y[blk] = y
        ACC[blk] = acc


# last: the copy's namespace holds every function above
run_adaptive = _adaptive_only(run_window)
