"""Observables of a chain, engine-neutral: they read a Trajectory, whatever produced it.

The rules are ``granchain.obsrules``' (which the engines' on-the-fly observables apply too).
Peak of particle i: v_max,i = max_t v_i(t), refined below the sample spacing:
- a sharp peak (at most PLATEAU_SAMPLES samples within PEAK_TOL of the maximum) is
  refined by the vertex of the parabola through the three samples around the maximum;
- a plateau (a particle flying freely across a gap keeps its velocity, so many samples
  lie within PEAK_TOL of the maximum) has an ill-defined maximum: its peak time is the
  start of the plateau, the first crossing of (1 - PEAK_TOL) v_max, linearly interpolated.
Arrival (front) time of particle i: first crossing of v_max,i / 2 on the rising edge,
linearly interpolated. It is defined whether the peak is sharp or a plateau.

A peak is reported only when it is *final* (``granchain.stoprule``: the wave has passed
an inner particle, the last particle has left): otherwise v_max, t_peak and t_front of
that particle are NaN and ``final`` is False for it. A maximum at the end of the record
is not a peak.

The chapter's observables: v_max,1 and v_max,2 are the peaks of the two probes (particles
2 and 13 by default), dt_peak the time between their peak times, and
v_g = (p2 - p1)(2R + gbar)/dt_peak with gbar the mean gap over the p2 - p1 contacts
between the probes (11 for the chapter's probes). ``v_g`` uses peak times, as the
chapter does; ``v_g_front`` uses arrival (half-peak) times and is the robust choice
for gapped chains; both are always reported, with ``plateau`` flags per particle. They
need both probes' peaks to be final; ``wave_arrived`` says whether they are.

Results are typed: :func:`summarize` returns a frozen :class:`ChainResult` (per-particle
values as tuples, the energy ledger as a frozen :class:`EnergyLedger` whose entries are
``ENERGY_COLUMNS`` plus initial, final_mechanical and balance_error).
``granchain.simulate.run_scene`` fills in the member fields with ``dataclasses.replace``.
``ChainResult.to_json`` is the JSON document of one run, ``ChainResult.to_row`` the run's
columns of the results table; the table's run-derived column names (``ENERGY_MAP``,
``vmax_columns``) are defined here, and ``granchain.tables`` uses them.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import collision, obsrules, stoprule
from .effects import SPECS
from .trajectory import ENERGY_COLUMNS, Trajectory

PEAK_TOL = stoprule.PEAK_TOL
PLATEAU_SAMPLES = stoprule.PLATEAU_SAMPLES


def _crossing(t, y, level, stop):
    """First time y crosses up through ``level`` at or before index ``stop``."""
    idx = np.flatnonzero(y[: stop + 1] >= level)
    if idx.size == 0:
        return math.nan
    j = int(idx[0])
    if j == 0:
        return float(t[0])
    return float(obsrules.crossing(t[j - 1], t[j], y[j - 1], y[j], level))


def peak(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, bool]:
    """(v_max, t_peak, t_front, plateau) of one sampled velocity history."""
    j = int(np.argmax(y))
    top = float(y[j])
    if not top > 0.0:
        return 0.0, math.nan, math.nan, False
    near = obsrules.near(y, top)
    # contiguous run of near-maximum samples containing j
    lo = j
    while lo > 0 and near[lo - 1]:
        lo -= 1
    hi = j
    while hi < len(y) - 1 and near[hi + 1]:
        hi += 1
    plateau = obsrules.plateau(hi - lo + 1)
    if not plateau and 0 < j < len(y) - 1:
        off, vmax = obsrules.vertex(float(y[j - 1]), top, float(y[j + 1]))
        h = float(t[j + 1] - t[j])
        tpk = float(t[j]) + off * h
    elif not plateau:
        vmax, tpk = top, float(t[j])
    else:
        vmax = top
        tpk = _crossing(t, y, obsrules.near_level(top), j)
    tfront = _crossing(t, y, obsrules.front_level(vmax), j)
    return float(vmax), float(tpk), tfront, bool(plateau)


def peak_final(traj: Trajectory, i: int) -> bool:
    """Is the peak of particle i (0-based) inside the record? (``granchain.stoprule``)"""
    y = traj.v[:, i]
    j = int(np.argmax(y))
    top = float(y[j])
    if not top > stoprule.arrival_speed(traj.v_striker):
        return False            # the wave never reached it
    if i == traj.n - 1 and traj.wall_force is None:
        return bool(stoprule.last_detached(y[-1], traj.last_overlap, traj.v_striker))
    # an inner particle, or the last one pressed against an end wall
    return stoprule.inner_passed(y[j + 1:], top)


def wall_peak(traj: Trajectory) -> tuple[float, float, bool]:
    """(F_max, t_peak, final) of the end wall's dynamic force F_w(t) - F_w(0): its
    maximum, refined by the parabola through the samples around it, and whether it is
    final (``stoprule.wall_passed``: the force has fallen below half its dynamic peak
    after it). NaN values when not final. Taken from the engine's on-the-fly measurement
    when the trajectory carries one (``traj.observed.wall_peak_final`` set)."""
    o = traj.observed
    if o is not None and o.wall_peak_final is not None:
        return float(o.wall_force_max), float(o.t_wall_peak), bool(o.wall_peak_final)
    F = np.asarray(traj.wall_force, dtype=float) - traj.wall_static
    j = int(np.argmax(F))
    top = float(F[j])
    if not (top > 0.0 and stoprule.wall_passed(F[j + 1:], top)):
        return math.nan, math.nan, False
    tpk = float(traj.t[j])
    if 0 < j < len(F) - 1:
        off, top = obsrules.vertex(float(F[j - 1]), top, float(F[j + 1]))
        tpk += off * float(traj.t[j + 1] - traj.t[j])
    return top, tpk, True


def peaks(traj: Trajectory):
    """(v_max, t_peak, t_front, plateau, final) of every particle; NaN where not final.
    Taken from the engine's on-the-fly measurement when the trajectory carries one
    (``traj.observed``), else from the samples (``sampled_peaks``)."""
    o = traj.observed
    if o is not None:
        return (np.array(o.v_max, dtype=float), np.array(o.t_peak, dtype=float),
                np.array(o.t_front, dtype=float), np.array(o.plateau, dtype=bool),
                np.array(o.final, dtype=bool))
    return sampled_peaks(traj)


def sampled_peaks(traj: Trajectory):
    """``peaks`` from the sampled trajectory alone."""
    cols = [peak(traj.t, traj.v[:, i]) for i in range(traj.n)]
    v_max, t_peak, t_front, plateau = (np.array(c, dtype=float) for c in zip(*cols))
    final = np.array([peak_final(traj, i) for i in range(traj.n)], dtype=bool)
    for a in (v_max, t_peak, t_front):
        a[~final] = math.nan
    return v_max, t_peak, t_front, plateau.astype(bool), final


# ---------------------------------------------------------------------------------------
# typed results
# ---------------------------------------------------------------------------------------
# Entries of the energy ledger: the engines' columns (from the effects registry), then the
# initial energy, the final mechanical energy and the balance error.
LEDGER_ENTRIES = ENERGY_COLUMNS + ("initial", "final_mechanical", "balance_error")


def _ledger_to_dict(self) -> dict[str, float]:
    """The ledger as a dict, in ``LEDGER_ENTRIES`` order (the JSON form)."""
    return {name: getattr(self, name) for name in LEDGER_ENTRIES}


# A frozen dataclass whose float fields are LEDGER_ENTRIES: an effect added to the registry
# adds its work field here. Read an entry as an attribute (``ledger.balance_error``), or
# ``getattr(ledger, name)`` for a name taken from ENERGY_COLUMNS.
EnergyLedger = dataclasses.make_dataclass(
    "EnergyLedger", [(name, float) for name in LEDGER_ENTRIES], frozen=True,
    namespace={"to_dict": _ledger_to_dict,
               "__doc__": "Energy ledger of one chain (J; balance_error relative to the "
                          "initial energy): the final value of every ENERGY_COLUMNS entry "
                          "(works: done on the particles by that effect from t = 0), the "
                          "initial energy, the final mechanical energy, the balance error."})
EnergyLedger.__module__ = __name__

# Results-table columns of a run (units in the names): the energy-ledger entries ->
# table columns (the works from the effects' declarations), and one v_max column per
# particle (``vmax_columns``). ``granchain.tables`` lays the table out with these.
ENERGY_MAP = {"energy_initial_J": "initial",
              **{s.table_column: s.work for s in SPECS.values() if s.work},
              "balance_error": "balance_error"}


# ChainResult fields of the vibrometer, and the table columns of a measured run (after
# the true observables; ``granchain.tables`` adds them to the tables of measured scenes).
MEASURED_FIELDS = ("measured", "v_max_1_measured", "v_max_2_measured", "dt_peak_measured",
                   "dt_front_measured", "v_g_measured", "v_g_front_measured",
                   "measured_not_final")
MEASURED_COLUMNS = ("v_max_1_measured_m_s", "v_max_2_measured_m_s", "v_max_ratio_measured",
                    "dt_peak_measured_s", "dt_front_measured_s", "v_g_measured_m_s",
                    "v_g_front_measured_m_s", "measured_not_final")


# ChainResult fields of the end wall, and the table columns of a walled scene's run
WALL_FIELDS = ("walled", "wall_force_max", "t_wall_peak", "wall_force_static",
               "wall_peak_final")
WALL_COLUMNS = ("wall_force_max_N", "t_wall_peak_s", "wall_force_static_N")
# ChainResult fields of a two-sphere collision (``granchain.collision``), and the table
# columns of a two-sphere scene's run
PAIR_FIELDS = ("pair", "collision", "captured", "restitution")
PAIR_COLUMNS = ("pair_collision", "pair_captured", "pair_restitution")


def vmax_columns(n: int) -> list[str]:
    """``vmax_p01_m_s`` ... one per particle, zero-padded to the width of n (at least 2)."""
    width = max(2, len(str(n)))
    return [f"vmax_p{i:0{width}d}_m_s" for i in range(1, n + 1)]


def vfinal_columns(n: int) -> list[str]:
    """``vfinal_p01_m_s`` ... one per particle, numbered as :func:`vmax_columns`."""
    return [c.replace("vmax_p", "vfinal_p", 1) for c in vmax_columns(n)]


def _ratio(a: float, b: float) -> float:
    return a / b if b > 0 and math.isfinite(a) and math.isfinite(b) else math.nan


@dataclass(frozen=True)
class ChainResult:
    """Observables of one chain (SI units; NaN where not measured), and, from
    ``simulate.run_scene``, which member of its scene it is and how it was run.

    Per particle (tuples of n, particle i at index i - 1): v_max, t_peak, t_front (NaN
    where the peak is not final), plateau, final. not_final: the particles (1-based)
    whose peak is not final. v_final: each particle's velocity at the end of the run (the
    last sample, t_end). probes: the probe particles (1-based). v_max_1, v_max_2,
    dt_peak, dt_front, v_g, v_g_front: the probes' observables (module docstring; NaN in
    a two-sphere scene, which has no probes); gap_mean_probes: mean gap between the
    probes (m). energy: the energy ledger.
    steps, rejected_steps: integration steps taken and rejected (adaptive, event);
    force_evaluations: right-hand-side (force routine) evaluations; wall_s: the
    engine's wall time of this chain; t_end: time of the last sample; samples: their count.

    Member fields (None or empty from ``summarize`` alone): member (index in the scene),
    realisation (gap realisation), engine, method, dt (the integrator's step, s),
    warnings (one-line physics warnings for this striker speed), batch_wall_s (wall
    time of the whole ``run_scene`` call).

    The field order is the key order of :meth:`to_json`.
    """
    v_striker: float
    wave_arrived: bool
    status: str
    v_max: tuple[float, ...]
    t_peak: tuple[float, ...]
    t_front: tuple[float, ...]
    plateau: tuple[bool, ...]
    final: tuple[bool, ...]
    not_final: tuple[int, ...]
    v_final: tuple[float, ...]
    probes: tuple[int, ...]
    v_max_1: float
    v_max_2: float
    dt_peak: float
    dt_front: float
    gap_mean_probes: float
    v_g: float
    v_g_front: float
    energy: EnergyLedger
    steps: int
    rejected_steps: int
    force_evaluations: int
    wall_s: float
    t_end: float
    samples: int
    member: int | None = None
    realisation: int | None = None
    engine: str | None = None
    method: str | None = None
    dt: float | None = None
    warnings: tuple[str, ...] = ()
    batch_wall_s: float | None = None
    # The vibrometer (``granchain.vibrometer``), set by run_scene for a scene with a
    # measurement block (measured True); otherwise None and left out of the JSON and the
    # table row. measured_not_final: the probes (1-based) whose recorded peak is not
    # final (its values, and the delays and v_g, are NaN).
    measured: bool = False
    v_max_1_measured: float | None = None
    v_max_2_measured: float | None = None
    dt_peak_measured: float | None = None
    dt_front_measured: float | None = None
    v_g_measured: float | None = None
    v_g_front_measured: float | None = None
    measured_not_final: tuple[int, ...] = ()
    # The end wall (walled True, a scene with walls.end; otherwise left out of the JSON
    # and the table row): wall_force_max, the peak of the wall's dynamic force (N, the
    # force less its static preload wall_force_static), at t_wall_peak (s); NaN with
    # wall_peak_final False when the run did not measure that peak.
    walled: bool = False
    wall_force_max: float | None = None
    t_wall_peak: float | None = None
    wall_force_static: float | None = None
    wall_peak_final: bool | None = None
    # A two-sphere collision (pair True, a scene of chain.n 2; otherwise left out of the
    # JSON and the table row): how it ended (``collision.OUTCOMES``), whether the pair
    # was captured, and the measured restitution (NaN unless separated)
    pair: bool = False
    collision: str | None = None
    captured: bool | None = None
    restitution: float | None = None
    # the fields (energy entries as ``energy.<entry>``) whose value left its physical
    # bounds (:func:`bounded`): NaN here, each with a line in ``warnings``
    out_of_bounds: tuple[str, ...] = ()

    @property
    def n(self) -> int:
        """Number of particles."""
        return len(self.v_max)

    def to_json(self) -> dict:
        """The JSON document of this run: a dict of plain Python values, keys in field
        order, tuples as lists, the ledger as a dict; the measured fields only for a
        measured run. Non-finite floats stay NaN/inf (the
        writer decides how to encode them; ``granchain run --json`` writes null)."""
        out = {}
        for f in dataclasses.fields(self):
            if not self.measured and f.name in MEASURED_FIELDS:
                continue
            if not self.walled and f.name in WALL_FIELDS:
                continue
            if not self.pair and f.name in PAIR_FIELDS:
                continue
            v = getattr(self, f.name)
            if isinstance(v, tuple):
                v = list(v)
            elif isinstance(v, EnergyLedger):
                v = v.to_dict()
            out[f.name] = v
        return out

    def to_row(self) -> dict:
        """This run's columns of the results table (``granchain.tables``): engine,
        method, dt_s, v_striker_m_s, realisation, status, wave_arrived, peaks_not_final,
        the probes' observables, gap_mean_probes_nm, the ``ENERGY_MAP`` columns, steps,
        warnings, the two-sphere collision's ``PAIR_COLUMNS``, ``vmax_columns(n)`` and
        ``vfinal_columns(n)``. Needs the member fields (``run_scene``)."""
        if self.realisation is None or self.dt is None:
            raise ValueError("a table row needs a run of simulate.run_scene (realisation "
                             "and dt are not set)")
        row = {
            "engine": self.engine,
            "method": self.method,
            "dt_s": float(self.dt),
            "v_striker_m_s": float(self.v_striker),
            "realisation": int(self.realisation),
            "status": self.status,
            "wave_arrived": bool(self.wave_arrived),
            # particles (1-based, ';'-separated) whose peak the run did not measure: their
            # vmax_p columns are NaN (granchain.stoprule)
            "peaks_not_final": ";".join(str(i) for i in self.not_final),
            "v_max_1_m_s": float(self.v_max_1),
            "v_max_2_m_s": float(self.v_max_2),
            "v_max_ratio": _ratio(float(self.v_max_2), float(self.v_max_1)),
            "dt_peak_s": float(self.dt_peak),
            "v_g_m_s": float(self.v_g),
            "v_g_front_m_s": float(self.v_g_front),
            "gap_mean_probes_nm": float(self.gap_mean_probes) * 1e9,
            "steps": int(self.steps),
            "force_evaluations": int(self.force_evaluations),
            "warnings": ";".join(self.warnings or ()),
        }
        for col, entry in ENERGY_MAP.items():
            row[col] = float(getattr(self.energy, entry))
        if self.measured:
            row.update(self.measured_row())
        if self.walled:
            row.update({"wall_force_max_N": float(self.wall_force_max),
                        "t_wall_peak_s": float(self.t_wall_peak),
                        "wall_force_static_N": float(self.wall_force_static)})
        if self.pair:
            row.update({"pair_collision": self.collision,
                        "pair_captured": bool(self.captured),
                        "pair_restitution": float(self.restitution)})
        for col, v in zip(vmax_columns(self.n), self.v_max):
            row[col] = float(v)
        for col, v in zip(vfinal_columns(self.n), self.v_final):
            row[col] = float(v)
        return row

    def measured_row(self) -> dict:
        """The ``MEASURED_COLUMNS`` of this run's table row (a measured run)."""
        return {
            "v_max_1_measured_m_s": float(self.v_max_1_measured),
            "v_max_2_measured_m_s": float(self.v_max_2_measured),
            "v_max_ratio_measured": _ratio(float(self.v_max_2_measured),
                                           float(self.v_max_1_measured)),
            "dt_peak_measured_s": float(self.dt_peak_measured),
            "dt_front_measured_s": float(self.dt_front_measured),
            "v_g_measured_m_s": float(self.v_g_measured),
            "v_g_front_measured_m_s": float(self.v_g_front_measured),
            "measured_not_final": ";".join(str(i) for i in self.measured_not_final),
        }


def energy_ledger(traj: Trajectory) -> EnergyLedger:
    """Energy ledger: final values, work by each effect, and the balance error.

    balance(t) = [E_kin,trans + E_kin,rot + E_hertz](t) - E(0) - sum of work done on the
    particles by the dissipative effects up to t; balance_error = max_t |balance| / E(0),
    over the samples, or when the trajectory carries on-the-fly observables
    (``traj.observed``) the engine's maximum over the states at its step ends (its
    samples may be the first and last states only, or interpolated between step ends).
    """
    e = traj.energy
    total = e[:, 0] + e[:, 1] + e[:, 2]
    work = e[:, 3:].sum(axis=1)
    e0 = float(total[0])
    bal = total - e0 - work
    out = {name: float(e[-1, i]) for i, name in enumerate(ENERGY_COLUMNS)}
    out["initial"] = e0
    out["final_mechanical"] = float(total[-1])
    out["balance_error"] = float(np.max(np.abs(bal)) / e0) if e0 > 0 else 0.0
    if traj.observed is not None:
        out["balance_error"] = float(traj.observed.balance_error)
    return EnergyLedger(**out)


def probe_span(traj: Trajectory, probes=(2, 13)) -> tuple[float, float]:
    """(gbar, span): the mean gap over the contacts between the probes and the probes'
    distance along the chain, (p2 - p1)(2R + gbar), in m; for spheres of different radii
    the sum of R_i + R_{i+1} + g_i over those contacts."""
    p1, p2 = probes[0], probes[1]
    gbar = float(np.mean(traj.gaps[p1 - 1:p2 - 1])) if p2 > p1 else 0.0
    if traj.radii is not None:
        R = np.asarray(traj.radii, dtype=float)
        span = float(np.sum(R[p1 - 1:p2 - 1] + R[p1:p2] + traj.gaps[p1 - 1:p2 - 1]))
        return gbar, span
    return gbar, (p2 - p1) * (2.0 * traj.radius + gbar)


def summarize(traj: Trajectory, probes=(2, 13), terms=None) -> ChainResult:
    """All observables of one chain (member fields unset: ``simulate.run_scene`` sets them).
    A two-sphere chain has no probes (its probe observables are NaN) and needs ``terms``,
    its physics (``effects.physics_terms``), for its collision (``granchain.collision``)."""
    v_max, t_peak, t_front, plateau, final = peaks(traj)
    p1, p2 = probes[0], probes[1]
    i1, i2 = p1 - 1, p2 - 1
    gbar, span = probe_span(traj, probes)
    pair = {}
    if traj.n == 2:
        if terms is None:
            raise ValueError("a two-sphere chain's collision needs its physics (terms)")
        c = collision.measure(traj.v_striker, traj.v[-1], traj.last_overlap, terms,
                              ended=traj.status in ("passed", "done"))
        pair = {"pair": True, "collision": c.collision, "captured": c.captured,
                "restitution": c.restitution}
    # both probes' peaks measured, by a run that did not fail numerically
    arrived = bool(traj.v_striker > 0 and final[i1] and final[i2] and not pair
                   and traj.status in ("passed", "done", "timeout"))
    wall = {}
    if traj.wall_force is not None:
        fmax, tw, wfinal = wall_peak(traj)
        wall = {"walled": True, "wall_force_max": fmax, "t_wall_peak": tw,
                "wall_force_static": float(traj.wall_static), "wall_peak_final": wfinal}
    dt_peak = float(t_peak[i2] - t_peak[i1]) if arrived else math.nan
    dt_front = float(t_front[i2] - t_front[i1]) if arrived else math.nan
    v_g = span / dt_peak if arrived and dt_peak > 0 else math.nan
    v_g_front = span / dt_front if arrived and dt_front > 0 else math.nan
    result = ChainResult(
        v_striker=float(traj.v_striker),
        wave_arrived=bool(arrived),
        status=str(traj.status),
        v_max=tuple(v_max.tolist()),
        t_peak=tuple(t_peak.tolist()),
        t_front=tuple(t_front.tolist()),
        plateau=tuple(plateau.tolist()),
        final=tuple(final.tolist()),
        not_final=tuple(i + 1 for i in range(traj.n) if not final[i]),
        v_final=tuple(float(x) for x in traj.v[-1]),
        probes=tuple(int(p) for p in probes),
        v_max_1=float(v_max[i1]) if not pair else math.nan,
        v_max_2=float(v_max[i2]) if not pair else math.nan,
        dt_peak=dt_peak,
        dt_front=dt_front,
        gap_mean_probes=gbar if not pair else math.nan,
        v_g=v_g,
        v_g_front=v_g_front,
        energy=energy_ledger(traj),
        steps=int(traj.steps),
        rejected_steps=int(traj.rejected),
        force_evaluations=int(traj.force_evaluations),
        wall_s=float(traj.wall_s),
        t_end=float(traj.t[-1]),
        samples=int(traj.t.size if traj.observed is None or traj.observed.samples is None
                    else traj.observed.samples),
        **wall, **pair,
    )
    return bounded(result, traj.limits)


# ---------------------------------------------------------------------------------------
# physical bounds
# ---------------------------------------------------------------------------------------
# statuses of a run that ended as planned; what any other means, for the human output
OK_STATUSES = ("passed", "done")
STATUS_TEXT = {
    "passed": "the run ended once the wave had left the chain",
    "done": "the run reached its end time",
    "timeout": "the run hit its time cap before the wave left the chain",
    "nonfinite": "the integration reached a non-finite state",
    "stepfail": "the adaptive step control failed",
    "unphysical": "a value left its physical bounds (see the warning)",
}


def status_text(status: str) -> str:
    """'status timeout: the run hit its time cap ...': a status for the human output."""
    return f"status {status}" + (f": {STATUS_TEXT[status]}" if status in STATUS_TEXT else "")


def status_summary(statuses) -> str:
    """For a progress or log line over many runs: '' when every run ended as planned
    (``OK_STATUSES``), else e.g. '2 of 8 runs ended timeout (1), unphysical (1)'."""
    statuses = list(statuses)
    bad: dict[str, int] = {}
    for s in statuses:
        if s not in OK_STATUSES:
            bad[s] = bad.get(s, 0) + 1
    if not bad:
        return ""
    return (f"{sum(bad.values())} of {len(statuses)} runs ended "
            + ", ".join(f"{s} ({k})" for s, k in sorted(bad.items())))


# (delay, group velocity) pairs: a delay that is not positive, or a group velocity above
# the sound speed, makes both impossible (v_g = span / delay)
_TIMING_PAIRS = (("dt_peak", "v_g"), ("dt_front", "v_g_front"),
                 ("dt_peak_measured", "v_g_measured"), ("dt_front_measured", "v_g_front_measured"))
_SPEEDS = ("v_max_1", "v_max_2", "v_max_1_measured", "v_max_2_measured", "wall_force_max",
           "t_wall_peak", "wall_force_static", "restitution")


def bounded(r: ChainResult, limits=None) -> ChainResult:
    """``r`` with every value outside its physical bounds set to NaN, named in
    ``out_of_bounds`` and explained by a one-line warning naming the scene key most
    likely at fault (``limits``: ``guards.Limits``; None checks only what needs no
    scene). Bounds: a delay between the probes must be positive, a group velocity at
    most ``limits.sound_speed`` (both of a pair are dropped when either fails), every
    velocity, force and time finite, every energy-ledger entry finite. A run that ended
    as planned (``OK_STATUSES``) but failed a bound gets status ``unphysical``; a run
    whose engine reported a non-finite state or a failed step gets the line too. The
    check is idempotent: applying it again changes nothing."""
    bad: dict[str, list[str]] = {"fast": [], "order": [], "nonfinite": []}
    change: dict = {}
    shown: dict[str, float] = {}

    def drop(kind: str, *names: str) -> None:
        for name in names:
            shown.setdefault(name, getattr(r, name))
            change[name] = math.nan
            if name not in bad[kind]:
                bad[kind].append(name)

    for dt_name, vg_name in _TIMING_PAIRS:
        dt, vg = getattr(r, dt_name), getattr(r, vg_name)
        if dt is None:
            continue
        if math.isinf(dt) or math.isinf(vg):
            drop("nonfinite", dt_name, vg_name)
        elif math.isfinite(dt) and dt <= 0.0:
            drop("order", dt_name, vg_name)
        elif limits is not None and math.isfinite(vg) and vg > limits.sound_speed:
            drop("fast", vg_name, dt_name)
    for name in _SPEEDS:
        x = getattr(r, name)
        if x is not None and math.isinf(x):
            drop("nonfinite", name)
    per_particle = {}
    for name in ("v_max", "t_peak", "t_front", "v_final"):
        vals = getattr(r, name)
        if any(math.isinf(x) for x in vals):
            per_particle[name] = tuple(math.nan if math.isinf(x) else x for x in vals)
            bad["nonfinite"].append(name)
    ledger = {}
    for entry, x in r.energy.to_dict().items():
        if not math.isfinite(x):
            ledger[entry] = math.nan
            bad["nonfinite"].append(f"energy.{entry}")
    failed = r.status in ("nonfinite", "stepfail")
    if not any(bad.values()) and not failed:
        return r
    lines = []
    head = f"v_s = {r.v_striker:g} m/s: "
    if bad["fast"]:
        names = [n for n in bad["fast"] if n.startswith("v_g")]
        vals = " and ".join(f"{n} = {shown[n]:.3g} m/s" for n in names)
        lines.append(f"{head}{vals} above the bar sound speed {limits.sound_speed:.3g} m/s of "
                     f"{limits.material} (sqrt(E/rho)) is impossible: "
                     f"{' and '.join(bad['fast'])} not reported (NaN) - check "
                     f"{limits.fast}")
    if bad["order"]:
        names = [n for n in bad["order"] if n.startswith("dt")]
        vals = " and ".join(f"{n} = {shown[n]:.3g} s" for n in names)
        lines.append(f"{head}{vals}: a wave cannot reach probe {r.probes[1]} before probe "
                     f"{r.probes[0]}: {' and '.join(bad['order'])} not reported (NaN) - check "
                     + (limits.order if limits is not None else "the scene"))
    if bad["nonfinite"] or failed:
        what = (f"the run ended with status {r.status}" if failed else "")
        if bad["nonfinite"]:
            what += (" and " if what else "") + f"{' and '.join(bad['nonfinite'])} not " \
                    "finite (NaN)"
        lines.append(f"{head}{what} - check "
                     + (limits.nonfinite if limits is not None else "the scene"))
    if ledger:
        change["energy"] = dataclasses.replace(r.energy, **ledger)
    names = tuple(n for kind in ("fast", "order", "nonfinite") for n in bad[kind])
    new = tuple(w for w in lines if w not in r.warnings)
    return dataclasses.replace(
        r, **change, **per_particle,
        status="unphysical" if r.status in OK_STATUSES else r.status,
        out_of_bounds=r.out_of_bounds + tuple(n for n in names if n not in r.out_of_bounds),
        warnings=tuple(r.warnings) + new)
