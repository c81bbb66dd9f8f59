"""The grids run the nodes that differ only in their mean gap in one engine call
(``inference.grid._run_nodes``): every value is the one a call per node gives, bit for bit,
for one setting and for a base of method auto resolved node by node (mixed settings are
run apart)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from granchain import inference
from granchain.gapdesign import design
from granchain.runplan import plan_run
from granchain.scene import load_scene
from granchain.simulate import run_scene

REPO = Path(__file__).resolve().parents[1]
R = 2


def _base(auto: bool):
    meas = inference.read_measurements(REPO / "measurements" / "example_restitution.csv",
                                       peaks=True)
    base = inference.complete_base(load_scene(REPO / "measurements" /
                                              "example_restitution.yaml"), meas)[0]
    if auto:
        # at 1e-3 auto takes RK4 on the packed nodes and the event method over the
        # wide gaps, whose flight multiplies a fixed step's work
        return base.derive({"integrator": {"method": "auto", "tolerance": 1e-3}})
    return inference.choose_setting(base, meas, peaks=True)[0]


@pytest.mark.parametrize("auto", [False, True])
def test_a_batched_joint_grid_is_a_call_per_node_bit_for_bit(auto):
    base = _base(auto)
    grid = inference.simulate_joint_grid(base, 500e-9, 4, 0.8, 2, R, None, progress=False)
    if auto:
        assert grid.setting["method"] == "per node"     # the nodes' settings differ
    d = design(base, R)
    checked = 0
    for k, g in enumerate(grid.gaps):
        for j, p in enumerate(grid.params):
            scene = plan_run(inference.joint_scene(base, g, p, R), per_speed=False).scene
            for r in run_scene(scene, gaps=d.gaps(g)):
                s = int(np.searchsorted(grid.speeds, r.v_striker))
                want = [inference.timing(r, "dt_peak_s"), inference.timing(r, "dt_front_s"),
                        inference.peak(r, 0), inference.peak(r, 1)]
                got = [grid.values[c][k, j, s, r.realisation] for c in inference.JOINT_OBS]
                np.testing.assert_array_equal(got, want)
                checked += 1
    assert checked == grid.n_chains == 4 * 2 * 3 * R


def test_a_batched_gap_grid_is_a_call_per_node_bit_for_bit():
    base = _base(False)
    grid = inference.simulate_grid(base, 200e-9, 3, R, None, progress=False)
    d = design(base, R)
    checked = 0
    for k, g in enumerate(grid.gaps):
        scene = plan_run(inference.grid_scene(base, g, R), per_speed=False).scene
        for r in run_scene(scene, gaps=d.gaps(g)):
            s = int(np.searchsorted(grid.speeds, r.v_striker))
            for c in inference.TIMING_COLUMNS:
                np.testing.assert_array_equal(grid.timings[c][k, s, r.realisation],
                                              inference.timing(r, c))
            checked += 1
    assert checked == grid.n_chains == 3 * 3 * R
