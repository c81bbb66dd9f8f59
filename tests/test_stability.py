"""Hard cases stay numerically stable: finite, energy ledger closes, converges with dt."""
import math

import numpy as np
import pytest

from granchain.effects import physics_terms
from granchain.engines import kernels as K
from granchain.engines.reference import Layout, pack

from conftest import SCENES, packed, run1

ALL = "[hertz,groove_friction,air_drag,rotation,particle_friction]"


def _stable(over, dts, tol_conv, tol_bal, method="rk4"):
    outs = [run1(packed(**over, **{"integrator.dt": dt, "integrator.method": method})) for dt in dts]
    for r in outs:
        assert r["wave_arrived"], r["status"]
        assert all(math.isfinite(v) for v in r["v_max"])
        assert r["energy"]["balance_error"] < tol_bal, r["energy"]
    a, b = outs[-2], outs[-1]
    assert abs(a["v_max_2"] / b["v_max_2"] - 1) < tol_conv
    assert abs(a["v_g"] / b["v_g"] - 1) < tol_conv
    return outs


def test_all_effects_pass_a_wave_without_chatter():
    """mu_pp = 1.4 through a passing wave: contact torques reach ~1e9 rad/s^2, yet the
    contact slips never flip sign step after step (an explicit sgn() law does)."""
    sc = packed(effects=ALL, **{"contact.mu_pp": 1.4})
    terms = physics_terms(sc)
    lay = Layout.of(terms)
    P, FL = pack(terms)
    LO = lay.LO
    y = np.zeros(lay.ny)
    y[LO[K.L_V]] = 0.1
    gaps = np.zeros(sc.n - 1)
    f = np.zeros(sc.n - 1)
    ks = [np.zeros(lay.ny) for _ in range(5)]
    slips, cap = [], 0.0
    for step in range(9000):
        K.rk4_step(y, 1e-9, gaps, P, FL, LO, *ks, f)
        w = y[LO[K.L_W]:LO[K.L_W] + sc.n]
        slips.append(w[:-1] + w[1:])
        if step % 10 == 0:
            dy = np.zeros(lay.ny)
            K.forces(y, gaps, P, FL, LO, 0.0, dy, f)
            cap = max(cap, 1.4 * f.max() * sc.radius / sc.inertia)
    slips = np.array(slips)
    assert np.all(np.isfinite(slips))
    assert cap > 1e8          # mu_pp f R / I: what a sgn() law applies at every step
    flips = (np.diff(np.sign(slips), axis=0) != 0).sum(axis=0)
    assert flips.max() < 60, flips         # smooth stick-slip, not a flip per step

    # the naive explicit law sgn(slip) flips sign every step or two under the same wave
    naive = _naive_sgn_flips(sc, terms)
    assert naive > 10 * max(flips.max(), 1)


def _naive_sgn_flips(sc, terms):
    """Chapter Eq. 5.1 evaluated literally with sgn() and forward steps (for contrast)."""
    n, R, m, I = sc.n, sc.radius, sc.mass, sc.inertia
    x = np.zeros(n)
    v = np.zeros(n)
    v[0] = 0.1
    w = np.zeros(n)
    Kh, mu = terms.hertz.K, 1.4
    flips, last = 0, np.zeros(n - 1)
    for _ in range(3000):
        d = x[:-1] - x[1:]
        fk = np.where(d > 0, Kh * np.maximum(d, 0) ** 1.5, 0.0)
        a = np.zeros(n)
        a[1:] += fk / m
        a[:-1] -= fk / m
        sl = np.sign(w[:-1] + w[1:])
        tq = np.zeros(n)
        tq[:-1] -= sl * fk * mu * R
        tq[1:] -= sl * fk * mu * R
        tq += R * np.sign(v - math.sqrt(0.5) * R * w) * m * 9.81 * 0.293
        v += 1e-9 * a
        w += 1e-9 * tq / I
        x += 1e-9 * v
        flips += int(((sl != last) & (sl != 0) & (last != 0)).sum())
        last = sl
    return flips


