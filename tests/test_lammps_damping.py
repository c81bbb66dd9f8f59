"""LAMMPS runs damped scenes natively (effects/contact_damping.py,
docs/explanation/lammps_laws.md section 13): pair granular's damping on every pair_coeff and on the end wall's fix
wall/gran, checked on the wheel against the law written out here, then two-sphere
collisions and damped chains against the reference engine's velocity Verlet.

Measured (this wheel, dt = 1 ns unless said; bounds ~3x):
- the damping force LAMMPS applies, unlike pair and wall, against the law: <= 3.5e-13 of
  F_el (the rounding of the overlap from absolute positions);
- coefficient of restitution of a two-sphere collision, e = 0.5, 0.8, 0.95 at 0.01-1 m/s:
  |e_LAMMPS - e| <= 6.0e-5 (Verlet's error: 3.7e-5 at 0.5 ns), and e_LAMMPS = the
  reference Verlet's e to 5.6e-11;
- viscoelastic: the loss 1 - e grows by 1.5845 and 1.5843 per decade (10^(1/5) = 1.5849),
  and equals the reference's RK4 loss (SI eta_n0) to 6.2e-5 relative;
- damped chains, ``granchain compare`` (tables in docs/explanation/lammps_engine.md): v_max, v_g
  <= 6.4e-10, peak times <= 1.4e-10, energies <= 7.1e-10 E0, v(t) <= 2.2e-8 v_s (a radius
  spread against a wall, growing after the reflection; 5.4e-9 without the wall).
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from granchain.compare import compare, comparison_scene
from granchain.effects import contact_damping as cd
from granchain.effects import ENERGY_COLUMNS, physics_terms, residual_work
from granchain.engines import lammps as lammps_engine
from granchain.engines import reference
from granchain.gaps import member_gaps, members
from granchain.lammps import deck as lammps_deck
from granchain.lammps import run_lammps
from granchain.lammps.deckplan import ledger_binary_columns
from granchain.materials import effective_modulus, library
from granchain.scene import scene_from_dict
from granchain.simulate import run_scene
from tests.conftest import packed
from tests.test_lammps_field_chains import run_deck, set_velocities

pytestmark = pytest.mark.lammps

MAT = library()
PLUGIN = "/PLUGIN/groove_drag.so"
DAMPED = "[hertz, contact_damping]"
ALL = ("[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction, "
       "contact_damping]")
K_CR = math.sqrt(1.5) * 2.0 * math.sqrt(5.0 / 6.0)      # sqrt(5)


# ---------------------------------------------------------------------------------------
# the law, written out here (SI or micro alike: it is homogeneous)
def c_restitution(e):
    """LAMMPS's coeff_restitution constant for Hertz contacts."""
    lg = math.log(e)
    return -K_CR * lg / math.sqrt(math.pi ** 2 + lg * lg)


def marshall(e):
    """Marshall 2009, Eq. 53 (LAMMPS's tsuji fit, without any sqrt(2))."""
    return (1.2728 - 4.2783 * e + 11.087 * e ** 2 - 22.348 * e ** 3 + 27.467 * e ** 4
            - 18.022 * e ** 5 + 4.8218 * e ** 6)


def damped_force(K, d, w, meff, Rs, prefactor, limit=False):
    """(F_el, F): Hertz K d^1.5 and the net F_el + eta w, eta = prefactor(...)."""
    fel = K * d ** 1.5
    F = fel + prefactor(fel, d, meff, Rs) * w
    return fel, (max(F, 0.0) if limit else F)


def sqrt_form(c):
    return lambda fel, d, meff, Rs: c * math.sqrt(meff * fel / d)


def viscoelastic(eta):
    return lambda fel, d, meff, Rs: eta * meff * math.sqrt(Rs * d)


