"""Table-level reductions shared by the figures and the thesis comparison.

Everything here reads or reduces the workflow's result tables -- CSVs with one row per
chain and units in the column names (``v_striker_m_s``, ``v_g_m_s``, ``vmax_p01_m_s`` ...;
the columns are written by granchain/tables.py) -- or a Fig. 5.1a trace npz. Nothing here
simulates and nothing draws: no matplotlib import. The figures (granchain/figures/) and
the thesis table (granchain/thesis/) both build on these functions, so each number they
share is computed in one place.

Sections: reading and checking tables; selecting rows; reductions of the packed chain
(v_max fits, v_g interpolation, peak profiles); spreads over realisations; Eq. 5.4 (the
chapter's bound on v_g with mean gap gbar); reductions of a trace and of the energy
columns. A missing table or column is a one-line :class:`~granchain.errors.GranchainError`.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .analytic import eq54_group_velocity
from .errors import GranchainError
from .materials import library
from .scene import DEFAULTS

# The chapter's probes (particles 2 and 13) and chain radius, used where a table cannot
# say them. The tables carry every particle's v_max but not the probes.
PROBES = tuple(DEFAULTS["probes"])
# Material names as the chapter prints them; also the order materials are listed in.
MATERIAL_LABEL = {"ss316": "316", "ss440c": "440C"}

VMAX_RE = re.compile(r"^vmax_p(\d+)_m_s$")

# Columns each use of a table needs (the tables' column names); the keys name the use in
# error messages.
NEEDS = {
    "fig5_1b": ["material", "v_striker_m_s", "v_max_1_m_s", "v_max_2_m_s"],
    "fig5_1c": ["material", "v_striker_m_s", "v_max_2_m_s", "v_g_m_s", "wave_arrived"],
    "fig5_3b": ["material", "v_striker_m_s", "realisation", "gap_mean_nm"],
    "fig5_3c": ["material", "v_striker_m_s", "gap_mean_nm", "realisation", "v_g_m_s",
                "wave_arrived"],
    "fig5_4b": ["material", "v_striker_m_s", "extra_length_um", "realisation", "v_g_m_s",
                "wave_arrived"],
    "packed_reference": ["material", "v_striker_m_s", "v_g_m_s", "wave_arrived"],
    "trace": ["t_s", "v_m_s", "v_striker_m_s", "material"],
}


# ---------------------------------------------------------------------------------------
# reading and checking tables
# ---------------------------------------------------------------------------------------
def read_table(path) -> pd.DataFrame:
    """One result table (its Parquet copy or its CSV, ``granchain.tables.read_table``) as
    a DataFrame, its file name in ``df.attrs["name"]``; a one-line error when the file is
    missing."""
    path = Path(path)
    if not path.is_file():
        raise GranchainError(f"table '{path}' not found; produce it with the workflow "
                             f"(snakemake --cores 2 {path})")
    from . import tables
    df = tables.read_table(path)
    df.attrs["name"] = path.name
    return df


def read_trace(path) -> dict:
    """The Fig. 5.1a trace npz as a dict: ``t_s`` (S,) in s, ``v_m_s`` (S, n) particle
    velocities in m/s, ``v_striker_m_s`` (float, m/s), ``material`` (str) and ``name``
    (the file name)."""
    path = Path(path)
    if not path.is_file():
        raise GranchainError(f"trace '{path}' not found; produce it with the workflow "
                             f"(snakemake --cores 2 {path})")
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in NEEDS["trace"] if k not in z.files]
        if missing:
            raise GranchainError(f"trace '{path.name}' lacks {', '.join(missing)}; "
                                 "regenerate it with the workflow (contract: t_s, v_m_s, "
                                 "v_striker_m_s, material)")
        out = {k: z[k] for k in z.files}
    out["material"] = str(out["material"])
    out["v_striker_m_s"] = float(out["v_striker_m_s"])
    out["name"] = path.name
    return out


def require(df: pd.DataFrame, columns, what: str) -> None:
    """Raise a one-line error naming the table and the missing columns (or that the
    table is absent or empty); ``what`` names the use in the message."""
    if df is None:
        raise GranchainError(f"{what}: no table given; pass it (see python -m granchain.figures -h)")
    missing = [c for c in columns if c not in df.columns]
    if missing:
        name = df.attrs.get("name", "table")
        raise GranchainError(f"{what}: table '{name}' lacks column(s) {', '.join(missing)}; "
                             "regenerate it with the workflow (granchain/tables.py writes "
                             "the contract's columns)")
    if len(df) == 0:
        raise GranchainError(f"{what}: table '{df.attrs.get('name', 'table')}' has no rows; "
                             "check the study's settings in config/config.yaml")


def vmax_columns(df: pd.DataFrame) -> list[str]:
    """The per-particle v_max columns vmax_p01_m_s ... in particle order."""
    cols = [(int(m.group(1)), c) for c in df.columns if (m := VMAX_RE.match(c))]
    return [c for _, c in sorted(cols)]


def require_vmax(df: pd.DataFrame, what: str) -> list[str]:
    """:func:`vmax_columns`, or a one-line error when the table has none."""
    cols = vmax_columns(df)
    if not cols:
        raise GranchainError(f"{what}: table '{df.attrs.get('name', 'table')}' lacks the "
                             "per-particle columns vmax_p01_m_s ...; regenerate it with the "
                             "workflow")
    return cols


# ---------------------------------------------------------------------------------------
# selecting rows
# ---------------------------------------------------------------------------------------
def reference_engine(df: pd.DataFrame) -> pd.DataFrame:
    """Rows of the reference engine when a table mixes engines (else all rows)."""
    if "engine" in df.columns and df["engine"].nunique() > 1:
        df = df[df["engine"] == "reference"]
    return df


def arrived(df: pd.DataFrame) -> pd.DataFrame:
    """Members whose wave reached the far probe with a finite v_g."""
    ok = df["wave_arrived"].astype(bool) & np.isfinite(df["v_g_m_s"].astype(float))
    return df[ok]


def materials_in(df: pd.DataFrame) -> list[str]:
    """The table's materials, 316 then 440C then any other in name order."""
    order = list(MATERIAL_LABEL)
    found = list(dict.fromkeys(df["material"]))
    return sorted(found, key=lambda m: (order.index(m) if m in order else len(order), m))


