"""The reference engine's integrators, on blocks of chains and on one chain.

The state of one chain is a flat float64 vector laid out by ``engines.reference.Layout``:
displacements x (from the initial, gapped positions), velocities v, and only when the
scene enables them the effects' blocks (spins, histories) and one accumulated-work entry
per effect that does work. Effects are switched by runtime flags checked once per force
call (not per particle), so a Hertz-only chain carries no rotational state and its force
loop never touches friction code.

One force routine, ``forces_block``, holds the physics: the effects' laws composed from
the registry (``engines.compose``) and the chain's own Newton's law between them. The
integrators call it:
- ``rk4``: classical fixed-step RK4 on the full state (histories integrate their rates,
  held at their caps while sliding), then the return mapping ``project``.
- ``verlet``: velocity Verlet in LAMMPS's order (half kick, drift, forces at the
  half-step velocities with the history update and return mapping inside the force
  call, half kick; no history update at setup), like ``fix nve/sphere``.
- ``dop853``: adaptive Dormand-Prince 8(5,3) with error control (``rk_trial``), the
  return mapping after each accepted step. Serves as converged truth.
The drivers that run them over chains are in ``engines.kernels`` (fixed step, adaptive)
and ``engines.events`` (the event method).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True): a cache keyed by every source compiled in

from .codes import (DOP_A, DOP_A_DENSE, DOP_B, DOP_D, DOP_E3, DOP_E5,  # noqa: E402
                    E_KIN_TRANS, E_LEN, E_WORK_LOAD, F_DEAD_LOAD, F_END_WALL, F_HETEROGENEOUS,
                    G_MASS, KICKED, L_DISP, L_STATE_SIZE, L_VEL, P_DEAD_LOAD, P_N_SPHERES,
                    WORK_SLOTS)
# the physics: the effects' laws, composed from the registry
from .compose import (effect_energies, effect_forces, normal_forces,  # noqa: E402
                      project_histories, wall_force, wall_force_at)
from .compose import bit as _bit  # noqa: E402


# Block kernels: the state of L chains is stored as an (ny, L) array, chains innermost,
# and every loop runs over the lanes innermost, so that LLVM vectorises across chains
# (``effects.lanes``: a lane's arithmetic is that of one chain alone, operation for
# operation; no fastmath: no reassociation and no FMA contraction). The block routines
# allocate nothing (their callers hand them every buffer), so numba's reference counting
# is compiled out of them (``_nrt=False``): the composed functions inlined into
# forces_block bind their array arguments again, and the atomic increments and
# decrements of those bindings cost the every-effect Verlet kernel 8 % of its time on one
# thread (benchmarks/kernels.py --threads 1). An allocation added here fails to compile.
_blk = njit(cache=True, error_model="numpy", boundscheck=False, _nrt=False)


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
    # the half kicks of the velocities and of the effects' kicked blocks (the spins), each
    # entry on its own: written here, not in an inlined helper, whose binding of y and acc
    # at every call would count references inside the loop
    for i in range(n):
        for l in range(L):
            y[ov + i, l] += hh * acc[ov + i, l]
    for slot in KICKED:
        o = LO[slot]
        if o >= 0:
            for i in range(n):
                for l in range(L):
                    y[o + i, l] += hh * acc[o + i, l]
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
    for slot in KICKED:
        o = LO[slot]
        if o >= 0:
            for i in range(n):
                for l in range(L):
                    y[o + i, l] += hh * acc[o + i, l]


# Per-chain entry points (1D state of one chain): the block routines on a block of one
# lane. The adaptive method and the tests use these. ``forces``, ``project`` and
# ``dop853_try`` are inlined by numba where they are called (a one-line wrapper compiled
# on its own is one more library that links, optimises and emits every effect's law
# again: the drivers above it emit them all the same); called from Python they compile
# on their own.
@njit(cache=True, inline="always")
def _col(a):
    return a.reshape((a.shape[0], 1))


@njit(cache=True, inline="always")
def forces(y, gaps, P, FL, LO, hist_dt, dy, f):
    """Time derivative dy of one chain's state y; f receives the Hertz force of every
    contact (``forces_block`` on one lane)."""
    forces_block(_col(y), _col(gaps), P, FL, LO, hist_dt, _col(dy), _col(f))


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _stage(y, h, A, r, s, K, tmp, gaps, P, FL, LO, f):
    """Stage s of a Runge-Kutta step from y of length h: K[s] = f(y + h sum_q A[r, q] K[q])
    over q < s. Terms of a zero coefficient are left out: for finite K the sums are the
    same to the last bit (each starts from +0.0, which a +-0.0 term leaves unchanged), and
    the lanes (``eventlanes._combine``) leave them out too."""
    for j in range(y.shape[0]):
        acc = 0.0
        for q in range(s):
            if A[r, q] != 0.0:
                acc += A[r, q] * K[q, j]
        tmp[j] = y[j] + h * acc
    forces(tmp, gaps, P, FL, LO, 0.0, K[s], f)


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
        _stage(y, h, A, s, s, K, tmp, gaps, P, FL, LO, f)
    for j in range(ny):
        acc = 0.0
        for q in range(S):
            if Bw[q] != 0.0:
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
            if E5[q] != 0.0:
                a5 += E5[q] * K[q, j]
            if E3[q] != 0.0:
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


@njit(cache=True, inline="always")
def dop853_try(y, h, gaps, P, FL, LO, K, ynew, tmp, f, scale_abs, rel, rtol):
    """One DOP853 trial step from y (evaluates K[0] = f(y) first); returns the scaled
    error norm (accept if <= 1)."""
    forces(y, gaps, P, FL, LO, 0.0, K[0], f)
    return rk_trial(y, h, gaps, P, FL, LO, K, ynew, tmp, f, scale_abs, rel, rtol,
                    DOP_A, DOP_B, DOP_E5, DOP_E3, 1)


@njit(cache=True)
def dop853_dense(y, ynew, h, gaps, P, FL, LO, K, tmp, f, F):
    """DOP853's 7th-order dense output of an accepted step y -> ynew of length h, as
    scipy's ``DOP853``: K holds the step's stages and K[NST] = f(ynew)
    (:func:`dop853_try`); evaluates the three more stages into K[NST + 1:] and leaves the
    interpolant's coefficients in F (``DENSE_POWER`` rows, :func:`dense_state`)."""
    ny = y.shape[0]
    S0 = K.shape[0] - DOP_A_DENSE.shape[0]
    for r in range(DOP_A_DENSE.shape[0]):
        _stage(y, h, DOP_A_DENSE, r, S0 + r, K, tmp, gaps, P, FL, LO, f)
    for j in range(ny):
        dy = ynew[j] - y[j]
        F[0, j] = dy
        F[1, j] = h * K[0, j] - dy
        F[2, j] = 2.0 * dy - h * (K[S0 - 1, j] + K[0, j])
    for i in range(DOP_D.shape[0]):
        for j in range(ny):
            acc = 0.0
            for q in range(DOP_D.shape[1]):
                if DOP_D[i, q] != 0.0:
                    acc += DOP_D[i, q] * K[q, j]
            F[3 + i, j] = h * acc


