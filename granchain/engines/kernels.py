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

from ..effects import air_drag, groove_friction, hertz, particle_friction, rolling_friction

# parameter vector P
P_N, P_R, P_M, P_I, P_K, P_S, P_FC, P_KG, P_T0, P_L, P_MU, P_KT, P_KR, P_GR, P_MUR, P_GG, P_LEN = range(17)
# flags FL
F_ROT, F_GROOVE, F_DRAG, F_ODD, F_PP, F_MINDLIN, F_ROLL, F_LEN = range(8)
# layout offsets LO (-1: absent)
L_X, L_V, L_W, L_XG, L_XT, L_PS, L_WG, L_WD, L_WT, L_WR, L_NY, L_LEN = range(12)
# methods
M_RK4, M_VERLET, M_DOP853 = 0, 1, 2
# sample columns of the energy array: kinetic translational, kinetic rotational, Hertz
# potential, then the work done on the particles by groove, drag, contact friction, rolling
E_KT, E_KR, E_H, E_WG, E_WD, E_WT, E_WR, E_LEN = range(8)
# status
S_RUNNING, S_DONE, S_PASSED, S_TIMEOUT, S_NONFINITE, S_STEPFAIL = 0, 1, 2, 3, 4, 5



def _dop853_tableau():
    """scipy's Dormand-Prince 8(5,3) coefficients, loaded from their own file: importing
    them through ``scipy.integrate`` would also load its quadrature and ODE packages
    (0.35 s a process, for a table of numbers). Falls back to the normal import if
    scipy's layout differs."""
    import importlib.util
    import os
    spec = importlib.util.find_spec("scipy")
    path = os.path.join(os.path.dirname(spec.origin or ""), "integrate", "_ivp",
                        "dop853_coefficients.py")
    if os.path.isfile(path):
        mod_spec = importlib.util.spec_from_file_location("granchain_dop853_coefficients", path)
        mod = importlib.util.module_from_spec(mod_spec)
        mod_spec.loader.exec_module(mod)
        return mod
    from scipy.integrate._ivp import dop853_coefficients
    return dop853_coefficients


_dc = _dop853_tableau()
NST = _dc.N_STAGES
DOP_A = np.ascontiguousarray(_dc.A[:NST, :NST])
DOP_B = np.ascontiguousarray(_dc.B)
DOP_C = np.ascontiguousarray(_dc.C[:NST])
DOP_E3 = np.ascontiguousarray(_dc.E3)
DOP_E5 = np.ascontiguousarray(_dc.E5)


@njit(cache=True, inline="always")
def _overlap(y, ox, gaps, k):
    return y[ox + k] - y[ox + k + 1] - gaps[k]


# The laws of the effects (granchain/effects/), compiled once here and used by every
# integrator and by the return mapping.
_law = njit(cache=True, inline="always")
_hertz_force = _law(hertz.force)
_hertz_energy = _law(hertz.energy)
_drag_force = _law(air_drag.force)
_groove_slip = _law(groove_friction.slip)
_groove_map = _law(groove_friction.groove_map)
_groove_force = _law(groove_friction.groove_force)
_contact_map = _law(particle_friction.contact_map)
_contact_force = _law(particle_friction.contact_force)
_rolling_map = _law(rolling_friction.rolling_map)
_rolling_moment = _law(rolling_friction.moment)
_rolling_moment_lammps = _law(rolling_friction.moment_lammps_order)