def material(name: str):
    """The :class:`~granchain.materials.Material` of a table's material name."""
    lib = library()
    if name not in lib:
        raise GranchainError(f"material '{name}' of the table is not in granchain/data/"
                             f"materials.yaml; known: {', '.join(lib)}")
    return lib[name]


def label(mat: str) -> str:
    """The chapter's name of a material (``ss440c`` -> ``440C``)."""
    return MATERIAL_LABEL.get(mat, mat)


def nearest_speed(df: pd.DataFrame, mat: str, vs: float) -> pd.DataFrame:
    """Reference-engine rows of ``mat`` at the striker speed closest to ``vs`` (m/s) in
    log v_s, i.e. minimising |ln(v_s / vs)|; empty if the table has no ``mat`` row."""
    d = reference_engine(df)
    d = d[d["material"] == mat]
    if d.empty:
        return d
    speeds = np.array(sorted(set(d["v_striker_m_s"].astype(float))))
    best = speeds[int(np.argmin(np.abs(np.log(speeds / vs))))]
    return d[d["v_striker_m_s"].astype(float) == best]


def striker_speed(d: pd.DataFrame) -> float:
    """v_s (m/s) of the first row, NaN for no rows."""
    return float(d["v_striker_m_s"].iloc[0]) if len(d) else math.nan


def radius_or_default(radius: float | None) -> float:
    """Sphere radius (m). The tables do not carry it: the caller passes the preset's
    (the workflow does), else the chapter's 150 um (scene default)."""
    if radius is None:
        return float(DEFAULTS["chain"]["radius"])
    if not (isinstance(radius, (int, float)) and radius > 0):
        raise GranchainError(f"radius {radius!r} must be a positive number of metres")
    return float(radius)


def n_particles(df: pd.DataFrame) -> int:
    """Chain length n: the number of per-particle v_max columns, else the scene
    default."""
    cols = vmax_columns(df)
    if cols:
        return len(cols)
    return int(DEFAULTS["chain"]["n"])


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


# ---------------------------------------------------------------------------------------
# the vibrometer study (tables/vibrometer.csv, traces/vibrometer_<material>.npz)
# ---------------------------------------------------------------------------------------
NEEDS["vibrometer"] = ["material", "gap_mean_nm", "v_striker_m_s", "filter", "bandwidth_hz",
                       "v_max_1_measured_over_true", "v_max_2_measured_over_true",
                       "dt_peak_bias_s", "dt_peak_s", "measured_not_final"]
NEEDS["vibrometer_trace"] = ["t_s", "v_m_s", "probes", "v_striker_m_s", "material",
                             "bandwidth_hz", "sampling_rate_hz", "order", "filters", "t_rec_s",
                             "vmax_true_m_s", "t_peak_true_s"]
# the ratios and the relative delay bias the vibrometer reductions report
VIB_QUANTITIES = {"v1": "v_max_1_measured_over_true", "v2": "v_max_2_measured_over_true",
                  "dt": "dt_peak_rel_bias"}


