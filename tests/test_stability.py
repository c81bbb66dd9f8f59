"""Hard cases stay numerically stable: finite, energy ledger closes, converges with dt."""
import math

import numpy as np
import pytest
from numba import njit

from granchain.effects import physics_terms
from granchain.engines import kernels
from granchain.engines.reference import Layout, chain_rows, pack

from conftest import SCENES, packed, run1
from independent import SS440C, hertz_chain_peaks

ALL = "[hertz,groove_friction,air_drag,rotation,particle_friction]"


def _stable(over, dts, tol_conv, tol_bal, method="rk4"):
    outs = [run1(packed(**over, **{"integrator.dt": dt, "integrator.method": method})) for dt in dts]
    for r in outs:
        assert r.wave_arrived, r.status
        assert all(math.isfinite(v) for v in r.v_max)
        assert r.energy.balance_error < tol_bal, r.energy
    a, b = outs[-2], outs[-1]
    assert abs(a.v_max_2 / b.v_max_2 - 1) < tol_conv
    assert abs(a.v_g / b.v_g - 1) < tol_conv
    return outs


# cached in the kernels' JIT cache folder (engines.backend.use_jit_cache, set when kernels is
# imported above): keyed by every kernel source, so a changed kernel is compiled again
@njit(cache=True)
def _friction_record(y, gaps, P, FL, LO, dt, steps):
    """RK4 steps of the reference kernel; per step the contact slips w = R(w_k + w_k+1),
    the groove slips u = v - sR omega, the groove's trial force over its cap
    |k_g xi_g + gamma_g u| / Fc and the contact's |k_t xi_t| / (mu_pp f) (NaN while the
    contact is open). Below 1: the history holds the force under the Coulomb cap (stick).
    Also the largest Hertz force of the run."""
    n = int(P[kernels.P_N_SPHERES])
    ny = y.shape[0]
    k1, k2, k3, k4 = np.empty(ny), np.empty(ny), np.empty(ny), np.empty(ny)
    tmp, dy = np.empty(ny), np.empty(ny)
    f = np.zeros(n)
    fmax = 0.0
    w = np.empty((steps, n - 1))
    u = np.empty((steps, n))
    groove = np.empty((steps, n))
    contact = np.empty((steps, n - 1))
    sR = P[kernels.P_GROOVE_S] * P[kernels.P_RADIUS]
    ox, ov, ow = LO[kernels.L_DISP], LO[kernels.L_VEL], LO[kernels.L_SPIN]
    og, ot = LO[kernels.L_GROOVE_HIST], LO[kernels.L_PARTICLE_HIST]
    for s in range(steps):
        kernels.rk4_step(y, dt, gaps, P, FL, LO, k1, k2, k3, k4, tmp, f)
        kernels.forces(y, gaps, P, FL, LO, 0.0, dy, f)
        for i in range(n):
            u[s, i] = y[ov + i] - sR * y[ow + i]
            groove[s, i] = abs(P[kernels.P_GROOVE_SPRING] * y[og + i]
                               + P[kernels.P_GROOVE_DASHPOT] * u[s, i]) / P[kernels.P_GROOVE_LIMIT]
        for k in range(n - 1):
            w[s, k] = P[kernels.P_RADIUS] * (y[ow + k] + y[ow + k + 1])
            contact[s, k] = np.nan
            fmax = max(fmax, f[k])
            if f[k] > 0.0:
                d = y[ox + k] - y[ox + k + 1] - gaps[k]
                kt = P[kernels.P_PARTICLE_SPRING]
                kt = kt * math.sqrt(d) if FL[kernels.F_PARTICLE_MINDLIN] != 0 else kt
                contact[s, k] = kt * abs(y[ot + k]) / (P[kernels.P_PARTICLE_MU] * f[k])
    return w, u, groove, contact, fmax


def _flips(slip):
    """Sign changes of each column (a contact) over the steps."""
    return (np.diff(np.sign(slip), axis=0) != 0).sum(axis=0)


