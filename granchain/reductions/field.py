"""Reductions of the field's studies, beyond the chapter: a precompressed chain and the
chain on a wall (tables/precompression.csv, tables/wall.csv)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..errors import GranchainError
from .table import (NEEDS, arrived, material, materials_in, radius_or_default,
                    reference_engine, require)

# Hertz: the wall force of a solitary wave scales as v_s^(6/5) (F ~ delta^(3/2), delta ~
# v_s^(4/5) for a wave of amplitude v_m ~ v_s: Nesterenko's xi_m ~ v_m^(4/5))
HERTZ_WALL_EXPONENT = 1.2


def precompression_rows(df: pd.DataFrame, radius: float | None = None) -> pd.DataFrame:
    """The precompression study's arrived members (reference engine when mixed), ordered
    by load then striker speed, with what the theory needs: ``F0_N`` (the dead load: the
    static wall force of the row's scene, which every contact carries at rest; the median
    over the scene's members, equal to rounding), ``v_m_m_s`` (the wave's
    peak particle velocity, the mean of the probes' v_max,1 and v_max,2), ``c0_m_s``
    (:func:`granchain.analytic.precompressed_sound_speed`; 0 unloaded), ``f_r`` (F_m/F0 of
    the solitary wave of that v_m, NaN unloaded), ``V_theory_m_s`` (Nesterenko's speed at
    v_m: Daraio et al. 2006 Eq. (3) loaded, the uncompressed wave unloaded) and the ratios
    ``vg_over_theory``, ``vg_front_over_theory``, ``vg_over_c0``. ``radius`` in m (the
    table does not carry it; default the chapter's 150 um)."""
    from ..analytic import (precompressed_amplitude, precompressed_solitary_speed,
                            precompressed_sound_speed)
    require(df, NEEDS["precompression"], "precompression")
    radius = radius_or_default(radius)
    d = arrived(reference_engine(df)).copy()
    if d.empty:
        raise GranchainError("precompression: no member of the table saw its wave arrive; "
                             "check studies.precompression (probes, t_end) in config/config.yaml")
    out = []
    for mat in materials_in(d):
        m = material(mat)
        g = d[d["material"] == mat]
        # the scene's load: its members' static wall force (equal to rounding)
        F0 = g.groupby("scene_hash")["wall_force_static_N"].transform("median") \
            .to_numpy(dtype=float)
        vm = 0.5 * (g["v_max_1_m_s"].to_numpy(dtype=float) + g["v_max_2_m_s"].to_numpy(dtype=float))
        c0 = np.asarray(precompressed_sound_speed(m, radius, F0), dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            fr = np.where(F0 > 0, precompressed_amplitude(m, radius, F0, vm), np.nan)
            V = np.asarray(precompressed_solitary_speed(m, radius, F0, vm), dtype=float)
            vg = g["v_g_m_s"].to_numpy(dtype=float)
            out.append(g.assign(F0_N=F0, v_m_m_s=vm, c0_m_s=c0, f_r=fr, V_theory_m_s=V,
                                vg_over_theory=vg / V,
                                vg_front_over_theory=g["v_g_front_m_s"].to_numpy(dtype=float) / V,
                                vg_over_c0=np.where(F0 > 0, vg / c0, np.nan)))
    return pd.concat(out).sort_values(["material", "F0_N", "v_striker_m_s"], kind="stable") \
        .reset_index(drop=True)


def power_law_fit(x, y) -> tuple[float, float]:
    """(exponent b, prefactor a) of y = a x^b, least squares of log y on log x over the
    pairs where both are finite and positive; NaNs with fewer than two such pairs."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if ok.sum() < 2 or np.unique(x[ok]).size < 2:
        return math.nan, math.nan
    b, loga = np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)
    return float(b), float(math.exp(loga))


def wall_fits(df: pd.DataFrame) -> dict:
    """Per material of the wall study (reference engine when mixed), over the rows whose
    wall peak was measured (finite ``wall_force_max_N``): ``exponent`` and ``prefactor``
    (N at v_s = 1 m/s) of the power-law fit F_wall = a v_s^b (:func:`power_law_fit`),
    ``prefactor_hertz`` (the fit with the exponent fixed at 6/5: a = exp(mean(ln F -
    1.2 ln v_s))), ``local`` (the exponents between neighbouring speeds, ascending v_s),
    ``v`` and ``F`` (the rows, ascending v_s), ``n`` and ``missing`` (rows without a
    measured peak)."""
    require(df, NEEDS["wall"], "wall")
    d = reference_engine(df)
    out = {}
    for mat in materials_in(d):
        g = d[d["material"] == mat].sort_values("v_striker_m_s", kind="stable")
        v = g["v_striker_m_s"].to_numpy(dtype=float)
        F = g["wall_force_max_N"].to_numpy(dtype=float)
        ok = np.isfinite(F) & (F > 0)
        b, a = power_law_fit(v[ok], F[ok])
        v, F = v[ok], F[ok]
        ah = float(np.exp(np.mean(np.log(F) - HERTZ_WALL_EXPONENT * np.log(v)))) if F.size \
            else math.nan
        local = np.diff(np.log(F)) / np.diff(np.log(v)) if F.size > 1 else np.array([])
        out[mat] = {"exponent": b, "prefactor": a, "prefactor_hertz": ah, "local": local,
                    "v": v, "F": F, "n": int(ok.sum()), "missing": int((~ok).sum())}
    return out
