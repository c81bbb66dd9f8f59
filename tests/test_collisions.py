"""Collisions as experiments: the two-sphere scene (chain.n 2), its measured restitution,
its capture flag and each sphere's final velocity v_final, on both engines, against the
independent solutions of tests/independent.py (Thornton's closed form e(v/v_y); the JKR
capture velocity from the law's hysteresis energy, integrated there over the
force-overlap curve, and e = sqrt(1 - v_c^2/v^2) above it; the pull-off forces).

The speeds here are held out: no other test runs them. Measured (reference engine): the
Thornton pairs (RK4, 0.1 ns) |e - e_Thornton| <= 2.6e-9 (1.7e-12 below v_y); the JKR
pairs (velocity Verlet, 0.2 ns, whose force jumps at touch and pull-off cost ~1e-4)
|e - e_JKR| <= 1.1e-4, LAMMPS's e the reference's to 2.9e-10.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from granchain.effects import adhesion
from granchain.errors import SceneError
from granchain.materials import effective_modulus, library
from granchain.scene import scene_from_dict
from granchain.simulate import run_scene
from granchain.tables import columns

from independent import (ThorntonContact, dmt_pulloff, jkr_capture_velocity, jkr_pulloff,
                         jkr_restitution, thornton_restitution)

LIB = library()
R = 150e-6
RS = R / 2.0
GAMMA = 1.0


def _mass(mat, r):
    return 4.0 / 3.0 * math.pi * r ** 3 * mat.rho


def _pair(speeds, **extra):
    d = {"name": "pair", "chain": {"n": 2}, "striker": {"velocity": list(speeds)}}
    d.update(extra)
    return scene_from_dict(d)


# ---------------------------------------------------------------------------------------
# the scene
def test_a_two_sphere_scene_has_no_probes_and_no_vibrometer():
    sc = _pair([0.01])
    assert sc.n == 2 and "probes" not in sc.spec
    with pytest.raises(SceneError) as err:
        _pair([0.01], probes=[2, 3])
    assert err.value.field == "probes"
    with pytest.raises(SceneError) as err:
        _pair([0.01], measurement={"bandwidth_hz": 2.5e6})
    assert err.value.field == "measurement"
    with pytest.raises(SceneError) as err:
        scene_from_dict({"chain": {"n": 1}})
    assert err.value.field == "chain.n"


def test_an_elastic_pair_separates_with_the_striker_at_rest():
    """Equal Hertz spheres exchange their velocities (e = 1): v_final = (0, v_s) to RK4's
    error, the collision separated, its probe observables NaN (no probes), the table row
    with the pair's columns and one final velocity per sphere."""
    v = 0.013
    r, = run_scene(_pair([v], integrator={"method": "rk4", "dt": 2e-10}))
    assert r.pair and r.collision == "separated" and r.captured is False
    assert abs(r.v_final[0]) < 1e-9 * v and abs(r.v_final[1] - v) < 1e-9 * v
    assert abs(r.restitution - 1.0) < 1e-9
    assert r.wave_arrived is False and r.status == "passed"
    for name in ("v_max_1", "v_max_2", "dt_peak", "v_g", "v_g_front"):
        assert math.isnan(getattr(r, name)), name
    row = r.to_row()
    assert {"pair_collision", "pair_captured", "pair_restitution"} <= set(row) <= set(columns(2))
    assert row["pair_collision"] == "separated" and row["pair_restitution"] == r.restitution
    assert (row["vfinal_p01_m_s"], row["vfinal_p02_m_s"]) == r.v_final


def test_a_chain_reports_every_final_velocity():
    """A chain's v_final is its last sample: in a 5-sphere Hertz chain of equal spheres
    the wave leaves the last sphere with nearly all the momentum m v_s, which v_final
    holds (to RK4's error: momentum is conserved), and no pair keys."""
    v = 0.02
    sc = scene_from_dict({"chain": {"n": 5}, "probes": [2, 5], "striker": {"velocity": v},
                          "integrator": {"method": "rk4", "dt": 2e-10}})
    r, = run_scene(sc)
    assert len(r.v_final) == 5 and not r.pair
    assert abs(sum(r.v_final) - v) < 1e-9 * v
    assert r.v_final[-1] > 0.9 * v
    assert "collision" not in r.to_json() and "vfinal_p05_m_s" in r.to_row()


