"""Cross-validation: the same scene through the reference engine and LAMMPS.

``compare(scene)`` runs every member of the scene through the reference engine with
velocity Verlet at the LAMMPS time step (the scene's dt) and through one batched LAMMPS
run, on the same sample grid, and returns a :class:`Comparison` whose ``rows`` (a pandas
DataFrame, one row per member and quantity) hold both values, their difference, the
tolerance it must meet and why. ``granchain compare`` formats it; the workflow reuses it.

Both engines apply the same laws (docs/explanation/lammps_laws.md) with the same
integrator and step, so they differ by rounding only. The tolerances below are about 10x
the largest disagreement measured on every scene the tests compare, the tiny and
default presets' lammps_check scenes and two large ensembles (1000 chains with every
effect at 0.1 m/s and 20 nm gaps; 200 at 0.01 m/s and 190 nm, the slowest and longest
runs, where rounding grows most); each constant states its measured maximum. Rounding is
far below the physics they guard: a missing groove friction or air drag term changes
v_max by ~1e-4 over one pass of the wave.

A scene with an end wall (``walls.end``) adds the wall's observables
(``granchain.observables.wall_peak``): the peak of its dynamic force ``wall_force_max``
and the time of that peak ``t_wall_peak`` (both NaN, and equal, when neither engine saw
the peak end), and its static force ``wall_force_static`` (the preload F0, 0 without
one).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .collision import terms_of
from .effects import residual_work
from .errors import GranchainError
from .observables import OK_STATUSES, status_text, summarize
from .runplan import plan_run
from .stoprule import arrival_speed
from .scene import Scene
from .trajectory import ENERGY_COLUMNS

# Largest disagreement measured (reference velocity Verlet against LAMMPS 22 Jul 2025,
# one rank; the scenes of the module doc), and the tolerance about 10x above it:
V_TOL = 3e-8       # relative, v_max of every particle, v_max_1, v_max_2, v_g, v_g_front:
#                    measured 3.5e-9 (v_max of the last sphere, preloaded chain at 0.01 m/s)
TRAJ_TOL = 5e-7    # max |v_lammps - v_reference| / v_s over every particle and sample:
#                    measured 5.0e-8 (190 nm gaps at 0.01 m/s: the record after many
#                    contacts opened and closed carries each closing time's rounding)
T_TOL = 1e-8       # relative, dt_peak, dt_front, t_wall_peak: measured 1.2e-9
E_TOL = 5e-8       # |difference| / E0, every energy-ledger entry: measured 7.3e-9 E0
W_TOL = 2e-8       # relative, the end wall's force, dynamic peak and static preload:
#                    measured 2.0e-9 (the peak, 20 nm gaps at 0.01 m/s); the static force 2e-14

WHY_V = ("not the 1e-3 of a loose cross-check: same law and Verlet, rounding only (measured <= 3.5e-9); "
         "1e-3 would miss a dropped groove/drag term (~1e-4)")
WHY_TRAJECTORY = ("the whole record (LAMMPS text dump read with MDAnalysis): same law, Verlet "
                  "and sample grid, rounding only (measured <= 5.0e-8 v_s)")
WHY_FINAL = ("the last sample of the record: it carries the rounding of the whole run, as "
             "the trajectory row does")
WHY_T = "same integrator and sample grid: peak times differ by rounding only (measured <= 1.2e-9)"
WHY_E = ("same steps: rounding only (measured <= 7.3e-9 E0); 5e-8 E0 still resolves "
         "the groove (~1e-3 E0) and drag (~1e-4 E0) works")
WHY_SAMPLES = "both engines must stop on the same sample (same grid, same stop rule)"
WHY_RESIDUAL = ("not independent: LAMMPS has no per-atom output of these works (contact "
                "friction, contact damping); their sum is the residual of its energy balance")
WHY_BALANCE_RESIDUAL = "not independent: the LAMMPS ledger balances by construction (residual)"
WHY_BALANCE = "both balances carry the same Verlet error"
WHY_WALL = ("same wall law (LAMMPS fix wall/gran, docs/explanation/lammps_laws.md 12) and "
            "Verlet: rounding only (measured <= 2.0e-9); 2e-8 still resolves the 2e-4 of mixing the wall's E "
            "and nu apart")
WHY_WALL_T = "same integrator and sample grid: the wall's peak time differs by rounding only"
WHY_WALL_STATIC = ("the preload F0 both engines start from (rounding only, measured 2e-14); "
                   "relative to the larger of it and the dynamic peak, as an unloaded wall's is 0")


# the columns of Comparison.rows: one row per member and quantity
ROW_COLUMNS = ("member", "realisation", "v_striker", "quantity", "reference", "lammps", "diff",
               "measure", "tolerance", "ok", "why")


@dataclass
class Comparison:
    scene: Scene                  # the scene as compared (verlet, fixed sample grid)
    rows: "object"                # pandas.DataFrame
    meta: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        checked = self.rows[self.rows["ok"].notna()]
        return bool(checked["ok"].astype(bool).all())

    def failures(self):
        return self.rows[self.rows["ok"].eq(False)]

    def worst(self):
        """The worst row of each quantity over the members (largest diff / tolerance;
        failed rows first)."""
        df = self.rows.copy()
        score = []
        for d, t, ok in zip(df["diff"], df["tolerance"], df["ok"]):
            if ok is False:
                score.append(math.inf)
            elif t is None or not (isinstance(t, float) and math.isfinite(t)):
                score.append(-1.0 if d is None or not math.isfinite(d) else d)
            else:
                score.append(d / t if t > 0 else d)
        df["_score"] = score
        idx = df.groupby("quantity", sort=False)["_score"].idxmax()
        return df.loc[idx].drop(columns="_score").reset_index(drop=True)


def comparison_scene(scene: Scene) -> Scene:
    """The scene both engines run: velocity Verlet, and the LAMMPS deck's sample grid
    (its finest member's) fixed for every member, so the two records share one grid.
    A scene with method auto is resolved first (its step is the one compared)."""
    from .lammps.deck import plan
    from .gaps import member_gaps, members
    run_plan = plan_run(scene, per_speed=False)
    scene = run_plan.scene
    mem = members(scene)
    pl = plan(scene, gaps=member_gaps(scene, mem), v_striker=[m.v_striker for m in mem],
              run_plan=run_plan)
    return scene.derive(**{"integrator.method": "verlet", "output.sample_dt": pl.sample_dt})


def compare(scene: Scene, *, nprocs: int = 1, workdir=None, force: bool = False,
            keep: bool = False, trajectory: bool = False, traces: int = 0) -> Comparison:
    """Run both engines on every member of ``scene`` and tabulate the differences (a
    scene with method auto: resolved; ``meta["scene_hash"]`` is the resolved scene's).

    The reference engine measures every member's observables on the fly (the same values,
    bit for bit, as summarising its sample record), so it holds no records.
    ``traces``: the first that many members are also run with their sample record, and
    each gets a row comparing the whole trajectories, every particle's v(t) at every
    sample, against LAMMPS' record. ``trajectory``: every member gets that row, and
    LAMMPS writes its full text dump, read with MDAnalysis."""
    import pandas as pd

    from .engines import lammps as lmp_engine
    from .engines import reference
    from .gaps import member_gaps, member_radii, members

    scene = plan_run(scene, per_speed=False).scene
    cs = comparison_scene(scene)
    cplan = plan_run(cs)                  # both engines run from the one plan
    mem = members(cs)
    if not mem:
        raise GranchainError("compare: the scene has no members (no striker speed)")
    gaps = member_gaps(cs, mem)
    vs = np.array([m.v_striker for m in mem])
    radii = member_radii(cs, mem)          # each member's own under a radius spread
    k = len(mem) if trajectory else max(0, min(int(traces), len(mem)))
    t0 = time.perf_counter()
    try:
        ref = list(reference.run(cs, gaps, vs, method="verlet", dt=cs.dt, progress=False,
                                 trace=trajectory, radii=radii, plan=cplan))
        # a member re-run alone gives the same bits, so its record belongs to ref[i]
        traced = ref[:k] if trajectory else list(reference.run(
            cs, gaps[:k], vs[:k], method="verlet", dt=cs.dt, progress=False, trace=True,
            radii=None if radii is None else radii[:k], plan=cplan)) if k else []
    except NotImplementedError as exc:
        raise GranchainError(f"compare: the reference engine cannot run this scene: {exc}") from None
    t1 = time.perf_counter()
    lmp = list(lmp_engine.run(cs, gaps, vs, nprocs=nprocs, workdir=workdir, force=force,
                              keep=keep, progress=False, radii=radii, plan=cplan,
                              output="dump" if trajectory else "binary"))
    t2 = time.perf_counter()
    rows, status, notes = [], {"reference": [], "lammps": []}, []
    for i, (m, r, lt) in enumerate(zip(mem, ref, lmp)):
        results = (summarize(r, cs.probes, terms_of(cs, r)),
                   summarize(lt, cs.probes, terms_of(cs, lt)))
        for row in member_rows(cs, r, lt, trace=traced[i] if i < k else None,
                               results=results):
            rows.append(dict(member=m.index, realisation=m.realisation, v_striker=m.v_striker,
                             **row))
        # a status other than passed or done, and the bounds' lines, of either engine
        for engine, s in zip(status, results):
            status[engine].append(s.status)
            if s.status not in OK_STATUSES:
                notes.append(f"member #{m.index} {engine}: {status_text(s.status)}")
            notes += [f"member #{m.index} {engine}: {w}" for w in s.warnings]
    df = pd.DataFrame(rows, columns=list(ROW_COLUMNS))
    meta = {"scene": scene.name, "scene_hash": scene.hash, "compared_scene_hash": cs.hash,
            "chains": len(mem), "traced_chains": k, "dt": cs.dt, "sample_dt": lmp[0].info.sample_dt,
            "nprocs": nprocs, "reference_wall_s": t1 - t0, "lammps_wall_s": t2 - t1,
            "lammps_output": "dump (MDAnalysis)" if trajectory else "binary",
            "lammps_version": lmp[0].info.lammps_version,
            "balance": lmp[0].info.balance, "deck": lmp[0].info.deck,
            "tolerances": {"v": V_TOL, "t": T_TOL, "energy_over_E0": E_TOL},
            "status": status, "warnings": notes}
    if k:
        meta["tolerances"]["trajectory_over_v_s"] = TRAJ_TOL
    if cs.wall is not None:
        meta["tolerances"]["wall_force"] = W_TOL
    return Comparison(cs, df, meta)


def _rel(a: float, b: float, floor: float) -> float:
    if not (math.isfinite(a) and math.isfinite(b)):
        return 0.0 if (math.isnan(a) and math.isnan(b)) else math.inf
    return abs(b - a) / max(abs(a), floor)


def _row(q, a, b, diff, measure, tol, why):
    ok = None if tol is None else bool(diff <= tol)
    return {"quantity": q, "reference": a, "lammps": b, "diff": diff, "measure": measure,
            "tolerance": tol, "ok": ok, "why": why}


def wall_rows(sr, sl) -> list[dict]:
    """Rows of the end wall's observables of one member (two ChainResults): the dynamic
    peak force and its time (NaN on both sides, when neither run measured the peak,
    compares equal; on one side only it fails), and the static force, relative to the
    larger of itself and the reference's dynamic peak (an unloaded wall's is 0). With
    contact damping both engines record the net force F_el + eta w at each sample's
    state."""
    if not (sr.walled and sl.walled):
        return [_row("wall_force_max", sr.wall_force_max, sl.wall_force_max, math.inf, "rel",
                     W_TOL, "one engine has no end wall")]
    fa, fb = sr.wall_force_max, sl.wall_force_max
    ta, tb = sr.wall_force_static, sl.wall_force_static
    scale = fa if math.isfinite(fa) else 0.0
    return [_row("wall_force_max", fa, fb, _rel(fa, fb, 0.0), "rel", W_TOL, WHY_WALL),
            _row("t_wall_peak", sr.t_wall_peak, sl.t_wall_peak,
                 _rel(sr.t_wall_peak, sl.t_wall_peak, 0.0), "rel", T_TOL, WHY_WALL_T),
            _row("wall_force_static", ta, tb, _rel(ta, tb, max(scale, 1e-300)), "rel",
                 W_TOL, WHY_WALL_STATIC)]


def member_rows(scene: Scene, ref, lmp, *, trace=None, results=None) -> list[dict]:
    """Rows of one member: both runs' observables side by side (``ref`` may have measured
    them on the fly; ``lmp`` holds LAMMPS' sample record). ``trace``: the reference's
    sample record of this member (``ref`` itself if it has one), adding the row of the
    trajectories themselves, max |v_lammps - v_reference| / v_s over every particle and
    sample. ``results``: both runs' ``summarize``, if the caller has them."""
    sr, sl = results or (summarize(ref, scene.probes, terms_of(scene, ref)),
                         summarize(lmp, scene.probes, terms_of(scene, lmp)))
    vfloor = arrival_speed(max(ref.v_striker, 1e-300))
    out = [_row("samples", sr.samples, sl.samples, float(abs(sr.samples - sl.samples)),
                "exact", 0.0, WHY_SAMPLES)]
    if trace is not None:
        same = trace.v.shape == lmp.v.shape
        dv = float(np.max(np.abs(lmp.v - trace.v))) if same and trace.v.size else math.inf
        out.append(_row("v(t), every particle", math.nan, math.nan,
                        dv / max(trace.v_striker, 1e-300) if same else math.inf, "max/v_s",
                        TRAJ_TOL, WHY_TRAJECTORY))
    for i, (a, b) in enumerate(zip(sr.v_max, sl.v_max)):
        out.append(_row(f"v_max[{i + 1}]", a, b, _rel(a, b, vfloor), "rel", V_TOL, WHY_V))
    dvf = float(np.max(np.abs(np.subtract(sl.v_final, sr.v_final))))
    out.append(_row("v_final, every particle", math.nan, math.nan,
                    dvf / max(ref.v_striker, 1e-300), "max/v_s", TRAJ_TOL, WHY_FINAL))
    if sr.pair or sl.pair:
        a, b = sr.restitution, sl.restitution
        out.append(_row("restitution", a, b, _rel(a, b, 0.0), "rel", V_TOL, WHY_V))
    for q, a, b in (("v_max_1", sr.v_max_1, sl.v_max_1), ("v_max_2", sr.v_max_2, sl.v_max_2)):
        out.append(_row(q, a, b, _rel(a, b, vfloor), "rel", V_TOL, WHY_V))
    for q, a, b in (("dt_peak", sr.dt_peak, sl.dt_peak), ("dt_front", sr.dt_front, sl.dt_front)):
        out.append(_row(q, a, b, _rel(a, b, 0.0), "rel", T_TOL, WHY_T))
    for q, a, b in (("v_g", sr.v_g, sl.v_g), ("v_g_front", sr.v_g_front, sl.v_g_front)):
        out.append(_row(q, a, b, _rel(a, b, 0.0), "rel", V_TOL, WHY_V))
    if sr.walled or sl.walled:
        out += wall_rows(sr, sl)
    er, el = sr.energy, sl.energy
    e0 = er.initial if er.initial > 0 else 1.0
    residual = lmp.info.balance == "residual"
    # the works LAMMPS has no output of (effects.residual_work: contact friction, rolling
    # friction, contact damping, those of the scene's effects): on the LAMMPS side their
    # sum is the balance residual, so they are compared as one sum, not independent
    group = residual_work(scene.effects) if residual else ()
    # the ledger's entries by name: ENERGY_COLUMNS comes from the effects registry
    for q in ENERGY_COLUMNS + ("initial", "final_mechanical"):
        if q in group:
            if q == group[0]:
                a = sum(getattr(er, c) for c in group)
                b = sum(getattr(el, c) for c in group)
                out.append(_row("+".join(group), a, b, abs(b - a) / e0, "abs/E0", None,
                                WHY_RESIDUAL))
            continue
        a, b = getattr(er, q), getattr(el, q)
        out.append(_row(q, a, b, abs(b - a) / e0, "abs/E0", E_TOL, WHY_E))
    a, b = er.balance_error, el.balance_error
    if residual:
        out.append(_row("balance_error", a, b, abs(b - a), "abs (of /E0)", None,
                        WHY_BALANCE_RESIDUAL))
    else:
        out.append(_row("balance_error", a, b, abs(b - a), "abs (of /E0)", E_TOL, WHY_BALANCE))
    return out
