"""Scenes of the chains the field builds (spheres of their own size and material, a
striker of its own, an end wall, a dead load): what a scene may say, what it refuses in
one line, and that scenes using none of it are unchanged."""
from __future__ import annotations

import math

import numpy as np
import pytest

from granchain.errors import SceneError
from granchain.materials import RIGID, effective_modulus, library
from granchain.effects import hertz
from granchain.scene import scene_from_dict
from granchain.simulate import run_scene

ALL = ["hertz", "rotation", "groove_friction", "air_drag", "particle_friction",
       "rolling_friction"]


def _refused(raw: dict) -> SceneError:
    with pytest.raises(SceneError) as info:
        scene_from_dict(dict(raw, name="bad"))
    assert "\n" not in str(info.value)
    return info.value


@pytest.mark.parametrize("raw, field, words", [
    ({"chain": {"n": 5, "radius": [1e-4, 1e-4]}, "probes": [2, 5]}, "chain.radius",
     "has 2 entries but the chain has n = 5"),
    ({"chain": {"n": 3, "radius": [1e-4, -1e-4, 1e-4]}, "probes": [2, 3]}, "chain.radius[1]",
     "must be > 0"),
    ({"chain": {"n": 3, "materials": ["ss440c", "bras", "ss440c"]}, "probes": [2, 3]},
     "chain.materials[1]", "did you mean 'brass'"),
    ({"chain": {"n": 3, "materials": ["ss440c"]}, "probes": [2, 3]}, "chain.materials",
     "has 1 entries"),
    ({"striker": {"velocity": 0.1, "radius": 0.0}}, "striker.radius", "must be > 0"),
    ({"striker": {"velocity": 0.1, "material": "unobtainium"}}, "striker.material",
     "unknown material"),
    ({"walls": {"end": "rigd"}}, "walls.end", "did you mean 'rigid'"),
    ({"walls": {"end": {"E": 2e11}}}, "walls.end.nu", "missing"),
    ({"precompression": {"force": 0.01}}, "precompression.force", "needs an end wall"),
    ({"precompression": {"force": 0}}, "precompression.force", "0 N has no effect"),
    ({"precompression": {"force": 0.0}, "walls": {"end": "rigid"}}, "precompression.force",
     "0 N has no effect"),
    ({"walls": {}}, "walls", "an empty block has no effect"),
    ({"precompression": {}, "walls": {"end": "rigid"}}, "precompression",
     "an empty block has no effect"),
    ({"precompression": {"force": -0.01}, "walls": {"end": "rigid"}}, "precompression.force",
     "must be > 0"),
    ({"precompression": {"force": 0.01}, "walls": {"end": "rigid"},
      "gaps": {"distribution": "fixed", "mean": 2e-8}}, "precompression.force", "gaps"),
    ({"walls": {"end": "rigid"}, "integrator": {"method": "event"}}, "integrator.method",
     "end wall"),
])
def test_bad_field_chain_inputs_are_refused_in_one_line(raw, field, words):
    err = _refused(raw)
    assert err.field == field and words in str(err), str(err)


def test_new_keys_not_given_leave_the_spec_and_hash_unchanged():
    """A scene that uses none of the new keys has the spec it had before they existed
    (its hash pinned to the earlier one: tests/test_regression_pins.py); each new key
    given changes the hash."""
    base = scene_from_dict({})
    assert set(base.spec) == {"name", "material", "chain", "striker", "gaps", "effects",
                              "groove", "drag", "contact", "rolling", "probes", "integrator",
                              "t_end", "output", "ensemble"}
    assert base.spec["chain"] == {"n": 15, "radius": 150e-6}
    assert base.spec["striker"] == {"velocity": 0.1}
    for extra in ({"walls": {"end": "rigid"}}, {"striker": {"velocity": 0.1, "radius": 2e-4}},
                  {"chain": {"n": 15, "materials": ["brass"] * 15}}):
        assert scene_from_dict(extra).hash != base.hash


