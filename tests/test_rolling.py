"""Rolling friction: LAMMPS ``rolling sds`` in the reference engine
(docs/explanation/lammps_laws.md section 5), its energy ledger, its stability, and a LAMMPS run of the same chain."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from granchain.effects import physics_terms
from granchain.engines import kernels
from granchain.engines import reference
from granchain.engines.reference import Layout, chain_rows, pack

from tests.conftest import SCENES, packed, pair, run1

ROLL = "[hertz, rotation, rolling_friction]"
CONTACT_ROLL = "[hertz, rotation, particle_friction, rolling_friction]"
ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"
# k_roll (N/m), gamma_roll (N s/m), mu_roll: the cap mu_roll Fn ~ 1e-4 N in a 0.1 m/s wave,
# reached with rho ~ 1 nm; the dashpot alone exceeds it at relative spins of ~300 rad/s
ROLL_PARAMS = {"rolling.k_roll": 1e5, "rolling.gamma_roll": 0.05, "rolling.mu_roll": 0.01}
SPINS = np.array([300.0, -200.0, 500.0, 0.0, -400.0])        # rad/s, 5-sphere chain


def five(effects, **over):
    roll = ROLL_PARAMS if "rolling_friction" in effects else {}     # unused keys are refused
    return packed(effects=effects, **{"chain.n": 5, "probes": "[2, 4]", **roll, **over})


class Chain:
    """One chain driven through the engine's own kernels, recording the full state."""

    def __init__(self, scene, w0=None, gaps=None):
        self.scene = scene
        self.terms = physics_terms(scene)
        self.lay = Layout.of(self.terms)
        self.P, self.FL = pack(self.terms)
        self.LO = self.lay.LO
        n = scene.n
        self.n = n
        self.y = np.zeros(self.lay.ny)
        self.y[self.LO[kernels.L_VEL]] = scene.striker_velocities[0]
        if w0 is not None:
            self.y[self.LO[kernels.L_SPIN]:self.LO[kernels.L_SPIN] + n] = w0
        gaps = np.zeros(n - 1) if gaps is None else np.asarray(gaps, dtype=float)
        # the kernels' per-chain rows: the gaps first, then masses, radii, constants
        self.gaps = chain_rows(self.terms, gaps)[0]
        self.f = np.zeros(n)

    def block(self, slot, size=None):
        o = self.LO[slot]
        return self.y[o:o + (self.n if size is None else size)]

    def energy(self):
        e = np.zeros(kernels.E_LEN)
        kernels.energies(self.y, self.gaps, self.P, self.FL, self.LO, e)
        return e

    def run(self, method, dt, nsteps, every=1):
        """States (every `every` steps, the initial one included) and energies."""
        acc = np.zeros(self.lay.ny)
        ks = [np.zeros(self.lay.ny) for _ in range(5)]
        if method == "verlet":      # setup: forces without history update
            kernels.forces(self.y, self.gaps, self.P, self.FL, self.LO, 0.0, acc, self.f)
        ys, es = [self.y.copy()], [self.energy()]
        for s in range(1, nsteps + 1):
            if method == "verlet":
                kernels.verlet_step(self.y, acc, dt, self.gaps, self.P, self.FL, self.LO, self.f)
            else:
                kernels.rk4_step(self.y, dt, self.gaps, self.P, self.FL, self.LO, *ks, self.f)
            if s % every == 0:
                ys.append(self.y.copy())
                es.append(self.energy())
        return np.array(ys), np.array(es)


def balance(E):
    tot = E[:, kernels.E_KIN_TRANS] + E[:, kernels.E_KIN_ROT] + E[:, kernels.E_POT]
    return np.abs(tot - tot[0] - E[:, kernels.E_WORK_GROOVE:].sum(axis=1)).max() / tot[0]


# ---------------------------------------------------------------------------------------
# (a) the law, by hand

def two_spheres(d, w, rho, **over):
    """Two spheres overlapping by d (m), spins w (rad/s), rolling history rho (m)."""
    c = Chain(pair(effects=ROLL, **{**ROLL_PARAMS, **over}), w0=w)
    c.block(kernels.L_DISP)[0] = d
    c.block(kernels.L_VEL)[0] = 0.0
    c.block(kernels.L_ROLLING_HIST, 1)[0] = rho
    return c


