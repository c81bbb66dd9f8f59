"""The mean gap of a chain inferred from measured wave timing (``granchain infer``).

Input: a CSV of measurements (SI units) -- ``v_striker_m_s``, one timing column
(``dt_peak_s``: peak-to-peak delay between the two probes, or ``dt_front_s``: half-peak
arrival delay), optional ``dt_err_s`` (one-sigma Gaussian error of that timing) and
optional ``chain_id`` (rows with the same id were measured on one assembled chain and share
one gap realisation) -- and a base scene (material, radius, n, probes, effects, integrator,
the gap law's shape in its ``gaps:`` block, the simulated striker speeds in
``striker.velocity``).

Method: a grid posterior over the gap law's mean, with a likelihood built from simulated
ensembles (never from Eq. 5.4).

- Grid: mean gaps ``0, dg, ..., gap_max`` x the base scene's striker speeds x R gap
  realisations, each grid cell one scene derived from the base scene (``Scene.derive``)
  and run through ``simulate.run_scene``. Realisation r draws the same normalised gap
  pattern at every mean gap (common random numbers, ``granchain.gaps``): for a uniform or
  exponential law its gaps are exactly ``mean x pattern_r``, so the timing of realisation
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
  ``L = (1/R) sum_r N(t; T_r(g), C)`` -- the average over realisations of the joint density
  of the group's rows. The kernel is multivariate because one realisation's timings at
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

Which simulated timing a CSV column is compared with is decided in one place,
:func:`timing`.
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
from .gaps import Member
from .scene import Scene

TIMING_COLUMNS = ("dt_peak_s", "dt_front_s")
COLUMNS = ("v_striker_m_s", *TIMING_COLUMNS, "dt_err_s", "chain_id")
GAP_LAWS = ("uniform", "exponential")     # laws whose realisations scale with their mean
CACHE_FORMAT = 1                          # bump when the cached arrays change meaning
FINE_POINTS = 801                         # posterior evaluation points over [0, gap_max]
EDGE_WEIGHT = 1e-2        # posterior density at gap_max, relative to its peak, that flags
PRIOR = "scale"
PRIOR_G0 = 2e-9
SPEED_RTOL = 1e-9         # a row's speed may exceed the simulated range by this (rounding)


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

    def __len__(self) -> int:
        return int(self.v.size)

    @property
    def groups(self) -> list[np.ndarray]:
        return [np.flatnonzero(self.group == k) for k in range(int(self.group.max()) + 1)]


def _bad(where: str, problem: str, fix: str) -> GranchainError:
    return GranchainError(f"{where}: {problem}; {fix}")


def _number(text: str, where: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise _bad(where, f"{text!r} is not a number", "give a number in SI units") from None
    if not math.isfinite(x):
        raise _bad(where, f"{text!r} is not a finite number", "give a measured value or drop the row")
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


def read_measurements(path) -> Measurements:
    """Read and check a measurement CSV (module doc). Lines starting with '#' are comments.
    Every problem is one GranchainError naming the file and the column or row."""
    name = str(path)
    text = _read_text(path, name)
    lines = [(k + 1, ln) for k, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise _bad(name, "the file is empty", "give a header line (v_striker_m_s, dt_peak_s or "
                   "dt_front_s, optional dt_err_s, chain_id) and at least one row")
    try:
        rows = list(csv.reader(io.StringIO("\n".join(ln for _, ln in lines)), strict=True))
    except csv.Error as exc:
        raise _bad(name, f"is not a valid CSV file ({exc})",
                   "give comma-separated values with balanced quotes") from None
    header = [h.strip() for h in rows[0]]
    for h in header:
        if h not in COLUMNS:
            close = difflib.get_close_matches(h, COLUMNS, n=1)
            raise _bad(f"{name}, column {h!r}", "unknown column",
                       f"did you mean {close[0]!r}?" if close else f"use {', '.join(COLUMNS)}")
    for j, h in enumerate(header):
        if h in header[:j]:
            raise _bad(f"{name}, column {h!r}", f"given twice (header cells {header.index(h) + 1} "
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
    if len(rows) < 2:
        raise _bad(name, "no data rows under the header", "add at least one measurement")
    v, t, err, ids, where_lines = [], [], [], [], []
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
        cid = cell.get("chain_id", "") or None
        v.append(vs), t.append(dt), err.append(e), ids.append(cid), where_lines.append(line)
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
    return Measurements(np.array(v), np.array(t), np.array(err), np.array(group, dtype=int),
                        col, tuple(where_lines), tuple(ids))


# ---------------------------------------------------------------------------------------
# the simulated grid
# ---------------------------------------------------------------------------------------
def timing(result, column: str) -> float:
    """The simulated timing that a measurement's ``column`` is compared with: the chain's
    true peak-to-peak (``dt_peak_s``) or half-peak arrival (``dt_front_s``) delay between
    the probes. This is the one place that chooses between true and instrument timing."""
    return {"dt_peak_s": result.dt_peak, "dt_front_s": result.dt_front}[column]


def check_base(base: Scene) -> None:
    """A base scene the inference can use: a gap law with a mean that scales its
    realisations, and a fixed set of striker speeds."""
    from .errors import SceneError
    if base.gap_distribution not in GAP_LAWS:
        raise SceneError("gaps.distribution", f"'{base.gap_distribution}' has no mean gap to "
                         "infer", f"use one of {', '.join(GAP_LAWS)} (mean: any value; the "
                         "inference sets it)")


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

    @property
    def realisations(self) -> int:
        return int(next(iter(self.timings.values())).shape[2])

    @property
    def n_chains(self) -> int:
        return int(self.gaps.size * self.speeds.size * self.realisations)


def _cache_file(cache_dir: Path, scene: Scene) -> Path:
    """One grid point's timings, keyed by its scene and by the package's source (a grid
    simulated by other code is never reused)."""
    from .fileio import source_hash
    return Path(cache_dir) / f"grid-{scene.hash}-{source_hash()[:12]}-v{CACHE_FORMAT}.npz"


def simulate_grid(base: Scene, gap_max: float, gap_points: int, realisations: int,
                  cache_dir=None, engine: str = "reference") -> Grid:
    """Simulate (or read from ``cache_dir``) the grid of mean gaps
    ``linspace(0, gap_max, gap_points)`` x the base scene's speeds x ``realisations``."""
    from .costmodel import resolve_auto
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
    gaps = np.linspace(0.0, gap_max, gap_points)
    out = {c: np.full((gaps.size, speeds.size, realisations), np.nan) for c in TIMING_COLUMNS}
    hashes, simulated = [], 0
    for k, g in enumerate(gaps):
        scene = resolve_auto(grid_scene(base, g, realisations))
        hashes.append(scene.hash)
        path = _cache_file(cache_dir, scene) if cache_dir is not None else None
        if path is not None and path.exists():
            with np.load(path) as z:
                for c in TIMING_COLUMNS:
                    out[c][k] = z[c]
            continue
        res = run_scene(scene, engine=engine)
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
    return Grid(gaps, speeds, out, tuple(hashes), simulated)


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


