"""Numba kernels of the reference engine.

State of one chain is a flat float64 vector laid out by ``engines.reference.Layout``:
displacements x (from the initial, gapped positions), velocities v, and only when the
scene enables them: spins omega, groove histories xi_g, contact histories xi_t, rolling
histories rho, and one accumulated-work entry per dissipative effect. Effects are switched
by runtime flags checked once per force call (not per particle), so a Hertz-only chain
carries no rotational state and its force loop never touches friction code.

One force routine, ``forces``, holds the physics of every effect; the three integrators
call it:
- ``rk4``: classical fixed-step RK4 on the full state (histories integrate xi' = slip,
  held at the Coulomb cap while sliding; the rolling history is not held, see
  ``forces``), then the return mapping ``project``.
- ``verlet``: velocity Verlet in LAMMPS's order (half kick, drift, forces at the
  half-step velocities with the history update xi += slip*dt and return mapping inside
  the force call, half kick; no history update at setup), like ``fix nve/sphere``.
- ``dop853``: adaptive Dormand-Prince 8(5,3) with error control, stepping exactly onto
  sample times, ``project`` after each accepted step. Serves as converged truth.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True): a cache keyed by every source compiled in

from ..stoprule import PEAK_TOL, PLATEAU_SAMPLES  # noqa: E402  the sampled peak rules
from ..stoprule import PASS_FRACTION  # noqa: E402
from .obscodes import (BAL_E0, BAL_MAX, OF_AFTER, OF_BEFORE, OF_MAX, OF_RECENT,  # noqa: E402
                       OI_AFTER_OPEN, OI_ARGMAX, OI_NAN, OI_NEAR_AFTER, OI_NEAR_BEFORE, OI_PASSED,
                       OI_RING_COUNT, OI_RING_HEAD, OI_RING_OVERFLOW, OUT_MAX_SAMPLE, OUT_PLATEAU,
                       OUT_T_FRONT, OUT_T_PEAK, OUT_VMAX, WF_AFTER, WF_BEFORE, WF_MAX, WF_PREV,
                       WI_ARGMAX, WI_NAN, WI_PASSED)

# the kernels' numbering of parameters, flags, layout blocks, methods, energy columns,
# statuses, and the DOP853 tableau (numba-free, shared with the engines' Python side)
from .codes import (DOP_A, DOP_B, DOP_C, DOP_E3, DOP_E5, E_KIN_ROT, E_KIN_TRANS,  # noqa: E402,F401
                    E_LEN, E_MECHANICAL, E_POT, E_WORK_LOAD, F_DEAD_LOAD, F_END_WALL,
                    F_HETEROGENEOUS, F_LEN, G_LEN, G_MASS, KICKED, L_DISP, L_LEN,
                    L_STATE_SIZE, L_VEL, M_DOP853, M_RK4, M_VERLET, NST, P_DEAD_LOAD, P_LEN,
                    P_N_SPHERES, S_DONE, S_NONFINITE, S_PASSED, S_RUNNING, S_STEPFAIL,
                    S_TIMEOUT, WORK_SLOTS)
from . import codes  # noqa: E402
# the physics: the effects' laws, composed from the registry
from .compose import (effect_energies, effect_forces, normal_forces,  # noqa: E402
                      project_histories, wall_force)
from .compose import bit as _bit, overlap as _overlap_l  # noqa: E402

# every numbered slot as an attribute here too (callers index the kernels' arrays by them)
globals().update(codes.NAMES)


@njit(cache=True, inline="always")
def _overlap(y, ox, gaps, k):
    return y[ox + k] - y[ox + k + 1] - gaps[k]


# Block kernels: the state of L chains is stored as an (ny, L) array, chains innermost,
# and every loop runs over the lanes innermost, so that LLVM vectorises across chains
# (``effects.lanes``: a lane's arithmetic is that of one chain alone, operation for
# operation; no fastmath: no reassociation and no FMA contraction).
_blk = njit(cache=True, error_model="numpy", boundscheck=False)


@njit(cache=True, inline="always")
def _flat(a):
    return a.reshape(a.size)


@_blk
def forces_block(y, gaps, P, FL, LO, hist_dt, dy, f):
    """Time derivative dy (ny, L) of the block state y (ny, L); f (n, L) receives the
    normal force of every contact (row n-1: the end wall's, when there is one).

    gaps (G_LEN * n, L): each chain's own rows (``codes.G_*``): kernel gaps, masses,
    inertias, radii, contact constants and the effects' per-sphere and per-contact
    parameters.

    The effects' normal forces (``compose.normal_forces``), then each sphere's
    acceleration from its contacts, the end wall and the dead load, then the effects'
    forces, torques and history rates (``compose.effect_forces``). With hist_dt > 0
    (velocity Verlet), the histories in y are first advanced by slip*hist_dt and
    return-mapped, as LAMMPS does inside its force call; with hist_dt = 0 (RK4, DOP853,
    Verlet setup) y is not modified and dy carries the history rates.
    """
    n = int(P[P_N_SPHERES])
    L = y.shape[1]
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    oM = G_MASS * n
    wall = FL[F_END_WALL] != 0
    # bit k of shut: contact k (k < 63) is open in every lane, its row of f is zero
    shut = normal_forces(y, gaps, P, FL, LO, dy, f)
    load = FL[F_DEAD_LOAD] != 0
    if wall or load:
        # the end wall's force and the dead load on particle 2
        F0 = P[P_DEAD_LOAD]
        for i in range(n):
            if (i == 0 or _bit(shut, i - 1)) and (_bit(shut, i) if (i < n - 1 or wall) else True) \
                    and not (load and i == 1):
                # no force on sphere i in any lane
                for l in range(L):
                    dy[ov + i, l] = 0.0
                continue
            for l in range(L):
                fl = f[i - 1, l] if i > 0 else 0.0
                fr = f[i, l] if (i < n - 1 or wall) else 0.0
                ext = F0 if i == 1 else 0.0
                dy[ov + i, l] = (0.0 + fl - fr + ext) / gaps[oM + i, l]
    else:
        for i in range(n):
            if (i == 0 or _bit(shut, i - 1)) and (i == n - 1 or _bit(shut, i)):
                # no force on sphere i in any lane: (0 + 0 - 0) / m
                for l in range(L):
                    dy[ov + i, l] = 0.0
            elif i == 0:
                for l in range(L):
                    dy[ov, l] = (0.0 - f[0, l]) / gaps[oM, l]
            elif i == n - 1:
                for l in range(L):
                    dy[ov + i, l] = (0.0 + f[i - 1, l]) / gaps[oM + i, l]
            else:
                for l in range(L):
                    dy[ov + i, l] = (0.0 + f[i - 1, l] - f[i, l]) / gaps[oM + i, l]
    yf, dyf = _flat(y), _flat(dy)
    nL = n * L
    for j in range(nL):
        dyf[ox * L + j] = yf[ov * L + j]
    # the effects' kicked blocks (the spins): their rates start from zero, the effects'
    # torques add to them
    for slot in KICKED:
        o = LO[slot]
        if o >= 0:
            for j in range(nL):
                dyf[o * L + j] = 0.0
    effect_forces(y, gaps, P, FL, LO, hist_dt, dy, f, shut)


@_blk
def project_block(y, gaps, P, FL, LO, f):
    """Return mapping of the effects' histories of a block onto their caps (after a
    step; ``compose.project_histories``)."""
    project_histories(y, gaps, P, FL, LO)


@_blk
def energies_block(y, gaps, P, FL, LO, out):
    """Energy ledger (E_LEN, L) of a block: the translational kinetic energy, the
    effects' energies (``compose.effect_energies``: rotational kinetic, potential), the
    work of the dead load and the accumulated works."""
    n = int(P[P_N_SPHERES])
    L = y.shape[1]
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    for e in range(E_LEN):
        for l in range(L):
            out[e, l] = 0.0
    if FL[F_HETEROGENEOUS] != 0:
        oM = G_MASS * n
        for i in range(n):
            for l in range(L):
                out[E_KIN_TRANS, l] += 0.5 * gaps[oM + i, l] * y[ov + i, l] * y[ov + i, l]
    else:
        for i in range(n):
            for l in range(L):
                out[E_KIN_TRANS, l] += y[ov + i, l] * y[ov + i, l]
        for l in range(L):
            out[E_KIN_TRANS, l] = 0.5 * gaps[G_MASS * n, l] * out[E_KIN_TRANS, l]
    effect_energies(y, gaps, P, FL, LO, out)
    if FL[F_DEAD_LOAD] != 0:
        F0 = P[P_DEAD_LOAD]
        for l in range(L):
            out[E_WORK_LOAD, l] = F0 * y[ox + 1, l]
    for slot, col in WORK_SLOTS:
        o = LO[slot]
        if o >= 0:
            for l in range(L):
                out[col, l] = y[o, l]


@_blk
def rk4_block(y, h, gaps, P, FL, LO, k1, k2, k3, k4, tmp, f):
    """One classical RK4 step of a block, then the return mapping."""
    ny, L = y.shape
    hh = 0.5 * h
    h6 = h / 6.0
    forces_block(y, gaps, P, FL, LO, 0.0, k1, f)
    for j in range(ny):
        for l in range(L):
            tmp[j, l] = y[j, l] + hh * k1[j, l]
    forces_block(tmp, gaps, P, FL, LO, 0.0, k2, f)
    for j in range(ny):
        for l in range(L):
            tmp[j, l] = y[j, l] + hh * k2[j, l]
    forces_block(tmp, gaps, P, FL, LO, 0.0, k3, f)
    for j in range(ny):
        for l in range(L):
            tmp[j, l] = y[j, l] + h * k3[j, l]
    forces_block(tmp, gaps, P, FL, LO, 0.0, k4, f)
    for j in range(ny):
        for l in range(L):
            y[j, l] += h6 * (k1[j, l] + 2.0 * k2[j, l] + 2.0 * k3[j, l] + k4[j, l])
    project_block(y, gaps, P, FL, LO, f)


@_blk
def verlet_block(y, acc, h, gaps, P, FL, LO, f):
    """One LAMMPS-order velocity-Verlet step of a block; acc holds the derivative of the
    last call."""
    n = int(P[P_N_SPHERES])
    L = y.shape[1]
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    hh = 0.5 * h
    for i in range(n):
        for l in range(L):
            y[ov + i, l] += hh * acc[ov + i, l]
        _kick(y, acc, LO, hh, i, L)
    for i in range(n):
        for l in range(L):
            y[ox + i, l] += h * y[ov + i, l]
    forces_block(y, gaps, P, FL, LO, h, acc, f)
    for c, _ in WORK_SLOTS:
        o = LO[c]
        if o >= 0:
            for l in range(L):
                y[o, l] += h * acc[o, l]
    for i in range(n):
        for l in range(L):
            y[ov + i, l] += hh * acc[ov + i, l]
        _kick(y, acc, LO, hh, i, L)


@njit(cache=True, inline="always")
def _kick(y, acc, LO, hh, i, L):
    """Half kick of entry i of the effects' kicked blocks (the spins)."""
    for slot in KICKED:
        o = LO[slot]
        if o >= 0:
            for l in range(L):
                y[o + i, l] += hh * acc[o + i, l]