# The chapter's scenes through every method and effect, against the independent Hertz
# chain (tests/independent.py: scipy DOP853, its own equations and handbook constants) with
# each member's own gaps. Probes 2 and 13: v_max, the peak time at 13 and the delay
# between them, relative to the independent values; the energy balance error against
# the method's own error. (Their bits at an earlier commit: tests/test_regression_pins.py.)
#
# Hertz only (RK4 at 1 ns): measured v_max 2.0e-8 (probe 2), t_peak,13 1.6e-8, delay
# 7.1e-8; bound 3e-7, the integrator's and the peak's location error with room.
# Every effect (groove and particle friction, air drag, rotation, rolling): the effects
# take energy from the wave: measured v_max,13 below the Hertz-only value by 3.43e-4 to
# 3.50e-4 over every member and method, the peak time at 13 later by 7.2e-5 to 9.0e-5,
# the delay by 8.3e-5 to 1.01e-4. Bounds: v_max,13 between -7e-4 and -1.5e-4 (a dropped
# effect gives ~0, a doubled one ~-7e-4), times within 3e-4.
# A 1 % error in the Hertz constant K moves every time by ~0.4 % (t ~ K^(-2/5)) and fails
# both kinds; the balance bound is 10x the measured error of each scene's method.
CHAPTER_CHECKS = {
    #  case:       (scene keys, (v_max,13 lo, hi), time bound, |balance error| bound)
    "hertz": ({}, (-3e-7, 3e-7), 3e-7, 6.3e-9),
    "rk4_all": ({"effects": ALL, "rolling": {"k_roll": 100.0},
                 "gaps": {"distribution": "uniform", "mean": 20e-9},
                 "ensemble": {"realisations": 3}}, (-7e-4, -1.5e-4), 3e-4, 5.9e-8),
    "verlet_all": ({"effects": ALL[:5], "integrator": {"method": "verlet", "dt": 1e-9},
                    "gaps": {"distribution": "uniform", "mean": 20e-9},
                    "ensemble": {"realisations": 2}}, (-7e-4, -1.5e-4), 3e-4, 6.5e-6),
    # the groove's stick/slip, which the adaptive method does not locate, sets its ledger's
    # error: 2.6e-6 at its default 1e-8, 2.5e-7 at 1e-10
    "adaptive": ({"effects": ALL[:4], "integrator": {"method": "adaptive", "tolerance": 1e-10},
                  "gaps": {"distribution": "fixed", "mean": 20e-9}},
                 (-7e-4, -1.5e-4), 3e-4, 2.5e-6),
    "event": ({"effects": ALL[:5], "integrator": {"method": "event"},
               "gaps": {"distribution": "uniform", "mean": 20e-9},
               "ensemble": {"realisations": 2}}, (-7e-4, -1.5e-4), 3e-4, 5.8e-5),
}


@pytest.mark.parametrize("case", list(CHAPTER_CHECKS))
def test_chapter_scenes_match_the_independent_hertz_chain(case):
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from independent import SS440C, hertz_chain_peaks
    from granchain.gaps import member_gaps, members
    raw, (lo, hi), t_tol, bal_tol = CHAPTER_CHECKS[case]
    sc = scene_from_dict(dict(raw, name=case))
    runs = run_scene(sc)
    gaps = member_gaps(sc, members(sc))
    assert len(runs) == sc.realisations == len(gaps) >= 1
    for r, g in zip(runs, gaps):
        assert r.status == "passed" and r.probes == (2, 13)
        # one t_end for every case (past every run's), so members of equal gaps share a
        # solve; rtol 1e-10: its own error 5e-10
        ind = hertz_chain_peaks(*SS440C, sc.radius, sc.n, r.v_striker, gaps=g[:sc.n - 1],
                                probes=(2, 13), t_end=1.5e-5, rtol=1e-10)
        rel_v = r.v_max[12] / ind.v_max[1] - 1
        assert lo < rel_v < hi, (r.member, rel_v)
        if case == "hertz":
            assert abs(r.v_max[1] / ind.v_max[0] - 1) < hi, r.v_max[1] / ind.v_max[0] - 1
        rel_t = r.t_peak[12] / ind.t_peak[1] - 1
        rel_dt = (r.t_peak[12] - r.t_peak[1]) / (ind.t_peak[1] - ind.t_peak[0]) - 1
        assert abs(rel_t) < t_tol and abs(rel_dt) < t_tol, (r.member, rel_t, rel_dt)
        assert abs(r.energy.balance_error) < bal_tol, (r.member, r.energy.balance_error)


