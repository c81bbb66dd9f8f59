"""Beyond the chapter: which contact damping gives the measured v_max,2 / v_max,1, and
does it give the measured peaks or leave a loss at the striker (dissipation study)?"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ... import reductions
from .common import FITTED_GAPS_NM, SIM_MATERIAL, PackedChain, make_row, pct

QUESTION_EXP = "experiment (beyond the chapter)"


def _nearest_gap(rows: pd.DataFrame, mat: str, gap_nm: float):
    """The row of material ``mat`` with a mean gap > 0 nearest ``gap_nm`` (None if none)."""
    r = rows[(rows["material"] == mat) & (rows["gap_mean_nm"] > 0)]
    if r.empty:
        return None
    return r.iloc[int(np.argmin(np.abs(r["gap_mean_nm"].to_numpy(dtype=float) - gap_nm)))]


def dissipation_rows(pk: PackedChain, dissipation: pd.DataFrame | None = None) -> list[dict]:
    """Which contact damping (coefficient of restitution e) gives the measured v_max,2 /
    v_max,1 = 0.80 +/- 0.08, and does it give the measured peaks 0.57 and 0.46 v_s, or leave
    a loss at the striker? From :func:`granchain.reductions.dissipation_match` (the median
    curves against e), for 440C (else the study's first material):

    - diss_e_ratio_packed, diss_e_ratio_gapped: the largest e at which the packed chain's,
      and the chain's at the chapter's fitted mean gap (the study's nearest), median ratio
      is 0.80;
    - diss_vmax1_at_e, diss_vmax2_at_e: the packed chain's v_max,1 / v_s and v_max,2 / v_s
      at that e, against the measured peaks;
    - diss_striker_factor: 0.57 / v_max,1 there, the factor on the striker's speed that the
      measured v_max,1 needs (the reason compares it with 0.46 / v_max,2's)."""
    ev = "dissipation; dissipation.csv"
    rm, rh = reductions.MEASURED_PEAKS["ratio"]
    (m1, h1), (m2, h2) = reductions.MEASURED_PEAKS["v1"], reductions.MEASURED_PEAKS["v2"]
    chap_ratio = f"v_max,2 / v_max,1 = {rm:g} +/- {rh:g} measured (95% CI, Fig. 5.2b)"
    ids = [("diss_e_ratio_packed", "packed chain with contact damping: the largest e at which "
            "the median v_max,2 / v_max,1 is the measured 0.80", chap_ratio, math.nan,
            math.nan, "-"),
           ("diss_e_ratio_gapped", "chain at the chapter's fitted mean gap with contact "
            "damping: the largest e at which the median v_max,2 / v_max,1 is 0.80",
            chap_ratio, math.nan, math.nan, "-"),
           ("diss_vmax1_at_e", "packed chain, at that e: v_max,1 / v_s",
            f"({m1:g} +/- {h1:g}) v_s measured (Fig. 5.2c)", m1, h1, "v_s"),
           ("diss_vmax2_at_e", "packed chain, at that e: v_max,2 / v_s",
            f"({m2:g} +/- {h2:g}) v_s measured (Fig. 5.2c)", m2, h2, "v_s"),
           ("diss_striker_factor", "packed chain, at that e: the factor on the striker's "
            "speed the measured v_max,1 needs, 0.57 / (v_max,1 / v_s)",
            "the chapter suspects a loss at the striker (Fig. 5.2c), not in Eq. 5.1",
            math.nan, math.nan, "-")]
    if dissipation is None:
        return [make_row(i, q, QUESTION_EXP, c, v, math.nan, u, ev,
                         "dissipation table not given (the preset has no dissipation study)",
                         chapter_uncertainty=h) for i, q, c, v, h, u in ids]
    m = reductions.dissipation_match(dissipation)
    curves = reductions.dissipation_curves(dissipation)
    mat = SIM_MATERIAL if SIM_MATERIAL in set(m["material"]) else m["material"].iloc[0]
    others = [x for x in dict.fromkeys(m["material"]) if x != mat]
    pm = m[(m["material"] == mat) & (m["gap_mean_nm"] == 0)]
    p = pm.iloc[0] if len(pm) else None
    gp = _nearest_gap(m, mat, FITTED_GAPS_NM.get(mat, 0.0))
    model = str(dissipation["damping_model"].iloc[0])
    vs = float(m["v_striker_m_s"].iloc[0])
    head = f"{reductions.label(mat)}, {model}, v_s = {vs:g} m/s"

    def band_e(r) -> str:
        lo, hi = r["e_ratio_lo"], r["e_ratio_hi"]
        return (f"the measured {rm - rh:.2f}-{rm + rh:.2f} needs e = {lo:.3f}-{hi:.3f}"
                if math.isfinite(lo) and math.isfinite(hi) else
                f"the measured {rm - rh:.2f}-{rm + rh:.2f}: ends at e = {lo:.3f}, {hi:.3f}")

    def at(r) -> str:
        gap = "packed" if r["gap_mean_nm"] == 0 else f"{r['gap_mean_nm']:g} nm gaps"
        return (f"{reductions.label(r['material'])} {gap}: e = {r['e_ratio']:.4f}, v_max,1 = "
                f"{r['v1']:.3f} v_s, v_max,2 = {r['v2']:.3f} v_s, v_g = {r['vg']:.1f} m/s")

    other_txt = "; ".join(at(r) for _, r in m.iterrows()
                          if r["material"] in others and math.isfinite(r["e_ratio"]))
    rows = []
    if p is not None:
        rows.append(make_row(
            ids[0][0], f"{head}: {ids[0][1]}", QUESTION_EXP, chap_ratio, math.nan,
            p["e_ratio"], "-", ev,
            f"undamped (e = {p['e_max']:g}) the packed ratio is {p['ratio_at_e_max']:.4f}; "
            f"{band_e(p)}; {other_txt or 'no other material'} (Hertz contacts with a "
            f"constant e have no scale: the packed chains of every material agree)"))
    else:
        rows.append(make_row(ids[0][0], f"{head}: {ids[0][1]}", QUESTION_EXP, chap_ratio,
                             math.nan, math.nan, "-", ev, "no packed chain in the table"))
    if gp is not None:
        rows.append(make_row(
            ids[1][0], f"{head}, {gp['gap_mean_nm']:g} nm uniform gaps (the chapter's fitted "
            f"{FITTED_GAPS_NM.get(mat, math.nan):g} nm): {ids[1][1]}", QUESTION_EXP,
            chap_ratio, math.nan, gp["e_ratio"], "-", ev,
            f"undamped the gapped chains' median ratio is {gp['ratio_at_e_max']:.4f}"
            + (f" (gaps alone lift it above the packed chain's {p['ratio_at_e_max']:.4f})"
               if p is not None and gp["ratio_at_e_max"] > p["ratio_at_e_max"] else "")
            + f"; {band_e(gp)}; there v_max,1 = "
            f"{gp['v1']:.3f} v_s, v_max,2 = {gp['v2']:.3f} v_s, v_g = {gp['vg']:.1f} m/s; "
            f"{other_txt or 'no other material'}"))
    else:
        rows.append(make_row(ids[1][0], f"{head}: {ids[1][1]}", QUESTION_EXP, chap_ratio,
                             math.nan, math.nan, "-", ev, "no gapped chain of this material"))
    if p is None or not math.isfinite(p["e_ratio"]):
        why = ("no packed chain in the table" if p is None else
               f"the packed ratio never reaches {rm:g} over e = "
               f"{curves['restitution_e'].min():g}-{curves['restitution_e'].max():g}")
        return rows + [make_row(i, f"{head}: {q}", QUESTION_EXP, c, v, math.nan, u, ev, why,
                                chapter_uncertainty=h) for i, q, c, v, h, u in ids[2:]]
    e_s = float(p["e_ratio"])
    g_txt = (f"; with the {gp['gap_mean_nm']:g} nm gaps (e = {gp['e_ratio']:.4f}) "
             f"v_max,1 = {gp['v1']:.3f}, v_max,2 = {gp['v2']:.3f} v_s, further above"
             if gp is not None and math.isfinite(gp["e_ratio"]) else "")
    # does any simulated e give all three measured numbers at once?
    c = curves[(curves["material"] == mat) & (curves["gap_mean_nm"] == 0)]
    both = c[((c["v1_median"] - m1).abs() <= h1) & ((c["ratio_median"] - rm).abs() <= rh)]
    lowest = c.loc[c["v1_median"].idxmin()]
    alone = (f"no e of the study's ({c['restitution_e'].min():g}-"
             f"{c['restitution_e'].max():g}) gives v_max,1 and the ratio within the measured "
             f"intervals at once: the lowest v_max,1, {lowest['v1_median']:.3f} v_s at e = "
             f"{lowest['restitution_e']:g}, comes with a ratio of {lowest['ratio_median']:.3f}"
             if both.empty else
             "e = " + ", ".join(f"{e:g}" for e in both["restitution_e"]) + " give v_max,1 "
             "and the ratio within the measured intervals at once")
    for (i, q, chap, val, half, unit), got in zip(ids[2:4], (p["v1"], p["v2"])):
        inside = abs(got - val) <= half
        rows.append(make_row(
            i, f"{head}: {q} (e = {e_s:.4f})", QUESTION_EXP, chap, val, got, unit, ev,
            f"{'inside' if inside else 'outside'} the measured {val - half:.2f}-"
            f"{val + half:.2f}: the e that gives the measured ratio leaves it "
            f"{pct(got / val - 1)} {'above' if got > val else 'below'} the measurement"
            f"{g_txt}; {alone}", chapter_uncertainty=half))
    f1, f2 = float(p["striker_v1"]), float(p["striker_v2"])
    u1, u2 = h1 / p["v1"], h2 / p["v2"]
    g_f = (f"; at the {gp['gap_mean_nm']:g} nm gaps the factors are {gp['striker_v1']:.3f} "
           f"and {gp['striker_v2']:.3f}" if gp is not None and math.isfinite(gp["e_ratio"])
           else "")
    inside = abs(p["v1"] - m1) <= h1 and abs(p["v2"] - m2) <= h2
    agree = abs(f1 - f2) <= min(u1, u2)
    if inside:
        verdict = (f"that e gives both measured peaks within their intervals: no loss at the "
                   f"striker is needed")
    elif agree:
        verdict = (f"one loss that scales the whole wave, a striker arriving at "
                   f"{0.5 * (f1 + f2):.2f} of v_s (a Hertz chain with a constant e scales with "
                   f"v_s), explains both peaks{g_f}; a striker-side loss, as the chapter "
                   f"suspects")
    else:
        verdict = (f"no single factor on the striker's speed gives both peaks{g_f}: the loss "
                   f"is not at the striker alone")
    rows.append(make_row(
        ids[4][0], f"{head}: {ids[4][1]} (e = {e_s:.4f})", QUESTION_EXP, ids[4][2], math.nan,
        f1, "-", ev,
        f"from v_max,2 the factor is 0.46 / {p['v2']:.3f} = {f2:.3f}: the two "
        f"{'agree within' if agree else 'differ by'} {abs(f1 - f2):.3f} (the measured "
        f"intervals allow +/- {u1:.2f} and +/- {u2:.2f}); once e = {e_s:.3f} gives the "
        f"ratio, {verdict}; contact damping alone: {alone}"))
    return rows
