"""The integrator an inference simulates with is chosen from the accuracy the data need
(``granchain.inference.setting``): method auto asked for ACCURACY_FRACTION of the
smallest stated relative error. Its error, measured against a fine reference on the same
gap realisations, is below that fraction of the noise; tighter noise asks for a finer
setting, whose error is below its own (tighter) bound too."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from granchain import inference
from granchain.cli import main
from granchain.errors import GranchainError
from granchain.gapdesign import design
from granchain.runplan import plan_run
from granchain.scene import load_scene
from granchain.simulate import run_scene

REPO = Path(__file__).resolve().parents[1]
CSV = REPO / "measurements" / "example_restitution.csv"
SCENE = REPO / "measurements" / "example_restitution.yaml"
R = 3                                   # realisations per node: each speed, both laws
NODES = ((0.0, 0.9), (47e-9, 0.92), (200e-9, 1.0))    # (mean gap, e): packed to wide gaps


def _values(scene, g, e, gaps, **integrator):
    """(chains, 3): dt_front, v_max_1, v_max_2 of the node (g, e) of ``scene`` on
    ``gaps``, with ``integrator`` in place of the scene's own if given."""
    s = inference.joint_scene(scene, g, e, R)
    if integrator:
        s = s.derive({"integrator": integrator})
    res = run_scene(plan_run(s, per_speed=False).scene, gaps=gaps)
    res = sorted(res, key=lambda r: (r.v_striker, r.realisation))
    return np.array([[r.dt_front, r.v_max_1, r.v_max_2] for r in res])


def _worst_error(scene) -> np.ndarray:
    """The largest relative error of (dt_front, v_max_1, v_max_2) of ``scene``'s setting
    over NODES x speeds x R realisations, against RK4 at 1/16 of a fixed step of 20 or
    more steps per contact (its own error ~1e-8 on these chains), on the same sample
    grid."""
    ref_dt = (scene.dt if scene.method in ("rk4", "verlet") else _chosen(1.0)[0].dt) / 16
    worst = np.zeros(3)
    for g, e in NODES:
        gaps = design(scene, R).gaps(g)
        got = _values(scene, g, e, gaps)
        ref = _values(scene, g, e, gaps, method="rk4", dt=ref_dt, tolerance=None)
        assert np.all(np.isfinite(ref)) and got.shape == ref.shape
        worst = np.maximum(worst, np.max(np.abs(got / ref - 1.0), axis=0))
    return worst


def _meas(scale: float = 1.0):
    meas = inference.read_measurements(CSV, peaks=True)
    return dataclasses.replace(meas, err=meas.err * scale, vmax_err=meas.vmax_err * scale)


def _chosen(scale: float):
    meas = _meas(scale)
    base = inference.complete_base(load_scene(SCENE), meas)[0]
    return inference.choose_setting(base, meas, peaks=True)


def test_the_tolerance_is_a_fraction_of_the_smallest_stated_relative_error():
    meas = _meas()
    rel = np.concatenate([meas.err / meas.t, meas.vmax_err / meas.vmax_1,
                          meas.vmax_err / meas.vmax_2])
    scene, rec = _chosen(1.0)
    assert rec["source"] == "data" and rec["fraction"] == inference.ACCURACY_FRACTION == 0.1
    assert rec["smallest_relative_error"] == pytest.approx(rel.min(), rel=1e-12)
    assert rec["v_g_tolerance"] == pytest.approx(0.1 * rel.min(), rel=1e-12)
    assert scene.auto_tolerance == rec["v_g_tolerance"]
    assert (rec["method"], rec["dt_s"]) == (scene.method, scene.dt)
    line = meas.lines[int(np.argmin(meas.err / meas.t))]
    assert rec["set_by"] == {"column": "dt_err_s", "line": line}
    assert f"line {line}" in rec["reason"] and rec["method"] in rec["reason"]
    # the gap-only fit reads the timing's errors alone; without any stated error auto
    # keeps its default tolerance, and says so
    gap_only = inference.choose_setting(scene, meas, peaks=False)[1]
    assert gap_only["smallest_relative_error"] == pytest.approx((meas.err / meas.t).min())
    none = dataclasses.replace(meas, err=meas.err * 0, vmax_err=meas.vmax_err * 0)
    rec0 = inference.choose_setting(scene, none, peaks=True)[1]
    assert rec0["source"] == "default" and rec0["smallest_relative_error"] is None
    assert "state no error" in rec0["reason"]


def test_a_scene_that_gives_its_integrator_keeps_it():
    meas = _meas()
    for sets in (["integrator={method: rk4, dt: 2.0e-9}"],
                 ["integrator={method: auto, tolerance: 1.0e-3}"]):
        base = inference.complete_base(load_scene(SCENE, sets), meas)[0]
        scene, rec = inference.choose_setting(base, meas, peaks=True)
        assert rec["source"] == "scene" and "the base scene's integrator" in rec["reason"]
    assert (scene.method, scene.auto_tolerance) == (rec["method"], 1e-3)
    again, rec2 = inference.choose_setting(scene, meas, peaks=True)
    assert again.hash == scene.hash and rec2 == rec