def test_all_effects_converge_and_close_the_ledger():
    _stable({"effects": ALL}, (2e-9, 1e-9), 1e-6, 1e-8)


def test_striker_at_5_m_per_s():
    _stable({"effects": ALL, "striker.velocity": 5.0}, (1e-9, 5e-10), 1e-5, 1e-7)


def test_striker_at_1e_minus_4_m_per_s():
    # Hertz alone: the scale-free solitary wave (same v_max/v_s as at 0.1 m/s)
    outs = _stable({"striker.velocity": 1e-4}, (4e-9, 2e-9), 1e-5, 1e-7)
    assert outs[-1]["v_max_2"] / 1e-4 == pytest.approx(0.6817, abs=2e-4)
    # All effects: groove Coulomb friction (mu g / s ~ 4 m/s^2) removes more than v_s
    # during the ~30 us transit (Eq. 5.2 grows as 1/v_s^2), so the wave dies before
    # particle 13. Stable, converged, ledger closed, and reported as no arrival.
    runs = [run1(packed(effects=ALL, **{"striker.velocity": 1e-4, "integrator.dt": dt}))
            for dt in (4e-9, 2e-9)]
    for r in runs:
        assert not r["wave_arrived"] and r["status"] == "timeout"
        assert math.isnan(r["v_g"])
        assert r["energy"]["balance_error"] < 1e-7
        assert r["energy"]["work_groove_friction"] < -0.5 * r["energy"]["initial"]
    assert runs[0]["v_max"][2] == pytest.approx(runs[1]["v_max"][2], rel=1e-5)


def test_micron_gaps_at_1_cm_per_s():
    outs = _stable({"effects": "[hertz]", "striker.velocity": 0.01,
                    "gaps": "{distribution: fixed, mean: 1.0e-6}"}, (4e-9, 2e-9), 1e-4, 1e-6)
    assert outs[-1]["v_g"] < 0.2 * run1(packed(**{"striker.velocity": 0.01}))["v_g"]


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


def test_micron_gaps_with_friction_use_plateau_timing():
    """All effects, 1 um gaps at 1 cm/s: the probes' peaks are plateaus (free flight
    across the gaps), the ledger closes, and v_g and v_max converge: from dt to dt/2
    they change by at most (2^p - 1) * tol, so (Richardson, order p >= 2) the dt/2 run
    is within tol of the converged value."""
    base = {"effects": ALL, "striker.velocity": 0.01, "output.sample_dt": 16e-9,
            "gaps": "{distribution: fixed, mean: 1.0e-6}"}
    runs = [run1(packed(**base, **{"integrator.dt": dt})) for dt in (MICRON_DT, MICRON_DT / 2)]
    for r in runs:
        assert r["wave_arrived"] and any(r["plateau"])
        assert r["plateau"][1]                  # the near probe's peak is a plateau
        assert r["energy"]["balance_error"] < 1e-6
    coarse, fine = runs
    for key, tol in MICRON_TOL.items():
        change = abs(coarse[key] / fine[key] - 1)
        assert change < (2**RK4_ORDER_LOW - 1) * tol, (key, change, tol)


def test_subnanometre_gaps():
    outs = _stable({"effects": ALL, "gaps": "{distribution: uniform, mean: 0.3e-9, seed: 5}"},
                   (2e-9, 1e-9), 1e-5, 5e-8)
    packed_vg = run1(packed(effects=ALL))["v_g"]
    assert 0.9 * packed_vg < outs[-1]["v_g"] < packed_vg


@pytest.mark.slow
def test_500_particle_chain():
    over = {"effects": ALL, "chain.n": 500, "probes": "[2, 499]", "striker.velocity": 0.1}
    outs = _stable(over, (4e-9, 2e-9), 1e-5, 1e-6)
    r = outs[-1]
    # a long chain carries the fully formed solitary wave: Nesterenko's speed
    from granchain import analytic
    V = analytic.nesterenko_speed(packed().material, r["v_max_2"])
    assert abs(r["v_g"] / V - 1) < 0.02
