"""Beyond the chapter: can a sphere-size tolerance alone make Fig. 5.3b's ~20%
oscillation (radius_spread study)?"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ... import reductions
from .common import SIM_MATERIAL, PackedChain, make_row, pct

QUESTION_SIM = "simulation (beyond the chapter)"


def tolerance_rows(pk: PackedChain, radius_spread: pd.DataFrame | None = None) -> list[dict]:
    """Can a sphere-size tolerance alone make the chapter's ~20% oscillation (Fig. 5.3b)?
    On the gap20_oscillation measure (:func:`granchain.reductions.spread_oscillation`), for
    440C (else the study's first material):

    - spread_oscillation: the median at the study's largest radius sd, against the
      chapter's ~20%;
    - spread_sd_for_gap_oscillation: the sd (um) at which the median reaches the gapped
      chains' median (linear between the study's sds, the packed chain at sd = 0), NaN
      when it never does in the study's range (the reason says so, with the numbers)."""
    ev = "radius_spread; radius_spread.csv"
    q1 = "radius spread alone, largest sd: spread of v_max,i along the chain (the " \
         "gap20_oscillation measure), median over chains"
    q2 = "sd of the radii at which that median reaches the gapped chains' median"
    chap1 = "peak velocity oscillates by ~20% with 20 nm gaps (Fig. 5.3b)"
    chap2 = "the chapter puts the ~20% down to gaps (Fig. 5.3b); no tolerance is given"
    if radius_spread is None:
        why = "radius_spread table not given (the preset has no radius_spread study)"
        return [make_row("spread_oscillation", q1, QUESTION_SIM, chap1, 0.20, math.nan, "-",
                         ev, why),
                make_row("spread_sd_for_gap_oscillation", q2, QUESTION_SIM, chap2, math.nan,
                         math.nan, "um", ev, why)]
    o = reductions.spread_oscillation(radius_spread)
    mat = SIM_MATERIAL if SIM_MATERIAL in set(o["material"]) else o["material"].iloc[0]
    o = o[o["material"] == mat]
    packed, spread, gaps = (o[o["kind"] == k] for k in reductions.SPREAD_KINDS)
    vs = reductions.striker_speed(reductions.reference_engine(radius_spread))
    dist = ", ".join(dict.fromkeys(
        radius_spread.loc[radius_spread["radius_sd_m"] > 0, "radius_spread_distribution"]))
    sd = spread["radius_sd_m"].to_numpy(dtype=float) * 1e6
    med = spread["osc_median"].to_numpy(dtype=float)
    pv = float(packed["osc_median"].iloc[0]) if len(packed) else math.nan
    top = float(med[-1]) if med.size else math.nan
    if len(gaps) == 0 or not med.size:
        why = "the radius_spread table has no " + ("gapped chains" if med.size else
                                                   "radius spread")
        return [make_row("spread_oscillation", q1, QUESTION_SIM, chap1, 0.20, top, "-", ev,
                         why),
                make_row("spread_sd_for_gap_oscillation", q2, QUESTION_SIM, chap2, math.nan,
                         math.nan, "um", ev, why)]
    g = gaps.iloc[0]
    target = float(g["osc_median"])
    x = np.concatenate([[0.0], sd]) if len(packed) else sd
    y = np.concatenate([[pv], med]) if len(packed) else med
    hit = reductions.first_reaching(x, y, target)
    curve = ", ".join(f"{s:g} um: {pct(m)}" for s, m in zip(sd, med))
    gtxt = (f"the {g['gap_mean_nm']:g} nm gaps' median {pct(target)} (5-95% {pct(g['osc_p5'])}"
            f"-{pct(g['osc_p95'])}, {int(g['n'])} chains of equal spheres)")
    share = (top - pv) / (target - pv) if target != pv else math.nan
    p95 = float(spread["osc_p95"].iloc[-1])
    if math.isfinite(hit):
        verdict = f"reaches {gtxt} at sd = {hit:.3g} um"
    else:
        verdict = (f"never reaches {gtxt} for sd <= {sd.max():g} um: at {sd.max():g} um its "
                   f"excess over the packed chain's {pct(pv)} is {pct(share)} of the gaps' "
                   f"excess, and its 95th percentile, {pct(p95)}, is "
                   + ("below" if p95 < g["osc_p5"] else "above") +
                   f" the gapped chains' 5th, {pct(g['osc_p5'])}")
    what = (f"{reductions.label(mat)}, v_s = {vs:g} m/s, {dist} spreads of sd {sd.min():g}-"
            f"{sd.max():g} um, {int(spread['n'].max())} chains each")
    return [
        make_row("spread_oscillation", f"{what}: {q1} (sd = {sd.max():g} um)", QUESTION_SIM,
                 chap1, 0.20, top, "-", ev,
                 f"the median {verdict}; medians {curve}; so tolerance alone "
                 + ("can make" if math.isfinite(hit) else "cannot make")
                 + f" the chapter's ~20% for sd <= {sd.max():g} um, and "
                 f"{g['gap_mean_nm']:g} nm gaps give {pct(target)}"),
        make_row("spread_sd_for_gap_oscillation", f"{what}: {q2} ({pct(target)})",
                 QUESTION_SIM, chap2, math.nan, hit, "um", ev,
                 (f"reached at sd = {hit:.3g} um (linear between the study's sds, the packed "
                  f"chain at sd = 0); medians {curve}" if math.isfinite(hit) else
                  f"NaN: not reached for sd <= {sd.max():g} um (largest median {pct(top)}, "
                  f"packed {pct(pv)}, gaps {pct(target)}); medians {curve}")),
    ]
