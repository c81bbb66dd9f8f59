"""The mean gap of a chain inferred from measured wave timing (``granchain infer``), and with
``--fit gap_mean,restitution`` its coefficient of restitution too, from the timing and the
peaks at both probes (section "Joint fit" below).

Input: a CSV of measurements (SI units) -- ``v_striker_m_s``, one timing column
(``dt_peak_s``: peak-to-peak delay between the two probes, or ``dt_front_s``: half-peak
arrival delay), optional ``dt_err_s`` (one-sigma Gaussian error of that timing) and
optional ``chain_id`` (rows with the same id were measured on one assembled chain and share
one gap realisation) -- and a base scene (material, radius, n, probes, effects, integrator,
the gap law's shape in its ``gaps:`` block, the simulated striker speeds in
``striker.velocity``). A base scene without ``gaps.distribution`` gets the chapter's
uniform law, one without ``striker.velocity`` is simulated at the data's own striker
speeds (:func:`~granchain.inference.grid.complete_base`; the result says which,
``gap_law_source`` and ``speeds_source``).

Method: a grid posterior over the gap law's mean, with a likelihood built from simulated
ensembles (never from Eq. 5.4).

- Grid: mean gaps ``0, dg, ..., gap_max`` x the base scene's striker speeds x R gap
  realisations, each grid cell one scene derived from the base scene (``Scene.derive``)
  and run through ``simulate.run_scene`` (the cells that differ only in their mean gap in
  one call, with the same values as a call each). Realisation r has the same normalised gap
  pattern at every mean gap (common random numbers): for a uniform or exponential law its
  gaps are exactly ``mean x pattern_r``. The patterns are designed
  (``granchain.gapdesign``): the law's own draws, but with the gaps on either side of each
  probe drawn toward small values from a heavier prior, so that the few-percent of
  chains with a near-zero gap next to a probe (whose peaks, and peak times, are a packed
  pair's) are represented by several realisations rather than by one or none. The joint
  fit's likelihood keeps that heavier prior for those contacts (w_r = 1); the gap-only
  fit's weights the realisations back to the gap law (w_r = prior / proposal):
  ``gapdesign.prior_weights`` says why. So the timing of realisation
  r is a smooth function of the mean gap and of the striker speed, and is interpolated:
  linearly in the mean gap between grid points, linearly in (log v, log t) between
  striker speeds. The interpolation error is measured on the grid itself (each interior
  node against the interpolation of its neighbours, ``interp_rel_error``) and enters the
  likelihood as a relative model error.
- Likelihood of a group of rows sharing one realisation (a chain_id; a row without one is
  its own group) at mean gap g: the R realisations' interpolated timings at the group's
  speeds form an R x m sample; a Gaussian kernel density estimate over them (kernel
  covariance = Silverman's factor^2 x the sample covariance across realisations, plus the
  rows' measurement variances and the model error) gives
  ``L = sum_r w_r N(t; T_r(g), C) / sum_r w_r`` -- the average over realisations of the
  joint density of the group's rows (weighted covariance, Silverman's factor for the
  weights' effective size; with equal weights, the plain kernel density,
  :func:`~granchain.inference.likelihood.kernel_log_density`). The kernel is multivariate
  because one realisation's timings at several speeds are strongly correlated: treating a
  chain's rows as independent given a simulated realisation counts the same gap pattern
  once per row and gives intervals that are too narrow (this is what the calibration
  measures). A realisation whose wave did not arrive at a speed of the group (NaN timing)
  gives that group zero likelihood for r.
- Posterior: prior density proportional to 1/(g + 2 nm) on [0, gap_max] (``PRIOR``
  "scale"; "uniform" on request), evaluated on a fine grid. The delay a gap adds grows in
  proportion to the gap, so the mean gap acts as a scale parameter and 1/g is its
  invariant prior (the 2 nm keeps a packed chain, g = 0, possible); measured on the
  calibration below, it gives slightly narrower and less biased intervals than a flat
  prior, with the same coverage; the report is the
  posterior median and the central 95 % interval. When the posterior still carries weight
  at gap_max the interval (and median) would be set by the grid's end, not the data: they
  are NaN with the flag ``posterior_at_grid_end``.

Why this method: the simulated timing of one realisation is smooth in (g, v), so a grid of
~10-30 mean gaps x a few speeds x a few tens of realisations, interpolated, gives the
likelihood at any g and v at the cost of the grid alone (its interpolation error, ~0.6 %
of the timing on a 25 nm x (0.03, 0.06, 0.1 m/s) grid, is far below the ~10 % spread of
the timing over realisations at a fixed mean gap). An emulator would need its own
validation on the same simulations, and ABC new simulations per dataset (thousands of
chains per inference) and a tolerance that trades bias for cost. What limits the grid is
the number of realisations: the grid's own sample of gap patterns is shared by every
inference, and with R = 24 its sampling error biased the medians by ~5 nm and the 95 %
intervals covered the truth in 88 % of 160 synthetic experiments; with R = 64, 97.5 %
(440C, 10-200 nm, benchmarks/inference_calibration.py), hence the default of 64. The grid
is simulated once per base scene and cached (``cache_dir``: one file per grid point, keyed
by the derived scene's hash), so later inferences on the same base scene run no simulation.

The intervals are calibrated for the base scene's model; they do not cover model error.
Measured on 112 synthetic experiments (tests/test_inference.py; 95 % intervals, covered
in 0.973 of them when the truth follows the model): gaps drawn from an exponential law
while the base scene's is uniform, 0.79 (the intervals keep their width; misses on both
sides, median bias -4 %); probe noise 10x the stated ``dt_err_s`` (3 us for 0.3 us),
0.77; heavy-tailed (Student t) noise at the stated level, unchanged (0.3 us is small
against the spread of the timing over gap realisations); timings from the LAMMPS engine
at another integrator and step, unchanged (intervals within 4e-4 of their width). Give
the base scene the gap law the chains have, and a ``dt_err_s`` that is not understated.

The chapter's Eq. 5.4, (2R + gbar)/v_g = 2R/v_g(packed) + gbar/v_s with
v_g = (p2 - p1)(2R + gbar)/dt, gives each row gbar_i = v_s (dt - dt_packed(v_s))/(p2 - p1)
(dt_packed: the grid's packed chain, g = 0, same timing column). ``eq54_gap_m`` is the
least-squares fit of that line to all rows (in time); ``eq54_gap_bound_m`` the largest
gbar whose Eq. 5.4 curve lies above every data point, as the chapter reads it (the minimum
of gbar_i). Eq. 5.4 assumes the particles fly across a gap at v_s, the fastest any
particle moves, so it overestimates the gap a given delay needs (the calibration measures
by how much).

Joint fit (``--fit gap_mean,restitution``). Input: the same CSV plus ``vmax_1_m_s`` and
``vmax_2_m_s`` (measured peaks at the two probes, m/s, on every row) and optional
``vmax_err_m_s`` (their one-sigma Gaussian error, m/s); a base scene with the
``contact_damping`` effect, model ``coeff_restitution`` (its e is a placeholder: the
inference sets it). The gap-only fit (``--fit gap_mean``, the default) reads the timing
alone, as before, and prints the same bytes; peak columns in its file are checked, not
used. A peak above what the base scene's striker can give (its kinetic energy bounds
every particle's: v_p <= v_s sqrt(m_1/m_p), v_s for an equal-mass striker) by more than
PEAK_SIGMAS of its stated error is refused (a unit or column mix-up, not noise).

- Grid: mean gaps ``gap_max (k/(G-1))^2`` x restitutions ``linspace(e_min, 1, E)``
  (default 0.7-1, 7 points) x the base scene's speeds x R realisations, each node one
  derived scene run through ``simulate.run_scene`` with one integrator setting
  (:func:`~granchain.inference.setting.choose_setting`: the base scene's own, else method
  auto asked for ``ACCURACY_FRACTION`` of the data's smallest stated relative error),
  cached per node as the gap-only grid.
  Common random numbers: realisation r has the same normalised gap pattern at every node,
  so each realisation's timing and peaks are smooth in (g, e, v) and are interpolated:
  linear in g, log-linear in e (log of each observable linear in e), in v as the gap-only
  fit for the timing and as v_max / v_s linear in log v for the peaks. The quadratic
  spacing in g is there because the peaks change from a packed chain's (v_max,1 = 0.70 v_s
  at e = 0.9) to a gapped one's (0.95 v_s) within 10-30 nm, the scale of the contact
  overlap: with 25 nm spacing the interpolation error of v_max,1 at 5-15 nm gaps was
  10-18 % (95th percentile over realisations, 0.01-1 m/s), above its 4 % spread over
  realisations; with quadratic spacing (12 nodes to 200 nm) 1.4 % at 15 nm and 0.05 % at
  200 nm. Log-linear in e,
  because v_max,2 of a gapped chain goes as ~((1 + e)/2)^(contacts passed): against a
  0.025-spaced reference over e = 0.8-1, linear interpolation on 0.05 spacing erred 1.3 %
  (v_max,2) and 0.6 % (timing) at the 95th percentile, log-linear 0.33 % and 0.27 %, cubic
  0.28 % and 0.13 %; what log-linear leaves is near the integrator's own scatter on these
  observables (v_max,1: 0.02 % whatever the scheme). The interpolation errors are measured
  on the grid itself (:func:`~granchain.inference.interpolation.joint_interp_errors`, per
  mean-gap node since they change by two orders of magnitude over g, and along e and v)
  and enter the likelihood as model error, as in the gap-only fit.
- Likelihood of a group (a chain_id, else one row): the R realisations' interpolated
  (timing, v_max,1, v_max,2) at each of its m rows form an R x 3m sample; the Gaussian
  kernel density over it (Silverman's factor^2 x the sample covariance + the rows' stated
  variances + model error; each row's values standardised by its observed timing and its
  striker speed) is the average over realisations of the joint density of the group's
  values -- today's multivariate kernel, with the peaks beside the timing, so one
  realisation's correlated timing and peaks at several speeds count once.
- Posterior: the gap-only prior on g (``PRIOR``) and a uniform prior on e in [e_min, 1],
  on 241 x 161 points (g quadratic, e uniform); when the points within exp(-20) of the peak
  span less than half the range, the posterior is evaluated again on 241 x 161 points over
  that box (a narrow posterior gets the same resolution as a wide one). The box is found
  on every 4th of those points (61 x 41, the box one of them wider on each side); when it
  spans half the range or more, on all of them (``FIRST_STRIDE``). Report: each
  parameter's marginal median and central 95 % interval, the posterior correlation of (g,
  e), and a posterior predictive check (how many measured values lie outside the 95 %
  range of 400 posterior draws x R realisations with the stated noise added). Weight at the
  largest mean gap flags ``posterior_at_grid_end`` (median and upper bound of g NaN), at
  e_min ``restitution_at_grid_end`` (median and lower bound of e NaN); e = 1 is the
  physical end of the range, not a grid end.

Why a 2D grid (measured): the grid of the shipped example (21 mean gaps x 7 e x 3 speeds x
64 realisations = 28,224 chains) ran in 90 s on the shared 2-core machine (RK4 at 7.2e-8 s,
the setting its stated errors ask for), once per base scene, and an inference from it takes 1-3 s;
its interpolation errors (above: <= 0.3 % in e, <= 1.4 % in g) are well inside the kernel
(timing spread 4-15 % and v_max,2 3-7 % over realisations at a fixed (g, e)). An emulator
(e.g. a Gaussian process for the realisations' mean and covariance) would replace their
spread -- skewed, and correlated across a chain's rows -- by a parametric form that needs
its own validation on the same simulations, to save a cost paid once per base scene.

Calibration (benchmarks/inference_joint_calibration.py, 200 synthetic experiments per
truth: 440C and 316, three independent chains or one chain at three speeds, true mean gaps
uniform on 10-200 nm and e on 0.85-1, realisations the grid never saw, timing noise 0.3 us
and peak noise 2 % or 8 % of v_s as stated; the default grid): with the likelihood's own
law the 95 % intervals covered the mean gap in 0.945 of them and e in 0.970 (both at once
0.920; 3 flagged at the grid's largest gap, counted as misses); median widths 68 nm (29-57
nm for independent chains, 70-129 nm for a one-chain series) and 0.036 in e (0.020 at 2 %
peak noise, 0.057 at 8 %); posterior correlation of (g, e) +0.07 at 2 % and +0.23 at 8 %.
Truths from LAMMPS's viscoelastic law (a law the likelihood does not use: 1 - e grows as
v^(1/5)), its eta giving the true e in a head-on collision at the geometric mean of the
experiment's speeds: coverage 0.915 (mean gap) and 0.930 (e); at 2 % peak noise e's misses
all fall on one side (8 of 8 intervals above the truth: a chain's collisions are slower than
the striker, where this law's e is higher), median error of e +0.002. The intervals do not
cover a damping law other than the base scene's beyond that.

Any declared key (``--fit gap_mean,KEY``): the joint fit above with the restitution's axis
replaced by any scalar scene key declared fittable (``validate.Fit`` on its ``Key``:
``damping.e``, alias ``restitution``; ``plasticity.yield_pressure``;
``adhesion.surface_energy``; :mod:`~granchain.inference.fitkeys`). Its declared range is
the prior's, uniform or, where it spans a decade or more, log-uniform; the grid's nodes,
the interpolation (log-linear) and the posterior are in the prior's coordinate (the key or
its log). An end of the range that is a bound of the key (e = 1) is physical; weight at
another flags ``<name>_at_grid_end``. The result names the key's median, interval and grid
by its results' name (``JointInference``). The limiting pressure (316 at 0.03-0.1 m/s)
and the surface energy (slow 440C chains) are calibrated by
``benchmarks/inference_joint_calibration.py --key KEY``, whose measured coverage, and what
the data cannot tell, docs/explanation/inference.md gives; the peaks' check takes the
attraction of the key's largest simulated value (the surface energy's top).

Model check (both fits, ``data_outside_model`` in the result): for data outside the
simulated cloud the kernel density is the Gaussian tail of the nearest kernels and the
posterior's width measures the steepness of that tail, not the spread of gap patterns: a
narrow, biased interval. ``granchain.modelcheck`` ranks the data's kernel log density
among replicates made from the realisations themselves (leave-one-out, at posterior draws)
and flags p < ``modelcheck.ALPHA``; the flag is in ``flags`` and the summary says plainly
that the interval is then not calibrated. Calibration of the design and the check:
``benchmarks/inference_outside.py`` (docs/explanation/inference.md gives its table).

Which simulated timing and peaks a CSV column is compared with is decided in one place
each, :func:`~granchain.inference.grid.timing` and
:func:`~granchain.inference.grid.peak`.

Modules, one job each (every public name is importable from ``granchain.inference``):

- ``measurements``   the CSV, its rows, what ``--fit`` names, the rows' checks against the
                     base scene (striker speeds, peaks);
- ``fitkeys``        the fittable scene keys, their grid axes and checks;
- ``grid``           the base scene and the two grids: their nodes, simulation and cache;
- ``interpolation``  reading a grid between its nodes, and the error of doing so;
- ``setting``        the integrator the grid runs, from the data's stated errors;
- ``likelihood``     the kernel density, the two fits' likelihoods and model checks;
- ``gapfit``         the gap-only fit (:func:`~granchain.inference.gapfit.infer`,
                     :class:`~granchain.inference.gapfit.Inference`): prior, posterior
                     summary, the Eq. 5.4 readings;
- ``jointfit``       the joint fit (:func:`~granchain.inference.jointfit.infer_joint`,
                     :class:`~granchain.inference.jointfit.JointInference`): the zoom
                     on a narrow posterior, posterior draws, the predictive check;
- ``result``         what the two results share (their JSON document);
- ``synthetic``      synthetic measurements, for the tests, the calibration and the examples.
"""
from __future__ import annotations

