"""Reductions of the vibrometer study (tables/vibrometer.csv,
traces/vibrometer_<material>.npz): what the chapter's instruments record of the peaks and
delays."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import GranchainError
from .table import NEEDS, require

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