def by_hand(c, d, w, rho, dt=0.0):
    """docs/explanation/lammps_laws.md section 8, rolling sds, written out for one contact."""
    rf, R, I = c.terms.rolling_friction, c.terms.R, c.terms.rotation.inertia
    fn = c.terms.hertz.K * d**1.5
    vroll = R / 2 * (w[0] - w[1])
    rho = rho + dt * vroll
    M = -rf.k_roll * rho - rf.gamma_roll * vroll
    cap = rf.mu_roll * fn
    if abs(M) > cap:
        rho_map = -(math.copysign(cap, M) + rf.gamma_roll * vroll) / rf.k_roll
        M = math.copysign(cap, M)
        if dt > 0:
            rho = rho_map
    return (R / 2) * M / I, -(R / 2) * M / I, M * vroll, rho


@pytest.mark.parametrize("hist_dt", [0.0, 1e-9])
@pytest.mark.parametrize("w, rho, regime", [
    ((105.0, 100.0), 0.0, "stick"),           # dashpot only: 1.9e-5 N < cap 1.4e-4 N
    ((105.0, 100.0), 2e-10, "stick"),
    ((105.0, 100.0), -4e-10, "stick"),
    ((0.0, 0.0), 5e-9, "slip"),               # spring beyond the cap, no spin
    ((2000.0, -3000.0), 0.0, "slip"),         # dashpot beyond the cap
    ((-2000.0, 3000.0), 1e-9, "slip"),
])
def test_rolling_torque_is_the_lammps_formula(w, rho, regime, hist_dt):
    d = 5e-8
    c = two_spheres(d, w, rho)
    dy = np.zeros(c.lay.ny)
    kernels.forces(c.y, c.gaps, c.P, c.FL, c.LO, hist_dt, dy, c.f)
    t0, t1, power, rho_new = by_hand(c, d, w, rho, hist_dt)
    cap = c.terms.rolling_friction.mu_roll * c.f[0]
    assert c.f[0] == pytest.approx(c.terms.hertz.K * d**1.5, rel=1e-15)
    assert (abs(t0) * c.terms.rotation.inertia / (c.terms.R / 2) < cap * (1 - 1e-9)) == (regime == "stick")
    wo = c.LO[kernels.L_SPIN]
    assert dy[wo] == pytest.approx(t0, rel=1e-14, abs=0)
    assert dy[wo + 1] == pytest.approx(t1, rel=1e-14, abs=0)
    assert dy[wo] == -dy[wo + 1]                       # equal and opposite
    assert dy[c.LO[kernels.L_WORK_ROLLING]] == pytest.approx(power, rel=1e-14, abs=0)
    assert power <= 0 or regime == "stick"             # sliding always dissipates
    assert dy[c.LO[kernels.L_ROLLING_HIST]] == pytest.approx(c.terms.R / 2 * (w[0] - w[1]),
                                                             rel=1e-15)
    if hist_dt > 0:                                    # LAMMPS: history advanced and mapped
        assert c.block(kernels.L_ROLLING_HIST, 1)[0] == pytest.approx(rho_new, rel=1e-13, abs=1e-30)
    else:                                              # derivative only: y untouched
        assert c.block(kernels.L_ROLLING_HIST, 1)[0] == rho


