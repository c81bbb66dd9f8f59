"""Reading and checking the workflow's result tables, and selecting their rows.

A result table is a CSV with one row per chain and units in the column names
(``v_striker_m_s``, ``v_g_m_s``, ``vmax_p01_m_s`` ...; granchain/tables.py writes them);
:data:`NEEDS` lists the columns each use of a table needs. A missing table or column is a
one-line :class:`~granchain.errors.GranchainError`.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import GranchainError
from ..materials import library
from ..scenekeys import DEFAULTS

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
    # the vibrometer study (tables/vibrometer.csv, traces/vibrometer_<material>.npz)
    "vibrometer": ["material", "gap_mean_nm", "v_striker_m_s", "filter", "bandwidth_hz",
                   "v_max_1_measured_over_true", "v_max_2_measured_over_true",
                   "dt_peak_bias_s", "dt_peak_s", "measured_not_final"],
    "vibrometer_trace": ["t_s", "v_m_s", "probes", "v_striker_m_s", "material",
                         "bandwidth_hz", "sampling_rate_hz", "order", "filters", "t_rec_s",
                         "vmax_true_m_s", "t_peak_true_s"],
    # the field's studies (tables/precompression.csv, tables/wall.csv)
    "precompression": ["material", "scene_hash", "v_striker_m_s", "v_max_1_m_s",
                       "v_max_2_m_s", "v_g_m_s", "v_g_front_m_s", "wave_arrived",
                       "wall_force_static_N"],
    "wall": ["material", "v_striker_m_s", "wall_force_max_N", "wave_arrived"],
    # the chapter's questions (tables/radius_spread.csv, tables/dissipation.csv)
    "radius_spread": ["material", "v_striker_m_s", "gap_mean_nm", "realisation",
                      "radius_spread_distribution", "radius_sd_m"],
    "dissipation": ["material", "v_striker_m_s", "gap_mean_nm", "realisation",
                    "v_max_1_m_s", "v_max_2_m_s", "v_max_ratio", "v_g_m_s", "wave_arrived",
                    "damping_model", "restitution_e"],
    "plasticity": ["material", "v_striker_m_s", "gap_mean_nm", "realisation",
                   "v_max_1_m_s", "v_max_2_m_s", "v_max_ratio", "v_g_m_s", "wave_arrived",
                   "plasticity_model", "yield_pressure_Pa"],
    "cohesion": ["material", "v_striker_m_s", "gap_mean_nm", "realisation",
                 "v_max_1_m_s", "v_max_2_m_s", "v_max_ratio", "v_g_m_s", "wave_arrived",
                 "cohesion_model", "surface_energy_J_m2", "groove_cohesion"],
    "capture": ["material", "v_striker_m_s", "pair_collision", "pair_restitution",
                "cohesion_model", "surface_energy_J_m2"],
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
    from .. import tables
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
