"""What accuracy costs in time, and the cost model behind ``method: auto``: the command
line ``python -m granchain.cost measure|figure|model`` and the names of the study.

The work lives in :mod:`granchain.accuracy` (``measure``: the harness; ``analysis``:
errors, envelope, cheapest setting, the model's rows; ``report``: tables, provenance, the
model file, the figure; ``cli``: this command line) and, for run time, in
:mod:`granchain.costmodel` (numpy only: the packaged model, ``resolve_auto``). This module
re-exports their names.
"""
from __future__ import annotations

import sys

from .accuracy.analysis import (achievable, cheapest, cheapest_table, envelope,
                                model_from_table, rel_err, scene_class)
from .accuracy.cli import main as _main
from .accuracy.cli import preset_blocks
from .accuracy.measure import (COLUMNS, DEFAULT_BASE, DEFAULT_COST, DETERMINISTIC, METHODS,
                               OBSERVABLES, TIMING_ONLY, Setting, contact_time, full_config,
                               lammps_unavailable, measure, reference_runs, sampling_floor,
                               scene_dicts, scene_for, settings, timing_settled,
                               timing_summary, to_frame)
from .accuracy.report import machine, plot, provenance_fields, write_model, write_outputs
from .costmodel import (AUTO_SAFETY, MODEL_COLUMNS, MODEL_FILE, MODEL_PROVENANCE,
                        SCENE_METHODS, auto_setting, fixed_step, is_packed, load_model,
                        resolve_auto)
from .scene import MIN_STEPS_PER_CONTACT

__all__ = ["AUTO_SAFETY", "COLUMNS", "DEFAULT_BASE", "DEFAULT_COST", "DETERMINISTIC",
           "METHODS", "MIN_STEPS_PER_CONTACT", "MODEL_COLUMNS", "MODEL_FILE",
           "MODEL_PROVENANCE", "OBSERVABLES", "SCENE_METHODS", "TIMING_ONLY", "Setting",
           "achievable", "auto_setting", "cheapest", "cheapest_table", "contact_time",
           "envelope", "fixed_step", "full_config", "is_packed", "lammps_unavailable",
           "load_model", "machine", "main", "measure", "model_from_table", "plot",
           "preset_blocks", "provenance_fields", "reference_runs", "rel_err",
           "resolve_auto", "sampling_floor", "scene_class", "scene_dicts", "scene_for",
           "settings", "timing_settled", "timing_summary", "to_frame", "write_model",
           "write_outputs"]


def main(argv=None) -> int:
    """``python -m granchain.cost measure|figure|model``."""
    return _main(argv, prog="python -m granchain.cost")


if __name__ == "__main__":
    sys.exit(main())