def _longest_run(mask):
    """Longest run of consecutive True of each column."""
    best = np.zeros(mask.shape[1], dtype=int)
    cur = np.zeros(mask.shape[1], dtype=int)
    for row in mask:
        cur = np.where(row, cur + 1, 0)
        best = np.maximum(best, cur)
    return best


# Bounds of the chatter test (40 us at 1 ns, v_s = 0.1 m/s, mu_pp = 1.4). Measured: at
# most 14 slip sign changes per contact and 10 per groove contact; every contact sticks
# while loaded for >= 1684 consecutive steps; 6 groove contacts (particles 7-12) stick
# after sliding for 13-27 us; the sgn() law of Eq. 5.1 flips up to 3000 times per
# contact in 3 us.
MAX_FLIPS = 30
STICK_STEPS = 1000


def test_all_effects_pass_a_wave_without_chatter():
    """mu_pp = 1.4 through a passing wave: contact torques reach ~1e9 rad/s^2, yet no
    contact slip and no groove slip changes sign more than a few times (an explicit sgn()
    law does at every step or two), and stick occurs: every loaded contact holds its
    history below the Coulomb cap for >= 1 us, and the groove contacts the wave left
    slowly slipping come to rolling without slip (history below the cap, slip -> 0) and
    hold it for >= 10 us."""
    sc = packed(effects=ALL, **{"contact.mu_pp": 1.4})
    terms = physics_terms(sc)
    lay = Layout.of(terms)
    P, FL = pack(terms)
    LO = lay.LO
    n, vs, steps = sc.n, 0.1, 40000
    y = np.zeros(lay.ny)
    y[LO[kernels.L_VEL]] = vs
    w, u, groove, contact, fmax = _friction_record(y, chain_rows(terms, np.zeros(n - 1))[0], P, FL,
                                                   LO, 1e-9, steps)
    assert np.all(np.isfinite(w)) and np.all(np.isfinite(u)) and np.all(np.isfinite(groove))
    loaded = np.isfinite(contact)
    assert 1.4 * fmax * sc.radius / sc.inertia > 1e8    # what a sgn() law applies per step

    # bounded sign changes, per contact and per groove contact
    assert _flips(w).max() <= MAX_FLIPS, _flips(w)
    assert _flips(u).max() <= MAX_FLIPS, _flips(u)
    # stick at every contact: loaded, history under the cap, for many consecutive steps
    assert loaded.any(axis=0).all()                     # the wave loaded every contact
    stick_c = _longest_run(loaded & (contact < 0.99))
    assert (stick_c >= STICK_STEPS).all(), stick_c
    # groove stick after sliding (at rest before the wave is not counted)
    slid = np.maximum.accumulate(groove >= 0.99, axis=0)
    stuck = slid & (groove < 0.99)
    stick_g = _longest_run(stuck)
    held = np.flatnonzero(stick_g >= 10 * STICK_STEPS)
    assert len(held) >= 4, stick_g
    for i in held:              # still stuck at the end, rolling without slip
        assert stuck[-1, i] and abs(u[-1, i]) < 1e-7 * vs, (i, u[-1, i])

    # the naive explicit law sgn(slip) flips sign every step or two under the same wave
    naive_c, naive_g = _naive_sgn_flips(sc, terms)
    assert naive_c.max() > 50 * MAX_FLIPS and naive_g.max() > 50 * MAX_FLIPS, (naive_c, naive_g)


