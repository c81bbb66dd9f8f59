"""Beyond the chapter: can yielding contacts (Thornton's law) give the measured peaks, and
keep the measured linear v_max,1(v_s) (plasticity study)?"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ... import reductions
from ...materials import library
from .common import PackedChain, make_row, pct
from .dissipation import QUESTION_EXP

V_AT = 0.1            # m/s: the speed the rows quote (the study's nearest)
UNTABLED = ("ss316", "ss440c")   # the materials of the rows without a table


def _nearest_log(values, target: float) -> float:
    v = np.asarray([x for x in values if math.isfinite(x) and x > 0], dtype=float)
    return float(v[np.argmin(np.abs(np.log(v) - math.log(target)))]) if v.size else math.nan


def plasticity_rows(pk: PackedChain, plasticity: pd.DataFrame | None = None) -> list[dict]:
    """Per material of the study (316, then 440C), on the chains of its smallest mean gap
    (packed when the study has them), from :func:`granchain.reductions.plasticity_match`
    and :func:`~granchain.reductions.plasticity_exponents`:

    - plast_vmax1_library_<material>: v_max,1 / v_s at the speed nearest 0.1 m/s with the
      material's library p_y (the study's nearest), against the measured 0.57 +/- 0.09;
    - plast_py_match_<material>: the p_y (Pa) at which the median v_max,1 / v_s is the
      measured 0.57 at that speed (NaN when no p_y of the study's range gives it), the
      reason listing the p_y it needs at each speed;
    - plast_exponent_<material>: the exponent b of v_max,1 = a v_s^b at the study's p_y
      nearest that match (the library p_y when there is none), against the measured
      linear v_max,1(v_s) (b = 1); the reason says whether v_max,1 / v_s stays inside the
      measured interval 0.48-0.66 at every speed of the study with that one p_y."""
    ev = "plasticity; plasticity.csv"
    m1, h1 = reductions.MEASURED_PEAKS["v1"]
    chap_v1 = f"({m1:g} +/- {h1:g}) v_s measured (Fig. 5.2c)"
    chap_lin = "v_max,1 linear in v_s, measured (Fig. 5.2c): exponent 1"
    if plasticity is None:
        return [make_row(f"plast_{what}_{mat}", f"{reductions.label(mat)}: {q}", QUESTION_EXP,
                         c, v, math.nan, u, ev,
                         "plasticity table not given (the preset has no plasticity study)",
                         chapter_uncertainty=h)
                for mat in UNTABLED
                for what, q, c, v, h, u in (
                    ("vmax1_library", "v_max,1 / v_s with Thornton's contacts at the "
                     "library p_y", chap_v1, m1, h1, "v_s"),
                    ("py_match", "the p_y at which v_max,1 = 0.57 v_s", chap_v1, math.nan,
                     math.nan, "Pa"),
                    ("exponent", "the exponent b of v_max,1 ~ v_s^b at that p_y", chap_lin,
                     1.0, math.nan, "-"))]
    curves = reductions.plasticity_curves(plasticity)
    match = reductions.plasticity_match(plasticity)
    expo = reductions.plasticity_exponents(plasticity)
    known = library()
    rows = []
    for mat in reductions.materials_in(curves):
        c = curves[curves["material"] == mat]
        gap = float(c["gap_mean_nm"].min())
        c = c[c["gap_mean_nm"] == gap]
        m = match[(match["material"] == mat) & (match["gap_mean_nm"] == gap)]
        e = expo[(expo["material"] == mat) & (expo["gap_mean_nm"] == gap)]
        vs = _nearest_log(c["v_striker_m_s"], V_AT)
        lib = known[mat].yield_pressure if mat in known else None
        pys = sorted(x for x in set(c["yield_pressure_Pa"]) if math.isfinite(x))
        py_lib = _nearest_log(pys, lib) if lib else math.nan
        where = ("packed" if gap == 0 else f"{gap:g} nm gaps")
        head = f"{reductions.label(mat)}, {where}, v_s = {vs:g} m/s"
        at_v = c[c["v_striker_m_s"] == vs]
        el = at_v[~np.isfinite(at_v["yield_pressure_Pa"].to_numpy(dtype=float))]
        v1_el = float(el["v1_median"].iloc[0]) if len(el) else math.nan
        r_lib = at_v[at_v["yield_pressure_Pa"] == py_lib]
        v1_lib = float(r_lib["v1_median"].iloc[0]) if len(r_lib) else math.nan
        inside = abs(v1_lib - m1) <= h1
        rows.append(make_row(
            f"plast_vmax1_library_{mat}",
            f"{head}: v_max,1 / v_s with Thornton's contacts at p_y = {py_lib / 1e6:.4g} MPa "
            f"(library {lib / 1e6 if lib else math.nan:.4g} MPa)", QUESTION_EXP, chap_v1, m1,
            v1_lib, "v_s", ev,
            f"{'inside' if inside else 'outside'} the measured {m1 - h1:.2f}-{m1 + h1:.2f}; "
            f"the elastic chain gives {v1_el:.4f} v_s, so yielding at the library p_y takes "
            f"{pct(1 - v1_lib / v1_el)} off v_max,1", chapter_uncertainty=h1))
        mv = m.sort_values("v_striker_m_s")
        here = mv[mv["v_striker_m_s"] == vs]
        py = float(here["py_v1"].iloc[0]) if len(here) else math.nan
        def need(r) -> str:
            if math.isfinite(r["py_v1"]):
                return f"{r['py_v1'] / 1e6:.3g} MPa"
            if r["v1_at_py_max"] < m1 < r["v1_elastic"]:
                return (f"above the study's largest p_y ({r['v1_at_py_max']:.3f} v_s at "
                        f"{r['py_max'] / 1e6:.3g} MPa, {r['v1_elastic']:.3f} elastic)")
            return (f"none ({r['v1_at_py_min']:.3f} v_s at {r['py_min'] / 1e6:.3g} MPa, "
                    f"{r['v1_elastic']:.3f} elastic)")
        per_v = "; ".join(f"{r['v_striker_m_s']:g} m/s: {need(r)}" for _, r in mv.iterrows())
        finite = mv["py_v1"].to_numpy(dtype=float)
        finite = finite[np.isfinite(finite)]
        spread = (f"; over the speeds that reach it the p_y needed spans "
                  f"{finite.min() / 1e6:.3g}-{finite.max() / 1e6:.3g} MPa (x "
                  f"{finite.max() / finite.min():.3g}): one material p_y cannot give "
                  f"0.57 v_s at every speed" if finite.size > 1 and
                  finite.max() / finite.min() > 1.5 else "")
        rows.append(make_row(
            f"plast_py_match_{mat}", f"{head}: the p_y at which the median v_max,1 is the "
            f"measured {m1:g} v_s", QUESTION_EXP, chap_v1, math.nan, py, "Pa", ev,
            (f"p_y = {py / 1e6:.4g} MPa, {py / lib:.3g} of the library value"
             if math.isfinite(py) and lib else "no p_y of the study's range "
             f"({pys[0] / 1e6:.3g}-{pys[-1] / 1e6:.3g} MPa) gives it" if pys else
             "the study has no finite p_y") + f"; per speed: {per_v}{spread}"))
        py_b = _nearest_log(pys, py) if math.isfinite(py) else py_lib
        eb = e[e["yield_pressure_Pa"] == py_b]
        ee = e[~np.isfinite(e["yield_pressure_Pa"].to_numpy(dtype=float))]
        b = float(eb["b"].iloc[0]) if len(eb) else math.nan
        b_el = float(ee["b"].iloc[0]) if len(ee) else math.nan
        along = c[c["yield_pressure_Pa"] == py_b].sort_values("v_striker_m_s")
        v1s = along["v1_median"].to_numpy(dtype=float)
        out_at = [f"{v:g}" for v, x in zip(along["v_striker_m_s"], v1s)
                  if not abs(x - m1) <= h1]
        rows.append(make_row(
            f"plast_exponent_{mat}", f"{reductions.label(mat)}, {where}: the exponent b of "
            f"the median v_max,1 = a v_s^b at p_y = {py_b / 1e6:.4g} MPa "
            f"({'the study p_y nearest the match' if math.isfinite(py) else 'the library p_y'})",
            QUESTION_EXP, chap_lin, 1.0, b, "-", ev,
            f"over v_s = {c['v_striker_m_s'].min():g}-{c['v_striker_m_s'].max():g} m/s (the "
            f"elastic chain's b = {b_el:.4f}) v_max,1 / v_s falls from {v1s[0]:.3f} to "
            f"{v1s[-1]:.3f} (x {v1s[-1] / v1s[0]:.3f}): " + (
                f"it stays inside the measured {m1 - h1:.2f}-{m1 + h1:.2f} at every speed, so "
                "the measured linear fit cannot tell this speed dependence apart"
                if not out_at else
                f"it leaves the measured {m1 - h1:.2f}-{m1 + h1:.2f} at v_s = "
                f"{', '.join(out_at)} m/s, so one p_y does not fit the measured linear "
                "v_max,1(v_s)")))
    return rows