def test_a_collision_cut_by_the_end_of_the_run_reports_no_restitution():
    """t_end inside the contact: the pair still presses, the collision is unfinished and
    e is NaN (null in the JSON), not the ratio of velocities of a collision under way."""
    r, = run_scene(_pair([0.01], t_end=1e-6, integrator={"method": "rk4", "dt": 2e-10}))
    assert r.collision == "unfinished" and not r.captured and math.isnan(r.restitution)
    assert r.v_final[1] > 0.0


# ---------------------------------------------------------------------------------------
# Thornton's plastic pair (reference engine)
@pytest.mark.parametrize("mats, radii", [(("ss316", "ss316"), (R, R)),
                                         (("ss440c", "ss316"), (170e-6, R))])
@pytest.mark.parametrize("r", [0.7, 3.3, 17.0])
def test_plastic_pair_restitution_is_thorntons(mats, radii, r):
    """The measured restitution of a two-sphere scene against Thornton's closed form at
    v = r v_y (1 below the yield speed), with the softer sphere's limiting pressure."""
    ma, mb = LIB[mats[0]], LIB[mats[1]]
    Es = 1.0 / ((1 - ma.nu ** 2) / ma.E + (1 - mb.nu ** 2) / mb.E)
    m1, m2 = _mass(ma, radii[0]), _mass(mb, radii[1])
    c = ThorntonContact(Es, radii[0] * radii[1] / sum(radii),
                        min(ma.yield_pressure, mb.yield_pressure))
    v = r * c.yield_speed(m1 * m2 / (m1 + m2))
    sc = _pair([v], chain={"n": 2, "radius": list(radii), "materials": list(mats)},
               effects=["hertz", "plastic_contact"],
               integrator={"method": "rk4", "dt": 1e-10})
    res, = run_scene(sc)
    assert res.collision == "separated" and res.captured is False
    assert abs(res.restitution - thornton_restitution(r)) < 1e-8, res.restitution
    # the final velocities are the collision's: momentum kept, their difference e v
    assert abs(m1 * res.v_final[0] + m2 * res.v_final[1] - m1 * v) < 1e-9 * m1 * v


# ---------------------------------------------------------------------------------------
# adhesion: the pull-off forces, and JKR's capture
def test_pull_off_forces():
    """The laws' pull-off forces are the least forces of the independent laws: 3 pi gamma
    R* (JKR, where its stable branch's force is least) and 4 pi gamma R* (DMT)."""
    E = effective_modulus(LIB["ss440c"], LIB["ss440c"])
    K = 4.0 / 3.0 * E * math.sqrt(RS)
    assert adhesion.pulloff_force(RS, GAMMA, True) == pytest.approx(
        -jkr_pulloff(RS, E, GAMMA)[2], rel=1e-13, abs=0.0)
    assert adhesion.pulloff_force(RS, GAMMA, False) == pytest.approx(
        dmt_pulloff(K, RS, GAMMA), rel=1e-13, abs=0.0)
    # and the least force of the engine's own laws over a closed contact's overlaps
    d_po = adhesion.pulloff_distance(RS, E, GAMMA)
    ds = np.linspace(-d_po, 4 * d_po, 4001)
    assert min(adhesion.law(K, RS, E, GAMMA, True, d) for d in ds) == pytest.approx(
        -3.0 * math.pi * GAMMA * RS, rel=1e-9, abs=0.0)
    assert adhesion.law(K, RS, E, GAMMA, False, 1e-300) == pytest.approx(
        -dmt_pulloff(K, RS, GAMMA), rel=1e-13, abs=0.0)


def _jkr_vc():
    st = LIB["ss440c"]
    m = 0.5 * _mass(st, R)
    return jkr_capture_velocity(RS, effective_modulus(st, st), GAMMA, m)


# below v_c: captured; above: e = sqrt(1 - v_c^2/v^2)
JKR_SPEEDS = (0.45, 0.9, 1.2, 2.6, 5.0)


