"""Calibration of ``granchain infer`` at a larger size than tests/test_inference.py: synthetic
experiments with known mean gaps (uniform 10-200 nm), drawn from gap realisations the
likelihood's grid never saw (gap seed 9001; the grid uses the scene's seed 0), for both
materials, independent chains and one-chain series, noise off and on (0.3 us stated).
Prints the coverage of the 95 % intervals, their median width, and the median relative
error of the inferred gap and of the chapter's Eq. 5.4 reading, per case and overall.

Every truth runs on the same experiments (true mean gaps, speeds, realisation indices and
noise draws), so the truths differ only in what they change:

- ``uniform``: the base scene's own gap law, engine, integrator and Gaussian noise at the
  stated level (what the likelihood assumes: the method's own calibration);
- ``exponential``: gaps drawn from an exponential law with the same mean (the likelihood
  assumes uniform on [0, 2 mean]);
- ``noise-t3``: Student-t noise (3 degrees of freedom) with the stated standard deviation;
- ``noise-x10``: Gaussian noise at 10x the stated level (dt_err_s still 0.3 us);
- ``lammps``: timings from the LAMMPS engine, velocity Verlet at 1 ns (the grid: the
  reference engine's RK4 at the auto setting). Not in the default list: one LAMMPS run
  per experiment (~0.5 s each).

The noise truths change only the noise-on cases (their noise-off cases are the uniform
truth's), so only those are run and printed.

    python benchmarks/inference_calibration.py [--trials N] [--realisations R] [--rows M]
        [--cache-dir DIR] [--truths uniform exponential noise-t3 noise-x10 lammps]

Every number printed is measured in this run (the grid may come from the cache).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from granchain import inference
from granchain.scene import scene_from_dict

EFFECTS = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
SPEEDS = [0.03, 0.06, 0.1]
TRUTH_SEED = 9001
NOISE = 0.3e-6
TRUTHS = {   # name -> (gap law, engine, noise model or None for the stated Gaussian)
    "uniform": ("uniform", "reference", None),
    "exponential": ("exponential", "reference", None),
    "noise-t3": ("uniform", "reference", "t3"),
    "noise-x10": ("uniform", "reference", "x10"),
    "lammps": ("uniform", "lammps", None),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=50, help="per material x mode x noise")
    ap.add_argument("--realisations", type=int, default=64)
    ap.add_argument("--rows", type=int, default=3)
    ap.add_argument("--gap-max-nm", type=float, default=500.0)
    ap.add_argument("--gap-points", type=int, default=21)
    ap.add_argument("--cache-dir", default=None)
    ap.add_argument("--column", default="dt_front_s", choices=inference.TIMING_COLUMNS)
    ap.add_argument("--truths", nargs="+", default=["uniform", "exponential", "noise-t3",
                                                    "noise-x10"], choices=list(TRUTHS))
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    grids, trials = {}, []
    for material in ("ss440c", "ss316"):
        base = scene_from_dict({"name": f"cal-{material}", "material": material,
                                "striker": {"velocity": SPEEDS}, "effects": EFFECTS,
                                "gaps": {"distribution": "uniform", "mean": 50e-9},
                                "integrator": {"method": "auto", "tolerance": 1e-3}})
        t0 = time.perf_counter()
        grid = inference.simulate_grid(base, a.gap_max_nm * 1e-9, a.gap_points, a.realisations,
                                       a.cache_dir)
        print(f"{material}: grid of {grid.n_chains} chains ({grid.simulated} simulated now) "
              f"in {time.perf_counter() - t0:.1f} s; interpolation error "
              f"{inference.interp_rel_error(grid, a.column):.2e}")
        grids[material] = (base, grid)
        k = 0
        for series in (False, True):
            for noise in (False, True):
                for _ in range(a.trials):
                    g = float(rng.uniform(10e-9, 200e-9))
                    v = rng.uniform(SPEEDS[0], SPEEDS[-1], size=a.rows)
                    reals = ([k * a.rows] * a.rows if series
                             else [k * a.rows + j for j in range(a.rows)])
                    trials.append(dict(index=len(trials), material=material, series=series,
                                       noise=noise, g=g, v=v, reals=reals,
                                       z=rng.standard_normal(a.rows)))
                    k += 1
    for name in a.truths:
        law, engine, noise_model = TRUTHS[name]
        print(f"\ntruth '{name}'")
        t0 = time.perf_counter()
        allres = []
        for material in grids:
            base, grid = grids[material]
            truth = base.derive(gaps={"seed": TRUTH_SEED, "distribution": law})
            if engine == "lammps":
                truth = truth.derive(integrator={"method": "verlet", "dt": 1e-9,
                                                 "tolerance": None})
            for series in (False, True):
                for noise in (False, True):
                    if noise_model is not None and not noise:
                        continue
                    res = []
                    for tr in trials:
                        if (tr["material"], tr["series"], tr["noise"]) != (material, series,
                                                                           noise):
                            continue
                        t = inference.simulate_rows(truth, tr["g"], tr["v"], tr["reals"], a.column,
                                                    engine)
                        eps, err = _noise(tr, noise_model, a.rows)
                        meas = inference.Measurements(tr["v"], t + eps, err,
                                                      np.zeros(a.rows, int) if series
                                                      else np.arange(a.rows), a.column,
                                                      tuple(range(a.rows)), (None,) * a.rows)
                        r = inference.infer(base, meas, grid=grid)
                        lo, hi = r.ci95_m
                        g = tr["g"]
                        res.append((bool(lo <= g <= hi), hi - lo, (r.gap_mean_m - g) / g,
                                    (r.eq54_gap_m - g) / g, bool(r.flags), bool(lo > g),
                                    bool(hi < g)))
                    allres += res
                    _report(f"{material} {'series' if series else 'independent'} "
                            f"noise {'on ' if noise else 'off'}", res)
        _report("all", allres)
        print(f"({time.perf_counter() - t0:.1f} s)")


def _noise(tr, model, rows):
    """(added noise, stated dt_err_s) of a trial under the noise model."""
    if not tr["noise"]:
        return np.zeros(rows), np.zeros(rows)
    err = np.full(rows, NOISE)
    if model is None:
        return NOISE * tr["z"], err
    if model == "x10":
        return 10 * NOISE * tr["z"], err
    if model == "t3":   # unit-variance Student t: z / sqrt(chi2_3 / 3) / sqrt(3)
        chi2 = np.random.default_rng([TRUTH_SEED, tr["index"]]).chisquare(3, rows)
        return NOISE * tr["z"] / np.sqrt(chi2 / 3) / np.sqrt(3.0), err
    raise ValueError(model)


def _report(label, res) -> None:
    c = np.array([r[0] for r in res])
    w, e, q = (np.array([r[k] for r in res], float) for k in (1, 2, 3))
    print(f"{label:28s} coverage {c.mean():.3f} ({c.sum()}/{c.size}, flagged "
          f"{sum(r[4] for r in res)}; truth below {sum(r[5] for r in res)}, above "
          f"{sum(r[6] for r in res)}), median width {np.nanmedian(w) * 1e9:5.1f} nm, "
          f"median rel. error inferred {np.nanmedian(e):+.3f}, Eq. 5.4 {np.nanmedian(q):+.3f}")


if __name__ == "__main__":
    main()