def check_speeds(meas: Measurements, grid: Grid, source: str = "") -> None:
    """Every row's striker speed must lie within the simulated speeds."""
    lo, hi = grid.speeds[0], grid.speeds[-1]
    for k, (v, line) in enumerate(zip(meas.v, meas.lines)):
        if v < lo * (1 - SPEED_RTOL) or v > hi * (1 + SPEED_RTOL):
            rng = f"{lo:g} m/s" if lo == hi else f"{lo:g}-{hi:g} m/s"
            raise _bad(f"{source}row {k + 1} (line {line}), column 'v_striker_m_s'",
                       f"{v:g} m/s is outside the simulated striker speeds ({rng})",
                       "add speeds to the base scene's striker.velocity list so they "
                       "bracket every row")


def log_likelihood(grid: Grid, meas: Measurements, fine: np.ndarray,
                   model_rel: float = 0.0) -> np.ndarray:
    """log L(g) at every mean gap of ``fine`` (module doc), shape (F,)."""
    T = _interp_gap(grid.timings[meas.column], grid.gaps, fine)         # (F, S, R)
    R = T.shape[2]
    total = np.zeros(fine.size)
    for idx in meas.groups:
        m = idx.size
        P = np.stack([_interp_speed(T, grid.speeds, float(meas.v[i])) for i in idx], axis=-1)
        t = meas.t[idx]                                                   # (m,)
        ok = np.all(np.isfinite(P), axis=-1)                              # (F, R)
        n_ok = ok.sum(axis=1)                                             # (F,)
        X = np.where(ok[..., None], P, 0.0)
        mean = X.sum(axis=1) / np.maximum(n_ok, 1)[:, None]               # (F, m)
        D = np.where(ok[..., None], P - mean[:, None, :], 0.0)
        cov = np.einsum("fri,frj->fij", D, D) / np.maximum(n_ok - 1, 1)[:, None, None]
        factor2 = ((R * (m + 2)) / 4.0) ** (-2.0 / (m + 4))               # Silverman^2
        var = meas.err[idx] ** 2 + (model_rel * t) ** 2 + (1e-9 * t) ** 2
        C = factor2 * cov + np.diag(var)[None]
        L = np.linalg.cholesky(C)                                          # (F, m, m)
        resid = np.where(ok[..., None], t[None, None, :] - P, 0.0)         # (F, R, m)
        Z = np.linalg.solve(L, np.swapaxes(resid, 1, 2))                   # (F, m, R)
        logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
        lp = (-0.5 * (Z * Z).sum(axis=1) - 0.5 * logdet[:, None]
              - 0.5 * m * math.log(2 * math.pi))                            # (F, R)
        lp = np.where(ok, lp, -np.inf)
        top = lp.max(axis=1)
        with np.errstate(invalid="ignore"):
            ll = top + np.log(np.exp(lp - top[:, None]).sum(axis=1)) - math.log(R)
        total += np.where(n_ok >= 2, ll, -np.inf)
    return total


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
    interp_rel_error: float
    rows: int
    chains: int
    scene: str
    scene_hashes: tuple[str, ...]
    flags: tuple[str, ...]
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
    span = probes[1] - probes[0]
    T0 = grid.timings[meas.column][0]                                     # (S, R) packed
    dt0 = np.array([float(np.nanmedian(_interp_speed(T0, grid.speeds, float(v))))
                    for v in meas.v])
    y = meas.t - dt0
    x = span / meas.v
    rows = meas.v * y / span
    fit = float(np.sum(x * y) / np.sum(x * x)) if np.all(np.isfinite(y)) else math.nan
    return fit, float(np.min(rows)), rows