def test_a_list_of_equal_spheres_is_the_chapter_chain():
    """Radii and materials given per sphere, all equal to the chain's, run the chapter
    chain bit for bit (same hash-independent physics)."""
    plain = run_scene(scene_from_dict({"name": "a"}))[0]
    listed = run_scene(scene_from_dict({"name": "b", "chain": {
        "n": 15, "radius": [150e-6] * 15, "materials": ["ss440c"] * 15}}))[0]
    assert plain.v_max == listed.v_max and plain.t_peak == listed.t_peak


def test_contact_law_of_unequal_spheres_and_walls():
    """K = (4/3) E* sqrt(R*), 1/E* = sum (1-nu^2)/E, R* = Ri Rj/(Ri+Rj); a flat wall R* = Ri;
    a rigid wall adds no compliance; equal spheres give the chapter's E/(2(1-nu^2))."""
    lib = library()
    s, b = lib["ss440c"], lib["brass"]
    Es = 1.0 / ((1 - s.nu**2) / s.E + (1 - b.nu**2) / b.E)
    assert hertz.constant(s, 150e-6, b, 100e-6) == pytest.approx(
        4 / 3 * Es * math.sqrt(150e-6 * 100e-6 / 250e-6), rel=1e-15)
    assert hertz.constant(s, 150e-6, RIGID, math.inf) == pytest.approx(
        4 / 3 * s.E / (1 - s.nu**2) * math.sqrt(150e-6), rel=1e-15)
    assert effective_modulus(s, s) == s.E / (2 * (1 - s.nu**2))
    sc = scene_from_dict({"name": "w", "walls": {"end": "ss440c"}})
    assert sc.wall_k == pytest.approx(4 / 3 * s.E / (2 * (1 - s.nu**2)) * math.sqrt(150e-6),
                                      rel=1e-15)


def test_static_overlaps_hold_the_load_on_every_contact():
    sc = scene_from_dict({"name": "p", "chain": {"n": 6, "radius": [150e-6, 100e-6] * 3},
                          "probes": [2, 6], "walls": {"end": "brass"},
                          "precompression": {"force": 0.02}})
    inner, wall = sc.static_overlaps
    assert inner[0] == 0.0                         # the striker only touches particle 2
    for K, d in zip(sc.contact_k[1:], inner[1:]):
        assert K * d**1.5 == pytest.approx(0.02, rel=1e-14)
    assert sc.wall_k * wall**1.5 == pytest.approx(0.02, rel=1e-14)


def test_precompressed_chain_at_rest_stays_at_rest():
    """With no striker speed the preloaded chain sits in its static state: every sphere's
    velocity stays below 1e-12 m/s over 20 us, and the wall carries F0."""
    sc = scene_from_dict({"name": "rest", "chain": {"n": 10}, "probes": [2, 10],
                          "walls": {"end": "ss440c"}, "precompression": {"force": 0.05},
                          "striker": {"velocity": 0.0}, "t_end": 2e-5,
                          "output": {"sample_dt": 1e-7}, "effects": ["hertz", "air_drag"]})
    from granchain.engines import reference
    from granchain.gaps import member_gaps, members
    mem = members(sc)
    traj = next(reference.run(sc, member_gaps(sc, mem), np.zeros(1)))
    assert np.max(np.abs(traj.v)) < 1e-12
    assert np.allclose(traj.wall_force, 0.05, rtol=1e-12)


