"""The chapter's questions, beyond Eq. 5.1: can a sphere-size tolerance alone make Fig.
5.3b's oscillation (radius_spread study), and which contact dissipation gives the measured
peaks of Fig. 5.2 (dissipation study), and which yielding (plasticity study) or adhesive
(adhesion study) contacts?

Draws into ``{out}.png`` and ``{out}.pdf`` from tables/radius_spread.csv and
tables/dissipation.csv; the numbers come from granchain.reductions (``spread_oscillation``,
``first_reaching``, ``dissipation_curves``, ``dissipation_match``, ``MEASURED_PEAKS``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.ticker import FuncFormatter

from ..reductions import (MEASURED_PEAKS, PROBES, capture_velocities, cohesion_curves,
                        cohesion_match,
                        dissipation_curves, dissipation_match,
                        first_reaching, label, n_particles, peak_profile, plasticity_curves,
                        plasticity_match, reference_engine, spread_oscillation)
from .style import color, colormap, drawn, figure, material_style, save

CHAPTER_OSCILLATION = 0.20      # Fig. 5.3b: "peak velocity oscillates by ~20%"


def _pct(x: float) -> str:
    return "nan" if not np.isfinite(x) else f"{100 * x:.1f}%"


@drawn
def radius_spread(df: pd.DataFrame, out) -> list[Path]:
    """Left: the chapter's Fig. 5.3b measure, (max - min)/mean of v_max,i / v_s over
    particles 2..13, against the radius sd (log scale): median over each sd's chains
    (line) and their 5-95% band; the packed chain's value (dashed), the chains with random
    gaps (median, dash-dotted, and 5-95% band) and the chapter's ~20% (dotted). The title
    says at which sd the median reaches the gapped chains' median, or that it does not in
    the study's range. Right: the median v_max,i / v_s along the chain per sd, the packed
    chain and the gapped chains."""
    osc = spread_oscillation(df)
    d = reference_engine(df)
    fig, (ax, axp) = figure(ncols=2, size=(11.0, 4.4))
    mats = list(dict.fromkeys(osc["material"]))
    answers = []
    for mat in mats:
        o = osc[osc["material"] == mat]
        packed, spread, gaps = (o[o["kind"] == k] for k in ("packed", "spread", "gaps"))
        x = spread["radius_sd_m"].to_numpy(dtype=float) * 1e6
        if x.size:
            ax.fill_between(x, spread["osc_p5"], spread["osc_p95"], color=color(mat),
                            alpha=0.25, lw=0, label="5-95% of chains")
            ax.plot(x, spread["osc_median"].to_numpy(dtype=float), "o-", color=color(mat),
                    label=f"{label(mat)}, radius spread: median over "
                          f"{int(spread['n'].max())} chains")
        xr = [x.min(), x.max()] if x.size else [0.1, 1.0]
        pv = float(packed["osc_median"].iloc[0]) if len(packed) else np.nan
        if len(packed):
            ax.plot(xr, [pv, pv], "--", color="k", lw=1.0,
                    label=f"packed chain, equal spheres: {_pct(pv)}")
        for _, g in gaps.iterrows():
            ax.fill_between(xr, [g["osc_p5"]] * 2, [g["osc_p95"]] * 2, color="#e377c2",
                            alpha=0.25, lw=0)
            ax.plot(xr, [g["osc_median"]] * 2, "-.", color="#8c1d6b",
                    label=f"{g['gap_mean_nm']:g} nm gaps, equal spheres: median "
                          f"{_pct(g['osc_median'])} (5-95%: {_pct(g['osc_p5'])}-"
                          f"{_pct(g['osc_p95'])}, {int(g['n'])} chains)")
            # the sd at which the spread's median reaches the gapped chains' (sd 0: packed)
            sx = np.concatenate([[0.0], x]) if len(packed) else x
            sy = np.concatenate([[pv], spread["osc_median"].to_numpy(dtype=float)]) \
                if len(packed) else spread["osc_median"].to_numpy(dtype=float)
            sd_hit = first_reaching(sx, sy, float(g["osc_median"]))
            answers.append(
                f"{label(mat)}: the median reaches the {g['gap_mean_nm']:g} nm gaps' "
                f"{_pct(g['osc_median'])} at sd = {sd_hit:.3g} um" if np.isfinite(sd_hit) else
                f"{label(mat)}: the median never reaches the {g['gap_mean_nm']:g} nm gaps' "
                f"{_pct(g['osc_median'])} for sd <= {x.max():g} um (largest "
                f"{_pct(sy[-1])})")
        ax.plot(xr, [CHAPTER_OSCILLATION] * 2, ":", color="0.3", lw=1.2,
                label="chapter: ~20% with 20 nm gaps (Fig. 5.3b)")
    ax.set_xscale("log")
    ax.set_xlabel("standard deviation of the radii, sd (um), log scale")
    ax.set_ylabel(f"(max - min)/mean of v_max,i, i = {PROBES[0]}..{PROBES[1]}")
    ax.set_ylim(0.0, max(0.3, 1.25 * float(np.nanmax(osc["osc_p95"]))))
    ax.set_title("Sphere-size tolerance alone: spread of v_max along the chain\n"
                 + "; ".join(answers), fontsize=7.5)
    ax.legend(loc="upper left", fontsize=6.5)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    # right: the median peak profiles (5-95% bands: the gaps and the largest sd)
    n = n_particles(d)
    idx = np.arange(1, n + 1)
    sds = sorted({float(s) for s in d["radius_sd_m"] if s > 0})
    cmap = colormap("viridis")
    col = {s: cmap(0.9 * k / max(len(sds) - 1, 1)) for k, s in enumerate(sds)}
    for mat in mats:
        dm = d[d["material"] == mat]
        for key, g in dm.groupby(["radius_sd_m", "gap_mean_nm"], sort=True):
            prof = peak_profile(g, "radius_spread", last=n)
            med = np.median(prof, axis=0)
            lo, hi = np.percentile(prof, [5, 95], axis=0)
            sd, gap = float(key[0]), float(key[1])
            if gap > 0:
                axp.fill_between(idx, lo, hi, color="#e377c2", alpha=0.25, lw=0)
                axp.plot(idx, med, "o-", color="#8c1d6b", ms=3,
                         label=f"{gap:g} nm gaps (median, 5-95%)")
            elif sd > 0:
                if sd == sds[-1]:
                    axp.fill_between(idx, lo, hi, color=col[sd], alpha=0.25, lw=0)
                axp.plot(idx, med, "-", color=col[sd], lw=1.0,
                         label=f"sd = {sd * 1e6:g} um (median" +
                               (", 5-95%)" if sd == sds[-1] else ")"))
            else:
                axp.plot(idx, med, "s-", color="k", mfc="none", ms=4, label="packed chain")
    axp.set_xlabel(f"particle index (1 = striker, {n} = the free end)")
    axp.set_ylabel("peak velocity v_max,i / v_s")
    axp.set_xticks(idx)
    axp.set_ylim(0.35, 1.05)
    vss = ", ".join(f"{v:g}" for v in sorted(set(d["v_striker_m_s"].astype(float))))
    axp.set_title(f"{'/'.join(label(m) for m in mats)} chain, v_s = {vss} m/s: peak profiles",
                  fontsize=8.5)
    axp.legend(loc="lower center", fontsize=6.5, ncol=3)
    fig.suptitle("Can a sphere-size tolerance alone make the chapter's ~20% oscillation "
                 "(Fig. 5.3b)? (beyond the chapter)", fontsize=9)
    fig.tight_layout()
    return save(fig, out)


# the panels of the dissipation figure: (curve quantity, y label, measured band key)
DISSIPATION_PANELS = (("v1", "v_max,1 / v_s (particle 2)", "v1"),
                      ("v2", "v_max,2 / v_s (particle 13)", "v2"),
                      ("ratio", "v_max,2 / v_max,1", "ratio"),
                      ("vg", "v_g (m/s), peak times", None))


@drawn
def dissipation(df: pd.DataFrame, out) -> list[Path]:
    """v_max,1 / v_s, v_max,2 / v_s, v_max,2 / v_max,1 and v_g against the coefficient of
    restitution e, one curve per material and mean gap (median over its chains; 5-95%
    band for the gapped ones), with the chapter's measured bands (grey: value and its 95%
    interval, Fig. 5.2b, 5.2c). Dotted verticals: for each curve, the largest e at which
    its median v_max,2/v_max,1 is the measured 0.80, marked on every panel at the curve's
    value there."""
    c = dissipation_curves(df)
    m = dissipation_match(df)
    fig, axes = figure(ncols=2, nrows=2, size=(10.0, 7.6), sharex=True)
    axes = axes.ravel()
    groups = list(c.groupby(["material", "gap_mean_nm", "v_striker_m_s"], sort=False))
    several_v = c["v_striker_m_s"].nunique() > 1
    order = list(dict.fromkeys(c["material"]))
    for ax, (q, ylab, band_key) in zip(axes, DISSIPATION_PANELS):
        if band_key is not None:
            val, half = MEASURED_PEAKS[band_key]
            ax.axhspan(val - half, val + half, color="0.75", alpha=0.45, lw=0)
            ax.axhline(val, color="0.35", lw=1.0,
                       label=f"measured (chapter, 95%): {val:g} +/- {half:g}")
            left = q == "ratio"          # where the panel's curves leave room
            ax.text(0.02 if left else 0.98, val - half, f" measured: {val:g} +/- {half:g} ",
                    fontsize=7, color="0.25", ha="left" if left else "right", va="bottom",
                    transform=ax.get_yaxis_transform())
        for (mat, gap, vs), g in groups:
            e = g["restitution_e"].to_numpy(dtype=float)
            what = f"{label(mat)}, " + ("packed" if gap == 0 else f"{gap:g} nm gaps") + \
                (f", v_s = {vs:g} m/s" if several_v else "")
            if gap > 0:
                ax.fill_between(e, g[f"{q}_p5"], g[f"{q}_p95"], color=color(mat), alpha=0.18,
                                lw=0)
                ax.plot(e, g[f"{q}_median"].to_numpy(dtype=float), "s--", color=color(mat),
                        ms=3.5, mfc="none", label=what)
            else:
                # packed chains of different materials coincide (Hertz scaling): the first
                # drawn large and hollow, the next small and filled on top
                ax.plot(e, g[f"{q}_median"].to_numpy(dtype=float), "o-", color=color(mat),
                        label=what, **material_style(mat, order.index(mat)))
            r = m[(m["material"] == mat) & (m["gap_mean_nm"] == gap)
                  & (m["v_striker_m_s"] == vs)].iloc[0]
            if np.isfinite(r["e_ratio"]):
                ax.axvline(r["e_ratio"], color=color(mat), ls=":", lw=0.9)
                # the curve's value there: the ratio is 0.80 by construction
                y = MEASURED_PEAKS["ratio"][0] if q == "ratio" else r[q]
                ax.plot([r["e_ratio"]], [y], "*", color=color(mat), ms=9, mec="k", mew=0.5)
        ax.set_ylabel(ylab)
        ax.set_title(ylab + " against e", fontsize=8.5)
    for ax in axes[2:]:
        ax.set_xlabel("coefficient of restitution e (contact_damping, "
                      f"{df['damping_model'].iloc[0]})")
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    handles, _ = axes[3].get_legend_handles_labels()
    handles += [Patch(color="0.75", alpha=0.6, label="measured, chapter: value and 95% "
                      "interval"),
                Line2D([], [], color="0.3", ls=":", marker="*", ms=8, mec="k", mew=0.5,
                       label="e where the median v_max,2/v_max,1 = 0.80")]
    axes[3].legend(handles=handles, loc="center", bbox_to_anchor=(0.5, 0.7), fontsize=6.5,
                   ncol=2)
    lines = []
    for _, r in m.iterrows():
        gap = "packed" if r["gap_mean_nm"] == 0 else f"{r['gap_mean_nm']:g} nm"
        lines.append(
            f"{label(r['material'])} {gap}: ratio 0.80 at e = {r['e_ratio']:.3f}, there "
            f"v_max,1 = {r['v1']:.3f} v_s, v_max,2 = {r['v2']:.3f} v_s (measured 0.57, 0.46: "
            f"x {r['striker_v1']:.3f}, x {r['striker_v2']:.3f})"
            if np.isfinite(r["e_ratio"]) else
            f"{label(r['material'])} {gap}: the ratio never reaches 0.80 "
            f"(e = {r['e_max']:g}: {r['ratio_at_e_max']:.3f})")
    fig.suptitle("Contact dissipation against the chapter's measured peaks (beyond the "
                 "chapter)\n" + "\n".join(lines), fontsize=7.5)
    fig.tight_layout()
    return save(fig, out)


def _measured(ax, band_key) -> None:
    """The chapter's measured value of a panel's quantity and its 95% interval (grey), if
    it has one (``MEASURED_PEAKS``)."""
    if band_key is not None:
        val, half = MEASURED_PEAKS[band_key]
        ax.axhspan(val - half, val + half, color="0.75", alpha=0.45, lw=0)
        ax.axhline(val, color="0.35", lw=1.0)


def _smallest_gap(c: pd.DataFrame, mat: str) -> pd.DataFrame:
    """The curves of material ``mat`` at its smallest mean gap (packed when there)."""
    cm = c[c["material"] == mat]
    return cm[cm["gap_mean_nm"] == cm["gap_mean_nm"].min()]


def _log_panels(axes, against: str, xlabel: str) -> None:
    """The 2 x 2 panels of DISSIPATION_PANELS on a log x axis: titles, labels, legend."""
    for ax, (_, ylab, _) in zip(axes, DISSIPATION_PANELS):
        ax.set_xscale("log")
        ax.set_ylabel(ylab)
        ax.set_title(f"{ylab} against {against}", fontsize=8.5)
    for ax in axes[2:]:
        ax.set_xlabel(xlabel)
    axes[3].legend(loc="best", fontsize=5.5, ncol=2)


def _shades(n: int) -> list:
    """n colours along viridis, light to dark, its ends left out."""
    cmap = colormap("viridis")
    return [cmap(0.15 + 0.7 * i / max(n - 1, 1)) for i in range(n)]


@drawn
def plasticity(df: pd.DataFrame, out) -> list[Path]:
    """v_max,1 / v_s, v_max,2 / v_s, v_max,2 / v_max,1 and v_g against the striker speed
    (log), one panel row per quantity pair, one curve per material and limiting pressure
    p_y (median over the chains of the material's smallest mean gap; the elastic chain
    black, the p_y from light to dark as they fall), with the chapter's measured bands
    (grey: value and its 95% interval, Fig. 5.2b, 5.2c). The title gives, per material,
    the p_y at which the median v_max,1 is the measured 0.57 v_s at the study's slowest and
    fastest speeds (:func:`~granchain.reductions.plasticity_match`)."""
    c = plasticity_curves(df)
    m = plasticity_match(df)
    fig, axes = figure(ncols=2, nrows=2, size=(10.0, 7.6), sharex=True)
    axes = axes.ravel()
    mats = list(dict.fromkeys(c["material"]))
    dashes = ("-", "--", "-.", ":")
    for ax, (q, ylab, band_key) in zip(axes, DISSIPATION_PANELS):
        _measured(ax, band_key)
        for k, mat in enumerate(mats):
            cm = _smallest_gap(c, mat)
            pys = sorted(set(cm["yield_pressure_Pa"]), reverse=True)
            finite = [p for p in pys if np.isfinite(p)]
            shades = _shades(len(finite))
            for py in pys:
                g = cm[cm["yield_pressure_Pa"] == py].sort_values("v_striker_m_s")
                if np.isfinite(py):
                    col, what = shades[finite.index(py)], f"p_y = {py / 1e6:.3g} MPa"
                else:
                    col, what = "k", "elastic"
                ax.plot(g["v_striker_m_s"], g[f"{q}_median"], "o", ls=dashes[k % 4],
                        color=col, ms=3.5, lw=1.0, label=f"{label(mat)}, {what}")
    _log_panels(axes, "v_s", "striker speed v_s (m/s)")
    lines = []
    for mat in mats:
        mm = m[(m["material"] == mat)]
        mm = mm[mm["gap_mean_nm"] == mm["gap_mean_nm"].min()].sort_values("v_striker_m_s")
        ends = [mm.iloc[0], mm.iloc[-1]]
        lines.append(f"{label(mat)}: v_max,1 = 0.57 v_s at p_y = " + ", ".join(
            (f"{r['py_v1'] / 1e6:.3g} MPa" if np.isfinite(r["py_v1"]) else "none")
            + f" ({r['v_striker_m_s']:g} m/s)" for r in ends))
    fig.suptitle("Thornton's yielding contacts against the measured peaks\n"
                 + "; ".join(lines), fontsize=8.5)
    return save(fig, out)


@drawn
def adhesion(df: pd.DataFrame, out) -> list[Path]:
    """v_max,1 / v_s, v_max,2 / v_s, v_max,2 / v_max,1 and v_g against the surface energy
    gamma (log), one curve per material, striker speed and groove setting (median over the
    chains of the material's smallest mean gap; solid: the contacts adhere, dashed: the
    groove's flats too), the chain without adhesion as a hollow marker at the panel's left
    edge, with the chapter's measured bands (grey: value and its 95% interval). The title
    gives, per material and groove setting, the gamma at which the median v_max,1 is the
    measured 0.57 v_s at the study's lowest speed (:func:`~granchain.reductions.cohesion_match`)."""
    c = cohesion_curves(df)
    m = cohesion_match(df)
    fig, axes = figure(ncols=2, nrows=2, size=(10.0, 7.6), sharex=True)
    axes = axes.ravel()
    mats = list(dict.fromkeys(c["material"]))
    speeds = sorted(set(c["v_striker_m_s"]))
    shade = dict(zip(speeds, _shades(len(speeds))))
    g_min = float(c.loc[c["surface_energy_J_m2"] > 0, "surface_energy_J_m2"].min())
    for ax, (q, ylab, band_key) in zip(axes, DISSIPATION_PANELS):
        _measured(ax, band_key)
        for k, mat in enumerate(mats):
            cm = _smallest_gap(c, mat)
            marker = "os^v"[k % 4]
            for (vs, groove), g in cm[cm["surface_energy_J_m2"] > 0].groupby(
                    ["v_striker_m_s", "groove_cohesion"]):
                ax.plot(g["surface_energy_J_m2"], g[f"{q}_median"], marker,
                        ls="--" if groove else "-", color=shade[vs], ms=3.5, lw=1.0,
                        label=f"{label(mat)}, v_s = {vs:g} m/s"
                              + (", groove too" if groove else ""))
            none = cm[cm["surface_energy_J_m2"] == 0].sort_values("v_striker_m_s")
            for _, r in none.iterrows():
                ax.plot([g_min / 2], [r[f"{q}_median"]], marker, mfc="none",
                        color=shade[r["v_striker_m_s"]], ms=6)
    _log_panels(axes, "gamma", "surface energy gamma (J/m^2; hollow: no adhesion)")
    lines = []
    for (mat, groove), mm in m.groupby(["material", "groove_cohesion"], sort=False):
        mm = mm[mm["gap_mean_nm"] == mm["gap_mean_nm"].min()].sort_values("v_striker_m_s")
        r = mm.iloc[0]
        lines.append(f"{label(mat)}{' + groove' if groove else ''}: 0.57 v_s at "
                     + (f"gamma = {r['gamma_v1']:.3g} J/m^2" if np.isfinite(r["gamma_v1"])
                        else "no gamma of the study") + f" ({r['v_striker_m_s']:g} m/s)")
    fig.suptitle("Adhesive contacts against the measured peaks\n" + "; ".join(lines),
                 fontsize=8.5)
    return save(fig, out)


@drawn
def capture(df: pd.DataFrame, out) -> list[Path]:
    """Two adhesive spheres. Left: the measured restitution e against v_s (log) of each
    surface energy's separated collisions, the captured ones as crosses at e = 0. Right:
    the capture velocity v_c against gamma (log-log; :func:`~granchain.reductions.capture_velocities`:
    the median of v_s sqrt(1 - e^2)), with the bracket between the fastest captured and
    the slowest separated collision as a bar, and the JKR scaling v_c ~ gamma^(5/6)
    (dotted) through the largest gamma's v_c."""
    cv = capture_velocities(df)
    fig, (ax, axc) = figure(ncols=2, size=(10.0, 4.2))
    gammas = sorted(set(df["surface_energy_J_m2"]))
    shade = dict(zip(gammas, _shades(len(gammas))))
    for (mat, gamma), g in df.groupby(["material", "surface_energy_J_m2"], sort=True):
        sep = g[g["pair_collision"] == "separated"].sort_values("v_striker_m_s")
        cap = g[g["pair_collision"] == "captured"].sort_values("v_striker_m_s")
        ax.plot(sep["v_striker_m_s"], sep["pair_restitution"], "o-", color=shade[gamma], ms=3.5,
                lw=1.0, label=f"{label(mat)}, gamma = {gamma:g} J/m^2")
        ax.plot(cap["v_striker_m_s"], np.zeros(len(cap)), "x", color=shade[gamma], ms=6)
    ax.set_xscale("log")
    ax.set_xlabel("striker speed v_s (m/s)")
    ax.set_ylabel("restitution e (separated); x: captured")
    ax.set_title("restitution against v_s", fontsize=8.5)
    ax.legend(loc="best", fontsize=6)
    for mat, c in cv.groupby("material", sort=False):
        ok = c[np.isfinite(c["v_c"])]
        axc.plot(ok["surface_energy_J_m2"], ok["v_c"], "o-", color=color(mat), ms=4,
                 label=f"{label(mat)}: v_c = median v_s sqrt(1 - e^2)")
        for _, r in c.iterrows():
            if np.isfinite(r["v_captured_max"]) and np.isfinite(r["v_separated_min"]):
                axc.plot([r["surface_energy_J_m2"]] * 2, [r["v_captured_max"],
                         r["v_separated_min"]], "-", color=color(mat), lw=3, alpha=0.35)
        if len(ok):
            g1, v1 = ok["surface_energy_J_m2"].iloc[-1], ok["v_c"].iloc[-1]
            x = np.array([ok["surface_energy_J_m2"].min(), g1])
            axc.plot(x, v1 * (x / g1) ** (5 / 6), ":", color="0.3", lw=1.0,
                     label="JKR scaling v_c ~ gamma^(5/6)")
    axc.set_xscale("log")
    axc.set_yscale("log")
    axc.set_xlabel("surface energy gamma (J/m^2)")
    axc.set_ylabel("capture velocity v_c (m/s)")
    axc.set_title("capture velocity against gamma (bar: fastest captured to slowest "
                  "separated)", fontsize=8.5)
    axc.legend(loc="best", fontsize=6)
    return save(fig, out)