def _jkr_scene(speeds, **extra):
    d = dict(effects=["hertz", "adhesion"], material="ss440c",
             adhesion={"model": "jkr", "surface_energy": GAMMA}, t_end=4e-5,
             integrator={"method": "verlet", "dt": 2e-10}, output={"sample_dt": 1e-8})
    d.update(extra)
    return _pair(speeds, **d)


def _check_jkr(results, vc):
    for res in results:
        v = res.v_striker
        if v < vc:
            assert res.collision == "captured" and res.captured is True, (v / vc, res)
            assert math.isnan(res.restitution)
        else:
            assert res.collision == "separated" and res.captured is False, (v / vc, res)
            assert abs(res.restitution - jkr_restitution(v, vc)) < 3e-4, (v / vc, res.restitution)


def test_jkr_pair_is_captured_below_the_capture_velocity():
    vc = _jkr_vc()
    results = run_scene(_jkr_scene([f * vc for f in JKR_SPEEDS]))
    _check_jkr(results, vc)


# t_end auto runs until the collision is decided: just below v_c and well below, captured;
# just above and well above, separated with e = sqrt(1 - v_c^2/v^2)
AUTO_SPEEDS = (0.45, 0.99, 1.2, 2.6)


def _auto_jkr_scene():
    return _jkr_scene([f * _jkr_vc() for f in AUTO_SPEEDS], t_end="auto",
                      output={"sample_dt": "auto"})


def test_a_jkr_pair_with_t_end_auto_runs_until_captured_or_separated():
    """With t_end auto the run does not stop while the JKR contact is held closed in
    tension with the energy to part (its overlap already open): it stops once the pair
    has parted (separated, with the independent e) or is bound (captured), status passed."""
    vc = _jkr_vc()
    results = run_scene(_auto_jkr_scene())
    _check_jkr(results, vc)
    assert all(r.status == "passed" for r in results)


def test_a_jkr_pair_with_t_end_auto_on_the_event_method():
    """The event method's stop rule is the same: captured below v_c, separated above with
    the independent e (measured within 3.3e-5)."""
    vc = _jkr_vc()
    results = run_scene(_jkr_scene([f * vc for f in AUTO_SPEEDS], t_end="auto",
                                   output={"sample_dt": "auto"},
                                   integrator={"method": "event"}))
    _check_jkr(results, vc)
    assert all(r.status == "passed" for r in results)


def test_a_jkr_run_whose_cap_is_too_short_is_unfinished(monkeypatch):
    """A t_end auto run that reaches its cap (``stoprule.auto_t_max``, here shorter than
    the contact) while the contact is still held reports unfinished, NaN restitution,
    status timeout, on both engines' stop rules."""
    import granchain.runplan as runplan
    monkeypatch.setattr(runplan, "auto_t_max", lambda scene, gaps, v: 3e-7)
    vc = _jkr_vc()
    for res in run_scene(_jkr_scene([0.45 * vc, 2.6 * vc], t_end="auto",
                                    output={"sample_dt": 1e-8})):
        assert res.status == "timeout", res
        assert res.collision == "unfinished" and not res.captured, res
        assert math.isnan(res.restitution)


def test_a_captured_pair_writes_null_and_the_flag(tmp_path):
    """granchain run --json: a captured pair's restitution is null, captured true."""
    vc = _jkr_vc()
    sc = tmp_path / "captured.yaml"
    sc.write_text(json.dumps({"chain": {"n": 2}, "material": "ss440c",
                              "effects": ["hertz", "adhesion"],
                              "adhesion": {"model": "jkr", "surface_energy": GAMMA},
                              "striker": {"velocity": 0.5 * vc}, "t_end": 1e-5,
                              "integrator": {"method": "verlet", "dt": 2e-10}}))
    out = subprocess.run([sys.executable, "-m", "granchain.cli", "run", str(sc), "--json"],
                         capture_output=True, text=True, check=True).stdout
    doc = json.loads(out)
    assert doc["pair"] is True and doc["captured"] is True and doc["collision"] == "captured"
    assert doc["restitution"] is None and doc["v_max_1"] is None and len(doc["v_final"]) == 2