@njit(cache=True)
def forces(y, gaps, P, FL, LO, hist_dt, dy, f):
    """Time derivative dy of state y; f receives the Hertz force of every contact.

    With hist_dt > 0 (velocity Verlet), the friction histories in y are first advanced
    by slip*hist_dt and return-mapped, as LAMMPS does inside its force call; with
    hist_dt = 0 (RK4, DOP853, Verlet setup) y is not modified and dy carries the
    history rates.
    """
    n = int(P[P_N])
    R = P[P_R]
    m = P[P_M]
    K = P[P_K]
    ox = LO[L_X]
    ov = LO[L_V]
    ow = LO[L_W]
    rot = FL[F_ROT] != 0
    for k in range(n - 1):
        f[k] = _hertz_force(K, _overlap(y, ox, gaps, k))
    for i in range(n):
        fi = 0.0
        if i > 0:
            fi += f[i - 1]
        if i < n - 1:
            fi -= f[i]
        dy[ox + i] = y[ov + i]
        dy[ov + i] = fi / m
        if rot:
            dy[ow + i] = 0.0

    if FL[F_DRAG] != 0:
        T0 = P[P_T0]
        L = P[P_L]
        odd = FL[F_ODD] != 0
        pw = 0.0
        for i in range(n):
            v = y[ov + i]
            F = _drag_force(m, v, T0, L, odd)
            dy[ov + i] += F / m
            pw += F * v
        dy[LO[L_WD]] = pw

    if FL[F_GROOVE] != 0:
        sR = P[P_S] * R
        Fc = P[P_FC]
        kg = P[P_KG]
        gam = P[P_GG]
        I = P[P_I]
        og = LO[L_XG]
        pw = 0.0
        for i in range(n):
            u = _groove_slip(y[ov + i], y[ow + i] if rot else 0.0, sR, rot)
            xi = y[og + i]
            if hist_dt > 0.0:
                xi = _groove_map(xi + u * hist_dt, u, kg, gam, Fc)
                y[og + i] = xi
            # history rate: xi' = u in stick; held while sliding at the cap
            F, dy[og + i] = _groove_force(xi, u, kg, gam, Fc)
            dy[ov + i] += F / m
            if rot:
                dy[ow + i] += -sR * F / I
            pw += F * u
        dy[LO[L_WG]] = pw

    if FL[F_PP] != 0:
        mu = P[P_MU]
        ktc = P[P_KT]
        I = P[P_I]
        mindlin = FL[F_MINDLIN] != 0
        ot = LO[L_XT]
        pw = 0.0
        for k in range(n - 1):
            fn = f[k]
            if fn > 0.0:
                d = _overlap(y, ox, gaps, k)
                kt = ktc * math.sqrt(d) if mindlin else ktc
                w = R * (y[ow + k] + y[ow + k + 1])
                xi = y[ot + k]
                cap = mu * fn
                if hist_dt > 0.0:
                    xi = _contact_map(xi + w * hist_dt, kt, cap)
                    y[ot + k] = xi
                T, dy[ot + k] = _contact_force(xi, w, kt, cap)
                # LAMMPS applies the tangential force at the contact point: lever arm
                # R - delta/2 (the slip above uses full radii, as LAMMPS does)
                arm = R - 0.5 * d
                dy[ow + k] += arm * T / I
                dy[ow + k + 1] += arm * T / I
                pw += T * arm * (y[ow + k] + y[ow + k + 1])
            else:
                if hist_dt > 0.0:
                    y[ot + k] = 0.0
                dy[ot + k] = 0.0
        dy[LO[L_WT]] = pw

    if FL[F_ROLL] != 0:
        # LAMMPS rolling sds on the 1D line (docs/lammps_laws.md sections 5 and 8):
        # v_roll = Reff (omega_k - omega_{k+1}), rho' = v_roll, moment
        # M = -k_roll rho - gamma_roll v_roll capped at mu_roll Fn, torque +Reff M on the
        # left sphere and -Reff M on the right one.
        kr = P[P_KR]
        gr = P[P_GR]
        mur = P[P_MUR]
        I = P[P_I]
        Reff = 0.5 * R
        op = LO[L_PS]
        pw = 0.0
        for k in range(n - 1):
            fn = f[k]
            if fn > 0.0:
                vr = Reff * (y[ow + k] - y[ow + k + 1])
                rho = y[op + k]
                cap = mur * fn
                if hist_dt > 0.0:
                    # Verlet: LAMMPS's order with the half-step spins
                    rho, M = _rolling_moment_lammps(rho, vr, kr, gr, cap, hist_dt)
                    y[op + k] = rho
                else:
                    # continuous law (RK4, DOP853): rho' = v_roll, project() return-maps
                    # rho after the step
                    M = _rolling_moment(rho, vr, kr, gr, cap)
                dy[op + k] = vr
                tq = Reff * M / I
                dy[ow + k] += tq
                dy[ow + k + 1] -= tq
                pw += M * vr
            else:
                if hist_dt > 0.0:
                    y[op + k] = 0.0
                dy[op + k] = 0.0
        dy[LO[L_WR]] = pw


