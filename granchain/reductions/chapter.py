"""Reductions of the chapter's chain: the packed chain (v_max fits, v_g interpolation,
peak profiles), spreads over realisations, Eq. 5.4 (the chapter's bound on v_g with mean
gap gbar), a trace's pulse width and the energy columns."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..analytic import eq54_group_velocity
from ..errors import GranchainError
from .table import (NEEDS, PROBES, arrived, materials_in, n_particles, reference_engine,
                    require, require_vmax, vmax_columns)


# ---------------------------------------------------------------------------------------
# the packed chain
# ---------------------------------------------------------------------------------------
def fit_through_origin(x, y) -> float:
    """Least-squares slope a of y = a x over the finite pairs, a = sum(x y) / sum(x^2)
    (the chapter's linear fit of Fig. 5.1b); NaN if no pair is finite."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return math.nan
    return float(np.dot(x[ok], y[ok]) / np.dot(x[ok], x[ok]))


def vmax_fits(packed: pd.DataFrame) -> dict:
    """Dimensionless slopes of v_max,1 = a1 v_s and v_max,2 = a2 v_s (fits through the
    origin over the packed sweep, reference engine):
    ``{material: {"v_max_1": a1, "v_max_2": a2}}``."""
    require(packed, NEEDS["fig5_1b"], "fig5_1b")
    packed = reference_engine(packed)
    out = {}
    for mat in materials_in(packed):
        d = packed[packed["material"] == mat]
        out[mat] = {c: fit_through_origin(d["v_striker_m_s"], d[c + "_m_s"])
                    for c in ("v_max_1", "v_max_2")}
    return out


def packed_vg(packed: pd.DataFrame, mat: str, v_striker, column: str = "v_g_m_s") -> np.ndarray:
    """Packed chain's v_g (``column``, m/s) of ``mat`` at the striker speeds ``v_striker``
    (m/s), as an array.

    Exact rows where the packed sweep has that speed (median if repeated); elsewhere
    linear interpolation in log v_g vs log v_s between the sweep's speeds, and outside
    the sweep the power law fitted to its two nearest ends (v_g ~ v_s^(1/5) for Hertz;
    with a single speed, that exponent 1/5).
    """
    require(packed, NEEDS["packed_reference"] + [column], "packed reference")
    d = arrived(reference_engine(packed))
    d = d[(d["material"] == mat) & np.isfinite(d[column].astype(float))]
    if d.empty:
        raise GranchainError(f"packed reference: no arrived packed-chain row for material "
                             f"'{mat}'; add it to studies.packed_sweep in config/config.yaml")
    g = d.groupby("v_striker_m_s")[column].median()
    xs = np.log(g.index.to_numpy(dtype=float))
    ys = np.log(g.to_numpy(dtype=float))
    q = np.log(np.atleast_1d(np.asarray(v_striker, dtype=float)))
    if xs.size == 1:
        # one speed: Nesterenko's v_g ~ v_m^(1/5) with v_m proportional to v_s
        return np.exp(ys[0] + 0.2 * (q - xs[0]))
    out = np.interp(q, xs, ys)
    lo, hi = q < xs[0], q > xs[-1]
    if lo.any():
        s = (ys[1] - ys[0]) / (xs[1] - xs[0])
        out[lo] = ys[0] + s * (q[lo] - xs[0])
    if hi.any():
        s = (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
        out[hi] = ys[-1] + s * (q[hi] - xs[-1])
    return np.exp(out)


def peak_profile(df: pd.DataFrame, what: str, last: int | None = None) -> np.ndarray:
    """Dimensionless peak profile v_max,i / v_s, shape (members, particles), for
    particles i = 1..last (default: the far probe, particle 13)."""
    cols = require_vmax(df, what)
    last = PROBES[-1] if last is None else last
    cols = cols[:last]
    return df[cols].to_numpy(dtype=float) / df["v_striker_m_s"].to_numpy(dtype=float)[:, None]


def packed_profile(packed: pd.DataFrame, mat: str, vs: float, what: str):
    """(v_max,i / v_s for every particle of the packed chain of ``mat`` at the sweep's
    speed closest to ``vs`` in log v_s, that speed in m/s); (None, None) if the table has
    no such row or no per-particle columns."""
    d = reference_engine(packed)
    d = d[d["material"] == mat]
    if d.empty or not vmax_columns(d):
        return None, None
    speeds = d["v_striker_m_s"].to_numpy(dtype=float)
    k = int(np.argmin(np.abs(np.log(speeds / vs))))
    row = d.iloc[[k]]
    return peak_profile(row, what, last=n_particles(row))[0], float(speeds[k])


# ---------------------------------------------------------------------------------------
# spreads
# ---------------------------------------------------------------------------------------
def oscillation(profile: np.ndarray, first: int = PROBES[0]) -> np.ndarray:
    """Relative peak-to-peak spread of v_max along each chain, (max - min)/mean over
    particles first..last of the profile (the striker, particle 1, excluded);
    dimensionless, one value per row of ``profile``."""
    p = np.asarray(profile, dtype=float)[:, first - 1:]
    return (p.max(axis=1) - p.min(axis=1)) / p.mean(axis=1)


def band(values, lo=5.0, hi=95.0):
    """(p_lo, median, p_hi) of finite values, NaNs if none (numpy linear percentiles);
    in the values' units."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, math.nan
    p = np.percentile(v, [lo, 50.0, hi])
    return float(p[0]), float(p[1]), float(p[2])


# ---------------------------------------------------------------------------------------
# Eq. 5.4: (2R + gbar) / v_g = 2R / v_g(packed) + gbar / v_s
# ---------------------------------------------------------------------------------------
def gap_for_reduction(vg0: float, vs: float, reduction: float, radius: float) -> float:
    """Mean gap gbar (m) at which Eq. 5.4 cuts the packed v_g ``vg0`` (m/s) by the
    fraction ``reduction`` at striker speed ``vs`` (m/s) with sphere radius ``radius``
    (m): with v = (1 - reduction) vg0, gbar = 2R (1/v - 1/vg0) / (1/vs - 1/v)."""
    v = (1.0 - reduction) * vg0
    return 2.0 * radius * (1.0 / v - 1.0 / vg0) / (1.0 / vs - 1.0 / v)


def bound_ratios(df: pd.DataFrame, packed: pd.DataFrame, radius: float,
                 gbar_nm=None) -> pd.DataFrame:
    """Arrived members of ``df`` with three added columns: ``vg_packed`` (m/s), the
    packed chain's v_g at the member's v_s (:func:`packed_vg`); ``r_peak`` = v_g / Eq. 5.4
    and ``r_front`` = v_g_front / Eq. 5.4 built on the packed chain's v_g_front (NaN
    without front columns), both dimensionless. Eq. 5.4 uses the member's own mean gap
    between the probes (``gap_mean_probes_nm``), or the column named by ``gbar_nm``, and
    the sphere radius ``radius`` (m)."""
    ok = arrived(df)
    parts = []
    for mt in materials_in(ok):
        d = ok[ok["material"] == mt].copy()
        vs = d["v_striker_m_s"].to_numpy(dtype=float)
        g = d[gbar_nm or "gap_mean_probes_nm"].to_numpy(dtype=float) * 1e-9
        d["vg_packed"] = packed_vg(packed, mt, vs)
        bound = eq54_group_velocity(d["vg_packed"].to_numpy(), g, vs, radius)
        d["r_peak"] = d["v_g_m_s"].to_numpy(dtype=float) / bound
        if "v_g_front_m_s" in d.columns and "v_g_front_m_s" in packed.columns:
            front = eq54_group_velocity(packed_vg(packed, mt, vs, "v_g_front_m_s"), g, vs,
                                        radius)
            d["r_front"] = d["v_g_front_m_s"].to_numpy(dtype=float) / front
        else:
            d["r_front"] = np.nan
        parts.append(d)
    return pd.concat(parts) if parts else ok.assign(vg_packed=[], r_peak=[], r_front=[])


# ---------------------------------------------------------------------------------------
# a trace, and the energy columns
# ---------------------------------------------------------------------------------------
def pulse_width(t, v, level: float = 0.5) -> float:
    """Measured width (s) of one particle's velocity pulse v(t) at ``level`` x its peak
    (0.5: full width at half maximum), with the two crossings linearly interpolated
    between samples; NaN if the pulse does not fall below that level on both sides.
    (:func:`granchain.analytic.pulse_width` is Nesterenko's predicted width.)"""
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    j = int(np.argmax(v))
    half = level * v[j]
    up = np.flatnonzero(v[: j + 1] < half)
    dn = np.flatnonzero(v[j:] < half)
    if up.size == 0 or dn.size == 0:
        return math.nan
    a, b = int(up[-1]), j + int(dn[0])
    t_up = t[a] + (half - v[a]) / (v[a + 1] - v[a]) * (t[a + 1] - t[a])
    t_dn = t[b - 1] + (half - v[b - 1]) / (v[b] - v[b - 1]) * (t[b] - t[b - 1])
    return float(t_dn - t_up)


def work_fraction(row: pd.DataFrame, column: str) -> float:
    """Work of one effect over the initial energy, W / E (dimensionless, signed: < 0
    when the effect takes energy), of the first row; ``column`` is a ``work_*_J``
    column."""
    return float(row[column].iloc[0]) / float(row["energy_initial_J"].iloc[0])


def non_hertz_work_fraction(row: pd.DataFrame) -> float:
    """All non-Hertz work over the initial energy of the first row,
    (W_groove + W_air + W_particle_friction + W_rolling) / E (dimensionless)."""
    e0 = float(row["energy_initial_J"].iloc[0])
    return (row["work_groove_J"] + row["work_air_J"] + row["work_particle_friction_J"]
            + row["work_rolling_J"]).iloc[0] / e0


def sphere_mass(rho: float, radius: float) -> float:
    """Mass (kg) of a sphere of density ``rho`` (kg/m^3) and radius ``radius`` (m),
    m = rho 4/3 pi R^3."""
    return rho * 4.0 / 3.0 * math.pi * radius**3


def groove_slide(work_groove: float, mass: float, g: float, mu: float) -> float:
    """Sliding distance dx (m) over which Coulomb friction of one particle in the groove,
    mu m g, does the work ``work_groove`` (J, negative): dx = -W / (m g mu) (the dx of
    Eq. 5.2, dE_coulomb/E ~ -2 g mu dx / v_s^2)."""
    return -work_groove / (mass * g * mu)
