"""Calibration of ``granchain infer --fit gap_mean,KEY`` for a fittable scene key
(``--key``: ``damping.e``, the restitution, by default; ``plasticity.yield_pressure``;
``adhesion.surface_energy``): synthetic experiments with a known mean gap (uniform
10-200 nm) and a known value of the key (drawn from the fit's prior over the key's
calibrated range, below), drawn from gap realisations the likelihood's grid never saw
(gap seed 9001; the grid uses the scene's seed 0), independent chains and one-chain
series, at the stated peak-noise levels. Prints, per case and overall, the coverage of the
95 % intervals of both parameters (each alone and both at once), their median widths, the
median relative error of the mean gap and the median error of the key (relative, for a
key with a log-uniform prior), the posterior correlation and the posterior predictive
check; and each coverage's binomial 95 % range (Wilson) for the number of experiments.

Every experiment: ``--rows`` rows (3) at striker speeds uniform between the base scene's
smallest and largest; timing (``dt_front_s``) with Gaussian noise of 0.3 us (stated as
``dt_err_s``); both peaks with Gaussian noise of ``level`` x v_s (stated as
``vmax_err_m_s``), level in ``--peak-noise`` (0.02 and 0.08: a precise vibrometer, and
about the chapter's scatter of 0.07-0.09 v_s). ``--noise-scale S`` states S x the noise
actually drawn (S < 1: the likelihood's noise understated, for a calibration that must
fail).

The keys' base scenes and ranges (``CASES``), chosen where the key shapes the data:

- ``damping.e``: 440C and 316, 0.03-0.1 m/s, ``contact_damping`` coeff_restitution; e
  uniform on 0.85-1, the grid's range ``--e-min`` to 1.
- ``plasticity.yield_pressure``: 316 (annealed: its library p_y 4.64e8 Pa yields above
  3.6 mm/s), 0.03-0.1 m/s, ``plastic_contact`` thornton (without particle_friction, which
  the plastic law does not take); p_y log-uniform on 1e8-1.5e9 Pa, the grid's range too
  (by Thornton's yield velocity two 316 spheres stay elastic up to 0.1 m/s for p_y above
  about 1.75e9 Pa: there the data could say no more than "elastic at these speeds").
- ``adhesion.surface_energy``: 440C chains of 8 spheres (probes 2 and 7) at 6-12 mm/s,
  ``adhesion`` jkr; gamma log-uniform on 0.05-0.5 J/m^2, the grid's range too (at 6 mm/s
  gamma = 0.02 J/m^2 changes v_max,1 by 0.04 % of v_s and 0.08 J/m^2 by 0.7 %: with 2 %
  peak noise the fit gives an upper bound below about 0.1 J/m^2, and with 8 % it does
  not tell gamma on this range).

A posterior at an end of the key's grid (flagged, that side NaN) still gives a one-sided
bound: the report counts how often it holds the truth, and the coverage of the reported
range (the interval, or that bound); experiments where no wave reached a probe are not
measured, so not fitted, and are counted apart.

Truths (the same experiments, noise draws and realisation indices in each):

- ``own``: the base scene's own law at the true value: the method's own calibration
  (``restitution`` is its name for damping.e);
- ``viscoelastic`` (damping.e, plasticity.yield_pressure): LAMMPS's viscoelastic damping,
  a law the likelihood does not use. For damping.e it replaces the law, eta_n0 chosen so
  that a head-on collision at the geometric mean of the experiment's striker speeds has
  the true e (``inference.matching_eta``; 1 - e ~ v^(1/5), so "the truth" for e is the e
  at that speed). For the limiting pressure it is added beside Thornton's law, eta_n0
  giving e = ``VISCO_E`` at ``VISCO_V`` (a loss the fit can only read as a lower p_y);
- ``dmt`` (adhesion.surface_energy): the same gamma in the DMT law (the other adhesion
  law: no contact hysteresis, pull-off 4 pi gamma R* instead of JKR's 3 pi gamma R*).

    python benchmarks/inference_joint_calibration.py [--key KEY] [--trials N]
        [--realisations R] [--gap-points G] [--e-min X] [--e-points E] [--gap-max-nm NM]
        [--cache-dir DIR] [--truths own viscoelastic dmt] [--peak-noise 0.02 0.08]
        [--materials ...] [--noise-scale S]

Every number printed is measured in this run (the grids may come from the cache).
"""
from __future__ import annotations