def _naive_sgn_flips(sc, terms):
    """Chapter Eq. 5.1 evaluated literally with sgn() and forward steps (for contrast):
    sign changes of each contact's and each groove contact's slip in 3 us."""
    n, R, m, I = sc.n, sc.radius, sc.mass, sc.inertia
    x = np.zeros(n)
    v = np.zeros(n)
    v[0] = 0.1
    w = np.zeros(n)
    Kh, mu = terms.hertz.K, 1.4
    flips_c, flips_g = np.zeros(n - 1, dtype=int), np.zeros(n, dtype=int)
    last_c, last_g = np.zeros(n - 1), np.zeros(n)
    for _ in range(3000):
        d = x[:-1] - x[1:]
        fk = np.where(d > 0, Kh * np.maximum(d, 0) ** 1.5, 0.0)
        a = np.zeros(n)
        a[1:] += fk / m
        a[:-1] -= fk / m
        sl = np.sign(w[:-1] + w[1:])
        sg = np.sign(v - math.sqrt(0.5) * R * w)
        tq = np.zeros(n)
        tq[:-1] -= sl * fk * mu * R
        tq[1:] -= sl * fk * mu * R
        tq += R * sg * m * 9.81 * 0.293
        v += 1e-9 * a
        w += 1e-9 * tq / I
        x += 1e-9 * v
        flips_c += (sl != last_c) & (sl != 0) & (last_c != 0)
        flips_g += (sg != last_g) & (sg != 0) & (last_g != 0)
        last_c, last_g = sl, sg
    return flips_c, flips_g


def test_all_effects_converge_and_close_the_ledger():
    _stable({"effects": ALL}, (2e-9, 1e-9), 1e-6, 1e-8)


def test_striker_at_5_m_per_s():
    _stable({"effects": ALL, "striker.velocity": 5.0}, (1e-9, 5e-10), 1e-5, 1e-7)


def _hertz_v_max_2(vs):
    """v_max,2 of the packed 440C Hertz chain (the scenes of ``packed``), solved
    independently of the engine (tests/independent.py)."""
    sc = packed()
    E, nu, rho = SS440C
    assert (sc.material.E, sc.material.nu, sc.material.rho) == (E, nu, rho)
    return hertz_chain_peaks(E, nu, rho, sc.radius, sc.n, vs, probes=sc.probes).v_max[1]


def test_striker_at_1e_minus_4_m_per_s():
    # Hertz alone: the scale-free solitary wave, against the independent solution
    # (measured: RK4 at 2 ns 1.0e-10 off)
    outs = _stable({"striker.velocity": 1e-4}, (4e-9, 2e-9), 1e-5, 1e-7)
    assert abs(outs[-1].v_max_2 / _hertz_v_max_2(1e-4) - 1) < 3e-10


@pytest.mark.slow
def test_striker_at_1e_minus_4_m_per_s_all_effects():
    # All effects: groove Coulomb friction (mu g / s ~ 4 m/s^2) removes more than v_s
    # during the ~30 us transit (Eq. 5.2 grows as 1/v_s^2), so the wave dies before
    # particle 13. Stable, converged, ledger closed, and reported as no arrival.
    runs = [run1(packed(effects=ALL, **{"striker.velocity": 1e-4, "integrator.dt": dt}))
            for dt in (4e-9, 2e-9)]
    for r in runs:
        assert not r.wave_arrived and r.status == "timeout"
        assert math.isnan(r.v_g)
        assert r.energy.balance_error < 1e-7
        assert r.energy.work_groove_friction < -0.5 * r.energy.initial
    assert runs[0].v_max[2] == pytest.approx(runs[1].v_max[2], rel=1e-5)


def test_micron_gaps_at_1_cm_per_s():
    outs = _stable({"effects": "[hertz]", "striker.velocity": 0.01,
                    "gaps": "{distribution: fixed, mean: 1.0e-6}"}, (8e-9, 4e-9), 1e-4, 1e-6)
    assert outs[-1].v_g < 0.2 * run1(packed(**{"striker.velocity": 0.01})).v_g


# Convergence of the friction run on micron gaps (RK4; reference: adaptive DOP853 at
# rtol 1e-10 on the same 16 ns sample grid, 49 s, too slow for the suite). Relative error
# of v_g / v_max,2: 4 ns 6.8e-6 / 6.1e-5, 2 ns 7.9e-6 / 7.4e-5, 1 ns 4.1e-6 / 3.9e-5,
# 0.5 ns 7.7e-7 / 6.7e-6. Down to 2 ns the error is pre-asymptotic (stick-slip and
# contact events): 4 and 2 ns agree to 1e-6 / 1.3e-5 while both are 7e-6 / 7e-5 off, so
# a 4-vs-2 ns check would understate it. From 1 ns on RK4 shows its order 2.5 (the
# Richardson estimate below matches the true error of the 0.5 ns run within 10%).
MICRON_DT = 1e-9
RK4_ORDER_LOW = 2.0            # a lower bound of RK4's observed order (2.5) here
MICRON_TOL = {"v_g": 2e-6, "v_g_front": 2e-6, "v_max_1": 1e-6, "v_max_2": 2e-5}


