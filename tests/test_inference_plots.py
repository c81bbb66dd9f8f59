"""What ``granchain infer --plot`` draws, read back from the figure: the measured points
from the measurement rows, the packed chain against the independent Hertz chain
(tests/independent.py), Eq. 5.4 from its formula, the posterior's lines and bands from
the result, and the physics the bands must show.

Grids: a gap-only one of a Hertz-only 440C chain (4 mean gaps to 150 nm x 0.03, 0.09 m/s x
6 realisations, the auto integrator at 1e-3) and a joint one with contact damping (3 mean
gaps x e 0.85, 1 x 0.04, 0.08 m/s x 6 realisations): about a second each.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from granchain import inference
from granchain.figures import inference as figs
from granchain.scene import scene_from_dict

sys.path.insert(0, str(Path(__file__).parent))
from independent import SS440C, hertz_chain_peaks  # noqa: E402

SPAN, TWO_R = 11, 300e-6                 # probes 2 and 13; 150 um spheres
TRUTH_SEED = 9001                        # the grids draw with seed 0


def drawn(monkeypatch, plot, *args, path):
    """Call ``plot(*args, path)``; return the matplotlib Figure it drew."""
    got, real = [], figs.figure
    monkeypatch.setattr(figs, "figure", lambda *a, **k: got.append(real(*a, **k)) or got[-1])
    plot(*args, path)
    assert len(got) == 1 and path.stat().st_size > 0
    return got[0][0]


def line(ax, label):
    found = [ln for ln in ax.get_lines() if ln.get_label() == label]
    assert len(found) == 1, (label, [ln.get_label() for ln in ax.get_lines()])
    return found[0].get_xydata()


def errorbar(ax):
    """(x, y, yerr) of the axes' one errorbar plot."""
    (bars,) = ax.containers
    data, _, (segments,) = bars
    xy = data.get_xydata()
    seg = np.array(segments.get_segments())              # (points, 2 ends, (x, y))
    np.testing.assert_allclose(seg[:, 0, 0], xy[:, 0], rtol=1e-15)
    np.testing.assert_allclose(seg.mean(axis=1)[:, 1], xy[:, 1], rtol=1e-12)
    return xy[:, 0], xy[:, 1], 0.5 * (seg[:, 1, 1] - seg[:, 0, 1])


def band(ax):
    """(x, lo, hi) of the axes' one fill_between band."""
    (coll,) = [c for c in ax.collections if type(c).__name__ in ("PolyCollection",
                                                                  "FillBetweenPolyCollection")]
    verts = coll.get_paths()[0].vertices
    xs = np.unique(verts[:, 0])
    lo = np.array([verts[verts[:, 0] == x, 1].min() for x in xs])
    hi = np.array([verts[verts[:, 0] == x, 1].max() for x in xs])
    return xs, lo, hi


# ---------------------------------------------------------------------------------------
# the gap-only fit
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def gap_fit():
    base = scene_from_dict({"name": "plot-gaps", "material": "ss440c", "effects": ["hertz"],
                            "striker": {"velocity": [0.03, 0.09]},
                            "gaps": {"distribution": "uniform", "mean": 50e-9},
                            "integrator": {"method": "auto", "tolerance": 1e-3}})
    grid = inference.simulate_grid(base, 150e-9, 4, 6)
    v = np.array([0.035, 0.05, 0.07, 0.085])
    t = inference.simulate_rows(base.derive(gaps={"seed": TRUTH_SEED}), 45e-9, v, [0, 1, 2, 3],
                                "dt_peak_s")
    err = np.full(4, 0.2e-6)
    meas = inference.Measurements(v, t + err * np.array([0.5, -1.0, 0.3, 1.2]), err,
                                  np.arange(4), "dt_peak_s", (2, 3, 4, 5), (None,) * 4)
    return base, meas, inference.infer(base, meas, grid=grid)