@pytest.mark.lammps
def test_jkr_pair_on_lammps(tmp_path):
    """LAMMPS's own jkr law: the same captures and restitutions against the independent
    solution; its final velocities those of the reference engine to 1e-8 v_s (measured
    4.5e-9, the captured pairs, which oscillate to the end)."""
    vc = _jkr_vc()
    sc = _jkr_scene([f * vc for f in JKR_SPEEDS])
    lmp = run_scene(sc, engine="lammps", workdir=tmp_path)
    _check_jkr(lmp, vc)
    ref = run_scene(sc)
    for a, b in zip(lmp, ref):
        assert np.max(np.abs(np.subtract(a.v_final, b.v_final))) < 1e-8 * a.v_striker


@pytest.mark.lammps
def test_jkr_pair_with_t_end_auto_on_lammps(tmp_path):
    """LAMMPS with t_end auto: the deck runs to its cap and the engine cuts each record
    where the collision is decided, as the reference engine's stop rule: the same
    outcomes, the independent e, the reference's e to 1e-8 (measured 3e-10). Each speed
    is sampled on its own grid (a deck per cadence), so each record ends on the
    reference's sample, and the captured pairs, which oscillate to the end, have its
    final velocities to 2e-9 v_s (measured 1.4e-10; sampled on the finest speed's grid
    they were 3.1e-2 v_s off)."""
    vc = _jkr_vc()
    sc = _auto_jkr_scene()
    lmp = run_scene(sc, engine="lammps", workdir=tmp_path)
    _check_jkr(lmp, vc)
    assert all(r.status == "passed" for r in lmp)
    for a, b in zip(lmp, run_scene(sc)):
        assert a.collision == b.collision and a.samples == b.samples
        assert np.max(np.abs(np.subtract(a.v_final, b.v_final))) < 2e-9 * b.v_striker
        if a.collision == "separated":
            assert abs(a.restitution - b.restitution) < 1e-8


# a JKR chain whose striker speeds (2, 5 and 20 mm/s) are sampled on three grids (auto
# sampling on Verlet's 1 ns step: every 20, 16 and 12 steps); at 2 mm/s spheres 1 and 2
# stay bound and oscillate to the end of the run; at 5 mm/s all three stay bound (they
# oscillate about v_s / 3 to 4e-4 s at least), so the run reaches its cap, sphere 3's peak
# unmeasured
MIXED_CADENCE = {"name": "mixed-cadence", "chain": {"n": 3}, "probes": [2, 3],
                 "material": "ss440c", "effects": ["hertz", "adhesion"],
                 "adhesion": {"model": "jkr", "surface_energy": GAMMA},
                 "striker": {"velocity": [0.002, 0.005, 0.02]}, "t_end": "auto",
                 "integrator": {"method": "verlet", "dt": 1e-9}}


@pytest.mark.lammps
def test_a_batch_of_several_sample_cadences_agrees_between_the_engines(tmp_path):
    """LAMMPS runs a deck per sample cadence, so each chain is sampled on its own grid and
    its record cut at the reference engine's sample (or run to its cap, the chain bound as
    a whole): the same sample count, status and final peaks per speed, the bound spheres'
    final velocities and every v_max to 2e-9 v_s (measured 4.9e-10 v_f, 3.7e-10 v_max; one
    deck sampling every chain on the finest grid cut the 2 mm/s record at another phase of
    its oscillation: v_final 5.8e-3 v_s off, v_max 1.7e-6 v_s)."""
    sc = scene_from_dict(MIXED_CADENCE)
    lmp = run_scene(sc, engine="lammps", workdir=tmp_path)
    ref = run_scene(sc)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cadence-12", "cadence-16",
                                                          "cadence-20"]
    for a, b in zip(lmp, ref):
        v = b.v_striker
        assert a.v_striker == v
        assert (a.samples, a.status, a.final, a.not_final) == \
            (b.samples, b.status, b.final, b.not_final), v
        if v == 0.005:
            assert a.status == "timeout" and a.final == (True, True, False), v
        else:
            assert a.status == "passed" and all(b.final), v
        assert a.t_end == pytest.approx(b.t_end, rel=1e-12, abs=0.0)
        # the chain bound as a whole oscillates to its cap, 1.2e-4 s: its final
        # velocities 6.9e-9 v_s apart (measured)
        tol = 2e-8 if v == 0.005 else 2e-9
        assert np.max(np.abs(np.subtract(a.v_final, b.v_final))) < tol * v, v
        assert np.nanmax(np.abs(np.subtract(a.v_max, b.v_max))) < 2e-9 * v, v