# Per-chain entry points (1D state of one chain): the block routines on a block of one
# lane. The adaptive method and the tests use these.
@njit(cache=True, inline="always")
def _col(a):
    return a.reshape((a.shape[0], 1))


@njit(cache=True)
def forces(y, gaps, P, FL, LO, hist_dt, dy, f):
    """Time derivative dy of one chain's state y; f receives the Hertz force of every
    contact (``forces_block`` on one lane)."""
    forces_block(_col(y), _col(gaps), P, FL, LO, hist_dt, _col(dy), _col(f))


@njit(cache=True)
def project(y, gaps, P, FL, LO, f):
    """Return mapping of one chain's friction histories (``project_block`` on one lane)."""
    project_block(_col(y), _col(gaps), P, FL, LO, _col(f))


@njit(cache=True)
def energies(y, gaps, P, FL, LO, out):
    """Energy ledger of one chain (``energies_block`` on one lane)."""
    energies_block(_col(y), _col(gaps), P, FL, LO, _col(out))


@njit(cache=True)
def rk4_step(y, h, gaps, P, FL, LO, k1, k2, k3, k4, tmp, f):
    rk4_block(_col(y), h, _col(gaps), P, FL, LO, _col(k1), _col(k2), _col(k3), _col(k4),
              _col(tmp), _col(f))


