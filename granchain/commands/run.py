"""The commands on one scene: ``granchain validate``, ``run``, ``compare`` and ``deck``,
and ``warm-up`` (the reference engine's kernels compiled for this machine).

A scene with ``integrator.method: auto`` is resolved from the cost model as soon as it is
loaded (``load``): every command shows and runs the resolved scene and its hash.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from ..costmodel import add_estimates, check_cost, run_estimate
from ..errors import GranchainError
from ..fileio import check_output_path, json_output
from ..guards import check_run, run_size, scene_warnings
from ..observables import OK_STATUSES, status_text
from ..progress import bar
from ..scene import load_scene
from .output import check_paths, emit, fmt, print_warnings, show_progress


# what --force may replace: an earlier output of the same command
RUN_JSON = json_output("a granchain run JSON document", {"scene_hash", "v_striker"},
                       {"scene_hash", "runs"})


COMPARE_JSON = json_output("a granchain compare JSON document", {"scene_hash", "rows", "meta"})


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
        if r.pair:
            print(f"{head}: {_collision_text(r)}; final velocities {fmt(r.v_final[0])} and "
                  f"{fmt(r.v_final[1])} m/s at t = {fmt(r.t_end)} s ({status_text(r.status)})",
                  file=out)
            continue
        if not r.wave_arrived:
            missed = [p for p in (p1, p2) if p in cut]
            print(f"{head}: no measured peak at probe{'s' if len(missed) > 1 else ''} "
                  f"{_ranges(missed)} ({status_text(r.status)}){note}", file=out)
            continue
        if r.status not in OK_STATUSES:
            note += f"; {status_text(r.status)}"
        print(f"{head}: v_max,1 = {fmt(r.v_max_1)} m/s ({fmt(r.v_max_1 / vs)} v_s) at particle {p1}; "
              f"v_max,2 = {fmt(r.v_max_2)} m/s ({fmt(r.v_max_2 / vs)} v_s) at {p2}; "
              f"dt = {fmt(r.dt_peak)} s; v_g = {fmt(r.v_g)} m/s "
              f"(front: {fmt(r.v_g_front)}); energy balance error {fmt(r.energy.balance_error, digits=2)}"
              f"{_residual_note(scene, r)}; "
              f"{r.steps} steps, {fmt(r.wall_s, ' s', 3)}{note}", file=out)
        if r.measured:
            m = scene.measurement
            lost = (f"; recorded peak not final at probe "
                    f"{_ranges(r.measured_not_final)} (n/a)" if r.measured_not_final else "")
            print(f"  recorded ({m.filter} order {m.order}, {m.bandwidth_hz:g} Hz, "
                  f"{m.sampling_rate_hz:g} S/s): v_max,1 = {fmt(r.v_max_1_measured)} m/s, "
                  f"v_max,2 = {fmt(r.v_max_2_measured)} m/s; dt = {fmt(r.dt_peak_measured)} s; "
                  f"v_g = {fmt(r.v_g_measured)} m/s{lost}", file=out)
        if r.walled:
            static = (f" over its static preload {fmt(r.wall_force_static)} N"
                      if r.wall_force_static else "")
            peak = (f"{fmt(r.wall_force_max)} N{static} at t = {fmt(r.t_wall_peak)} s"
                    if r.wall_peak_final else "n/a (its peak is not inside the run)")
            print(f"  end wall ({scene.wall.name}): dynamic force peak {peak}", file=out)
    print_warnings([w for r in runs for w in r.warnings], out)


def _collision_text(r) -> str:
    """What a two-sphere collision came to, for the human output."""
    if r.collision == "separated":
        return f"separated, restitution e = {fmt(r.restitution)}"
    if r.collision == "captured":
        return "captured (the pair stays bound; no restitution)"
    if r.collision == "unfinished":
        return "unfinished by the end of the run (no restitution: a longer t_end finishes it)"
    return "no impact (the striker does not move)"


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


def _residual_note(scene, r) -> str:
    from ..effects import residual_work
    missing = residual_work(scene.effects)
    if r.engine == "lammps" and missing:
        return (f" (LAMMPS: {' + '.join(missing)} is the balance residual, not an "
                "independent check)")
    return ""


def load(args):
    """The scene of a command's arguments, method auto resolved."""
    from ..runplan import plan_run
    return plan_run(load_scene(args.scene, args.set), per_speed=False).scene


def cmd_validate(args) -> int:
    from ..runplan import describe_auto, plan_run
    plan = plan_run(load_scene(args.scene, args.set))
    scene = plan.scene
    print(f"{args.scene}: valid scene '{scene.name}' ({scene.hash}), {scene.n} particles, "
          f"{len(scene.striker_velocities)} striker speed(s) x {scene.realisations} realisation(s), "
          f"effects: {', '.join(sorted(scene.effects))}, integrator "
          f"{plan.auto or describe_auto(scene)}")
    # what an effect says of its own regime (``validate_notes``, ``validate_warnings``)
    from ..effects import MODULES
    on = [m for m in MODULES if scene.has(m.SPEC.name)]
    for m in on:
        for line in getattr(m, "validate_notes", lambda s: [])(scene):
            print(line)
    print_warnings(scene_warnings(scene) + [w for m in on for w in
                                            getattr(m, "validate_warnings", lambda s: [])(scene)],
                   sys.stdout)
    return 0


SCENE_SIZE_FIX = "lower ensemble.realisations, the striker speeds (striker.velocity) or chain.n"


def check_whole_run(scene, args, est) -> None:
    """Refuse a run of every member of ``scene`` beyond the command's whole-run limits."""
    check_run(f"scene '{scene.name}'", est, size=run_size(scene), fix=SCENE_SIZE_FIX,
              max_total_steps=args.max_total_steps, max_memory_gb=args.max_memory_gb)


def cmd_run(args) -> int:
    from ..runplan import plan_run
    from ..simulate import run_scene
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
    with bar(chains, f"{scene.name}: chains", enabled=show_progress(args)) as shown:
        runs = run_scene(plan, engine=args.engine, max_steps=args.max_steps,
                         max_memory_gb=args.max_memory_gb, progress=shown.update, **kw)
    if len(runs) == 1:
        doc = dict(runs[0].to_json(), scene=scene.name, scene_hash=scene.hash)
    else:
        doc = {"scene": scene.name, "scene_hash": scene.hash,
               "runs": [r.to_json() for r in runs]}
    emit(args, doc, lambda: _print_human(scene, runs))
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
    print_warnings(m.get("warnings", ()), out)
    bad = cmp.failures()
    verdict = "all tolerances met" if cmp.ok else f"{len(bad)} tolerance(s) missed"
    if m.get("warnings"):
        # engines that agree on a value a guard set aside have not checked it
        verdict += " on the values both engines measured; see the warnings above"
    print(verdict, file=out)


def cmd_compare(args) -> int:
    from ..compare import compare
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
    emit(args, doc, lambda: _print_comparison(cmp))
    return 0 if cmp.ok else 1


def cmd_deck(args) -> int:
    from ..lammps.deck import DATA_NAME, DECK_NAME, write_decks
    check_paths(args, [("-o/--output", Path(args.output) / name)
                       for name in (DECK_NAME, DATA_NAME)])
    scene = load(args)
    for path in write_decks(scene, Path(args.output), force=args.force, output=args.write):
        print(path)
    return 0


def cmd_warm_up(args) -> int:
    from ..engines import backend, warmup
    warmup.build(log=lambda msg: print(msg, file=sys.stderr), workers=backend.num_threads(),
                 progress=show_progress(args))
    return 0