def test_choosing_again_changes_nothing():
    scene, rec = _chosen(1.0)
    again, rec2 = inference.choose_setting(scene, _meas(), peaks=True)
    assert again.hash == scene.hash and again.given == scene.given and rec2 == rec


def test_an_error_auto_cannot_reach_is_one_line_naming_the_column():
    meas = _meas(1e-12)
    base = inference.complete_base(load_scene(SCENE), meas)[0]
    with pytest.raises(GranchainError) as e:
        inference.choose_setting(base, meas, peaks=True, source="m.csv, ")
    text = str(e.value)
    assert "\n" not in text and "dt_err_s" in text and "line" in text
    assert "integrator.method" in text


@pytest.mark.parametrize("scale", [1.0, 0.3, 0.1])
def test_the_chosen_setting_errs_below_the_fraction_of_the_noise(scale):
    """Measured, not taken from the cost model: the chosen setting's values at packed,
    47 nm and 200 nm nodes of the shipped example's grid, damped, against a fine RK4 on the
    same gaps. The timing's error is below the fraction of the smallest stated error (it
    sets the tolerance); each peak's below the fraction of the peaks' smallest. A third
    and a tenth of the noise ask for finer settings, which meet their own bounds and err
    less than the coarse one. Auto rates these chains in the cost model's damped class
    (its errors the worst over every measured scene, damped or not). Measured: the event
    method at 1e-5, 1e-6 and 1e-7, at 0.10, 0.064 and 0.036 of the timing's bound and
    0.066, 0.058 and 0.037 of the peaks'; the coarse setting at 0.34 and 1.0 of the
    tighter timing bounds. (Before the damped class, auto chose RK4 and the event method
    from the undamped chains' rows, at 0.47, 0.91 and 0.88 of the timing's bound.)"""
    scene, rec = _chosen(scale)
    meas = _meas(scale)
    worst = _worst_error(scene)
    frac = inference.ACCURACY_FRACTION
    t_bound = frac * np.min(meas.err / meas.t)
    p_bound = frac * np.min(np.concatenate([meas.vmax_err / meas.vmax_1,
                                            meas.vmax_err / meas.vmax_2]))
    assert worst[0] <= t_bound, (rec["reason"], worst)
    assert max(worst[1], worst[2]) <= p_bound, (rec["reason"], worst)
    if scale < 1.0:
        coarse, rec1 = _chosen(1.0)
        assert rec["v_g_tolerance"] == pytest.approx(scale * rec1["v_g_tolerance"])
        # finer: another method, the same fixed-step method at a smaller step, or the
        # same tolerance method at a tighter tolerance
        assert (scene.method, scene.dt, scene.tolerance) != \
            (coarse.method, coarse.dt, coarse.tolerance)
        if scene.method == coarse.method and scene.tolerance is None:
            assert scene.dt < coarse.dt
        elif scene.method == coarse.method:
            assert scene.tolerance < coarse.tolerance
        # and it buys accuracy on these chains: the coarse setting errs more
        assert _worst_error(coarse)[0] > worst[0]


def test_infer_records_the_integrator_it_chose(tmp_path, capsys):
    """A bare base scene (no integrator: the chapter's RK4 at 1 ns before) runs the
    setting the data ask for; the JSON and the summary say which and why."""
    bare = tmp_path / "bare.yaml"
    bare.write_text("name: bare\nmaterial: ss440c\nchain: {n: 15, radius: 150e-6}\n"
                    "probes: [2, 13]\nstriker: {velocity: [0.03, 0.06, 0.1]}\n"
                    "effects: [hertz, groove_friction, air_drag, rotation, particle_friction, "
                    "contact_damping]\ndamping: {model: coeff_restitution, e: 0.95}\n")
    small = ["--gap-points", "3", "--e-points", "3", "--realisations", "2", "--no-progress",
             "--cache-dir", str(tmp_path / "c")]
    argv = ["infer", str(CSV), "--scene", str(bare), "--fit", "gap_mean,restitution", *small]
    assert main([*argv, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    rec = doc["integrator"]
    scene, want = _chosen(1.0)
    assert rec["source"] == "data" and rec["method"] == want["method"]
    assert rec["dt_s"] == pytest.approx(want["dt_s"]) and rec["tolerance"] == want["tolerance"]
    assert (rec["method"], rec["dt_s"]) != ("rk4", 1e-9)     # not the chapter's RK4 at 1 ns
    assert rec["v_g_tolerance"] == pytest.approx(want["v_g_tolerance"])
    assert main(argv) == 0
    out = capsys.readouterr().out
    line, = [ln for ln in out.splitlines() if ln.startswith("integrator: ")]
    assert rec["reason"] in line
