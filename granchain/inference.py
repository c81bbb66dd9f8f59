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
speeds (:func:`complete_base`; the result says which, ``gap_law_source`` and
``speeds_source``).

Method: a grid posterior over the gap law's mean, with a likelihood built from simulated
ensembles (never from Eq. 5.4).

- Grid: mean gaps ``0, dg, ..., gap_max`` x the base scene's striker speeds x R gap
  realisations, each grid cell one scene derived from the base scene (``Scene.derive``)
  and run through ``simulate.run_scene``. Realisation r has the same normalised gap
  pattern at every mean gap (common random numbers): for a uniform or exponential law its
  gaps are exactly ``mean x pattern_r``. The patterns are designed
  (``granchain.gapdesign``): the law's own draws, but with the gaps on either side of each
  probe importance-sampled toward small values, and a weight w_r = prior / proposal per
  realisation, so that the few-percent of chains with a near-zero gap next to a probe
  (whose peaks, and peak times, are a packed pair's) are represented by several
  realisations rather than by one or none. So the timing of realisation
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
  :func:`kernel_log_density`). The kernel is multivariate because one realisation's timings at
  several speeds are strongly correlated: treating a chain's rows as independent given a
  simulated realisation counts the same gap pattern once per row and gives intervals that
  are too narrow (this is what the calibration measures). A realisation whose wave did not
  arrive at a speed of the group (NaN timing) gives that group zero likelihood for r.
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
  derived scene run through ``simulate.run_scene`` with the base scene's integrator (the
  event method, or what ``auto`` chooses per node), cached per node as the gap-only grid.
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
  on the grid itself (:func:`joint_interp_errors`, per mean-gap node since they change by
  two orders of magnitude over g, and along e and v) and enter the likelihood as model
  error, as in the gap-only fit.
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
  that box (a narrow posterior gets the same resolution as a wide one). Report: each
  parameter's marginal median and central 95 % interval, the posterior correlation of (g,
  e), and a posterior predictive check (how many measured values lie outside the 95 %
  range of 400 posterior draws x R realisations with the stated noise added). Weight at the
  largest mean gap flags ``posterior_at_grid_end`` (median and upper bound of g NaN), at
  e_min ``restitution_at_grid_end`` (median and lower bound of e NaN); e = 1 is the
  physical end of the range, not a grid end.

Why a 2D grid (measured): the grid of the shipped example (21 mean gaps x 7 e x 3 speeds x
64 realisations = 28,224 chains) ran in 90 s on the shared 2-core machine (auto: RK4 or
the event method per node), once per base scene, and an inference from it takes 1-3 s;
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

Model check (both fits, ``data_outside_model`` in the result): for data outside the
simulated cloud the kernel density is the Gaussian tail of the nearest kernels and the
posterior's width measures the steepness of that tail, not the spread of gap patterns: a
narrow, biased interval. ``granchain.modelcheck`` ranks the data's kernel log density
among replicates made from the realisations themselves (leave-one-out, at posterior draws)
and flags p < ``modelcheck.ALPHA``; the flag is in ``flags`` and the summary says plainly
that the interval is then not calibrated. Calibration of the design and the check:
``benchmarks/inference_outside.py`` (docs/explanation/inference.md gives its table).

Which simulated timing and peaks a CSV column is compared with is decided in one place
each, :func:`timing` and :func:`peak`.
"""
from __future__ import annotations

import csv
import dataclasses
import difflib
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import GranchainError
from .fileio import atomic_write_bytes
from .gapdesign import EMPHASIS, design
from .gaps import Member
from .scene import Scene
from .validate import short

TIMING_COLUMNS = ("dt_peak_s", "dt_front_s")
PEAK_COLUMNS = ("vmax_1_m_s", "vmax_2_m_s")     # measured peaks at the two probes (m/s)
COLUMNS = ("v_striker_m_s", *TIMING_COLUMNS, "dt_err_s", "chain_id", *PEAK_COLUMNS,
           "vmax_err_m_s")
FITS = ("gap_mean", "restitution")      # what --fit may name
GAP_LAWS = ("uniform", "exponential")     # laws whose realisations scale with their mean
DEFAULT_GAP_LAW = "uniform"               # the chapter's: uniform on [0, 2 mean], i.i.d.
CACHE_FORMAT = 1                          # bump when the cached arrays change meaning
FINE_POINTS = 801                         # posterior evaluation points over [0, gap_max]
EDGE_WEIGHT = 1e-2        # posterior density at gap_max, relative to its peak, that flags
PRIOR = "scale"
PRIOR_G0 = 2e-9
# the most data rows a measurement file may hold (the joint fit of the peaks: fewer, each
# row costs ~0.4-1 s of likelihood; 1000 rows took 7 min on a small grid), and one chain's
# series (its rows enter the likelihood together: a kernel density in as many dimensions,
# three per row when the peaks are fitted too; the joint fit of a 20-row chain took 22 s
# and 0.9 GB on a small grid, of 50 rows over 15 min); a lab's file is far smaller
MAX_ROWS = 10_000
MAX_PEAK_ROWS = 200
MAX_CHAIN_ROWS = 20
SPEED_RTOL = 1e-9         # a row's speed may exceed the simulated range by this (rounding)
PEAK_RTOL = 1e-3          # a peak may exceed what the striker can give by this (rounding,
                          # the drag's small propulsive work, a preload's)
PEAK_SIGMAS = 5.0         # ... and by this many of its stated errors (noise)


# ---------------------------------------------------------------------------------------
# measurements
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Measurements:
    """Rows of a measurement CSV: striker speed (m/s), timing (s), its one-sigma error (s,
    0 where none is given), the group index each row belongs to (rows sharing a chain_id
    share one; others one each), ``column`` the timing column, ``lines`` the file line of
    each row (for messages), ``chain_ids`` the given ids (None where none)."""
    v: np.ndarray
    t: np.ndarray
    err: np.ndarray
    group: np.ndarray
    column: str
    lines: tuple[int, ...]
    chain_ids: tuple
    # measured peaks at the two probes (m/s; NaN in an empty cell, None without the
    # column) and their one-sigma error (m/s, 0 where none is given)
    vmax_1: np.ndarray | None = None
    vmax_2: np.ndarray | None = None
    vmax_err: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.v.size)

    @property
    def has_peaks(self) -> bool:
        """Are both probes' peaks given on every row?"""
        return (self.vmax_1 is not None and self.vmax_2 is not None
                and bool(np.all(np.isfinite(self.vmax_1)) and np.all(np.isfinite(self.vmax_2))))

    @property
    def peak_err(self) -> np.ndarray:
        return np.zeros(len(self)) if self.vmax_err is None else self.vmax_err

    @property
    def groups(self) -> list[np.ndarray]:
        return [np.flatnonzero(self.group == k) for k in range(int(self.group.max()) + 1)]


def _bad(where: str, problem: str, fix: str) -> GranchainError:
    return GranchainError(f"{where}: {problem}; {fix}")