@pytest.mark.lammps
def test_a_jkr_run_whose_cap_is_too_short_is_unfinished_on_lammps(monkeypatch, tmp_path):
    import granchain.runplan as runplan
    monkeypatch.setattr(runplan, "auto_t_max", lambda scene, gaps, v: 3e-7)
    vc = _jkr_vc()
    for res in run_scene(_jkr_scene([0.45 * vc, 2.6 * vc], t_end="auto",
                                    output={"sample_dt": 1e-8}),
                         engine="lammps", workdir=tmp_path):
        assert res.status == "timeout", res
        assert res.collision == "unfinished" and math.isnan(res.restitution)


@pytest.mark.lammps
def test_dmt_pairs_on_lammps(tmp_path):
    """LAMMPS's dmt pair: undamped (no hysteresis) it separates with e = 1 to Verlet's
    error at the force's jumps (measured 2.5e-4 at 4 mm/s); with viscoelastic damping
    (eta_n0 = 1e9) it is captured at 0.5 mm/s and separates at 2 mm/s, as on the
    reference engine (e equal to 9.4e-10)."""
    sc = _pair([0.004, 0.03], effects=["hertz", "adhesion"], material="ss440c",
               adhesion={"model": "dmt", "surface_energy": GAMMA}, t_end=2e-5,
               integrator={"method": "verlet", "dt": 2e-10}, output={"sample_dt": 1e-8})
    for res in run_scene(sc, engine="lammps", workdir=tmp_path / "dmt"):
        assert res.collision == "separated" and abs(res.restitution - 1.0) < 1e-3
    damped = _pair([0.0005, 0.002], effects=["hertz", "adhesion", "contact_damping"],
                   material="ss440c", adhesion={"model": "dmt", "surface_energy": GAMMA},
                   damping={"model": "viscoelastic", "eta": 1e9}, t_end=2e-5,
                   integrator={"method": "verlet", "dt": 2e-10}, output={"sample_dt": 1e-8})
    lmp = run_scene(damped, engine="lammps", workdir=tmp_path / "damped")
    ref = run_scene(damped)
    for res in (lmp, ref):
        assert [r.collision for r in res] == ["captured", "separated"]
        assert math.isnan(res[0].restitution) and res[0].captured
    assert abs(lmp[1].restitution - ref[1].restitution) < 1e-8


def test_the_inference_refuses_a_two_sphere_scene():
    from granchain.inference.grid import check_gappable
    with pytest.raises(SceneError) as err:
        check_gappable(_pair([0.01]))
    assert err.value.field == "chain.n"


@pytest.mark.lammps
def test_plastic_pair_on_lammps(tmp_path):
    """The plugin's Thornton law on LAMMPS (velocity Verlet, 0.1 ns): the measured
    restitution of a 316 pair against Thornton's closed form (measured 8.3e-10)."""
    ma = LIB["ss316"]
    m = _mass(ma, R)
    c = ThorntonContact(1.0 / (2.0 * (1 - ma.nu ** 2) / ma.E), R / 2.0, ma.yield_pressure)
    vy = c.yield_speed(m / 2.0)
    sc = _pair([4.1 * vy, 23.0 * vy], material="ss316", effects=["hertz", "plastic_contact"],
               integrator={"method": "verlet", "dt": 1e-10})
    for res in run_scene(sc, engine="lammps", workdir=tmp_path):
        assert res.collision == "separated"
        assert abs(res.restitution - thornton_restitution(res.v_striker / vy)) < 1e-8