def test_rolling_torque_opposes_relative_spin():
    """The left sphere spins faster: the moment slows it and speeds up its neighbour."""
    for w in ((105.0, 100.0), (400.0, 100.0)):         # stick, slide
        c = two_spheres(5e-8, w, 0.0)
        dy = np.zeros(c.lay.ny)
        kernels.forces(c.y, c.gaps, c.P, c.FL, c.LO, 1e-9, dy, c.f)
        assert dy[c.LO[kernels.L_SPIN]] < 0 < dy[c.LO[kernels.L_SPIN] + 1]
    c = two_spheres(5e-8, (105.0, 100.0), 0.0, **{"rolling.gamma_roll": 0.0})
    kernels.forces(c.y, c.gaps, c.P, c.FL, c.LO, 1e-9, dy, c.f)
    assert c.block(kernels.L_ROLLING_HIST, 1)[0] > 0                   # rho += dt Reff (w_L - w_R)
    assert dy[c.LO[kernels.L_SPIN]] < 0 < dy[c.LO[kernels.L_SPIN] + 1]
    # spheres rolling together (equal spins) feel no rolling moment
    c = two_spheres(5e-8, (400.0, 400.0), 0.0)
    kernels.forces(c.y, c.gaps, c.P, c.FL, c.LO, 1e-9, dy, c.f)
    assert dy[c.LO[kernels.L_SPIN]] == 0 and dy[c.LO[kernels.L_SPIN] + 1] == 0


def test_return_map_stores_the_dashpot_and_project_matches_it():
    """Above the cap, rho is mapped to -(cap sgn(M) + gamma v)/k (LAMMPS); project()
    (RK4, DOP853) uses the same map; an open contact has no history."""
    d, w = 5e-8, (2000.0, -3000.0)
    c = two_spheres(d, w, 0.0)
    kernels.project(c.y, c.gaps, c.P, c.FL, c.LO, c.f)
    rf = c.terms.rolling_friction
    cap = rf.mu_roll * c.terms.hertz.K * d**1.5
    vr = c.terms.R / 2 * 5000.0
    rho = c.block(kernels.L_ROLLING_HIST, 1)[0]
    assert rho == pytest.approx((cap - rf.gamma_roll * vr) / rf.k_roll, rel=1e-13)
    assert -rf.k_roll * rho - rf.gamma_roll * vr == pytest.approx(-cap, rel=1e-9)
    c = two_spheres(-1e-9, w, 3e-9)                   # apart: history erased
    kernels.project(c.y, c.gaps, c.P, c.FL, c.LO, c.f)
    assert c.block(kernels.L_ROLLING_HIST, 1)[0] == 0.0
    c = two_spheres(-1e-9, w, 3e-9)
    dy = np.zeros(c.lay.ny)
    kernels.forces(c.y, c.gaps, c.P, c.FL, c.LO, 1e-9, dy, c.f)
    assert c.block(kernels.L_ROLLING_HIST, 1)[0] == 0.0 and dy[c.LO[kernels.L_SPIN]] == 0.0


def test_zero_history_above_the_cap_gives_zero_moment_in_verlet():
    """LAMMPS zeroes the rolling moment when the updated history is exactly 0 and the
    trial (the dashpot alone) exceeds the cap (gran_sub_mod_rolling: 'else zero3(fr)')."""
    w, dt = (2000.0, -3000.0), 1e-9
    c = Chain(pair(effects=ROLL, **ROLL_PARAMS))
    vr = 0.5 * c.terms.R * (w[0] - w[1])              # as the kernel computes it
    c = two_spheres(5e-8, w, -(vr * dt))              # rho + dt v_roll == 0 exactly
    dy = np.zeros(c.lay.ny)
    kernels.forces(c.y, c.gaps, c.P, c.FL, c.LO, dt, dy, c.f)
    assert c.n == 2 and c.f[0] > 0
    assert c.terms.rolling_friction.gamma_roll * vr > c.terms.rolling_friction.mu_roll * c.f[0]
    assert c.block(kernels.L_ROLLING_HIST, 1)[0] == 0.0
    assert dy[c.LO[kernels.L_SPIN]] == 0.0 and dy[c.LO[kernels.L_SPIN] + 1] == 0.0


# ---------------------------------------------------------------------------------------
# (b) energy ledger

