"""The joint fit (``--fit gap_mean,KEY``; ``gap_mean,restitution`` is KEY ``damping.e``):
the grid posterior of the mean gap and a fittable scene key (``inference.fitkeys``) from
the timing and both probes' peaks (:func:`infer_joint`, result :class:`JointInference`):
its evaluation points and their zoom on a narrow posterior, the marginal summaries, the
posterior draws and the posterior predictive check (module doc of
:mod:`granchain.inference`). The key's prior is uniform in its coordinate
(``FitKey.coord``: the value, or its log for a log-uniform prior); the posterior is
evaluated, summarised and drawn from in that coordinate, and reported in the key's
values."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..errors import GranchainError
from ..scene import Scene
from .gapfit import EDGE_WEIGHT, PRIOR, _eq54, log_prior
from .fitkeys import DEFAULT_KEY, check_fit_base, fit_key
from .grid import (GAP_MAX, GAP_POINTS, REALISATIONS, JointGrid, check_base, complete_base,
                   simulate_joint_grid)
from .interpolation import _interp_param, joint_interp_errors, joint_values
from .likelihood import _trapz_weights, joint_log_likelihood, joint_model_check
from .measurements import Measurements, check_peaks, check_speeds
from .result import FitResult, shared_fields
from .setting import choose_setting

FINE_G, FINE_E = 241, 161         # posterior evaluation points (mean gap, fitted key)
ZOOM_DROP = 20.0                  # the second pass covers log posterior >= peak - this
FIRST_STRIDE = 4                  # the first pass's points: every 4th of FINE_G x FINE_E
PREDICTIVE_DRAWS = 400            # posterior draws of the predictive check and the figure
PREDICTIVE_SEED = 20250


def fine_axes(grid: JointGrid) -> tuple[np.ndarray, np.ndarray]:
    """The posterior's evaluation points: mean gaps (quadratic spacing, as the nodes) and
    the fitted key's coordinate (uniform) over the grid's range."""
    return (float(grid.gaps[-1]) * np.linspace(0.0, 1.0, FINE_G) ** 2,
            np.linspace(float(grid.coords[0]), float(grid.coords[-1]), FINE_E))


def zoom_box(fine_g, fine_e, logpost, drop: float = ZOOM_DROP, shrink: float = 0.5):
    """((g0, g1), (u0, u1)): the box of the points whose log posterior is within ``drop``
    of its peak, one point wider on each side, when it spans less than ``shrink`` of the
    range in either parameter (``fine_e``: the fitted key's coordinate; the posterior is
    then evaluated again on it, for the resolution of a narrow posterior); None
    otherwise."""
    ok = np.isfinite(logpost)
    if not np.any(ok):
        return None
    keep = ok & (logpost >= np.max(logpost[ok]) - drop)
    gi, ej = np.flatnonzero(keep.any(axis=1)), np.flatnonzero(keep.any(axis=0))
    a, b = max(gi[0] - 1, 0), min(gi[-1] + 1, fine_g.size - 1)
    c, d = max(ej[0] - 1, 0), min(ej[-1] + 1, fine_e.size - 1)
    span_g = (fine_g[b] - fine_g[a]) / (fine_g[-1] - fine_g[0])
    span_e = (fine_e[d] - fine_e[c]) / (fine_e[-1] - fine_e[0])
    if min(span_g, span_e) >= shrink:
        return None
    return (float(fine_g[a]), float(fine_g[b])), (float(fine_e[c]), float(fine_e[d]))


def _summary(x: np.ndarray, pdf: np.ndarray, low_flag: str | None, high_flag: str | None):
    """(median, lo, hi, flags) of a 1D density on the points x; an end of the grid where
    the density is above EDGE_WEIGHT x its peak sets the end's quantile and the median to
    NaN with its flag."""
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(x))])
    cdf = cdf / cdf[-1]
    med, lo, hi = (float(np.interp(q, cdf, x)) for q in (0.5, 0.025, 0.975))
    flags = []
    top = float(np.max(pdf))
    if low_flag and pdf[0] > EDGE_WEIGHT * top:
        flags.append(low_flag)
        med, lo = math.nan, math.nan
    if high_flag and pdf[-1] > EDGE_WEIGHT * top:
        flags.append(high_flag)
        med, hi = math.nan, math.nan
    return med, lo, hi, flags


# the result's fields of the fitted key, named in its JSON document and as attributes by
# the key's results' name (``Fit.name``: ``restitution``, ``restitution_ci95``, ...)
_PARAM_FIELDS = ("param", "param_ci95", "param_grid")


@dataclass(frozen=True)
class JointInference(FitResult):
    """Result of :func:`infer_joint` (SI units; NaN where not measured, with ``flags``).
    ``fit`` is ("gap_mean", the key's results' name), ``key`` the key's path; ``param``,
    ``param_ci95`` (its median and central 95 % interval) and ``param_grid`` (the grid's
    range and nodes) go by that name in the JSON document and as attributes
    (``res.restitution``); ``posterior_correlation`` is that of the mean gap and the key's
    coordinate (its log for a log-uniform prior)."""
    fit: tuple[str, ...]
    key: str
    gap_mean_m: float
    ci95_m: tuple[float, float]
    param: float
    param_ci95: tuple[float, float]
    posterior_correlation: float
    eq54_gap_m: float
    eq54_gap_bound_m: float
    eq54_gap_rows_m: tuple[float, ...]
    predictive_outside: int | None    # None: no posterior draw, nothing checked
    predictive_values: int
    predictive_rows: tuple
    n_simulated: int
    n_simulated_now: int
    n_unmeasured: int
    gap_law: str
    law: str                      # the fitted key's effect and its model
    timing_column: str
    method: str
    realisations: int
    gap_grid_m: tuple[float, float, int]
    gap_spacing: str
    param_grid: tuple[float, float, int]
    param_spacing: str            # "uniform" or "log"
    speeds_m_s: tuple[float, ...]
    gap_law_source: str           # as Inference
    speeds_source: str
    interp_rel_error: dict
    rows: int
    chains: int
    scene: str
    scene_hashes: tuple[str, ...]
    flags: tuple[str, ...]
    data_outside_model: dict      # as Inference
    integrator: dict              # as Inference
    posterior_g_m: np.ndarray = dataclasses.field(repr=False, compare=False)
    posterior_p: np.ndarray = dataclasses.field(repr=False, compare=False)    # key values
    posterior_pdf: np.ndarray = dataclasses.field(repr=False, compare=False)   # (F_g, F_e)
    marginal_g: np.ndarray = dataclasses.field(repr=False, compare=False)
    marginal_p: np.ndarray = dataclasses.field(repr=False, compare=False)     # per coordinate
    draws: np.ndarray = dataclasses.field(repr=False, compare=False)           # (D, 2)
    grid: JointGrid | None = dataclasses.field(default=None, repr=False, compare=False)

    HIDDEN = ("posterior_g_m", "posterior_p", "posterior_pdf", "marginal_g", "marginal_p",
              "draws", "grid")

    def _named(self, field: str) -> str:
        # a result without a fitted name (a stand-in) is the default key's fit
        name = self.fit[1] if len(self.fit) > 1 else fit_key(DEFAULT_KEY).name
        return name + field[len("param"):]

    def to_json(self) -> dict:
        """As :meth:`~granchain.inference.result.FitResult.to_json`, the key's fields named by its results' name."""
        return {(self._named(k) if k in _PARAM_FIELDS else k): v
                for k, v in super().to_json().items()}

    def __getattr__(self, attr):
        # res.restitution, res.yield_pressure_ci95, ...: the key's fields by its name
        if "fit" in self.__dict__:
            for f in _PARAM_FIELDS:
                if attr == self._named(f):
                    return getattr(self, f)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {attr!r}")


def posterior_draws(fine_g, fine_e, pdf, draws: int = PREDICTIVE_DRAWS,
                    seed: int = PREDICTIVE_SEED) -> np.ndarray:
    """(draws, 2) (g, u) drawn from the posterior on the fine points (``fine_e``: the
    fitted key's coordinate u; cell masses pdf x trapezoid weights), with a fixed seed: the
    same result gives the same draws."""
    mass = pdf * _trapz_weights(fine_g)[:, None] * _trapz_weights(fine_e)[None, :]
    p = mass.ravel() / mass.sum()
    k = np.random.default_rng(seed).choice(p.size, size=draws, p=p)
    return np.stack([fine_g[k // fine_e.size], fine_e[k % fine_e.size]], axis=1)


def predictive(grid: JointGrid, meas: Measurements, draws: np.ndarray,
               seed: int = PREDICTIVE_SEED):
    """Posterior predictive of every row: (per row [(2.5, 50, 97.5) % of timing, vmax_1,
    vmax_2] with the stated measurement noise added, number of measured values outside
    their 95 % range, number of values). Rows of one chain share a realisation, but each
    value is checked on its own."""
    rng = np.random.default_rng([seed, 1])
    rows, outside = [], 0
    perr = meas.peak_err
    for i in range(len(meas)):
        X = joint_values(grid, meas.column, float(meas.v[i]), draws[:, 0], draws[:, 1])
        X = X.reshape(-1, 3)
        X = X[np.all(np.isfinite(X), axis=1)]
        sd = np.array([meas.err[i], perr[i], perr[i]])
        X = X + sd * rng.standard_normal(X.shape)
        q = np.percentile(X, [2.5, 50, 97.5], axis=0) if X.size else np.full((3, 3), np.nan)
        y = (meas.t[i], meas.vmax_1[i], meas.vmax_2[i])
        outside += int(sum(not (q[0, c] <= y[c] <= q[2, c]) for c in range(3)))
        rows.append({"v_striker_m_s": float(meas.v[i]),
                     meas.column: [float(x) for x in q[:, 0]],
                     "vmax_1_m_s": [float(x) for x in q[:, 1]],
                     "vmax_2_m_s": [float(x) for x in q[:, 2]]})
    return tuple(rows), outside, 3 * len(meas)


def infer_joint(base: Scene, meas: Measurements, *, gap_max: float = GAP_MAX,
                gap_points: int = GAP_POINTS, e_min: float | None = None,
                e_points: int | None = None, realisations: int = REALISATIONS,
                cache_dir=None, grid: JointGrid | None = None, source: str = "",
                prior: str = PRIOR, progress: bool | None = None, key: str = DEFAULT_KEY,
                hi: float | None = None) -> JointInference:
    """Infer the mean gap and the fittable scene key ``key`` (``damping.e``: the
    coefficient of restitution) together (module doc) from ``meas`` (timings and both
    probes' peaks on every row) with the base scene's model, completed by
    :func:`~granchain.inference.grid.complete_base`, its integrator as
    :func:`~granchain.inference.gapfit.infer`'s. The grid spans the key's values from
    ``e_min`` to ``hi`` in ``e_points`` nodes (None: its declared prior range and nodes,
    ``validate.Fit``); a given ``grid`` is used as is (from ``simulate_joint_grid`` on the
    completed base scene). ``progress`` as :func:`~granchain.inference.gapfit.infer`."""
    fk = fit_key(key if grid is None else grid.key)
    base, src = complete_base(base, meas)
    check_base(base)
    check_fit_base(base, fk)
    base, chosen = choose_setting(base, meas, peaks=meas.has_peaks, source=source)
    if not meas.has_peaks:
        raise GranchainError(f"{source}columns 'vmax_1_m_s', 'vmax_2_m_s': fitting the "
                             f"{fk.fit.label} needs the measured peaks on every row; give "
                             "them")
    # the peaks' bound at the fitted key's largest value, not the base scene's placeholder:
    # the most energy the contacts' attraction (its surface energy) can add at any node
    top = float(grid.params[-1]) if grid is not None else (fk.fit.hi if hi is None else hi)
    check_peaks(meas, base.derive({fk.path: top}), source)
    check_speeds(meas, base.striker_velocities if grid is None else grid.speeds, source)
    if grid is None:
        grid = simulate_joint_grid(base, gap_max, gap_points,
                                   fk.fit.lo if e_min is None else e_min,
                                   fk.fit.points if e_points is None else e_points,
                                   realisations, cache_dir, progress=progress, key=fk.path,
                                   hi=hi)
    fg, fu = fine_axes(grid)
    errs = joint_interp_errors(grid, meas.column)

    def log_post(fg, fu):
        return (joint_log_likelihood(grid, meas, fg, fk.value(fu), errs)
                + log_prior(fg, prior)[:, None])

    # the first pass on every FIRST_STRIDE-th point finds the box of a narrow posterior
    # (one point wider on each side: FIRST_STRIDE points of the full lattice); a wide one
    # is evaluated on every point, as the box is then found again on those
    box = zoom_box(fg[::FIRST_STRIDE], fu[::FIRST_STRIDE],
                   log_post(fg[::FIRST_STRIDE], fu[::FIRST_STRIDE]))
    if box is None:
        logpost = log_post(fg, fu)
        box = zoom_box(fg, fu, logpost)
    ends = (True, True, True)     # (g's top, the key's bottom, its top) at the grid's ends
    if box is not None:           # the posterior again, on a grid over its own mass
        (g0, g1), (u0, u1) = box
        ends = (g1 >= fg[-1], u0 <= fu[0], u1 >= fu[-1])
        fg, fu = np.linspace(g0, g1, FINE_G), np.linspace(u0, u1, FINE_E)
        logpost = log_post(fg, fu)
    low_phys, high_phys = fk.key.physical_ends()
    edge = f"{fk.name}_at_grid_end"
    flags = []
    if not np.any(np.isfinite(logpost)):
        nan = math.nan
        pdf = np.zeros_like(logpost)
        mg, mp = np.zeros_like(fg), np.zeros_like(fu)
        gq = pq = (nan, nan, nan)
        corr, draws = nan, np.zeros((0, 2))
        flags.append("no_simulated_match")
    else:
        p = np.exp(logpost - np.max(logpost[np.isfinite(logpost)]))
        p[~np.isfinite(p)] = 0.0
        wg, wu = _trapz_weights(fg), _trapz_weights(fu)
        pdf = p / float((p * wg[:, None] * wu[None, :]).sum())
        mg, mp = (pdf * wu[None, :]).sum(axis=1), (pdf * wg[:, None]).sum(axis=0)
        *gq, fl_g = _summary(fg, mg, None, "posterior_at_grid_end" if ends[0] else None)
        *uq, fl_p = _summary(fu, mp, edge if ends[1] and not low_phys else None,
                             edge if ends[2] and not high_phys else None)
        pq = tuple(float(fk.value(u)) if math.isfinite(u) else math.nan for u in uq)
        flags += fl_g + sorted(set(fl_p), key=fl_p.index)
        mass = pdf * wg[:, None] * wu[None, :]
        G, U = np.meshgrid(fg, fu, indexing="ij")
        mu_g, mu_u = (mass * G).sum(), (mass * U).sum()
        cov = (mass * (G - mu_g) * (U - mu_u)).sum()
        sd = math.sqrt((mass * (G - mu_g) ** 2).sum() * (mass * (U - mu_u) ** 2).sum())
        corr = float(cov / sd) if sd > 0 else math.nan
        draws = posterior_draws(fg, fu, pdf)
        draws[:, 1] = fk.value(draws[:, 1])
    if draws.size:
        pred_rows, outside, checked = predictive(grid, meas, draws)
    else:
        pred_rows, outside, checked = (), None, 3 * len(meas)   # nothing checked
    mc = joint_model_check(grid, meas, draws, errs)
    if mc.flag:
        flags.append("data_outside_model")
    # Eq. 5.4's packed chain at the inferred value of the key (the grid's top when the
    # median is not measured)
    p_eq = pq[0] if math.isfinite(pq[0]) else float(grid.params[-1])
    T0 = _interp_param(grid.values[meas.column][0], grid.coords, fk.coord([p_eq]), axis=0)[0]
    fit54, bound54, rows54 = _eq54(T0, grid.speeds, meas, base.probes)
    return JointInference(
        fit=("gap_mean", fk.name), key=fk.path, gap_mean_m=gq[0], ci95_m=(gq[1], gq[2]),
        param=pq[0], param_ci95=(pq[1], pq[2]), posterior_correlation=corr,
        eq54_gap_m=fit54, eq54_gap_bound_m=bound54,
        eq54_gap_rows_m=tuple(float(r) for r in rows54), predictive_outside=outside,
        predictive_values=checked, predictive_rows=pred_rows,
        law=f"{fk.effect} {base.setting(fk.effect).model}",
        method=f"2D grid posterior (mean gap x {fk.name}), simulated-ensemble kernel "
               "likelihood of timing and both peaks",
        gap_spacing="quadratic",
        param_grid=(float(grid.params[0]), float(grid.params[-1]), int(grid.params.size)),
        param_spacing="log" if fk.log else "uniform",
        interp_rel_error={k: {"g_max": float(np.max(v["g"])), "param": float(v["param"]),
                              "speed": float(v["speed"])} for k, v in errs.items()},
        flags=tuple(flags), posterior_g_m=fg, posterior_p=fk.value(fu), posterior_pdf=pdf,
        marginal_g=mg, marginal_p=mp, draws=draws,
        **shared_fields(base, src, meas, grid, mc, chosen))