MICRON = {"effects": ALL, "striker.velocity": 0.01, "gaps": "{distribution: fixed, mean: 1.0e-6}"}
# The RK4 runs stop at 2.6 ms: the probes (2 and 13) peak by 2.35 ms; the spheres after them,
# slowed by the groove, peak at 5.0 and 17.9 ms, and waiting for them (t_end auto) costs 7x
# the steps. The probes' values are the same either way (the run before 2.6 ms is the same
# run); those two spheres' peaks are then not final (NaN).
MICRON_RK4_T_END = 2.6e-3
_MICRON_RK4 = {}


def _micron_rk4(dt):
    """The RK4 run of the micron-gap friction chain at ``dt`` on the 16 ns sample grid
    (cached: the RK4 and the event tests below share it; 27 s at 1 ns and 52 s at 0.5 ns
    on 2 cores)."""
    if dt not in _MICRON_RK4:
        _MICRON_RK4[dt] = run1(packed(**MICRON, **{"output.sample_dt": 16e-9, "integrator.dt": dt,
                                                   "t_end": MICRON_RK4_T_END}))
    return _MICRON_RK4[dt]


@pytest.mark.slow
def test_micron_gaps_with_friction_use_plateau_timing():
    """All effects, 1 um gaps at 1 cm/s: the probes' peaks are plateaus (free flight
    across the gaps), the ledger closes, and v_g and v_max converge: from dt to dt/2
    they change by at most (2^p - 1) * tol, so (Richardson, order p >= 2) the dt/2 run
    is within tol of the converged value."""
    runs = [_micron_rk4(dt) for dt in (MICRON_DT, MICRON_DT / 2)]
    for r in runs:
        assert r.wave_arrived and any(r.plateau)
        assert r.plateau[1]                  # the near probe's peak is a plateau
        assert r.energy.balance_error < 1e-6
    coarse, fine = runs
    for key, tol in MICRON_TOL.items():
        change = abs(getattr(coarse, key) / getattr(fine, key) - 1)
        assert change < (2**RK4_ORDER_LOW - 1) * tol, (key, change, tol)


def test_subnanometre_gaps():
    outs = _stable({"effects": ALL, "gaps": "{distribution: uniform, mean: 0.3e-9, seed: 5}"},
                   (2e-9, 1e-9), 1e-5, 5e-8)
    packed_vg = run1(packed(effects=ALL)).v_g
    assert 0.9 * packed_vg < outs[-1].v_g < packed_vg


@pytest.mark.slow
def test_500_particle_chain():
    over = {"effects": ALL, "chain.n": 500, "probes": "[2, 499]", "striker.velocity": 0.1}
    outs = _stable(over, (4e-9, 2e-9), 1e-5, 1e-6)
    r = outs[-1]
    # a long chain carries the fully formed solitary wave: Nesterenko's speed
    from granchain import analytic
    V = analytic.nesterenko_speed(packed().material, r.v_max_2)
    assert abs(r.v_g / V - 1) < 0.02


# The hard cases with the event method (engines/events.py): finite, ledger closed,
# converged between two tolerances, and agreeing with RK4 at 1 ns where that converges.
def _stable_event(over, tols=(1e-7, 1e-8), tol_conv=1e-5, tol_bal=1e-5):
    outs = [run1(packed(**over, **{"integrator.method": "event", "integrator.tolerance": t}))
            for t in tols]
    for r in outs:
        assert all(math.isfinite(v) for v in r.v_max if r.wave_arrived)
        assert r.energy.balance_error < tol_bal, r.energy
    a, b = outs
    if b.wave_arrived:
        assert abs(a.v_max_2 / b.v_max_2 - 1) < tol_conv
        assert abs(a.v_g_front / b.v_g_front - 1) < tol_conv
    return outs