def test_energy_balance_closes_with_rolling_rk4():
    """5 spinning spheres struck at 0.1 m/s, 3 us at dt = 1 ns: rolling friction does work
    of ~1.5 % of E(0) (stick, dashpot slides, release), the ledger closes to RK4's error of
    the Hertz chain itself (measured 4.1e-10; without the rolling work column: 1.5e-2)."""
    c = Chain(five(CONTACT_ROLL), w0=SPINS)
    _, E = c.run("rk4", 1e-9, 3000)
    wr = E[-1, kernels.E_WORK_ROLLING]
    e0 = E[0, kernels.E_KIN_TRANS] + E[0, kernels.E_KIN_ROT]
    assert wr < -1e-2 * e0
    assert balance(E) < 1e-9
    # the same chain without rolling: the ledger error is no smaller (it is the Hertz one)
    c0 = Chain(five("[hertz, rotation, particle_friction]"), w0=SPINS)
    _, E0 = c0.run("rk4", 1e-9, 3000)
    assert balance(E) < 1.1 * balance(E0)


@pytest.mark.parametrize("method", ["rk4", "adaptive"])
def test_scene_energy_balance_with_rolling(method):
    """Whole pipeline (scene -> terms -> engine -> ledger), every effect with rolling on:
    measured 6.1e-10 (rk4 at 1 ns) and 2.2e-9 (adaptive at 1e-10)."""
    integ = {"integrator.tolerance": 1e-10} if method == "adaptive" else {}
    r = run1(packed(effects=ALL, **ROLL_PARAMS, **{"integrator.method": method}, **integ))
    assert r.wave_arrived
    assert r.energy.balance_error < 1e-8
    assert r.energy.work_rolling_friction < 0


@pytest.mark.lammps
def test_rk4_converges_to_the_lammps_law(tmp_path):
    """RK4 (the continuous law) at 1 ns against LAMMPS's own rolling sds at 1/32 ns (the
    deck write_deck writes, run in LAMMPS): the spins and velocities agree, so the two
    integrate the same law. Measured max differences relative to each particle's max
    |history|: omega_y 8.2e-10, vx 2.5e-9 (bounds 3x); the rolling law changed the spins by
    > 1 % (a history held at the cap while sliding, like the contact law, was 1e-5 off)."""
    T, dt = 3e-6, 1e-9
    scene = five(ROLL, t_end=T, **{"integrator.method": "verlet", "integrator.dt": dt / 32,
                                    "output.sample_dt": dt})
    vx, wy, every, last, w_read = _lammps_histories(tmp_path, scene, SPINS)
    assert every == 32 and last == 32 * int(round(T / dt))
    c = Chain(five(ROLL), w0=w_read)
    Yr, _ = c.run("rk4", dt, int(round(T / dt)))
    wo, vo = c.LO[kernels.L_SPIN], c.LO[kernels.L_VEL]
    wr, vr = Yr[:, wo:wo + 5], Yr[:, vo:vo + 5]
    rel_w = np.abs(wr - wy).max(axis=0) / np.abs(wy).max(axis=0)
    rel_v = np.abs(vr - vx).max(axis=0) / np.abs(vx).max(axis=0)
    print("max rel omega_y", rel_w.max(), "vx", rel_v.max())
    assert rel_w.max() < 2.5e-9 and rel_v.max() < 7.5e-9
    assert np.abs(wy[-1] - SPINS).max() > 1e-2 * np.abs(SPINS).max()   # rolling changed the spins


# ---------------------------------------------------------------------------------------
# (c) stability

def test_chain_with_rolling_is_stable_at_scene_dt():
    """15-sphere chain, every effect, a stiff and strongly damped rolling law: finite,
    bounded by the striker's energy, and the three integrators agree."""
    over = {"rolling.k_roll": 1e7, "rolling.gamma_roll": 1.0, "rolling.mu_roll": 0.1}
    runs = {m: run1(packed(effects=ALL, **over, **{"integrator.method": m}))
            for m in ("rk4", "verlet", "adaptive")}
    for m, r in runs.items():
        assert r.wave_arrived and r.status == "passed", (m, r.status)
        assert all(math.isfinite(v) and 0 <= v <= 0.1 for v in r.v_max)
        e = r.energy
        assert e.final_mechanical <= e.initial
        assert e.work_rolling_friction <= 0
    assert runs["rk4"].v_max_2 == pytest.approx(runs["adaptive"].v_max_2, rel=1e-6)
    assert runs["verlet"].v_max_2 == pytest.approx(runs["adaptive"].v_max_2, rel=1e-5)


