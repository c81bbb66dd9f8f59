"""One validator for every scene the tool runs: a scene derived from another
(``Scene.derive``, which inference, compare, the studies and the accuracy harness use) is
validated whole, as a file giving its keys would be; ``infer`` refuses a base scene that
cannot take a gap law before it simulates anything; an empty predictive check never
prints as a pass, and simulated chains without a timing are reported."""
from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest

from granchain import inference
from granchain.inference import gapfit, jointfit
from granchain.cli import main
from granchain.errors import SceneError
from granchain.scene import scene_from_dict

from conftest import REPO

PRELOADED = {"name": "pre", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
             "striker": {"velocity": 0.1}, "walls": {"end": "rigid"},
             "precompression": {"force": 0.1}, "integrator": {"method": "rk4", "dt": 1e-9}}
PRE_BASE = """name: pre_base
material: ss440c
chain: {n: 15, radius: 150e-6}
walls: {end: rigid}
precompression: {force: 0.1}
effects: [hertz, groove_friction, air_drag, rotation, particle_friction, contact_damping]
damping: {model: coeff_restitution, e: 0.95}
integrator: {method: auto, tolerance: 1.0e-3}
"""


def test_a_derived_scene_is_refused_what_its_file_would_be():
    """A file with a preload and gaps is refused; the same scene derived by adding the
    gaps to a preloaded scene was accepted (only the changed keys were checked)."""
    file = dict(PRELOADED, gaps={"distribution": "uniform", "mean": 2e-8})
    with pytest.raises(SceneError) as in_file:
        scene_from_dict(file)
    with pytest.raises(SceneError) as derived:
        scene_from_dict(PRELOADED).derive(gaps={"distribution": "uniform", "mean": 2e-8})
    assert in_file.value.field == derived.value.field == "precompression.force"


def test_a_derived_scene_keeps_its_base_keys_and_can_unset_one():
    base = scene_from_dict({"name": "a", "striker": {"velocity": 0.1},
                            "integrator": {"method": "adaptive", "tolerance": 1e-7}})
    d = base.derive(integrator={"method": "verlet", "dt": 1e-9, "tolerance": None})
    assert "integrator.tolerance" in base.given and "integrator.tolerance" not in d.given
    assert {"name", "striker.velocity", "integrator.method"} <= d.given
    # a key this scene gives, left without effect by the change, is the change's choice
    assert base.derive(**{"integrator.method": "verlet", "integrator.dt": 1e-9}).method == "verlet"
    # a key the change names that has no effect is refused, as in a file
    with pytest.raises(SceneError) as e:
        base.derive(**{"integrator.method": "verlet", "integrator.dt": 1e-9,
                       "integrator.tolerance": 1e-6})
    assert e.value.field == "integrator.tolerance"


def no_simulation(*args, **kwargs):
    raise AssertionError("the inference simulated a scene it should have refused")


@pytest.mark.parametrize("fit, csv", [("gap_mean", "example_synthetic.csv"),
                                      ("gap_mean,restitution", "example_restitution.csv")])
def test_infer_refuses_a_preloaded_base_before_simulating(tmp_path, monkeypatch, capsys, fit,
                                                          csv):
    """The base scene validates alone; the chapter's gap law makes it one the validator
    refuses. Fails on a build that simulated it and printed 'mean gap n/a'."""
    (tmp_path / "pre_base.yaml").write_text(PRE_BASE)
    # where the fits call them
    monkeypatch.setattr(gapfit, "simulate_grid", no_simulation)
    monkeypatch.setattr(jointfit, "simulate_joint_grid", no_simulation)
    monkeypatch.setattr("granchain.simulate.run_scene", no_simulation)
    code = main(["infer", str(REPO / "measurements" / csv), "--scene",
                 str(tmp_path / "pre_base.yaml"), "--fit", fit, "--no-cache", "--no-progress"])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert out.err.count("\n") == 1 and "precompression.force" in out.err
    assert "Traceback" not in out.err


def nan_joint_grid(base, gap_max, gap_points, e_min, e_points, realisations, cache_dir=None,
                   engine="reference", progress=None, key=inference.DEFAULT_KEY, hi=None):
    """A joint grid in which no simulated chain measured anything (every value NaN)."""
    gaps = inference.gap_nodes(gap_max, gap_points)
    es = inference.fit_key(key).nodes(e_min, 1.0 if hi is None else hi, e_points)
    speeds = np.array(sorted({float(v) for v in base.striker_velocities}))
    shape = (gaps.size, es.size, speeds.size, realisations)
    values = {k: np.full(shape, np.nan) for k in inference.JOINT_OBS}
    return inference.JointGrid(gaps, es, speeds, values, ("0" * 16,) * gaps.size, 0)


@pytest.mark.filterwarnings("ignore:All-NaN slice:RuntimeWarning")
def test_an_empty_predictive_check_is_not_printed_as_a_pass(monkeypatch):
    """Fails on a build that printed '0 of 24 measured values outside their 95% predictive
    range' for a check that checked nothing."""
    grids = []
    monkeypatch.setattr(jointfit, "simulate_joint_grid",
                        lambda *a, **k: grids.append(nan_joint_grid(*a, **k)) or grids[-1])
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["infer", str(REPO / "measurements" / "example_restitution.csv"),
                     "--scene", str(REPO / "measurements" / "example_restitution.yaml"),
                     "--fit", "gap_mean,restitution", "--no-cache", "--no-progress",
                     "--gap-points", "4", "--e-points", "3", "--realisations", "4"])
    text = out.getvalue()
    assert code == 0 and len(grids) == 1           # the fit read the NaN grid
    line, = [ln for ln in text.splitlines() if ln.startswith("posterior predictive check")]
    assert "not made" in line and "0 of" not in line
    # and the chains without a timing are named
    assert any(ln.startswith("warning:") and "simulated chains have no" in ln
               for ln in text.splitlines())