def test_every_material_names_its_source():
    for name, mat in library().items():
        assert mat.source, name
    for name in ("brass", "al6061", "chrome_steel_52100", "tungsten_carbide", "ptfe",
                 "soda_lime_glass"):
        assert name in library()


def test_wall_table_columns_and_json():
    sc = scene_from_dict({"name": "w", "walls": {"end": "rigid"}})
    r = run_scene(sc)[0]
    doc = r.to_json()
    assert doc["walled"] and doc["wall_peak_final"] and doc["wall_force_static"] == 0.0
    assert doc["wall_force_max"] > 0 and doc["t_wall_peak"] > r.t_peak[13]
    from granchain.tables import columns, member_row
    meta = {"study": "s", "material": "ss440c", "gap_distribution": "none", "gap_mean_nm": 0.0,
            "extra_length_um": 0.0, "seed": 0, "scene_hash": "h"}
    row = member_row(meta, r, 15)
    assert list(row) == columns(15, walled=True) and row["wall_force_max_N"] == r.wall_force_max


def test_a_wall_peak_cut_off_by_t_end_is_not_reported():
    """A fixed t_end that ends before the wall force has passed its peak: NaN, flagged."""
    sc = scene_from_dict({"name": "cut", "walls": {"end": "rigid"}, "t_end": 1.0e-5})
    r = run_scene(sc)[0]
    assert not r.wall_peak_final and math.isnan(r.wall_force_max) and math.isnan(r.t_wall_peak)


# ---------------------------------------------------------------------------------------
# chain.radius_spread: each member's radii drawn about the nominal ones
# ---------------------------------------------------------------------------------------
SPREAD = {"name": "spread", "chain": {"n": 15, "radius_spread": {"sd": 0.5e-6, "seed": 7}},
          "integrator": {"method": "verlet", "dt": 1e-9}, "ensemble": {"realisations": 6}}


@pytest.mark.parametrize("raw, field, words", [
    ({"chain": {"n": 15, "radius_spread": {"sd": 40e-6}}}, "chain.radius_spread.sd",
     "can make a radius non-positive"),
    ({"chain": {"n": 15, "radius_spread": {"distribution": "uniform", "sd": 90e-6}}},
     "chain.radius_spread.sd", "sqrt(3) sd"),
    ({"chain": {"n": 15, "radius_spread": {"sd": 0.0}}}, "chain.radius_spread.sd", "must be > 0"),
    ({"chain": {"n": 15, "radius_spread": {"sigma": 1e-7}}}, "chain.radius_spread.sigma",
     "unknown key"),
    ({"chain": {"n": 15, "radius_spread": {"distribution": "gauss", "sd": 1e-7}}},
     "chain.radius_spread.distribution", "unknown distribution"),
    ({"chain": {"n": 15, "radius_spread": 1e-7}}, "chain.radius_spread", "expected a mapping"),
])
def test_bad_radius_spreads_are_refused(raw, field, words):
    err = _refused(raw)
    assert err.field == field and words in str(err), str(err)