def test_event_mu_pp_1_4_all_effects():
    r = _stable_event({"effects": ALL, "contact.mu_pp": 1.4})[-1]
    ref = run1(packed(effects=ALL, **{"contact.mu_pp": 1.4}))
    assert r.wave_arrived and abs(r.v_g_front / ref.v_g_front - 1) < 1e-5
    assert abs(r.v_max_2 / ref.v_max_2 - 1) < 1e-5


def test_event_striker_at_5_m_per_s():
    r = _stable_event({"effects": ALL, "striker.velocity": 5.0})[-1]
    ref = run1(packed(effects=ALL, **{"striker.velocity": 5.0, "integrator.dt": 5e-10}))
    assert r.wave_arrived and abs(r.v_max_2 / ref.v_max_2 - 1) < 1e-5


def test_event_striker_at_1e_minus_4_m_per_s():
    r = _stable_event({"striker.velocity": 1e-4})[-1]
    # against the independent solution (measured: 1.45e-8 off at tolerance 1e-8)
    assert abs(r.v_max_2 / _hertz_v_max_2(1e-4) - 1) < 5e-8


@pytest.mark.slow
def test_event_striker_at_1e_minus_4_m_per_s_all_effects():
    # all effects: the wave dies before particle 13 (see the RK4 test above)
    r = run1(packed(effects=ALL, **{"striker.velocity": 1e-4, "integrator.method": "event",
                                    "integrator.tolerance": 1e-8}))
    assert not r.wave_arrived and r.status == "timeout" and math.isnan(r.v_g)
    assert r.energy.balance_error < 1e-5
    assert r.energy.work_groove_friction < -0.5 * r.energy.initial


# The event method at tolerance 1e-8 against RK4 at 0.5 ns (the run of the micron-gap
# test above, itself within 7.7e-7 (v_g) and 6.7e-6 (v_max,2) of DOP853 at rtol 1e-10).
# Measured differences: v_g 1.75e-5 (RK4's plateau peak times are interpolated on its
# 16 ns sample grid, the event method's are not), v_g_front 8.4e-7, v_max,1 2.7e-6,
# v_max,2 7.2e-6 (about RK4's own error). Against RK4 at 1 ns: 2.1e-5, 4.3e-6, 2.7e-6,
# 3.9e-5.
EVENT_MICRON_TOL = {"v_g": 5e-5, "v_g_front": 2.5e-6, "v_max_1": 8e-6, "v_max_2": 2.2e-5}


@pytest.mark.slow
def test_event_micron_gaps_with_friction():
    r = _stable_event(MICRON)[-1]
    assert r.wave_arrived and r.plateau[1]
    ref = _micron_rk4(MICRON_DT / 2)
    for key, tol in EVENT_MICRON_TOL.items():
        diff = abs(getattr(r, key) / getattr(ref, key) - 1)
        assert diff < tol, (key, diff, tol)


def test_event_subnanometre_gaps():
    over = {"effects": ALL, "gaps": "{distribution: uniform, mean: 0.3e-9, seed: 5}"}
    r = _stable_event(over)[-1]
    ref = run1(packed(**over))
    assert abs(r.v_g_front / ref.v_g_front - 1) < 1e-5


@pytest.mark.slow
def test_event_100_particle_chain():
    # The event method's step count grows faster than the chain (one shared step for all
    # particles, landing on every contact event: 1656 steps at 50 spheres, 17677 at 100),
    # so its long-chain case is 100 spheres; the fixed-step kernels run 500 above.
    over = {"effects": ALL, "chain.n": 100, "probes": "[2, 99]", "striker.velocity": 0.1}
    r = _stable_event(over, tols=(1e-6, 1e-7))[-1]
    from granchain import analytic
    V = analytic.nesterenko_speed(packed().material, r.v_max_2)
    assert abs(r.v_g / V - 1) < 0.02