# ---------------------------------------------------------------------------------------
# the deck
def test_every_pair_coeff_and_the_wall_carry_the_damping():
    """A chain of two materials on a 316 wall: like and unlike type pairs and the wall
    all get the model and its coefficient (eta_n0 x 1e-12 in units micro) and the
    limit_damping keyword; tsuji becomes coeff_restitution with e' whose constant is the
    reference's c = sqrt(2) x Marshall(e); undamped scenes keep 0.0 and
    'damping viscoelastic' (chapter decks: tests/test_lammps_field_chains.py)."""
    base = {"chain.n": 4, "probes": "[2, 4]", "walls.end": "ss316",
            "chain.materials": "[ss440c, brass, ss440c, brass]"}
    cases = {("viscoelastic", None, 3e9, False): ("0.003", "damping viscoelastic"),
             ("coeff_restitution", 0.8, None, True): ("0.8", "damping coeff_restitution "
                                                              "limit_damping"),
             ("tsuji", 0.7, None, False): (repr(cd.equivalent_restitution(cd.tsuji_damp(0.7))),
                                           "damping coeff_restitution")}
    for (model, e, eta, lim), (coef, words) in cases.items():
        over = {"damping.model": model, "damping.limit_damping": str(lim).lower(), **base}
        over.update({"damping.e": e} if e is not None else {"damping.eta": eta})
        deck = lammps_deck.render(packed(effects=DAMPED, **over), plugin=PLUGIN)[0]
        normals = re.findall(r"^(?:pair_coeff +\d \d|fix +wall lasts wall/gran granular) "
                             r"hertz/material (\S+) (\S+) (\S+) (damping [a-z_]+(?: limit_damping)?)",
                             deck, re.M)
        assert len(normals) == 4, deck              # 1 1, 1 2, 2 2 and the wall
        assert all(n[1] == coef and n[3] == words for n in normals), normals
        assert "tangential" in deck and "Hertz with contact damping" in deck
    assert c_restitution(float(cases[("tsuji", 0.7, None, False)][0])) == pytest.approx(
        math.sqrt(2) * marshall(0.7), rel=1e-14)
    plain = lammps_deck.render(packed(**base), plugin=PLUGIN)[0]
    assert plain.count(" 0.0 0.28 damping viscoelastic &") == 1
    assert "contact damping" not in plain and "limit_damping" not in plain


