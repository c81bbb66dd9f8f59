"""Counterpart of the chapter's Fig. 5.3c for an inference (``granchain infer --plot``):
v_g against v_s with the measured points, the band the inferred mean gap predicts, and
the chapter's Eq. 5.4 line.

Measured points: v_g = (p2 - p1)(2R + g)/dt with g the inferred median (0 where none was
measured). Band: the 2.5-97.5 % range of the simulated v_g over the posterior of the mean
gap and the gap realisations (the grid of ``granchain.inference``), interpolated to each
speed. Lines: the packed chain (g = 0) and Eq. 5.4 at the least-squares Eq. 5.4 gap.
"""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from ..analytic import eq54_group_velocity
from ..fileio import atomic_write_bytes
from .style import drawn, figure, plain_log

FORMATS = (".png", ".pdf", ".svg")



def outside_note(res) -> str:
    """A title's warning when the model check flagged the data (``data_outside_model``):
    the interval drawn is then not calibrated."""
    mc = res.data_outside_model
    if not mc["flag"]:
        return ""
    p = mc["p_value"]
    return ("\nDATA OUTSIDE THE SIMULATED REALISATIONS"
            + (f" (p = {p:.2g})" if math.isfinite(p) else "") + ": interval not calibrated")

def predicted_vg(res, base, speeds, draws: int = 200):
    """(lo, median, hi) of simulated v_g (m/s) at each striker speed of ``speeds``, over
    ``draws`` posterior quantiles of the mean gap x the grid's realisations."""
    from ..inference.interpolation import _interp_gap, _interp_speed
    grid = res.grid
    span = base.probes[1] - base.probes[0]
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (res.posterior_pdf[1:] + res.posterior_pdf[:-1])
                                            * np.diff(res.posterior_g_m))])
    cdf /= cdf[-1]
    g = np.interp((np.arange(draws) + 0.5) / draws, cdf, res.posterior_g_m)
    T = _interp_gap(grid.timings[res.timing_column], grid.gaps, g)          # (D, S, R)
    out = []
    for v in speeds:
        t = _interp_speed(T, grid.speeds, float(v))                         # (D, R)
        vg = span * (2 * base.radius + g[:, None]) / t
        out.append(np.nanpercentile(vg, [2.5, 50, 97.5]))
    return np.array(out).T


@drawn
def plot_inference(res, meas, base, path, force: bool = False) -> Path:
    """Draw the figure into ``path`` (.png, .pdf or .svg), atomically, never replacing an
    existing file without ``force``."""
    from ..inference.interpolation import _interp_speed
    grid = res.grid
    span = base.probes[1] - base.probes[0]
    two_r = 2 * base.radius
    v = np.geomspace(grid.speeds[0], grid.speeds[-1], 40) if grid.speeds.size > 1 else grid.speeds
    lo, med, hi = predicted_vg(res, base, v)
    dt0 = np.array([np.nanmedian(_interp_speed(grid.timings[res.timing_column][0], grid.speeds,
                                               float(x))) for x in v])
    vg0 = span * two_r / dt0
    g_hat = res.gap_mean_m if math.isfinite(res.gap_mean_m) else 0.0
    fig, ax = figure(size=(6.0, 4.2))
    ax.fill_between(v, lo, hi, color="#e377c2", alpha=0.35, lw=0,
                    label="simulated, inferred mean gap (95 %)")
    ax.plot(v, med, "-", color="#8c1d6b", label="simulated median")
    ax.plot(v, vg0, "-", color="#6a3d9a", lw=1.0, label="packed chain (gap = 0)")
    if math.isfinite(res.eq54_gap_m):
        ax.plot(v, eq54_group_velocity(vg0, res.eq54_gap_m, v, base.radius), "--", color="#1f77b4",
                label=f"Eq. 5.4, gbar = {res.eq54_gap_m * 1e9:.1f} nm (chapter's reading)")
    ax.errorbar(meas.v, span * (two_r + g_hat) / meas.t,
                yerr=span * (two_r + g_hat) * meas.err / meas.t**2, fmt="o", color="k",
                ms=4, label="measurements")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("striker velocity v_s (m/s)")
    ax.set_ylabel("group velocity v_g (m/s)")
    ci = "n/a" if not math.isfinite(res.ci95_m[1]) else \
        f"[{res.ci95_m[0] * 1e9:.1f}, {res.ci95_m[1] * 1e9:.1f}] nm"
    med_txt = "n/a" if not math.isfinite(res.gap_mean_m) else f"{res.gap_mean_m * 1e9:.1f} nm"
    ax.set_title(f"{base.material.name}: inferred mean gap {med_txt}, 95 % {ci}\n"
                 f"({res.timing_column}, {res.n_simulated} simulated chains)"
                 + outside_note(res))
    ax.legend(loc="best")
    path = Path(path)
    fmt = path.suffix.lower()
    buf = io.BytesIO()
    meta = {"Software": None} if fmt == ".png" else (
        {"CreationDate": None, "ModDate": None, "Producer": None, "Creator": None}
        if fmt == ".pdf" else {"Date": None, "Creator": None})
    fig.savefig(buf, format=fmt[1:], metadata=meta)
    return atomic_write_bytes(path, buf.getvalue(), force, "--plot")


