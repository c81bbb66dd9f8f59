"""Command line: ``granchain validate|run|deck|compare SCENE.yaml``, ``granchain infer CSV --scene BASE.yaml``.

Errors a user can cause print one line, ``granchain: error: ...``, and exit with 2.
A scene with ``integrator.method: auto`` is resolved from the cost model as soon as it is
loaded (``load``): every command shows and runs the resolved scene and its hash.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from .costmodel import DEFAULT_MAX_TOTAL_STEPS, add_estimates, run_estimate
from .errors import GranchainError
from .fileio import (IMAGE, atomic_write_text, check_distinct, check_output_path, json_output,
                     json_text)
from .guards import check_run, run_size, scene_warnings
from .progress import bar
from .costmodel import DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_STEPS, check_cost
from .observables import OK_STATUSES, status_text
from .scene import load_scene


def one_line(text: str) -> str:
    """A message on one line: control characters (newlines, ...) shown escaped."""
    return re.sub(r"[\x00-\x1f\x7f]", lambda m: repr(m.group())[1:-1], text)


# what --force may replace: an earlier output of the same command
RUN_JSON = json_output("a granchain run JSON document", {"scene_hash", "v_striker"},
                       {"scene_hash", "runs"})
COMPARE_JSON = json_output("a granchain compare JSON document", {"scene_hash", "rows", "meta"})
INFER_JSON = json_output("a granchain infer JSON document", {"measurements", "timing_column"})


def _workdir_files(args) -> list:
    """(--workdir, path) of every file the LAMMPS engine writes into a kept --workdir."""
    if not getattr(args, "workdir", None):
        return []
    from .lammps.deckplan import WORKDIR_FILES
    return [("--workdir", Path(args.workdir) / name) for name in WORKDIR_FILES]


def check_paths(args, outputs, inputs=()) -> None:
    """Refuse, before any work, an output of a command that is one of its inputs (the
    scene file, the measurement file) or another of its outputs (``--out``, ``--plot``, the
    files of a kept ``--workdir``), with or without --force (``fileio.check_distinct``),
    and a kept ``--workdir`` holding a file the run would replace that is not an earlier
    run's (``lammps.deck.check_workdir``)."""
    check_distinct(_workdir_files(args) + list(outputs),
                   [("the scene file", getattr(args, "scene", None)), *inputs])
    if getattr(args, "workdir", None):
        from .lammps.deck import check_workdir
        check_workdir(args.workdir, args.force)


def _fmt(x, unit="", digits=4):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}{unit}"


def _print_human(scene, runs, out=None):
    out = out or sys.stdout
    if scene.heterogeneous:
        what = (f"{scene.n} spheres ({', '.join(sorted({m.name for m in scene.materials}))}; "
                f"R = {min(scene.radii):g} to {max(scene.radii):g} m)")
    else:
        what = f"{scene.n} x {scene.material.name}, R = {scene.radius:g} m"
    print(f"scene {scene.name} ({scene.hash}): {what}, effects: "
          f"{', '.join(sorted(scene.effects))}", file=out)
    p1, p2 = scene.probes[:2]
    for r in runs:
        vs = r.v_striker
        head = f"v_s = {vs:g} m/s, realisation {r.realisation}"
        cut = list(r.not_final)
        note = (f"; peak not measured (n/a) for particle{'s' if len(cut) > 1 else ''} "
                f"{_ranges(cut)}" if cut else "")
        if not r.wave_arrived:
            missed = [p for p in (p1, p2) if p in cut]
            print(f"{head}: no measured peak at probe{'s' if len(missed) > 1 else ''} "
                  f"{_ranges(missed)} ({status_text(r.status)}){note}", file=out)
            continue
        if r.status not in OK_STATUSES:
            note += f"; {status_text(r.status)}"
        print(f"{head}: v_max,1 = {_fmt(r.v_max_1)} m/s ({_fmt(r.v_max_1 / vs)} v_s) at particle {p1}; "
              f"v_max,2 = {_fmt(r.v_max_2)} m/s ({_fmt(r.v_max_2 / vs)} v_s) at {p2}; "
              f"dt = {_fmt(r.dt_peak)} s; v_g = {_fmt(r.v_g)} m/s "
              f"(front: {_fmt(r.v_g_front)}); energy balance error {_fmt(r.energy.balance_error, digits=2)}"
              f"{_residual_note(scene, r)}; "
              f"{r.steps} steps, {_fmt(r.wall_s, ' s', 3)}{note}", file=out)
        if r.measured:
            m = scene.measurement
            lost = (f"; recorded peak not final at probe "
                    f"{_ranges(r.measured_not_final)} (n/a)" if r.measured_not_final else "")
            print(f"  recorded ({m.filter} order {m.order}, {m.bandwidth_hz:g} Hz, "
                  f"{m.sampling_rate_hz:g} S/s): v_max,1 = {_fmt(r.v_max_1_measured)} m/s, "
                  f"v_max,2 = {_fmt(r.v_max_2_measured)} m/s; dt = {_fmt(r.dt_peak_measured)} s; "
                  f"v_g = {_fmt(r.v_g_measured)} m/s{lost}", file=out)
        if r.walled:
            static = (f" over its static preload {_fmt(r.wall_force_static)} N"
                      if r.wall_force_static else "")
            peak = (f"{_fmt(r.wall_force_max)} N{static} at t = {_fmt(r.t_wall_peak)} s"
                    if r.wall_peak_final else "n/a (its peak is not inside the run)")
            print(f"  end wall ({scene.wall.name}): dynamic force peak {peak}", file=out)
    _print_warnings([w for r in runs for w in r.warnings], out)