def packed_vg(v):
    """v_g of the packed Hertz chain from the peak times at probes 2 and 13 (independent
    solution at 0.03 m/s; a packed Hertz chain's times scale exactly as v_s^(-1/5))."""
    ind = hertz_chain_peaks(*SS440C, 150e-6, 15, 0.03, probes=(2, 13))
    dt = (ind.t_peak[1] - ind.t_peak[0]) * (np.asarray(v) / 0.03) ** -0.2
    return SPAN * TWO_R / dt


def test_the_gap_plot_draws_the_data_the_packed_chain_and_eq54(gap_fit, monkeypatch,
                                                               tmp_path):
    """Measured points: v_g = 11 (2R + g)/dt at the inferred median g, with dt_err
    carried through; the packed chain against the independent Hertz chain (measured
    1.1e-4 to 1.8e-4 apart: the auto integrator at 1e-3; a 1 % error in the Hertz constant
    gives 0.4 %); Eq. 5.4 at its fitted gap from that packed chain; the simulated band
    around its median and below the packed chain (the gaps slow the wave)."""
    base, meas, res = gap_fit
    assert not res.flags and 20e-9 < res.gap_mean_m < 150e-9
    fig = drawn(monkeypatch, figs.plot_inference, res, meas, base, path=tmp_path / "f.png")
    (ax,) = fig.axes
    g = res.gap_mean_m
    x, y, yerr = errorbar(ax)
    np.testing.assert_allclose(x, meas.v, rtol=1e-15)
    np.testing.assert_allclose(y, SPAN * (TWO_R + g) / meas.t, rtol=1e-12)
    np.testing.assert_allclose(yerr, SPAN * (TWO_R + g) * meas.err / meas.t ** 2, rtol=1e-9)
    packed = line(ax, "packed chain (gap = 0)")
    np.testing.assert_allclose(packed[[0, -1], 0], [0.03, 0.09], rtol=1e-12)
    assert len(packed) == 40 and np.all(np.diff(np.log(packed[:, 0])) > 0)
    np.testing.assert_allclose(packed[:, 1], packed_vg(packed[:, 0]), rtol=5e-4)
    (eq54,) = [ln.get_xydata() for ln in ax.get_lines() if ln.get_label().startswith("Eq. 5.4")]
    g54, v = res.eq54_gap_m, eq54[:, 0]
    assert 0 < g54 < 200e-9
    np.testing.assert_allclose(eq54[:, 1], (TWO_R + g54) / (TWO_R / packed_vg(v) + g54 / v),
                               rtol=5e-4)
    med = line(ax, "simulated median")
    xs, lo, hi = band(ax)
    np.testing.assert_allclose(xs, med[:, 0], rtol=1e-12)
    assert np.all(lo <= med[:, 1]) and np.all(med[:, 1] <= hi) and np.all(lo < hi)
    assert np.all(hi < packed_vg(xs))
    # v_g grows with the striker speed, packed and gapped
    assert np.all(np.diff(packed[:, 1]) > 0) and np.all(np.diff(med[:, 1]) > 0)
    lo_ci, hi_ci = (x * 1e9 for x in res.ci95_m)
    assert (f"inferred mean gap {g * 1e9:.1f} nm, 95 % [{lo_ci:.1f}, {hi_ci:.1f}] nm"
            in ax.get_title())


# ---------------------------------------------------------------------------------------
# the joint fit
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def joint_fit():
    base = scene_from_dict({"name": "plot-joint", "material": "ss440c",
                            "effects": ["hertz", "contact_damping"],
                            "damping": {"model": "coeff_restitution", "e": 0.95},
                            "striker": {"velocity": [0.04, 0.08]},
                            "gaps": {"distribution": "uniform", "mean": 50e-9},
                            "integrator": {"method": "auto", "tolerance": 1e-3}})
    grid = inference.simulate_joint_grid(base, 90e-9, 3, 0.85, 2, 6)
    v = np.array([0.045, 0.06, 0.075])
    X = inference.simulate_joint_rows(base.derive(gaps={"seed": TRUTH_SEED}), 40e-9, 0.92, v,
                                      [0, 1, 2], "dt_front_s")
    perr = 0.02 * v
    meas = inference.Measurements(v, X[:, 0], np.full(3, 0.3e-6), np.arange(3), "dt_front_s",
                                  (2, 3, 4), (None,) * 3, X[:, 1], X[:, 2], perr)
    return base, meas, inference.infer_joint(base, meas, grid=grid)


