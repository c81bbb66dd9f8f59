"""Chapter Fig. 5.4b, loose chains: v_g vs the mean gap inferred from the extra chain
length, with the Eq. 5.4 bound.

Draws into ``{out}.png`` and ``{out}.pdf`` from the extra_length and packed_sweep
tables; the numbers come from granchain.reductions.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..reductions import (NEEDS, PROBES, arrived, band, label, materials_in, n_particles,
                        packed_vg, radius_or_default, reference_engine, require)
from ..analytic import eq54_group_velocity
from .style import color, drawn, figure, save


@drawn
def fig5_4b(extra: pd.DataFrame, packed: pd.DataFrame, out, radius=None) -> list[Path]:
    """Chapter Fig. 5.4b: v_g vs gbar = extra_length/(n-1) at fixed v_s, with Eq. 5.4."""
    require(extra, NEEDS["fig5_4b"], "fig5_4b")
    require(packed, NEEDS["packed_reference"], "fig5_4b packed reference")
    d = reference_engine(extra)
    mats = materials_in(d)
    n = n_particles(d)
    radius = radius_or_default(radius)
    fig, axes = figure(ncols=len(mats), size=(max(4.6 * len(mats), 6.4), 4.4),
                        sharey=True, squeeze=False)
    for ax, mat in zip(axes[0], mats):
        dm = d[d["material"] == mat]
        vss = sorted(set(dm["v_striker_m_s"].astype(float)))
        ok = arrived(dm)
        nfail = len(dm) - len(ok)
        gb = ok["extra_length_um"].to_numpy(dtype=float) * 1e3 / (n - 1)
        ax.plot(gb, ok["v_g_m_s"], "o", color=color(mat), alpha=0.45, ms=3, mew=0,
                label="single realisations at gbar = extra/" + str(n - 1))
        if "gap_mean_probes_nm" in ok.columns:
            ax.plot(ok["gap_mean_probes_nm"], ok["v_g_m_s"], "x", color="0.45", ms=3.5,
                    mew=0.7, label=f"same, at their realised gbar between\n"
                                   f"probes {PROBES[0]} and {PROBES[1]}")
        st = ok.groupby("extra_length_um")["v_g_m_s"]
        xs = np.array(sorted(st.groups), dtype=float)
        if xs.size:
            q = np.array([band(st.get_group(v)) for v in xs])
            ax.errorbar(xs * 1e3 / (n - 1), q[:, 1], yerr=[q[:, 1] - q[:, 0], q[:, 2] - q[:, 1]],
                        fmt="o", color="k", mfc=color(mat), capsize=3, lw=0.9,
                        label="median, 5-95%")
        span = np.asarray(sorted(set(dm["extra_length_um"].astype(float)))) * 1e3 / (n - 1)
        if "gap_mean_probes_nm" in ok.columns and len(ok):
            span = np.concatenate([span, ok["gap_mean_probes_nm"].to_numpy(dtype=float)])
        gg = np.linspace(span.min() * 0.9, span.max() * 1.05, 80)
        for vs in vss:
            vg0 = float(packed_vg(packed, mat, vs)[0])
            ax.plot(gg, eq54_group_velocity(vg0, gg * 1e-9, vs, radius), "--", color="0.2",
                    lw=1.0, label=f"Eq. 5.4 bound (v_s = {vs:g} m/s,\npacked v_g = {vg0:.0f} m/s)")
        ax.set_xlim(gg[0], gg[-1])
        sec = ax.secondary_xaxis("top", functions=(lambda g: g * (n - 1) / 1e3,
                                                   lambda L: L * 1e3 / (n - 1)))
        sec.set_xlabel("extra chain length (um)")
        ax.set_xlabel(f"mean gap gbar (nm); nominal: extra length / {n - 1}")
        nr = int(dm.groupby(["extra_length_um", "v_striker_m_s"]).size().max())
        ax.set_title(f"{label(mat)}, v_s = {', '.join(f'{v:g}' for v in vss)} m/s, up to "
                     f"{nr} realisations per length" +
                     (f"\nnot arrived (excluded): {nfail}/{len(dm)}" if nfail else ""),
                     fontsize=8)
        ax.legend(loc="lower left")
        ax.set_ylim(0, None)
    axes[0][0].set_ylabel("group velocity v_g (m/s)")
    fig.suptitle("Loose chains: v_g vs mean gap from the extra length\n"
                 "(chapter Fig. 5.4b counterpart)", fontsize=9)
    fig.tight_layout()
    return save(fig, out)