def _ranges(ps) -> str:
    """[11, 12, 13, 15] -> '11-13, 15'."""
    out, ps = [], sorted(ps)
    i = 0
    while i < len(ps):
        j = i
        while j + 1 < len(ps) and ps[j + 1] == ps[j] + 1:
            j += 1
        out.append(str(ps[i]) if i == j else f"{ps[i]}-{ps[j]}")
        i = j + 1
    return ", ".join(out)


def _print_warnings(warnings, out) -> None:
    shown = []
    for w in warnings:
        if w not in shown:
            shown.append(w)
            print(f"warning: {one_line(w)}", file=out)


def _residual_note(scene, r) -> str:
    from .effects import residual_work
    missing = residual_work(scene.effects)
    if r.engine == "lammps" and missing:
        return (f" (LAMMPS: {' + '.join(missing)} is the balance residual, not an "
                "independent check)")
    return ""


def load(args):
    """The scene of a command's arguments, method auto resolved."""
    from .runplan import plan_run
    return plan_run(load_scene(args.scene, args.set), per_speed=False).scene


def cmd_validate(args) -> int:
    from .runplan import describe_auto, plan_run
    plan = plan_run(load_scene(args.scene, args.set))
    scene = plan.scene
    print(f"{args.scene}: valid scene '{scene.name}' ({scene.hash}), {scene.n} particles, "
          f"{len(scene.striker_velocities)} striker speed(s) x {scene.realisations} realisation(s), "
          f"effects: {', '.join(sorted(scene.effects))}, integrator "
          f"{plan.auto or describe_auto(scene)}")
    _print_warnings(scene_warnings(scene), sys.stdout)
    return 0


SCENE_SIZE_FIX = "lower ensemble.realisations, the striker speeds (striker.velocity) or chain.n"


def check_whole_run(scene, args, est) -> None:
    """Refuse a run of every member of ``scene`` beyond the command's whole-run limits."""
    check_run(f"scene '{scene.name}'", est, size=run_size(scene), fix=SCENE_SIZE_FIX,
              max_total_steps=args.max_total_steps, max_memory_gb=args.max_memory_gb)


def cmd_run(args) -> int:
    from .runplan import plan_run
    from .simulate import run_scene
    check_paths(args, [("--out", args.out)])          # refuse before spending the compute
    # the run plan: method auto chooses per striker speed for the reference engine
    plan = plan_run(load_scene(args.scene, args.set))
    scene = plan.scene
    if args.out:
        check_output_path(args.out, args.force, "--out", kind=RUN_JSON)
    plan.check(args.max_steps, args.max_memory_gb)
    check_whole_run(scene, args, plan.estimate(engine=args.engine))
    kw = _engine_kw(args)
    if args.engine == "reference":
        kw["trace"] = False         # observables on the fly; a measured scene still traces
    chains = len(scene.striker_velocities) * scene.realisations
    with bar(chains, f"{scene.name}: chains", enabled=_progress(args)) as shown:
        runs = run_scene(plan, engine=args.engine, max_steps=args.max_steps,
                         max_memory_gb=args.max_memory_gb, progress=shown.update, **kw)
    if len(runs) == 1:
        doc = dict(runs[0].to_json(), scene=scene.name, scene_hash=scene.hash)
    else:
        doc = {"scene": scene.name, "scene_hash": scene.hash,
               "runs": [r.to_json() for r in runs]}
    if not args.json:
        _print_human(scene, runs)
    elif not args.out:
        print(json_text(doc))
    if args.out:
        atomic_write_text(args.out, json_text(doc, indent=1) + "\n", args.force, "--out")
    return 0


def _engine_kw(args) -> dict:
    """Options of the LAMMPS engine (refused with the reference engine)."""
    kw = {}
    if args.np is not None or args.workdir is not None or args.lammps_output is not None:
        if args.engine != "lammps":
            raise GranchainError("--np, --workdir and --lammps-output are options of the LAMMPS "
                                 "engine; add --engine lammps or drop them")
        if args.lammps_output is not None:
            kw["output"] = args.lammps_output
        if args.np is not None:
            if args.np < 1:
                raise GranchainError(f"--np: must be >= 1 (got {args.np})")
            kw["nprocs"] = args.np
        if args.workdir is not None:
            kw["workdir"] = Path(args.workdir)
            kw["force"] = args.force
    return kw


