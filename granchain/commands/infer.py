"""``granchain infer``: the mean gap of a chain (and its coefficient of restitution)
inferred from measured wave timing (and peaks): the guards on the simulated grid's size,
the inference and what it prints."""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

from ..costmodel import run_estimate
from ..errors import GranchainError
from ..fileio import IMAGE, check_output_path, json_output
from ..guards import check_run
from ..scene import load_scene
from .output import check_paths, emit, fmt, print_warnings, show_progress


INFER_JSON = json_output("a granchain infer JSON document", {"measurements", "timing_column"})


def _print_inference(res, out=None) -> None:
    out = out or sys.stdout
    nm = lambda x: fmt(None if x is None else x * 1e9, " nm")    # noqa: E731
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
    print_warnings([f"{f}: " + {
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
    print(f"model check: data {verdict} (p = {fmt(mc['p_value'], digits=3)}, flagged "
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
    rec = getattr(res, "integrator", None)
    if rec:
        print(f"integrator: {rec['reason']}", file=out)


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
    from ..inference import check_base, grid_scene
    from ..runplan import plan_run
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
    from ..inference import fit_key
    out = out or sys.stdout
    fk = fit_key(res.key)
    sym = fk.fit.symbol
    nm = lambda x: fmt(None if x is None else x * 1e9, " nm")    # noqa: E731
    unit = "" if fk.key.unit == "1" else f" {fk.key.unit}"
    val = lambda x: fmt(x, unit)                                  # noqa: E731
    lo, hi = res.ci95_m
    plo, phi = res.param_ci95
    named = "" if fk.name == "restitution" else f" ({fk.path})"
    print(f"inferred from {res.timing_column} and the peaks at both probes ({res.rows} row(s) "
          f"on {res.chains} chain(s)):", file=out)
    print(f"  mean gap {nm(res.gap_mean_m)}, 95% interval [{nm(lo)}, {nm(hi)}]", file=out)
    print(f"  {fk.fit.label} {sym}{named} {val(res.param)}, 95% interval "
          f"[{val(plo)}, {val(phi)}]", file=out)
    print(f"  posterior correlation of mean gap and {'log ' if fk.log else ''}{sym}: "
          f"{fmt(res.posterior_correlation, digits=2)}", file=out)
    g0, g1, G = res.gap_grid_m
    p0, p1, P = res.param_grid
    spacing = ", log spacing" if fk.log else ""
    print(f"gap law: {res.gap_law}; {res.law}; {res.n_simulated} simulated "
          f"chains ({res.n_simulated_now} run now, the rest cached): mean gaps "
          f"{nm(g0)}-{nm(g1)} ({G} points, {res.gap_spacing} spacing) x {sym} "
          f"{fmt(p0)}-{fmt(p1)}{unit} ({P} points{spacing}) x {len(res.speeds_m_s)} striker "
          f"speed(s) x {res.realisations} realisations", file=out)
    _print_sources(res, out)
    ranged = _predictive_ranged(res)
    if ranged == 0:
        # no posterior draw gave a range: nothing was checked, which is not a pass
        print(f"posterior predictive check: not made (n/a): none of the "
              f"{res.predictive_values} measured values has a simulated predictive range",
              file=out)
    else:
        print(f"posterior predictive check ({res.law}): {res.predictive_outside} of "
              f"{res.predictive_values} measured values outside their 95% predictive range"
              + (f" ({res.predictive_values - ranged} without a simulated range, counted "
                 "outside)" if ranged < res.predictive_values else ""), file=out)
    _print_model_check(res, out)
    print(f"Eq. 5.4 reading (chapter; packed chain at the inferred {sym}): least-squares "
          f"{nm(res.eq54_gap_m)}, upper-bound reading {nm(res.eq54_gap_bound_m)}", file=out)
    print_warnings([f"{f}: " + {
        "posterior_at_grid_end": "the posterior still has weight at the largest simulated "
                                 "mean gap; its median and upper bound not measured (n/a): "
                                 "raise --gap-max-nm",
        f"{fk.name}_at_grid_end": _param_edge(res, fk),
        "no_simulated_match": f"no simulated (mean gap, {sym}) reproduces the data",
        "data_outside_model": _OUTSIDE}[f]
        for f in res.flags], out)
    _print_unmeasured(res, out)


def _param_edge(res, fk) -> str:
    """The warning of a posterior with weight at an end of the fitted key's grid (the end
    whose bound is NaN)."""
    sym = fk.fit.symbol
    ends = []
    if not math.isfinite(res.param_ci95[0]):
        ends.append(("smallest", "lower bound",
                     "lower --e-min" if fk.name == "restitution" else
                     "lower the bottom of --fit-range"))
    if not math.isfinite(res.param_ci95[1]):
        ends.append(("largest", "upper bound", "raise the top of --fit-range"))
    return "; ".join(f"the posterior still has weight at the {end} simulated {sym}; its "
                     f"median and {bound} not measured (n/a): {fix}"
                     for end, bound, fix in ends)


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
    """A warning when simulated chains of an inference's grid have no value of what the
    fit reads (``n_unmeasured``): their wave did not reach both probes within the run, the
    run timed out, or a guard set an impossible value aside (``observables.bounded``);
    they match no measurement."""
    k = res.n_unmeasured
    if k:
        what = res.timing_column + (" or probe peak" if hasattr(res, "param_grid") else "")
        print_warnings([f"{k} of {res.n_simulated} simulated chains have no {what}: "
                        "their wave did not reach both probes within the run or a guard set "
                        "an impossible value aside (granchain run on the base scene shows "
                        "which); they match no measurement"], out)


@dataclass(frozen=True)
class FitRange:
    """The joint grid's range of the fitted key: its FitKey ``fk``, [lo, hi] in
    ``points`` nodes, and the options that set lo and the points (named in refusals)."""
    fk: object
    lo: float
    hi: float
    points: int
    options: tuple[str, str]

    @property
    def plural(self) -> str:
        """The grid's values of the key, in the size of a refused grid."""
        return "restitutions" if self.fk.name == "restitution" else f"values of {self.fk.path}"


def fit_range(args, fk) -> FitRange:
    """The range of ``fk`` the command's options give: its declared prior range and nodes
    (``validate.Fit``), or --fit-range LO,HI and --fit-points N; for the restitution also
    --e-min (the top is 1) and --e-points, as before --fit took other keys."""
    from ..inference import DEFAULT_KEY
    e_given = [o for o, v in (("--e-min", args.e_min), ("--e-points", args.e_points))
               if v is not None]
    if e_given and fk.path != DEFAULT_KEY:
        raise GranchainError(f"{e_given[0]}: sets the restitution's grid, not that of "
                             f"{fk.path}; give --fit-range LO,HI and --fit-points N")
    for e_opt, opt, a, b in (("--e-min", "--fit-range", args.e_min, args.fit_range),
                             ("--e-points", "--fit-points", args.e_points, args.fit_points)):
        if a is not None and b is not None:
            raise GranchainError(f"{opt}: given together with {e_opt}; give one of them")
    lo, hi = fk.fit.lo, fk.fit.hi
    if args.fit_range is not None:
        try:
            lo, hi = (float(x) for x in str(args.fit_range).split(","))
        except ValueError:
            raise GranchainError(f"--fit-range: {args.fit_range!r} is not LO,HI; give the "
                                 f"smallest and largest {fk.fit.label} to simulate, e.g. "
                                 f"{fk.fit.lo:g},{fk.fit.hi:g}") from None
    if args.e_min is not None:
        lo = args.e_min
    points = next((p for p in (args.e_points, args.fit_points) if p is not None),
                  fk.fit.points)
    options = ("--e-min" if args.e_min is not None else "--fit-range",
               "--e-points" if args.e_points is not None else "--fit-points")
    return FitRange(fk, lo, hi, points, options)


def check_joint_grid(base, args, src, rng: FitRange) -> None:
    """Refuse a joint inference whose grid (mean gaps x values of the fitted key x striker
    speeds x realisations) is beyond the whole-run limits, as :func:`check_grid`."""
    from ..errors import SceneError
    from ..inference import check_joint_options, gap_nodes, joint_scene
    from ..runplan import plan_run
    fk = rng.fk
    check_joint_options(args.gap_max_nm * 1e-9, args.gap_points, rng.lo, rng.points,
                        args.realisations, fk.path, rng.hi, rng.options)
    if min(base.striker_velocities) <= 0:
        return
    G, E, R = args.gap_points, rng.points, args.realisations
    speeds = sorted({float(v) for v in base.striker_velocities})
    base = base.derive(striker={"velocity": speeds})
    gmax = args.gap_max_nm * 1e-9
    # the costlier end of the key's range at each end of the mean gaps
    ends = []
    for g in (0.0, gmax):
        at = []
        for x, opt in ((rng.lo, rng.options[0]), (rng.hi, "--fit-range")):
            try:
                at.append(run_estimate(plan_run(joint_scene(base, g, x, R, fk.path),
                                                per_speed=False).scene))
            except SceneError as exc:
                raise GranchainError(f"{opt} {x:g}: the base scene at this {fk.fit.symbol} "
                                     f"is refused ({exc}); narrow the range, or give the "
                                     "base scene an integrator that resolves the law "
                                     "(method event or adaptive)") from None
        ends.append({k: max(a[k] for a in at) for k in at[0]})
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
            f"{rng.plural} ({rng.options[1]}) x {len(speeds)} striker speed"
            f"{'s' if len(speeds) != 1 else ''} ({origin}) x {R} "
            f"realisations (--realisations) of {base.n} spheres (chain.n)")
    check_run("the inference grid", est, size=size,
              fix=f"lower --realisations, --gap-points, {rng.options[1]} or {fewer}",
              max_total_steps=args.max_total_steps, max_memory_gb=args.max_memory_gb)


def cmd_infer(args) -> int:
    from ..errors import SceneError
    from ..inference import (check_fit_base, choose_setting, complete_base, fit_key, infer,
                             parse_fit, read_measurements)
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
    joint = len(fit) > 1
    rng = fit_range(args, fit_key(fit[1])) if joint else None
    meas = read_measurements(args.measurements, peaks=joint)
    # the gap law and speeds the base scene leaves out are filled in before the integrator
    # is chosen (from the data's errors, or the scene's own), so that auto chooses for the
    # scene that runs
    base, src = complete_base(load_scene(args.scene, args.set), meas)
    base = choose_setting(base, meas, peaks=joint, source=f"{args.measurements}, ")[0]
    if joint:
        named = next(w.strip() for w in str(args.fit).split(",") if w.strip() != "gap_mean")
        try:
            check_fit_base(base, rng.fk)
        except SceneError as exc:
            raise GranchainError(f"{args.scene}: {exc} (--fit names {named})") from None
        return _infer_joint(args, meas, base, src, rng)
    check_grid(base, args, src)
    res = infer(base, meas, gap_max=args.gap_max_nm * 1e-9, gap_points=args.gap_points,
                realisations=args.realisations, cache_dir=None if args.no_cache else args.cache_dir,
                source=f"{args.measurements}, ", prior=args.prior, progress=show_progress(args))
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


def _infer_joint(args, meas, base, src, rng: FitRange) -> int:
    from ..inference import infer_joint
    check_joint_grid(base, args, src, rng)
    res = infer_joint(base, meas, gap_max=args.gap_max_nm * 1e-9, gap_points=args.gap_points,
                      e_min=rng.lo, e_points=rng.points, realisations=args.realisations,
                      cache_dir=None if args.no_cache else args.cache_dir,
                      source=f"{args.measurements}, ", prior=args.prior,
                      progress=show_progress(args), key=rng.fk.path, hi=rng.hi)
    return _report_inference(args, res, meas, base, _print_joint_inference,
                             "plot_joint_inference")


def _report_inference(args, res, meas, base, print_human, plot: str) -> int:
    """An inference's output: its JSON document (stdout with --json, the file --out) or
    the human summary, and with --plot the figure of ``figures.inference.<plot>``
    (matplotlib is loaded only then)."""
    doc = dict(res.to_json(), measurements=str(args.measurements))
    emit(args, doc, lambda: print_human(res))
    if args.plot:
        from ..figures import inference as figs
        getattr(figs, plot)(res, meas, base, args.plot, force=args.force)
    return 0
