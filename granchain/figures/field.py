"""The field's chains, beyond the chapter: a precompressed chain (precompression study) and
the chapter's chain ending on a wall (wall study).

Draws into ``{out}.png`` and ``{out}.pdf`` from tables/precompression.csv and
tables/wall.csv; the numbers come from granchain.reductions (``precompression_rows``,
``wall_fits``) and the theory from granchain.analytic.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..reductions import (SOLITARY_WALL_EXPONENT, label, precompression_rows, radius_or_default,
                        wall_fits)
from ..analytic import precompressed_speed_ratio
from .style import colormap, drawn, figure, plain_log, save


def _load_colors(loads):
    """A colour per dead load, dark for the unloaded chain to bright for the largest load."""
    cmap = colormap("viridis")
    k = max(len(loads) - 1, 1)
    return {F0: cmap(0.85 * i / k) for i, F0 in enumerate(loads)}


@drawn
def precompression(df: pd.DataFrame, out, radius=None) -> list[Path]:
    """v_g against v_s for each dead load F0 (left) and v_g / c0 against the amplitude
    ratio f_r = F_m/F0 (right), with the sound speed c0 and Nesterenko's solitary-wave
    speed in a precompressed chain (Daraio et al. 2006, Eq. (3)).

    Left, per F0: v_g from peak times (filled) and from half-peak arrival times (hollow);
    dotted, c0; dashed, the theory's V_s at each member's measured peak velocity v_m (the
    probes' mean; for F0 = 0 Nesterenko's uncompressed wave). Right, loaded chains: the
    same members against f_r - 1 of their v_m (log scale: the weak waves, f_r -> 1, spread
    out), with V_s(f_r)/c0 as a curve."""
    radius = radius_or_default(radius)
    rows = precompression_rows(df, radius)
    fig, (ax, axr) = figure(ncols=2, size=(11.0, 4.4))
    mats = list(dict.fromkeys(rows["material"]))
    for mat in mats:
        d = rows[rows["material"] == mat]
        loads = sorted(set(d["F0_N"]))
        col = _load_colors(loads)
        for F0 in loads:
            g = d[d["F0_N"] == F0]
            x = g["v_striker_m_s"].to_numpy(dtype=float)
            name = f"F0 = {F0:.3g} N" if F0 > 0 else "F0 = 0"
            ax.plot(x, g["v_g_m_s"].to_numpy(dtype=float), "o", color=col[F0], ls="none",
                    label=f"{name}: v_g (peak times)")
            ax.plot(x, g["v_g_front_m_s"].to_numpy(dtype=float), "o", mfc="none",
                    mec=col[F0], ls="none", ms=7)
            ax.plot(x, g["V_theory_m_s"].to_numpy(dtype=float), "--", color=col[F0], lw=1.0)
            if F0 > 0:
                c0 = float(g["c0_m_s"].iloc[0])
                ax.plot([x.min(), x.max()], [c0, c0], ":", color=col[F0], lw=1.2)
                fr = g["f_r"].to_numpy(dtype=float)
                axr.plot(fr - 1.0, g["vg_over_c0"].to_numpy(dtype=float), "o", color=col[F0],
                         ls="none", label=f"{name} (c0 = {c0:.0f} m/s): v_g / c0")
                axr.plot(fr - 1.0, g["v_g_front_m_s"].to_numpy(dtype=float) / c0, "o",
                         mfc="none", mec=col[F0], ls="none", ms=7)
        fr_all = d["f_r"].to_numpy(dtype=float)
        fr_all = fr_all[np.isfinite(fr_all)]
        if fr_all.size:
            ff = np.geomspace((fr_all.min() - 1.0) / 1.5, (fr_all.max() - 1.0) * 1.5, 200)
            axr.plot(ff, precompressed_speed_ratio(1.0 + ff), "-", color="0.2", lw=1.1,
                     label="Nesterenko: V_s / c0 (Daraio et al. 2006, Eq. 3)")
    ax.plot([], [], "o", mfc="none", mec="0.3", ms=7, ls="none",
            label="hollow: v_g from half-peak arrival times")
    ax.plot([], [], ":", color="0.3", label="c0 = 2R sqrt(k2/m), k2 = (3/2) K^(2/3) F0^(1/3)")
    ax.plot([], [], "--", color="0.3", label="Nesterenko's V_s at each chain's v_m\n"
            "(F0 = 0: (16/25)^(1/5) c^(4/5) v_m^(1/5))")
    ax.set_xscale("log")
    plain_log(ax, "x", subs=(1.0, 2.0, 5.0))
    ax.set_xlabel("striker velocity v_s (m/s), log scale")
    ax.set_ylabel("group velocity (m/s)")
    ax.set_title(f"{', '.join(label(m) for m in mats)} chain on a wall under a dead load F0: "
                 "v_g vs v_s", fontsize=8.5)
    top = float(np.nanmax(rows[["v_g_m_s", "v_g_front_m_s", "V_theory_m_s"]].to_numpy(dtype=float)))
    ax.set_ylim(None, 1.45 * top)          # room for the legend above the data
    ax.legend(loc="upper left", fontsize=6.5, ncol=2)
    axr.axhline(1.0, color="0.6", lw=0.8)
    axr.set_xscale("log")
    axr.set_xlabel("f_r - 1, f_r = F_m / F0 the amplitude ratio of the wave's v_m (log scale)")
    axr.set_ylabel("v_g / c0")
    axr.set_title("loaded chains against the amplitude ratio (filled: peak times, "
                  "hollow: arrival)", fontsize=8.5)
    axr.legend(loc="upper left", fontsize=6.5)
    fig.suptitle("Precompressed chain: group velocity against c0 and Nesterenko's "
                 "solitary wave (beyond the chapter)", fontsize=9)
    fig.tight_layout()
    return save(fig, out)


@drawn
def wall(df: pd.DataFrame, out) -> list[Path]:
    """The wall's force peak F_wall (its dynamic part, above the static preload) against
    v_s, log-log (top), with the power-law fit F_wall = a v_s^b and the Hertz solitary
    wave's v_s^(6/5) (dashed, fitted prefactor); bottom, F_wall / (a' v_s^(6/5)): flat
    where the 6/5 law holds (the title gives the range of the local exponents between
    neighbouring speeds)."""
    fits = wall_fits(df)
    fig, (ax, axr) = figure(nrows=2, size=(6.4, 6.0), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.6]})
    for k, (mat, f) in enumerate(fits.items()):
        c = ("#d62728", "#1f77b4", "#2ca02c")[k % 3]
        v, F = f["v"], f["F"]
        ax.plot(v, F, "o", color=c, ls="none",
                label=f"{label(mat)} chain: wall force peak ({f['n']} speeds"
                      + (f", {f['missing']} not measured)" if f["missing"] else ")"))
        if v.size >= 2:
            vv = np.geomspace(v.min(), v.max(), 60)
            ax.plot(vv, f["prefactor"] * vv ** f["exponent"], "-", color=c, lw=1.0,
                    label=f"fit: {f['prefactor']:.4g} N x (v_s / 1 m/s)^{f['exponent']:.4f}")
            ax.plot(vv, f["prefactor_solitary"] * vv ** SOLITARY_WALL_EXPONENT, "--", color="0.3",
                    lw=1.0, label=f"Hertz solitary wave: {f['prefactor_solitary']:.4g} N x "
                                  "v_s^(6/5)")
            axr.plot(v, F / (f["prefactor_solitary"] * v ** SOLITARY_WALL_EXPONENT), "o-",
                     color=c, lw=0.8, label=f"{label(mat)}: F_wall / ({f['prefactor_solitary']:.4g}"
                                            " N v_s^(6/5))")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log(ax, "y")
    ax.set_ylabel("wall force peak F_wall (N), log scale")
    mats = ", ".join(label(m) for m in fits)
    wall_txt = "; ".join(
        f"{label(m)}: exponent {f['exponent']:.4f}" + (
            f", local {f['local'].min():.4f}-{f['local'].max():.4f}" if f["local"].size else "")
        for m, f in fits.items())
    ax.set_title(f"The chapter's chain ({mats}) ending on a wall: F_wall vs v_s\n"
                 f"({wall_txt}; Hertz: 6/5)", fontsize=8.5)
    ax.legend(loc="upper left", fontsize=7)
    axr.axhline(1.0, color="0.5", lw=0.8)
    axr.set_xscale("log")
    plain_log(axr, "x", subs=(1.0, 2.0, 5.0))
    axr.set_xlabel("striker velocity v_s (m/s), log scale")
    axr.set_ylabel("ratio to the 6/5 law")
    axr.legend(loc="best", fontsize=6.5)
    fig.tight_layout()
    return save(fig, out)
