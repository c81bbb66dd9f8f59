"""20 nm gaps and the chapter's fitted mean gaps (Fig. 5.3b, 5.3c), from the gap_profile
and gap_sweep tables."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ... import reductions
from ...analytic import eq54_group_velocity
from .common import FITTED_GAPS_NM, V_REF, PackedChain, gap_profile_table, make_row, pct

def gap_rows(pk: PackedChain, gap_profile: pd.DataFrame | None = None,
             gap_sweep: pd.DataFrame | None = None) -> list[dict]:
    """gap20_oscillation, gap20_vg_reduction (20 nm gaps) and, per material, the
    chapter's fitted mean gap with the Eq. 5.4 bound and the simulated v_g there."""
    radius = pk.radius
    gp = gap_profile_table(gap_profile)
    if gp is not None:
        g_nm = float(gp["gap_mean_nm"].iloc[0])
        o = reductions.band(reductions.oscillation(reductions.peak_profile(gp, "thesis")))
        posc = float(reductions.oscillation(pk.prof)[0]) if pk.prof is not None else math.nan
        gpa = reductions.arrived(gp)
        vs_gp = reductions.striker_speed(gp)
        vg0_gp = float(reductions.packed_vg(pk.table, gp["material"].iloc[0], vs_gp)[0])
        vg_gp = float(gpa["v_g_m_s"].median()) if len(gpa) else math.nan
        red = 1.0 - vg_gp / vg0_gp
        bound_gp = float(eq54_group_velocity(vg0_gp, g_nm * 1e-9, vs_gp, radius))
        need = reductions.gap_for_reduction(vg0_gp, vs_gp, 1.0 / 3.0, radius) * 1e9
        n_gp = len(gp)
    else:
        o = (math.nan,) * 3
        posc = red = bound_gp = need = vg0_gp = vg_gp = vs_gp = math.nan
        g_nm, n_gp = 20.0, 0
    rows = [
        make_row("gap20_oscillation", f"{g_nm:g} nm mean gaps, v_s = {vs_gp:g} m/s: spread "
                 "of v_max,i along the chain, (max - min)/mean over particles 2..13, median "
                 "over realisations", "simulation", "peak velocity oscillates by ~20% "
                 "(Fig. 5.3b)", 0.20, o[1], "-", "fig5_3b; gap_profile.csv",
                 f"5-95% over {n_gp} chains: {pct(o[0])}-{pct(o[2])}; the packed chain's "
                 f"monotone decay alone gives {pct(posc)} on this measure; the chapter does "
                 f"not define its 'variation' nor its gap law (here uniform on [0, 2 gbar])"),
        make_row("gap20_vg_reduction", f"{g_nm:g} nm mean gaps: 1 - v_g / v_g(packed) at "
                 f"v_s = {vs_gp:g} m/s (median over realisations)", "simulation",
                 "gaps of 20 nm cut v_g by ~1/3 at 0.1 m/s", 1.0 / 3.0, red, "-",
                 "fig5_3b; fig5_3c; gap_profile.csv; packed_sweep.csv",
                 f"v_g {vg_gp:.1f} vs packed {vg0_gp:.1f} m/s; the chapter's own Eq. 5.4 gives "
                 f"{bound_gp:.1f} m/s at {g_nm:g} nm (a {1 - bound_gp / vg0_gp:.1%} cut) and "
                 f"needs gbar ~ {need:.0f} nm for a 1/3 cut, so the chapter's ~1/3 is loose "
                 f"for 20 nm"),
    ]
    gs = None
    if gap_sweep is not None:
        gs = reductions.reference_engine(gap_sweep)
        reductions.require(gs, reductions.NEEDS["fig5_3c"] + ["gap_mean_probes_nm"], "thesis comparison")
    for gm, key in (("ss316", "fitted_gap_316"), ("ss440c", "fitted_gap_440c")):
        rows += _fitted_gap_rows(pk, gs, gm, key)
    return rows


def _fitted_gap_rows(pk: PackedChain, gs: pd.DataFrame | None, gm: str, key: str):
    """The chapter's fitted mean gap of material ``gm``: the fit itself (not
    reproducible here), Eq. 5.4 at that gap and V_REF, and the simulated median v_g at
    the nearest simulated mean gap."""
    gfit = FITTED_GAPS_NM[gm]
    bound = math.nan
    sim_txt = "gap_sweep table not given"
    sim_med, g_near = math.nan, math.nan
    if gm in pk.fits:
        vg0_f = float(reductions.packed_vg(pk.table, gm, V_REF)[0])
        bound = float(eq54_group_velocity(vg0_f, gfit * 1e-9, V_REF, pk.radius))
    if gs is not None and gm in set(gs["material"]):
        d = reductions.nearest_speed(gs, gm, V_REF)
        gaps = np.array(sorted(set(d["gap_mean_nm"].astype(float))))
        g_near = float(gaps[int(np.argmin(np.abs(gaps - gfit)))])
        dn = reductions.arrived(d[d["gap_mean_nm"].astype(float) == g_near])
        if len(dn):
            b = reductions.band(dn["v_g_m_s"])
            sim_med = b[1]
            sim_txt = (f"simulated v_g at the nearest simulated gap {g_near:g} nm: median "
                       f"{b[1]:.1f} (5-95% {b[0]:.1f}-{b[2]:.1f}) m/s at "
                       f"{reductions.striker_speed(d):g} m/s")
        else:
            sim_txt = f"no arrived chain at {g_near:g} nm"
    name = reductions.label(gm)
    return [
        make_row(key, f"fitted mean gap, {name} chain (fit of measured v_g to Fig. 5.3c)",
                 "fit to experiment", f"{gfit:g} nm", gfit, math.nan, "nm",
                 "fig5_3c; gap_sweep.csv",
                 f"needs the chapter's measured v_g(v_s) for {name} (Fig. 5.2d/5.3c points), "
                 f"not available; at {gfit:g} nm and {V_REF:g} m/s the model gives Eq. 5.4 "
                 f"bound {bound:.1f} m/s, {sim_txt}"),
        make_row(f"vg_bound_at_{key}", f"Eq. 5.4 bound v_g at the chapter's fitted gap "
                 f"{gfit:g} nm, {name}, v_s = {V_REF:g} m/s", "simulation",
                 "dashed fit line of Fig. 5.3c (value not printed)", math.nan, bound, "m/s",
                 "fig5_3c; packed_sweep.csv",
                 "the chapter reads the gap off this bound; Eq. 5.4 with this project's "
                 "packed v_g"),
        make_row(f"vg_sim_at_{key}", f"simulated median v_g near the chapter's fitted gap "
                 f"({name}, nearest simulated mean gap {g_near:g} nm, v_s ~ {V_REF:g} m/s)",
                 "simulation", "pink band of Fig. 5.3c (value not printed)", math.nan,
                 sim_med, "m/s", "fig5_3c; gap_sweep.csv",
                 f"median / Eq. 5.4 at {gfit:g} nm = {sim_med / bound:.3f}: the band straddles "
                 f"the dashed line because each chain's gbar between the probes scatters "
                 f"around the nominal mean (see bound_5_3c)"),
    ]