@njit(cache=True)
def project(y, gaps, P, FL, LO, f):
    """Return mapping of the friction histories onto their Coulomb caps (after a step)."""
    n = int(P[P_N])
    if FL[F_GROOVE] != 0:
        Fc = P[P_FC]
        kg = P[P_KG]
        gam = P[P_GG]
        sR = P[P_S] * P[P_R]
        og = LO[L_XG]
        ov = LO[L_V]
        ow = LO[L_W]
        for i in range(n):
            rot = FL[F_ROT] != 0
            u = _groove_slip(y[ov + i], y[ow + i] if rot else 0.0, sR, rot)
            y[og + i] = _groove_map(y[og + i], u, kg, gam, Fc)
    if FL[F_PP] != 0:
        ox = LO[L_X]
        ot = LO[L_XT]
        K = P[P_K]
        mu = P[P_MU]
        for k in range(n - 1):
            d = _overlap(y, ox, gaps, k)
            if d <= 0.0:
                y[ot + k] = 0.0
            else:
                kt = P[P_KT] * math.sqrt(d) if FL[F_MINDLIN] != 0 else P[P_KT]
                y[ot + k] = _contact_map(y[ot + k], kt, mu * K * d * math.sqrt(d))
    if FL[F_ROLL] != 0:
        ox = LO[L_X]
        ow = LO[L_W]
        op = LO[L_PS]
        K = P[P_K]
        Reff = 0.5 * P[P_R]
        for k in range(n - 1):
            d = _overlap(y, ox, gaps, k)
            if d <= 0.0:
                y[op + k] = 0.0
            else:
                vr = Reff * (y[ow + k] - y[ow + k + 1])
                y[op + k] = _rolling_map(y[op + k], vr, P[P_KR], P[P_GR],
                                         P[P_MUR] * K * d * math.sqrt(d))


@njit(cache=True)
def energies(y, gaps, P, FL, LO, out):
    n = int(P[P_N])
    ox = LO[L_X]
    ov = LO[L_V]
    m = P[P_M]
    K = P[P_K]
    ekt = 0.0
    for i in range(n):
        ekt += y[ov + i] * y[ov + i]
    out[E_KT] = 0.5 * m * ekt
    ekr = 0.0
    if FL[F_ROT] != 0:
        ow = LO[L_W]
        for i in range(n):
            ekr += y[ow + i] * y[ow + i]
        ekr *= 0.5 * P[P_I]
    out[E_KR] = ekr
    eh = 0.0
    for k in range(n - 1):
        eh += _hertz_energy(K, _overlap(y, ox, gaps, k))
    out[E_H] = eh
    out[E_WG] = y[LO[L_WG]] if LO[L_WG] >= 0 else 0.0
    out[E_WD] = y[LO[L_WD]] if LO[L_WD] >= 0 else 0.0
    out[E_WT] = y[LO[L_WT]] if LO[L_WT] >= 0 else 0.0
    out[E_WR] = y[LO[L_WR]] if LO[L_WR] >= 0 else 0.0


@njit(cache=True)
def rk4_step(y, h, gaps, P, FL, LO, k1, k2, k3, k4, tmp, f):
    ny = y.shape[0]
    forces(y, gaps, P, FL, LO, 0.0, k1, f)
    for j in range(ny):
        tmp[j] = y[j] + 0.5 * h * k1[j]
    forces(tmp, gaps, P, FL, LO, 0.0, k2, f)
    for j in range(ny):
        tmp[j] = y[j] + 0.5 * h * k2[j]
    forces(tmp, gaps, P, FL, LO, 0.0, k3, f)
    for j in range(ny):
        tmp[j] = y[j] + h * k3[j]
    forces(tmp, gaps, P, FL, LO, 0.0, k4, f)
    for j in range(ny):
        y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    project(y, gaps, P, FL, LO, f)


