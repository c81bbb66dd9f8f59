"""Beyond the chapter, against theory: the field's chains (precompression and wall
studies)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ... import reductions
from .common import SIM_MATERIAL, PackedChain, make_row

BEYOND = "theory (beyond the chapter)"
DARAIO = ("Nesterenko's solitary wave in a precompressed chain, V_s = c0 (f_r^(2/3) - 1)^-1 "
          "[(4/15)(3 + 2 f_r^(5/3) - 5 f_r^(2/3))]^(1/2) (Daraio et al., PRE 73, 026610, "
          "2006, Eq. 3)")


def field_rows(pk: PackedChain, precompression: pd.DataFrame | None = None,
               wall: pd.DataFrame | None = None) -> list[dict]:
    """Rows that answer the field studies' questions against theory (not chapter numbers):

    - pre_vg_front_over_theory, pre_vg_over_theory: does a precompressed chain carry
      Nesterenko's precompressed solitary wave? v_g (arrival, then peak times) / V_s(f_r)
      at the wave's measured v_m, median over the loaded members (F0 > 0);
    - pre_vg_over_c0_weak: does the weakest wave run at the sound speed c0? v_g / c0 of the
      member with the smallest amplitude ratio f_r;
    - wall_force_exponent: does the wall's force peak scale as a Hertz solitary wave's,
      v_s^(6/5)? The fitted exponent (440C, else the study's first material)."""
    rows = []
    ev_pre = "precompression; precompression.csv"
    if precompression is None:
        rows += [make_row(i, q, BEYOND, DARAIO if i != "pre_vg_over_c0_weak" else
                          "a weak wave runs at c0 = 2R sqrt(k2/m)", 1.0, math.nan, "-", ev_pre,
                          "precompression table not given (the preset has no precompression "
                          "study)")
                 for i, q in (("pre_vg_front_over_theory", "precompressed chain: v_g (arrival) "
                               "/ Nesterenko's V_s"),
                              ("pre_vg_over_theory", "precompressed chain: v_g (peak) / "
                               "Nesterenko's V_s"),
                              ("pre_vg_over_c0_weak", "precompressed chain, weakest wave: "
                               "v_g / c0"))]
    else:
        r = reductions.precompression_rows(precompression, pk.radius)
        mats = ", ".join(reductions.label(m) for m in dict.fromkeys(r["material"]))
        loaded = r[r["F0_N"] > 0]
        free = r[r["F0_N"] == 0]
        loads = ", ".join(f"{f:g}" for f in sorted(set(loaded["F0_N"])))
        speeds = sorted(set(r["v_striker_m_s"].astype(float)))
        front = loaded["vg_front_over_theory"].to_numpy(dtype=float)
        peak = loaded["vg_over_theory"].to_numpy(dtype=float)
        what = (f"{len(loaded)} members, F0 = {loads} N, v_s = {speeds[0]:g}-{speeds[-1]:g} "
                f"m/s, f_r = {loaded['f_r'].min():.3g}-{loaded['f_r'].max():.3g}")
        free_txt = (f"; unloaded (F0 = 0) v_g / V_N(v_m) = {free['vg_over_theory'].min():.4f}-"
                    f"{free['vg_over_theory'].max():.4f}" if len(free) else "")
        if len(loaded):
            weak = loaded.loc[loaded["f_r"].idxmin()]
            strong = loaded[loaded["f_r"] >= 3.0]
            strong_txt = (f"; for f_r >= 3 peak-time v_g is {strong['vg_over_theory'].min():.4f}-"
                          f"{strong['vg_over_theory'].max():.4f} of it" if len(strong) else "")
            rows.append(make_row(
                "pre_vg_front_over_theory", f"precompressed {mats} chain on a wall: v_g from "
                "half-peak arrival times / Nesterenko's V_s(f_r) at the wave's v_m, median",
                BEYOND, DARAIO, 1.0, float(np.median(front)), "-", ev_pre,
                f"agrees: {front.min():.4f}-{front.max():.4f} over {what}{free_txt}"))
            rows.append(make_row(
                "pre_vg_over_theory", f"precompressed {mats} chain on a wall: v_g from peak "
                "times / Nesterenko's V_s(f_r) at the wave's v_m, median", BEYOND, DARAIO,
                1.0, float(np.median(peak)), "-", ev_pre,
                f"{peak.min():.4f}-{peak.max():.4f} over {what}{strong_txt}; the peak lags "
                "most for weak waves (f_r -> 1): a solitary wave's width grows without bound "
                "as f_r -> 1 (KdV limit), so near c0 the pulse is still a dispersing linear "
                "one whose peak trails its front, while the arrival times follow V_s"))
            rows.append(make_row(
                "pre_vg_over_c0_weak", f"precompressed {mats} chain, weakest wave (F0 = "
                f"{weak['F0_N']:g} N, v_s = {weak['v_striker_m_s']:g} m/s, f_r = "
                f"{weak['f_r']:.4g}): v_g / c0", BEYOND,
                "a weak wave runs at the sound speed c0 = 2R sqrt(k2/m), k2 = (3/2) K^(2/3) "
                "F0^(1/3)", 1.0, float(weak["vg_over_c0"]), "-", ev_pre,
                f"c0 = {weak['c0_m_s']:.1f} m/s; arrival-time v_g / c0 = "
                f"{weak['v_g_front_m_s'] / weak['c0_m_s']:.4f}, theory V_s / c0 = "
                f"{weak['V_theory_m_s'] / weak['c0_m_s']:.4f}: the weak pulse disperses (the "
                "long-wave c0 bounds a discrete chain's group velocity), its peak trailing"))
        else:
            rows += [make_row(i, "precompressed chain", BEYOND, DARAIO, 1.0, math.nan, "-",
                              ev_pre, "no loaded member (every force_N is 0)")
                     for i in ("pre_vg_front_over_theory", "pre_vg_over_theory",
                               "pre_vg_over_c0_weak")]
    quantity = "chain on a wall: exponent b of the wall's force peak F_wall = a v_s^b"
    chap = "a Hertz solitary wave: F_wall ~ v_s^(6/5)"
    if wall is None:
        rows.append(make_row("wall_force_exponent", quantity, BEYOND, chap,
                             reductions.HERTZ_WALL_EXPONENT, math.nan, "-", "wall; wall.csv",
                             "wall table not given (the preset has no wall study)"))
        return rows
    fits = reductions.wall_fits(wall)
    mat = SIM_MATERIAL if SIM_MATERIAL in fits else next(iter(fits))
    f = fits[mat]
    local = (f"local exponents {f['local'].min():.4f}-{f['local'].max():.4f}, the largest at "
             f"the lowest speeds" if f["local"].size else "one speed")
    rows.append(make_row(
        "wall_force_exponent", f"{reductions.label(mat)} {quantity}, fit over v_s = {f['v'].min():g}-"
        f"{f['v'].max():g} m/s", BEYOND, chap, reductions.HERTZ_WALL_EXPONENT, f["exponent"], "-",
        "wall; wall.csv",
        f"agrees: a = {f['prefactor']:.4g} N at 1 m/s over {f['n']} speeds ({local}); a pure "
        "Hertz chain gives exactly 6/5 (Hertz laws scale: F ~ v^(6/5) at any amplitude), "
        "so the excess is the groove friction and drag, which take a larger share of a "
        "slower wave's energy"))
    return rows
