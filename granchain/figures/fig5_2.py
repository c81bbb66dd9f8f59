"""Chapter Fig. 5.2, the vibrometer: true against recorded velocities of the probes (5.2a
counterpart) and what the instrument does to v_max,1, v_max,2 and dt against its
bandwidth (the vibrometer study).

Each function draws into ``{out}.png`` and ``{out}.pdf`` from the vibrometer trace or
table; the numbers come from granchain.reductions (the recordings from
granchain.vibrometer, in the workflow's vibrometer job).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..reductions import NEEDS, label, vibrometer_bands
from ..errors import GranchainError
from .style import drawn, figure, plain_log, save

FILTER_COLOR = {"butterworth": "#1f77b4", "bessel": "#d62728"}
PROBE_STYLE = ("-", "-")
PROBE_COLOR = ("#2ca02c", "#9467bd")
# the chapter's measured peaks as a fraction of its own simulation (Fig. 5.2c against
# 0.89 and 0.64 v_s), drawn for scale on the ratio panels
CHAPTER_MEASURED_OVER_SIMULATED = {"v_max,1": 0.57 / 0.89, "v_max,2": 0.46 / 0.64}
CHAPTER_BANDWIDTH_MHZ = 2.5


@drawn
def fig5_2a(trace: dict, out) -> list[Path]:
    """True and recorded velocities of the two probes, one panel per filter."""
    for k in NEEDS["vibrometer_trace"]:
        if k not in trace:
            raise GranchainError(f"fig5_2a: trace lacks '{k}'; regenerate it with the workflow")
    t = np.asarray(trace["t_s"], dtype=float) * 1e6
    v = np.asarray(trace["v_m_s"], dtype=float)
    tr = np.asarray(trace["t_rec_s"], dtype=float) * 1e6
    vs = float(trace["v_striker_m_s"])
    probes = [int(p) for p in trace["probes"]]
    filters = list(trace["filters"])
    fig, axes = figure(ncols=len(filters), size=(5.2 * len(filters), 4.0), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, f in zip(axes, filters):
        rec = np.asarray(trace[f"v_rec_{f}_m_s"], dtype=float)
        for j, p in enumerate(probes):
            ax.plot(t, v[:, j] / vs, PROBE_STYLE[j], color=PROBE_COLOR[j], lw=1.0, alpha=0.55,
                    label=f"particle {p}, true")
            ax.plot(tr, rec[:, j] / vs, "--", color=PROBE_COLOR[j], lw=1.4,
                    label=f"particle {p}, recorded")
            vt, tt = trace["vmax_true_m_s"][j], 1e6 * trace["t_peak_true_s"][j]
            vr, trp = trace[f"vmax_rec_{f}_m_s"][j], 1e6 * trace[f"t_peak_rec_{f}_s"][j]
            ax.plot([tt], [vt / vs], "o", color=PROBE_COLOR[j], ms=4)
            ax.plot([trp], [vr / vs], "s", mfc="none", color=PROBE_COLOR[j], ms=5)
            ax.annotate(f"recorded/true peak {vr / vt:.4f}\ndelay {1e3 * (trp - tt):+.0f} ns",
                        xy=(trp, vr / vs), xytext=(8, -4 - 22 * j), textcoords="offset points",
                        fontsize=7)
        ax.set_xlabel("time t (us)")
        ax.set_title(f"{f} order {int(trace['order'])}, -3 dB at "
                     f"{trace['bandwidth_hz'] / 1e6:g} MHz, {trace['sampling_rate_hz'] / 1e6:g} MS/s",
                     fontsize=8.5)
        ax.set_xlim(t[0], t[-1])
    axes[0].set_ylabel("v / v_s")
    axes[0].legend(loc="center", fontsize=7)
    fig.suptitle(f"Packed {label(str(trace['material']))} chain, v_s = {vs:g} m/s: what the "
                 "vibrometers record (chapter Fig. 5.2a counterpart)", fontsize=9)
    fig.tight_layout()
    return save(fig, out)


@drawn
def vibrometer(table: pd.DataFrame, out) -> list[Path]:
    """Recorded/true v_max,1 and v_max,2 and the relative dt bias against bandwidth:
    median over striker speeds (and realisations) with the min-max band, per filter and
    chain (packed solid, gapped dashed)."""
    b = vibrometer_bands(table)
    fig, axes = figure(ncols=3, size=(13.0, 4.2))
    panels = [("v1", "recorded / true v_max,1", "v_max,1"),
              ("v2", "recorded / true v_max,2", "v_max,2"),
              ("dt", "(dt_recorded - dt) / dt", None)]
    gaps = sorted(set(b["gap_mean_nm"].astype(float)))
    for ax, (q, ylabel, chap) in zip(axes, panels):
        for (mat, g, f), d in b.groupby(["material", "gap_mean_nm", "filter"], sort=True):
            d = d.sort_values("bandwidth_hz")
            x = d["bandwidth_hz"].to_numpy(dtype=float) / 1e6
            ls = "-" if g == 0 else "--"
            name = "packed" if g == 0 else f"{g:g} nm gaps"
            ax.plot(x, d[f"{q}_median"], ls, marker="o", color=FILTER_COLOR.get(f, "0.3"),
                    label=f"{f}, {name}" + (f" ({label(mat)})" if b["material"].nunique() > 1
                                            else ""))
            ax.fill_between(x, d[f"{q}_min"], d[f"{q}_max"], color=FILTER_COLOR.get(f, "0.3"),
                            alpha=0.12 if g == 0 else 0.06, lw=0)
        ax.axvline(CHAPTER_BANDWIDTH_MHZ, color="0.3", ls=":", lw=1.0)
        ax.set_xscale("log")
        plain_log(ax, "x", subs=(1.0, 2.0, 5.0))
        ax.set_xlabel("vibrometer bandwidth (MHz, -3 dB)")
        ax.set_ylabel(ylabel)
        if chap is not None:
            ax.axhline(1.0, color="0.5", lw=0.8)
            r = CHAPTER_MEASURED_OVER_SIMULATED[chap]
            ax.axhline(r, color="0.2", ls="-.", lw=1.0)
            ax.annotate(f"chapter: measured / its simulated {chap} = {r:.2f}", xy=(0.02, r),
                        xycoords=("axes fraction", "data"), xytext=(0, 3),
                        textcoords="offset points", fontsize=7)
            ax.set_ylim(min(r - 0.03, ax.get_ylim()[0]), max(1.03, ax.get_ylim()[1]))
        else:
            ax.axhline(0.0, color="0.5", lw=0.8)
    n_cut = int((b["n"] - b["n_final"]).sum())
    axes[0].legend(fontsize=7, loc="center right")
    fig.suptitle("What a causal low-pass vibrometer does to the chapter's observables "
                 f"(median over striker speeds, band: min-max; dotted: the chapter's "
                 f"{CHAPTER_BANDWIDTH_MHZ:g} MHz"
                 + (f"; {n_cut} recordings cut by the run's end are left out)" if n_cut
                    else ")") + f"; gaps {', '.join(f'{g:g}' for g in gaps)} nm", fontsize=8.5)
    fig.tight_layout()
    return save(fig, out)
