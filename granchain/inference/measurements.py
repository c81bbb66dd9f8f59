"""The measurements an inference reads: the CSV of one experiment
(:func:`read_measurements`; every problem one error naming the file, the row and the
column), its rows (:class:`Measurements`), what ``--fit`` names (:func:`parse_fit`,
:func:`fit_for`), and the checks of the rows against the base scene: striker speeds within
the simulated ones (:func:`check_speeds`), peaks its striker can give (:func:`check_peaks`).
The columns are described in the module doc of :mod:`granchain.inference`."""
from __future__ import annotations

import csv
import difflib
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..effects import physics_terms, touch_energy
from ..errors import GranchainError
from ..scene import Scene
from ..validate import short

TIMING_COLUMNS = ("dt_peak_s", "dt_front_s")
PEAK_COLUMNS = ("vmax_1_m_s", "vmax_2_m_s")     # measured peaks at the two probes (m/s)
COLUMNS = ("v_striker_m_s", *TIMING_COLUMNS, "dt_err_s", "chain_id", *PEAK_COLUMNS,
           "vmax_err_m_s")
FITS = ("gap_mean", "restitution")      # the joint fit of a damped scene (fit_for)
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
    """What ``--fit`` names: ``("gap_mean",)`` (the default), or ``("gap_mean", KEY)`` with
    KEY the path of a fittable scene key (``inference.fitkeys``; named by its path or its
    results' name: ``restitution`` is ``damping.e``). Every other value is one
    GranchainError naming --fit and the fittable keys."""
    from .fitkeys import fit_key, fittable_text
    names = [w.strip() for w in str(text).split(",")]
    for j, w in enumerate(names):
        if w in names[:j]:
            raise GranchainError(f"--fit: {short(w)} is named twice; name each parameter once")
    keys = [fit_key(w).path for w in names if w != "gap_mean"]
    for j, k in enumerate(keys):
        if k in keys[:j]:
            raise GranchainError(f"--fit: {k} is named twice (by its path and its name); "
                                 "name each parameter once")
    if keys and "gap_mean" not in names:
        raise GranchainError(f"--fit: {keys[0]} is fitted together with the mean gap (both "
                             "set the timing and the peaks); give --fit "
                             f"gap_mean,{names[0]}")
    if len(keys) > 1:
        raise GranchainError(f"--fit: one scene key is fitted beside the mean gap (got "
                             f"{', '.join(keys)}); give gap_mean,KEY with KEY one of "
                             f"{fittable_text()}")
    return ("gap_mean", *keys)


def fit_for(base: Scene, columns) -> tuple[str, ...]:
    """What to fit when nobody says (the workflow's inference rule): the mean gap and the
    restitution for a damped base scene (contact_damping, model coeff_restitution) whose
    measurement file has both peak columns (``columns``: its header), else the mean gap."""
    damped = ("contact_damping" in base.effects
              and base.setting("contact_damping").model == "coeff_restitution")
    if damped and all(c in columns for c in PEAK_COLUMNS):
        return FITS
    return ("gap_mean",)


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
    sqrt((b v_s)^2 + 2 W / m_p), b its ``peak_bounds`` and W the energy the contacts'
    attraction can add (``effects.touch_energy``: 0 without adhesion), plus PEAK_SIGMAS of
    its stated error (a peak measured just above an attainable value is noise, one far
    above it is not from this chain: a unit or a column mix-up)."""
    if meas.vmax_1 is None and meas.vmax_2 is None:
        return
    bounds = peak_bounds(base)
    W = touch_energy(physics_terms(base))
    m = base.masses
    for col, vals, bound, p in zip(PEAK_COLUMNS, (meas.vmax_1, meas.vmax_2), bounds,
                                   base.probes[:2]):
        if vals is None:
            continue
        for k, (x, vs, e, line) in enumerate(zip(vals, meas.v, meas.peak_err, meas.lines)):
            top = bound * vs if W == 0.0 else math.sqrt((bound * vs) ** 2 + 2.0 * W / m[p - 1])
            if math.isfinite(x) and x > top * (1 + PEAK_RTOL) + PEAK_SIGMAS * e:
                who = ("a striker of its mass" if bound == 1.0 else
                       f"the base scene's striker (at most {bound:.4g} v_s)")
                if W > 0.0:
                    who += f" and the contacts' adhesion (up to {W:.3g} J)"
                raise _bad(f"{source}row {k + 1} (line {line}), column {col!r}",
                           f"{x:g} m/s is above what {who} can give particle {p} at "
                           f"v_s = {vs:g} m/s ({top:g} m/s"
                           + (f" + {PEAK_SIGMAS:g} x vmax_err_m_s" if e > 0 else "") + ")",
                           "give the peak in m/s at the row's striker speed (not in units of "
                           "v_s or mm/s)")