@njit(cache=True)
def verlet_step(y, acc, h, gaps, P, FL, LO, f):
    """One LAMMPS-order velocity-Verlet step; acc holds the derivative of the last call."""
    n = int(P[P_N])
    ox = LO[L_X]
    ov = LO[L_V]
    ow = LO[L_W]
    rot = FL[F_ROT] != 0
    for i in range(n):
        y[ov + i] += 0.5 * h * acc[ov + i]
        if rot:
            y[ow + i] += 0.5 * h * acc[ow + i]
    for i in range(n):
        y[ox + i] += h * y[ov + i]
    forces(y, gaps, P, FL, LO, h, acc, f)
    for c in (L_WG, L_WD, L_WT, L_WR):
        if LO[c] >= 0:
            y[LO[c]] += h * acc[LO[c]]
    for i in range(n):
        y[ov + i] += 0.5 * h * acc[ov + i]
        if rot:
            y[ow + i] += 0.5 * h * acc[ow + i]


@njit(cache=True)
def dop853_try(y, h, gaps, P, FL, LO, K, ynew, tmp, f, scale_abs, rel, rtol):
    """One DOP853 trial step; returns the scaled error norm (accept if <= 1)."""
    ny = y.shape[0]
    forces(y, gaps, P, FL, LO, 0.0, K[0], f)
    for s in range(1, NST):
        for j in range(ny):
            acc = 0.0
            for q in range(s):
                acc += DOP_A[s, q] * K[q, j]
            tmp[j] = y[j] + h * acc
        forces(tmp, gaps, P, FL, LO, 0.0, K[s], f)
    for j in range(ny):
        acc = 0.0
        for q in range(NST):
            acc += DOP_B[q] * K[q, j]
        ynew[j] = y[j] + h * acc
    forces(ynew, gaps, P, FL, LO, 0.0, K[NST], f)
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
        for q in range(NST + 1):
            a5 += DOP_E5[q] * K[q, j]
            a3 += DOP_E3[q] * K[q, j]
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * ny)


@njit(cache=True)
def _finite(y, LO, n):
    for j in range(LO[L_X], LO[L_V] + n):
        if not math.isfinite(y[j]):
            return False
    return True


@njit(parallel=True, cache=True)
def run_window(method, Y, ACC, T, H, NS, STEPS, REJ, STATUS, VTHR, gaps, P, FL, LO,
               scale_abs, rel, rtol, dt, every, sample_dt, NT, auto_stop, Vout, Eout, counts):
    """Advance every running chain by up to Vout.shape[1] samples.

    Per chain b: Y[b] state, ACC[b] last derivative (Verlet), T[b] time, H[b] adaptive
    step, NS[b] samples recorded so far, STEPS/REJ counters, STATUS[b] (S_*), VTHR[b]
    the arrival speed of chain b (``schedule.arrival_speed``). A sample is taken every
    ``every`` fixed steps (rk4, verlet) or exactly every ``sample_dt`` (dop853). A chain
    stops after NT[b] samples, or (auto_stop) at the first sample at which its last
    particle has taken the wave and left (``schedule.last_detached``: velocity above
    VTHR[b], contact with its neighbour open), with status S_PASSED.
    """
    B = Y.shape[0]
    W = Vout.shape[1]
    n = int(P[P_N])
    ny = Y.shape[1]
    ov = LO[L_V]
    for b in prange(B):
        counts[b] = 0
        if STATUS[b] != S_RUNNING:
            continue
        y = Y[b]
        g = gaps[b]
        f = np.zeros(max(n - 1, 1))
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
            energies(y, g, P, FL, LO, ebuf)
            Eout[b, c, :] = ebuf
            counts[b] = c + 1
            NS[b] += 1
            if not _finite(y, LO, n):
                STATUS[b] = S_NONFINITE
                break
            if auto_stop and y[ov + n - 1] > VTHR[b] and _overlap(y, LO[L_X], g, n - 2) <= 0.0:
                STATUS[b] = S_PASSED