def infer(base: Scene, meas: Measurements, *, gap_max: float = 250e-9, gap_points: int = 26,
          realisations: int = 64, cache_dir=None, grid: Grid | None = None,
          source: str = "", prior: str = PRIOR) -> Inference:
    """Infer the mean gap (module doc) from ``meas`` with the base scene's model; a given
    ``grid`` is used as is (it must come from ``simulate_grid`` on this base scene)."""
    check_base(base)
    if grid is None:
        grid = simulate_grid(base, gap_max, gap_points, realisations, cache_dir)
    check_speeds(meas, grid, source)
    fine = np.linspace(0.0, float(grid.gaps[-1]), FINE_POINTS)
    rel = interp_rel_error(grid, meas.column)
    logpost = log_likelihood(grid, meas, fine, rel) + log_prior(fine, prior)
    pdf, med, lo, hi, flags = posterior_summary(fine, logpost)
    fit, bound, rows = eq54_gaps(grid, meas, base.probes)
    return Inference(
        gap_mean_m=med, ci95_m=(lo, hi), eq54_gap_m=fit, eq54_gap_bound_m=bound,
        eq54_gap_rows_m=tuple(float(r) for r in rows), n_simulated=grid.n_chains,
        n_simulated_now=grid.simulated, gap_law=_law(base), timing_column=meas.column,
        method="grid posterior, simulated-ensemble kernel likelihood",
        realisations=grid.realisations,
        gap_grid_m=(float(grid.gaps[0]), float(grid.gaps[-1]), int(grid.gaps.size)),
        speeds_m_s=tuple(float(v) for v in grid.speeds), interp_rel_error=rel,
        rows=len(meas), chains=len(meas.groups), scene=base.name,
        scene_hashes=grid.hashes, flags=tuple(flags), posterior_g_m=fine, posterior_pdf=pdf,
        grid=grid)


def _law(base: Scene) -> str:
    if base.gap_distribution == "uniform":
        return "uniform on [0, 2 mean], i.i.d. per contact"
    return "exponential with the given mean, i.i.d. per contact"