def _number(text: str, where: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise _bad(where, f"{short(text)} is not a number", "give a number in SI units") from None
    if not math.isfinite(x):
        raise _bad(where, f"{short(text)} is not a finite number",
                   "give a measured value or drop the row")
    return x


def _read_text(path, name: str) -> str:
    """The text of a measurement file: a regular file, UTF-8 (a byte-order mark is
    dropped); every problem one GranchainError naming the file (and the line of a byte
    that is not UTF-8)."""
    p = Path(path)
    try:
        if p.is_dir():
            raise _bad(name, "is a directory, not a CSV file",
                       "give the path of the measurement CSV file")
        if p.exists() and not p.is_file():
            raise _bad(name, "is not a regular file", "give the path of a measurement CSV file")
        data = p.read_bytes()
    except OSError as exc:
        raise _bad(name, f"cannot read the file ({exc.strerror or exc})",
                   "give a readable CSV file") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise _bad(f"{name}, line {line}", f"is not UTF-8 text (byte 0x{data[exc.start]:02x} "
                   f"at character {col})", "save the file as UTF-8 CSV") from None


def read_measurements(path, peaks: bool = False) -> Measurements:
    """Read and check a measurement CSV (module doc). Lines starting with '#' are comments.
    ``peaks``: the fit needs the measured peaks (``vmax_1_m_s``, ``vmax_2_m_s``) on every
    row. Every problem is one GranchainError naming the file and the column or row."""
    name = str(path)
    text = _read_text(path, name)
    lines = [(k + 1, ln) for k, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise _bad(name, "the file is empty", "give a header line (v_striker_m_s, dt_peak_s or "
                   "dt_front_s, optional dt_err_s, chain_id, vmax_1_m_s, vmax_2_m_s, "
                   "vmax_err_m_s) and at least one row")
    try:
        rows = list(csv.reader(io.StringIO("\n".join(ln for _, ln in lines)), strict=True))
    except csv.Error as exc:
        raise _bad(name, f"is not a valid CSV file ({exc})",
                   "give comma-separated values with balanced quotes") from None
    header = [h.strip() for h in rows[0]]
    for h in header:
        if h not in COLUMNS:
            close = difflib.get_close_matches(h, COLUMNS, n=1)
            raise _bad(f"{name}, column {short(h)}", "unknown column",
                       f"did you mean {close[0]!r}?" if close else f"use {', '.join(COLUMNS)}")
    for j, h in enumerate(header):
        if h in header[:j]:
            raise _bad(f"{name}, column {short(h)}", f"given twice (header cells {header.index(h) + 1} "
                       f"and {j + 1})", "keep one")
    if "v_striker_m_s" not in header:
        raise _bad(f"{name}, column 'v_striker_m_s'", "missing",
                   "add the striker speed of each measurement in m/s")
    timing_cols = [c for c in TIMING_COLUMNS if c in header]
    if not timing_cols:
        raise _bad(f"{name}, column 'dt_peak_s'", "missing (no timing column)",
                   "add dt_peak_s (peak-to-peak delay, s) or dt_front_s (half-peak arrival delay, s)")
    if len(timing_cols) > 1:
        raise _bad(f"{name}, column 'dt_front_s'", "given together with dt_peak_s",
                   "give one timing column per file")
    col = timing_cols[0]
    if peaks:
        for c in PEAK_COLUMNS:
            if c not in header:
                raise _bad(f"{name}, column {c!r}", "missing; fitting the restitution needs "
                           "the measured peak at each probe",
                           "add vmax_1_m_s and vmax_2_m_s (peak velocities at the two "
                           "probes, m/s), or fit gap_mean alone")
    if len(rows) < 2:
        raise _bad(name, "no data rows under the header", "add at least one measurement")
    most = MAX_PEAK_ROWS if peaks else MAX_ROWS
    if len(rows) - 1 > most:
        raise _bad(name, f"has {len(rows) - 1} data rows, more than {most}"
                   + (" for a fit of the peaks" if peaks else ""),
                   "give one row per measurement (average repeated ones), or split the file")
    v, t, err, ids, where_lines = [], [], [], [], []
    peak_cols = [c for c in PEAK_COLUMNS if c in header]
    pk = {c: [] for c in peak_cols}
    pk_err = []
    for (line, _), row in zip(lines[1:], rows[1:]):
        k = len(v) + 1
        if len(row) != len(header):
            raise _bad(f"{name}, row {k} (line {line})",
                       f"has {len(row)} cells but the header has {len(header)}",
                       "give one cell per column")
        cell = dict(zip(header, (c.strip() for c in row)))
        here = f"{name}, row {k} (line {line})"
        vs = _number(cell["v_striker_m_s"], f"{here}, column 'v_striker_m_s'")
        if vs <= 0:
            raise _bad(f"{here}, column 'v_striker_m_s'", f"{vs:g} m/s is not > 0",
                       "give the striker speed towards the chain in m/s")
        dt = _number(cell[col], f"{here}, column {col!r}")
        if dt <= 0:
            raise _bad(f"{here}, column {col!r}", f"non-positive time {dt:g} s",
                       "give the delay between the probes in seconds (> 0)")
        e = 0.0
        if "dt_err_s" in cell and cell["dt_err_s"] != "":
            e = _number(cell["dt_err_s"], f"{here}, column 'dt_err_s'")
            if e < 0:
                raise _bad(f"{here}, column 'dt_err_s'", f"{e:g} s is negative",
                           "give the one-sigma timing error in seconds (>= 0)")
        for c in peak_cols:
            if cell[c] == "":
                if peaks:
                    raise _bad(f"{here}, column {c!r}", "empty; fitting the restitution needs "
                               "the measured peak on every row",
                               "give the peak velocity at the probe in m/s, or drop the row")
                pk[c].append(math.nan)
                continue
            x = _number(cell[c], f"{here}, column {c!r}")
            if x <= 0:
                raise _bad(f"{here}, column {c!r}", f"{x:g} m/s is not > 0",
                           "give the peak velocity at the probe in m/s (> 0)")
            pk[c].append(x)
        pe = 0.0
        if "vmax_err_m_s" in cell and cell["vmax_err_m_s"] != "":
            pe = _number(cell["vmax_err_m_s"], f"{here}, column 'vmax_err_m_s'")
            if pe < 0:
                raise _bad(f"{here}, column 'vmax_err_m_s'", f"{pe:g} m/s is negative",
                           "give the one-sigma error of the peaks in m/s (>= 0)")
        pk_err.append(pe)
        cid = cell.get("chain_id", "") or None
        v.append(vs), t.append(dt), err.append(e), ids.append(cid), where_lines.append(line)
    per_chain: dict = {}
    for cid in ids:
        per_chain[cid] = per_chain.get(cid, 0) + 1
    for cid, rows_of in per_chain.items():
        if cid is not None and rows_of > MAX_CHAIN_ROWS:
            raise _bad(f"{name}, column 'chain_id'", f"chain {short(cid)} has {rows_of} rows, "
                       f"more than {MAX_CHAIN_ROWS} (a chain's rows are fitted as one series)",
                       "give one row per striker speed of that chain, or leave chain_id empty "
                       "for rows of separate chains")
    group, seen = [], {}
    for cid in ids:
        if cid is None:
            group.append(len(seen))
            seen[object()] = None
        else:
            if cid not in seen:
                seen[cid] = len(seen)
            group.append(seen[cid])
    # renumber groups in order of first appearance
    peak = {c: np.array(pk[c]) if c in pk else None for c in PEAK_COLUMNS}
    return Measurements(np.array(v), np.array(t), np.array(err), np.array(group, dtype=int),
                        col, tuple(where_lines), tuple(ids), peak["vmax_1_m_s"],
                        peak["vmax_2_m_s"], np.array(pk_err) if peak_cols else None)


def parse_fit(text: str) -> tuple[str, ...]:
    """The parameters ``--fit`` names, in FITS order: ``gap_mean`` (the default) or
    ``gap_mean,restitution``; every other value is one GranchainError."""
    names = [w.strip() for w in str(text).split(",")]
    for w in names:
        if w not in FITS:
            close = difflib.get_close_matches(w, FITS, n=1)
            raise GranchainError(f"--fit: unknown parameter {short(w)}; " + (
                f"did you mean {close[0]!r}?" if close else
                "fit gap_mean, or gap_mean,restitution"))
    for j, w in enumerate(names):
        if w in names[:j]:
            raise GranchainError(f"--fit: {short(w)} is named twice; name each parameter once")
    if "gap_mean" not in names:
        raise GranchainError("--fit: the restitution is fitted together with the mean gap "
                             "(both set the timing and the peaks); give --fit "
                             "gap_mean,restitution")
    return tuple(f for f in FITS if f in names)


def fit_for(base: Scene, columns) -> tuple[str, ...]:
    """What to fit when nobody says (the workflow's inference rule): the mean gap and the
    restitution for a damped base scene (contact_damping, model coeff_restitution) whose
    measurement file has both peak columns (``columns``: its header), else the mean gap."""
    damped = ("contact_damping" in base.effects
              and base.setting("contact_damping").model == "coeff_restitution")
    if damped and all(c in columns for c in PEAK_COLUMNS):
        return FITS
    return ("gap_mean",)


# ---------------------------------------------------------------------------------------
# the simulated grid
# ---------------------------------------------------------------------------------------
def timing(result, column: str) -> float:
    """The simulated timing that a measurement's ``column`` is compared with: the chain's
    true peak-to-peak (``dt_peak_s``) or half-peak arrival (``dt_front_s``) delay between
    the probes. This is the one place that chooses between true and instrument timing."""
    return {"dt_peak_s": result.dt_peak, "dt_front_s": result.dt_front}[column]


def complete_base(base: Scene, meas: Measurements) -> tuple[Scene, dict]:
    """The scene the inference simulates, and where its gap law and striker speeds come
    from (``{"gap_law": "scene" | "default", "speeds": "scene" | "data"}``).

    A base scene that does not give ``gaps.distribution`` gets DEFAULT_GAP_LAW, the
    chapter's (its mean is a placeholder: the inference sets it); one that does not give
    ``striker.velocity`` is simulated at the data's own striker speeds. What the scene
    gives is kept as it is, and checked by :func:`check_base` and :func:`check_speeds`.
    The returned scene keeps the base scene's ``given``, so completing it again changes
    nothing and reports the same sources. A base scene that cannot take a gap law is
    refused first (:func:`check_gappable`)."""
    check_gappable(base)
    change = {}
    src = {"gap_law": "scene", "speeds": "scene"}
    if "gaps.distribution" not in base.given:
        src["gap_law"] = "default"
        if base.gap_distribution != DEFAULT_GAP_LAW:
            change["gaps"] = {"distribution": DEFAULT_GAP_LAW, "mean": 0.0}
    if "striker.velocity" not in base.given:
        src["speeds"] = "data"
        speeds = sorted({float(v) for v in meas.v})
        if list(base.striker_velocities) != speeds:
            change["striker"] = {"velocity": speeds}
    if change:
        base = dataclasses.replace(base.derive(change), given=base.given)
    return base, src


def check_gappable(base: Scene) -> None:
    """Refuse (SceneError naming the key) a base scene whose chain cannot have gaps: a
    preloaded chain (``precompression.force``) is pressed together, so it has no mean gap
    to infer."""
    from .errors import SceneError
    if base.precompression > 0.0 or "precompression.force" in base.given:
        raise SceneError("precompression.force", "a preloaded chain is pressed together and "
                         "has no gaps, so the inference cannot give it a gap law",
                         "drop precompression (and walls.end if only the preload needs it) "
                         "from the base scene")


def check_base(base: Scene) -> None:
    """A base scene the inference can use: a chain that can have gaps
    (:func:`check_gappable`), a gap law with a mean that scales its realisations, and a
    fixed set of striker speeds."""
    from .errors import SceneError
    check_gappable(base)
    if base.gap_distribution not in GAP_LAWS:
        raise SceneError("gaps.distribution", f"'{base.gap_distribution}' has no mean gap to "
                         "infer", f"use one of {', '.join(GAP_LAWS)} (mean: any value; the "
                         "inference sets it), or leave gaps.distribution out for the "
                         f"chapter's {DEFAULT_GAP_LAW} law")


def grid_scene(base: Scene, gap_mean: float, realisations: int) -> Scene:
    """The scene of one grid point: the base scene at mean gap ``gap_mean`` (m) with
    ``realisations`` gap realisations at every striker speed of the base scene."""
    return base.derive({"gaps": {"mean": float(gap_mean)},
                        "ensemble": {"realisations": int(realisations)}})


@dataclass(frozen=True)
class Grid:
    """Simulated timings: ``timings[column]`` of shape (G, S, R) in s (NaN where the wave
    did not arrive), at mean gaps ``gaps`` (G, m), striker speeds ``speeds`` (S, m/s,
    ascending) and R realisations; ``hashes`` the grid scenes' hashes; ``simulated`` how
    many chains this call ran (the rest came from the cache)."""
    gaps: np.ndarray
    speeds: np.ndarray
    timings: dict
    hashes: tuple[str, ...]
    simulated: int
    weights: np.ndarray | None = None

    @property
    def realisations(self) -> int:
        return int(next(iter(self.timings.values())).shape[2])

    @property
    def realisation_weights(self) -> np.ndarray:
        """(R,) the realisations' weights (``granchain.gapdesign``; 1 each when the grid
        has plain draws)."""
        return np.ones(self.realisations) if self.weights is None else self.weights

    @property
    def n_chains(self) -> int:
        return int(self.gaps.size * self.speeds.size * self.realisations)


def _cache_file(cache_dir: Path, scene: Scene, tag: str) -> Path:
    """One grid point's timings, keyed by its scene, its realisations' design ``tag``
    (``gapdesign.Design.tag``) and the package's source (a grid simulated by other code is
    never reused)."""
    from .fileio import source_hash
    return Path(cache_dir) / (f"grid-{scene.hash}-{tag}-{source_hash()[:12]}-"
                              f"v{CACHE_FORMAT}.npz")


def simulate_grid(base: Scene, gap_max: float, gap_points: int, realisations: int,
                  cache_dir=None, engine: str = "reference",
                  progress: bool | None = None, emphasis: float = EMPHASIS) -> Grid:
    """Simulate (or read from ``cache_dir``) the grid of mean gaps
    ``linspace(0, gap_max, gap_points)`` x the base scene's speeds x ``realisations``
    designed realisations (``gapdesign.design`` with ``emphasis``; 0: the gap law's own
    draws, weight 1 each). ``progress``: a bar of the chains still to simulate on stderr
    (``granchain.progress``; None: when stderr is a terminal)."""
    from .costmodel import resolve_auto
    from .progress import bar
    from .simulate import run_scene
    check_base(base)
    if gap_points < 3:
        raise GranchainError(f"--gap-points: {gap_points} is too few; give >= 3")
    if not gap_max > 0:
        raise GranchainError(f"--gap-max-nm: {gap_max * 1e9:g} must be > 0")
    if realisations < 2:
        raise GranchainError(f"--realisations: {realisations} is too few; give >= 2")
    speeds = np.array(sorted(set(float(v) for v in base.striker_velocities)))
    if speeds[0] <= 0:
        raise GranchainError("scene field 'striker.velocity': a speed of 0 has no wave; give "
                             "speeds > 0")
    base = base.derive(striker={"velocity": [float(v) for v in speeds]})
    designed = design(base, realisations, emphasis)
    gaps = np.linspace(0.0, gap_max, gap_points)
    out = {c: np.full((gaps.size, speeds.size, realisations), np.nan) for c in TIMING_COLUMNS}
    hashes, simulated, todo = [], 0, []
    for k, g in enumerate(gaps):
        scene = resolve_auto(grid_scene(base, g, realisations))
        hashes.append(scene.hash)
        path = _cache_file(cache_dir, scene, designed.tag) if cache_dir is not None else None
        if path is not None and path.exists():
            with np.load(path) as z:
                for c in TIMING_COLUMNS:
                    out[c][k] = z[c]
        else:
            todo.append((k, scene, path))
    with bar(len(todo) * speeds.size * realisations, f"{base.name}: inference grid",
             enabled=progress) as shown:
        for k, scene, path in todo:
            res = run_scene(scene, engine=engine, progress=shown.update,
                            gaps=designed.gaps(gaps[k]))
            simulated += len(res)
            for r in res:
                j = int(np.searchsorted(speeds, r.v_striker))
                for c in TIMING_COLUMNS:
                    out[c][k, j, r.realisation] = timing(r, c)
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                buf = io.BytesIO()
                np.savez(buf, **{c: out[c][k] for c in TIMING_COLUMNS})
                atomic_write_bytes(path, buf.getvalue(), force=True, field="--cache-dir")
    return Grid(gaps, speeds, out, tuple(hashes), simulated, designed.weights)


def simulate_rows(base: Scene, gap_mean: float, speeds, realisations,
                  column: str, engine: str = "reference") -> np.ndarray:
    """Simulated timings (s) of chains of the base scene at mean gap ``gap_mean`` (m), one
    per (speed, realisation) pair: synthetic measurements (realisations drawn with the
    base scene's ``gaps.seed``; give another seed for chains the grid never saw)."""
    from .costmodel import resolve_auto
    from .observables import summarize
    from .simulate import trajectories
    speeds = [float(v) for v in speeds]
    scene = resolve_auto(base.derive({"gaps": {"mean": float(gap_mean)},
                                      "striker": {"velocity": sorted(set(speeds))}}))
    mem = [Member(i, v, int(r)) for i, (v, r) in enumerate(zip(speeds, realisations))]
    out = np.empty(len(mem))
    for m, traj in trajectories(scene, mem, engine):
        out[m.index] = timing(summarize(traj, scene.probes), column)
    return out


# ---------------------------------------------------------------------------------------
# interpolation and likelihood
# ---------------------------------------------------------------------------------------
def _interp_gap(T: np.ndarray, gaps: np.ndarray, fine: np.ndarray) -> np.ndarray:
    """(G, S, R) -> (F, S, R), linear in the mean gap."""
    j = np.clip(np.searchsorted(gaps, fine, side="right") - 1, 0, gaps.size - 2)
    w = ((fine - gaps[j]) / (gaps[j + 1] - gaps[j]))[:, None, None]
    return (1.0 - w) * T[j] + w * T[j + 1]


def _interp_speed(T: np.ndarray, speeds: np.ndarray, v: float) -> np.ndarray:
    """(..., S, R) at speed v -> (..., R), linear in (log v, log t)."""
    if speeds.size == 1:
        return T[..., 0, :]
    j = int(np.clip(np.searchsorted(speeds, v, side="right") - 1, 0, speeds.size - 2))
    w = (math.log(v) - math.log(speeds[j])) / (math.log(speeds[j + 1]) - math.log(speeds[j]))
    w = min(max(w, 0.0), 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.exp((1.0 - w) * np.log(T[..., j, :]) + w * np.log(T[..., j + 1, :]))


def interp_rel_error(grid: Grid, column: str) -> float:
    """Relative error of the grid's interpolation, measured on the grid: every interior
    node (mean gap, and speed where there are >= 3) against the interpolation of its two
    neighbours; linear interpolation over twice the spacing errs ~4x more than over the
    spacing, so the 95th percentile of |node - interpolation| / node is divided by 4."""
    T = grid.timings[column]
    errs = []
    if grid.gaps.size >= 3:
        g = grid.gaps
        w = ((g[1:-1] - g[:-2]) / (g[2:] - g[:-2]))[:, None, None]
        mid = (1 - w) * T[:-2] + w * T[2:]
        errs.append(np.abs(T[1:-1] - mid) / T[1:-1])
    if grid.speeds.size >= 3:
        lv = np.log(grid.speeds)
        w = ((lv[1:-1] - lv[:-2]) / (lv[2:] - lv[:-2]))[None, :, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            mid = np.exp((1 - w) * np.log(T[:, :-2]) + w * np.log(T[:, 2:]))
        errs.append(np.abs(T[:, 1:-1] - mid) / T[:, 1:-1])
    e = np.concatenate([x.ravel() for x in errs]) if errs else np.array([])
    e = e[np.isfinite(e)]
    return float(np.percentile(e, 95) / 4.0) if e.size else 0.0


def check_speeds(meas: Measurements, speeds, source: str = "") -> None:
    """Every row's striker speed must lie within the simulated ``speeds`` (m/s)."""
    lo, hi = float(min(speeds)), float(max(speeds))
    for k, (v, line) in enumerate(zip(meas.v, meas.lines)):
        if v < lo * (1 - SPEED_RTOL) or v > hi * (1 + SPEED_RTOL):
            rng = f"{lo:g} m/s" if lo == hi else f"{lo:g}-{hi:g} m/s"
            raise _bad(f"{source}row {k + 1} (line {line}), column 'v_striker_m_s'",
                       f"{v:g} m/s is outside the simulated striker speeds ({rng})",
                       "add speeds to the base scene's striker.velocity list so they "
                       "bracket every row, or leave striker.velocity out to simulate the "
                       "data's own speeds")


def peak_bounds(base: Scene) -> tuple[float, float]:
    """The largest peak, as a multiple of the striker speed, that the striker of the base
    scene can give each probe: its kinetic energy is all the energy the chain gets, so
    1/2 m_p v_p^2 <= 1/2 m_1 v_s^2, v_p <= v_s sqrt(m_1 / m_p) (1 for a striker of the
    probe's mass)."""
    m = base.masses
    return tuple(math.sqrt(m[0] / m[p - 1]) for p in base.probes[:2])


def check_peaks(meas: Measurements, base: Scene, source: str = "") -> None:
    """Every given peak must be one the base scene's striker can cause: at most
    ``peak_bounds`` x v_s, plus PEAK_SIGMAS of its stated error (a peak measured just above
    an attainable value is noise, one far above it is not from this chain: a unit or a
    column mix-up)."""
    if meas.vmax_1 is None and meas.vmax_2 is None:
        return
    bounds = peak_bounds(base)
    for col, vals, bound, p in zip(PEAK_COLUMNS, (meas.vmax_1, meas.vmax_2), bounds,
                                   base.probes[:2]):
        if vals is None:
            continue
        for k, (x, vs, e, line) in enumerate(zip(vals, meas.v, meas.peak_err, meas.lines)):
            top = bound * vs
            if math.isfinite(x) and x > top * (1 + PEAK_RTOL) + PEAK_SIGMAS * e:
                who = ("a striker of its mass" if bound == 1.0 else
                       f"the base scene's striker (at most {bound:.4g} v_s)")
                raise _bad(f"{source}row {k + 1} (line {line}), column {col!r}",
                           f"{x:g} m/s is above what {who} can give particle {p} at "
                           f"v_s = {vs:g} m/s ({top:g} m/s"
                           + (f" + {PEAK_SIGMAS:g} x vmax_err_m_s" if e > 0 else "") + ")",
                           "give the peak in m/s at the row's striker speed (not in units of "
                           "v_s or mm/s)")


def log_likelihood(grid: Grid, meas: Measurements, fine: np.ndarray,
                   model_rel: float = 0.0) -> np.ndarray:
    """log L(g) at every mean gap of ``fine`` (module doc), shape (F,)."""
    T = _interp_gap(grid.timings[meas.column], grid.gaps, fine)         # (F, S, R)
    weights = grid.realisation_weights
    total = np.zeros(fine.size)
    for idx in meas.groups:
        P = np.stack([_interp_speed(T, grid.speeds, float(meas.v[i])) for i in idx], axis=-1)
        t = meas.t[idx]                                                   # (m,)
        var = meas.err[idx] ** 2 + (model_rel * t) ** 2 + (1e-9 * t) ** 2
        total += kernel_log_density(P, t, np.broadcast_to(var, P[:, 0].shape), weights)
    return total


def kernel_log_density(X: np.ndarray, y: np.ndarray, var: np.ndarray,
                       weights: np.ndarray) -> np.ndarray:
    """log of the weighted Gaussian kernel density over realisations at the data: X (P, R,
    d) the R realisations' values at P parameter points (NaN where not measured), y (d,)
    the data, var (P, d) the variance added to the kernel (measurement, model error),
    weights (R,) the realisations' weights. The kernel covariance is Silverman's factor^2
    (for the weights' effective size) x the realisations' weighted covariance, plus var;
    the density is sum_r w_r N(y; X_r, C) / sum_r w_r over all R (a realisation without
    values adds nothing), -inf where fewer than two realisations give values."""
    from .modelcheck import kernel_factor
    d = X.shape[-1]
    ok = np.all(np.isfinite(X), axis=-1)                                # (P, R)
    w = np.where(ok, weights[None, :], 0.0)
    Xz = np.where(ok[..., None], X, 0.0)
    L = kernel_factor(Xz, w, weights, var)                                 # (P, d, d)
    resid = np.where(ok[..., None], y[None, None, :] - X, 0.0)             # (P, R, d)
    Z = np.linalg.solve(L, np.swapaxes(resid, 1, 2))                       # (P, d, R)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
    lp = -0.5 * (Z * Z).sum(axis=1) - 0.5 * logdet[:, None] - 0.5 * d * math.log(2 * math.pi)
    lp = np.where(ok, lp, -np.inf)
    top = lp.max(axis=1)
    with np.errstate(invalid="ignore"):
        ll = (top + np.log((np.exp(lp - top[:, None]) * weights[None, :]).sum(axis=1))
              - math.log(weights.sum()))
    return np.where(ok.sum(axis=1) >= 2, ll, -np.inf)


def gap_model_check(grid: Grid, meas: Measurements, fine: np.ndarray, pdf: np.ndarray,
                    model_rel: float):
    """Do the timings lie inside what the grid's realisations produce at the posterior?
    (``granchain.modelcheck``; each chain's kernel as in :func:`log_likelihood`.)"""
    from .modelcheck import ALPHA, CHECK_DRAWS, CHECK_SEED, STATISTIC, ModelCheck, check
    if not np.any(pdf > 0):
        return ModelCheck(STATISTIC, math.nan, math.nan, math.nan, math.nan, ALPHA, 0, True)
    mass = pdf * _trapz_weights(fine)
    g = fine[np.random.default_rng(CHECK_SEED).choice(fine.size, size=CHECK_DRAWS,
                                                      p=mass / mass.sum())]
    T = _interp_gap(grid.timings[meas.column], grid.gaps, g)            # (K, S, R)
    groups = []
    for idx in meas.groups:
        P = np.stack([_interp_speed(T, grid.speeds, float(meas.v[i])) for i in idx], axis=-1)
        t = meas.t[idx]
        var = meas.err[idx] ** 2 + (model_rel * t) ** 2 + (1e-9 * t) ** 2
        groups.append((P / t, np.ones_like(t), np.broadcast_to(var / t ** 2, P[:, 0].shape)))
    return check(groups, grid.realisation_weights)


# ---------------------------------------------------------------------------------------
# the inference
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Inference:
    """Result of :func:`infer` (SI units; NaN where not measured, with ``flags``)."""
    gap_mean_m: float
    ci95_m: tuple[float, float]
    eq54_gap_m: float
    eq54_gap_bound_m: float
    eq54_gap_rows_m: tuple[float, ...]
    n_simulated: int
    n_simulated_now: int
    gap_law: str
    timing_column: str
    method: str
    realisations: int
    gap_grid_m: tuple[float, float, int]
    speeds_m_s: tuple[float, ...]
    gap_law_source: str           # "scene": the base scene's gaps.distribution; "default"
    speeds_source: str            # "scene": its striker.velocity; "data": the rows' speeds
    interp_rel_error: float
    rows: int
    chains: int
    scene: str
    scene_hashes: tuple[str, ...]
    flags: tuple[str, ...]
    data_outside_model: dict      # modelcheck.ModelCheck.to_json(): flag, statistic, p_value
    posterior_g_m: np.ndarray = dataclasses.field(repr=False, compare=False)
    posterior_pdf: np.ndarray = dataclasses.field(repr=False, compare=False)
    grid: Grid | None = dataclasses.field(default=None, repr=False, compare=False)

    def to_json(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
             if f.name not in ("posterior_g_m", "posterior_pdf", "grid")}
        d["ci95_m"] = list(self.ci95_m)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


def log_prior(fine: np.ndarray, prior: str = PRIOR) -> np.ndarray:
    """log prior density (unnormalised) of the mean gap at the points ``fine`` (m)."""
    if prior == "uniform":
        return np.zeros_like(fine)
    if prior == "scale":
        return -np.log(fine + PRIOR_G0)
    raise GranchainError(f"--prior: unknown prior {prior!r}; use uniform or scale")


def posterior_summary(fine: np.ndarray, logpost: np.ndarray):
    """(pdf, median, lo, hi, flags) of a posterior on the points ``fine``."""
    flags = []
    if not np.any(np.isfinite(logpost)):
        return np.zeros_like(fine), math.nan, math.nan, math.nan, ["no_simulated_match"]
    p = np.exp(logpost - np.max(logpost[np.isfinite(logpost)]))
    p[~np.isfinite(p)] = 0.0
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(fine))])
    pdf = p / cdf[-1]
    cdf = cdf / cdf[-1]
    q = [float(np.interp(x, cdf, fine)) for x in (0.5, 0.025, 0.975)]
    if p[-1] > EDGE_WEIGHT:
        flags.append("posterior_at_grid_end")
        q = [math.nan, q[1], math.nan]
    return pdf, q[0], q[1], q[2], flags


def eq54_gaps(grid: Grid, meas: Measurements, probes) -> tuple[float, float, np.ndarray]:
    """(least-squares fit, bound reading, per-row values) of the mean gap from Eq. 5.4
    (module doc), with the packed chain's timing from the grid's g = 0 point."""
    return _eq54(grid.timings[meas.column][0], grid.speeds, meas, probes)


def _eq54(T0: np.ndarray, speeds: np.ndarray, meas: Measurements, probes):
    """Eq. 5.4 readings with the packed chain's timings ``T0`` (S, R) at ``speeds``."""
    span = probes[1] - probes[0]
    grid_speeds = speeds
    dt0 = np.array([float(np.nanmedian(_interp_speed(T0, grid_speeds, float(v))))
                    for v in meas.v])
    y = meas.t - dt0
    x = span / meas.v
    rows = meas.v * y / span
    fit = float(np.sum(x * y) / np.sum(x * x)) if np.all(np.isfinite(y)) else math.nan
    return fit, float(np.min(rows)), rows


def infer(base: Scene, meas: Measurements, *, gap_max: float = 250e-9, gap_points: int = 26,
          realisations: int = 64, cache_dir=None, grid: Grid | None = None,
          source: str = "", prior: str = PRIOR, progress: bool | None = None) -> Inference:
    """Infer the mean gap (module doc) from ``meas`` with the base scene's model, completed
    by :func:`complete_base`; a given ``grid`` is used as is (it must come from
    ``simulate_grid`` on the completed base scene). ``progress``: a progress bar of the
    grid's simulation on stderr (``simulate_grid``)."""
    base, src = complete_base(base, meas)
    check_base(base)
    check_peaks(meas, base, source)
    # checked before the grid is simulated
    check_speeds(meas, base.striker_velocities if grid is None else grid.speeds, source)
    if grid is None:
        grid = simulate_grid(base, gap_max, gap_points, realisations, cache_dir,
                             progress=progress)
    fine = np.linspace(0.0, float(grid.gaps[-1]), FINE_POINTS)
    rel = interp_rel_error(grid, meas.column)
    logpost = log_likelihood(grid, meas, fine, rel) + log_prior(fine, prior)
    pdf, med, lo, hi, flags = posterior_summary(fine, logpost)
    mc = gap_model_check(grid, meas, fine, pdf, rel)
    if mc.flag:
        flags.append("data_outside_model")
    fit, bound, rows = eq54_gaps(grid, meas, base.probes)
    return Inference(
        gap_mean_m=med, ci95_m=(lo, hi), eq54_gap_m=fit, eq54_gap_bound_m=bound,
        eq54_gap_rows_m=tuple(float(r) for r in rows), n_simulated=grid.n_chains,
        n_simulated_now=grid.simulated, gap_law=_law(base), timing_column=meas.column,
        method="grid posterior, simulated-ensemble kernel likelihood",
        realisations=grid.realisations,
        gap_grid_m=(float(grid.gaps[0]), float(grid.gaps[-1]), int(grid.gaps.size)),
        speeds_m_s=tuple(float(v) for v in grid.speeds), gap_law_source=src["gap_law"],
        speeds_source=src["speeds"], interp_rel_error=rel,
        rows=len(meas), chains=len(meas.groups), scene=base.name,
        scene_hashes=grid.hashes, flags=tuple(flags), data_outside_model=mc.to_json(),
        posterior_g_m=fine, posterior_pdf=pdf, grid=grid)


# ---------------------------------------------------------------------------------------
# the joint fit: mean gap and coefficient of restitution (--fit gap_mean,restitution)
# ---------------------------------------------------------------------------------------
JOINT_OBS = ("dt_peak_s", "dt_front_s", "v_max_1", "v_max_2")
JOINT_CACHE_FORMAT = 1
E_MIN, E_POINTS = 0.7, 7          # restitution nodes linspace(E_MIN, 1, E_POINTS): spacing 0.05
FINE_G, FINE_E = 241, 161         # posterior evaluation points (mean gap, restitution)
ZOOM_DROP = 20.0                  # the second pass covers log posterior >= peak - this
CHUNK_BYTES = 64e6                # working memory of one block of the joint likelihood
PREDICTIVE_DRAWS = 400            # posterior draws of the predictive check and the figure
PREDICTIVE_SEED = 20250


def peak(result, probe: int) -> float:
    """The simulated peak (m/s) that a measured ``vmax_1_m_s`` (probe 0) or ``vmax_2_m_s``
    (probe 1) is compared with: the chain's true peak, as :func:`timing` takes the true
    timing."""
    return result.v_max_1 if probe == 0 else result.v_max_2


def check_restitution_base(base: Scene) -> None:
    """A base scene whose coefficient of restitution the inference can set: the
    contact_damping effect with model coeff_restitution."""
    from .errors import SceneError
    fix = ("add contact_damping to effects with damping: {model: coeff_restitution, "
           "e: 0.95} (any e; the inference sets it)")
    if "contact_damping" not in base.effects:
        raise SceneError("effects", "has no contact_damping, so the model has no "
                         "restitution to fit", fix)
    model = base.setting("contact_damping").model
    if model != "coeff_restitution":
        raise SceneError("damping.model", f"is {model}; the inference fits the coefficient "
                         "of restitution e of model coeff_restitution",
                         "write damping: {model: coeff_restitution, e: 0.95} (any e; the "
                         "inference sets it)")


def gap_nodes(gap_max: float, points: int) -> np.ndarray:
    """Mean gaps of the joint grid: gap_max (k/(points-1))^2, dense where the peaks change
    fastest (the packed-to-gapped change at gaps of the order of the contact overlap,
    ~10-30 nm; module doc)."""
    return gap_max * np.linspace(0.0, 1.0, points) ** 2


def restitution_nodes(e_min: float, points: int) -> np.ndarray:
    return np.linspace(e_min, 1.0, points)


def joint_scene(base: Scene, gap_mean: float, e: float, realisations: int) -> Scene:
    """The scene of one node of the joint grid: the base scene at mean gap ``gap_mean``
    (m) and coefficient of restitution ``e``, ``realisations`` gap realisations."""
    return base.derive({"gaps": {"mean": float(gap_mean)}, "damping": {"e": float(e)},
                        "ensemble": {"realisations": int(realisations)}})


@dataclass(frozen=True)
class JointGrid:
    """Simulated observables ``values[name]`` (``JOINT_OBS``: the two timings in s, the
    probes' peaks in m/s) of shape (G, E, S, R), NaN where not measured, at mean gaps
    ``gaps`` (G), restitutions ``restitutions`` (E, ascending, the last 1), striker speeds
    ``speeds`` (S) and R realisations (the same gap patterns at every node)."""
    gaps: np.ndarray
    restitutions: np.ndarray
    speeds: np.ndarray
    values: dict
    hashes: tuple[str, ...]
    simulated: int
    wall_s: float = 0.0
    weights: np.ndarray | None = None

    @property
    def realisations(self) -> int:
        return int(next(iter(self.values.values())).shape[3])

    @property
    def realisation_weights(self) -> np.ndarray:
        """(R,) the realisations' weights, as :attr:`Grid.realisation_weights`."""
        return np.ones(self.realisations) if self.weights is None else self.weights

    @property
    def n_chains(self) -> int:
        return int(self.gaps.size * self.restitutions.size * self.speeds.size
                   * self.realisations)


def _joint_cache_file(cache_dir: Path, scene: Scene, tag: str) -> Path:
    from .fileio import source_hash
    return Path(cache_dir) / (f"joint-{scene.hash}-{tag}-{source_hash()[:12]}-"
                              f"v{JOINT_CACHE_FORMAT}.npz")


def check_joint_options(gap_max: float, gap_points: int, e_min: float, e_points: int,
                        realisations: int) -> None:
    if gap_points < 3:
        raise GranchainError(f"--gap-points: {gap_points} is too few; give >= 3")
    if not gap_max > 0:
        raise GranchainError(f"--gap-max-nm: {gap_max * 1e9:g} must be > 0")
    if realisations < 2:
        raise GranchainError(f"--realisations: {realisations} is too few; give >= 2")
    if not (0.0 < e_min < 1.0):
        raise GranchainError(f"--e-min: {e_min:g} is not between 0 and 1; give the smallest "
                             "coefficient of restitution to simulate, e.g. 0.8")
    if e_points < 2:
        raise GranchainError(f"--e-points: {e_points} is too few; give >= 2")


def simulate_joint_grid(base: Scene, gap_max: float, gap_points: int, e_min: float,
                        e_points: int, realisations: int, cache_dir=None,
                        engine: str = "reference", progress: bool | None = None,
                        emphasis: float = EMPHASIS) -> JointGrid:
    """Simulate (or read from ``cache_dir``) the joint grid: mean gaps
    ``gap_nodes(gap_max, gap_points)`` x restitutions ``restitution_nodes(e_min,
    e_points)`` x the base scene's speeds x ``realisations`` designed realisations (module
    doc). ``progress`` and ``emphasis`` as :func:`simulate_grid`."""
    import time
    from .costmodel import resolve_auto
    from .progress import bar
    from .simulate import run_scene
    check_base(base)
    check_restitution_base(base)
    check_joint_options(gap_max, gap_points, e_min, e_points, realisations)
    speeds = np.array(sorted(set(float(v) for v in base.striker_velocities)))
    if speeds[0] <= 0:
        raise GranchainError("scene field 'striker.velocity': a speed of 0 has no wave; give "
                             "speeds > 0")
    base = base.derive(striker={"velocity": [float(v) for v in speeds]})
    designed = design(base, realisations, emphasis)
    gaps, es = gap_nodes(gap_max, gap_points), restitution_nodes(e_min, e_points)
    shape = (gaps.size, es.size, speeds.size, realisations)
    out = {c: np.full(shape, np.nan) for c in JOINT_OBS}
    hashes, simulated, todo = [], 0, []
    t0 = time.perf_counter()
    for k, g in enumerate(gaps):
        for j, e in enumerate(es):
            scene = resolve_auto(joint_scene(base, g, e, realisations))
            hashes.append(scene.hash)
            path = (_joint_cache_file(cache_dir, scene, designed.tag) if cache_dir is not None
                    else None)
            if path is not None and path.exists():
                with np.load(path) as z:
                    for c in JOINT_OBS:
                        out[c][k, j] = z[c]
            else:
                todo.append((k, j, scene, path))
    with bar(len(todo) * speeds.size * realisations, f"{base.name}: inference grid",
             enabled=progress) as shown:
        for k, j, scene, path in todo:
            res = run_scene(scene, engine=engine, progress=shown.update,
                            gaps=designed.gaps(gaps[k]))
            simulated += len(res)
            for r in res:
                s = int(np.searchsorted(speeds, r.v_striker))
                for c in TIMING_COLUMNS:
                    out[c][k, j, s, r.realisation] = timing(r, c)
                out["v_max_1"][k, j, s, r.realisation] = peak(r, 0)
                out["v_max_2"][k, j, s, r.realisation] = peak(r, 1)
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                buf = io.BytesIO()
                np.savez(buf, **{c: out[c][k, j] for c in JOINT_OBS})
                atomic_write_bytes(path, buf.getvalue(), force=True, field="--cache-dir")
    return JointGrid(gaps, es, speeds, out, tuple(hashes), simulated,
                     time.perf_counter() - t0, designed.weights)


def simulate_joint_rows(base: Scene, gap_mean: float, e: float | None, speeds, realisations,
                        column: str, engine: str = "reference") -> np.ndarray:
    """(rows, 3) simulated (timing in s, vmax_1, vmax_2 in m/s) of chains of the base scene
    at mean gap ``gap_mean`` (m) and restitution ``e`` (None: the base scene's damping as
    it is, e.g. another law), one per (speed, realisation) pair: synthetic measurements
    (give the base scene another ``gaps.seed`` for chains the grid never saw)."""
    from .costmodel import resolve_auto
    from .observables import summarize
    from .simulate import trajectories
    speeds = [float(v) for v in speeds]
    change = {"gaps": {"mean": float(gap_mean)}, "striker": {"velocity": sorted(set(speeds))}}
    if e is not None:
        change["damping"] = {"e": float(e)}
    scene = resolve_auto(base.derive(change))
    mem = [Member(i, v, int(r)) for i, (v, r) in enumerate(zip(speeds, realisations))]
    out = np.empty((len(mem), 3))
    for m, traj in trajectories(scene, mem, engine):
        res = summarize(traj, scene.probes)
        out[m.index] = (timing(res, column), peak(res, 0), peak(res, 1))
    return out


def collision_restitution(base: Scene, v: float, damping: dict) -> float:
    """The coefficient of restitution of one head-on collision of the base scene's striker
    with particle 2 at closing speed v (m/s), Hertz contact with ``damping`` (a scene
    ``damping`` section) and nothing else: (v_2' - v_1') / v."""
    from .simulate import trajectories
    sc = base.derive({"chain": {"n": 3}, "probes": [2, 3], "t_end": 40 * base.contact_time(v),
                      "effects": ["hertz", "contact_damping"], "damping": damping,
                      "gaps": {"distribution": "list", "values": [0.0, 1e-3]},
                      "striker": {"velocity": float(v)},
                      "integrator": {"method": "adaptive", "tolerance": 1e-9}})
    _, traj = next(trajectories(sc, [Member(0, float(v), 0)]))
    return float((traj.v[-1, 1] - traj.v[-1, 0]) / v)


def matching_eta(base: Scene, e: float, v: float, tol: float = 1e-5) -> float:
    """The viscoelastic eta_n0 (1/(m s)) whose head-on collision at closing speed v gives
    the coefficient of restitution e (secant on 1 - e, which is nearly proportional to
    eta for weak damping); at other speeds its e differs (1 - e ~ v^(1/5))."""
    if e >= 1.0:
        return 0.0
    loss = lambda eta: 1.0 - collision_restitution(   # noqa: E731
        base, v, {"model": "viscoelastic", "eta": eta, "e": None})
    a = 1e12 * (1.0 - e)          # 1 - e ~ 1e-12 eta for 150 um steel at 0.05 m/s
    la = loss(a)
    b = a * (1.0 - e) / la
    lb = loss(b)
    for _ in range(30):
        if abs(lb - (1.0 - e)) < tol:
            return b
        a, la, b = b, lb, b + (1.0 - e - lb) * (b - a) / (lb - la)
        lb = loss(b)
    raise GranchainError(f"no viscoelastic eta found for e = {e:g} at {v:g} m/s")

# --- interpolation of the joint grid -------------------------------------------------
def _speed_weight(speeds: np.ndarray, v: float) -> tuple[int, float]:
    """(j, w): v between speeds j and j + 1, weight w of j + 1, linear in log v."""
    if speeds.size == 1:
        return 0, 0.0
    j = int(np.clip(np.searchsorted(speeds, v, side="right") - 1, 0, speeds.size - 2))
    w = (math.log(v) - math.log(speeds[j])) / (math.log(speeds[j + 1]) - math.log(speeds[j]))
    return j, min(max(w, 0.0), 1.0)


def _at_speed(grid: JointGrid, column: str, v: float) -> np.ndarray:
    """(G, E, R, 3) simulated (timing s, vmax_1, vmax_2 m/s) at striker speed v: the
    timing linear in (log v, log t) as in the gap-only fit, the peaks as v_max / v_s
    linear in log v (a packed chain's v_max / v_s does not depend on v_s)."""
    j, w = _speed_weight(grid.speeds, v)
    k = min(j + 1, grid.speeds.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        T = grid.values[column]
        t = np.exp((1 - w) * np.log(T[:, :, j]) + w * np.log(T[:, :, k]))
        pk = [v * ((1 - w) * grid.values[c][:, :, j] / grid.speeds[j]
                   + w * grid.values[c][:, :, k] / grid.speeds[k])
              for c in ("v_max_1", "v_max_2")]
    out = np.stack([t, *pk], axis=-1)
    return np.where(out > 0, out, np.nan)


def _weights(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    j = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
    w = (x - nodes[j]) / (nodes[j + 1] - nodes[j])
    return j, np.clip(w, 0.0, 1.0)


def _interp_e(A: np.ndarray, es: np.ndarray, e: np.ndarray, axis: int = 1) -> np.ndarray:
    """A (..., E, ...) -> (..., len(e), ...) along ``axis``: log A linear in e."""
    j, w = _weights(es, np.asarray(e, float))
    shape = [1] * A.ndim
    shape[axis] = w.size
    w = w.reshape(shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        L = np.log(A)
        return np.exp((1 - w) * np.take(L, j, axis=axis) + w * np.take(L, j + 1, axis=axis))


def _interp_g(A: np.ndarray, gaps: np.ndarray, g: np.ndarray) -> np.ndarray:
    """A (G, ...) -> (len(g), ...), linear in the mean gap."""
    j, w = _weights(gaps, np.asarray(g, float))
    w = w.reshape((-1,) + (1,) * (A.ndim - 1))
    return (1 - w) * A[j] + w * A[j + 1]


def joint_values(grid: JointGrid, column: str, v: float, g, e) -> np.ndarray:
    """(len(g), R, 3) simulated (timing, vmax_1, vmax_2) at speed v and the pairs
    (g[i], e[i])."""
    A = _at_speed(grid, column, v)                                    # (G, E, R, 3)
    g, e = np.atleast_1d(np.asarray(g, float)), np.atleast_1d(np.asarray(e, float))
    jg, wg = _weights(grid.gaps, g)
    je, we = _weights(grid.restitutions, e)
    out = 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        L = np.log(A)
        for dj, ww in ((0, 1 - wg), (1, wg)):
            row = L[jg + dj]                                              # (n, E, R, 3)
            n = np.arange(g.size)
            Le = (1 - we)[:, None, None] * row[n, je] + we[:, None, None] * row[n, je + 1]
            out = out + ww[:, None, None] * np.exp(Le)
    return out


def joint_interp_errors(grid: JointGrid, column: str) -> dict:
    """Relative interpolation error of each observable (the timing ``column``, v_max_1,
    v_max_2), measured on the grid as in the gap-only fit (each interior node against the
    interpolation of its two neighbours, 95th percentile / 4): ``g`` per mean-gap node (G;
    an end node takes its neighbour's; the error changes by orders of magnitude over the
    gaps, so it is interpolated between the nodes), ``e`` and ``speed`` one value each."""
    names = (column, "v_max_1", "v_max_2")
    out = {}
    for name in names:
        A = grid.values[name]                                            # (G, E, S, R)
        if name != column:
            A = A / grid.speeds[None, None, :, None]
        g = grid.gaps
        w = ((g[1:-1] - g[:-2]) / (g[2:] - g[:-2]))[:, None, None, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            node = np.abs(A[1:-1] - ((1 - w) * A[:-2] + w * A[2:])) / A[1:-1]
        per = np.array([_p95(x) for x in node]) / 4.0                     # (G - 2,)
        g_err = np.concatenate([[per[0]], per, [per[-1]]])                # every node
        e_err = s_err = 0.0
        if grid.restitutions.size >= 3:
            es = grid.restitutions
            w = ((es[1:-1] - es[:-2]) / (es[2:] - es[:-2]))[None, :, None, None]
            with np.errstate(invalid="ignore", divide="ignore"):
                mid = np.exp((1 - w) * np.log(A[:, :-2]) + w * np.log(A[:, 2:]))
                e_err = _p95(np.abs(A[:, 1:-1] - mid) / A[:, 1:-1]) / 4.0
        if grid.speeds.size >= 3:
            lv = np.log(grid.speeds)
            w = ((lv[1:-1] - lv[:-2]) / (lv[2:] - lv[:-2]))[None, None, :, None]
            with np.errstate(invalid="ignore", divide="ignore"):
                if name == column:
                    mid = np.exp((1 - w) * np.log(A[:, :, :-2]) + w * np.log(A[:, :, 2:]))
                else:
                    mid = (1 - w) * A[:, :, :-2] + w * A[:, :, 2:]
                s_err = _p95(np.abs(A[:, :, 1:-1] - mid) / A[:, :, 1:-1]) / 4.0
        out[name] = {"g": g_err, "e": e_err, "speed": s_err}
    return out


def _p95(x: np.ndarray) -> float:
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    return float(np.percentile(x, 95)) if x.size else 0.0


def _model_rel(errs: dict, column: str, fine_g: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """(F_g, 3) relative model error of (timing, vmax_1, vmax_2) at each fine mean gap."""
    cols = []
    for name in (column, "v_max_1", "v_max_2"):
        d = errs[name]
        cols.append(np.sqrt(np.interp(fine_g, gaps, d["g"]) ** 2 + d["e"] ** 2
                            + d["speed"] ** 2))
    return np.stack(cols, axis=-1)


# --- likelihood and posterior --------------------------------------------------------
def fine_axes(grid: JointGrid) -> tuple[np.ndarray, np.ndarray]:
    """The posterior's evaluation points: mean gaps (quadratic spacing, as the nodes) and
    restitutions (uniform) over the grid's range."""
    return (float(grid.gaps[-1]) * np.linspace(0.0, 1.0, FINE_G) ** 2,
            np.linspace(float(grid.restitutions[0]), float(grid.restitutions[-1]), FINE_E))


def joint_log_likelihood(grid: JointGrid, meas: Measurements, fine_g: np.ndarray,
                         fine_e: np.ndarray, errs: dict | None = None) -> np.ndarray:
    """log L(g, e), shape (F_g, F_e): per group (a chain), the kernel density over the R
    realisations of the group's 3m observables (each row's timing and two peaks),
    standardised by the row's observed timing and striker speed (module doc)."""
    if errs is None:
        errs = joint_interp_errors(grid, meas.column)
    rel = _model_rel(errs, meas.column, fine_g, grid.gaps)             # (F_g, 3)
    R = grid.realisations
    weights = grid.realisation_weights
    total = np.zeros((fine_g.size, fine_e.size))
    for idx in meas.groups:
        m = idx.size
        d = 3 * m
        scale, y, var_meas, var_floor = _joint_group(meas, idx)
        var_model = (np.tile(rel, (1, m)) * y[None, :]) ** 2                 # (F_g, d)
        nodes = np.concatenate([_at_speed(grid, meas.column, float(meas.v[i])) for i in idx],
                               axis=-1) / scale                            # (G, E, R, d)
        Ne = _interp_e(nodes, grid.restitutions, fine_e, axis=1)          # (G, F_e, R, d)
        rows = max(1, int(CHUNK_BYTES // (fine_e.size * R * d * 8 * 6)))
        for a in range(0, fine_g.size, rows):
            b = min(a + rows, fine_g.size)
            X = _interp_g(Ne, grid.gaps, fine_g[a:b])                      # (c, F_e, R, d)
            var = var_meas + var_floor + np.repeat(var_model[a:b], fine_e.size, axis=0)
            ll = kernel_log_density(X.reshape(-1, R, d), y, var, weights)
            total[a:b] += ll.reshape(b - a, fine_e.size)
    return total


def _joint_group(meas: Measurements, idx: np.ndarray):
    """(scale, y, var_meas, var_floor), each (3m,), of a group's rows in the joint
    likelihood: each row's (timing, vmax_1, vmax_2) standardised by its observed timing
    and its striker speed, their stated variances and the kernel's floor."""
    perr = meas.peak_err
    scale = np.concatenate([[meas.t[i], meas.v[i], meas.v[i]] for i in idx])
    y = np.concatenate([[meas.t[i], meas.vmax_1[i], meas.vmax_2[i]] for i in idx]) / scale
    var_meas = (np.concatenate([[meas.err[i], perr[i], perr[i]] for i in idx]) / scale) ** 2
    return scale, y, var_meas, (1e-9 * y) ** 2


def zoom_box(fine_g, fine_e, logpost, drop: float = ZOOM_DROP, shrink: float = 0.5):
    """((g0, g1), (e0, e1)): the box of the points whose log posterior is within ``drop``
    of its peak, one point wider on each side, when it spans less than ``shrink`` of the
    range in either parameter (the posterior is then evaluated again on it, for the
    resolution of a narrow posterior); None otherwise."""
    ok = np.isfinite(logpost)
    if not np.any(ok):
        return None
    keep = ok & (logpost >= np.max(logpost[ok]) - drop)
    gi, ej = np.flatnonzero(keep.any(axis=1)), np.flatnonzero(keep.any(axis=0))
    a, b = max(gi[0] - 1, 0), min(gi[-1] + 1, fine_g.size - 1)
    c, d = max(ej[0] - 1, 0), min(ej[-1] + 1, fine_e.size - 1)
    span_g = (fine_g[b] - fine_g[a]) / (fine_g[-1] - fine_g[0])
    span_e = (fine_e[d] - fine_e[c]) / (fine_e[-1] - fine_e[0])
    if min(span_g, span_e) >= shrink:
        return None
    return (float(fine_g[a]), float(fine_g[b])), (float(fine_e[c]), float(fine_e[d]))


def _trapz_weights(x: np.ndarray) -> np.ndarray:
    w = np.zeros_like(x)
    dx = np.diff(x)
    w[:-1] += 0.5 * dx
    w[1:] += 0.5 * dx
    return w


def _summary(x: np.ndarray, pdf: np.ndarray, low_flag: str | None, high_flag: str | None):
    """(median, lo, hi, flags) of a 1D density on the points x; an end of the grid where
    the density is above EDGE_WEIGHT x its peak sets the end's quantile and the median to
    NaN with its flag."""
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(x))])
    cdf = cdf / cdf[-1]
    med, lo, hi = (float(np.interp(q, cdf, x)) for q in (0.5, 0.025, 0.975))
    flags = []
    top = float(np.max(pdf))
    if low_flag and pdf[0] > EDGE_WEIGHT * top:
        flags.append(low_flag)
        med, lo = math.nan, math.nan
    if high_flag and pdf[-1] > EDGE_WEIGHT * top:
        flags.append(high_flag)
        med, hi = math.nan, math.nan
    return med, lo, hi, flags


@dataclass(frozen=True)
class JointInference:
    """Result of :func:`infer_joint` (SI units; NaN where not measured, with ``flags``)."""
    fit: tuple[str, ...]
    gap_mean_m: float
    ci95_m: tuple[float, float]
    restitution: float
    restitution_ci95: tuple[float, float]
    posterior_correlation: float
    eq54_gap_m: float
    eq54_gap_bound_m: float
    eq54_gap_rows_m: tuple[float, ...]
    predictive_outside: int | None    # None: no posterior draw, nothing checked
    predictive_values: int
    predictive_rows: tuple
    n_simulated: int
    n_simulated_now: int
    gap_law: str
    damping_model: str
    timing_column: str
    method: str
    realisations: int
    gap_grid_m: tuple[float, float, int]
    gap_spacing: str
    restitution_grid: tuple[float, float, int]
    speeds_m_s: tuple[float, ...]
    gap_law_source: str           # as Inference
    speeds_source: str
    interp_rel_error: dict
    rows: int
    chains: int
    scene: str
    scene_hashes: tuple[str, ...]
    flags: tuple[str, ...]
    data_outside_model: dict      # as Inference
    posterior_g_m: np.ndarray = dataclasses.field(repr=False, compare=False)
    posterior_e: np.ndarray = dataclasses.field(repr=False, compare=False)
    posterior_pdf: np.ndarray = dataclasses.field(repr=False, compare=False)   # (F_g, F_e)
    marginal_g: np.ndarray = dataclasses.field(repr=False, compare=False)
    marginal_e: np.ndarray = dataclasses.field(repr=False, compare=False)
    draws: np.ndarray = dataclasses.field(repr=False, compare=False)           # (D, 2)
    grid: JointGrid | None = dataclasses.field(default=None, repr=False, compare=False)

    HIDDEN = ("posterior_g_m", "posterior_e", "posterior_pdf", "marginal_g", "marginal_e",
              "draws", "grid")

    def to_json(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
             if f.name not in self.HIDDEN}
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


def joint_model_check(grid: JointGrid, meas: Measurements, draws: np.ndarray, errs: dict):
    """Do the timings and peaks lie inside what the grid's realisations produce at the
    posterior draws? (``granchain.modelcheck``; each chain's kernel as in
    :func:`joint_log_likelihood`.)"""
    from .modelcheck import CHECK_DRAWS, ModelCheck, STATISTIC, ALPHA, check
    if not draws.size:
        return ModelCheck(STATISTIC, math.nan, math.nan, math.nan, math.nan, ALPHA, 0, True)
    sub = draws[:CHECK_DRAWS]
    rel = _model_rel(errs, meas.column, sub[:, 0], grid.gaps)          # (K, 3)
    groups = []
    for idx in meas.groups:
        scale, y, var_meas, var_floor = _joint_group(meas, idx)
        X = np.concatenate([joint_values(grid, meas.column, float(meas.v[i]), sub[:, 0],
                                         sub[:, 1]) for i in idx], axis=-1) / scale
        var = var_meas + var_floor + (np.tile(rel, (1, idx.size)) * y[None, :]) ** 2
        groups.append((X, y, var))
    return check(groups, grid.realisation_weights)


def posterior_draws(fine_g, fine_e, pdf, draws: int = PREDICTIVE_DRAWS,
                    seed: int = PREDICTIVE_SEED) -> np.ndarray:
    """(draws, 2) (g, e) drawn from the posterior on the fine points (cell masses
    pdf x trapezoid weights), with a fixed seed: the same result gives the same draws."""
    mass = pdf * _trapz_weights(fine_g)[:, None] * _trapz_weights(fine_e)[None, :]
    p = mass.ravel() / mass.sum()
    k = np.random.default_rng(seed).choice(p.size, size=draws, p=p)
    return np.stack([fine_g[k // fine_e.size], fine_e[k % fine_e.size]], axis=1)


def predictive(grid: JointGrid, meas: Measurements, draws: np.ndarray,
               seed: int = PREDICTIVE_SEED):
    """Posterior predictive of every row: (per row [(2.5, 50, 97.5) % of timing, vmax_1,
    vmax_2] with the stated measurement noise added, number of measured values outside
    their 95 % range, number of values). Rows of one chain share a realisation, but each
    value is checked on its own."""
    rng = np.random.default_rng([seed, 1])
    rows, outside = [], 0
    perr = meas.peak_err
    for i in range(len(meas)):
        X = joint_values(grid, meas.column, float(meas.v[i]), draws[:, 0], draws[:, 1])
        X = X.reshape(-1, 3)
        X = X[np.all(np.isfinite(X), axis=1)]
        sd = np.array([meas.err[i], perr[i], perr[i]])
        X = X + sd * rng.standard_normal(X.shape)
        q = np.percentile(X, [2.5, 50, 97.5], axis=0) if X.size else np.full((3, 3), np.nan)
        y = (meas.t[i], meas.vmax_1[i], meas.vmax_2[i])
        outside += int(sum(not (q[0, c] <= y[c] <= q[2, c]) for c in range(3)))
        rows.append({"v_striker_m_s": float(meas.v[i]),
                     meas.column: [float(x) for x in q[:, 0]],
                     "vmax_1_m_s": [float(x) for x in q[:, 1]],
                     "vmax_2_m_s": [float(x) for x in q[:, 2]]})
    return tuple(rows), outside, 3 * len(meas)


def infer_joint(base: Scene, meas: Measurements, *, gap_max: float = 500e-9,
                gap_points: int = 21, e_min: float = E_MIN, e_points: int = E_POINTS,
                realisations: int = 64, cache_dir=None, grid: JointGrid | None = None,
                source: str = "", prior: str = PRIOR,
                progress: bool | None = None) -> JointInference:
    """Infer the mean gap and the coefficient of restitution together (module doc) from
    ``meas`` (timings and both probes' peaks on every row) with the base scene's model,
    completed by :func:`complete_base`; a given ``grid`` is used as is (from
    ``simulate_joint_grid`` on the completed base scene). ``progress`` as :func:`infer`."""
    base, src = complete_base(base, meas)
    check_base(base)
    check_restitution_base(base)
    if not meas.has_peaks:
        raise GranchainError(f"{source}columns 'vmax_1_m_s', 'vmax_2_m_s': fitting the "
                             "restitution needs the measured peaks on every row; give them")
    check_peaks(meas, base, source)
    check_speeds(meas, base.striker_velocities if grid is None else grid.speeds, source)
    if grid is None:
        grid = simulate_joint_grid(base, gap_max, gap_points, e_min, e_points, realisations,
                                   cache_dir, progress=progress)
    fg, fe = fine_axes(grid)
    errs = joint_interp_errors(grid, meas.column)
    logpost = joint_log_likelihood(grid, meas, fg, fe, errs) + log_prior(fg, prior)[:, None]
    ends = (True, True)
    box = zoom_box(fg, fe, logpost)
    if box is not None:           # the posterior again, on a grid over its own mass
        (g0, g1), (e0, e1) = box
        ends = (g1 >= fg[-1], e0 <= fe[0])
        fg, fe = np.linspace(g0, g1, FINE_G), np.linspace(e0, e1, FINE_E)
        logpost = joint_log_likelihood(grid, meas, fg, fe, errs) + log_prior(fg, prior)[:, None]
    flags = []
    if not np.any(np.isfinite(logpost)):
        nan = math.nan
        pdf = np.zeros_like(logpost)
        mg, me = np.zeros_like(fg), np.zeros_like(fe)
        gq = eq = (nan, nan, nan)
        corr, draws = nan, np.zeros((0, 2))
        flags.append("no_simulated_match")
    else:
        p = np.exp(logpost - np.max(logpost[np.isfinite(logpost)]))
        p[~np.isfinite(p)] = 0.0
        wg, we = _trapz_weights(fg), _trapz_weights(fe)
        pdf = p / float((p * wg[:, None] * we[None, :]).sum())
        mg, me = (pdf * we[None, :]).sum(axis=1), (pdf * wg[:, None]).sum(axis=0)
        *gq, fl_g = _summary(fg, mg, None, "posterior_at_grid_end" if ends[0] else None)
        *eq, fl_e = _summary(fe, me, "restitution_at_grid_end" if ends[1] else None, None)
        flags += fl_g + fl_e
        mass = pdf * wg[:, None] * we[None, :]
        G, E = np.meshgrid(fg, fe, indexing="ij")
        mu_g, mu_e = (mass * G).sum(), (mass * E).sum()
        cov = (mass * (G - mu_g) * (E - mu_e)).sum()
        sd = math.sqrt((mass * (G - mu_g) ** 2).sum() * (mass * (E - mu_e) ** 2).sum())
        corr = float(cov / sd) if sd > 0 else math.nan
        draws = posterior_draws(fg, fe, pdf)
    if draws.size:
        pred_rows, outside, checked = predictive(grid, meas, draws)
    else:
        pred_rows, outside, checked = (), None, 3 * len(meas)   # nothing checked
    mc = joint_model_check(grid, meas, draws, errs)
    if mc.flag:
        flags.append("data_outside_model")
    e_eq = eq[0] if math.isfinite(eq[0]) else float(grid.restitutions[-1])
    T0 = _interp_e(grid.values[meas.column][0], grid.restitutions, [e_eq], axis=0)[0]
    fit54, bound54, rows54 = _eq54(T0, grid.speeds, meas, base.probes)
    return JointInference(
        fit=("gap_mean", "restitution"), gap_mean_m=gq[0], ci95_m=(gq[1], gq[2]),
        restitution=eq[0], restitution_ci95=(eq[1], eq[2]), posterior_correlation=corr,
        eq54_gap_m=fit54, eq54_gap_bound_m=bound54,
        eq54_gap_rows_m=tuple(float(r) for r in rows54), predictive_outside=outside,
        predictive_values=checked, predictive_rows=pred_rows,
        n_simulated=grid.n_chains, n_simulated_now=grid.simulated, gap_law=_law(base), damping_model="coeff_restitution",
        timing_column=meas.column,
        method="2D grid posterior (mean gap x restitution), simulated-ensemble kernel "
               "likelihood of timing and both peaks",
        realisations=grid.realisations,
        gap_grid_m=(float(grid.gaps[0]), float(grid.gaps[-1]), int(grid.gaps.size)),
        gap_spacing="quadratic",
        restitution_grid=(float(grid.restitutions[0]), float(grid.restitutions[-1]),
                          int(grid.restitutions.size)),
        speeds_m_s=tuple(float(v) for v in grid.speeds), gap_law_source=src["gap_law"],
        speeds_source=src["speeds"],
        interp_rel_error={k: {"g_max": float(np.max(v["g"])), "e": float(v["e"]),
                              "speed": float(v["speed"])} for k, v in errs.items()},
        rows=len(meas), chains=len(meas.groups), scene=base.name,
        scene_hashes=grid.hashes, flags=tuple(flags), data_outside_model=mc.to_json(),
        posterior_g_m=fg, posterior_e=fe,
        posterior_pdf=pdf, marginal_g=mg, marginal_e=me, draws=draws, grid=grid)


def _law(base: Scene) -> str:
    if base.gap_distribution == "uniform":
        return "uniform on [0, 2 mean], i.i.d. per contact"
    return "exponential with the given mean, i.i.d. per contact"
