"""An inference that knows when a chain lies outside its simulations: the grid's designed
realisations (``granchain.gapdesign``: the gaps next to the probes importance-sampled
toward small values, with weights), the weighted kernel likelihood, and the model check
(``granchain.modelcheck``: ``data_outside_model``, a density-rank p-value).

The quick tier checks the design's weights against the gap law, the kernel density against
a direct sum written here with scipy, the check's calibration on Gaussian clouds, and one
rare-pattern series (a gap 2-3 of 0.001 of the mean) on a small simulated grid, which must
be covered or flagged. The slow tier runs a CI-sized version of the calibration suite
(``benchmarks/inference_outside.py``)."""
from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from granchain import gapdesign, inference, modelcheck
from granchain.gaps import realise
from granchain.scene import scene_from_dict

from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import inference_outside as suite  # noqa: E402


def scene(**kw):
    spec = {"name": "t", "material": "ss316", "striker": {"velocity": [0.03, 0.1]},
            "gaps": {"distribution": "uniform", "mean": 1e-7}}
    spec.update(kw)
    return scene_from_dict(spec)


# ---------------------------------------------------------------------------------------
# the design
# ---------------------------------------------------------------------------------------
def test_key_contacts_are_the_gaps_beside_the_probes_but_the_strikers():
    assert gapdesign.key_contacts(scene()) == (1, 11, 12)          # probes 2 and 13, n = 15
    assert gapdesign.key_contacts(scene(probes=[3, 6], chain={"n": 8})) == (1, 2, 4, 5)


@pytest.mark.parametrize("law", ["uniform", "exponential"])
def test_weighted_design_reproduces_the_gap_law(law):
    """Weighted averages over the designed realisations are the law's expectations: the
    share of key gaps below 0.05 of the mean (2.5 % uniform, 4.9 % exponential), their
    mean (1); the proposal holds several times more of them than plain draws."""
    sc = scene(gaps={"distribution": law, "mean": 1e-7})
    d = gapdesign.design(sc, 20000)
    w = d.weights / d.weights.sum()
    assert np.all(d.weights > 0) and np.max(d.weights) <= 2.0 ** len(d.contacts) + 1e-9
    for k in d.contacts:
        u = d.patterns[:, k]
        p_small = 0.025 if law == "uniform" else 1 - np.exp(-0.05)
        assert np.sum(w * (u < 0.05)) == pytest.approx(p_small, rel=0.12)
        assert np.mean(u < 0.05) > 3 * p_small                       # oversampled
        assert np.sum(w * u) == pytest.approx(1.0, abs=0.03)
    plain = np.stack([realise(sc.derive(gaps={"mean": 1.0}), r) for r in range(50)])
    others = [k for k in range(sc.n - 1) if k not in d.contacts]
    assert np.array_equal(d.patterns[:50, others], plain[:, others])   # same stream
    flat = gapdesign.design(sc, 50, emphasis=0.0)
    assert np.array_equal(flat.patterns, plain) and np.all(flat.weights == 1.0)


def test_proposal_quantile_inverts_the_cdf():
    x = np.linspace(0, 1, 101)
    assert np.allclose(gapdesign.proposal_cdf(gapdesign.proposal_quantile(x)), x, atol=1e-12)


# ---------------------------------------------------------------------------------------
# the kernel likelihood and the check
# ---------------------------------------------------------------------------------------
def test_kernel_density_is_the_weighted_mixture_of_gaussians():
    rng = np.random.default_rng(1)
    P, R, d = 3, 9, 2
    X = rng.normal(size=(P, R, d))
    X[1, 4] = np.nan                                   # a realisation without a value
    w = rng.uniform(0.2, 2.0, R)
    y = rng.normal(size=d)
    var = rng.uniform(0.1, 0.3, (P, d))
    got = inference.kernel_log_density(X, y, var, w)
    for p in range(P):
        ok = np.all(np.isfinite(X[p]), axis=1)
        x, ww = X[p][ok], w[ok]
        m = np.sum(ww[:, None] * x, 0) / ww.sum()
        cov = (ww[:, None, None] * np.einsum("ri,rj->rij", x - m, x - m)).sum(0) / (
            ww.sum() - np.sum(ww ** 2) / ww.sum())
        n_eff = w.sum() ** 2 / np.sum(w ** 2)
        C = ((n_eff * (d + 2)) / 4) ** (-2 / (d + 4)) * cov + np.diag(var[p])
        dens = sum(wi * multivariate_normal(xi, C).pdf(y) for wi, xi in zip(ww, x)) / w.sum()
        assert got[p] == pytest.approx(np.log(dens), rel=1e-10)


