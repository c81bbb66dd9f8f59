"""granchain infer: calibration of the inferred mean gap on synthetic experiments with
known gaps (drawn from realisations the likelihood's grid never saw), the bias of the
chapter's Eq. 5.4 reading, the cache, and one-line errors for bad measurement files."""
from __future__ import annotations

import json

import numpy as np
import pytest

from granchain import inference as I
from granchain.cli import main
from granchain.scene import scene_from_dict

from conftest import REPO

EFFECTS = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
SPEEDS = [0.03, 0.06, 0.1]
GAP_MAX, GAP_POINTS, REALISATIONS = 500e-9, 21, 64
TRUTH_SEED = 9001                  # the grid draws with seed 0
NOISE = 0.3e-6


def base_scene(material):
    return scene_from_dict({"name": f"cal-{material}", "material": material,
                            "striker": {"velocity": SPEEDS}, "effects": EFFECTS,
                            "gaps": {"distribution": "uniform", "mean": 50e-9},
                            "integrator": {"method": "auto", "tolerance": 1e-3}})


@pytest.fixture(scope="module")
def grids(tmp_path_factory):
    cache = tmp_path_factory.mktemp("infer-cache")
    return {m: (base_scene(m), I.simulate_grid(base_scene(m), GAP_MAX, GAP_POINTS,
                                               REALISATIONS, cache))
            for m in ("ss440c", "ss316")}


def synthetic(base, rng, trial, series, noise, rows=3, column="dt_front_s"):
    """A synthetic experiment: (true mean gap, Measurements)."""
    g = float(rng.uniform(10e-9, 200e-9))
    v = rng.uniform(SPEEDS[0], SPEEDS[-1], size=rows)
    reals = [trial * rows] * rows if series else [trial * rows + k for k in range(rows)]
    t = I.simulate_rows(base.derive(gaps={"seed": TRUTH_SEED}), g, v, reals, column)
    err = np.full(rows, NOISE if noise else 0.0)
    t = t + err * rng.standard_normal(rows)
    group = np.zeros(rows, int) if series else np.arange(rows)
    return g, I.Measurements(v, t, err, group, column, tuple(range(2, rows + 2)),
                             ("A",) * rows if series else (None,) * rows)


def test_intervals_cover_the_true_gap(grids):
    """112 synthetic experiments: 440C and 316, independent chains and one-chain series,
    noise on and off, true mean gaps 10-200 nm; the 95 % intervals must cover the truth
    in 90-99 % of them. Also reports the interval widths and the Eq. 5.4 reading's bias,
    which must be an overestimate (Eq. 5.4 lets particles cross gaps at v_s)."""
    rng = np.random.default_rng(20240)
    results = []
    trial = 0
    for material, (base, grid) in grids.items():
        for series in (False, True):
            for noise in (False, True):
                for _ in range(14):
                    g, meas = synthetic(base, rng, trial, series, noise)
                    trial += 1
                    res = I.infer(base, meas, grid=grid)
                    lo, hi = res.ci95_m      # a flagged interval (NaN) counts as a miss
                    results.append((material, series, noise, g, bool(lo <= g <= hi), hi - lo,
                                    res.gap_mean_m, res.eq54_gap_m))
    covered = np.mean([r[4] for r in results])
    width = np.nanmedian([r[5] / r[3] for r in results])
    eq54_rel = np.array([(r[7] - r[3]) / r[3] for r in results])
    post_rel = np.array([(r[6] - r[3]) / r[3] for r in results])
    post_rel = post_rel[np.isfinite(post_rel)]
    print(f"\ncoverage {covered:.3f} of {len(results)}; median 95% width / truth {width:.2f}; "
          f"median relative error: inferred {np.median(post_rel):+.3f}, "
          f"Eq. 5.4 {np.median(eq54_rel):+.3f} (mean {np.mean(eq54_rel):+.3f})")
    for series in (False, True):
        sel = [r for r in results if r[1] == series]
        print(f"  {'series' if series else 'independent'}: coverage "
              f"{np.mean([r[4] for r in sel]):.3f}, median width "
              f"{np.nanmedian([r[5] for r in sel]) * 1e9:.1f} nm")
    assert len(results) >= 100
    assert 0.90 <= covered <= 0.99
    # Eq. 5.4 bounds v_g from above, so it reads a longer delay as a larger gap: biased up
    assert np.median(eq54_rel) > 0
    # and the inference is less biased than the chapter's reading
    assert abs(np.median(post_rel)) < abs(np.median(eq54_rel))


