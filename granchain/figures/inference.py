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
from .style import drawn, figure

FORMATS = (".png", ".pdf", ".svg")


def predicted_vg(res, base, speeds, draws: int = 200):
    """(lo, median, hi) of simulated v_g (m/s) at each striker speed of ``speeds``, over
    ``draws`` posterior quantiles of the mean gap x the grid's realisations."""
    from ..inference import _interp_gap, _interp_speed
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
    from ..inference import _interp_speed
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
                 f"({res.timing_column}, {res.n_simulated} simulated chains)")
    ax.legend(loc="best")
    path = Path(path)
    fmt = path.suffix.lower()
    buf = io.BytesIO()
    meta = {"Software": None} if fmt == ".png" else (
        {"CreationDate": None, "ModDate": None, "Producer": None, "Creator": None}
        if fmt == ".pdf" else {"Date": None, "Creator": None})
    fig.savefig(buf, format=fmt[1:], metadata=meta)
    return atomic_write_bytes(path, buf.getvalue(), force, "--plot")
