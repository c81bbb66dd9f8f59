"""Do the measurements lie inside what the simulated realisations produce? The check behind
an inference's ``data_outside_model``.

The likelihood of a chain's rows is a kernel density over the grid's R realisations
(``granchain.inference``). For data inside the simulated cloud that density is an estimate of
the model's; for data outside it, it is the Gaussian tail of the nearest kernels, and the
posterior's width then measures the steepness of that tail, not the spread of the possible
gap patterns: a narrow, biased interval. This module measures how far the data lie from the
cloud, with a p-value calibrated against the model itself.

Replicates: data made from the simulated realisations themselves, at K posterior draws
theta -- realisation j of each chain (drawn with the realisations' weights) plus noise of
the kernel's stated variance (measurement and model error). Two statistics, each ranked
among the replicates:

- the kernel log density of the data, summed over the chains (groups) of the measurement,
  T = sum_g log p_hat_g(y_g | theta), a replicate scored by the same kernel density without
  its own realisation (leave one out, so it is not scored by the kernel centred on it):
  ``p_density``, the share of replicates with T at or below the data's. It sees a chain
  whose values together are unlike every realisation's;
- the most extreme single value: each value's two-sided tail probability under the pooled
  replicates (all draws), the smallest over the chain's values, ``p_marginal`` the share of
  replicates whose smallest is at or below the data's. In many dimensions the kernel is
  nearly as wide as the cloud and one observable far out (a probe's peak below every
  simulated one at every speed) moves the density little; this sees it.

``p_value`` = min(1, 2 min(p_density, p_marginal)) (Bonferroni over the two), flagged below
``ALPHA``. Both ranks are posterior predictive p-values: conservative under the model (the
posterior was fitted to the same data), so the flag fires on at most about ALPHA of the
experiments the model describes; the calibration suite (``benchmarks/inference_outside.py``)
measures the rate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ALPHA = 0.01          # flag data whose density rank among the replicates is below this
CHECK_DRAWS = 100     # posterior draws the check evaluates the kernel density at
CHECK_SEED = 31415    # replicate noise and realisation draws: the same data, the same p


@dataclass(frozen=True)
class ModelCheck:
    """The check's result: ``log_density`` the data's kernel log density (summed over its
    chains; median over the posterior draws); ``p_density`` the share of model replicates
    at or below it; ``p_marginal`` the share of replicates whose most extreme single value
    is at least as extreme as the data's; ``p_value`` min(1, 2 min(p_density,
    p_marginal)) (Bonferroni over the two); ``flag`` p_value < ``alpha``; ``replicates``
    how many were scored."""
    statistic: str
    log_density: float
    p_density: float
    p_marginal: float
    p_value: float
    alpha: float
    replicates: int
    flag: bool

    def to_json(self) -> dict:
        return {"flag": self.flag, "statistic": self.statistic,
                "log_density": self.log_density, "p_density": self.p_density,
                "p_marginal": self.p_marginal, "p_value": self.p_value,
                "alpha": self.alpha, "replicates": self.replicates}


STATISTIC = ("kernel log density (leave-one-out) and most extreme single value of the data, "
             "each ranked among posterior-predictive replicates made from the simulated "
             "realisations")


def weighted_cov(X: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(K, d, d) weighted covariances of X (K, R, d) with weights w (K, R) (0 where a
    realisation is not used): sum w D D^T / (sum w - sum w^2 / sum w), which for equal
    weights is the sample covariance with R - 1."""
    sw = w.sum(axis=1)
    sw = np.where(sw > 0, sw, 1.0)
    mean = (X * w[..., None]).sum(axis=1) / sw[:, None]
    D = np.where(w[..., None] > 0, X - mean[:, None, :], 0.0) * np.sqrt(w)[..., None]
    norm = sw - (w * w).sum(axis=1) / sw
    return (np.matmul(np.swapaxes(D, 1, 2), D)        # batched BLAS: faster than einsum
            / np.where(norm > 0, norm, 1.0)[:, None, None])


def effective_size(weights: np.ndarray) -> float:
    """Kish's effective sample size (sum w)^2 / sum w^2 of the realisations' weights (R
    for equal weights): the bandwidth's sample size."""
    w = np.asarray(weights, float)
    return float(w.sum() ** 2 / np.sum(w * w))


def silverman2(n_eff: float, d: int) -> float:
    """Silverman's factor squared for n_eff points in d dimensions (Python's float power:
    numpy's may differ in the last bit on some CPUs)."""
    return ((float(n_eff) * (d + 2)) / 4.0) ** (-2.0 / (d + 4))


def kernel_factor(Xz: np.ndarray, w: np.ndarray, weights: np.ndarray,
                  var: np.ndarray) -> np.ndarray:
    """(P, d, d) Cholesky factors of the kernel covariance: Silverman's factor^2 (for the
    weights' effective size) x the weighted covariance of Xz (P, R, d; w (P, R) the weights
    of the realisations used), plus ``var`` (P, d) on the diagonal. The likelihood
    (``inference.kernel_log_density``) and the check use this one kernel."""
    d = Xz.shape[-1]
    C = silverman2(effective_size(weights), d) * weighted_cov(Xz, w)
    C[:, np.arange(d), np.arange(d)] += var
    return np.linalg.cholesky(C)