def test_member_radii_follow_the_spread_and_their_own_stream():
    """Normal draws have the asked sd and stay within 4 sd; uniform ones within sqrt(3) sd;
    a member's radii depend only on (seed, realisation), not on the gaps' stream."""
    from granchain.gaps import member_gaps, member_radii, members
    for dist, bound in (("normal", 4.0), ("uniform", math.sqrt(3.0))):
        sc = scene_from_dict({"name": "d", "chain": {"n": 15, "radius_spread": {
            "distribution": dist, "sd": 1e-7}}, "ensemble": {"realisations": 400}})
        e = member_radii(sc, members(sc)) - 150e-6
        assert abs(e.std() / 1e-7 - 1) < 0.05 and np.abs(e).max() <= bound * 1e-7
    sc = scene_from_dict(dict(SPREAD, gaps={"distribution": "uniform", "mean": 2e-8, "seed": 7},
                              ensemble={"realisations": 500}))
    mem = members(sc)
    r_all = member_radii(sc, mem)
    assert np.array_equal(member_radii(sc, mem[3:4])[0], r_all[3])
    assert not np.array_equal(r_all[0], r_all[1])
    # same seed for gaps and radii: the streams differ (measured correlation -0.009 over
    # 7000 pairs)
    g = member_gaps(sc, mem)
    assert abs(np.corrcoef(g[:, :14].ravel(), (r_all[:, :14] - 150e-6).ravel())[0, 1]) < 0.05


def test_spread_member_rerun_alone_is_bit_identical():
    """A member of a radius-spread ensemble re-run alone gives the same bits."""
    sc = scene_from_dict(SPREAD)
    runs = run_scene(sc)
    alone = run_scene(sc, realisations=[4])[0]
    assert alone.v_max == runs[4].v_max and alone.t_peak == runs[4].t_peak
    assert runs[0].v_max != runs[1].v_max


def test_spread_member_matches_the_independent_solution():
    """One member's drawn radii, solved independently: v_max of every final particle."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from independent import hertz_chain_general
    from granchain.gaps import member_radii, members
    sc = scene_from_dict(dict(SPREAD, integrator={"method": "rk4", "dt": 2.5e-10}))
    r = run_scene(sc, realisations=[2])[0]
    radii = member_radii(sc, members(sc, [2]))[0]
    m = library()["ss440c"]
    ind = hertz_chain_general(list(radii), (m.E, m.nu, m.rho), 0.1, r.t_end)
    got = np.array(r.v_max)
    ok = np.isfinite(got)
    assert ok.sum() >= 13
    # measured 2.0e-8 (RK4 at 0.25 ns, automatic sampling); the nominal radii are far off
    assert np.max(np.abs(got[ok] / ind.v_max[ok] - 1)) < 6e-8
    nominal = run_scene(scene_from_dict({"name": "nom", "integrator": {"method": "rk4",
                                                                       "dt": 2.5e-10}}))[0]
    assert np.nanmax(np.abs(np.array(nominal.v_max)[ok] / ind.v_max[ok] - 1)) > 1e-6


@pytest.mark.lammps
def test_lammps_and_the_reference_engine_agree_on_a_radius_spread_ensemble():
    """Both engines run each member with its own radii (LAMMPS: one deck, each chain its
    own diameters and masses; Verlet at the same dt and sample grid). Measured: v_max of
    every particle 3.2e-10, v_g 2.3e-11 relative, the same samples and status; granchain
    compare (which passes the members' radii to both engines) within its tolerances.
    LAMMPS with the nominal radii instead: v_max 1.6e-2 off."""
    from granchain.compare import compare
    sc = scene_from_dict(SPREAD)
    ref, lmp = run_scene(sc), run_scene(sc, engine="lammps")
    assert [r.engine for r in lmp] == ["lammps"] * 6 and lmp[0].v_max != lmp[1].v_max
    assert [r.engine for r in ref] == ["reference"] * 6
    for a, b in zip(ref, lmp):
        assert b.status == a.status == "passed" and b.samples == a.samples
        va, vb = np.array(a.v_max), np.array(b.v_max)
        ok = np.isfinite(va)
        assert ok.sum() >= 13 and np.array_equal(ok, np.isfinite(vb))
        assert np.max(np.abs(vb[ok] / va[ok] - 1)) < 3e-9
        assert b.v_g == pytest.approx(a.v_g, rel=3e-10)
    c = compare(scene_from_dict(dict(SPREAD, ensemble={"realisations": 2})))
    assert c.ok, c.failures()