from .measurements import (TIMING_COLUMNS, PEAK_COLUMNS, COLUMNS, FITS, SPEED_RTOL, PEAK_RTOL,
                           PEAK_SIGMAS, MAX_ROWS, MAX_PEAK_ROWS, MAX_CHAIN_ROWS, Measurements,
                           read_measurements, parse_fit, fit_for,
                           check_speeds, peak_bounds, check_peaks)
from .fitkeys import (DEFAULT_KEY, FitKey, fittable, fit_key, check_fit_base,
                      check_fit_range)
from .grid import (GAP_LAWS, DEFAULT_GAP_LAW, CACHE_FORMAT, GAP_MAX, GAP_POINTS, REALISATIONS,
                   E_MIN, E_POINTS, JOINT_OBS, JOINT_CACHE_FORMAT, timing, peak, complete_base,
                   check_gappable, check_base, check_joint_options,
                   grid_scene, joint_scene, gap_nodes, Grid, JointGrid,
                   simulate_grid, simulate_joint_grid)
from .interpolation import interp_rel_error, joint_values, joint_interp_errors
from .likelihood import (CHUNK_BYTES, kernel_log_density, log_likelihood, gap_model_check,
                         joint_log_likelihood, joint_model_check)
from .result import FitResult
from .setting import (ACCURACY_FRACTION, CHOICE_GAP, smallest_error, scene_gives_integrator,
                      choose_setting)
