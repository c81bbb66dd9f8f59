"""The gap-only fit (``--fit gap_mean``, the default): the mean gap's grid posterior from
the timing (:func:`infer`, result :class:`Inference`), its prior and summary, and the
chapter's Eq. 5.4 readings beside it (module doc of :mod:`granchain.inference`)."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..errors import GranchainError
from ..scene import Scene
from .grid import (GAP_MAX, GAP_POINTS, REALISATIONS, Grid, check_base, complete_base,
                   simulate_grid)
from .interpolation import _interp_speed, interp_rel_error
from .likelihood import gap_model_check, log_likelihood
from .measurements import Measurements, check_peaks, check_speeds
from .result import FitResult, shared_fields
from .setting import choose_setting

FINE_POINTS = 801                         # posterior evaluation points over [0, gap_max]
EDGE_WEIGHT = 1e-2        # posterior density at gap_max, relative to its peak, that flags
PRIOR = "scale"
PRIOR_G0 = 2e-9


@dataclass(frozen=True)
class Inference(FitResult):
    """Result of :func:`infer` (SI units; NaN where not measured, with ``flags``)."""
    gap_mean_m: float
    ci95_m: tuple[float, float]
    eq54_gap_m: float
    eq54_gap_bound_m: float
    eq54_gap_rows_m: tuple[float, ...]
    n_simulated: int
    n_simulated_now: int
    n_unmeasured: int
    gap_law: str
    timing_column: str
    method: str
    realisations: int
    gap_grid_m: tuple[float, float, int]
    speeds_m_s: tuple[float, ...]
    gap_law_source: str           # "scene": the base scene's gaps.distribution; "default"
    speeds_source: str            # "scene": its striker.velocity; "data": the rows' speeds
    interp_rel_error: float
    rows: int
    chains: int
    scene: str
    scene_hashes: tuple[str, ...]
    flags: tuple[str, ...]
    data_outside_model: dict      # modelcheck.ModelCheck.to_json(): flag, statistic, p_value
    integrator: dict              # the grid's integrator and why (result.integrator_record)
    posterior_g_m: np.ndarray = dataclasses.field(repr=False, compare=False)
    posterior_pdf: np.ndarray = dataclasses.field(repr=False, compare=False)
    grid: Grid | None = dataclasses.field(default=None, repr=False, compare=False)

    HIDDEN = ("posterior_g_m", "posterior_pdf", "grid")


def log_prior(fine: np.ndarray, prior: str = PRIOR) -> np.ndarray:
    """log prior density (unnormalised) of the mean gap at the points ``fine`` (m)."""
    if prior == "uniform":
        return np.zeros_like(fine)
    if prior == "scale":
        return -np.log(fine + PRIOR_G0)
    raise GranchainError(f"--prior: unknown prior {prior!r}; use uniform or scale")


def posterior_summary(fine: np.ndarray, logpost: np.ndarray):
    """(pdf, median, lo, hi, flags) of a posterior on the points ``fine``."""
    flags = []
    if not np.any(np.isfinite(logpost)):
        return np.zeros_like(fine), math.nan, math.nan, math.nan, ["no_simulated_match"]
    p = np.exp(logpost - np.max(logpost[np.isfinite(logpost)]))
    p[~np.isfinite(p)] = 0.0
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(fine))])
    pdf = p / cdf[-1]
    cdf = cdf / cdf[-1]
    q = [float(np.interp(x, cdf, fine)) for x in (0.5, 0.025, 0.975)]
    if p[-1] > EDGE_WEIGHT:
        flags.append("posterior_at_grid_end")
        q = [math.nan, q[1], math.nan]
    return pdf, q[0], q[1], q[2], flags


def eq54_gaps(grid: Grid, meas: Measurements, probes) -> tuple[float, float, np.ndarray]:
    """(least-squares fit, bound reading, per-row values) of the mean gap from Eq. 5.4
    (module doc), with the packed chain's timing from the grid's g = 0 point."""
    return _eq54(grid.timings[meas.column][0], grid.speeds, meas, probes)


def _eq54(T0: np.ndarray, speeds: np.ndarray, meas: Measurements, probes):
    """Eq. 5.4 readings with the packed chain's timings ``T0`` (S, R) at ``speeds``."""
    span = probes[1] - probes[0]
    grid_speeds = speeds
    dt0 = np.array([float(np.nanmedian(_interp_speed(T0, grid_speeds, float(v))))
                    for v in meas.v])
    y = meas.t - dt0
    x = span / meas.v
    rows = meas.v * y / span
    fit = float(np.sum(x * y) / np.sum(x * x)) if np.all(np.isfinite(y)) else math.nan
    return fit, float(np.min(rows)), rows


def infer(base: Scene, meas: Measurements, *, gap_max: float = GAP_MAX,
          gap_points: int = GAP_POINTS, realisations: int = REALISATIONS, cache_dir=None, grid: Grid | None = None,
          source: str = "", prior: str = PRIOR, progress: bool | None = None) -> Inference:
    """Infer the mean gap (module doc) from ``meas`` with the base scene's model, completed
    by :func:`~granchain.inference.grid.complete_base`, its integrator chosen from the
    data's stated errors unless it gives one (:func:`~granchain.inference.setting.choose_setting`);
    a given ``grid`` is used as is (it must come from ``simulate_grid`` on that scene). ``progress``: a progress
    bar of the grid's simulation on stderr (``simulate_grid``)."""
    base, src = complete_base(base, meas)
    check_base(base)
    base, chosen = choose_setting(base, meas, peaks=False, source=source)
    check_peaks(meas, base, source)
    # checked before the grid is simulated
    check_speeds(meas, base.striker_velocities if grid is None else grid.speeds, source)
    if grid is None:
        grid = simulate_grid(base, gap_max, gap_points, realisations, cache_dir,
                             progress=progress)
    fine = np.linspace(0.0, float(grid.gaps[-1]), FINE_POINTS)
    rel = interp_rel_error(grid, meas.column)
    logpost = log_likelihood(grid, meas, fine, rel) + log_prior(fine, prior)
    pdf, med, lo, hi, flags = posterior_summary(fine, logpost)
    mc = gap_model_check(grid, meas, fine, pdf, rel)
    if mc.flag:
        flags.append("data_outside_model")
    fit, bound, rows = eq54_gaps(grid, meas, base.probes)
    return Inference(
        gap_mean_m=med, ci95_m=(lo, hi), eq54_gap_m=fit, eq54_gap_bound_m=bound,
        eq54_gap_rows_m=tuple(float(r) for r in rows),
        method="grid posterior, simulated-ensemble kernel likelihood",
        interp_rel_error=rel, flags=tuple(flags), posterior_g_m=fine, posterior_pdf=pdf,
        **shared_fields(base, src, meas, grid, mc, chosen))