def test_spinning_chain_with_rolling_stays_bounded():
    """Kernel level, 5 spinning spheres, stiff and damped rolling law, 20 us: finite,
    mechanical energy never above E(0), ledger closed."""
    c = Chain(five(ROLL, **{"rolling.k_roll": 1e7, "rolling.gamma_roll": 1.0}), w0=SPINS)
    Y, E = c.run("rk4", 1e-9, 20000, every=10)
    assert np.all(np.isfinite(Y))
    mech = E[:, kernels.E_KIN_TRANS] + E[:, kernels.E_KIN_ROT] + E[:, kernels.E_POT]
    assert mech.max() <= mech[0] * (1 + 2e-9)
    assert balance(E) < 1e-9


def test_cli_run_with_rolling(tmp_path):
    from granchain.cli import main as cli_main
    out = tmp_path / "r.json"
    assert cli_main(["run", str(SCENES / "packed-440c.yaml"), "--json", "--out", str(out),
                     "--set", f"effects={ALL}", "--set", "rolling.k_roll=1e5",
                     "--set", "t_end=3e-6"]) == 0
    res = json.loads(out.read_text())
    assert res["energy"]["work_rolling_friction"] < 0
    assert res["energy"]["balance_error"] < 1e-8


# ---------------------------------------------------------------------------------------
# (d) LAMMPS cross-check

def test_chain_driver_is_the_engines_verlet():
    """The kernel driver used against LAMMPS below gives, from rest, bit for bit the
    velocities of reference.run (so the comparison is with the engine itself)."""
    scene = five(ALL, t_end=4e-6, **{"integrator.method": "verlet", "output.sample_dt": 1e-8,
                                       "gaps.distribution": "list",
                                       "gaps.values": "[0.0, 20.0e-9, 0.0, 5.0e-9]"})
    gaps = np.array([0.0, 20e-9, 0.0, 5e-9])
    traj = next(reference.run(scene, gaps[None, :], scene.striker_velocities, method="verlet"))
    c = Chain(scene, gaps=gaps)
    Y, E = c.run("verlet", scene.dt, 4000, every=10)
    assert np.array_equal(traj.v, Y[:, c.LO[kernels.L_VEL]:c.LO[kernels.L_VEL] + 5])
    assert np.array_equal(traj.energy, E)
    assert np.any(Y[:, c.LO[kernels.L_ROLLING_HIST]:c.LO[kernels.L_ROLLING_HIST] + 4] != 0)

def _lammps_histories(tmp_path, scene, w0):
    """Run write_deck's deck in LAMMPS with initial spins ``w0`` (rad/s) written into
    chain.data; returns the dumped vx (m/s) and omega_y (rad/s) histories, the dump's
    step interval, its last step, and the spins as LAMMPS read them (w0 rounded through
    the data file's rad/us)."""
    from granchain.lammps.deck import DATA_NAME, write_deck
    from tests.test_lammps_deck import read_dump, run_deck

    deck = write_deck(scene, tmp_path)
    # the deck dumps id x y z vx only (its ledger has the energies): add the spins here
    deck.write_text(deck.read_text().replace("traj.dump id x y z vx", "traj.dump id x y z vx omegay"))
    data = tmp_path / DATA_NAME
    head, vel = data.read_text().split("Velocities\n\n", 1)
    rows = vel.strip().splitlines()
    assert len(rows) == scene.n
    new = []
    for i, row in enumerate(rows):
        c = row.split()
        c[5] = repr(float(w0[i]) * 1e-6)               # omega_y: rad/s -> rad/us
        new.append(" ".join(c))
    data.write_text(head + "Velocities\n\n" + "\n".join(new) + "\n")
    run_deck(deck)
    d = read_dump(tmp_path / "traj.dump")
    steps = sorted(d)
    every = steps[1] - steps[0]
    vx = np.array([d[s]["vx"] for s in steps])                 # m/s
    wy = np.array([d[s]["omegay"] for s in steps]) * 1e6        # rad/s
    w_read = np.array([float(repr(float(w) * 1e-6)) * 1e6 for w in w0])
    return vx, wy, every, steps[-1], w_read