from .gapfit import (FINE_POINTS, EDGE_WEIGHT, PRIOR, PRIOR_G0, Inference, log_prior,
                     posterior_summary, eq54_gaps, infer)
from .jointfit import (FINE_G, FINE_E, ZOOM_DROP, PREDICTIVE_DRAWS, PREDICTIVE_SEED,
                       fine_axes, zoom_box, JointInference, posterior_draws, predictive,
                       infer_joint)
from .synthetic import (simulate_rows, simulate_joint_rows, collision_restitution,
                        matching_eta)

__all__ = [
    "TIMING_COLUMNS", "PEAK_COLUMNS", "COLUMNS", "FITS", "SPEED_RTOL", "PEAK_RTOL",
    "PEAK_SIGMAS", "Measurements", "read_measurements", "parse_fit", "fit_for",
    "check_speeds", "peak_bounds", "check_peaks",
    "DEFAULT_KEY", "FitKey", "fittable", "fit_key", "check_fit_base", "check_fit_range",
    "GAP_LAWS", "DEFAULT_GAP_LAW", "CACHE_FORMAT", "GAP_MAX", "GAP_POINTS", "REALISATIONS",
    "E_MIN", "E_POINTS", "JOINT_OBS", "JOINT_CACHE_FORMAT", "timing", "peak", "complete_base",
    "check_gappable", "check_base", "check_joint_options",
    "grid_scene", "joint_scene", "gap_nodes", "Grid", "JointGrid",
    "simulate_grid", "simulate_joint_grid",
    "interp_rel_error", "joint_values", "joint_interp_errors",
    "CHUNK_BYTES", "kernel_log_density", "log_likelihood", "gap_model_check",
    "joint_log_likelihood", "joint_model_check",
    "FitResult",
    "ACCURACY_FRACTION", "CHOICE_GAP", "smallest_error", "scene_gives_integrator",
    "choose_setting",
    "FINE_POINTS", "EDGE_WEIGHT", "PRIOR", "PRIOR_G0", "Inference", "log_prior",
    "posterior_summary", "eq54_gaps", "infer",
    "FINE_G", "FINE_E", "ZOOM_DROP", "PREDICTIVE_DRAWS", "PREDICTIVE_SEED", "fine_axes",
    "zoom_box", "JointInference", "posterior_draws", "predictive", "infer_joint",
    "simulate_rows", "simulate_joint_rows", "collision_restitution", "matching_eta",
]
