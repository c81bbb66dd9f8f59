"""Calibration of ``granchain infer --fit gap_mean,restitution``: synthetic experiments
with a known mean gap (uniform 10-200 nm) and coefficient of restitution (uniform
0.85-1), drawn from gap realisations the likelihood's grid never saw (gap seed 9001; the
grid uses the scene's seed 0), for both materials (440C, 316), independent chains and
one-chain series, at two peak-noise levels. Prints, per case and overall, the coverage of
the 95 % intervals of both parameters (each alone and both at once), their median widths,
the median relative error of the mean gap and the median error of e, the posterior
correlation and the posterior predictive check.

Every experiment: ``--rows`` rows (3) at striker speeds uniform in the grid's 0.03-0.1 m/s;
timing (``dt_front_s``) with Gaussian noise of 0.3 us (stated as ``dt_err_s``); both
peaks with Gaussian noise of ``level`` x v_s (stated as ``vmax_err_m_s``), level in
``--peak-noise`` (0.02 and 0.08: a precise vibrometer, and about the chapter's
scatter of 0.07-0.09 v_s).

Truths (the same experiments, noise draws and realisation indices in each):

- ``restitution``: the base scene's own law (contact_damping coeff_restitution at the
  true e): the method's own calibration;
- ``viscoelastic``: LAMMPS's viscoelastic damping (a law the likelihood does not use),
  eta_n0 chosen so that a head-on collision at the geometric mean of the experiment's
  striker speeds has the true e (``inference.matching_eta``); its e grows with speed
  (1 - e ~ v^(1/5)), so "the truth" for e is the e at that speed.

    python benchmarks/inference_joint_calibration.py [--trials N] [--realisations R]
        [--gap-points G] [--e-points E] [--e-min X] [--gap-max-nm NM] [--cache-dir DIR]
        [--truths restitution viscoelastic] [--peak-noise 0.02 0.08] [--materials ...]

Every number printed is measured in this run (the grids may come from the cache).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from granchain import inference
from granchain.scene import scene_from_dict

EFFECTS = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction",
           "contact_damping"]
SPEEDS = [0.03, 0.06, 0.1]
TRUTH_SEED = 9001
NOISE = 0.3e-6
COLUMN = "dt_front_s"
G_RANGE, E_RANGE = (10e-9, 200e-9), (0.85, 1.0)


def base_scene(material: str):
    return scene_from_dict({"name": f"jcal-{material}", "material": material,
                            "striker": {"velocity": SPEEDS}, "effects": EFFECTS,
                            "damping": {"model": "coeff_restitution", "e": 0.95},
                            "gaps": {"distribution": "uniform", "mean": 50e-9},
                            "integrator": {"method": "auto", "tolerance": 1e-3}})


def make_trials(materials, levels, trials: int, rows: int, seed: int = 1):
    """The experiments: dicts of material, series, peak-noise level, true g and e,
    speeds, realisation indices and the noise draws (z: rows x 3)."""
    rng = np.random.default_rng(seed)
    out = []
    for material in materials:
        k = 0
        for series in (False, True):
            for level in levels:
                for _ in range(trials):
                    g = float(rng.uniform(*G_RANGE))
                    e = float(rng.uniform(*E_RANGE))
                    v = rng.uniform(SPEEDS[0], SPEEDS[-1], size=rows)
                    reals = ([k * rows] * rows if series
                             else [k * rows + j for j in range(rows)])
                    out.append(dict(index=len(out), material=material, series=series,
                                    level=level, g=g, e=e, v=v, reals=reals,
                                    z=rng.standard_normal((rows, 3))))
                    k += 1
    return out


def truth_rows(base, tr, law: str) -> tuple[np.ndarray, float]:
    """(rows x 3 noise-free (timing, vmax_1, vmax_2), eta or NaN) of an experiment."""
    truth = base.derive(gaps={"seed": TRUTH_SEED})
    if law == "restitution":
        return inference.simulate_joint_rows(truth, tr["g"], tr["e"], tr["v"], tr["reals"],
                                             COLUMN), float("nan")
    v_ref = float(np.exp(np.mean(np.log(tr["v"]))))
    eta = inference.matching_eta(base, tr["e"], v_ref)
    truth = truth.derive(damping={"model": "viscoelastic", "eta": eta, "e": None})
    return inference.simulate_joint_rows(truth, tr["g"], None, tr["v"], tr["reals"], COLUMN), eta


def measurements(tr, X: np.ndarray) -> inference.Measurements:
    """The experiment's rows with its noise added (and stated)."""
    rows = len(tr["v"])
    err = np.full(rows, NOISE)
    perr = tr["level"] * tr["v"]
    sd = np.stack([err, perr, perr], axis=1)
    Y = X + sd * tr["z"]
    return inference.Measurements(np.asarray(tr["v"], float), Y[:, 0], err,
                                  np.zeros(rows, int) if tr["series"] else np.arange(rows), COLUMN,
                                  tuple(range(2, rows + 2)), ("A",) * rows if tr["series"]
                                  else (None,) * rows, Y[:, 1], Y[:, 2], perr)