def _lammps_vs_reference(tmp_path, scene, w0, gaps=None):
    """Run write_deck's deck (initial spins written into chain.data) in LAMMPS and the
    reference Verlet from the same state; per-particle max relative differences of the
    vx and omega_y histories (scale: each particle's max |history|)."""
    vx, wy, every, last, w_read = _lammps_histories(tmp_path, scene, w0)
    gaps = np.zeros(scene.n - 1) if gaps is None else np.asarray(gaps, dtype=float)
    c = Chain(scene, w0=w_read, gaps=gaps)
    Y, _ = c.run("verlet", scene.dt, last, every=every)
    v_ref = Y[:, c.LO[kernels.L_VEL]:c.LO[kernels.L_VEL] + scene.n]
    w_ref = Y[:, c.LO[kernels.L_SPIN]:c.LO[kernels.L_SPIN] + scene.n]
    rel_v = np.abs(vx - v_ref).max(axis=0) / np.abs(v_ref).max(axis=0)
    rel_w = np.abs(wy - w_ref).max(axis=0) / np.abs(w_ref).max(axis=0)
    return rel_v, rel_w, c, Y


@pytest.mark.lammps
@pytest.mark.parametrize("effects, tol", [(ROLL, 2e-10), (CONTACT_ROLL, 1e-9)])
def test_lammps_rolling_chain_matches_reference_verlet(tmp_path, effects, tol):
    """Five spinning spheres struck at 0.1 m/s, 4000 steps, Hertz + rolling sds (+ mindlin
    contact friction): LAMMPS and the reference Verlet agree per particle. Measured max
    relative differences: vx 6.3e-11, omega_y 6.3e-11 (rolling) and 2.5e-10 (with the
    contact friction, which alone gives the same 2.5e-10: rounding growth)."""
    scene = five(effects, t_end=4e-6, **{"integrator.method": "verlet", "output.sample_dt": 1e-8})
    rel_v, rel_w, c, Y = _lammps_vs_reference(tmp_path, scene, SPINS)
    print("max rel vx", rel_v.max(), "omegay", rel_w.max())
    assert rel_v.max() < tol and rel_w.max() < tol
    # the run exercised the rolling law: slides at the cap and sticks below it
    rf = c.terms.rolling_friction
    ps, wo = c.LO[kernels.L_ROLLING_HIST], c.LO[kernels.L_SPIN]
    xo = c.LO[kernels.L_DISP]
    dlt = Y[:, xo:xo + 4] - Y[:, xo + 1:xo + 5]
    on = dlt > 0
    cap = rf.mu_roll * c.terms.hertz.K * np.where(on, dlt, 0) ** 1.5
    vr = c.terms.R / 2 * (Y[:, wo:wo + 4] - Y[:, wo + 1:wo + 5])
    trial = np.abs(-rf.k_roll * Y[:, ps:ps + 4] - rf.gamma_roll * vr)
    assert np.any(on & (trial < 0.5 * cap)) and np.any(on & (trial > 0.999 * cap))
    assert np.abs(Y[-1, wo:wo + 5] - SPINS).max() > 1e-2 * np.abs(SPINS).max()


@pytest.mark.lammps
def test_lammps_all_effects_with_rolling_matches_reference_verlet(tmp_path):
    """Every effect (groove/drag plugin too) with rolling, spinning spheres, 20 nm and
    5 nm gaps: measured max relative differences vx 5.8e-11, omega_y 1.4e-10."""
    scene = five(ALL, t_end=4e-6, **{"integrator.method": "verlet", "output.sample_dt": 1e-8,
                                       "gaps.distribution": "list",
                                       "gaps.values": "[0.0, 20.0e-9, 0.0, 5.0e-9]"})
    rel_v, rel_w, c, Y = _lammps_vs_reference(tmp_path, scene, SPINS, [0.0, 20e-9, 0.0, 5e-9])
    print("max rel vx", rel_v.max(), "omegay", rel_w.max())
    assert rel_v.max() < 1e-9 and rel_w.max() < 1e-9