import argparse
import math
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
VISCO_E, VISCO_V = 0.95, 0.05     # the viscoelastic loss added to a plastic truth
# per key: the materials, the base scene's extra keys, its speeds, the truths' range
# (also the grid's, except damping.e's: --e-min to 1), the grid's points, its truths
CASES = {
    "damping.e": dict(
        materials=["ss440c", "ss316"], speeds=SPEEDS, range=E_RANGE, points=None,
        truths=["restitution", "viscoelastic"],
        scene={"effects": EFFECTS, "damping": {"model": "coeff_restitution", "e": 0.95}}),
    "plasticity.yield_pressure": dict(
        materials=["ss316"], speeds=SPEEDS, range=(1e8, 1.5e9), points=6,
        truths=["own", "viscoelastic"],
        scene={"effects": ["hertz", "groove_friction", "air_drag", "rotation",
                           "plastic_contact"],
               "plasticity": {"model": "thornton", "yield_pressure": 1e9}}),
    "adhesion.surface_energy": dict(
        materials=["ss440c"], speeds=[0.006, 0.009, 0.012], range=(0.05, 0.5), points=6,
        truths=["own", "dmt"],
        scene={"chain": {"n": 8}, "probes": [2, 7], "effects": ["hertz", "adhesion"],
               "adhesion": {"model": "jkr", "surface_energy": 0.5}}),
}


def base_scene(material: str, key: str = "damping.e"):
    case = CASES[key]
    return scene_from_dict({"name": f"jcal-{material}", "material": material,
                            "striker": {"velocity": case["speeds"]},
                            "gaps": {"distribution": "uniform", "mean": 50e-9},
                            "integrator": {"method": "auto", "tolerance": 1e-3},
                            **case["scene"]})


def make_trials(materials, levels, trials: int, rows: int, seed: int = 1,
                key: str = "damping.e"):
    """The experiments: dicts of material, series, peak-noise level, true g and e (the
    key's value: uniform on the case's range, or log-uniform for a log-uniform prior),
    speeds, realisation indices and the noise draws (z: rows x 3)."""
    rng = np.random.default_rng(seed)
    fk, case = inference.fit_key(key), CASES[key]
    lo, hi = fk.coord(case["range"])
    speeds = case["speeds"]
    out = []
    for material in materials:
        k = 0
        for series in (False, True):
            for level in levels:
                for _ in range(trials):
                    g = float(rng.uniform(*G_RANGE))
                    e = float(fk.value(rng.uniform(lo, hi)))
                    v = rng.uniform(speeds[0], speeds[-1], size=rows)
                    reals = ([k * rows] * rows if series
                             else [k * rows + j for j in range(rows)])
                    out.append(dict(index=len(out), material=material, series=series,
                                    level=level, g=g, e=e, v=v, reals=reals,
                                    z=rng.standard_normal((rows, 3))))
                    k += 1
    return out


def truth_rows(base, tr, law: str, key: str = "damping.e") -> tuple[np.ndarray, float]:
    """(rows x 3 noise-free (timing, vmax_1, vmax_2), eta or NaN) of an experiment."""
    truth = base.derive(gaps={"seed": TRUTH_SEED})
    if law in ("restitution", "own"):
        return inference.simulate_joint_rows(truth, tr["g"], tr["e"], tr["v"], tr["reals"],
                                             COLUMN, key=key), float("nan")
    if law == "dmt":
        truth = truth.derive(adhesion={"model": "dmt"})
        return inference.simulate_joint_rows(truth, tr["g"], tr["e"], tr["v"], tr["reals"],
                                             COLUMN, key=key), float("nan")
    if key == "damping.e":
        v_ref = float(np.exp(np.mean(np.log(tr["v"]))))
        eta = inference.matching_eta(base, tr["e"], v_ref)
        truth = truth.derive(damping={"model": "viscoelastic", "eta": eta, "e": None})
        return inference.simulate_joint_rows(truth, tr["g"], None, tr["v"], tr["reals"],
                                             COLUMN), eta
    eta = visco_eta(base)
    truth = truth.derive(effects=sorted(base.effects) + ["contact_damping"],
                         damping={"model": "viscoelastic", "eta": eta})
    return inference.simulate_joint_rows(truth, tr["g"], tr["e"], tr["v"], tr["reals"],
                                         COLUMN, key=key), eta


_ETA: dict = {}


def visco_eta(base) -> float:
    """eta_n0 of the viscoelastic loss added to a plastic truth (e = VISCO_E at VISCO_V)."""
    name = base.material.name
    if name not in _ETA:
        _ETA[name] = inference.matching_eta(base, VISCO_E, VISCO_V)
    return _ETA[name]