@njit(cache=True)
def verlet_step(y, acc, h, gaps, P, FL, LO, f):
    """One LAMMPS-order velocity-Verlet step; acc holds the derivative of the last call."""
    verlet_block(_col(y), _col(acc), h, _col(gaps), P, FL, LO, _col(f))

@njit(cache=True)
def rk_trial(y, h, gaps, P, FL, LO, K, ynew, tmp, f, scale_abs, rel, rtol,
             A, Bw, E5, E3, dopnorm):
    """One trial step of an explicit embedded Runge-Kutta pair (tableau ``A``, weights
    ``Bw``, error weights ``E5``/``E3`` over the stages and f(ynew)) from y, with
    K[0] = f(y) already evaluated; leaves ynew and K[S] = f(ynew). Returns the scaled
    error norm (accept if <= 1): DOP853's combined 5th/3rd-order norm if ``dopnorm``,
    else the RMS of the ``E5`` estimate."""
    ny = y.shape[0]
    S = Bw.shape[0]
    for s in range(1, S):
        for j in range(ny):
            acc = 0.0
            for q in range(s):
                acc += A[s, q] * K[q, j]
            tmp[j] = y[j] + h * acc
        forces(tmp, gaps, P, FL, LO, 0.0, K[s], f)
    for j in range(ny):
        acc = 0.0
        for q in range(S):
            acc += Bw[q] * K[q, j]
        ynew[j] = y[j] + h * acc
    forces(ynew, gaps, P, FL, LO, 0.0, K[S], f)
    e5 = 0.0
    e3 = 0.0
    for j in range(ny):
        sc = rtol * scale_abs[j]
        if rel[j] != 0:
            sc += rtol * max(abs(y[j]), abs(ynew[j]))
        if sc <= 0.0:
            continue
        a5 = 0.0
        a3 = 0.0
        for q in range(S + 1):
            a5 += E5[q] * K[q, j]
            a3 += E3[q] * K[q, j]
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    return error_norm(e5, e3, h, ny, dopnorm)