def test_a_chain_series_is_not_treated_as_independent_rows(grids):
    """Rows of one chain share a realisation: given as independent chains, the same
    timings would claim more evidence (a narrower interval) than they carry."""
    base, grid = grids["ss440c"]
    g, meas = synthetic(base, np.random.default_rng(3), 500, True, False, rows=4)
    as_chain = I.infer(base, meas, grid=grid)
    apart = I.infer(base, I.Measurements(meas.v, meas.t, meas.err, np.arange(4), meas.column,
                                         meas.lines, (None,) * 4), grid=grid)
    w_chain = as_chain.ci95_m[1] - as_chain.ci95_m[0]
    w_apart = apart.ci95_m[1] - apart.ci95_m[0]
    assert w_apart < 0.8 * w_chain


def test_more_data_narrows_the_interval_and_noise_widens_it(grids):
    base, grid = grids["ss316"]
    rng = np.random.default_rng(11)
    g, few = synthetic(base, rng, 600, False, False, rows=2)
    widths = {}
    for rows in (2, 12):
        _, meas = synthetic(base, np.random.default_rng(11), 600, False, False, rows=rows)
        r = I.infer(base, meas, grid=grid)
        widths[rows] = r.ci95_m[1] - r.ci95_m[0]
    assert widths[12] < 0.6 * widths[2]
    _, meas = synthetic(base, np.random.default_rng(11), 600, False, False, rows=12)
    noisy = I.Measurements(meas.v, meas.t, np.full(12, 5e-6), meas.group, meas.column,
                           meas.lines, meas.chain_ids)
    r = I.infer(base, noisy, grid=grid)
    assert r.ci95_m[1] - r.ci95_m[0] > 1.3 * widths[12]


def test_a_gap_beyond_the_grid_is_flagged_not_reported(grids):
    base, grid = grids["ss440c"]
    small = I.Grid(grid.gaps[:5], grid.speeds, {c: a[:5] for c, a in grid.timings.items()},
                   grid.hashes[:5], 0)                    # simulated up to 100 nm only
    _, meas = synthetic(base, np.random.default_rng(5), 700, False, False)
    meas = I.Measurements(meas.v, I.simulate_rows(base.derive(gaps={"seed": TRUTH_SEED}),
                                                  180e-9, meas.v, [1, 2, 3], meas.column),
                          meas.err, meas.group, meas.column, meas.lines, meas.chain_ids)
    res = I.infer(base, meas, grid=small)
    assert "posterior_at_grid_end" in res.flags
    assert np.isnan(res.gap_mean_m) and np.isnan(res.ci95_m[1])


def test_the_grid_is_cached_by_scene_hash(grids, tmp_path):
    base = base_scene("ss440c").derive(striker={"velocity": [0.05]})
    a = I.simulate_grid(base, 40e-9, 3, 2, tmp_path)
    files = sorted(p.name for p in tmp_path.iterdir())
    assert a.simulated == 6 and len(files) == 3 and all(h in " ".join(files) for h in a.hashes)
    b = I.simulate_grid(base, 40e-9, 3, 2, tmp_path)
    assert b.simulated == 0
    np.testing.assert_array_equal(a.timings["dt_peak_s"], b.timings["dt_peak_s"])
    c = I.simulate_grid(base.derive(material="ss316"), 40e-9, 3, 2, tmp_path)
    assert c.simulated == 6          # another scene, another key


# ---------------------------------------------------------------------------------------
# the command line
# ---------------------------------------------------------------------------------------
SCENE = """name: small
material: ss440c
striker: {velocity: [0.04, 0.06]}
gaps: {distribution: uniform, mean: 20.0e-9}
integrator: {method: auto, tolerance: 1.0e-3}
"""


def refused(capsys, argv, *needles):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


