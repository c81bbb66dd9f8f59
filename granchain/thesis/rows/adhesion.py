"""Beyond the chapter: which surface energy of adhesive contacts, alone or with the groove's
flats adhering, gives the measured v_max,1 at the lowest speeds (adhesion study)?"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ... import reductions
from .common import PackedChain, make_row
from .dissipation import QUESTION_EXP

# the surface energy of clean iron (Tyson & Miller 1977, Surf. Sci. 62, 267: 2.42 J/m^2 at
# 0 K, from liquid surface tensions), the upper end of what a steel contact in air can have
UNTABLED = ("ss316", "ss440c")   # the materials of the rows without a table
CLEAN_IRON_J_M2 = 2.42


def adhesion_rows(pk: PackedChain, adhesion: pd.DataFrame | None = None) -> list[dict]:
    """Per material of the study, on the chains of its smallest mean gap at the study's
    lowest striker speed, from :func:`granchain.reductions.cohesion_match`:

    - adh_gamma_contacts_<material>: the least surface energy gamma (J/m^2) at which the
      median v_max,1 / v_s falls to the measured 0.57 with the contacts adhering alone (NaN
      when no gamma of the study's range gives it: the contacts' pull raises the peak);
    - adh_gamma_groove_<material>: the same with the groove's flats adhering too
      (``adhesion.groove``), beside the surface energy of clean iron, 2.42 J/m^2."""
    ev = "adhesion; adhesion.csv"
    m1, h1 = reductions.MEASURED_PEAKS["v1"]
    chap = f"v_max,1 = ({m1:g} +/- {h1:g}) v_s measured (Fig. 5.2c)"
    ids = (("contacts", "the surface energy gamma at which the contacts' adhesion alone "
            "gives v_max,1 = 0.57 v_s"),
           ("groove", "the surface energy gamma at which the contacts' and the groove's "
            "adhesion give v_max,1 = 0.57 v_s"))
    if adhesion is None:
        return [make_row(f"adh_gamma_{w}_{mat}", f"{reductions.label(mat)}: {q}",
                         QUESTION_EXP, chap, math.nan, math.nan, "J/m^2", ev,
                         "adhesion table not given (the preset has no adhesion study)")
                for mat in UNTABLED for w, q in ids]
    m = reductions.cohesion_match(adhesion)
    rows = []
    for mat in reductions.materials_in(m):
        mm = m[m["material"] == mat]
        gap = float(mm["gap_mean_nm"].min())
        mm = mm[mm["gap_mean_nm"] == gap]
        vs = float(mm["v_striker_m_s"].min())
        mm = mm[mm["v_striker_m_s"] == vs]
        head = (f"{reductions.label(mat)}, {'packed' if gap == 0 else f'{gap:g} nm gaps'}, "
                f"v_s = {vs:g} m/s")
        for what, q in ids:
            r = mm[mm["groove_cohesion"] == (what == "groove")]
            if r.empty:
                rows.append(make_row(f"adh_gamma_{what}_{mat}", f"{head}: {q}", QUESTION_EXP,
                                     chap, math.nan, math.nan, "J/m^2", ev,
                                     "the study has no chains of this groove setting"))
                continue
            r = r.iloc[0]
            g = float(r["gamma_v1"])
            if math.isfinite(g):
                found = (f"gamma = {g:.3g} J/m^2, {g / CLEAN_IRON_J_M2:.3g} of clean iron's "
                         f"{CLEAN_IRON_J_M2:g} J/m^2 (Tyson & Miller 1977)")
            elif r["v1_at_gamma_min"] <= m1:
                found = (f"below the study's least gamma: at {r['gamma_min']:g} J/m^2 "
                         f"v_max,1 = {r['v1_at_gamma_min']:.3f} v_s already")
            else:
                found = (f"no gamma of the study's {r['gamma_min']:g}-{r['gamma_max']:g} "
                         f"J/m^2 brings v_max,1 down to {m1:g} v_s")
            rows.append(make_row(
                f"adh_gamma_{what}_{mat}", f"{head}: {q}", QUESTION_EXP, chap, math.nan, g,
                "J/m^2", ev,
                f"{found}; without adhesion v_max,1 = {r['v1_none']:.3f} v_s, at gamma = "
                f"{r['gamma_min']:g} J/m^2 {r['v1_at_gamma_min']:.3f} v_s, at gamma = "
                f"{r['gamma_max']:g} J/m^2 {r['v1_at_gamma_max']:.3f} v_s (ratio "
                f"{r['ratio_at_gamma_max']:.3f}, v_g {r['vg_at_gamma_max']:.1f} m/s; NaN "
                "where the far probe's peak is not final)"))
    return rows


JKR_CAPTURE_EXPONENT = 5 / 6    # v_c ~ gamma^(5/6): JKR's hysteresis energy ~ gamma^(5/3)
GAMMA_AT = 0.1                  # J/m^2: the surface energy the row quotes (the nearest)


def capture_rows(pk: PackedChain, capture: pd.DataFrame | None = None) -> list[dict]:
    """Per material of the capture study (two adhesive spheres), from
    :func:`granchain.reductions.capture_velocities`:

    - adh_capture_velocity_<material>: the capture velocity v_c (m/s) at the study's
      surface energy nearest 0.1 J/m^2, the reason listing every gamma's and whether the
      collisions bracket it;
    - adh_capture_exponent_<material>: the exponent b of v_c = a gamma^b over the study's
      gammas (power-law fit), against JKR's 5/6."""
    from ...reductions import power_law_fit
    ev = "capture; capture.csv"
    theory = "JKR's hysteresis energy ~ gamma^(5/3): v_c ~ gamma^(5/6) (theory)"
    if capture is None:
        return [make_row(f"adh_capture_{w}_{mat}", f"{reductions.label(mat)}: {q}",
                         "theory (beyond the chapter)", theory, v, math.nan, u, ev,
                         "capture table not given (the preset has no capture study)")
                for mat in ("ss440c",)
                for w, q, v, u in (("velocity", "capture velocity of two spheres", math.nan,
                                    "m/s"),
                                   ("exponent", "exponent of v_c ~ gamma^b",
                                    JKR_CAPTURE_EXPONENT, "-"))]
    cv = reductions.capture_velocities(capture)
    rows = []
    for mat in reductions.materials_in(cv):
        c = cv[cv["material"] == mat]
        gam = c["surface_energy_J_m2"].to_numpy(dtype=float)
        k = int(np.argmin(np.abs(np.log(gam) - math.log(GAMMA_AT))))
        r = c.iloc[k]
        model = str(capture["cohesion_model"].iloc[0])
        each = "; ".join(
            f"{x['surface_energy_J_m2']:g} J/m^2: " + (
                f"{x['v_c'] * 1e3:.4g} mm/s ({x['n_separated']} separated, "
                f"{x['n_captured']} captured" + (", bracketed" if x["bracketed"] else "")
                + ")" if math.isfinite(x["v_c"]) else
                f"none separated ({x['n_captured']} captured, {x['n_unfinished']} "
                "unfinished)")
            for _, x in c.iterrows())
        rows.append(make_row(
            f"adh_capture_velocity_{mat}", f"{reductions.label(mat)}, two spheres, {model}: "
            f"the capture velocity at gamma = {r['surface_energy_J_m2']:g} J/m^2",
            "theory (beyond the chapter)", theory, math.nan, r["v_c"], "m/s", ev,
            f"v_c = median v_s sqrt(1 - e^2) over the separated collisions; {each}"))
        b, _ = power_law_fit(gam, c["v_c"].to_numpy(dtype=float))
        rows.append(make_row(
            f"adh_capture_exponent_{mat}", f"{reductions.label(mat)}, two spheres, {model}: "
            "the exponent b of v_c = a gamma^b", "theory (beyond the chapter)", theory,
            JKR_CAPTURE_EXPONENT, b, "-", ev,
            f"power-law fit over gamma = {gam.min():g}-{gam.max():g} J/m^2 "
            f"({int(np.isfinite(c['v_c']).sum())} with a v_c)"))
    return rows
