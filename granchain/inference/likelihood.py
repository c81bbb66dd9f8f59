"""The likelihood of both fits: the weighted Gaussian kernel density over the grid's
realisations (:func:`kernel_log_density`), per group of rows that share a chain, for the
timing alone (:func:`log_likelihood`) or the timing and both peaks
(:func:`joint_log_likelihood`), and the model check of each fit's data against the same
kernels (:func:`gap_model_check`, :func:`joint_model_check`; ``granchain.modelcheck``).
The method is in the module doc of :mod:`granchain.inference`."""
from __future__ import annotations

import math

import numpy as np

from .grid import Grid, JointGrid
from .interpolation import (_at_speed, _interp_param, _interp_g, _interp_gap, _interp_speed,
                            _model_rel, joint_interp_errors, joint_values)
from .measurements import Measurements

CHUNK_BYTES = 64e6                # working memory of one block of the joint likelihood


def log_likelihood(grid: Grid, meas: Measurements, fine: np.ndarray,
                   model_rel: float = 0.0) -> np.ndarray:
    """log L(g) at every mean gap of ``fine`` (module doc), shape (F,)."""
    T = _interp_gap(grid.timings[meas.column], grid.gaps, fine)         # (F, S, R)
    weights = grid.realisation_weights
    total = np.zeros(fine.size)
    for idx in meas.groups:
        P = np.stack([_interp_speed(T, grid.speeds, float(meas.v[i])) for i in idx], axis=-1)
        t = meas.t[idx]                                                   # (m,)
        var = meas.err[idx] ** 2 + (model_rel * t) ** 2 + (1e-9 * t) ** 2
        total += kernel_log_density(P, t, np.broadcast_to(var, P[:, 0].shape), weights)
    return total


def kernel_log_density(X: np.ndarray, y: np.ndarray, var: np.ndarray,
                       weights: np.ndarray) -> np.ndarray:
    """log of the weighted Gaussian kernel density over realisations at the data: X (P, R,
    d) the R realisations' values at P parameter points (NaN where not measured), y (d,)
    the data, var (P, d) the variance added to the kernel (measurement, model error),
    weights (R,) the realisations' weights. The kernel covariance is Silverman's factor^2
    (for the weights' effective size) x the realisations' weighted covariance, plus var;
    the density is sum_r w_r N(y; X_r, C) / sum_r w_r over all R (a realisation without
    values adds nothing), -inf where fewer than two realisations give values."""
    from ..modelcheck import kernel_factor
    d = X.shape[-1]
    ok = np.all(np.isfinite(X), axis=-1)                                # (P, R)
    w = np.where(ok, weights[None, :], 0.0)
    Xz = np.where(ok[..., None], X, 0.0)
    L = kernel_factor(Xz, w, weights, var)                                 # (P, d, d)
    resid = np.where(ok[..., None], y[None, None, :] - X, 0.0)             # (P, R, d)
    # L^-1 once per point, then one batched product (a general solve would factor L again)
    Z = np.matmul(np.linalg.inv(L), np.swapaxes(resid, 1, 2))            # (P, d, R)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
    lp = -0.5 * (Z * Z).sum(axis=1) - 0.5 * logdet[:, None] - 0.5 * d * math.log(2 * math.pi)
    lp = np.where(ok, lp, -np.inf)
    top = lp.max(axis=1)
    with np.errstate(invalid="ignore"):
        ll = (top + np.log((np.exp(lp - top[:, None]) * weights[None, :]).sum(axis=1))
              - math.log(weights.sum()))
    return np.where(ok.sum(axis=1) >= 2, ll, -np.inf)


def gap_model_check(grid: Grid, meas: Measurements, fine: np.ndarray, pdf: np.ndarray,
                    model_rel: float):
    """Do the timings lie inside what the grid's realisations produce at the posterior?
    (``granchain.modelcheck``; each chain's kernel as in :func:`log_likelihood`.)"""
    from ..modelcheck import ALPHA, CHECK_DRAWS, CHECK_SEED, STATISTIC, ModelCheck, check
    if not np.any(pdf > 0):
        return ModelCheck(STATISTIC, math.nan, math.nan, math.nan, math.nan, ALPHA, 0, True)
    mass = pdf * _trapz_weights(fine)
    g = fine[np.random.default_rng(CHECK_SEED).choice(fine.size, size=CHECK_DRAWS,
                                                      p=mass / mass.sum())]
    T = _interp_gap(grid.timings[meas.column], grid.gaps, g)            # (K, S, R)
    groups = []
    for idx in meas.groups:
        P = np.stack([_interp_speed(T, grid.speeds, float(meas.v[i])) for i in idx], axis=-1)
        t = meas.t[idx]
        var = meas.err[idx] ** 2 + (model_rel * t) ** 2 + (1e-9 * t) ** 2
        groups.append((P / t, np.ones_like(t), np.broadcast_to(var / t ** 2, P[:, 0].shape)))
    return check(groups, grid.realisation_weights)