def _cloud_check(rng, shift, K=20, R=64, d=6, groups=1):
    out = []
    for _ in range(groups):
        X = rng.normal(size=(K, R, d)) * np.linspace(1, 3, d)
        y = rng.normal(size=d) * np.linspace(1, 3, d) + shift
        out.append((X, y, np.full((K, d), 0.05)))
    return modelcheck.check(out, np.ones(R), seed=int(rng.integers(1 << 30)))


def test_model_check_is_calibrated_on_data_from_the_cloud():
    """Data drawn like the realisations: each rank's p-value is uniform (median 0.5, 5 %
    below 0.05) and the combined flag fires on at most about ALPHA of them; data 6 sd
    outside are flagged every time."""
    rng = np.random.default_rng(3)
    checks = [_cloud_check(rng, 0.0, groups=1 + k % 3) for k in range(150)]
    for key in ("p_density", "p_marginal"):
        ps = np.array([getattr(c, key) for c in checks])
        assert np.median(ps) == pytest.approx(0.5, abs=0.1), key
        assert np.mean(ps < 0.05) < 0.1, key
    assert np.mean([c.flag for c in checks]) <= 0.02
    far = [_cloud_check(rng, 6.0) for _ in range(20)]
    assert all(c.flag and c.p_value < modelcheck.ALPHA for c in far)
    one = []                   # one value far out, the rest like the cloud
    for _ in range(20):
        X = rng.normal(size=(20, 64, 6))
        y = rng.normal(size=6)
        y[2] = 5.0
        one.append(modelcheck.check([(X, y, np.full((20, 6), 0.05))], np.ones(64)))
    assert np.mean([c.flag for c in one]) >= 0.9


# ---------------------------------------------------------------------------------------
# one rare-pattern series on a simulated grid
# ---------------------------------------------------------------------------------------
RARE_SPEEDS = [0.03, 0.1]


@pytest.fixture(scope="module")
def rare_case(tmp_path_factory):
    """316 joint base scene; a one-chain series of 4 rows whose gap 2-3 is 0.0014 of the
    mean (realisation 206 of seed 9001), true mean gap 100 nm, e = 0.95; a small joint
    grid (6 mean gaps to 300 nm x e 0.85, 0.925, 1 x 2 speeds x 48 realisations)."""
    base = suite.base_scene("ss316", "joint", "reference", RARE_SPEEDS)
    v = np.array([0.03, 0.05, 0.07, 0.1])
    tr = dict(set="stress", series=True, g=100e-9, e=0.95, v=v, reals=[206] * 4,
              z=np.random.default_rng(11).standard_normal((4, 3)),
              realised=[suite.patterns(15, 207)[206]] * 4)
    assert tr["realised"][0][1] < 0.002
    X = suite.truth_rows(base, tr, True, "reference")
    meas = suite.measurements(tr, X)
    grids = {}

    def grid(emphasis):
        if emphasis not in grids:
            grids[emphasis] = inference.simulate_joint_grid(base, 300e-9, 6, 0.85, 3, 48,
                                                            emphasis=emphasis)
        return grids[emphasis]
    return base, tr, meas, grid


def test_a_rare_pattern_series_is_covered_or_flagged(rare_case):
    base, tr, meas, grid = rare_case
    res = inference.infer_joint(base, meas, grid=grid(gapdesign.EMPHASIS))
    lo, hi = res.ci95_m
    covered = lo <= tr["g"] <= hi
    assert covered or "data_outside_model" in res.flags, (res.ci95_m, res.data_outside_model)
    mc = res.data_outside_model
    assert set(mc) >= {"flag", "statistic", "p_value", "alpha", "replicates"}
    assert 0.0 <= mc["p_value"] <= 1.0 and mc["flag"] == (mc["p_value"] < mc["alpha"])


@pytest.mark.slow
def test_plain_draws_miss_the_rare_series_and_the_check_says_so(rare_case):
    """Without the design (the gap law's own draws) the same series is the failure the
    design cures: the interval misses the truth, and the check flags it."""
    base, tr, meas, grid = rare_case
    res = inference.infer_joint(base, meas, grid=grid(0.0))
    lo, hi = res.ci95_m
    assert not lo <= tr["g"] <= hi
    assert "data_outside_model" in res.flags


# ---------------------------------------------------------------------------------------
# the command and the workflow
# ---------------------------------------------------------------------------------------
def test_the_likelihood_takes_the_key_contacts_heavier_prior_by_default():
    d = gapdesign.design(scene(), 32)
    assert gapdesign.KEY_PRIOR == "robust" and gapdesign.GAP_ONLY_KEY_PRIOR == "law"
    assert inference.JointGrid.key_prior == "robust" and inference.Grid.key_prior == "law"
    assert np.array_equal(gapdesign.prior_weights(d.weights, 32), np.ones(32))
    assert np.array_equal(gapdesign.prior_weights(d.weights, 32, "law"), d.weights)
    assert np.array_equal(gapdesign.prior_weights(None, 32, "law"), np.ones(32))
    assert not np.allclose(d.weights, 1.0)       # the law's weights are not trivial