def _cell(x, digits=6):
    import numpy as np
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    return f"{x:.{digits}g}"


def _print_comparison(cmp, out=None) -> None:
    out = out or sys.stdout
    m = cmp.meta
    print(f"compare {m['scene']} ({m['scene_hash']}): reference velocity Verlet vs LAMMPS "
          f"{m['lammps_version']}, dt = {m['dt']:g} s, samples every {m['sample_dt']:.6g} s, "
          f"{m['chains']} chain(s); walls: reference {m['reference_wall_s']:.3g} s, LAMMPS "
          f"{m['lammps_wall_s']:.3g} s ({m['nprocs']} rank(s))", file=out)
    rows = cmp.rows if m["chains"] == 1 else cmp.worst()
    if m["chains"] > 1:
        print("worst member for each quantity (all rows: --json)", file=out)
    whys = {}
    table = []
    for r in rows.to_dict("records"):
        key = whys.setdefault(r["why"], chr(ord("a") + len(whys)))
        ok = r["ok"] if isinstance(r["ok"], bool) else None
        tol = r["tolerance"]
        table.append([r["quantity"] + ("" if m["chains"] == 1 else f" (#{r['member']})"),
                      _cell(r["reference"], 10), _cell(r["lammps"], 10), _cell(r["diff"], 3),
                      r["measure"], _cell(tol, 2), "ok" if ok else ("FAIL" if ok is False else "-"),
                      f"[{key}]"])
    head = ["quantity", "reference", "lammps", "diff", "measure", "tolerance", "check", "why"]
    widths = [max(len(str(row[i])) for row in table + [head]) for i in range(len(head))]
    for row in [head] + table:
        print("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip(), file=out)
    for why, key in whys.items():
        print(f"[{key}] {why}", file=out)
    _print_warnings(m.get("warnings", ()), out)
    bad = cmp.failures()
    verdict = "all tolerances met" if cmp.ok else f"{len(bad)} tolerance(s) missed"
    if m.get("warnings"):
        # engines that agree on a value a guard set aside have not checked it
        verdict += " on the values both engines measured; see the warnings above"
    print(verdict, file=out)


def cmd_compare(args) -> int:
    from .compare import compare
    check_paths(args, [("--out", args.out)])
    scene = load(args)
    if args.out:
        check_output_path(args.out, args.force, "--out", kind=COMPARE_JSON)
    if args.np < 1:
        raise GranchainError(f"--np: must be >= 1 (got {args.np})")
    check_cost(scene, args.max_steps, args.max_memory_gb)
    if args.traces < 0:
        raise GranchainError(f"--traces: must be >= 0 (got {args.traces})")
    # both engines run every member with velocity Verlet at the scene's step; LAMMPS'
    # records of every member are read back, the reference's only for the traced members
    verlet = scene.derive(**{"integrator.method": "verlet"})
    check_whole_run(scene, args, add_estimates(
        run_estimate(verlet, engine="reference", trace=args.trajectory),
        run_estimate(verlet, engine="lammps")))
    cmp = compare(scene, nprocs=args.np,
                  workdir=Path(args.workdir) if args.workdir else None, force=args.force,
                  trajectory=args.trajectory, traces=args.traces)
    doc = {"scene": scene.name, "scene_hash": scene.hash, "ok": cmp.ok, "meta": cmp.meta,
           "rows": cmp.rows.astype(object).where(cmp.rows.notna(), None).to_dict("records")}
    if args.json and not args.out:
        print(json_text(doc))
    elif not args.json:
        _print_comparison(cmp)
    if args.out:
        atomic_write_text(args.out, json_text(doc, indent=1) + "\n", args.force, "--out")
    return 0 if cmp.ok else 1


def cmd_deck(args) -> int:
    from .lammps.deck import DATA_NAME, DECK_NAME, write_deck
    check_paths(args, [("-o/--output", Path(args.output) / name)
                       for name in (DECK_NAME, DATA_NAME)])
    scene = load(args)
    path = write_deck(scene, Path(args.output), force=args.force, output=args.write)
    print(path)
    return 0


def _print_inference(res, out=None) -> None:
    out = out or sys.stdout
    nm = lambda x: _fmt(None if x is None else x * 1e9, " nm")    # noqa: E731
    lo, hi = res.ci95_m
    print(f"inferred mean gap ({res.timing_column}, {res.rows} row(s) on {res.chains} chain(s)): "
          f"{nm(res.gap_mean_m)}, 95% interval [{nm(lo)}, {nm(hi)}]", file=out)
    print(f"gap law: {res.gap_law}; {res.n_simulated} simulated chains ({res.n_simulated_now} "
          f"run now, the rest cached): mean gaps {nm(res.gap_grid_m[0])}-{nm(res.gap_grid_m[1])} "
          f"({res.gap_grid_m[2]} points) x {len(res.speeds_m_s)} striker speed(s) x "
          f"{res.realisations} realisations", file=out)
    _print_sources(res, out)
    _print_model_check(res, out)
    print(f"Eq. 5.4 reading (chapter): least-squares {nm(res.eq54_gap_m)}, "
          f"upper-bound reading {nm(res.eq54_gap_bound_m)}", file=out)
    _print_warnings([f"{f}: " + {
        "posterior_at_grid_end": "the posterior still has weight at the largest simulated "
                                 "mean gap; median and upper bound not measured (n/a): "
                                 "raise --gap-max-nm",
        "no_simulated_match": "no simulated mean gap reproduces the timings",
        "data_outside_model": _OUTSIDE}[f]
        for f in res.flags], out)
    _print_unmeasured(res, out)


_OUTSIDE = ("the measured values lie outside what the simulated gap realisations produce "
            "(model check below its threshold): the posterior describes the nearest simulated "
            "chains, not this one, and its interval is not calibrated (too narrow, biased); "
            "check the data, or give the base scene the chain's gap law, effects and "
            "integrator, or simulate more realisations (--realisations)")


def _print_model_check(res, out) -> None:
    """The model check's line (``granchain.modelcheck``): where the data's kernel density
    ranks among posterior-predictive replicates of the simulated realisations."""
    mc = res.data_outside_model
    p = mc.get("p_value")
    if not mc["flag"] and (p is None or not math.isfinite(p)):
        # no p-value: nothing was checked, which is not a pass
        print("model check: not made (n/a): no posterior-predictive replicate to rank the "
              "data among", file=out)
        return
    verdict = ("OUTSIDE the simulated realisations" if mc["flag"]
               else "inside the simulated realisations")
    print(f"model check: data {verdict} (p = {_fmt(mc['p_value'], digits=3)}, flagged "
          f"below {mc['alpha']:g}; density rank among {mc['replicates']} replicates)",
          file=out)


def _print_sources(res, out) -> None:
    """Where an inference's gap law and striker speeds came from: the base scene, or the
    defaults of ``inference.complete_base``."""
    speeds = ", ".join(f"{v:g}" for v in res.speeds_m_s)
    law = ("the base scene's gap law (gaps.distribution)" if res.gap_law_source == "scene"
           else "the chapter's gap law (default: the base scene gives no gaps.distribution)")
    sp = (f"the base scene's striker speeds {speeds} m/s (striker.velocity)"
          if res.speeds_source == "scene" else
          f"the data's striker speeds {speeds} m/s (default: the base scene gives no "
          "striker.velocity)")
    print(f"simulated with {law} and {sp}", file=out)


def _speeds_origin(src) -> tuple[str, str]:
    """(where the simulated striker speeds come from, how to simulate fewer), for the
    grid guards' messages; ``src``: the sources of ``inference.complete_base``."""
    if src["speeds"] == "data":
        return ("the data's; the base scene gives no striker.velocity",
                "give the base scene fewer striker speeds (striker.velocity) bracketing the "
                "data")
    return "striker.velocity of --scene", "the base scene's striker speeds"


def check_grid(base, args, src) -> None:
    """Refuse an inference whose simulated grid (mean gaps x striker speeds x
    realisations) is beyond the whole-run limits, cached points included. Values the
    inference itself refuses (too few points or realisations) are left to it. ``base``:
    the completed base scene, ``src`` its sources (``inference.complete_base``)."""
    from .inference import check_base, grid_scene
    from .runplan import plan_run
    check_base(base)
    G, R = args.gap_points, args.realisations
    if G < 3 or R < 2 or min(base.striker_velocities) <= 0:
        return
    speeds = sorted({float(v) for v in base.striker_velocities})
    base = base.derive(striker={"velocity": speeds})
    # a chain's steps and record grow linearly with its gaps' mean (flight over them):
    # the grid's total is G times the mean of its two ends
    ends = [run_estimate(plan_run(grid_scene(base, g, R), per_speed=False).scene)
            for g in (0.0, args.gap_max_nm * 1e-9)]
    est = {k: G * (ends[0][k] + ends[1][k]) / 2 for k in ("members", "steps", "seconds")}
    est["worst_chain_steps"] = ends[1]["worst_chain_steps"]
    # the points run one after another: at most two points' results and records are held
    # at once, with the grid's timings (two columns of G x S x R)
    est["result_bytes"] = 2 * ends[1]["result_bytes"] + 16.0 * G * len(speeds) * R
    est["record_bytes"] = 2 * ends[1]["record_bytes"]
    est["bytes"] = est["result_bytes"] + est["record_bytes"]
    origin, fewer = _speeds_origin(src)
    size = (f"{G * len(speeds) * R} chains: {G} mean gaps (--gap-points) x {len(speeds)} "
            f"striker speed{'s' if len(speeds) != 1 else ''} ({origin}) x "
            f"{R} realisations (--realisations) of {base.n} spheres (chain.n)")
    check_run("the inference grid", est, size=size,
              fix=f"lower --realisations, --gap-points or {fewer}",
              max_total_steps=args.max_total_steps, max_memory_gb=args.max_memory_gb)


def _print_joint_inference(res, out=None) -> None:
    out = out or sys.stdout
    nm = lambda x: _fmt(None if x is None else x * 1e9, " nm")    # noqa: E731
    lo, hi = res.ci95_m
    elo, ehi = res.restitution_ci95
    print(f"inferred from {res.timing_column} and the peaks at both probes ({res.rows} row(s) "
          f"on {res.chains} chain(s)):", file=out)
    print(f"  mean gap {nm(res.gap_mean_m)}, 95% interval [{nm(lo)}, {nm(hi)}]", file=out)
    print(f"  coefficient of restitution e {_fmt(res.restitution)}, 95% interval "
          f"[{_fmt(elo)}, {_fmt(ehi)}]", file=out)
    print(f"  posterior correlation of mean gap and e: {_fmt(res.posterior_correlation, digits=2)}",
          file=out)
    g0, g1, G = res.gap_grid_m
    e0, e1, E = res.restitution_grid
    print(f"gap law: {res.gap_law}; damping {res.damping_model}; {res.n_simulated} simulated "
          f"chains ({res.n_simulated_now} run now, the rest cached): mean gaps "
          f"{nm(g0)}-{nm(g1)} ({G} points, {res.gap_spacing} spacing) x e {_fmt(e0)}-{_fmt(e1)} "
          f"({E} points) x {len(res.speeds_m_s)} striker speed(s) x {res.realisations} "
          "realisations", file=out)
    _print_sources(res, out)
    ranged = _predictive_ranged(res)
    if ranged == 0:
        # no posterior draw gave a range: nothing was checked, which is not a pass
        print(f"posterior predictive check: not made (n/a): none of the "
              f"{res.predictive_values} measured values has a simulated predictive range",
              file=out)
    else:
        print(f"posterior predictive check: {res.predictive_outside} of "
              f"{res.predictive_values} measured values outside their 95% predictive range"
              + (f" ({res.predictive_values - ranged} without a simulated range, counted "
                 "outside)" if ranged < res.predictive_values else ""), file=out)
    _print_model_check(res, out)
    print(f"Eq. 5.4 reading (chapter; packed chain at the inferred e): least-squares "
          f"{nm(res.eq54_gap_m)}, upper-bound reading {nm(res.eq54_gap_bound_m)}", file=out)
    _print_warnings([f"{f}: " + {
        "posterior_at_grid_end": "the posterior still has weight at the largest simulated "
                                 "mean gap; its median and upper bound not measured (n/a): "
                                 "raise --gap-max-nm",
        "restitution_at_grid_end": "the posterior still has weight at the smallest "
                                   "simulated e; its median and lower bound not measured "
                                   "(n/a): lower --e-min",
        "no_simulated_match": "no simulated (mean gap, e) reproduces the data",
        "data_outside_model": _OUTSIDE}[f]
        for f in res.flags], out)
    _print_unmeasured(res, out)


def _predictive_ranged(res) -> int:
    """How many measured values of a joint inference have a finite 95% predictive range
    (``predictive_rows``): the values its predictive check actually checked."""
    n = 0
    for row in res.predictive_rows:
        for key, q in row.items():
            if key != "v_striker_m_s":
                n += int(all(x is not None and math.isfinite(x) for x in q))
    return n


def _print_unmeasured(res, out) -> None:
    """A warning when simulated chains of an inference's grid have no timing: their wave
    did not reach both probes within the run, the run timed out, or a guard set an
    impossible value aside (``observables.bounded``); they match no measurement."""
    import numpy as np
    grid = res.grid
    if grid is None:
        return
    table = grid.timings if hasattr(grid, "timings") else grid.values
    T = np.asarray(table[res.timing_column])
    k = int(np.count_nonzero(np.isnan(T)))
    if k:
        _print_warnings([f"{k} of {T.size} simulated chains have no {res.timing_column}: "
                         "their wave did not reach both probes within the run or a guard set "
                         "an impossible value aside (granchain run on the base scene shows "
                         "which); they match no measurement"], out)


def check_joint_grid(base, args, src) -> None:
    """Refuse a joint inference whose grid (mean gaps x restitutions x striker speeds x
    realisations) is beyond the whole-run limits, as :func:`check_grid`."""
    from .errors import SceneError
    from .inference import check_joint_options, gap_nodes, joint_scene
    from .runplan import plan_run
    check_joint_options(args.gap_max_nm * 1e-9, args.gap_points, args.e_min, args.e_points,
                        args.realisations)
    if min(base.striker_velocities) <= 0:
        return
    G, E, R = args.gap_points, args.e_points, args.realisations
    speeds = sorted({float(v) for v in base.striker_velocities})
    base = base.derive(striker={"velocity": speeds})
    gmax = args.gap_max_nm * 1e-9
    try:
        ends = [run_estimate(plan_run(joint_scene(base, g, args.e_min, R),
                                      per_speed=False).scene)
                for g in (0.0, gmax)]
    except SceneError as exc:
        raise GranchainError(f"--e-min {args.e_min:g}: the base scene at this e is refused "
                             f"({exc}); raise --e-min, or give the base scene an integrator "
                             "that resolves the damping (method event or adaptive)") from None
    # steps grow linearly with the mean gap: the nodes' mean gap is gmax mean((k/(G-1))^2)
    f = float((gap_nodes(1.0, G)).mean())
    est = {k: G * E * (ends[0][k] + f * (ends[1][k] - ends[0][k]))
           for k in ("members", "steps", "seconds")}
    est["worst_chain_steps"] = ends[1]["worst_chain_steps"]
    est["result_bytes"] = 2 * ends[1]["result_bytes"] + 32.0 * G * E * len(speeds) * R
    est["record_bytes"] = 2 * ends[1]["record_bytes"]
    est["bytes"] = est["result_bytes"] + est["record_bytes"]
    origin, fewer = _speeds_origin(src)
    size = (f"{G * E * len(speeds) * R} chains: {G} mean gaps (--gap-points) x {E} "
            f"restitutions (--e-points) x {len(speeds)} striker speed"
            f"{'s' if len(speeds) != 1 else ''} ({origin}) x {R} "
            f"realisations (--realisations) of {base.n} spheres (chain.n)")
    check_run("the inference grid", est, size=size,
              fix=f"lower --realisations, --gap-points, --e-points or {fewer}",
              max_total_steps=args.max_total_steps, max_memory_gb=args.max_memory_gb)


def cmd_infer(args) -> int:
    from .errors import SceneError
    from .inference import (check_restitution_base, complete_base, infer, parse_fit,
                            read_measurements)
    from .runplan import plan_run
    fit = parse_fit(args.fit)
    check_paths(args, [("--out", args.out), ("--plot", args.plot)],
                [("the measurement file", args.measurements)])
    if args.plot:
        if Path(args.plot).suffix.lower() not in (".png", ".pdf", ".svg"):
            raise GranchainError(f"--plot: {args.plot!r} has no known image suffix; end it "
                                 "with .png, .pdf or .svg")
        check_output_path(args.plot, args.force, "--plot", kind=IMAGE)
    if args.out:
        check_output_path(args.out, args.force, "--out", kind=INFER_JSON)
    if not args.no_cache:
        _check_cache_dir(args.cache_dir)
    joint = "restitution" in fit
    meas = read_measurements(args.measurements, peaks=joint)
    # the gap law and speeds the base scene leaves out are filled in before method auto
    # is resolved, so that auto chooses for the scene that runs
    base, src = complete_base(load_scene(args.scene, args.set), meas)
    base = plan_run(base, per_speed=False).scene
    if joint:
        try:
            check_restitution_base(base)
        except SceneError as exc:
            raise GranchainError(f"{args.scene}: {exc} (--fit names restitution)") from None
        return _infer_joint(args, meas, base, src)
    check_grid(base, args, src)
    res = infer(base, meas, gap_max=args.gap_max_nm * 1e-9, gap_points=args.gap_points,
                realisations=args.realisations, cache_dir=None if args.no_cache else args.cache_dir,
                source=f"{args.measurements}, ", prior=args.prior, progress=_progress(args))
    return _report_inference(args, res, meas, base, _print_inference, "plot_inference")


def _check_cache_dir(path) -> None:
    """Refuse, before any work, a --cache-dir that is not (and cannot become) a directory."""
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise GranchainError(f"--cache-dir: {str(d)!r} is not a directory; give a directory "
                             "for the simulated grids (it is created if missing), or pass "
                             "--no-cache")
    up = d
    while not up.exists() and up != up.parent:
        up = up.parent
    if up != d and not up.is_dir():
        # created when the first grid point is cached: refused now, not after that work
        raise GranchainError(f"--cache-dir: cannot create {str(d)!r} ({str(up)!r} is a file); "
                             "choose another directory, or pass --no-cache")


def _infer_joint(args, meas, base, src) -> int:
    from .inference import infer_joint
    check_joint_grid(base, args, src)
    res = infer_joint(base, meas, gap_max=args.gap_max_nm * 1e-9, gap_points=args.gap_points,
                      e_min=args.e_min, e_points=args.e_points, realisations=args.realisations,
                      cache_dir=None if args.no_cache else args.cache_dir,
                      source=f"{args.measurements}, ", prior=args.prior,
                      progress=_progress(args))
    return _report_inference(args, res, meas, base, _print_joint_inference,
                             "plot_joint_inference")


def _report_inference(args, res, meas, base, print_human, plot: str) -> int:
    """An inference's output: its JSON document (stdout with --json, the file --out) or
    the human summary, and with --plot the figure of ``figures.inference.<plot>``
    (matplotlib is loaded only then)."""
    doc = dict(res.to_json(), measurements=str(args.measurements))
    if args.json and not args.out:
        print(json_text(doc))
    elif not args.json:
        print_human(res)
    if args.out:
        atomic_write_text(args.out, json_text(doc, indent=1) + "\n", args.force, "--out")
    if args.plot:
        from .figures import inference as figs
        getattr(figs, plot)(res, meas, base, args.plot, force=args.force)
    return 0


def _progress(args) -> bool | None:
    """Progress bars: off with --no-progress, else when stderr is a terminal (None)."""
    return False if args.no_progress else None


def _no_progress(sp) -> None:
    sp.add_argument("--no-progress", action="store_true",
                    help="no progress bar on stderr (shown only when stderr is a terminal)")


def _default_cache() -> str:
    from .fileio import cache_dir
    return str(cache_dir() / "inference")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2), like every other granchain error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def _limit(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text!r} must be a number > 0")
    return value


