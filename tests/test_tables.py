"""The per-member tables' Parquet copies: typed, zstd, deterministic, and read back equal
to the CSV; tables.read_table picks the copy."""
from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from granchain import reductions, tables
from granchain.columns import member_column

N = 12


def _study_table() -> pd.DataFrame:
    """A table of every kind of column (measured, walled, a question study's settings):
    NaNs in the float columns, both flag values, text that a CSV reader would take for a
    number (a scene hash of digits, one particle), empty text."""
    rng = np.random.default_rng(3)
    cols = tables.columns(N, measured=True, walled=True, settings=tables.SPREAD_COLUMNS)
    text = ["0123456789012345", "13", "1;2", "", "1e5", "ss440c"]
    rows = []
    for r in range(7):
        row = {}
        for c in cols:
            kind = member_column(c).dtype
            if kind == "float":
                row[c] = math.nan if (r + len(c)) % 3 == 0 else float(rng.standard_normal())
            elif kind == "int":
                row[c] = int(rng.integers(0, 2**40))
            elif kind == "bool":
                row[c] = r % 2 == 0
            else:
                row[c] = text[(r + len(c)) % len(text)]
        rows.append(row)
    return tables.study_table(rows, N)


def test_parquet_round_trips_equal_to_the_csv(tmp_path):
    df = _study_table()
    csv = tmp_path / "t.csv"
    tables.write_csv(df, csv)
    from_csv = tables.read_table(csv)                  # no Parquet copy yet: the CSV
    tables.write_parquet(df, tables.parquet_path(csv))
    from_parquet = tables.read_table(tables.parquet_path(csv))
    pd.testing.assert_frame_equal(from_parquet, from_csv)
    assert from_parquet["v_max_1_m_s"].isna().any() and from_parquet["wave_arrived"].dtype == bool
    assert set(from_parquet["wave_arrived"]) == {True, False}
    assert (from_parquet["scene_hash"] == df["scene_hash"]).all()
    for c in ("realisation", "seed", "steps", "force_evaluations"):
        assert from_parquet[c].dtype == "int64"
    # the values are the table's own, not just those of a lossy reading
    assert np.array_equal(from_parquet["dt_s"].to_numpy(), df["dt_s"].to_numpy(), equal_nan=True)


def test_parquet_is_typed_and_zstd(tmp_path):
    df = _study_table()
    path = tmp_path / "t.parquet"
    tables.write_parquet(df, path)
    meta = pq.ParquetFile(path).metadata
    assert meta.num_row_groups == 1 and meta.metadata is None     # no pandas metadata
    schema = pq.read_schema(path)
    want = {"float": "double", "int": "int64", "bool": "bool", "string": "string"}
    for c in df.columns:
        assert str(schema.field(c).type) == want[member_column(c).dtype], c
    rg = meta.row_group(0)
    assert {rg.column(i).compression for i in range(rg.num_columns)} == {"ZSTD"}
    floats = [rg.column(i) for i in range(rg.num_columns)
              if member_column(rg.column(i).path_in_schema).dtype == "float"]
    assert len(floats) >= 10
    for col in floats:
        assert "BYTE_STREAM_SPLIT" in col.encodings, col.path_in_schema


def test_parquet_is_deterministic():
    """The same table gives the same bytes, in another process too, and from its CSV read."""
    df = _study_table()
    data = tables.parquet_bytes(df)
    code = ("import sys, test_tables; "
            "sys.stdout.buffer.write(test_tables.bytes_of_table())")
    env = dict(os.environ, PYTHONPATH=os.path.dirname(__file__) + os.pathsep
               + os.environ.get("PYTHONPATH", ""))
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, env=env,
                           check=True, timeout=120).stdout
    assert other == data
    assert tables.parquet_bytes(df.copy()) == data


def bytes_of_table() -> bytes:
    return tables.parquet_bytes(_study_table())


def test_parquet_needs_every_column_documented():
    df = _study_table().assign(undocumented_m_s=1.0)
    with pytest.raises(ValueError, match="undocumented_m_s.*granchain.columns"):
        tables.parquet_bytes(df)


def test_read_table_prefers_a_parquet_copy_that_is_not_older(tmp_path):
    df = _study_table()
    csv = tmp_path / "t.csv"
    tables.write_csv(df, csv)
    changed = df.assign(v_g_m_s=123.0)
    tables.write_parquet(changed, tables.parquet_path(csv))
    t = csv.stat().st_mtime
    os.utime(tables.parquet_path(csv), (t + 1, t + 1))
    assert (reductions.read_table(csv)["v_g_m_s"] == 123.0).all()       # the copy
    assert reductions.read_table(csv).attrs["name"] == "t.csv"
    os.utime(csv, (t + 2, t + 2))                                      # a newer CSV wins
    assert not (tables.read_table(tables.parquet_path(csv))["v_g_m_s"] == 123.0).any()


def test_write_parquet_leaves_no_temporary_file(tmp_path):
    tables.write_parquet(_study_table(), tmp_path / "sub" / "t.parquet")
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["t.parquet"]
