"""LAMMPS support: deck plans and texts (``deckplan``, ``deck``), the ``fix groove/drag``
plugin (``plugin``) and the LAMMPS runner (``runner``); micro units are
``granchain.units``, at the bottom layer, for the effects' deck fragments.

The runner and plugin names below load on first use, so that importing the deck writer
loads neither.
The granular contact laws that LAMMPS applies, and the exact Verlet sequence the
reference integrator has to mirror, are written down in ``docs/explanation/lammps_laws.md``.
"""
import importlib

_LAZY = {"PLUGIN_FIX_STYLE": "plugin", "PluginBuildError": "plugin", "build_plugin": "plugin",
         "LammpsError": "runner", "LammpsRun": "runner", "lammps_version": "runner",
         "lammps_version_date": "runner", "run_lammps": "runner"}


def __getattr__(name):
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = sorted(_LAZY)
