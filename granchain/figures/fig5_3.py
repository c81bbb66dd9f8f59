"""Chapter Fig. 5.3, chains with random gaps: peak velocity along a chain with 20 nm
mean gaps (5.3b), v_g vs v_s for each mean gap with bands and the Eq. 5.4 bound (5.3c).

Each function draws one panel into ``{out}.png`` and ``{out}.pdf`` from the gap_profile
or gap_sweep table and the packed_sweep table; the numbers come from granchain.reductions.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..reductions import (NEEDS, PROBES, arrived, band, label, materials_in, n_particles,
                        oscillation, packed_profile, packed_vg, peak_profile,
                        radius_or_default, reference_engine, require)
from ..analytic import eq54_group_velocity
from .style import colormap, drawn, figure, plain_log, save


@drawn
def fig5_3b(gap_profile: pd.DataFrame, packed: pd.DataFrame | None, out) -> list[Path]:
    """Chapter Fig. 5.3b: v_max,i / v_s along a chain with random gaps (20 nm mean)."""
    require(gap_profile, NEEDS["fig5_3b"], "fig5_3b")
    d = reference_engine(gap_profile)
    mats = materials_in(d)
    prof = peak_profile(d, "fig5_3b", last=n_particles(d))   # every particle's peak is measured
    n_show = prof.shape[1]
    idx = np.arange(1, n_show + 1)
    p1, p2 = PROBES
    osc = oscillation(prof[:, :p2])      # the chapter's stretch, clear of the free chain end
    fig, ax = figure(size=(6.4, 4.2))
    for row in prof:
        ax.plot(idx, row, "-", color="0.55", lw=0.5, alpha=0.35)
    lo, med, hi = np.nanpercentile(prof, [5, 50, 95], axis=0)
    gaps = ", ".join(f"{g:g}" for g in sorted(set(d["gap_mean_nm"].astype(float))))
    vss = sorted(set(d["v_striker_m_s"].astype(float)))
    ax.fill_between(idx, lo, hi, color="#e377c2", alpha=0.3, lw=0,
                    label=f"5-95% over {len(prof)} realisations")
    ax.plot(idx, med, "o-", color="#8c1d6b", label="median over realisations")
    ax.plot([], [], "-", color="0.55", lw=0.5, label="single realisations")
    first = d["realisation"].astype(int).to_numpy().argmin()
    ax.plot(idx, prof[first], "-", color="#1f77b4", lw=1.0,
            label=f"realisation {int(d['realisation'].iloc[first])} (one chain)")
    packed_txt = ""
    if packed is not None:
        for mat in mats:
            p, vs_ref = packed_profile(packed, mat, vss[0], "fig5_3b")
            if p is not None:
                ax.plot(idx[:p.size], p[:n_show], "s-", color="k", mfc="none",
                        label=f"packed {label(mat)} chain (v_s = {vs_ref:g} m/s)")
                packed_txt = (f"\npacked chain on the same measure: "
                              f"{oscillation(p[None, :p2])[0]:.1%} (monotone decay)")
    o_lo, o_med, o_hi = band(osc)
    ax.text(0.98, 0.04,
            f"spread along the chain, (max - min)/mean of v_max,i, i = {p1}..{p2}:\n"
            f"median {o_med:.1%} (5-95%: {o_lo:.1%} - {o_hi:.1%})  [chapter: ~20%]"
            + packed_txt,
            transform=ax.transAxes, ha="right", va="bottom", fontsize=7.5,
            bbox={"boxstyle": "round", "fc": "white", "ec": "0.7"})
    ax.set_xlabel(f"particle index (1 = striker, {n_show} = the free end)")
    ax.set_ylabel("peak velocity v_max,i / v_s")
    ax.set_xticks(idx)
    ax.set_ylim(0.4, 1.1)
    ax.set_title(f"{'/'.join(label(m) for m in mats)} chain with random gaps, mean {gaps} nm, "
                 f"v_s = {', '.join(f'{v:g}' for v in vss)} m/s\n(chapter Fig. 5.3b counterpart)")
    ax.legend(loc="lower left")
    fig.tight_layout()
    return save(fig, out)


@drawn
def fig5_3c(gap_sweep: pd.DataFrame, packed: pd.DataFrame, out, radius=None) -> list[Path]:
    """Chapter Fig. 5.3c: v_g vs v_s for each mean gap, bands, packed curve, Eq. 5.4."""
    require(gap_sweep, NEEDS["fig5_3c"], "fig5_3c")
    require(packed, NEEDS["packed_reference"], "fig5_3c packed reference")
    d = reference_engine(gap_sweep)
    mats = materials_in(d)
    gaps = sorted(set(d["gap_mean_nm"].astype(float)))
    radius = radius_or_default(radius)
    cmap = colormap("viridis")
    gcol = {g: cmap(0.9 * k / max(len(gaps) - 1, 1)) for k, g in enumerate(gaps)}
    fig, axes = figure(ncols=len(mats), size=(max(5.0 * len(mats), 6.4), 5.6),
                        sharey=True, squeeze=False)
    vall = np.array(sorted(set(d["v_striker_m_s"].astype(float))))
    xx = np.geomspace(vall.min(), vall.max(), 60) if vall.size > 1 else vall
    for ax, mat in zip(axes[0], mats):
        dm = d[d["material"] == mat]
        pk = packed[(packed["material"] == mat)]
        pa = arrived(reference_engine(pk)).sort_values("v_striker_m_s")
        ax.plot(pa["v_striker_m_s"], pa["v_g_m_s"], "o-", color="k", lw=1.6, ms=3.5,
                label="packed chain (gap = 0)", zorder=5)
        vg0 = packed_vg(packed, mat, xx)
        missing = []
        for g in gaps:
            dg = dm[dm["gap_mean_nm"].astype(float) == g]
            if dg.empty:
                continue
            ok = arrived(dg)
            nfail = len(dg) - len(ok)
            if nfail:
                missing.append(f"{g:g} nm: {nfail}/{len(dg)}")
            st = ok.groupby("v_striker_m_s")["v_g_m_s"]
            if len(ok):
                x = np.array(sorted(st.groups), dtype=float)
                q = np.array([band(st.get_group(v)) for v in x])
                ax.fill_between(x, q[:, 0], q[:, 2], color=gcol[g], alpha=0.28, lw=0)
                ax.plot(x, q[:, 1], "-", color=gcol[g], lw=1.0)
            ax.plot(xx, eq54_group_velocity(vg0, g * 1e-9, xx, radius), "--", color=gcol[g],
                    lw=0.9)
        ax.set_xscale("log")
        ax.set_yscale("log")
        plain_log(ax, "x", subs=(1.0, 2.0, 5.0))
        ax.set_xlabel("striker velocity v_s (m/s), log scale")
        nr = int(dm.groupby(["gap_mean_nm", "v_striker_m_s"]).size().max())
        note = ("not arrived (excluded): " + "; ".join(missing)) if missing else \
            "every member arrived"
        ax.set_title(f"{label(mat)}: up to {nr} realisations per (gap, v_s)\n{note}",
                     fontsize=7.5)
    axes[0][0].set_ylabel("group velocity v_g (m/s), log scale")
    plain_log(axes[0][0], "y", subs=(1.0, 2.0, 5.0))
    # legend: gap colours + line styles, in the empty lower-right corner
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    handles = [Line2D([], [], color="k", marker="o", ms=3.5, lw=1.6, label="packed chain")]
    handles += [Patch(color=gcol[g], alpha=0.5, label=f"mean gap {g:g} nm") for g in gaps]
    handles += [Line2D([], [], color="0.3", lw=1.0, label="median over realisations"),
                Patch(color="0.6", alpha=0.5, label="5-95% of arrived realisations"),
                Line2D([], [], color="0.3", ls="--", lw=0.9,
                       label="Eq. 5.4 bound at the mean gap")]
    ncol = min(len(handles), 5 if len(mats) > 1 else 3)
    nrow = -(-len(handles) // ncol)
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=7)
    fig.suptitle("v_g vs v_s with random gaps (chapter Fig. 5.3c counterpart)", fontsize=9)
    fig.tight_layout(rect=(0, 0.032 * nrow + 0.01, 1, 1))
    return save(fig, out)