def test_the_joint_plot_draws_the_data_the_posterior_and_its_bands(joint_fit, monkeypatch,
                                                                   tmp_path):
    """The rows (timing in us, both peaks over v_s, with their errors); each marginal a
    density (integral 1) with its median and 95 % interval drawn where the result puts
    them, the joint posterior scaled to its peak; the simulated bands: the timing falls as
    the striker speeds up, and the damped wave's peak falls along the chain, below the
    striker's speed."""
    base, meas, res = joint_fit
    assert not res.flags
    fig = drawn(monkeypatch, figs.plot_joint_inference, res, meas, base,
                path=tmp_path / "j.png")
    a_joint, a_g, a_e, a_t, a_v1, a_v2 = fig.axes[:6]
    for ax, y, err in ((a_t, meas.t * 1e6, meas.err * 1e6),
                       (a_v1, meas.vmax_1 / meas.v, meas.vmax_err / meas.v),
                       (a_v2, meas.vmax_2 / meas.v, meas.vmax_err / meas.v)):
        x, yy, ee = errorbar(ax)
        np.testing.assert_allclose(x, meas.v, rtol=1e-15)
        np.testing.assert_allclose(yy, y, rtol=1e-12)
        np.testing.assert_allclose(ee, err, rtol=1e-9)
    g_nm = line(a_g, "_child0")      # the marginal: the axes' first, unlabelled line
    assert np.trapezoid(g_nm[:, 1], g_nm[:, 0]) == pytest.approx(1.0, rel=1e-6)
    e_pdf = a_e.get_lines()[0].get_xydata()
    assert np.trapezoid(e_pdf[:, 1], e_pdf[:, 0]) == pytest.approx(1.0, rel=1e-6)
    for ax, med, (lo, hi) in ((a_g, res.gap_mean_m * 1e9, [x * 1e9 for x in res.ci95_m]),
                              (a_e, res.restitution, res.restitution_ci95)):
        assert line(ax, "median")[0, 0] == pytest.approx(med, rel=1e-12)
        (span,) = [p for p in ax.patches if p.get_label() == "95 % interval"]
        box = span.get_path().transformed(span.get_patch_transform()).vertices[:, 0]
        assert (box.min(), box.max()) == pytest.approx((lo, hi), rel=1e-12)
        assert lo < med < hi
    assert line(a_joint, "posterior medians").tolist() == [[res.gap_mean_m * 1e9,
                                                            res.restitution]]
    (mesh,) = [c for c in a_joint.collections if type(c).__name__ == "QuadMesh"]
    assert mesh.get_array().max() == pytest.approx(1.0, rel=1e-12)
    bands = {}
    for name, ax in (("t", a_t), ("v1", a_v1), ("v2", a_v2)):
        med = line(ax, "simulated median")
        xs, lo, hi = band(ax)
        np.testing.assert_allclose(xs, med[:, 0], rtol=1e-12)
        assert np.all(lo <= med[:, 1]) and np.all(med[:, 1] <= hi)
        bands[name] = med[:, 1]
    assert np.all(np.diff(bands["t"]) < 0)
    assert np.all(bands["v2"] < bands["v1"]) and np.all(bands["v1"] < 1.0)
    assert np.all(bands["v2"] > 0.3)
    assert (f"predictive check: {res.predictive_outside} of {res.predictive_values} values"
            in a_v2.get_title())