# ---------------------------------------------------------------------------------------
# the joint fit (--fit gap_mean,restitution)
# ---------------------------------------------------------------------------------------
def joint_bands(res, speeds):
    """(3, 3, len(speeds)): for (timing, vmax_1 / v_s, vmax_2 / v_s) the 2.5, 50 and
    97.5 % of the simulated values over the posterior draws x the grid's realisations at
    each striker speed (no measurement noise)."""
    from ..inference import joint_values
    out = np.full((3, 3, len(speeds)), np.nan)
    if res.draws.size == 0:
        return out
    for k, v in enumerate(speeds):
        X = joint_values(res.grid, res.timing_column, float(v), res.draws[:, 0],
                         res.draws[:, 1]).reshape(-1, 3)
        X = X[np.all(np.isfinite(X), axis=1)] / np.array([1.0, v, v])
        if X.size:
            out[:, :, k] = np.percentile(X, [2.5, 50, 97.5], axis=0).T
    return out


def _zoom(x, pdf, pad: float = 0.5):
    """(lo, hi) around the mass of a 1D density on the points x: its 0.05-99.95 % range
    widened by ``pad`` of its width on each side, inside the grid."""
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(x))])
    if not cdf[-1] > 0:
        return float(x[0]), float(x[-1])
    a, b = np.interp([5e-4, 1 - 5e-4], cdf / cdf[-1], x)
    w = max(b - a, 1e-3 * (x[-1] - x[0]))
    return max(float(x[0]), a - pad * w), min(float(x[-1]), b + pad * w)


def _interval(ax, lo, hi, med, color):
    if math.isfinite(lo) and math.isfinite(hi):
        ax.axvspan(lo, hi, color=color, alpha=0.15, lw=0, label="95 % interval")
    if math.isfinite(med):
        ax.axvline(med, color=color, lw=1.2, label="median")


