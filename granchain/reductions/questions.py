"""Reductions of the chapter's questions, beyond Eq. 5.1: a sphere-size tolerance, contact
dissipation, yielding and adhesive contacts (tables/radius_spread.csv,
tables/dissipation.csv, tables/plasticity.csv, tables/adhesion.csv)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .chapter import band, oscillation, peak_profile
from .field import power_law_fit
from .table import NEEDS, arrived, materials_in, reference_engine, require, require_vmax

# The chapter's measured peaks (Fig. 5.2b, 5.2c): (value, half-width of its 95% interval),
# v_max,2/v_max,1 and v_max,1, v_max,2 in units of v_s
MEASURED_PEAKS = {"ratio": (0.80, 0.08), "v1": (0.57, 0.09), "v2": (0.46, 0.07)}
SPREAD_KINDS = ("packed", "spread", "gaps")


def spread_oscillation(df: pd.DataFrame) -> pd.DataFrame:
    """Per scene group of the radius_spread study (reference engine when mixed): material,
    ``kind`` (packed: neither spread nor gaps; spread: radius sd > 0; gaps: mean gap > 0),
    ``radius_sd_m``, ``gap_mean_nm``, ``n`` (chains) and the median, 5th and 95th
    percentiles (``osc_median``, ``osc_p5``, ``osc_p95``) over its chains of the chapter's
    Fig. 5.3b measure: :func:`oscillation` of v_max,i / v_s over particles 2..13, every
    chain (the gap20_oscillation row's and fig5_3b's measure, exactly). Ordered by
    material, then packed, the spreads by sd, the gaps by mean."""
    require(df, NEEDS["radius_spread"], "radius_spread")
    require_vmax(df, "radius_spread")
    d = reference_engine(df)
    rows = []
    for mat in materials_in(d):
        dm = d[d["material"] == mat]
        sd = dm["radius_sd_m"].to_numpy(dtype=float)
        gap = dm["gap_mean_nm"].to_numpy(dtype=float)
        kind = np.where(gap > 0, "gaps", np.where(sd > 0, "spread", "packed"))
        for k in SPREAD_KINDS:
            mk = dm[kind == k]
            for key, g in mk.groupby(["radius_sd_m", "gap_mean_nm"], sort=True):
                o = oscillation(peak_profile(g, "radius_spread"))
                lo, med, hi = band(o)
                rows.append({"material": mat, "kind": k, "radius_sd_m": float(key[0]),
                             "gap_mean_nm": float(key[1]), "n": int(len(g)),
                             "osc_median": med, "osc_p5": lo, "osc_p95": hi})
    return pd.DataFrame(rows, columns=["material", "kind", "radius_sd_m", "gap_mean_nm", "n",
                                       "osc_median", "osc_p5", "osc_p95"])


def first_reaching(x, y, target: float) -> float:
    """The smallest x (x ascending) at which the piecewise-linear y(x) through the points
    reaches ``target`` from below: the first x itself if y is there already, else linear
    interpolation between the two neighbouring points that bracket it; NaN if no y
    reaches it."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    for k in range(x.size):
        if y[k] >= target:
            if k == 0:
                return float(x[0])
            return float(x[k - 1] + (target - y[k - 1]) / (y[k] - y[k - 1]) * (x[k] - x[k - 1]))
    return math.nan


