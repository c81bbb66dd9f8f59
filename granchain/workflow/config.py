"""Workflow configuration: schema validation, preset selection, and the one-line error.

A configuration (config/config.yaml, schema workflow/schemas/config.schema.yaml) has a
``preset`` name and ``presets``; each preset has ``materials``, ``base`` (the chain and
integrator shared by every study), ``studies``, ``batch`` and optionally ``cost``.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import GranchainError

SCHEMA = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "config.schema.yaml"


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


def read_config(path, preset: str | None = None) -> dict:
    """A workflow configuration file (e.g. config/config.yaml), validated against the
    schema with its defaults filled; ``preset`` replaces its ``preset`` name."""
    from snakemake.common.configfile import load_configfile
    config = load_configfile(str(path))
    if preset is not None:
        config["preset"] = preset
    return validate_config(config)


def select_preset(config: dict) -> tuple[str, dict]:
    """(name, preset mapping) chosen by ``config['preset']``."""
    name = config.get("preset", "default")
    presets = config.get("presets") or {}
    if name not in presets:
        known = ", ".join(sorted(presets)) or "none"
        raise ConfigError(f"invalid configuration at 'preset': unknown preset '{name}'; "
                          f"use --config preset=NAME with one of: {known}")
    return str(name), presets[name]
