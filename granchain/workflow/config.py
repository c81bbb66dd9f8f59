"""Workflow configuration: schema validation, preset selection, and the one-line error.

A configuration (config/config.yaml, schema workflow/schemas/config.schema.yaml) has a
``preset`` name and ``presets``; each preset has ``materials``, ``base`` (the chain and
integrator shared by every study), ``studies``, ``batch`` and optionally ``cost``.

Each ensemble study runs on one engine, its ``engine`` key (reference unless set); a
top-level ``engine`` (``--config engine=lammps``) sets it for every ensemble study of the
preset, and for the field's studies (``FIELD_STUDIES``: precompression, wall) and the
chapter's questions (``QUESTION_STUDIES``: radius_spread, dissipation, plasticity,
adhesion, capture) when the preset has
them. ``lammps_check`` runs the engines its ``engines`` list names and ignores
both.
"""
from __future__ import annotations

import copy
from pathlib import Path

from ..errors import GranchainError

SCHEMA = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "config.schema.yaml"
ENGINES = ("reference", "lammps")
# Studies whose rows one engine makes (the study's ``engine`` key or the top-level override).
ENSEMBLE_STUDIES = ("packed_sweep", "packed_trace", "gap_profile", "gap_sweep", "extra_length")
# Optional studies of the field's chains (an end wall, a dead load), beyond the chapter;
# each also runs on one engine (its ``engine`` key or the top-level override).
FIELD_STUDIES = ("precompression", "wall")
# Optional studies that put a question of the chapter to its own chain (beyond Eq. 5.1): a
# sphere-size tolerance (radius_spread), contact dissipation (dissipation), yielding
# contacts (plasticity), adhesive ones in the chain (adhesion) and two adhesive spheres'
# capture (capture); each runs on one engine too.
QUESTION_STUDIES = ("radius_spread", "dissipation", "plasticity", "adhesion", "capture")
# every optional ensemble study, in table order
OPTIONAL_STUDIES = FIELD_STUDIES + QUESTION_STUDIES


class ConfigError(GranchainError):
    """The workflow configuration is invalid (one line: where, what, and the fix)."""


def config_error_message(exc: BaseException) -> str:
    """One line for a failed ``snakemake.utils.validate``: config path, problem, hint."""
    import jsonschema
    err, seen = exc, 0
    while err is not None and not isinstance(err, jsonschema.ValidationError) and seen < 10:
        err, seen = err.__cause__ or err.__context__, seen + 1   # validate() raises from it
    if err is None:
        return f"invalid configuration: {exc}"
    where = ".".join(str(p) for p in err.absolute_path) or "<top level>"
    hint = err.schema.get("description") if isinstance(err.schema, dict) else None
    msg = f"invalid configuration at '{where}': {err.message}"
    return msg + (f"; {hint}" if hint else "")


def validate_config(config: dict, schema=SCHEMA) -> dict:
    """Check ``config`` against the workflow's JSON schema and fill its defaults (in place),
    as ``snakemake.utils.validate`` does in the Snakefile; one-line ConfigError if bad."""
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import validate
    if not Path(schema).is_file():
        raise ConfigError(f"workflow schema '{schema}' not found: run from a checkout "
                          "installed with pip install -e .")
    try:
        validate(config, str(schema))
    except WorkflowError as exc:
        raise ConfigError(config_error_message(exc)) from None
    return config


def read_config(path, preset: str | None = None, engine: str | None = None) -> dict:
    """A workflow configuration file (e.g. config/config.yaml), validated against the
    schema with its defaults filled; ``preset`` replaces its ``preset`` name, ``engine``
    its top-level engine (as ``--config preset=... engine=...``)."""
    from snakemake.common.configfile import load_configfile
    config = load_configfile(str(path))
    if preset is not None:
        config["preset"] = preset
    if engine is not None:
        config["engine"] = engine
    return validate_config(config)


def study_engine(spec: dict) -> str:
    """The engine of an ensemble study's rows: its ``engine`` key, reference by default."""
    return spec.get("engine", "reference")


def with_engine(preset: dict, engine: str | None = None) -> dict:
    """A copy of ``preset`` whose ensemble studies run on ``engine`` (None: each study's
    own key). The default engine is written by leaving the key out, so a preset means the
    same, and has the same config hash, whether or not it spells out ``engine: reference``."""
    if engine is not None and engine not in ENGINES:
        raise ConfigError(f"invalid configuration at 'engine': unknown engine '{engine}'; "
                          f"use --config engine=NAME with one of: {', '.join(ENGINES)}")
    out = copy.deepcopy(preset)
    for study, spec in (out.get("studies") or {}).items():
        if study not in ENSEMBLE_STUDIES + OPTIONAL_STUDIES or not isinstance(spec, dict):
            continue
        if engine is not None:
            spec["engine"] = engine
        if spec.get("engine") == "reference":
            del spec["engine"]
    return out


def select_preset(config: dict) -> tuple[str, dict]:
    """(name, preset mapping) chosen by ``config['preset']``, its ensemble studies sent to
    ``config['engine']`` if given (:func:`with_engine`)."""
    name = config.get("preset", "default")
    presets = config.get("presets") or {}
    if name not in presets:
        known = ", ".join(sorted(presets)) or "none"
        raise ConfigError(f"invalid configuration at 'preset': unknown preset '{name}'; "
                          f"use --config preset=NAME with one of: {known}")
    return str(name), with_engine(presets[name], config.get("engine"))
