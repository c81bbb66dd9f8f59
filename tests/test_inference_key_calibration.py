"""Calibration (slow) of ``granchain infer --fit gap_mean,KEY`` for the limiting pressure
and the surface energy: synthetic experiments with truths drawn from the fit's prior over
each key's calibrated range, realisations the grid never saw, and stated noise, on the
grids of ``benchmarks/inference_joint_calibration.py`` (its base scenes, ranges, truths and
report; the benchmark gives the full run and its table in docs/explanation/inference.md).

Peak noise: 8 % of v_s for the limiting pressure (about the chapter's scatter), 2 % for
the surface energy (at 8 % the data do not tell gamma on 0.05-0.5 J/m^2 at these speeds).
An interval made too narrow fails the coverage bound (checked when the test was written:
below)."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from granchain import inference

from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import inference_joint_calibration as cal  # noqa: E402

YIELD, GAMMA = "plasticity.yield_pressure", "adhesion.surface_energy"
# the benchmark's run: mean gaps to 500 nm in gap_points x the key's points x 3 speeds x
# realisations
GRID = {YIELD: dict(gap_points=11, realisations=64), GAMMA: dict(gap_points=9, realisations=48)}
LEVEL = {YIELD: 0.08, GAMMA: 0.02}   # peak noise / v_s of the experiments held here
NOISE_SCALE = 1.0          # the stated noise over the noise drawn


def outcomes(key: str, cache_dir, scale: float = NOISE_SCALE) -> list[dict]:
    """The benchmark's outcome of each experiment (truths from the base scene's own law)
    on the key's grid (simulated into ``cache_dir``, or read from it)."""
    material = cal.CASES[key]["materials"][0]
    base = cal.base_scene(material, key)
    grid = cal.build_grid(base, key, 500e-9, GRID[key]["gap_points"],
                          GRID[key]["realisations"], cache_dir)
    fk = inference.fit_key(key)
    out = []
    for tr in cal.make_trials([material], [LEVEL[key]], 20, 3, key=key):
        X, _ = cal.truth_rows(base, tr, "own", key)
        if not np.all(np.isfinite(X)):
            continue              # no wave at a probe: nothing measured (counted apart)
        res = inference.infer_joint(base, cal.measurements(tr, X, scale), grid=grid)
        out.append(cal.outcome(tr, res, fk.log))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("key", [YIELD, GAMMA])
def test_key_intervals_cover_near_nominal(key, tmp_path_factory):
    """40 experiments per key (20 of three independent chains, 20 one-chain series at three
    speeds; those where no wave reached a probe are not measured, so not fitted): the
    range each fit reports holds the truth in at least 0.875 of the fitted ones, for the
    key and for the mean gap (at nominal coverage 0.95, fewer has probability 0.01-0.06 for
    25-40 fits). The range is the 95 % interval or, when the posterior reaches an end of
    the grid (flagged, that side NaN), the one-sided bound the fit still gives; a fit with
    weight at both ends reports no range and counts as a miss. Measured (the benchmark's
    run, 2026-11-29): p_y's range held it in 30 of 30 fitted (10 without a wave), the mean
    gap's in 30; gamma's in 37 of 40 (2 with no range), the mean gap's in 39. With the
    kernel's width scaled by 0.3 (intervals too narrow; ``modelcheck.kernel_factor`` x
    0.3) the same experiments gave 20 of 30 for p_y (mean gap 25) and 33 of 40 for gamma
    (mean gap 33): the bound fails for both. Stating 0.3 x the noise drawn (the peaks' 2 %)
    left gamma's independent chains unchanged (19 of 20): the kernel's spread over the
    realisations, not the stated noise, sets these intervals."""
    res = outcomes(key, tmp_path_factory.mktemp("key-cal"))
    print("\n" + cal.report(key, res, inference.fit_key(key).fit.symbol, True))
    n = len(res)
    assert n >= 25, n
    assert sum(r["rep_e"] for r in res) >= 0.875 * n
    assert sum(r["rep_g"] for r in res) >= 0.875 * n
