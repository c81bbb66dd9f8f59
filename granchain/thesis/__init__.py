"""The thesis comparison table.

Every number the chapter reports (its v_max slopes and ratios, v_g against Nesterenko's
speed, the measured peaks, the effect of 20 nm gaps, the fitted mean gaps, the energy
losses) beside this project's value computed from the workflow's tables, the ratio
project/chapter, the figure or table that backs it, and a one-line reason for any
difference. Reasons are computed from the same tables (each quotes the numbers that
support it); nothing here is tuned to the chapter. Experimental numbers of the chapter
are compared as "experiment vs model".

The rows are built per group of chapter numbers in :mod:`granchain.thesis.rows`, from
the reductions of :mod:`granchain.reductions`; this module assembles them
(:func:`comparison`), writes CSV and Markdown (:func:`write`, :func:`markdown`) and is
the command line::

    python -m granchain.thesis --packed-sweep P.csv --packed-trace T.csv --gap-profile G.csv \
        --gap-sweep S.csv --extra-length E.csv --trace packed_trace_ss440c.npz \
        --out-csv thesis_comparison.csv --out-md thesis_comparison.md
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ..reductions import read_table, read_trace
from ..errors import GranchainError
from ..fileio import check_distinct
from . import rows as thesis_rows

COLUMNS = ["id", "quantity", "kind", "chapter_text", "chapter_value", "chapter_uncertainty",
           "project_value", "ratio", "unit", "evidence", "reason"]

# Rows holding the numbers the chapter reports (the other rows back them up).
REPORTED = ["vmax_slope", "vmax1_over_vs", "vmax2_over_vs", "vmax_ratio", "vg_nesterenko",
            "exp_vmax_ratio", "exp_vmax1_over_vs", "exp_vmax2_over_vs", "exp_vg_below_packed",
            "gap20_oscillation", "gap20_vg_reduction", "fitted_gap_316", "fitted_gap_440c",
            "dE_coulomb_over_E", "dE_air_over_E"]
# Rows that need the chapter's measurements, which this project does not have.
NEEDS_EXPERIMENT = ["fitted_gap_316", "fitted_gap_440c"]

STUDIES = ("packed_sweep", "packed_trace", "gap_profile", "gap_sweep", "extra_length",
           "vibrometer", "precompression", "wall", "radius_spread", "dissipation",
           "plasticity", "adhesion", "capture")


def comparison(packed_sweep: pd.DataFrame, packed_trace: pd.DataFrame | None = None,
               gap_profile: pd.DataFrame | None = None, gap_sweep: pd.DataFrame | None = None,
               extra_length: pd.DataFrame | None = None, trace: dict | None = None,
               radius: float | None = None, vibrometer: pd.DataFrame | None = None,
               precompression: pd.DataFrame | None = None, wall: pd.DataFrame | None = None,
               radius_spread: pd.DataFrame | None = None,
               dissipation: pd.DataFrame | None = None,
               plasticity: pd.DataFrame | None = None,
               adhesion: pd.DataFrame | None = None,
               capture: pd.DataFrame | None = None) -> pd.DataFrame:
    """The comparison table (one row per chapter number, columns ``COLUMNS``);
    ``radius`` (m) of the spheres (the tables do not carry it; default 150 um). Only
    packed_sweep is required; rows whose table is not given hold NaN (the
    pulse_width row needs the trace and is left out without it; the vibrometer rows
    need the vibrometer study's table, the field rows the precompression and wall
    studies' tables, the question rows the radius_spread, dissipation, plasticity,
    adhesion and capture studies')."""
    pk = thesis_rows.packed_chain(packed_sweep, radius)
    rows = (thesis_rows.packed_chain_rows(pk)
            + thesis_rows.group_velocity_rows(pk)
            + thesis_rows.experiment_rows(pk, gap_profile, gap_sweep)
            + thesis_rows.gap_rows(pk, gap_profile, gap_sweep)
            + thesis_rows.bound_rows(pk, gap_sweep, extra_length)
            + thesis_rows.energy_rows(pk, packed_trace, trace)
            + thesis_rows.instrument_rows(pk, vibrometer)
            + thesis_rows.field_rows(pk, precompression, wall)
            + thesis_rows.tolerance_rows(pk, radius_spread)
            + thesis_rows.dissipation_rows(pk, dissipation)
            + thesis_rows.plasticity_rows(pk, plasticity)
            + thesis_rows.adhesion_rows(pk, adhesion)
            + thesis_rows.capture_rows(pk, capture))
    return pd.DataFrame(rows, columns=COLUMNS)


# ---------------------------------------------------------------------------------------
def _num(x: float, unc: float = math.nan) -> str:
    """4 significant digits (with "+/- unc" when given); "-" for NaN."""
    if not np.isfinite(x):
        return "-"
    s = f"{x:.4g}"
    if np.isfinite(unc):
        s += f" +/- {unc:.2g}"
    return s


def markdown(df: pd.DataFrame, title: str = "Thesis comparison") -> str:
    """The table as Markdown under ``# {title}``: quantity, kind, chapter, this
    project's value (percent for fractions), ratio, evidence, reason."""
    lines = [f"# {title}", "",
             "The numbers the chapter reports (its simulations and measurements) beside this "
             "project's values computed from the workflow's tables; ratio = project/chapter. "
             "`experiment` rows compare the chapter's measurements with this model; "
             "`theory (beyond the chapter)` rows compare the field's chains (a precompressed "
             "chain, a chain on a wall) with the theory they test; `simulation (beyond the "
             "chapter)` and `experiment (beyond the chapter)` rows put the chapter's questions "
             "to its own chain (a sphere-size tolerance, contact damping) and compare the "
             "answers with its simulated and measured numbers.", "",
             "| quantity | kind | chapter | this project | ratio | evidence | reason |",
             "|---|---|---|---|---|---|---|"]
    for r in df.itertuples():
        chap = r.chapter_text          # states the chapter's number in its own words
        if r.unit == "fraction" and np.isfinite(r.project_value):
            proj = f"{100 * r.project_value:.3g}%"
        else:
            proj = _num(r.project_value)
            if np.isfinite(r.project_value) and r.unit != "-":
                proj += f" {r.unit}"
        cells = [r.quantity, r.kind, chap, proj, _num(r.ratio), r.evidence, r.reason]
        lines.append("| " + " | ".join(str(c).replace("|", "/") for c in cells) + " |")
    return "\n".join(lines) + "\n"


def write(df: pd.DataFrame, csv, md, title: str = "Thesis comparison") -> None:
    """Write the table as CSV (floats with 17 significant digits) and as Markdown."""
    csv, md = Path(csv), Path(md)
    csv.parent.mkdir(parents=True, exist_ok=True)
    md.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(csv, index=False, float_format="%.17g")
    md.write_text(markdown(df, title))


def read_inputs(paths: dict) -> dict:
    """{study: path, trace: npz} -> keyword arguments of :func:`comparison`."""
    if paths.get("packed_sweep") is None:
        raise GranchainError("thesis comparison: needs --packed-sweep (the packed_sweep table)")
    kw = {s: read_table(paths[s]) for s in STUDIES if paths.get(s) is not None}
    if paths.get("trace") is not None:
        kw["trace"] = read_trace(paths["trace"])
    return kw


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m granchain.thesis``."""
    ap = argparse.ArgumentParser(prog="python -m granchain.thesis",
                                 description="The thesis comparison table (CSV and Markdown).")
    for s in STUDIES:
        ap.add_argument("--" + s.replace("_", "-"), dest=s,
                        help=f"results/<preset>/tables/{s}.csv")
    ap.add_argument("--trace", help="results/<preset>/traces/packed_trace_ss440c.npz")
    ap.add_argument("--out-csv", required=True)
    ap.add_argument("--out-md", required=True)
    ap.add_argument("--title", default="Thesis comparison")
    ap.add_argument("--radius", type=float, help="sphere radius in m (default 150e-6)")
    return ap


def main(argv=None) -> int:
    """``python -m granchain.thesis --packed-sweep P.csv ... --out-csv C --out-md M``; a
    missing or invalid table prints one line and returns 2."""
    a = build_parser().parse_args(argv)
    try:
        check_distinct([("--out-csv", a.out_csv), ("--out-md", a.out_md)],
                       [(f"the --{k.replace('_', '-')} input", getattr(a, k))
                        for k in (*STUDIES, "trace")])
        kw = read_inputs(vars(a))
        kw["radius"] = a.radius
        write(comparison(**kw), a.out_csv, a.out_md, a.title)
    except GranchainError as exc:
        print(f"granchain.thesis: error: {exc}", file=sys.stderr)
        return 2
    print(a.out_csv)
    print(a.out_md)
    return 0
