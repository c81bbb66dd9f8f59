"""The chapter's figures, drawn from the workflow's tables.

One function per chapter panel, grouped by chapter figure in one module each. Each takes
pandas DataFrames read from ``results/{preset}/tables/{study}.csv`` (one row per chain,
units in column names; the columns are written by granchain/tables.py) -- or, for
Fig. 5.1a, the trace npz -- and writes ``{out}.png`` and ``{out}.pdf``. Nothing here
simulates: figures only read tables, and every number they show comes from
granchain.reductions.

- :func:`fig5_1a`  particle velocities in time along the packed chain (one trace);
- :func:`fig5_1b`  v_max vs striker velocity, linear fit through the origin (packed_sweep);
- :func:`fig5_1c`  v_g vs striker velocity with Nesterenko's curve (packed_sweep);
- :func:`fig5_3b`  peak velocity along a chain with 20 nm mean gaps (gap_profile);
- :func:`fig5_3c`  v_g vs striker velocity for mean gaps 10..190 nm, bands and Eq. 5.4 (gap_sweep);
- :func:`fig5_4b`  v_g vs the mean gap inferred from the extra chain length (extra_length);
- :func:`fig5_2a`  true and recorded probe velocities, packed chain (vibrometer trace);
- :func:`vibrometer`  recorded/true v_max,1, v_max,2 and dt bias vs bandwidth (vibrometer);
- :func:`precompression`  v_g vs v_s under dead loads F0, with c0 and Nesterenko's
  precompressed solitary wave (precompression; beyond the chapter);
- :func:`wall`  the wall's force peak vs v_s, with the Hertz v_s^(6/5) (wall; beyond the chapter);
- :func:`radius_spread`  Fig. 5.3b's oscillation measure against the radius sd, beside 20 nm
  gaps (radius_spread; beyond the chapter);
- :func:`dissipation`  v_max,1, v_max,2, their ratio and v_g against the coefficient of
  restitution, with the chapter's measured bands (dissipation; beyond the chapter);
- :func:`plasticity`  v_max,1, v_max,2, their ratio and v_g against v_s at limiting pressures
  p_y of Thornton's yielding contacts, with the measured bands (plasticity; beyond the
  chapter);
- :func:`adhesion`  the same against the surface energy gamma of adhesive contacts, with and
  without the groove's flats adhering (adhesion; beyond the chapter);
- :func:`capture`  two adhesive spheres: restitution against v_s and the capture velocity
  against gamma (capture; beyond the chapter).

Modules: ``style`` (fixed rcParams, colours, deterministic saving), ``fig5_1`` (packed
chain), ``fig5_2`` (the vibrometer), ``fig5_3`` (random gaps), ``fig5_4`` (loose chains), ``field``
(the field's chains: precompression, wall), ``questions`` (the chapter's questions:
radius_spread, dissipation, plasticity, adhesion, capture). Output is deterministic: a
rerun on the same tables gives byte-identical PNG and PDF files.

Command line (what the workflow's figure rules call)::

    python -m granchain.figures fig5_3c --gap-sweep G.csv --packed-sweep P.csv --out DIR/fig5_3c

A missing table or column is a one-line :class:`~granchain.errors.GranchainError`.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..reductions import read_table, read_trace, read_vibrometer_trace
from ..errors import GranchainError
from ..fileio import check_distinct
from .style import figure_paths
from .fig5_1 import fig5_1a, fig5_1b, fig5_1c
from .fig5_2 import fig5_2a, vibrometer
from .fig5_3 import fig5_3b, fig5_3c
from .fig5_4 import fig5_4b
from .field import precompression, wall
from .questions import adhesion, capture, dissipation, plasticity, radius_spread

# name -> (drawing function, the tables it reads, in argument order)
FIGURES = {
    "fig5_1a": (fig5_1a, ["trace"]),
    "fig5_1b": (fig5_1b, ["packed_sweep"]),
    "fig5_1c": (fig5_1c, ["packed_sweep"]),
    "fig5_3b": (fig5_3b, ["gap_profile", "packed_sweep"]),
    "fig5_3c": (fig5_3c, ["gap_sweep", "packed_sweep"]),
    "fig5_4b": (fig5_4b, ["extra_length", "packed_sweep"]),
    "fig5_2a": (fig5_2a, ["vibrometer_trace"]),
    "vibrometer": (vibrometer, ["vibrometer"]),
    "precompression": (precompression, ["precompression"]),
    "wall": (wall, ["wall"]),
    "radius_spread": (radius_spread, ["radius_spread"]),
    "dissipation": (dissipation, ["dissipation"]),
    "plasticity": (plasticity, ["plasticity"]),
    "adhesion": (adhesion, ["adhesion"]),
    "capture": (capture, ["capture"]),
}
# readers of the inputs that are not result tables
READERS = {"trace": read_trace, "vibrometer_trace": read_vibrometer_trace}


def render(name: str, paths: dict, out, radius: float | None = None) -> list[Path]:
    """Draw figure ``name`` from {study: path} (trace: npz path) into ``out``.{png,pdf};
    ``radius`` (m) for the figures that draw Eq. 5.4."""
    if name not in FIGURES:
        raise GranchainError(f"unknown figure '{name}'; use one of {', '.join(FIGURES)}")
    func, needs = FIGURES[name]
    args = []
    for study in needs:
        p = paths.get(study)
        if p is None:
            flag = "--" + study.replace("_", "-")
            raise GranchainError(f"{name}: needs {flag} (the {study} "
                                 f"{'npz' if study in READERS else 'table'})")
        args.append(READERS.get(study, read_table)(p))
    if name in ("fig5_3c", "fig5_4b", "precompression"):
        return func(*args, out, radius=radius)
    return func(*args, out)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m granchain.figures``."""
    ap = argparse.ArgumentParser(prog="python -m granchain.figures",
                                 description="Draw one of the chapter's figures from the "
                                             "workflow's tables (PNG and PDF).")
    ap.add_argument("name", help=", ".join(FIGURES))
    for study in ("packed_sweep", "gap_profile", "gap_sweep", "extra_length", "vibrometer",
                  "precompression", "wall", "radius_spread", "dissipation", "plasticity", "adhesion",
                  "capture"):
        ap.add_argument("--" + study.replace("_", "-"), dest=study,
                        help=f"results/<preset>/tables/{study}.csv")
    ap.add_argument("--trace", help="results/<preset>/traces/packed_trace_<material>.npz")
    ap.add_argument("--vibrometer-trace", dest="vibrometer_trace",
                    help="results/<preset>/traces/vibrometer_<material>.npz")
    ap.add_argument("--radius", type=float, help="sphere radius in m for Eq. 5.4 and the "
                    "precompressed chain's c0 (default the chapter's 150e-6; the tables do "
                    "not carry it)")
    ap.add_argument("--out", required=True, help="output path (.png/.pdf or no extension)")
    return ap


def main(argv=None) -> int:
    """``python -m granchain.figures NAME --<study> PATH ... --out PATH``; a missing or
    invalid table, trace or column prints one line and returns 2."""
    a = build_parser().parse_args(argv)
    paths = {k: v for k, v in vars(a).items() if k not in ("name", "out", "radius") and v}
    try:
        check_distinct([("--out", p) for p in figure_paths(a.out)],
                       [(f"the --{k.replace('_', '-')} input", v) for k, v in paths.items()])
        for p in render(a.name, paths, a.out, a.radius):
            print(p)
    except GranchainError as exc:
        print(f"granchain.figures: error: {exc}", file=sys.stderr)
        return 2
    return 0
