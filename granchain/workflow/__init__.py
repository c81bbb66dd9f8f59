"""The workflow's logic: configuration -> preset -> study scenes -> job batches -> tables.

The Snakemake rules (workflow/rules/*.smk) and their scripts (workflow/scripts/*.py) call
only this package, through the names re-exported here (``from granchain import workflow
as gw``). One job per module; each imports only those above it:

- ``config``      schema validation, preset selection (and its engine), :class:`ConfigError`
- ``studies``     a study -> its :class:`StudyScene` list; packed and trace scenes; the
                  field's studies, the chapter's questions and lammps_check's field chains
- ``batches``     cost estimates, :class:`Batch`, cutting a study into jobs, runtimes
- ``presetplan``  :class:`Plan`: a preset's scenes and batches, built once (the check)
- ``captions``    study sizes for the report's captions
- ``run``         a job: one batch, the traces, the packed reference; threads and logs
- ``gather``      batch tables -> a study's table, summary, provenance and timing
- ``lammps_check``  LAMMPS against the reference engine (granchain.compare)
- ``rerun``       one member alone, reproducing its row
- ``vibrometer``  the vibrometer study: one run per chain, recorded with every setting
"""
from __future__ import annotations

from .batches import (JOB_OVERHEAD_S, Batch, batches, find_batch, members_per_job,
                      realisation_cost, runtime_minutes)
from .captions import FIGURES, caption_sizes, describe, vibrometer_sizes
from .lammps_check import COMPARISON_META, engine_comparison, write_engine_comparison
from .config import (ENGINES, ENSEMBLE_STUDIES, FIELD_STUDIES, OPTIONAL_STUDIES,
                     QUESTION_STUDIES, SCHEMA, ConfigError,
                     config_error_message,
                     read_config, select_preset, study_engine, validate_config, with_engine)
from .gather import gather, study_provenance
from .presetplan import Plan, load_config
from .rerun import rerun_member
from .run import (engine_options, log_to, member_rows, packed_reference, run_batch,
                  run_members, run_traces, set_threads, write_batch)
from .studies import (ENGINE_ORDER, STUDIES, VIBROMETER, StudyScene, check_chain_scenes,
                      field_scenes, packed_scene, preset_studies, question_scenes,
                      study_scenes, trace_scene, vibrometer_scenes, vibrometer_settings)
from .vibrometer import VIB_COLUMNS, run_vibrometer, write_vibrometer

__all__ = [
    "JOB_OVERHEAD_S", "Batch", "batches", "find_batch", "members_per_job",
    "realisation_cost", "runtime_minutes",
    "FIGURES", "caption_sizes", "describe", "vibrometer_sizes",
    "COMPARISON_META", "engine_comparison", "write_engine_comparison",
    "ENGINES", "ENSEMBLE_STUDIES", "FIELD_STUDIES", "OPTIONAL_STUDIES", "QUESTION_STUDIES",
    "SCHEMA", "ConfigError", "config_error_message",
    "read_config", "select_preset", "study_engine", "validate_config", "with_engine",
    "gather", "study_provenance",
    "Plan", "load_config",
    "rerun_member",
    "engine_options", "log_to", "member_rows", "packed_reference", "run_batch", "run_members",
    "run_traces", "set_threads", "write_batch",
    "ENGINE_ORDER", "STUDIES", "StudyScene", "check_chain_scenes", "field_scenes",
    "packed_scene", "preset_studies", "question_scenes", "study_scenes", "trace_scene",
    "VIBROMETER", "vibrometer_scenes", "vibrometer_settings",
    "VIB_COLUMNS", "run_vibrometer", "write_vibrometer",
]