def read_vibrometer_trace(path) -> dict:
    """A vibrometer trace npz (``granchain.workflow.vibrometer``) as a dict; ``filters``
    as a list of str, scalars as Python numbers, ``name`` the file name."""
    path = Path(path)
    if not path.is_file():
        raise GranchainError(f"trace '{path}' not found; produce it with the workflow "
                             f"(snakemake --cores 2 {path})")
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in NEEDS["vibrometer_trace"] if k not in z.files]
        if missing:
            raise GranchainError(f"trace '{path.name}' lacks {', '.join(missing)}; "
                                 "regenerate it with the workflow")
        out = {k: z[k] for k in z.files}
    out["filters"] = [str(f) for f in out["filters"]]
    out["material"] = str(out["material"])
    for k in ("v_striker_m_s", "bandwidth_hz", "sampling_rate_hz"):
        out[k] = float(out[k])
    out["name"] = path.name
    return out


def vibrometer_bands(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, filter, bandwidth_hz): rows, rows with both recorded
    peaks final, and the median, min and max over striker speeds and realisations of
    the recorded/true v_max,1 and v_max,2 (v1, v2) and of the relative peak-to-peak delay
    bias (dt: (dt_measured - dt)/dt), over the rows where each is finite."""
    require(df, NEEDS["vibrometer"], "vibrometer")
    d = df.assign(dt_peak_rel_bias=df["dt_peak_bias_s"].astype(float)
                  / df["dt_peak_s"].astype(float))
    rows = []
    for key, g in d.groupby(["material", "gap_mean_nm", "filter", "bandwidth_hz"], sort=True):
        row = dict(zip(["material", "gap_mean_nm", "filter", "bandwidth_hz"], key))
        nf = g["measured_not_final"].fillna("").astype(str).str.len() > 0
        row.update(n=int(len(g)), n_final=int((~nf).sum()))
        for q, col in VIB_QUANTITIES.items():
            x = g[col].to_numpy(dtype=float)
            x = x[np.isfinite(x)]
            row[f"{q}_median"] = float(np.median(x)) if x.size else math.nan
            row[f"{q}_min"] = float(x.min()) if x.size else math.nan
            row[f"{q}_max"] = float(x.max()) if x.size else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def nearest_bandwidth(df: pd.DataFrame, bandwidth_hz: float) -> float:
    """The table's bandwidth closest to ``bandwidth_hz`` in log scale."""
    bws = np.array(sorted(set(df["bandwidth_hz"].astype(float))))
    return float(bws[int(np.argmin(np.abs(np.log(bws / bandwidth_hz))))])


# ---------------------------------------------------------------------------------------
# the field's studies: a precompressed chain and the chain on a wall (tables/precompression.csv,
# tables/wall.csv); beyond the chapter
# ---------------------------------------------------------------------------------------
NEEDS["precompression"] = ["material", "scene_hash", "v_striker_m_s", "v_max_1_m_s",
                           "v_max_2_m_s", "v_g_m_s", "v_g_front_m_s", "wave_arrived",
                           "wall_force_static_N"]
NEEDS["wall"] = ["material", "v_striker_m_s", "wall_force_max_N", "wave_arrived"]
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
    from .analytic import (precompressed_amplitude, precompressed_solitary_speed,
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


# ---------------------------------------------------------------------------------------
# the chapter's questions: a sphere-size tolerance and contact dissipation
# (tables/radius_spread.csv, tables/dissipation.csv); beyond Eq. 5.1
# ---------------------------------------------------------------------------------------
NEEDS["radius_spread"] = ["material", "v_striker_m_s", "gap_mean_nm", "realisation",
                          "radius_spread_distribution", "radius_sd_m"]
NEEDS["dissipation"] = ["material", "v_striker_m_s", "gap_mean_nm", "realisation",
                        "v_max_1_m_s", "v_max_2_m_s", "v_max_ratio", "v_g_m_s", "wave_arrived",
                        "damping_model", "restitution_e"]
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


def dissipation_curves(df: pd.DataFrame) -> pd.DataFrame:
    """Per (material, gap_mean_nm, v_striker_m_s, restitution_e) of the dissipation study
    (reference engine when mixed), ascending e within each (material, gap, v_s): ``n``,
    and the median, 5th and 95th percentiles over its chains of v_max,1 / v_s (``v1``),
    v_max,2 / v_s (``v2``) and v_max,2 / v_max,1 (``ratio``, the rows' v_max_ratio), and
    over its arrived chains (``n_arrived``) of v_g in m/s (``vg``): columns ``<q>_median``,
    ``<q>_p5``, ``<q>_p95``."""
    require(df, NEEDS["dissipation"], "dissipation")
    d = reference_engine(df)
    vs = d["v_striker_m_s"].to_numpy(dtype=float)
    d = d.assign(_v1=d["v_max_1_m_s"].to_numpy(dtype=float) / vs,
                 _v2=d["v_max_2_m_s"].to_numpy(dtype=float) / vs)
    keys = ["material", "gap_mean_nm", "v_striker_m_s", "restitution_e"]
    rows = []
    for mat in materials_in(d):
        for key, g in d[d["material"] == mat].groupby(keys[1:], sort=True):
            row = {"material": mat, **dict(zip(keys[1:], (float(k) for k in key))),
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