def group_scores(X: np.ndarray, weights: np.ndarray, y: np.ndarray, var: np.ndarray,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One chain's scores. X (K, R, d): its simulated values at K posterior draws (NaN
    where a realisation did not give them); weights (R,); y (d,): the data; var (K, d): the
    kernel's added variance (measurement, model error). Returns (obs (K,): the data's
    kernel log density, rep (K, R): realisation j's replicate scored without j, ok (K, R):
    the realisations that gave values, Y (K, R, d): the replicates)."""
    K, R, d = X.shape
    ok = np.all(np.isfinite(X), axis=-1)
    w = np.where(ok, weights[None, :], 0.0)
    Xz = np.where(ok[..., None], X, 0.0)
    L = kernel_factor(Xz, w, weights, var)                                 # (K, d, d)
    A = np.linalg.solve(L, np.swapaxes(Xz, 1, 2))                          # (K, d, R)
    b = np.linalg.solve(L, np.broadcast_to(y, (K, d))[..., None])[..., 0]  # (K, d)
    logw = np.where(w > 0, np.log(np.where(w > 0, w, 1.0)), -np.inf)      # (K, R)
    # the data under every kernel
    q_obs = ((b[:, :, None] - A) ** 2).sum(axis=1)                         # (K, R)
    obs = _lse(logw - 0.5 * q_obs, axis=1) - _lse(logw, axis=1)
    # replicate j: realisation j plus noise of the kernel's added variance, in the whitened
    # frame of L
    noise = rng.standard_normal((K, R, d)) * np.sqrt(var)[:, None, :]
    Y = Xz + noise                                                          # (K, R, d)
    Yr = np.swapaxes(Y, 1, 2)                                               # (K, d, R)
    Br = np.linalg.solve(L, Yr)                                             # (K, d, R)
    q = ((Br * Br).sum(axis=1)[:, :, None] + (A * A).sum(axis=1)[:, None, :]
         - 2.0 * np.einsum("kdj,kdr->kjr", Br, A))                         # (K, R_j, R_r)
    lw = np.broadcast_to(logw[:, None, :], q.shape).copy()
    idx = np.arange(R)
    lw[:, idx, idx] = -np.inf                                               # leave j out
    rep = _lse(lw - 0.5 * q, axis=2) - _lse(lw, axis=2)
    return obs, rep, ok, Y


def _lse(x: np.ndarray, axis: int) -> np.ndarray:
    top = np.max(x, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return np.log(np.exp(x - top).sum(axis=axis)) + np.squeeze(top, axis=axis)


def marginal_p(sample: np.ndarray, weights: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Two-sided tail probabilities 2 min(F, 1 - F) of the points y (..., d) under the
    weighted sample (N, d) per component (F: the weighted share of the sample below, kept
    within half a sample's weight of 0 and 1)."""
    N, d = sample.shape
    out = np.empty(y.shape)
    w = weights / weights.sum()
    half = 0.5 * float(np.min(w))
    for c in range(d):
        order = np.argsort(sample[:, c], kind="stable")
        cum = np.concatenate([[0.0], np.cumsum(w[order])])
        F = cum[np.searchsorted(sample[order, c], y[..., c], side="left")]
        F = np.clip(F, half, 1.0 - half)
        out[..., c] = 2.0 * np.minimum(F, 1.0 - F)
    return out


def check(groups: list[tuple[np.ndarray, np.ndarray, np.ndarray]], weights: np.ndarray,
          alpha: float = ALPHA, seed: int = CHECK_SEED) -> ModelCheck:
    """The check over a measurement's chains: ``groups`` lists each chain's (X (K, R, d),
    y (d,), var (K, d)) at the same K posterior draws (module doc)."""
    rng = np.random.default_rng(seed)
    weights = np.asarray(weights, float)
    obs_d = rep_d = obs_m = rep_m = None
    for X, y, var in groups:
        K, R, d = X.shape
        obs, rep, ok, Y = group_scores(X, weights, y, var, rng)
        # each replicate set draws its realisation of this chain with the weights of the
        # realisations that gave values
        p = np.where(ok, weights[None, :], 0.0)
        p = p / p.sum(axis=1, keepdims=True)
        cum = np.cumsum(p, axis=1)
        u = rng.random((K, R))
        j = np.minimum((u[:, :, None] > cum[:, None, :]).sum(axis=2), R - 1)   # (K, M)
        pick = np.take_along_axis(rep, j, axis=1)
        # the most extreme single value: the predictive sample is every replicate
        sw = np.where(ok, weights[None, :], 0.0).ravel()
        sample = Y.reshape(-1, d)[sw > 0]
        mp_obs = float(np.min(marginal_p(sample, sw[sw > 0], y)))
        mp_rep = np.min(marginal_p(sample, sw[sw > 0], Y), axis=-1)             # (K, R)
        mp_pick = np.take_along_axis(mp_rep, j, axis=1)
        obs_d = obs if obs_d is None else obs_d + obs
        rep_d = pick if rep_d is None else rep_d + pick
        obs_m = mp_obs if obs_m is None else min(obs_m, mp_obs)
        rep_m = mp_pick if rep_m is None else np.minimum(rep_m, mp_pick)
    good = np.isfinite(obs_d)
    if not np.any(good):
        return ModelCheck(STATISTIC, -math.inf, 0.0, 0.0, 0.0, alpha, 0, True)
    below = rep_d[good] <= obs_d[good][:, None]
    p_density = float(below.mean())
    p_marginal = float(np.mean(rep_m <= obs_m))
    pv = min(1.0, 2.0 * min(p_density, p_marginal))
    return ModelCheck(STATISTIC, float(np.median(obs_d[good])), p_density, p_marginal, pv,
                      alpha, int(below.size), pv < alpha)