def measurements(tr, X: np.ndarray, scale: float = 1.0) -> inference.Measurements:
    """The experiment's rows with its noise added, stated as ``scale`` x the noise drawn."""
    rows = len(tr["v"])
    err = np.full(rows, NOISE)
    perr = tr["level"] * tr["v"]
    sd = np.stack([err, perr, perr], axis=1)
    Y = X + sd * tr["z"]
    return inference.Measurements(np.asarray(tr["v"], float), Y[:, 0], scale * err,
                                  np.zeros(rows, int) if tr["series"] else np.arange(rows), COLUMN,
                                  tuple(range(2, rows + 2)), ("A",) * rows if tr["series"]
                                  else (None,) * rows, Y[:, 1], Y[:, 2], scale * perr)


def outcome(tr, res, log: bool = False) -> dict:
    """One experiment's outcome (a flagged, NaN bound is a miss); the key's error is
    relative (value / truth - 1) for a key with a log-uniform prior (``log``), absolute
    otherwise. ``at_end``: the key's posterior at an end of its grid (flagged), ``bound_e``:
    and its one-sided bound (the other end of the interval) holds the truth; ``rep_e``:
    the reported range (interval or that bound) holds it; ``no_range``: weight at both
    ends, no range reported; ``rep_g``: the mean gap's reported range (its interval, or
    its lower bound when flagged at the grid's top) holds the truth."""
    g, e = tr["g"], tr["e"]
    (glo, ghi), (elo, ehi) = res.ci95_m, res.param_ci95
    # weight at an end of the key's grid that is no bound of the key: a flag, that side of
    # the interval NaN; the other side a one-sided bound
    end = f"{res.fit[1]}_at_grid_end" in res.flags
    cg, ce = bool(glo <= g <= ghi), bool(elo <= e <= ehi)
    out = dict(cov_g=cg, cov_e=ce, cov_both=cg and ce, width_g=ghi - glo,
                width_e=(ehi / elo if log else ehi - elo),
                rel_g=(res.gap_mean_m - g) / g,
                err_e=(res.param / e - 1.0 if log else res.param - e),
                g_low=bool(glo > g), g_high=bool(ghi < g), e_low=bool(elo > e),
                e_high=bool(ehi < e), corr=res.posterior_correlation,
                outside=res.predictive_outside, values=res.predictive_values,
                flagged=bool(res.flags), at_end=bool(end),
                bound_e=bool(end) and bool(elo <= e if math.isnan(ehi) else e <= ehi))
    out["rep_e"] = out["cov_e"] or out["bound_e"]
    # the mean gap's range: its interval, or its lower bound when flagged at the grid's top
    out["rep_g"] = cg or ("posterior_at_grid_end" in res.flags and bool(glo <= g))
    out["no_range"] = bool(math.isnan(elo) and math.isnan(ehi))
    return out


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson 95 % range of a binomial proportion k / n."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, c - h), min(1.0, c + h)


def report(label: str, res: list[dict], sym: str = "e", log: bool = False) -> str:
    """One line of a case's outcomes; an experiment without data (``None``: no wave
    reached a probe, so nothing was measured or fitted) is counted apart."""
    skipped = sum(r is None for r in res)
    res = [r for r in res if r is not None]

    def m(k):
        return np.array([r[k] for r in res], float)

    def cov(k):
        c = int(m(k).sum())
        lo, hi = wilson(c, n)
        return f"{c / n:.3f} [{lo:.2f}, {hi:.2f}]"
    n = len(res)
    width = (f"{sym} x{np.nanmedian(m('width_e')):.3f} (hi/lo)" if log
             else f"{sym} {np.nanmedian(m('width_e')):.4f}")
    err = (f"rel. error {sym} {np.nanmedian(m('err_e')):+.3f}" if log
           else f"error {sym} {np.nanmedian(m('err_e')):+.4f}")
    return (f"{label:34s} n={n:3d}  coverage g {cov('cov_g')}, reported range "
            f"{cov('rep_g')} (truth below "
            f"{int(m('g_low').sum())}, above {int(m('g_high').sum())}), {sym} "
            f"{cov('cov_e')} (below {int(m('e_low').sum())}, above "
            f"{int(m('e_high').sum())}), both {cov('cov_both')}; median width g "
            f"{np.nanmedian(m('width_g')) * 1e9:5.1f} nm, {width}; "
            f"median rel. error g {np.nanmedian(m('rel_g')):+.3f}, {err}; median corr "
            f"{np.nanmedian(m('corr')):+.2f}; predictive outside "
            f"{int(np.nansum(m('outside')))}/{int(m('values').sum())}; "
            f"flagged {int(m('flagged').sum())}, {sym} at its grid's end "
            f"{int(m('at_end').sum())} (one-sided bound holds the truth in "
            f"{int(m('bound_e').sum())}); the reported range (interval, or one-sided bound "
            f"when flagged) holds {sym} in {cov('rep_e')}; no range (weight at both ends) "
            f"{int(m('no_range').sum())}; no wave at a probe (not fitted) {skipped}")


