"""granchain infer --fit gap_mean,KEY: the joint fit of the mean gap and any scene key
declared fittable (``validate.Fit`` on its Key): Thornton's limiting pressure and the JKR
surface energy recovered from synthetic chains at held-out true values, the refusal of a
key that is not declared fittable, and the command's report of such a fit.

Grids are small (4 mean gaps x 4-5 values of the key x 2 speeds x 8 realisations, a few
seconds each): they check that the fit reads the key, not its calibration."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import yaml

from granchain import inference
from granchain.cli import main
from granchain.errors import GranchainError, SceneError
from granchain.scene import scene_from_dict

PLASTIC = """name: plastic
material: ss316
striker: {velocity: [0.04, 0.08]}
gaps: {distribution: uniform, mean: 20.0e-9}
effects: [hertz, groove_friction, air_drag, rotation, plastic_contact]
plasticity: {model: thornton, yield_pressure: 1.0e9}
integrator: {method: auto, tolerance: 1.0e-3}
"""
# a short chain at low speeds, where the JKR hysteresis and pull shape the peaks
STICKY = """name: sticky
material: ss440c
chain: {n: 8}
probes: [2, 7]
striker: {velocity: [0.006, 0.012]}
gaps: {distribution: uniform, mean: 20.0e-9}
effects: [hertz, adhesion]
adhesion: {model: jkr, surface_energy: 0.1}
integrator: {method: auto, tolerance: 1.0e-3}
"""
YIELD, GAMMA = "plasticity.yield_pressure", "adhesion.surface_energy"
TRUTH_SEED = 9001


def measurements(base, key, value, v, gap=60e-9, err=0.3e-6, level=0.02, seed=0):
    """Independent chains at mean gap ``gap`` and ``key`` = ``value``, drawn with a gap
    seed the grid never used, with noise as stated (0.3 us, 2 % of v_s on the peaks)."""
    v = np.asarray(v, float)
    X = inference.simulate_joint_rows(base.derive(gaps={"seed": TRUTH_SEED}), gap, value, v,
                                      list(range(v.size)), "dt_front_s", key=key)
    perr = level * v
    sd = np.stack([np.full(v.size, err), perr, perr], axis=1)
    Y = X + sd * np.random.default_rng(seed).standard_normal(X.shape)
    return inference.Measurements(v, Y[:, 0], np.full(v.size, err), np.arange(v.size),
                                  "dt_front_s", tuple(range(2, v.size + 2)), (None,) * v.size,
                                  Y[:, 1], Y[:, 2], perr)


def grid_of(text, key, lo, hi, points, cache):
    base = scene_from_dict(yaml.safe_load(text))
    return base, inference.simulate_joint_grid(base, 200e-9, 4, lo, points, 8, cache,
                                               emphasis=0.0, key=key, hi=hi)


def test_a_yield_pressure_is_recovered(tmp_path):
    """Four 316 chains at p_y = 7e8 Pa (between the grid's nodes 6e8 and 1.2e9): the 95 %
    interval of p_y covers it and is narrow (measured: 6.99e8 [6.46e8, 7.59e8] Pa); the
    grid's nodes are log-spaced (the declared prior spans two decades); the result names
    the key. Fails on a fit that kept the restitution's axis or ignored the key."""
    base, grid = grid_of(PLASTIC, YIELD, 3e8, 2.4e9, 4, tmp_path)
    np.testing.assert_allclose(grid.params, [3e8, 6e8, 1.2e9, 2.4e9], rtol=1e-12)
    meas = measurements(base, YIELD, 7e8, [0.045, 0.055, 0.065, 0.075])
    res = inference.infer_joint(base, meas, grid=grid)
    lo, hi = res.yield_pressure_ci95
    assert lo <= 7e8 <= hi and hi / lo < 1.5, (lo, hi)
    assert not res.flags and res.predictive_values == 12
    doc = res.to_json()
    assert doc["fit"] == ["gap_mean", "yield_pressure"] and doc["key"] == YIELD
    assert doc["yield_pressure"] == res.param and doc["yield_pressure_grid"][2] == 4
    assert doc["param_spacing"] == "log" and "restitution" not in doc
    assert doc["law"] == "plastic_contact thornton"
    json.dumps(doc)


def test_a_surface_energy_is_recovered(tmp_path):
    """Four 440C chains of 8 spheres at 6.5-11 mm/s with JKR adhesion at gamma = 0.3 J/m^2
    (between the nodes 0.28 and 0.5): the interval covers it (measured: 0.265 [0.218,
    0.315])."""
    base, grid = grid_of(STICKY, GAMMA, 0.05, 0.5, 5, tmp_path)
    meas = measurements(base, GAMMA, 0.3, [0.0065, 0.008, 0.0095, 0.011])
    res = inference.infer_joint(base, meas, grid=grid)
    lo, hi = res.surface_energy_ci95
    assert lo <= 0.3 <= hi and hi / lo < 2.0, (lo, hi)
    assert not res.flags


@pytest.mark.parametrize("fit, needles", [
    ("gap_mean,groove.mu", ["--fit", "'groove.mu' is not declared fittable",
                            "plasticity.yield_pressure", "adhesion.surface_energy", "damping.e"]),
    ("gap_mean,adhesion.model", ["--fit", "'adhesion.model' is not declared fittable"]),
    ("gap_mean,chain.radius", ["--fit", "'chain.radius' is not declared fittable"]),
    ("gap_mean,plasticity.yeld_pressure", ["--fit", "did you mean 'plasticity.yield_pressure'"]),
    ("gap_mean,damping.e,adhesion.surface_energy", ["--fit", "one scene key"]),
    ("gap_mean,damping.e,restitution", ["--fit", "named twice"]),
])
def test_a_key_not_declared_fittable_is_refused(tmp_path, capsys, fit, needles):
    """One line naming --fit and the fittable keys, before anything is read or run."""
    scene = tmp_path / "s.yaml"
    scene.write_text(PLASTIC)
    code = main(["infer", str(tmp_path / "none.csv"), "--scene", str(scene), "--fit", fit])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)


