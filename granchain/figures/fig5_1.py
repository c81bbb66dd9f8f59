"""Chapter Fig. 5.1, the packed chain: particle velocities in time (5.1a), v_max vs v_s
with fits through the origin (5.1b), v_g vs v_s with Nesterenko's curve (5.1c).

Each function draws one panel into ``{out}.png`` and ``{out}.pdf`` from a trace or the
packed_sweep table; the numbers come from granchain.reductions.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..reductions import (NEEDS, PROBES, arrived, label, material, peak_profile,
                        reference_engine, require, vmax_columns, vmax_fits)
from ..analytic import nesterenko_speed
from ..errors import GranchainError
from .style import color, colormap, drawn, figure, material_style, plain_log, save

CHAPTER_VMAX_SLOPE = 0.64          # chapter Fig. 5.1b fit (used only as a drawn reference)


@drawn
def fig5_1a(trace: dict, out) -> list[Path]:
    """Chapter Fig. 5.1a: velocity of every particle vs time, packed chain, one trace."""
    for k in NEEDS["trace"]:
        if k not in trace:
            raise GranchainError(f"fig5_1a: trace lacks '{k}'; regenerate it with the workflow")
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    t = np.asarray(trace["t_s"], dtype=float) * 1e6
    v = np.asarray(trace["v_m_s"], dtype=float)
    if v.ndim != 2 or v.shape[0] != t.size:
        raise GranchainError(f"fig5_1a: trace v_m_s has shape {v.shape}, expected "
                             f"({t.size}, n); regenerate it with the workflow")
    vs = float(trace["v_striker_m_s"])
    mat = str(trace["material"])
    n = v.shape[1]
    fig, ax = figure(size=(6.4, 4.0))
    cmap = colormap("viridis")
    for i in range(n):
        ax.plot(t, v[:, i] * 1e3, color=cmap(i / max(n - 1, 1)), lw=1.0)
    vmax = v.max(axis=0)
    p1, p2 = PROBES
    if n >= p2:
        for p, dx, ha in ((p1, 8, "left"), (p2, -6, "right")):
            j = int(np.argmax(v[:, p - 1]))
            ax.annotate(f"particle {p}: v_max = {vmax[p - 1] / vs:.3f} v_s",
                        xy=(t[j], vmax[p - 1] * 1e3), xytext=(dx, 12),
                        textcoords="offset points", ha=ha, fontsize=7.5,
                        arrowprops={"arrowstyle": "-", "lw": 0.6})
    # particles whose peak lies at the trace's end were cut off by the run's end time
    cut = [i + 1 for i in range(n) if int(np.argmax(v[:, i])) >= t.size - 2 or vmax[i] <= 0]
    note = (f"\ntrace ends before particle{'s' if len(cut) > 1 else ''} "
            f"{', '.join(map(str, cut))} peak{'' if len(cut) > 1 else 's'} (the run stops "
            "before the wave has crossed the chain)") if cut else ""
    sm = ScalarMappable(cmap=cmap, norm=Normalize(1, n))
    cb = fig.colorbar(sm, ax=ax, pad=0.02)
    cb.set_label("particle index (1 = striker)")
    ax.set_xlabel("time t (us)")
    ax.set_ylabel("particle velocity (mm/s)")
    ax.set_xlim(t[0], t[-1])
    ax.set_title(f"Packed {label(mat)} chain, n = {n}, striker v_s = {vs:g} m/s "
                 f"(chapter Fig. 5.1a)" + note, fontsize=8.5)
    fig.tight_layout()
    return save(fig, out)




@drawn
def fig5_1b(packed: pd.DataFrame, out) -> list[Path]:
    """Chapter Fig. 5.1b: v_max,1 and v_max,2 vs v_s, both materials, fit through 0."""
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.patches import Patch
    fits = vmax_fits(packed)
    packed = reference_engine(packed)
    fig, (ax, ax2) = figure(ncols=2, size=(10.0, 4.2))
    p1, p2 = PROBES
    marker = {"v_max_1": "o", "v_max_2": "s"}
    ls = {"v_max_1": "-", "v_max_2": "--"}
    vmax_all = vmax_columns(packed)
    xs_max = float(packed["v_striker_m_s"].max())
    xx = np.linspace(0.0, xs_max * 1.05, 50)
    handles, labels = [], []
    for k, (mat, fit) in enumerate(fits.items()):
        st = material_style(mat, k)
        lw = 2.2 if k == 0 else 0.9
        alpha = 0.45 if k == 0 else 1.0
        d = packed[packed["material"] == mat].sort_values("v_striker_m_s")
        x = d["v_striker_m_s"].to_numpy(dtype=float)
        for c in ("v_max_1", "v_max_2"):
            y = d[c + "_m_s"].to_numpy(dtype=float)
            a = fit[c]
            h1, = ax.plot(x, y, marker[c], ls="none", color=color(mat), **st)
            h2, = ax.plot(xx, a * xx, ls[c], color=color(mat), lw=lw, alpha=alpha)
            handles.append((h1, h2))
            labels.append(f"{label(mat)} v_max,{c[-1]} (particle {p1 if c == 'v_max_1' else p2}):"
                          f" fit {a:.4f} v_s")
            ax2.plot(x, y / x, marker[c], ls=ls[c], color=color(mat), lw=lw * 0.6,
                     alpha=1.0, **st)
        if vmax_all:
            prof = peak_profile(d, "fig5_1b")[:, p1 - 1:]
            ax2.fill_between(x, prof.min(axis=1), prof.max(axis=1), color=color(mat),
                             alpha=0.10, lw=0)
    hc, = ax.plot(xx, CHAPTER_VMAX_SLOPE * xx, ":", color="0.35", lw=1.0)
    handles.append(hc)
    labels.append(f"chapter fit v_max = {CHAPTER_VMAX_SLOPE} v_s")
    ax.legend(handles, labels, handler_map={tuple: HandlerTuple(ndivide=None)},
              loc="upper left", handlelength=3.0)
    ax.set_xlim(0, xs_max * 1.05)
    ax.set_ylim(0, None)
    ax.set_xlabel("striker velocity v_s (m/s)")
    ax.set_ylabel("maximum particle velocity v_max (m/s)")
    ax.set_title("v_max vs v_s, packed chains; least-squares fits through the origin")
    ax2.axhline(CHAPTER_VMAX_SLOPE, ls=":", color="0.35", lw=1.0)
    h2 = [Patch(color=color(m), alpha=0.25, label=f"{label(m)}: range of v_max,i / v_s, "
                f"particles {p1}..{p2}") for m in fits]
    h2.append(ax2.plot([], [], ":", color="0.35", label="chapter 0.64")[0])
    ax2.legend(handles=h2, loc="lower right")
    ax2.set_xscale("log")
    plain_log(ax2, "x", subs=(1.0, 2.0, 5.0))
    ax2.set_xlabel("striker velocity v_s (m/s), log scale")
    ax2.set_ylabel("v_max / v_s")
    ax2.set_title("normalised (markers as left): flat = linear law")
    ax2.set_ylim(0.45, 0.8)
    if len(fits) > 1:
        same = max(abs(fits[m]["v_max_1"] / next(iter(fits.values()))["v_max_1"] - 1)
                   for m in fits)
        ax2.text(0.02, 0.50, f"materials differ by at most {same:.1e} (relative) in the\n"
                 "v_max,1 slope: v_max / v_s does not depend on E, rho (Hertz scaling)",
                 transform=ax2.transAxes, fontsize=7, va="top", color="0.25")
    fig.suptitle("Chapter Fig. 5.1b counterpart", fontsize=9)
    fig.tight_layout()
    return save(fig, out)


@drawn
def fig5_1c(packed: pd.DataFrame, out) -> list[Path]:
    """Chapter Fig. 5.1c: v_g vs v_s with Nesterenko's curve at v_m = slope * v_s."""
    require(packed, NEEDS["fig5_1c"], "fig5_1c")
    fits = vmax_fits(packed)
    packed = reference_engine(packed)
    fig, (ax, axr) = figure(nrows=2, size=(6.4, 5.2), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.3]})
    vmin = float(packed["v_striker_m_s"].min())
    vmax = float(packed["v_striker_m_s"].max())
    xx = np.geomspace(vmin / 1.3, vmax * 1.3, 100)
    for k, mat in enumerate(fits):
        st = material_style(mat, k)
        m = material(mat)
        d = arrived(packed[packed["material"] == mat]).sort_values("v_striker_m_s")
        a = fits[mat]["v_max_2"]
        x = d["v_striker_m_s"].to_numpy(dtype=float)
        y = d["v_g_m_s"].to_numpy(dtype=float)
        ax.plot(x, y, "o", ls="none", color=color(mat), **st,
                label=f"{label(mat)} simulated v_g (Eq. 5.1)")
        ax.plot(xx, nesterenko_speed(m, a * xx), "-", color=color(mat), lw=0.9,
                label=f"{label(mat)} Nesterenko, v_m = {a:.4f} v_s (fit of 5.1b)")
        ax.plot(xx, nesterenko_speed(m, CHAPTER_VMAX_SLOPE * xx), ":", color=color(mat),
                lw=0.9, label=f"{label(mat)} Nesterenko, v_m = 0.64 v_s (chapter)")
        axr.plot(x, y / nesterenko_speed(m, a * x), "o-", color=color(mat), lw=0.8, **st,
                 label=f"{label(mat)}: v_g / fit curve")
        axr.plot(x, y / nesterenko_speed(m, CHAPTER_VMAX_SLOPE * x), "^:", color=color(mat),
                 lw=0.8, **st, label=f"{label(mat)}: v_g / 0.64 curve")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log(ax, "y")
    ax.set_ylabel("group velocity v_g (m/s), log scale")
    ax.set_title("v_g vs v_s, packed chains, with Nesterenko's solitary-wave speed\n"
                 "(chapter Fig. 5.1c counterpart)")
    ax.legend(loc="upper left")
    axr.axhline(1.0, color="0.3", lw=0.8)
    axr.set_xscale("log")
    plain_log(axr, "x", subs=(1.0, 2.0, 5.0))
    axr.set_xlabel("striker velocity v_s (m/s), log scale")
    axr.set_ylabel("v_g / Nesterenko")
    axr.legend(loc="best", ncol=2, fontsize=6.5)
    fig.tight_layout()
    return save(fig, out)
