"""LAMMPS engine support: the ``fix groove/drag`` plugin and the LAMMPS runner.

The granular contact laws that LAMMPS applies, and the exact Verlet sequence the
reference integrator has to mirror, are written down in ``docs/lammps_laws.md``.
"""

from granchain.lammps.plugin import PLUGIN_FIX_STYLE, PluginBuildError, build_plugin
from granchain.lammps.runner import (
    LammpsError,
    LammpsRun,
    lammps_version,
    lammps_version_date,
    run_lammps,
)

__all__ = [
    "PLUGIN_FIX_STYLE",
    "LammpsError",
    "LammpsRun",
    "PluginBuildError",
    "build_plugin",
    "lammps_version",
    "lammps_version_date",
    "run_lammps",
]