def _run_limits(sp) -> None:
    sp.add_argument("--max-total-steps", type=_limit, default=DEFAULT_MAX_TOTAL_STEPS,
                    metavar="N", help=f"refuse a run needing more integration steps over all "
                    f"its chains (estimate; default {DEFAULT_MAX_TOTAL_STEPS:.0e})")
    sp.add_argument("--max-memory-gb", type=_limit, default=DEFAULT_MAX_MEMORY_GB, metavar="X",
                    help=f"refuse a run that would hold more GB: every chain's results and "
                         f"the sample records kept until it ends, or one chain's record "
                         f"(estimate; default {DEFAULT_MAX_MEMORY_GB:g})")


def _cost_args(sp) -> None:
    sp.add_argument("--max-steps", type=_limit, default=DEFAULT_MAX_STEPS, metavar="N",
                    help=f"refuse a scene needing more integration steps per chain "
                         f"(estimate; default {DEFAULT_MAX_STEPS:.0e})")
    _run_limits(sp)


def build_parser() -> argparse.ArgumentParser:
    from .inference import E_MIN, E_POINTS, GAP_MAX, GAP_POINTS, REALISATIONS
    p = _Parser(prog="granchain", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def scene_args(sp):
        sp.add_argument("scene", help="scene YAML file")
        sp.add_argument("--set", action="append", default=[], metavar="KEY.SUB=VALUE",
                        help="override a scene field (value parsed as YAML); repeatable")

    sp = sub.add_parser("validate", help="check a scene file")
    scene_args(sp)
    sp.set_defaults(func=cmd_validate)

    sp = sub.add_parser("run", help="simulate a scene and print its observables")
    scene_args(sp)
    sp.add_argument("--engine", default="reference", choices=["reference", "lammps"])
    sp.add_argument("--json", action="store_true", help="print one JSON object")
    sp.add_argument("--out", help="also write the JSON results to this new file")
    sp.add_argument("--force", action="store_true",
                    help="allow --out to replace an earlier run JSON (never an input) and a "
                         "non-empty --workdir's files to be replaced")
    sp.add_argument("--np", type=int, default=None, metavar="N",
                    help="LAMMPS engine: MPI ranks (mpirun -np N; default 1)")
    sp.add_argument("--workdir", metavar="DIR",
                    help="LAMMPS engine: keep deck, dump and log in DIR (must be empty)")
    sp.add_argument("--lammps-output", choices=["binary", "dump"], default=None,
                    help="LAMMPS engine: what the run writes and reads back; binary (default): "
                         "LAMMPS binary dumps read with numpy; dump: the text dump traj.dump "
                         "(id x y z vx) read with MDAnalysis, for a full trajectory kept with "
                         "--workdir. Same results")
    _cost_args(sp)
    _no_progress(sp)
    sp.set_defaults(func=cmd_run)

    sp = sub.add_parser("compare", help="run a scene through the reference engine and LAMMPS "
                                        "and tabulate the differences")
    scene_args(sp)
    sp.add_argument("--json", action="store_true", help="print one JSON object (every row)")
    sp.add_argument("--out", help="also write the JSON document to this new file")
    sp.add_argument("--force", action="store_true",
                    help="allow --out to replace an earlier compare JSON (never an input) and "
                         "a non-empty --workdir's files to be replaced")
    sp.add_argument("--np", type=int, default=1, metavar="N", help="LAMMPS MPI ranks (default 1)")
    sp.add_argument("--workdir", metavar="DIR", help="keep the LAMMPS deck, dump and log in DIR")
    sp.add_argument("--traces", type=int, default=1, metavar="N",
                    help="also compare the whole trajectories (every particle's v(t) at every "
                         "sample) of the first N members (default 1; the observables are "
                         "compared for every member)")
    sp.add_argument("--trajectory", action="store_true",
                    help="compare the whole trajectories of every member (LAMMPS writes its "
                         "text dump, read with MDAnalysis)")
    _cost_args(sp)
    sp.set_defaults(func=cmd_compare)

    sp = sub.add_parser("deck", help="write a LAMMPS input deck for a scene")
    scene_args(sp)
    sp.add_argument("-o", "--output", required=True, help="directory for the deck")
    sp.add_argument("--force", action="store_true",
                    help="replace the deck.lmp and chain.data an earlier deck wrote")
    sp.add_argument("--write", choices=["dump", "binary", "none"], default="dump",
                    help="what the deck writes at every sample: dump (default) the text dump "
                         "traj.dump and ledger.txt; binary the LAMMPS binary dumps traj.bin and "
                         "ledger.bin (what granchain run reads); none no per-sample output")
    sp.set_defaults(func=cmd_deck)

    sp = sub.add_parser("warm-up", help="compile the reference engine's kernels for this machine "
                                        "(numba's JIT cache and the ahead-of-time module)")
    _no_progress(sp)
    sp.set_defaults(func=cmd_warm_up)

    sp = sub.add_parser("infer", help="infer the mean gap of a chain (and its coefficient of "
                                      "restitution) from measured wave timing (and peaks)")
    sp.add_argument("measurements", help="CSV: v_striker_m_s, dt_peak_s or dt_front_s, "
                                         "optional dt_err_s, chain_id, vmax_1_m_s, vmax_2_m_s, "
                                         "vmax_err_m_s (SI units)")
    sp.add_argument("--fit", default="gap_mean", metavar="NAMES",
                    help="what to infer: gap_mean (default; from the timing) or "
                         "gap_mean,restitution (the mean gap and contact_damping's e, from "
                         "the timing and both probes' peaks)")
    sp.add_argument("--scene", required=True, help="base scene YAML: material, chain, effects, "
                    "integrator, gap law (gaps.distribution; default the chapter's uniform "
                    "law), simulated speeds (striker.velocity; default the data's)")
    sp.add_argument("--set", action="append", default=[], metavar="KEY.SUB=VALUE",
                    help="override a field of the base scene; repeatable")
    sp.add_argument("--json", action="store_true", help="print one JSON object")
    sp.add_argument("--out", help="also write the JSON result to this new file")
    sp.add_argument("--plot", metavar="FILE", help="draw v_g vs v_s (data, inferred band, "
                    "Eq. 5.4) into this new file (.png or .pdf); with restitution fitted: "
                    "the joint posterior, its marginals and the data against the fitted model")
    sp.add_argument("--force", action="store_true",
                    help="allow --out and --plot to replace an earlier infer JSON and image "
                         "(never an input)")
    sp.add_argument("--gap-max-nm", type=_limit, default=GAP_MAX * 1e9, metavar="NM",
                    help=f"largest simulated mean gap in nm (default {GAP_MAX * 1e9:g})")
    sp.add_argument("--gap-points", type=int, default=GAP_POINTS, metavar="N",
                    help=f"simulated mean gaps from 0 to --gap-max-nm (default {GAP_POINTS})")
    sp.add_argument("--realisations", type=int, default=REALISATIONS, metavar="R",
                    help=f"gap realisations per mean gap and speed (default {REALISATIONS})")
    sp.add_argument("--e-min", type=float, default=E_MIN, metavar="E",
                    help=f"--fit ...,restitution: smallest simulated e (default {E_MIN:g}; "
                         "the largest is 1)")
    sp.add_argument("--e-points", type=int, default=E_POINTS, metavar="N",
                    help=f"--fit ...,restitution: simulated e from --e-min to 1 (default "
                         f"{E_POINTS})")
    sp.add_argument("--prior", choices=["scale", "uniform"], default="scale",
                    help="prior of the mean gap: scale (1/(g + 2 nm), default) or uniform")
    sp.add_argument("--cache-dir", default=_default_cache(), metavar="DIR",
                    help="where simulated grids are kept, keyed by scene hash "
                         "(default $GRANCHAIN_CACHE_DIR/inference, else $XDG_CACHE_HOME/granchain/inference)")
    sp.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    _run_limits(sp)
    _no_progress(sp)
    sp.set_defaults(func=cmd_infer)

    return p


def cmd_warm_up(args) -> int:
    from .engines import backend, warmup
    warmup.build(log=lambda msg: print(msg, file=sys.stderr), workers=backend.num_threads(),
                 progress=_progress(args))
    return 0


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:        # argparse: --help (0) or a bad option (2, one line)
        return exc.code if isinstance(exc.code, int) else 2
    try:
        for flag, dest in (("--out", "out"), ("-o/--output", "output"), ("--workdir", "workdir")):
            if getattr(args, dest, None) == "":
                raise GranchainError(f"{flag}: the path is empty; give a path")
        return args.func(args)
    except GranchainError as exc:
        print(f"granchain: error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("granchain: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