# ---------------------------------------------------------------------------------------
# the wheel's forces (run 0: the setup force, x and v as given)
def _force_deck(normal_11, normal_22, normal_12, wall, d, va, vb, Ra, Rb, ma_rho, mb_rho):
    atoms = [f"create_atoms 1 single 0.0 0 0", "set atom 1 diameter {} density {}".format(
        2 * Ra, ma_rho), f"set atom 1 vx {va}"]
    if wall is None:
        atoms += [f"create_atoms 2 single {Ra + Rb - d!r} 0 0",
                  f"set atom 2 diameter {2 * Rb} density {mb_rho}", f"set atom 2 vx {vb}"]
    lines = ["units micro", "atom_style sphere", "dimension 3", "boundary f f f", "newton on",
             "comm_modify vel yes", "atom_modify map array",
             "region box block -1000 1000 -1000 1000 -1000 1000", "create_box 2 box",
             *atoms, "pair_style granular",
             f"pair_coeff 1 1 {normal_11} tangential linear_history 0 0 0",
             f"pair_coeff 2 2 {normal_22} tangential linear_history 0 0 0",
             f"pair_coeff 1 2 {normal_12} tangential linear_history 0 0 0"]
    if wall is not None:
        lines.append(f"fix w all wall/gran granular {wall} tangential linear_history 0 0 0 "
                     f"xplane NULL {Ra - d!r} contacts")
    lines += ["variable fx1 equal fx[1]", "thermo_style custom step v_fx1",
              "thermo_modify format float %.17g", "run 0"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("wall", [False, True], ids=["unlike-pair", "wall"])
def test_the_wheel_applies_the_law_to_unlike_pairs_and_the_wall(wall, tmp_path):
    """440C (R 150 um) against 316 (R 189 um) with the deck's explicit unlike pair_coeff
    (E = 2 E*, nu = 0: LAMMPS takes m_eff and R* from the atoms, so the damping needs
    nothing of the pair), or the 440C sphere on a 316 wall (m_eff = m, R* = R), delta =
    0.1 um, closing and opening: LAMMPS's force is F_el + eta w with eta of the law (E15,
    measured <= 3.5e-13 of F_el), held at 0 with limit_damping where it would pull; the
    wheel's own 'damping tsuji' has Marshall's constant without the sqrt(2) (ratio of the
    damping forces 1/sqrt(2), E16), hence the deck's coeff_restitution stand-in."""
    a, b = MAT["ss440c"], MAT["ss316"]
    Ra, Rb, d = 150.0, 189.0, 0.1
    ma = 4.0 / 3.0 * math.pi * Ra ** 3 * a.rho * 1e-3          # pg
    mb = 4.0 / 3.0 * math.pi * Rb ** 3 * b.rho * 1e-3
    Es = effective_modulus(a, b) * 1e-3                           # 1e3 Pa
    if wall:
        K, meff, Rs = 4.0 / 3.0 * Es * math.sqrt(Ra), ma, Ra
    else:
        K, meff, Rs = 4.0 / 3.0 * Es * math.sqrt(Ra * Rb / (Ra + Rb)), ma * mb / (ma + mb), \
            Ra * Rb / (Ra + Rb)
    laws = [("coeff_restitution", 0.7, sqrt_form(c_restitution(0.7))),
            ("viscoelastic", 1e10, viscoelastic(1e10 * 1e-12)),      # 1/(m s) -> 1/(um us)
            ("tsuji", 0.7, sqrt_form(math.sqrt(2) * marshall(0.7)))]
    k = 0
    for model, value, prefactor in laws:
        for lim in (False, True):
            for va, vb in ((0.05, -0.02), (-1.0, 0.5)):
                over = {"damping.model": model, "damping.limit_damping": str(lim).lower(),
                        ("damping.eta" if model == "viscoelastic" else "damping.e"): value}
                term = physics_terms(packed(effects=DAMPED, **over)).contact_damping
                n11 = cd.lammps_normal(term, a.E, a.nu)
                n22 = cd.lammps_normal(term, b.E, b.nu)
                n12 = cd.lammps_normal(term, 2.0 * effective_modulus(a, b), 0.0)
                nw = cd.lammps_normal(term, 2.0 * effective_modulus(a, b), 0.0) if wall else None
                w = va if wall else va - vb
                fel, F = damped_force(K, d, w, meff, Rs, prefactor, lim)
                got = _run_force(tmp_path / f"r{k}", _force_deck(
                    n11, n22, n12, nw, d, va, vb, Ra, Rb, a.rho * 1e-3, b.rho * 1e-3))
                k += 1
                assert abs(-got - F) <= 1e-12 * fel, (model, lim, va, got, F)
                pulls = damped_force(K, d, w, meff, Rs, prefactor)[1] < 0.0
                if pulls:                                 # opening fast (coeff_restitution, tsuji)
                    assert got == 0.0 if lim else got > 0.0, (model, lim, got)
    # the wheel's own tsuji: Marshall's constant alone
    tsu = "hertz/material {} 0.7 {} damping tsuji"
    va, vb = 0.05, -0.02
    w = va if wall else va - vb
    got = _run_force(tmp_path / "tsuji", _force_deck(
        tsu.format(a.E * 1e-3, a.nu), tsu.format(b.E * 1e-3, b.nu),
        tsu.format(2 * Es, 0.0), tsu.format(2 * Es, 0.0) if wall else None,
        d, va, vb, Ra, Rb, a.rho * 1e-3, b.rho * 1e-3))
    fel, F = damped_force(K, d, w, meff, Rs, sqrt_form(marshall(0.7)))
    assert abs(-got - F) <= 1e-12 * fel
    assert (-got - fel) / (F - fel) == pytest.approx(1.0, rel=1e-9)


def _run_force(wd, text):
    wd.mkdir()
    (wd / "in.lmp").write_text(text)
    log = run_lammps(wd / "in.lmp", wd, timeout=120).log.read_text()
    m = re.search(r"Step\s+v_fx1\s*\n\s*0\s+(\S+)", log)
    return float(m.group(1))


# ---------------------------------------------------------------------------------------
# two-sphere collisions
def collision_scene(damping, speeds=(0.01, 0.1, 1.0), dt=1e-9):
    """The striker hits particle 2 of a 3-sphere chain whose third sphere is 1 mm away (as
    tests/test_damping.py), one chain per speed."""
    return scene_from_dict({"name": "pair", "chain": {"n": 3}, "probes": [2, 3],
                            "effects": ["hertz", "contact_damping"], "damping": damping,
                            "striker": {"velocity": list(speeds)}, "t_end": 2e-5,
                            "integrator": {"method": "verlet", "dt": dt},
                            "gaps": {"distribution": "list", "values": [0.0, 1e-3]}})


def restitution(scene, engine="lammps", **kw):
    """e = (v2' - v1')/v of every member, LAMMPS or the reference engine."""
    mem = members(scene)
    g, vs = member_gaps(scene, mem), np.array([m.v_striker for m in mem])
    run = (lammps_engine.run(scene, g, vs) if engine == "lammps"
           else reference.run(scene, g, vs, **kw))
    return np.array([(t.v[-1, 1] - t.v[-1, 0]) / v for t, v in zip(run, vs)])


@pytest.mark.parametrize("e", [0.5, 0.8, 0.95])
def test_two_sphere_collision_gives_the_requested_e(e):
    """coeff_restitution in LAMMPS: e at every speed within Verlet's error (measured
    <= 6.0e-5 at 1 ns), and the reference Verlet's e to 5.6e-11 (the same law and
    steps: the error is Verlet's, not the law's)."""
    sc = collision_scene({"model": "coeff_restitution", "e": e})
    got = restitution(sc)
    assert np.all(np.abs(got - e) < 2e-4), got - e
    ref = restitution(sc, "reference", method="verlet")
    assert np.all(np.abs(got - ref) < 2e-10), got - ref


def test_limit_damping_and_tsuji_collisions_match_the_reference():
    """limit_damping (e = 0.5 asked, 0.5503 obtained: the limit lowers the loss) and
    tsuji (its coeff_restitution stand-in): LAMMPS = reference Verlet to 5.6e-11."""
    for damping in ({"model": "coeff_restitution", "e": 0.5, "limit_damping": True},
                    {"model": "tsuji", "e": 0.7}):
        sc = collision_scene(damping)
        got, ref = restitution(sc), restitution(sc, "reference", method="verlet")
        assert np.all(np.abs(got - ref) < 2e-10), (damping, got - ref)
    assert got == pytest.approx(0.69994, abs=1e-4)          # tsuji at e = 0.7
    lim = restitution(collision_scene({"model": "coeff_restitution", "e": 0.5,
                                       "limit_damping": True}))
    assert np.all(lim > 0.55) and np.all(lim < 0.551)


def test_viscoelastic_loss_grows_as_the_fifth_root_of_speed():
    """viscoelastic, eta_n0 = 1e9 1/(m s) (1e-3 1/(um us) in the deck): 1 - e grows by
    10^(1/5) per decade (measured 1.5845, 1.5843), and equals the reference engine's
    continuous law (RK4 at 0.2 ns, SI eta_n0) to 6.2e-5 relative: the unit conversion."""
    damping = {"model": "viscoelastic", "eta": 1e9}
    loss = 1.0 - restitution(collision_scene(damping))
    for a, b in zip(loss, loss[1:]):
        assert b / a == pytest.approx(10 ** 0.2, rel=1.5e-3)
    rk4 = collision_scene(damping, dt=2e-10).derive(**{"integrator.method": "rk4"})
    ref = 1.0 - restitution(rk4, "reference")
    np.testing.assert_allclose(loss, ref, rtol=2e-4)


def test_wall_force_is_fix_wall_gran_whole_force(tmp_path):
    """A 440C sphere onto a 316 wall at 0.1 m/s, coeff_restitution e = 0.8, every step
    sampled: the wall's force (its 'contacts' output, in the per-chain ledger) at step k
    is K_w delta_k^1.5 + c(e) sqrt(m K_w delta_k^0.5) v_(k-1/2), the half-step velocity
    (x_k - x_(k-1))/dt the force call sees (measured 2.2e-11 of the peak: the rounding of
    the x differences); the sphere leaves at e v within Verlet's error (measured 2.5e-5);
    the net force pulls before release (down to -4.8 % of the peak). The engine's
    Trajectory.wall_force is the law at the sample's x and v instead."""
    v, e = 0.1, 0.8
    sc = packed(effects=DAMPED, t_end=12e-6, **{
        "chain.n": 3, "probes": "[2, 3]", "walls.end": "ss316", "damping.e": e,
        "gaps.distribution": "list", "gaps.values": "[5e-6, 5e-6]", "output.sample_dt": 1e-9})
    pl, step, c = run_deck(sc, tmp_path, lambda t: set_velocities(t, [0.0, 0.0, v]))
    x, vx = c["x"][:, 2], c["vx"][:, 2]
    cols = ledger_binary_columns(pl)
    _, led = lammps_engine.read_binary_dump(tmp_path / lammps_deck.LEDGER_BINARY_NAME, cols, 1,
                                            pl.nsamples, "ledger")
    F = -led[cols[-1]][:, 0] * 1e-9                              # N, compression > 0
    s440, R = MAT["ss440c"], 150e-6
    Kw = 4.0 / 3.0 * effective_modulus(s440, MAT["ss316"]) * math.sqrt(R)
    m = 4.0 / 3.0 * math.pi * R ** 3 * s440.rho
    d = (x + 150.0) * 1e-6                                        # the wall plane is x = 0
    vh = np.diff(x) * 1e-6 / 1e-9                                 # (x_k - x_(k-1))/dt
    dk = np.maximum(d[1:], 0.0)
    law = np.where(dk > 0, Kw * dk ** 1.5 + c_restitution(e) * np.sqrt(m * Kw * np.sqrt(dk)) * vh,
                   0.0)
    assert np.abs(F[1:] - law).max() < 1e-10 * F.max()
    assert vx[-1] == pytest.approx(-e * v, rel=1e-4)
    assert F.min() < 0.0 < F.max()                                # it pulls before release
    # the engine records the force at each sample's state, F_el + eta w of x_k and v_k (as
    # the reference engine does): it differs from fix wall/gran's, the step's force with the
    # half-step velocity, by O(dt) (measured 1.5e-4 of the peak)
    rec = lammps_engine.read_binary(tmp_path / lammps_deck.BINARY_NAME, sc, pl)["wall_force"][:, 0]
    dd = np.maximum(d, 0.0)
    at_k = np.where(dd > 0, Kw * dd ** 1.5 + c_restitution(e) * np.sqrt(m * Kw * np.sqrt(dd)) * vx,
                    0.0)
    assert np.abs(rec - at_k).max() < 1e-12 * F.max()
    assert 1e-5 < np.abs(rec - F).max() / F.max() < 5e-4


# ---------------------------------------------------------------------------------------
# damped chains: granchain compare and run_scene on both engines
D_LIST = "[0.0, 20e-9, 5e-9, 0.0, 40e-9, 1e-9, 0.0, 3e-9, 0.0, 10e-9, 7e-9, 0.0, 2e-9, 0.0]"
CHAINS = {
    "packed": lambda: packed(effects=DAMPED, **{"damping.e": 0.9}),
    "gapped": lambda: packed(effects=DAMPED, **{
        "damping.model": "viscoelastic", "damping.eta": 1e10, "gaps.distribution": "uniform",
        "gaps.mean": 20e-9, "ensemble.realisations": 2}),
    "wall": lambda: packed(effects=DAMPED, **{
        "damping.model": "tsuji", "damping.e": 0.8, "walls.end": "ss316", "chain.n": 8,
        "probes": "[2, 8]", "precompression.force": 0.5}),
    "mixed": lambda: packed(effects=DAMPED, **{
        "damping.e": 0.8, "chain.n": 8, "probes": "[2, 8]",
        "chain.materials": "[ss440c, brass, ss316, ss440c, brass, ss316, ss440c, brass]",
        "chain.radius": "[150e-6, 189e-6, 120e-6, 150e-6, 150e-6, 189e-6, 120e-6, 150e-6]"}),
    # each member its own radii, right to left from the wall: the striker's contact is
    # written at zero overlap, not an ulp inside it (field.positions)
    "spread-wall": lambda: packed(effects=DAMPED, **{
        "damping.e": 0.85, "chain.n": 8, "probes": "[2, 8]", "walls.end": "ss316",
        "chain.radius_spread": "{distribution: uniform, sd: 3e-6, seed: 5}",
        "ensemble.realisations": 3}),
    "limit": lambda: packed(effects=DAMPED, **{
        "damping.e": 0.3, "damping.limit_damping": "true", "gaps.distribution": "list",
        "gaps.values": D_LIST}),
    "every-effect": lambda: packed(effects=ALL, **{
        "rolling.k_roll": 1e3, "damping.e": 0.9, "gaps.distribution": "uniform",
        "gaps.mean": 20e-9, "ensemble.realisations": 2}),
}
# measured: v_max/v_g, peak times, energies / E0, v(t) / v_s (every particle and sample)
V_BOUND, T_BOUND, E_BOUND, TRAJ_BOUND, W_BOUND = 2e-9, 5e-10, 2e-9, 6e-8, 3e-10


@pytest.mark.parametrize("name", list(CHAINS))
def test_damped_chains_agree_with_the_reference_verlet(name, tmp_path):
    """granchain compare (text dump path, whole trajectories): measured v_max, v_g <=
    6.4e-10 (limit), peak times <= 1.4e-10 (wall), energies <= 7.1e-10 E0 (spread-wall),
    v(t) <= 2.2e-8 v_s (spread-wall, after the reflection; gapped 5.4e-9). The damping work is the LAMMPS balance residual, one
    not-independent row with the scene's other residual works. With a wall both engines
    record F_el + eta w at each sample's state: peak force and its time <= 7.5e-11."""
    scene = CHAINS[name]()
    cmp = compare(scene, trajectory=True, workdir=tmp_path / "lmp")
    rows = cmp.rows
    assert cmp.ok, cmp.failures().to_string()
    chk = rows[rows.ok.notna()]
    assert (chk.loc[chk.quantity == "samples", "diff"] == 0).all()
    v = chk[chk.quantity.str.startswith("v_max") | chk.quantity.str.startswith("v_g")]
    assert v["diff"].max() < V_BOUND
    assert chk[chk.quantity.isin(["dt_peak", "dt_front"])]["diff"].max() < T_BOUND
    group = "+".join(residual_work(scene.effects))
    energy = chk[chk.measure == "abs/E0"]      # every ledger entry but the residual group
    n_e = len(ENERGY_COLUMNS) + 2 - len(residual_work(scene.effects))
    assert len(energy) == n_e * len(members(scene)) and energy["diff"].max() < E_BOUND
    assert rows[rows.quantity == "v(t), every particle"]["diff"].max() < TRAJ_BOUND
    assert group.endswith("work_contact_damping") and cmp.meta["balance"] == "residual"
    res = rows[rows.quantity == group]
    assert len(res) == len(members(scene)) and res.ok.isna().all()
    assert (res.reference < 0).all() and (res.lammps < 0).all()
    # the LAMMPS residual is the energy lost; the reference's damping work differs from it
    # by no more than the reference ledger's own Verlet balance error
    bal = rows[rows.quantity == "balance_error"]
    assert np.all(res["diff"].to_numpy() <= 1.1 * np.abs(bal.reference.to_numpy()) + 1e-9)
    if scene.wall is not None:
        w = rows[rows.quantity.str.contains("wall")]
        assert len(w) == 3 * len(members(scene)) and w.ok.all()
        assert w["diff"].max() < W_BOUND


def test_run_scene_on_both_engines_agrees_on_a_mixed_damped_chain():
    """run_scene, reference (Verlet, the comparison grid) and LAMMPS: the same
    observables per member (measured v_max 1.0e-10, v_g 4.4e-12), and the LAMMPS
    ledger's damping column is the residual."""
    sc = comparison_scene(CHAINS["mixed"]())
    (r,), (lt,) = run_scene(sc), run_scene(sc, engine="lammps")
    np.testing.assert_allclose(lt.v_max, r.v_max, rtol=1e-9)
    assert lt.v_g == pytest.approx(r.v_g, rel=1e-10) and lt.status == r.status == "passed"
    assert lt.energy.work_contact_damping == pytest.approx(r.energy.work_contact_damping,
                                                           rel=1e-3)
    assert lt.energy.work_particle_friction == 0.0 and abs(lt.energy.balance_error) < 1e-12