def outcome(tr, res) -> dict:
    g, e = tr["g"], tr["e"]
    (glo, ghi), (elo, ehi) = res.ci95_m, res.restitution_ci95
    cg, ce = bool(glo <= g <= ghi), bool(elo <= e <= ehi)
    return dict(cov_g=cg, cov_e=ce, cov_both=cg and ce, width_g=ghi - glo, width_e=ehi - elo,
                rel_g=(res.gap_mean_m - g) / g, err_e=res.restitution - e,
                g_low=bool(glo > g), g_high=bool(ghi < g), e_low=bool(elo > e),
                e_high=bool(ehi < e), corr=res.posterior_correlation,
                outside=res.predictive_outside, values=res.predictive_values,
                flagged=bool(res.flags))


def report(label: str, res: list[dict]) -> str:
    def m(k):
        return np.array([r[k] for r in res], float)
    n = len(res)
    return (f"{label:34s} n={n:3d}  coverage g {m('cov_g').mean():.3f} (truth below "
            f"{int(m('g_low').sum())}, above {int(m('g_high').sum())}), e "
            f"{m('cov_e').mean():.3f} (below {int(m('e_low').sum())}, above "
            f"{int(m('e_high').sum())}), both {m('cov_both').mean():.3f}; median width g "
            f"{np.nanmedian(m('width_g')) * 1e9:5.1f} nm, e {np.nanmedian(m('width_e')):.4f}; "
            f"median rel. error g {np.nanmedian(m('rel_g')):+.3f}, error e "
            f"{np.nanmedian(m('err_e')):+.4f}; median corr {np.nanmedian(m('corr')):+.2f}; "
            f"predictive outside {int(m('outside').sum())}/{int(m('values').sum())}; "
            f"flagged {int(m('flagged').sum())}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=15,
                    help="per material x (independent, series) x peak-noise level")
    ap.add_argument("--rows", type=int, default=3)
    ap.add_argument("--realisations", type=int, default=64)
    ap.add_argument("--gap-max-nm", type=float, default=500.0)
    ap.add_argument("--gap-points", type=int, default=21)
    ap.add_argument("--e-min", type=float, default=inference.E_MIN)
    ap.add_argument("--e-points", type=int, default=inference.E_POINTS)
    ap.add_argument("--peak-noise", type=float, nargs="+", default=[0.02, 0.08])
    ap.add_argument("--materials", nargs="+", default=["ss440c", "ss316"])
    ap.add_argument("--cache-dir", default=None)
    ap.add_argument("--truths", nargs="+", default=["restitution", "viscoelastic"],
                    choices=["restitution", "viscoelastic"])
    a = ap.parse_args()
    grids = {}
    for material in a.materials:
        base = base_scene(material)
        t0 = time.perf_counter()
        grid = inference.simulate_joint_grid(base, a.gap_max_nm * 1e-9, a.gap_points, a.e_min,
                                             a.e_points, a.realisations, a.cache_dir)
        errs = inference.joint_interp_errors(grid, COLUMN)
        print(f"{material}: grid of {grid.n_chains} chains ({grid.simulated} simulated now) "
              f"in {time.perf_counter() - t0:.1f} s; interpolation error (largest over the "
              "gaps / e / speed): " + ", ".join(
                  f"{k} {np.max(v['g']):.1e}/{v['e']:.1e}/{v['speed']:.1e}"
                  for k, v in errs.items()))
        grids[material] = (base, grid)
    trials = make_trials(a.materials, a.peak_noise, a.trials, a.rows)
    for law in a.truths:
        print(f"\ntruth '{law}'")
        t0 = time.perf_counter()
        allres, t_inf = [], 0.0
        etas = []
        for material in a.materials:
            base, grid = grids[material]
            for series in (False, True):
                for level in a.peak_noise:
                    res = []
                    for tr in trials:
                        if (tr["material"], tr["series"], tr["level"]) != (material, series,
                                                                           level):
                            continue
                        X, eta = truth_rows(base, tr, law)
                        etas.append(eta)
                        t1 = time.perf_counter()
                        r = inference.infer_joint(base, measurements(tr, X), grid=grid)
                        t_inf += time.perf_counter() - t1
                        res.append(outcome(tr, r))
                    allres += res
                    print(report(f"{material} {'series' if series else 'independent'} "
                                 f"peaks {level:g} v_s", res))
        for level in a.peak_noise:
            print(report(f"all, peaks {level:g} v_s", [r for r, tr in zip(allres, trials)
                                                       if tr["level"] == level]))
        print(report("all", allres))
        if law == "viscoelastic":
            print(f"eta_n0 {np.nanmin(etas):.3g} to {np.nanmax(etas):.3g} 1/(m s)")
        print(f"({time.perf_counter() - t0:.1f} s; inference {t_inf / len(allres):.2f} s "
              "per experiment)")


if __name__ == "__main__":
    main()