@pytest.mark.parametrize("text, needles", [
    ("", ["empty"]),
    ("# only a comment\n", ["empty"]),
    ("dt_peak_s\n1e-5\n", ["'v_striker_m_s'", "missing"]),
    ("v_striker_m_s\n0.05\n", ["'dt_peak_s'", "missing"]),
    ("v_striker_m_s,dt_peak_s\n", ["no data rows"]),
    ("v_striker_m_s,dt_peak_s,dt_front_s\n0.05,1e-5,1e-5\n", ["'dt_front_s'"]),
    ("v_striker_m_s,dt_peak\n0.05,1e-5\n", ["'dt_peak'", "did you mean 'dt_peak_s'"]),
    ("v_striker_m_s,dt_peak_s\n0.05,1e-5\n0.05,-2e-6\n", ["row 2 (line 3)", "'dt_peak_s'",
                                                         "non-positive"]),
    ("v_striker_m_s,dt_peak_s\n0.05,0\n", ["row 1", "non-positive"]),
    ("v_striker_m_s,dt_front_s\n0.05,abc\n", ["row 1", "'dt_front_s'", "not a number"]),
    ("v_striker_m_s,dt_front_s\nNaN,1e-5\n", ["row 1", "'v_striker_m_s'", "not a finite"]),
    ("v_striker_m_s,dt_front_s\n0.05,inf\n", ["'dt_front_s'", "not a finite"]),
    ("v_striker_m_s,dt_front_s,dt_err_s\n0.05,1e-5,-1e-7\n", ["'dt_err_s'", "negative"]),
    ("v_striker_m_s,dt_front_s\n0.05\n", ["row 1", "cells"]),
    ("v_striker_m_s,dt_front_s\n-0.05,1e-5\n", ["'v_striker_m_s'", "not > 0"]),
    ("# comment\nv_striker_m_s,dt_front_s\n0.05,1e-5\n0.5,1e-5\n",
     ["row 2 (line 4)", "'v_striker_m_s'", "outside the simulated striker speeds",
      "striker.velocity"]),
])
def test_bad_measurements_are_one_line(tmp_path, capsys, text, needles):
    csv_path = tmp_path / "m.csv"
    csv_path.write_text(text)
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    refused(capsys, ["infer", str(csv_path), "--scene", str(scene), "--gap-points", "3",
                     "--realisations", "2", "--gap-max-nm", "40",
                     "--cache-dir", str(tmp_path / "c")], *needles)


def test_bad_base_scene_and_options_are_one_line(tmp_path, capsys):
    csv_path = tmp_path / "m.csv"
    csv_path.write_text("v_striker_m_s,dt_front_s\n0.05,1e-5\n")
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE.replace("uniform, mean: 20.0e-9", "none"))
    refused(capsys, ["infer", str(csv_path), "--scene", str(scene)], "gaps.distribution")
    scene.write_text(SCENE)
    refused(capsys, ["infer", str(tmp_path / "nope.csv"), "--scene", str(scene)], "nope.csv")
    refused(capsys, ["infer", str(csv_path), "--scene", str(scene), "--plot",
                     str(tmp_path / "x.txt")], "--plot")
    (tmp_path / "x.png").write_text("keep")
    refused(capsys, ["infer", str(csv_path), "--scene", str(scene), "--plot",
                     str(tmp_path / "x.png")], "--plot", "exists")
    assert (tmp_path / "x.png").read_text() == "keep"


def test_infer_command_json_and_plot(tmp_path, capsys):
    """The command on a small grid: JSON keys, the plot written, the cache reused."""
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    base = scene_from_dict({**__import__("yaml").safe_load(SCENE)})
    t = I.simulate_rows(base.derive(gaps={"seed": 5}), 20e-9, [0.045, 0.055], [0, 0],
                        "dt_peak_s")
    csv_path = tmp_path / "m.csv"
    csv_path.write_text("v_striker_m_s,dt_peak_s,chain_id\n"
                        f"0.045,{float(t[0])!r},a\n0.055,{float(t[1])!r},a\n")
    argv = ["infer", str(csv_path), "--scene", str(scene), "--gap-points", "5",
            "--gap-max-nm", "80", "--realisations", "8", "--cache-dir", str(tmp_path / "c"),
            "--json"]
    assert main(argv + ["--plot", str(tmp_path / "f.png")]) == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("gap_mean_m", "ci95_m", "eq54_gap_m", "n_simulated", "gap_law",
                "timing_column"):
        assert key in doc
    assert doc["n_simulated"] == 5 * 2 * 8 and doc["n_simulated_now"] == 80
    assert doc["timing_column"] == "dt_peak_s" and doc["chains"] == 1
    assert (tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"
    assert main(argv) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["n_simulated_now"] == 0 and again["gap_mean_m"] == doc["gap_mean_m"]


def test_shipped_example_is_labelled_synthetic(repo):
    text = (repo / "measurements" / "example_synthetic.csv").read_text()
    assert text.startswith("# SYNTHETIC")
    meas = I.read_measurements(repo / "measurements" / "example_synthetic.csv")
    assert len(meas) == 8 and len(meas.groups) == 5