def _curves(df: pd.DataFrame, study: str, *settings: str) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s, ``settings``) of a question study
    (reference engine when mixed), ascending in each key after the material: ``n``, and
    the median, 5th and 95th percentiles over its chains of v_max,1 / v_s (``v1``),
    v_max,2 / v_s (``v2``) and v_max,2 / v_max,1 (``ratio``, the rows' v_max_ratio), and
    over its arrived chains (``n_arrived``) of v_g in m/s (``vg``): columns
    ``<q>_median``, ``<q>_p5``, ``<q>_p95``."""
    require(df, NEEDS[study], study)
    d = reference_engine(df)
    vs = d["v_striker_m_s"].to_numpy(dtype=float)
    d = d.assign(_v1=d["v_max_1_m_s"].to_numpy(dtype=float) / vs,
                 _v2=d["v_max_2_m_s"].to_numpy(dtype=float) / vs)
    keys = ["material", "gap_mean_nm", "v_striker_m_s", *settings]
    rows = []
    for mat in materials_in(d):
        for key, g in d[d["material"] == mat].groupby(keys[1:], sort=True):
            row = {"material": mat, **dict(zip(keys[1:], (
                bool(k) if isinstance(k, (bool, np.bool_)) else float(k) for k in key))),
                   "n": int(len(g))}
            ok = arrived(g)
            row["n_arrived"] = int(len(ok))
            for q, vals in (("v1", g["_v1"]), ("v2", g["_v2"]), ("ratio", g["v_max_ratio"]),
                            ("vg", ok["v_g_m_s"])):
                lo, med, hi = band(vals)
                row.update({f"{q}_median": med, f"{q}_p5": lo, f"{q}_p95": hi})
            rows.append(row)
    cols = keys + ["n", "n_arrived"] + [f"{q}_{s}" for q in ("v1", "v2", "ratio", "vg")
                                        for s in ("median", "p5", "p95")]
    return pd.DataFrame(rows, columns=cols)


def dissipation_curves(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s, restitution_e) of the dissipation study,
    ascending e within each (material, gap, v_s): the bands of :func:`_curves`."""
    return _curves(df, "dissipation", "restitution_e")


def plasticity_curves(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s, yield_pressure_Pa) of the plasticity
    study, ascending p_y within each (material, gap, v_s), the elastic chain (p_y inf)
    last: the bands of :func:`_curves`."""
    return _curves(df, "plasticity", "yield_pressure_Pa")


def cohesion_curves(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s, groove_cohesion, surface_energy_J_m2) of
    the adhesion study, ascending gamma within each (material, gap, v_s, groove), the chain
    without adhesion (gamma 0, groove False) first: the bands of :func:`_curves`."""
    require(df, NEEDS["cohesion"], "cohesion")
    d = df.assign(groove_cohesion=df["groove_cohesion"].astype(bool))
    return _curves(d, "cohesion", "groove_cohesion", "surface_energy_J_m2")


def last_crossing(x, y, target: float) -> float:
    """The largest x (x ascending) at which the piecewise-linear y(x) through the points
    equals ``target`` (a point on it, or linear interpolation between the two neighbouring
    points on either side of it); NaN if y never does. For the dissipation study: the
    weakest damping (largest e) that brings a curve to ``target``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float) - target
    for k in range(x.size - 1, -1, -1):
        if y[k] == 0.0:
            return float(x[k])
        if k > 0 and np.isfinite(y[k - 1]) and np.isfinite(y[k]) and y[k - 1] * y[k] < 0:
            return float(x[k - 1] - y[k - 1] / (y[k] - y[k - 1]) * (x[k] - x[k - 1]))
    return math.nan


def interpolate_at(x, y, x0: float) -> float:
    """y(x0) on the piecewise-linear curve through the points (x ascending); NaN for x0
    NaN or outside [x_0, x_last]."""
    x = np.asarray(x, dtype=float)
    if not (math.isfinite(x0) and x[0] <= x0 <= x[-1]):
        return math.nan
    return float(np.interp(x0, x, np.asarray(y, dtype=float)))


def dissipation_match(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s) of the dissipation study, on the median
    curves of :func:`dissipation_curves`: ``e_ratio`` the largest e at which the median
    v_max,2/v_max,1 equals the chapter's measured 0.80 (:func:`last_crossing`),
    ``e_ratio_lo`` and ``e_ratio_hi`` where it equals the ends of the measured interval,
    0.72 and 0.88 (NaN where it never does), the medians v_max,1/v_s (``v1``),
    v_max,2/v_s (``v2``) and v_g (``vg``, m/s) at ``e_ratio`` (linear in e), the
    striker-side factors the measured peaks need there, ``striker_v1`` = 0.57 / v1 and
    ``striker_v2`` = 0.46 / v2, and the largest e's ``e_max``, ``ratio_at_e_max``,
    ``v1_at_e_max``; ``n_e`` the number of e values."""
    c = dissipation_curves(df)
    rm, rh = MEASURED_PEAKS["ratio"]
    rows = []
    for key, g in c.groupby(["material", "gap_mean_nm", "v_striker_m_s"], sort=False):
        e = g["restitution_e"].to_numpy(dtype=float)
        ratio = g["ratio_median"].to_numpy(dtype=float)
        es = last_crossing(e, ratio, rm)
        v1 = interpolate_at(e, g["v1_median"], es)
        v2 = interpolate_at(e, g["v2_median"], es)
        rows.append({"material": key[0], "gap_mean_nm": float(key[1]),
                     "v_striker_m_s": float(key[2]), "n_e": int(e.size), "e_ratio": es,
                     "e_ratio_lo": last_crossing(e, ratio, rm - rh),
                     "e_ratio_hi": last_crossing(e, ratio, rm + rh),
                     "v1": v1, "v2": v2, "vg": interpolate_at(e, g["vg_median"], es),
                     "striker_v1": MEASURED_PEAKS["v1"][0] / v1,
                     "striker_v2": MEASURED_PEAKS["v2"][0] / v2,
                     "e_max": float(e[-1]), "ratio_at_e_max": float(ratio[-1]),
                     "v1_at_e_max": float(g["v1_median"].iloc[-1])})
    return pd.DataFrame(rows)


def plasticity_match(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s) of the plasticity study, on the median
    curves of :func:`plasticity_curves` against log p_y (its finite p_y; the elastic chain
    is the limit p_y -> inf): ``py_v1`` the largest p_y at which the median v_max,1 / v_s
    equals the chapter's measured 0.57 (:func:`last_crossing` in log p_y), ``py_v1_lo`` and
    ``py_v1_hi`` where it equals the ends of the measured interval, 0.48 and 0.66 (NaN where
    it never does in the study's range), the medians v_max,2 / v_s (``v2``), the ratio
    (``ratio``) and v_g (``vg``, m/s) there (linear in log p_y), the elastic chain's
    ``v1_elastic`` and ``ratio_elastic``, the smallest p_y's ``py_min``, ``v1_at_py_min`` and
    the largest's ``py_max``, ``v1_at_py_max``; ``n_py`` the number of finite p_y."""
    c = plasticity_curves(df)
    m1, h1 = MEASURED_PEAKS["v1"]
    rows = []
    for key, g in c.groupby(["material", "gap_mean_nm", "v_striker_m_s"], sort=False):
        fin = g[np.isfinite(g["yield_pressure_Pa"].to_numpy(dtype=float))]
        el = g[~np.isfinite(g["yield_pressure_Pa"].to_numpy(dtype=float))]
        lp = np.log10(fin["yield_pressure_Pa"].to_numpy(dtype=float))
        v1 = fin["v1_median"].to_numpy(dtype=float)
        lo, hi = last_crossing(lp, v1, m1 - h1), last_crossing(lp, v1, m1 + h1)
        at = last_crossing(lp, v1, m1)
        row = {"material": key[0], "gap_mean_nm": float(key[1]),
               "v_striker_m_s": float(key[2]), "n_py": int(lp.size),
               "py_v1": 10.0 ** at if math.isfinite(at) else math.nan,
               "py_v1_lo": 10.0 ** lo if math.isfinite(lo) else math.nan,
               "py_v1_hi": 10.0 ** hi if math.isfinite(hi) else math.nan}
        for q in ("v2", "ratio", "vg"):
            row[q] = interpolate_at(lp, fin[f"{q}_median"], at) if lp.size else math.nan
        row["v1_elastic"] = float(el["v1_median"].iloc[0]) if len(el) else math.nan
        row["ratio_elastic"] = float(el["ratio_median"].iloc[0]) if len(el) else math.nan
        row["py_min"] = float(10.0 ** lp[0]) if lp.size else math.nan
        row["v1_at_py_min"] = float(v1[0]) if lp.size else math.nan
        row["py_max"] = float(10.0 ** lp[-1]) if lp.size else math.nan
        row["v1_at_py_max"] = float(v1[-1]) if lp.size else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def plasticity_exponents(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, yield_pressure_Pa) of the plasticity study: the exponent
    ``b`` of the median v_max,1 = a v_s^b over the study's striker speeds
    (:func:`~granchain.reductions.field.power_law_fit`; the chapter measures a linear
    v_max,1(v_s), b = 1, as does an elastic Hertz chain), its prefactor ``a`` (m/s at
    v_s = 1 m/s), the same for v_max,2 (``b2``), and ``n_v`` the number of speeds."""
    c = plasticity_curves(df)
    rows = []
    for key, g in c.groupby(["material", "gap_mean_nm", "yield_pressure_Pa"], sort=False):
        vs = g["v_striker_m_s"].to_numpy(dtype=float)
        b, a = power_law_fit(vs, g["v1_median"].to_numpy(dtype=float) * vs)
        b2, _ = power_law_fit(vs, g["v2_median"].to_numpy(dtype=float) * vs)
        rows.append({"material": key[0], "gap_mean_nm": float(key[1]),
                     "yield_pressure_Pa": float(key[2]), "n_v": int(vs.size), "b": b, "a": a,
                     "b2": b2})
    return pd.DataFrame(rows)


def cohesion_match(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s, groove_cohesion) of the adhesion study,
    on the median curves of :func:`cohesion_curves` against log gamma (its gamma > 0; the
    chain without adhesion is gamma -> 0): ``gamma_v1`` the least gamma at which the median
    v_max,1 / v_s falls to the chapter's measured 0.57 (:func:`first_reaching` in log gamma:
    the weakest adhesion that gives the measured peak; the curve need not be monotone, the
    contacts' pull raises the peak at large gamma); NaN where it never does in the study's
    range, or where the least gamma's is 0.57 or below already (the crossing lies below the
    study's range), the chain without adhesion's ``v1_none``, the least gamma's
    ``gamma_min``, ``v1_at_gamma_min``, and the largest gamma's ``gamma_max``,
    ``v1_at_gamma_max``, ``ratio_at_gamma_max`` and ``vg_at_gamma_max``; ``n_gamma`` the
    number of gamma > 0."""
    c = cohesion_curves(df)
    m1 = MEASURED_PEAKS["v1"][0]
    none = c[c["surface_energy_J_m2"] == 0]
    rows = []
    for key, g in c[c["surface_energy_J_m2"] > 0].groupby(
            ["material", "gap_mean_nm", "v_striker_m_s", "groove_cohesion"], sort=False):
        lg = np.log10(g["surface_energy_J_m2"].to_numpy(dtype=float))
        v1 = g["v1_median"].to_numpy(dtype=float)
        at = first_reaching(lg, -v1, -m1) if v1[0] > m1 else math.nan
        base = none[(none["material"] == key[0]) & (none["gap_mean_nm"] == key[1])
                    & (none["v_striker_m_s"] == key[2])]
        rows.append({"material": key[0], "gap_mean_nm": float(key[1]),
                     "v_striker_m_s": float(key[2]), "groove_cohesion": bool(key[3]),
                     "n_gamma": int(lg.size),
                     "gamma_v1": 10.0 ** at if math.isfinite(at) else math.nan,
                     "v1_none": float(base["v1_median"].iloc[0]) if len(base) else math.nan,
                     "gamma_min": float(10.0 ** lg[0]), "v1_at_gamma_min": float(v1[0]),
                     "gamma_max": float(10.0 ** lg[-1]), "v1_at_gamma_max": float(v1[-1]),
                     "ratio_at_gamma_max": float(g["ratio_median"].iloc[-1]),
                     "vg_at_gamma_max": float(g["vg_median"].iloc[-1])})
    return pd.DataFrame(rows)


def capture_velocities(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, surface_energy_J_m2) of the capture study (two-sphere collisions,
    ascending gamma): ``n`` collisions, ``n_captured``, ``n_separated``, ``n_unfinished``;
    ``v_c`` the capture velocity, the median over the separated collisions of
    v_s sqrt(1 - e^2) (a law that loses a fixed energy per collision, as JKR's hysteresis
    without damping does, gives v_c exactly: e^2 = 1 - v_c^2 / v_s^2), with its least and
    largest values ``v_c_min``, ``v_c_max``; ``v_captured_max`` the fastest captured
    collision and ``v_separated_min`` the slowest separated one (NaN where none), and
    ``bracketed``: v_captured_max < v_c < v_separated_min where both exist."""
    require(df, NEEDS["capture"], "capture")
    rows = []
    for mat in materials_in(df):
        for gamma, g in df[df["material"] == mat].groupby("surface_energy_J_m2", sort=True):
            sep = g[g["pair_collision"] == "separated"]
            cap = g[g["pair_collision"] == "captured"]
            vs = sep["v_striker_m_s"].to_numpy(dtype=float)
            e = sep["pair_restitution"].to_numpy(dtype=float)
            vc = vs * np.sqrt(np.clip(1.0 - e ** 2, 0.0, None))
            lo, med, hi = (float(np.min(vc)), float(np.median(vc)), float(np.max(vc))) \
                if vc.size else (math.nan,) * 3
            vcap = float(cap["v_striker_m_s"].max()) if len(cap) else math.nan
            vsep = float(vs.min()) if vs.size else math.nan
            rows.append({"material": mat, "surface_energy_J_m2": float(gamma),
                         "n": int(len(g)), "n_captured": int(len(cap)),
                         "n_separated": int(len(sep)),
                         "n_unfinished": int((g["pair_collision"] == "unfinished").sum()),
                         "v_c": med, "v_c_min": lo, "v_c_max": hi,
                         "v_captured_max": vcap, "v_separated_min": vsep,
                         "bracketed": bool(vcap < med < vsep)})
    return pd.DataFrame(rows)