def test_restitution_is_an_alias_of_damping_e():
    assert inference.parse_fit("gap_mean,restitution") == ("gap_mean", "damping.e")
    assert inference.parse_fit("gap_mean, damping.e") == ("gap_mean", "damping.e")
    assert inference.parse_fit("gap_mean") == ("gap_mean",)
    assert inference.parse_fit("gap_mean,yield_pressure") == ("gap_mean", YIELD)


def test_the_declarations_say_which_ends_are_physical():
    """e = 1 is the physical top of the restitution (weight there is no grid end); the
    log-uniform keys' ranges end at grid ends on both sides."""
    keys = inference.fittable()
    assert set(keys) == {"damping.e", YIELD, GAMMA}
    assert keys["damping.e"].key.physical_ends() == (False, True)
    assert not keys["damping.e"].log and keys[YIELD].log and keys[GAMMA].log
    for k in (YIELD, GAMMA):
        assert keys[k].key.physical_ends() == (False, False)
        nodes = keys[k].nodes(keys[k].fit.lo, keys[k].fit.hi, keys[k].fit.points)
        ratios = nodes[1:] / nodes[:-1]
        np.testing.assert_allclose(ratios, ratios[0], rtol=1e-9)


def test_a_base_scene_without_the_keys_effect_is_refused():
    base = scene_from_dict(yaml.safe_load(PLASTIC.replace(", plastic_contact]", "]")
                                          .replace("plasticity: {model: thornton, "
                                                   "yield_pressure: 1.0e9}\n", "")))
    with pytest.raises(SceneError, match="no plastic_contact.*plasticity.yield_pressure"):
        inference.check_fit_base(base, inference.fit_key(YIELD))