@drawn
def plot_joint_inference(res, meas, base, path, force: bool = False) -> Path:
    """The joint fit's figure into ``path`` (.png, .pdf or .svg): the joint posterior of
    (mean gap, e), its two marginals, and the timing and both probes' peaks against the
    striker speed, measured (error bars: the stated one-sigma errors) and simulated at the
    posterior (95 % band over posterior draws and gap realisations, and its median)."""
    from ..inference import fit_key
    grid = res.grid
    fk = fit_key(res.key)
    sym = fk.fit.symbol
    unit = "" if fk.key.unit == "1" else f" ({fk.key.unit})"
    axis_label = f"{fk.fit.label} {sym}{unit}"
    fig, axes = figure(ncols=3, nrows=2, size=(11.0, 6.6))
    (a_joint, a_g, a_e), (a_t, a_v1, a_v2) = axes
    g_nm = res.posterior_g_m * 1e9
    if np.any(res.posterior_pdf > 0):
        P = res.posterior_pdf.T / np.max(res.posterior_pdf)
        a_joint.pcolormesh(g_nm, res.posterior_p, P, shading="auto", cmap="Purples")
        a_joint.contour(g_nm, res.posterior_p, P, levels=[np.exp(-3.0), np.exp(-0.5)],
                        colors=["#6a3d9a", "#3f007d"], linewidths=0.9)
    if math.isfinite(res.gap_mean_m) and math.isfinite(res.param):
        a_joint.plot([res.gap_mean_m * 1e9], [res.param], "+", color="k", ms=9,
                     label="posterior medians")
        a_joint.legend(loc="best")
    g_lim = [x * 1e9 for x in _zoom(res.posterior_g_m, res.marginal_g)]
    # the key's marginal is a density per its coordinate (log p for a log-uniform prior)
    e_lim = [float(fk.value(u)) for u in _zoom(fk.coord(res.posterior_p), res.marginal_p)]
    if fk.log:
        a_joint.set_yscale("log")
        a_e.set_xscale("log")
    a_joint.set_xlim(*g_lim)
    a_joint.set_ylim(*e_lim)
    a_g.set_xlim(*g_lim)
    a_e.set_xlim(*e_lim)
    a_joint.set_xlabel("mean gap (nm)")
    a_joint.set_ylabel(axis_label)
    a_joint.set_title(f"joint posterior (correlation {res.posterior_correlation:+.2f});\n"
                      "contours at exp(-1/2) and exp(-3) of its peak")
    a_g.plot(g_nm, res.marginal_g / 1e9, color="#8c1d6b")
    _interval(a_g, res.ci95_m[0] * 1e9, res.ci95_m[1] * 1e9, res.gap_mean_m * 1e9, "#8c1d6b")
    a_g.set_xlabel("mean gap (nm)")
    a_g.set_ylabel("posterior density (1/nm)")
    ci = ("n/a" if not math.isfinite(res.ci95_m[1]) or not math.isfinite(res.ci95_m[0])
          else f"[{res.ci95_m[0] * 1e9:.1f}, {res.ci95_m[1] * 1e9:.1f}] nm")
    med = "n/a" if not math.isfinite(res.gap_mean_m) else f"{res.gap_mean_m * 1e9:.1f} nm"
    a_g.set_title(f"mean gap {med}, 95 % {ci}" + outside_note(res))
    a_g.legend(loc="best")
    a_e.plot(res.posterior_p, res.marginal_p, color="#1f77b4")
    _interval(a_e, *res.param_ci95, res.param, "#1f77b4")
    a_e.set_xlabel(axis_label)
    a_e.set_ylabel("posterior density" + (f" (per log {sym})" if fk.log else ""))
    eci = ("n/a" if not all(math.isfinite(x) for x in res.param_ci95)
           else f"[{res.param_ci95[0]:.4g}, {res.param_ci95[1]:.4g}]")
    emed = "n/a" if not math.isfinite(res.param) else f"{res.param:.4g}"
    a_e.set_title(f"{sym} {emed}, 95 % {eci}")
    a_e.legend(loc="best")
    v = (np.geomspace(grid.speeds[0], grid.speeds[-1], 25) if grid.speeds.size > 1
         else grid.speeds)
    band = joint_bands(res, v)
    data = (meas.t * 1e6, meas.vmax_1 / meas.v, meas.vmax_2 / meas.v)
    errs = (meas.err * 1e6, meas.peak_err / meas.v, meas.peak_err / meas.v)
    scale = (1e6, 1.0, 1.0)
    p1, p2 = base.probes[:2]
    labels = (f"{res.timing_column} (us), probes {p1} to {p2}", f"v_max at probe {p1} / v_s",
              f"v_max at probe {p2} / v_s")
    for k, ax in enumerate((a_t, a_v1, a_v2)):
        ax.fill_between(v, band[k, 0] * scale[k], band[k, 2] * scale[k], color="#e377c2",
                        alpha=0.35, lw=0, label="simulated at the posterior (95 %)")
        ax.plot(v, band[k, 1] * scale[k], "-", color="#8c1d6b", label="simulated median")
        ax.errorbar(meas.v, data[k], yerr=errs[k], fmt="o", color="k", ms=4,
                    label="measurements")
        ax.set_xscale("log")
        plain_log(ax, "x", subs=(1.0, 2.0, 5.0))
        ax.set_xlabel("striker velocity v_s (m/s)")
        ax.set_ylabel(labels[k])
    a_t.legend(loc="upper right")
    a_t.set_title(f"{base.material.name}: {res.rows} row(s) on {res.chains} chain(s)")
    a_v1.set_title(f"{res.n_simulated} simulated chains")
    outside = "n/a" if res.predictive_outside is None else res.predictive_outside
    a_v2.set_title(f"predictive check: {outside} of {res.predictive_values} values outside "
                   "95 %")
    fig.tight_layout()
    path = Path(path)
    fmt = path.suffix.lower()
    buf = io.BytesIO()
    meta = {"Software": None} if fmt == ".png" else (
        {"CreationDate": None, "ModDate": None, "Producer": None, "Creator": None}
        if fmt == ".pdf" else {"Date": None, "Creator": None})
    fig.savefig(buf, format=fmt[1:], metadata=meta)
    return atomic_write_bytes(path, buf.getvalue(), force, "--plot")