@njit(cache=True, inline="always")
def error_norm(e5, e3, h, ny, dopnorm):
    """The scaled error norm of a trial step of size h from the sums of squares of its
    scaled 5th- and 3rd-order estimates over ny components (accept if <= 1): DOP853's
    combined norm if ``dopnorm``, else the RMS of the 5th-order one."""
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    if dopnorm != 0:
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * ny)
    return abs(h) * math.sqrt(e5 / ny)


@njit(cache=True)
def dop853_try(y, h, gaps, P, FL, LO, K, ynew, tmp, f, scale_abs, rel, rtol):
    """One DOP853 trial step from y (evaluates K[0] = f(y) first); returns the scaled
    error norm (accept if <= 1)."""
    forces(y, gaps, P, FL, LO, 0.0, K[0], f)
    return rk_trial(y, h, gaps, P, FL, LO, K, ynew, tmp, f, scale_abs, rel, rtol,
                    DOP_A, DOP_B, DOP_E5, DOP_E3, 1)


@njit(cache=True)
def _finite(y, LO, n):
    for j in range(LO[L_DISP], LO[L_VEL] + n):
        if not math.isfinite(y[j]):
            return False
    return True


@njit(parallel=True, cache=True)
def run_window(method, Y, ACC, T, H, NS, STEPS, REJ, STATUS, VTHR, gaps, P, FL, LO,
               scale_abs, rel, rtol, dt, every, sample_dt, NT, auto_stop, Vout, Eout, counts):
    """Advance every running chain by up to Vout.shape[1] samples.

    Per chain b: Y[b] state, ACC[b] last derivative (Verlet), T[b] time, H[b] adaptive
    step, NS[b] samples recorded so far, STEPS/REJ counters, STATUS[b] (S_*), VTHR[b]
    the arrival speed of chain b (``stoprule.arrival_speed``). A sample is taken every
    ``every`` fixed steps (rk4, verlet) or exactly every ``sample_dt`` (dop853). A chain
    stops after NT[b] samples, or (auto_stop) at the first sample at which its last
    particle has taken the wave and left (``stoprule.last_detached``: velocity above
    VTHR[b], contact with its neighbour open), with status S_PASSED.
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
        Kst = np.empty((NST + 1, ny))
        ynew = np.empty(ny)
        ebuf = np.empty(E_LEN)
        if NS[b] == 0:
            if method == M_VERLET:
                forces(y, g, P, FL, LO, 0.0, ACC[b], f)
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
            if method == M_RK4:
                for _ in range(every):
                    rk4_step(y, dt, g, P, FL, LO, k1, k2, k3, k4, tmp, f)
                STEPS[b] += every
                T[b] += every * dt
            elif method == M_VERLET:
                for _ in range(every):
                    verlet_step(y, ACC[b], dt, g, P, FL, LO, f)
                STEPS[b] += every
                T[b] += every * dt
            else:
                t_target = NS[b] * sample_dt
                while T[b] < t_target * (1.0 - 1e-14):
                    h = min(H[b], t_target - T[b])
                    clipped = h < H[b]
                    err = dop853_try(y, h, g, P, FL, LO, Kst, ynew, tmp, f, scale_abs, rel, rtol)
                    if err <= 1.0:
                        for j in range(ny):
                            y[j] = ynew[j]
                        project(y, g, P, FL, LO, f)
                        T[b] += h
                        STEPS[b] += 1
                        fac = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** (-1.0 / 8.0))
                        if not clipped:
                            H[b] = h * fac
                    else:
                        REJ[b] += 1
                        H[b] = h * max(0.2, 0.9 * err ** (-1.0 / 8.0))
                        if H[b] < 1e-22:
                            STATUS[b] = S_STEPFAIL
                            break
                    if not math.isfinite(err):
                        STATUS[b] = S_NONFINITE
                        break
                T[b] = t_target
                if STATUS[b] != S_RUNNING:
                    break
            c = counts[b]
            for i in range(n):
                Vout[b, c, i] = y[ov + i]
            if Vout.shape[2] > n:
                Vout[b, c, n] = _wall_force(y, g, n, LO, P, FL)
            energies(y, g, P, FL, LO, ebuf)
            Eout[b, c, :] = ebuf
            counts[b] = c + 1
            NS[b] += 1
            if not _finite(y, LO, n):
                STATUS[b] = S_NONFINITE
                break
            if auto_stop and _left(y[ov + n - 1], _overlap(y, LO[L_DISP], g, n - 2),
                                   y[LO[L_DISP] + n - 1], VTHR[b], FL[F_END_WALL] != 0):
                STATUS[b] = S_PASSED


@njit(cache=True, inline="always")
def _left(v_last, overlap_last, x_last, vthr, wall):
    """Has the wave left the chain (``stoprule.last_detached``, ``stoprule.wall_left``)?
    Free end: the last
    sphere moves faster than the arrival speed with its contact open. End wall: the last
    sphere moves back from the wall faster than the arrival speed and is back at (or
    behind) its starting position x_last = 0: the wave has reflected and the wall force
    is back at (or below) its static value, so its dynamic peak is behind."""
    if wall:
        return v_last < -vthr and x_last <= 0.0
    return v_last > vthr and overlap_last <= 0.0


@njit(cache=True, inline="always")
def _wall_force_l(y, g, n, LO, P, FL, l):
    """Force (N) of the end wall on lane l of a block (``compose.wall_force``)."""
    return wall_force(y[LO[L_DISP] + n - 1, l] - g[n - 1, l], y[LO[L_VEL] + n - 1, l], g, P,
                      FL, n, l)


@njit(cache=True, inline="always")
def _wall_force(y, g, n, LO, P, FL):
    """Force (N) of the end wall on one chain (state y, per-chain array g)."""
    return _wall_force_l(_col(y), _col(g), n, LO, P, FL, 0)


@njit(cache=True, inline="always")
def _stop_lane(y, acc, l, YF, b, status, STATUS):
    """Chain b in lane l stops: its final state goes to YF[b], its lane is set to rest
    (a resting chain stays exactly at rest, costs nothing special and keeps no stale
    values in the block while its neighbours run on)."""
    STATUS[b] = status
    for j in range(y.shape[0]):
        YF[b, j] = y[j, l]
        y[j, l] = 0.0
        acc[j, l] = 0.0


# On-the-fly observables of the fixed-step blocks (``run_blocks`` with observe): the rules
# of ``granchain.observables`` (``peak``, ``peak_final``, ``wall_peak``, ``energy_ledger``)
# applied to the samples as they are taken, with the same floating-point operations, so
# that the results equal those of the Python summariser on the sampled record. Array
# slots: ``engines.obscodes``.


@njit(cache=True, inline="always")
def _pymax(a, b):
    """Python's max(a, b) (a unless b > a)."""
    return b if b > a else a


