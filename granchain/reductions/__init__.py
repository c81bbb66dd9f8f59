"""Table-level reductions shared by the figures and the thesis comparison.

Everything here reads or reduces the workflow's result tables -- CSVs with one row per
chain and units in the column names (``v_striker_m_s``, ``v_g_m_s``, ``vmax_p01_m_s`` ...;
the columns are written by granchain/tables.py) -- or a Fig. 5.1a trace npz. Nothing here
simulates and nothing draws: no matplotlib import. The figures (granchain/figures/) and
the thesis table (granchain/thesis/) both build on these functions, so each number they
share is computed in one place.

Modules, one job each (every name is importable from ``granchain.reductions``):

- ``table``       reading and checking tables (:data:`NEEDS`), selecting rows;
- ``chapter``     the packed chain (v_max fits, v_g interpolation, peak profiles), spreads
                  over realisations, Eq. 5.4 (the chapter's bound on v_g with mean gap
                  gbar), a trace's pulse width and the energy columns;
- ``vibrometer``  the vibrometer study;
- ``field``       the field's studies (a precompressed chain, the chain on a wall);
- ``questions``   the chapter's questions (a sphere-size tolerance, contact dissipation,
                  yielding and adhesive contacts).

A missing table or column is a one-line :class:`~granchain.errors.GranchainError`.
"""
from __future__ import annotations

from .table import (PROBES, MATERIAL_LABEL, VMAX_RE, NEEDS, read_table, read_trace, require,
                    vmax_columns, require_vmax, reference_engine, arrived, materials_in,
                    material, label, nearest_speed, striker_speed, radius_or_default,
                    n_particles)
from .chapter import (fit_through_origin, vmax_fits, packed_vg, peak_profile,
                      packed_profile, oscillation, band, gap_for_reduction, bound_ratios,
                      pulse_width, work_fraction, effects_work_fraction, sphere_mass,
                      groove_slide)
from .vibrometer import (VIB_QUANTITIES, read_vibrometer_trace, vibrometer_bands,
                         nearest_bandwidth)
from .field import (SOLITARY_WALL_EXPONENT, precompression_rows, power_law_fit, wall_fits)
from .questions import (MEASURED_PEAKS, SPREAD_KINDS, spread_oscillation, first_reaching,
                        dissipation_curves, last_crossing, interpolate_at,
                        dissipation_match, plasticity_curves, plasticity_match,
                        plasticity_exponents, cohesion_curves, cohesion_match,
                        capture_velocities)

__all__ = [
    "PROBES", "MATERIAL_LABEL", "VMAX_RE", "NEEDS", "read_table", "read_trace", "require",
    "vmax_columns", "require_vmax", "reference_engine", "arrived", "materials_in",
    "material", "label", "nearest_speed", "striker_speed", "radius_or_default",
    "n_particles", "fit_through_origin", "vmax_fits", "packed_vg", "peak_profile",
    "packed_profile", "oscillation", "band", "gap_for_reduction", "bound_ratios",
    "pulse_width", "work_fraction", "effects_work_fraction", "sphere_mass",
    "groove_slide", "VIB_QUANTITIES", "read_vibrometer_trace", "vibrometer_bands",
    "nearest_bandwidth", "SOLITARY_WALL_EXPONENT", "precompression_rows", "power_law_fit",
    "wall_fits", "MEASURED_PEAKS", "SPREAD_KINDS", "spread_oscillation", "first_reaching",
    "dissipation_curves", "last_crossing", "interpolate_at", "dissipation_match",
    "plasticity_curves", "plasticity_match", "plasticity_exponents", "cohesion_curves",
    "cohesion_match", "capture_velocities",
]
