"""What every row group of the thesis comparison shares: the chapter's simulated material
and reference speed, its fitted gaps, :func:`make_row`, :class:`PackedChain` (the packed
440C chain's reductions every group quotes) and the gapped tables' reference-engine rows."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ... import reductions
from ...errors import GranchainError

SIM_MATERIAL = "ss440c"          # the chapter simulates 440C
V_REF = 0.1                      # m/s: Fig. 5.1a, 5.3b, 5.4 and the 20-nm statement
FITTED_GAPS_NM = {"ss316": 190.4, "ss440c": 47.0}


def make_row(id_, quantity, kind, chapter_text, chapter_value, project_value, unit, evidence,
             reason, chapter_uncertainty=math.nan) -> dict:
    """One table row; ratio = project_value / chapter_value (NaN unless both are finite
    and the chapter's is not 0)."""
    cv, pv = float(chapter_value), float(project_value)
    ratio = pv / cv if np.isfinite(cv) and np.isfinite(pv) and cv != 0 else math.nan
    return dict(id=id_, quantity=quantity, kind=kind, chapter_text=chapter_text,
                chapter_value=cv, chapter_uncertainty=float(chapter_uncertainty),
                project_value=pv, ratio=ratio, unit=unit, evidence=evidence, reason=reason)


def pct(x: float) -> str:
    """A fraction as a percentage with 3 significant digits ("nan" for NaN)."""
    return "nan" if not np.isfinite(x) else f"{100 * x:.3g}%"


@dataclass(frozen=True)
class PackedChain:
    """Reductions of the packed sweep (reference engine) that the row groups share.

    ``s1``, ``s2``: slopes of v_max,1 = s1 v_s and v_max,2 = s2 v_s of 440C (fits through
    the origin); ``r1``, ``r2``: v_max,1 / v_s and v_max,2 / v_s of each 440C row;
    ``ratio_med``: median v_max,2 / v_max,1; ``vmin``, ``vmax``: the sweep's v_s range
    (m/s); ``ref``: the 440C rows at the speed nearest ``V_REF``, ``vs_ref`` that speed;
    ``prof``: their v_max,i / v_s for particles 1..13 (None without per-particle
    columns); ``radius``: sphere radius (m)."""
    table: pd.DataFrame
    fits: dict
    rows: pd.DataFrame
    s1: float
    s2: float
    r1: np.ndarray
    r2: np.ndarray
    ratio_med: float
    vmin: float
    vmax: float
    ref: pd.DataFrame
    vs_ref: float
    prof: np.ndarray | None
    radius: float


def packed_chain(packed_sweep: pd.DataFrame, radius: float | None = None) -> PackedChain:
    """:class:`PackedChain` of the packed sweep; ``radius`` in m (default 150 um)."""
    reductions.require(packed_sweep, reductions.NEEDS["fig5_1c"] + ["v_max_ratio"], "thesis comparison")
    mat = SIM_MATERIAL
    radius = reductions.radius_or_default(radius)
    packed = reductions.reference_engine(packed_sweep)
    fits = reductions.vmax_fits(packed)
    if mat not in fits:
        raise GranchainError(f"thesis comparison: packed_sweep has no '{mat}' rows (the "
                             "chapter simulates 440C); add it to the config's materials")
    pm = packed[packed["material"] == mat]
    ref = reductions.nearest_speed(packed, mat, V_REF)
    return PackedChain(
        table=packed, fits=fits, rows=pm,
        s1=fits[mat]["v_max_1"], s2=fits[mat]["v_max_2"],
        r1=(pm["v_max_1_m_s"] / pm["v_striker_m_s"]).to_numpy(dtype=float),
        r2=(pm["v_max_2_m_s"] / pm["v_striker_m_s"]).to_numpy(dtype=float),
        ratio_med=float(np.median(pm["v_max_ratio"].astype(float))),
        vmin=float(pm["v_striker_m_s"].min()), vmax=float(pm["v_striker_m_s"].max()),
        ref=ref, vs_ref=reductions.striker_speed(ref),
        prof=reductions.peak_profile(ref, "thesis") if reductions.vmax_columns(ref) else None,
        radius=radius)



def gap_profile_table(gap_profile: pd.DataFrame | None) -> pd.DataFrame | None:
    """The gap_profile table's reference-engine rows, checked for the columns used."""
    if gap_profile is None:
        return None
    gp = reductions.reference_engine(gap_profile)
    reductions.require(gp, reductions.NEEDS["fig5_3b"] + ["v_max_1_m_s", "v_max_2_m_s", "v_max_ratio",
                                        "v_g_m_s", "wave_arrived"], "thesis comparison")
    return gp


def gap_sweep_table(gap_sweep: pd.DataFrame | None, pk: PackedChain):
    """(reference-engine gap_sweep rows, their :func:`~granchain.reductions.bound_ratios`),
    or (None, None) without the table."""
    if gap_sweep is None:
        return None, None
    gs = reductions.reference_engine(gap_sweep)
    reductions.require(gs, reductions.NEEDS["fig5_3c"] + ["gap_mean_probes_nm"], "thesis comparison")
    return gs, reductions.bound_ratios(gs, pk.table, pk.radius)