def test_restitution_options_are_refused_for_another_key(tmp_path, capsys):
    scene = tmp_path / "s.yaml"
    scene.write_text(PLASTIC)
    csv_path = tmp_path / "m.csv"
    csv_path.write_text("v_striker_m_s,dt_front_s,vmax_1_m_s,vmax_2_m_s\n0.05,3e-5,0.04,0.03\n")
    for extra, needle in ((["--e-min", "0.8"], "--e-min: sets the restitution's grid"),
                          (["--fit-range", "1e9"], "--fit-range: '1e9' is not LO,HI"),
                          (["--fit-range", "1e9,5e8"], "is not below the range's top"),
                          (["--fit-range", "1e4,1e9"], "is not between 100000 and 1e11")):
        code = main(["infer", str(csv_path), "--scene", str(scene), "--fit",
                     f"gap_mean,{YIELD}", "--no-cache", *extra])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and needle in err, (extra, err)


def test_the_command_reports_a_fit_of_the_yield_pressure(tmp_path, capsys):
    """The summary names the key, its unit and its log-spaced grid, and prints the
    posterior predictive check and the model check, as for the restitution; --json names
    the parameter by its results' name."""
    scene = tmp_path / "s.yaml"
    scene.write_text(PLASTIC)
    base = scene_from_dict(yaml.safe_load(PLASTIC))
    X = inference.simulate_joint_rows(base.derive(gaps={"seed": 5}), 40e-9, 8e8, [0.045, 0.07],
                                      [0, 0], "dt_front_s", key=YIELD)
    csv_path = tmp_path / "m.csv"
    csv_path.write_text("v_striker_m_s,dt_front_s,chain_id,vmax_1_m_s,vmax_2_m_s,vmax_err_m_s\n"
                        + "".join(f"{v},{float(x[0])!r},a,{float(x[1])!r},{float(x[2])!r},0.001\n"
                                  for v, x in zip((0.045, 0.07), X)))
    argv = ["infer", str(csv_path), "--scene", str(scene), "--fit", f"gap_mean,{YIELD}",
            "--gap-points", "3", "--gap-max-nm", "120", "--fit-range", "4e8,1.6e9",
            "--fit-points", "3", "--realisations", "4", "--cache-dir", str(tmp_path / "c"),
            "--no-progress"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    for words in ("limiting contact pressure p_y (plasticity.yield_pressure)", " Pa, 95% interval",
                  "x p_y 4e+08-1.6e+09 Pa (3 points, log spacing)",
                  "posterior correlation of mean gap and log p_y",
                  "posterior predictive check (plastic_contact thornton): ", "model check: "):
        assert words in text, (words, text)
    assert main(argv + ["--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["n_simulated_now"] == 0 and doc["n_simulated"] == 3 * 3 * 2 * 4
    assert doc["yield_pressure_grid"] == [4e8, 1.6e9, 3]
    assert "data_outside_model" in doc and "predictive_outside" in doc


def test_the_peaks_check_allows_what_the_fitted_range_of_gamma_gives(tmp_path):
    """The peaks' bound counts the attraction of the largest surface energy the fit
    simulates, not the base scene's placeholder: two chains at gamma = 0.5 J/m^2 and 6 mm/s
    (v_max,1 = 1.14 v_s, measured; peak noise 0.2 % of v_s), fitted on a range to 0.5 with
    a base scene at 0.1 (whose contacts can add up to 1.07 v_s at that speed), are data,
    not a unit mix-up.
    A peak twice the bound at the range's top is still refused."""
    base = scene_from_dict(yaml.safe_load(STICKY))
    grid = inference.simulate_joint_grid(base, 200e-9, 3, 0.1, 2, 2, tmp_path, emphasis=0.0,
                                         key=GAMMA, hi=0.5)
    meas = measurements(base, GAMMA, 0.5, [0.006, 0.006], gap=20e-9, level=0.002)
    assert np.max(meas.vmax_1 / meas.v) > 1.1
    res = inference.infer_joint(base, meas, grid=grid)
    assert res.predictive_values == 6
    far = dataclasses.replace(meas, vmax_1=3.0 * meas.vmax_1)
    with pytest.raises(GranchainError, match="vmax_1_m_s"):
        inference.infer_joint(base, far, grid=grid)