def joint_log_likelihood(grid: JointGrid, meas: Measurements, fine_g: np.ndarray,
                         fine_e: np.ndarray, errs: dict | None = None) -> np.ndarray:
    """log L(g, p), shape (F_g, F_e), at mean gaps ``fine_g`` and values ``fine_e`` of the
    fitted key: per group (a chain), the kernel density over the R
    realisations of the group's 3m observables (each row's timing and two peaks),
    standardised by the row's observed timing and striker speed (module doc)."""
    if errs is None:
        errs = joint_interp_errors(grid, meas.column)
    rel = _model_rel(errs, meas.column, fine_g, grid.gaps)             # (F_g, 3)
    R = grid.realisations
    weights = grid.realisation_weights
    total = np.zeros((fine_g.size, fine_e.size))
    for idx in meas.groups:
        m = idx.size
        d = 3 * m
        scale, y, var_meas, var_floor = _joint_group(meas, idx)
        var_model = (np.tile(rel, (1, m)) * y[None, :]) ** 2                 # (F_g, d)
        nodes = np.concatenate([_at_speed(grid, meas.column, float(meas.v[i])) for i in idx],
                               axis=-1) / scale                            # (G, E, R, d)
        Ne = _interp_param(nodes, grid.coords, grid.fit_key.coord(fine_e),
                           axis=1)                                         # (G, F_e, R, d)
        rows = max(1, int(CHUNK_BYTES // (fine_e.size * R * d * 8 * 6)))
        for a in range(0, fine_g.size, rows):
            b = min(a + rows, fine_g.size)
            X = _interp_g(Ne, grid.gaps, fine_g[a:b])                      # (c, F_e, R, d)
            var = var_meas + var_floor + np.repeat(var_model[a:b], fine_e.size, axis=0)
            ll = kernel_log_density(X.reshape(-1, R, d), y, var, weights)
            total[a:b] += ll.reshape(b - a, fine_e.size)
    return total


def _joint_group(meas: Measurements, idx: np.ndarray):
    """(scale, y, var_meas, var_floor), each (3m,), of a group's rows in the joint
    likelihood: each row's (timing, vmax_1, vmax_2) standardised by its observed timing
    and its striker speed, their stated variances and the kernel's floor."""
    perr = meas.peak_err
    scale = np.concatenate([[meas.t[i], meas.v[i], meas.v[i]] for i in idx])
    y = np.concatenate([[meas.t[i], meas.vmax_1[i], meas.vmax_2[i]] for i in idx]) / scale
    var_meas = (np.concatenate([[meas.err[i], perr[i], perr[i]] for i in idx]) / scale) ** 2
    return scale, y, var_meas, (1e-9 * y) ** 2


def joint_model_check(grid: JointGrid, meas: Measurements, draws: np.ndarray, errs: dict):
    """Do the timings and peaks lie inside what the grid's realisations produce at the
    posterior draws? (``granchain.modelcheck``; each chain's kernel as in
    :func:`joint_log_likelihood`.)"""
    from ..modelcheck import CHECK_DRAWS, ModelCheck, STATISTIC, ALPHA, check
    if not draws.size:
        return ModelCheck(STATISTIC, math.nan, math.nan, math.nan, math.nan, ALPHA, 0, True)
    sub = draws[:CHECK_DRAWS]
    rel = _model_rel(errs, meas.column, sub[:, 0], grid.gaps)          # (K, 3)
    groups = []
    for idx in meas.groups:
        scale, y, var_meas, var_floor = _joint_group(meas, idx)
        X = np.concatenate([joint_values(grid, meas.column, float(meas.v[i]), sub[:, 0],
                                         sub[:, 1]) for i in idx], axis=-1) / scale
        var = var_meas + var_floor + (np.tile(rel, (1, idx.size)) * y[None, :]) ** 2
        groups.append((X, y, var))
    return check(groups, grid.realisation_weights)


def _trapz_weights(x: np.ndarray) -> np.ndarray:
    w = np.zeros_like(x)
    dx = np.diff(x)
    w[:-1] += 0.5 * dx
    w[1:] += 0.5 * dx
    return w