@njit(cache=True)
def dense_state(y, F, x, out):
    """The dense output (:func:`dop853_dense`, coefficients F) of the step from y at the
    fraction x in [0, 1] of its length, into out (scipy's ``Dop853DenseOutput``)."""
    R = F.shape[0]
    for j in range(y.shape[0]):
        acc = 0.0
        for i in range(R):
            acc += F[R - 1 - i, j]
            acc *= x if i % 2 == 0 else 1.0 - x
        out[j] = y[j] + acc


@njit(cache=True)
def _wall_force_l(y, g, n, LO, P, FL, l):
    """Force (N) of the end wall on lane l of a block (``compose.wall_force_at``: the
    laws that read their history in the state included)."""
    return wall_force_at(y, g, P, FL, LO, n, l)


# compiled once and called by the per-chain drivers (inlined, the wall's laws were compiled
# at each of their samples' calls)
@njit(cache=True)
def _wall_force(y, g, n, LO, P, FL):
    """Force (N) of the end wall on one chain (state y, per-chain array g)."""
    return _wall_force_l(_col(y), _col(g), n, LO, P, FL, 0)


@njit(cache=True)
def wall_forces(d, w, G, P, FL, n, out):
    """out[s, b]: the end wall's force (N) on chain b (rows G[b]) at overlap d[s, b] (m)
    and closing speed w[s, b] (m/s), by ``compose.wall_force`` (the LAMMPS engine's ledger
    evaluates the kernels' own law at its dumped states)."""
    g = np.empty((G.shape[1], 1))
    for b in range(d.shape[1]):
        for r in range(G.shape[1]):
            g[r, 0] = G[b, r]
        for s in range(d.shape[0]):
            out[s, b] = wall_force(d[s, b], w[s, b], g, P, FL, n, 0)


@njit(cache=True)
def wall_forces_at(d, w, s, G, P, FL, LO, blocks, n, out):
    """out[i, b]: the end wall's force (N) on chain b (rows G[b]) in the state a sample
    reports: overlap d[i, b] (m), closing speed w[i, b] (m/s) and, for each state block
    offset blocks[j], the wall's entry s[i, b, j]; by ``compose.wall_force_at`` (the laws
    that read their history in the state included). The LAMMPS engine's ledger evaluates
    it where LAMMPS reports the wall's state (``EffectSpec.lammps_wall_state``)."""
    g = np.empty((G.shape[1], 1))
    y = np.zeros((LO[L_STATE_SIZE], 1))
    for b in range(d.shape[1]):
        for r in range(G.shape[1]):
            g[r, 0] = G[b, r]
        for i in range(d.shape[0]):
            y[LO[L_DISP] + n - 1, 0] = d[i, b] + g[n - 1, 0]
            y[LO[L_VEL] + n - 1, 0] = w[i, b]
            for j in range(blocks.shape[0]):
                y[blocks[j] + n - 1, 0] = s[i, b, j]
            out[i, b] = wall_force_at(y, g, P, FL, LO, n, 0)