@njit(cache=True, inline="always")
def _pymin(a, b):
    """Python's min(a, b) (a unless b < a)."""
    return b if b < a else a


@njit(cache=True)
def _obs_velocity(k, y, of, oi, rk, rv):
    """Sample k of one particle's velocity y into its running peak state (of, oi) and its
    record samples (rk: sample index, rv: (previous sample, sample)): the samples that set a
    new maximum, which are the only candidates for a first crossing of a level below the
    final maximum; those below PASS_FRACTION of the running maximum are dropped (a level
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
        thr = (1.0 - PEAK_TOL) * y
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
        half = PASS_FRACTION * y
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
            if y >= (1.0 - PEAK_TOL) * top:
                if oi[OI_NEAR_AFTER] < PLATEAU_SAMPLES:
                    oi[OI_NEAR_AFTER] += 1
            else:
                oi[OI_AFTER_OPEN] = 0
        if y < PASS_FRACTION * top:
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
            ta = float(j - 1) * sdt
            tb = float(j) * sdt
            return ta + (level - y0) / (y1 - y0) * (tb - ta)
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
    plateau = (oi[OI_NEAR_BEFORE] + 1 + oi[OI_NEAR_AFTER]) > PLATEAU_SAMPLES
    if not plateau and 0 < j < S - 1:
        y0 = of[OF_BEFORE]
        y1 = top
        y2 = of[OF_AFTER]
        den = y0 - 2.0 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den < 0.0 else 0.0
        off = _pymin(_pymax(off, -0.5), 0.5)
        vmax = y1 - 0.25 * (y0 - y2) * off
        h = float(j + 1) * sdt - float(j) * sdt
        tpk = float(j) * sdt + off * h
    elif not plateau:
        vmax = top
        tpk = float(j) * sdt
    else:
        vmax = top
        tpk = _obs_crossing((1.0 - PEAK_TOL) * top, oi, rk, rv, sdt)
    out[OUT_VMAX] = vmax
    out[OUT_T_PEAK] = tpk
    out[OUT_T_FRONT] = _obs_crossing(0.5 * vmax, oi, rk, rv, sdt)
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
        if F < PASS_FRACTION * wf[WF_MAX]:
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
        y0 = wf[WF_BEFORE]
        y2 = wf[WF_AFTER]
        den = y0 - 2.0 * top + y2
        off = _pymin(_pymax(0.5 * (y0 - y2) / den, -0.5), 0.5) if den < 0.0 else 0.0
        top = top - 0.25 * (y0 - y2) * off
        tpk += off * (float(j + 1) * sdt - float(j) * sdt)
    wout[0] = top
    wout[1] = tpk
    wout[2] = 1.0


@njit(cache=True, inline="always")
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
    NT[b] samples (S_DONE), or (auto_stop) at the first sample at which its last particle
    is faster than VTHR[b] with its last contact open (S_PASSED), or on a non-finite
    state.

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
                elif auto_stop and _left(y[ov + n - 1, l], _overlap_l(y, ox, g, n - 2, l),
                                         y[ox + n - 1, l], VTHR[b], FLb[F_END_WALL] != 0):
                    _stop_lane(y, acc, l, YF, b, S_PASSED, STATUS)
                    _finish_lane(b, n, NS, sample_dt, observe, OF, OI, RK, RV, WF, WI, OUT,
                                 WOUT, wall)
            c += 1
        Y[blk] = y
        ACC[blk] = acc