def build_grid(base, key: str, gap_max: float, gap_points: int, realisations: int,
               cache_dir=None, e_min: float | None = None, e_points: int | None = None):
    """The case's joint grid: damping.e from ``e_min`` to 1 in ``e_points``; another key
    over its case's range in its case's points."""
    case = CASES[key]
    if key == "damping.e":
        return inference.simulate_joint_grid(base, gap_max, gap_points, e_min, e_points,
                                             realisations, cache_dir)
    lo, hi = case["range"]
    return inference.simulate_joint_grid(base, gap_max, gap_points, lo, case["points"],
                                         realisations, cache_dir, key=key, hi=hi)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--key", default="damping.e", choices=list(CASES))
    ap.add_argument("--trials", type=int, default=15,
                    help="per material x (independent, series) x peak-noise level")
    ap.add_argument("--rows", type=int, default=3)
    ap.add_argument("--realisations", type=int, default=64)
    ap.add_argument("--gap-max-nm", type=float, default=500.0)
    ap.add_argument("--gap-points", type=int, default=21)
    ap.add_argument("--e-min", type=float, default=inference.E_MIN)
    ap.add_argument("--e-points", type=int, default=inference.E_POINTS)
    ap.add_argument("--peak-noise", type=float, nargs="+", default=[0.02, 0.08])
    ap.add_argument("--materials", nargs="+", default=None)
    ap.add_argument("--cache-dir", default=None)
    ap.add_argument("--truths", nargs="+", default=None,
                    choices=["restitution", "own", "viscoelastic", "dmt"])
    ap.add_argument("--noise-scale", type=float, default=1.0)
    a = ap.parse_args()
    key, case = a.key, CASES[a.key]
    fk = inference.fit_key(key)
    sym = "e" if key == "damping.e" else fk.fit.symbol
    materials = a.materials or case["materials"]
    truths = a.truths or case["truths"]
    grids = {}
    for material in materials:
        base = base_scene(material, key)
        t0 = time.perf_counter()
        grid = build_grid(base, key, a.gap_max_nm * 1e-9, a.gap_points, a.realisations,
                          a.cache_dir, a.e_min, a.e_points)
        errs = inference.joint_interp_errors(grid, COLUMN)
        print(f"{material}: grid of {grid.n_chains} chains ({grid.simulated} simulated now) "
              f"in {time.perf_counter() - t0:.1f} s; interpolation error (largest over the "
              f"gaps / {sym} / speed): " + ", ".join(
                  f"{k} {np.max(v['g']):.1e}/{v['param']:.1e}/{v['speed']:.1e}"
                  for k, v in errs.items()))
        grids[material] = (base, grid)
    trials = make_trials(materials, a.peak_noise, a.trials, a.rows, key=key)
    print(f"key {key}: truths {case['range'][0]:g}-{case['range'][1]:g}"
          f"{' (log-uniform)' if fk.log else ''}, mean gaps {G_RANGE[0] * 1e9:g}-"
          f"{G_RANGE[1] * 1e9:g} nm; stated noise x{a.noise_scale:g}")
    for law in truths:
        print(f"\ntruth '{law}'")
        t0 = time.perf_counter()
        allres, t_inf = [], 0.0
        etas = []
        for material in materials:
            base, grid = grids[material]
            for series in (False, True):
                for level in a.peak_noise:
                    res = []
                    for tr in trials:
                        if (tr["material"], tr["series"], tr["level"]) != (material, series,
                                                                           level):
                            continue
                        X, eta = truth_rows(base, tr, law, key)
                        etas.append(eta)
                        if not np.all(np.isfinite(X)):
                            res.append(None)      # no wave at a probe: nothing measured
                            continue
                        t1 = time.perf_counter()
                        r = inference.infer_joint(base, measurements(tr, X, a.noise_scale),
                                                  grid=grid)
                        t_inf += time.perf_counter() - t1
                        res.append(outcome(tr, r, fk.log))
                    allres += res
                    print(report(f"{material} {'series' if series else 'independent'} "
                                 f"peaks {level:g} v_s", res, sym, fk.log), flush=True)
        for level in a.peak_noise:
            print(report(f"all, peaks {level:g} v_s", [r for r, tr in zip(allres, trials)
                                                       if tr["level"] == level], sym, fk.log))
        print(report("all", allres, sym, fk.log))
        if law == "viscoelastic":
            print(f"eta_n0 {np.nanmin(etas):.3g} to {np.nanmax(etas):.3g} 1/(m s)")
        print(f"({time.perf_counter() - t0:.1f} s; inference "
              f"{t_inf / max(1, sum(r is not None for r in allres)):.2f} s per experiment)",
              flush=True)


if __name__ == "__main__":
    main()