def test_the_robust_prior_is_wider_in_e_than_the_law_on_the_rare_series(rare_case):
    """On a series with a near-contact beside probe 2 the law-weighted likelihood reads the
    low peak as a lower e; the heavier prior on the key contacts keeps e's interval open
    to the truth."""
    base, tr, meas, grid = rare_case
    g = grid(gapdesign.EMPHASIS)
    robust = inference.infer_joint(base, meas, grid=g)
    law = inference.infer_joint(base, meas, grid=dataclasses.replace(g, key_prior="law"))
    w = [r.restitution_ci95[1] - r.restitution_ci95[0] for r in (robust, law)]
    assert w[0] > w[1], w
    assert robust.restitution_ci95[0] <= tr["e"] <= robust.restitution_ci95[1], robust
    assert "heavier prior" in robust.gap_law and "heavier prior" not in law.gap_law


def test_fit_for_a_damped_scene_with_peaks_is_joint():
    damped = scene(effects=["hertz", "contact_damping"],
                   damping={"model": "coeff_restitution", "e": 0.9})
    assert inference.fit_for(damped, set(inference.COLUMNS)) == ("gap_mean", "restitution")
    assert inference.fit_for(damped, {"v_striker_m_s", "dt_peak_s"}) == ("gap_mean",)
    assert inference.fit_for(scene(), set(inference.COLUMNS)) == ("gap_mean",)


def test_the_workflow_rule_passes_the_fit():
    text = (REPO / "workflow" / "scripts" / "infer.py").read_text()
    assert '"--fit", fit' in text and "fit_for(" in text


def test_gap_only_json_and_summary_carry_the_check(tmp_path, capsys):
    from granchain.cli import main
    base = REPO / "measurements" / "example_synthetic.yaml"
    csv = REPO / "measurements" / "example_synthetic.csv"
    cache = tmp_path / "cache"
    assert main(["infer", str(csv), "--scene", str(base), "--gap-points", "6",
                 "--realisations", "16", "--cache-dir", str(cache), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    mc = doc["data_outside_model"]
    assert mc["flag"] is False and 0.0 < mc["p_value"] <= 1.0
    assert main(["infer", str(csv), "--scene", str(base), "--gap-points", "6",
                 "--realisations", "16", "--cache-dir", str(cache)]) == 0
    out = capsys.readouterr().out
    assert "model check: data inside the simulated realisations (p = " in out


# ---------------------------------------------------------------------------------------
# the calibration suite, CI-sized
# ---------------------------------------------------------------------------------------
@pytest.mark.slow
def test_calibration_suite_ci_sized():
    """The suite at CI size: 316, joint fit, the command's grid (21 mean gaps x 7 e) at 3
    striker speeds 0.03-0.5 m/s x 64 realisations, 16 natural and 16 stress experiments
    (series and independent chains of 3-10 rows). The full suite's measured coverage is in
    docs/explanation/inference.md; on 16 experiments a miss or two more than nominal is
    binomial noise, so this asks: natural, the mean gap and e covered in at least 13 of 16
    and the flag on at most one; stress, the mean gap and e each covered in at least 14 of
    16 or every miss flagged (the plain draws of the gap law covered the mean gap in 0.70
    of the suite's stress set, and the law-weighted design e in 0.86, unflagged)."""
    speeds = [0.03, 0.1, 0.5]
    base = suite.base_scene("ss316", "joint", "reference", speeds)
    trials = suite.make_trials(base, ["natural", "stress"], 16, (3, 10), True)
    grid = inference.simulate_joint_grid(base, 500e-9, 21, inference.E_MIN, inference.E_POINTS,
                                         64)
    res = {"natural": [], "stress": []}
    for tr in trials:
        r = inference.infer_joint(base, suite.measurements(tr, suite.truth_rows(
            base, tr, True, "reference")), grid=grid)
        res[tr["set"]].append(suite.outcome(tr, r, base.probes, True))
    nat, st = res["natural"], res["stress"]
    assert sum(o["cov_g"] for o in nat) >= 13, nat
    assert sum(o["cov_e"] for o in nat) >= 13, nat
    assert sum(o["flagged"] for o in nat) <= 1, nat
    for key in ("cov_g", "cov_e"):      # 14 of 16 is 0.875: one miss of binomial noise
        assert (sum(o[key] for o in st) >= 14
                or all(o["flagged"] for o in st if not o[key])), (key, st)
