"""Reading a grid between its nodes, and the error of doing so, measured on the grid
itself (module doc of :mod:`granchain.inference`).

- The gap-only grid: linear in the mean gap (``_interp_gap``), linear in (log v, log t)
  between striker speeds (``_interp_speed``); its error :func:`interp_rel_error`.
- The joint grid: the timing as in the gap-only grid and the peaks as v_max / v_s linear
  in log v, log-linear in the fitted key's coordinate (the restitution; the log of a key
  with a log-uniform prior), linear in the mean gap (:func:`joint_values`); its errors per
  observable and per mean-gap node :func:`joint_interp_errors`."""
from __future__ import annotations

import math

import numpy as np

from .grid import Grid, JointGrid


def _interp_gap(T: np.ndarray, gaps: np.ndarray, fine: np.ndarray) -> np.ndarray:
    """(G, S, R) -> (F, S, R), linear in the mean gap."""
    j = np.clip(np.searchsorted(gaps, fine, side="right") - 1, 0, gaps.size - 2)
    w = ((fine - gaps[j]) / (gaps[j + 1] - gaps[j]))[:, None, None]
    return (1.0 - w) * T[j] + w * T[j + 1]


def _interp_speed(T: np.ndarray, speeds: np.ndarray, v: float) -> np.ndarray:
    """(..., S, R) at speed v -> (..., R), linear in (log v, log t)."""
    if speeds.size == 1:
        return T[..., 0, :]
    j = int(np.clip(np.searchsorted(speeds, v, side="right") - 1, 0, speeds.size - 2))
    w = (math.log(v) - math.log(speeds[j])) / (math.log(speeds[j + 1]) - math.log(speeds[j]))
    w = min(max(w, 0.0), 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.exp((1.0 - w) * np.log(T[..., j, :]) + w * np.log(T[..., j + 1, :]))


def interp_rel_error(grid: Grid, column: str) -> float:
    """Relative error of the grid's interpolation, measured on the grid: every interior
    node (mean gap, and speed where there are >= 3) against the interpolation of its two
    neighbours; linear interpolation over twice the spacing errs ~4x more than over the
    spacing, so the 95th percentile of |node - interpolation| / node is divided by 4."""
    T = grid.timings[column]
    errs = []
    if grid.gaps.size >= 3:
        g = grid.gaps
        w = ((g[1:-1] - g[:-2]) / (g[2:] - g[:-2]))[:, None, None]
        mid = (1 - w) * T[:-2] + w * T[2:]
        errs.append(np.abs(T[1:-1] - mid) / T[1:-1])
    if grid.speeds.size >= 3:
        lv = np.log(grid.speeds)
        w = ((lv[1:-1] - lv[:-2]) / (lv[2:] - lv[:-2]))[None, :, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            mid = np.exp((1 - w) * np.log(T[:, :-2]) + w * np.log(T[:, 2:]))
        errs.append(np.abs(T[:, 1:-1] - mid) / T[:, 1:-1])
    e = np.concatenate([x.ravel() for x in errs]) if errs else np.array([])
    e = e[np.isfinite(e)]
    return float(np.percentile(e, 95) / 4.0) if e.size else 0.0


def _speed_weight(speeds: np.ndarray, v: float) -> tuple[int, float]:
    """(j, w): v between speeds j and j + 1, weight w of j + 1, linear in log v."""
    if speeds.size == 1:
        return 0, 0.0
    j = int(np.clip(np.searchsorted(speeds, v, side="right") - 1, 0, speeds.size - 2))
    w = (math.log(v) - math.log(speeds[j])) / (math.log(speeds[j + 1]) - math.log(speeds[j]))
    return j, min(max(w, 0.0), 1.0)


def _at_speed(grid: JointGrid, column: str, v: float) -> np.ndarray:
    """(G, E, R, 3) simulated (timing s, vmax_1, vmax_2 m/s) at striker speed v: the
    timing linear in (log v, log t) as in the gap-only fit, the peaks as v_max / v_s
    linear in log v (a packed chain's v_max / v_s does not depend on v_s)."""
    j, w = _speed_weight(grid.speeds, v)
    k = min(j + 1, grid.speeds.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        T = grid.values[column]
        t = np.exp((1 - w) * np.log(T[:, :, j]) + w * np.log(T[:, :, k]))
        pk = [v * ((1 - w) * grid.values[c][:, :, j] / grid.speeds[j]
                   + w * grid.values[c][:, :, k] / grid.speeds[k])
              for c in ("v_max_1", "v_max_2")]
    out = np.stack([t, *pk], axis=-1)
    return np.where(out > 0, out, np.nan)


def _weights(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    j = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
    w = (x - nodes[j]) / (nodes[j + 1] - nodes[j])
    return j, np.clip(w, 0.0, 1.0)


def _interp_param(A: np.ndarray, coords: np.ndarray, u: np.ndarray,
                  axis: int = 1) -> np.ndarray:
    """A (..., P, ...) -> (..., len(u), ...) along ``axis``: log A linear in the fitted
    key's coordinate (nodes ``coords``, points ``u``; ``FitKey.coord``)."""
    j, w = _weights(coords, np.asarray(u, float))
    shape = [1] * A.ndim
    shape[axis] = w.size
    w = w.reshape(shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        L = np.log(A)
        return np.exp((1 - w) * np.take(L, j, axis=axis) + w * np.take(L, j + 1, axis=axis))


def _interp_g(A: np.ndarray, gaps: np.ndarray, g: np.ndarray) -> np.ndarray:
    """A (G, ...) -> (len(g), ...), linear in the mean gap."""
    j, w = _weights(gaps, np.asarray(g, float))
    w = w.reshape((-1,) + (1,) * (A.ndim - 1))
    return (1 - w) * A[j] + w * A[j + 1]


def joint_values(grid: JointGrid, column: str, v: float, g, p) -> np.ndarray:
    """(len(g), R, 3) simulated (timing, vmax_1, vmax_2) at speed v and the pairs
    (g[i], p[i]) of mean gap and the fitted key's value."""
    A = _at_speed(grid, column, v)                                    # (G, P, R, 3)
    g, p = np.atleast_1d(np.asarray(g, float)), np.atleast_1d(np.asarray(p, float))
    jg, wg = _weights(grid.gaps, g)
    je, we = _weights(grid.coords, grid.fit_key.coord(p))
    out = 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        L = np.log(A)
        for dj, ww in ((0, 1 - wg), (1, wg)):
            row = L[jg + dj]                                              # (n, E, R, 3)
            n = np.arange(g.size)
            Le = (1 - we)[:, None, None] * row[n, je] + we[:, None, None] * row[n, je + 1]
            out = out + ww[:, None, None] * np.exp(Le)
    return out


def joint_interp_errors(grid: JointGrid, column: str) -> dict:
    """Relative interpolation error of each observable (the timing ``column``, v_max_1,
    v_max_2), measured on the grid as in the gap-only fit (each interior node against the
    interpolation of its two neighbours, 95th percentile / 4): ``g`` per mean-gap node (G;
    an end node takes its neighbour's; the error changes by orders of magnitude over the
    gaps, so it is interpolated between the nodes), ``param`` (along the fitted key) and
    ``speed`` one value each."""
    names = (column, "v_max_1", "v_max_2")
    out = {}
    for name in names:
        A = grid.values[name]                                            # (G, P, S, R)
        if name != column:
            A = A / grid.speeds[None, None, :, None]
        g = grid.gaps
        w = ((g[1:-1] - g[:-2]) / (g[2:] - g[:-2]))[:, None, None, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            node = np.abs(A[1:-1] - ((1 - w) * A[:-2] + w * A[2:])) / A[1:-1]
        per = np.array([_p95(x) for x in node]) / 4.0                     # (G - 2,)
        g_err = np.concatenate([[per[0]], per, [per[-1]]])                # every node
        e_err = s_err = 0.0
        if grid.params.size >= 3:
            es = grid.coords
            w = ((es[1:-1] - es[:-2]) / (es[2:] - es[:-2]))[None, :, None, None]
            with np.errstate(invalid="ignore", divide="ignore"):
                mid = np.exp((1 - w) * np.log(A[:, :-2]) + w * np.log(A[:, 2:]))
                e_err = _p95(np.abs(A[:, 1:-1] - mid) / A[:, 1:-1]) / 4.0
        if grid.speeds.size >= 3:
            lv = np.log(grid.speeds)
            w = ((lv[1:-1] - lv[:-2]) / (lv[2:] - lv[:-2]))[None, None, :, None]
            with np.errstate(invalid="ignore", divide="ignore"):
                if name == column:
                    mid = np.exp((1 - w) * np.log(A[:, :, :-2]) + w * np.log(A[:, :, 2:]))
                else:
                    mid = (1 - w) * A[:, :, :-2] + w * A[:, :, 2:]
                s_err = _p95(np.abs(A[:, :, 1:-1] - mid) / A[:, :, 1:-1]) / 4.0
        out[name] = {"g": g_err, "param": e_err, "speed": s_err}
    return out


def _p95(x: np.ndarray) -> float:
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    return float(np.percentile(x, 95)) if x.size else 0.0


def _model_rel(errs: dict, column: str, fine_g: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """(F_g, 3) relative model error of (timing, vmax_1, vmax_2) at each fine mean gap."""
    cols = []
    for name in (column, "v_max_1", "v_max_2"):
        d = errs[name]
        cols.append(np.sqrt(np.interp(fine_g, gaps, d["g"]) ** 2 + d["param"] ** 2
                            + d["speed"] ** 2))
    return np.stack(cols, axis=-1)

