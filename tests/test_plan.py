"""The run plan (granchain.runplan): computed once per run, and the one cost estimate that
auto, the cost guard and the workflow's batches read."""
from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import granchain

from granchain import costmodel, stoprule
from granchain import runplan as plan_mod
from granchain import workflow as gw
from granchain.workflow.batches import realisation_limit
from granchain.errors import GranchainError
from granchain.runplan import plan_run
from granchain.scene import scene_from_dict

EFFECTS = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]


def _scene(method="auto", gap_nm=20.0, v=(0.05, 0.1), **integrator):
    gaps = ({"distribution": "uniform", "mean": gap_nm * 1e-9, "seed": 3} if gap_nm
            else {"distribution": "none"})
    return scene_from_dict({"material": "ss440c", "striker": {"velocity": list(v)},
                            "gaps": gaps, "effects": EFFECTS,
                            "integrator": {"method": method, **integrator},
                            "ensemble": {"realisations": 2}})


def test_plan_resolves_auto_as_resolve_auto_does():
    """The plan's scene (its one setting for every speed) is the one resolve_auto gives
    (same setting, same hash), with auto's choice described, and each speed's own after
    it; a scene that is not auto runs as it is."""
    for tol in (1e-3, 1e-4, 1e-5):
        raw = _scene(tolerance=tol)
        p = plan_run(raw)
        assert p.scene.hash == plan_mod.resolve_auto(raw).hash
        assert p.auto.startswith(plan_mod.describe_auto(p.scene) + "; per striker speed: 0.05 m/s ")
    rk4 = _scene("rk4", dt=1e-9)
    assert plan_run(rk4).scene is rk4 and plan_run(rk4).auto == ""
    p = plan_run(rk4)
    assert plan_run(p) is p


def test_the_one_setting_plan_is_resolve_autos_scene():
    """per_speed=False plans auto's one setting for every striker speed: the scene
    resolve_auto gives, which a LAMMPS deck, the comparison of engines and the inference's
    grid run. A sweep whose fast striker alone would get a fixed step of its own, which
    the given dt refuses, keeps its one setting; the per-speed plan refuses it."""
    from granchain.errors import SceneError
    raw = scene_from_dict({"material": "ss440c", "chain": {"n": 8}, "probes": [2, 7],
                           "striker": {"velocity": [0.01, 1.0]},
                           "gaps": {"distribution": "uniform", "mean": 1.9e-7, "seed": 3},
                           "effects": ["hertz", "groove_friction", "rotation",
                                       "particle_friction"],
                           "integrator": {"method": "auto", "tolerance": 1e-4, "dt": 1e-9}})
    with pytest.raises(SceneError, match="integrator.dt"):
        plan_run(raw)
    one = plan_run(raw, per_speed=False)
    assert not one.per_speed and one.scene.method in ("adaptive", "event")
    assert one.scene.hash == plan_mod.resolve_auto(raw).hash
    for tol in (1e-3, 1e-4, 1e-5):
        sweep = _scene(tolerance=tol)
        one = plan_run(sweep, per_speed=False)
        assert not one.per_speed and one.scene.hash == plan_mod.resolve_auto(sweep).hash
        assert one.auto == plan_mod.describe_auto(one.scene)


def test_plan_estimates_match_the_planning_modules():
    """Per striker speed the plan holds the stop rule's sampling, duration, steps and record,
    guards' warnings; its whole-run estimate is costmodel.run_estimate's."""
    sc = _scene("verlet", dt=1e-9, v=(0.05, 0.1, 20.0))
    p = plan_run(sc)
    for sp in p.speeds:
        c = costmodel.cost_estimate(sc, sp.v_striker)
        assert sp.sample_dt == stoprule.sample_interval(sc, sp.v_striker)
        assert sp.estimate() == pytest.approx(c, rel=1e-12)
    assert any(p.at(20.0).warnings) and not p.at(0.1).warnings
    for eng in ("reference", "lammps"):
        for reals in (None, 3, [0, 4]):
            assert p.estimate(reals, eng) == pytest.approx(
                costmodel.run_estimate(sc, reals, eng), rel=1e-12)


def test_member_seconds_is_the_cost_auto_ranks_by():
    """At the setting auto picked, a member's estimated wall time summed over the
    scene's striker speeds is the measured wall time of that setting times the scene's
    work ratio: the cost auto minimised. A fixed step is the setting's steps per contact
    snapped to the step's grid: its wall time is interpolated log-log between the two
    measured settings around it (written out here). Each kind of plan (each speed its
    own setting, a fixed step, a tolerance method) is met by some case."""
    model = costmodel.load_model()
    kinds = {"per_speed": 0, "fixed": 0, "tolerance": 0}
    for gap in (0.0, 20.0, 190.0):
        for v in ((0.1,), (0.01, 0.05)):
            raw = _scene(gap_nm=gap, v=v, tolerance=1e-4)
            p = plan_run(raw)
            if p.per_speed:
                # each speed at its own setting: the cost of that speed's run alone
                alone = [plan_run(raw.derive(**{"striker.velocity": u})).member_seconds()
                         for u in v]
                assert len(alone) == len(v) >= 2 and all(a > 0 for a in alone)
                assert p.member_seconds() == pytest.approx(sum(alone), rel=1e-12)
                kinds["per_speed"] += 1
                continue
            cls = p.scene_class
            ratio = costmodel.work_ratio(raw, model, cls)[p.method]
            rows = [r for r in model.envelope("v_g", cls) if r["method"] == p.method]
            if p.method in ("adaptive", "event"):
                row = next(r for r in rows if r["tolerance"] == p.scene.tolerance)
                wall = row["wall_s_per_chain"]
                kinds["tolerance"] += 1
            else:
                n = p.scene.contact_time(max(v)) / p.scene.dt
                pts = sorted((r["steps_per_contact"], r["wall_s_per_chain"]) for r in rows)
                (n0, w0), (n1, w1) = next((a, b) for a, b in zip(pts, pts[1:])
                                          if a[0] <= n <= b[0])
                # auto's setting is a measured one; snapping dt moves it by a few %
                assert min(abs(math.log(n / n0)), abs(math.log(n / n1))) < 0.05, (n, n0, n1)
                wall = w0 * (w1 / w0) ** (math.log(n / n0) / math.log(n1 / n0))
                kinds["fixed"] += 1
            assert p.member_seconds() == pytest.approx(wall * ratio, rel=1e-9)
    assert all(kinds.values()), kinds


def test_setting_seconds_interpolates_between_measured_settings():
    """At a measured setting: its wall time; between two: between theirs; beyond the
    finest fixed step: in proportion to the steps."""
    model = costmodel.load_model()
    rows = [r for r in model.envelope("v_g", "gapped") if r["method"] == "rk4"]
    rows.sort(key=lambda r: r["steps_per_contact"])
    for a, b in zip(rows, rows[1:]):
        wa, wb = a["wall_s_per_chain"], b["wall_s_per_chain"]
        assert model.setting_seconds("rk4", "gapped",
                                     steps_per_contact=a["steps_per_contact"]) == pytest.approx(wa)
        mid = model.setting_seconds("rk4", "gapped", steps_per_contact=math.sqrt(
            a["steps_per_contact"] * b["steps_per_contact"]))
        assert min(wa, wb) <= mid <= max(wa, wb)
    top = rows[-1]
    assert model.setting_seconds("rk4", "gapped", steps_per_contact=4 * top["steps_per_contact"]) \
        == pytest.approx(4 * top["wall_s_per_chain"])
    with pytest.raises(GranchainError, match="no lammps rows"):
        model.setting_seconds("lammps", "gapped", steps_per_contact=100)


def test_run_scene_plans_once(monkeypatch):
    """run_scene of an auto scene asks the cost model for auto's settings once (the
    sweep's, and each speed's) and computes each striker speed's sampling and duration once (the engine aside); given a plan, not
    at all."""
    from granchain import simulate
    calls = {"auto": 0, "dur": 0}
    real_auto, real_dur = plan_mod.auto_setting, plan_mod.expected_duration

    def auto(*a, **k):
        calls["auto"] += 1
        return real_auto(*a, **k)

    def dur(*a, **k):
        calls["dur"] += 1
        return real_dur(*a, **k)

    monkeypatch.setattr(plan_mod, "auto_setting", auto)
    monkeypatch.setattr(plan_mod, "expected_duration", dur)

    def fake_trajectories(scene, mem, engine="reference", **kw):
        raise RuntimeError("stop before the engine")

    monkeypatch.setattr(simulate, "trajectories", fake_trajectories)
    raw = _scene(tolerance=1e-4)
    with pytest.raises(RuntimeError, match="stop before"):
        simulate.run_scene(raw)
    # the sweep's one setting, then each speed's own
    assert calls == {"auto": 1 + len(raw.striker_velocities), "dur": len(raw.striker_velocities)}
    p = plan_run(raw)
    calls.update(auto=0, dur=0)
    with pytest.raises(RuntimeError, match="stop before"):
        simulate.run_scene(p)
    assert calls == {"auto": 0, "dur": 0}


def test_the_reference_engine_reads_the_plans_sampling(monkeypatch):
    """The engine takes each speed's sample interval and expected duration from the plan
    (it computes neither itself), with the same results as when it plans the scene
    itself; without a plan it asks the plan module for one."""
    from granchain import simulate
    from granchain.engines import reference
    from granchain.gaps import member_gaps, members
    sc = scene_from_dict({"material": "ss440c", "chain": {"n": 6}, "probes": [2, 5],
                          "striker": {"velocity": [0.05, 0.1]},
                          "gaps": {"distribution": "uniform", "mean": 2e-8, "seed": 3},
                          "effects": EFFECTS, "integrator": {"method": "verlet", "dt": 1e-9},
                          "ensemble": {"realisations": 2}})
    mem = members(sc)
    alone = [s.v_max for s in (summarize_all(reference.run(
        sc, member_gaps(sc, mem), [m.v_striker for m in mem], trace=False), sc))]
    p = plan_run(sc)

    def refuse(*a, **k):
        raise AssertionError("the engine recomputed what the plan holds")

    monkeypatch.setattr(plan_mod, "sample_interval", refuse)
    monkeypatch.setattr(plan_mod, "expected_duration", refuse)
    assert [r.v_max for r in simulate.run_scene(p)] == alone
    with pytest.raises(AssertionError, match="recomputed"):
        next(reference.run(sc, member_gaps(sc, mem)[:1], [0.05]))


def _names_in(paths, names) -> list[str]:
    """'file:line name' of every use of one of ``names`` (a name, an attribute or an
    imported name) in the Python files ``paths``."""
    out = []
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            used = ([a.name for a in node.names] if isinstance(node, ast.ImportFrom)
                    else [node.id] if isinstance(node, ast.Name)
                    else [node.attr] if isinstance(node, ast.Attribute) else [])
            out += [f"{path.name}:{node.lineno} {u}" for u in used if u in names]
    return out


PACKAGE = Path(granchain.__file__).parent
AUTO_CHOICE = {"resolve_auto", "auto_setting", "apply_auto"}
PLANNERS = {"sample_interval", "expected_duration", "auto_t_max"}


def test_only_the_run_plan_chooses_method_auto():
    """Method auto's choice (resolve_auto, auto_setting, apply_auto) is named in
    granchain/runplan.py only: every other module of the package takes the scene that runs
    from the run plan (plan_run(scene).scene)."""
    files = sorted(PACKAGE.rglob("*.py"))
    assert len(files) > 50 and _names_in([PACKAGE / "runplan.py"], AUTO_CHOICE)
    outside = _names_in([f for f in files if f != PACKAGE / "runplan.py"], AUTO_CHOICE)
    assert not outside, outside


def test_the_engines_plan_nothing_themselves():
    """No module of the engines (granchain/engines, granchain/lammps) names the stop
    rule's planners (sample interval, expected duration, time cap): they read them from
    the run plan (SpeedPlan)."""
    files = sorted((PACKAGE / "engines").glob("*.py")) + sorted((PACKAGE / "lammps").glob("*.py"))
    assert len(files) > 10 and _names_in([PACKAGE / "runplan.py"], PLANNERS)
    assert not _names_in(files, PLANNERS), _names_in(files, PLANNERS)


def _packed(method, **integrator):
    return scene_from_dict({"material": "ss440c", "chain": {"n": 6}, "probes": [2, 5],
                            "striker": {"velocity": [0.05, 0.1]}, "gaps": {"distribution": "none"},
                            "effects": EFFECTS, "integrator": {"method": method, **integrator}})


def _scaled(p, factor):
    """The plan ``p`` with every speed's sample interval times ``factor``."""
    return dataclasses.replace(p, speeds=tuple(
        dataclasses.replace(sp, sample_dt=factor * sp.sample_dt) for sp in p.speeds))


@pytest.mark.parametrize("method,integrator", [("rk4", {"dt": 1e-9}),
                                               ("adaptive", {"tolerance": 1e-8}),
                                               ("event", {"tolerance": 1e-6})])
def test_the_reference_engine_samples_as_its_speed_plans_say(monkeypatch, method, integrator):
    """Each chain's sample interval is its SpeedPlan's sample_dt (on a fixed step, the
    whole steps nearest it: runplan.step_grid), and its sample count SpeedPlan.sample_count's:
    a plan with other values gives another grid and another length."""
    from granchain.engines import reference
    from granchain.runplan import step_grid
    sc = _packed(method, **integrator)
    p3 = _scaled(plan_run(sc), 3.0)
    gaps = np.zeros((2, sc.n - 1))
    for tr, sp in zip(reference.run(sc, gaps, [0.05, 0.1], trace=True, plan=p3), p3.speeds):
        want = step_grid(sp.sample_dt, sc.dt)[1] if method == "rk4" else sp.sample_dt
        assert tr.info.sample_dt == want
        assert np.allclose(np.diff(tr.t), want, rtol=1e-9, atol=0)
        assert tr.status == "passed"
    # 20 samples: the wave is still in the chain, so the chain stops there (timeout)
    monkeypatch.setattr(plan_mod.SpeedPlan, "sample_count", lambda self, gaps, sdt: 20)
    for tr in reference.run(sc, gaps, [0.05, 0.1], trace=True, plan=p3):
        assert len(tr.t) == 20 and tr.status == "timeout"


def test_the_reference_engines_chunks_follow_the_plans_durations():
    """A chain's record, which sizes the chunks (adaptive method, t_end auto), is its
    slowest speed's SpeedPlan.duration_s over the sample interval."""
    from granchain.effects import physics_terms
    from granchain.engines import reference
    sc = _packed("adaptive", tolerance=1e-8)
    p = plan_run(sc)
    sdt = p.speeds[0].sample_dt

    def cut(plan):
        return [len(c) for c, _ in reference._chunks(np.arange(100), sc, physics_terms(sc), sdt,
                                                        "adaptive", False, plan)]
    assert cut(p) == [100]
    longer = dataclasses.replace(p, speeds=tuple(
        dataclasses.replace(sp, duration_s=1e6 * sp.duration_s) for sp in p.speeds))
    assert cut(longer) == [1] * 100


def test_the_lammps_deck_runs_as_its_speed_plans_say(monkeypatch):
    """The deck plan takes its cadence from the finest SpeedPlan.sample_dt (runplan.step_grid
    on the scene's step), its run length from the longest SpeedPlan.run_length, and each
    chain's sample cap (where the LAMMPS engine cuts a chain the wave has not left) from
    SpeedPlan.sample_count."""
    from granchain.engines.lammps import auto_stop
    from granchain.lammps.deck import plan as deck_plan
    from granchain.runplan import step_grid
    sc = _packed("rk4", dt=1e-9)
    p = plan_run(sc)
    for plan in (p, _scaled(p, 3.0)):
        pl = deck_plan(sc, run_plan=plan)
        fine = min(sp.sample_dt for sp in plan.speeds)
        assert (pl.every, pl.sample_dt) == step_grid(fine, sc.dt)
        assert pl.chain_samples.tolist() == [sp.sample_count(g, pl.sample_dt)
                                             for sp, g in zip(plan.speeds, pl.gaps)]
    monkeypatch.setattr(plan_mod.SpeedPlan, "run_length", lambda self, gaps: 1e-3 * self.v_striker)
    monkeypatch.setattr(plan_mod.SpeedPlan, "sample_count", lambda self, gaps, sdt: 7)
    pl = deck_plan(sc, run_plan=p)
    assert pl.nsteps == math.ceil(1e-4 / pl.sample_dt - 1e-9) * pl.every
    assert pl.chain_samples.tolist() == [7, 7]
    # the engine's cut: a chain the wave has not left stops at its cap
    assert auto_stop(7, 0.1, np.zeros(50), np.ones(50)) == (7, "timeout")


def test_auto_chooses_per_striker_speed():
    """Method auto on a sweep gives each striker speed the cheapest setting for itself
    (190 nm gaps at 1e-4: the event method for the slow striker, where the flight between
    contacts is long, a fixed step for the fast one). The reference engine runs each
    member with its speed's setting: the same results, bit for bit, as the speed's own
    scene resolved and run alone; the plan's one setting stays for LAMMPS."""
    from granchain import simulate
    sc = scene_from_dict({"material": "ss440c", "chain": {"n": 8}, "probes": [2, 7],
                          "striker": {"velocity": [0.01, 1.0]},
                          "gaps": {"distribution": "uniform", "mean": 1.9e-7, "seed": 3},
                          "effects": EFFECTS, "integrator": {"method": "auto", "tolerance": 1e-4},
                          "ensemble": {"realisations": 2}})
    p = plan_run(sc)
    slow, fast = p.at(0.01).scene, p.at(1.0).scene
    assert p.per_speed and slow.method == "event" and fast.method in ("rk4", "verlet")
    assert "per striker speed: 0.01 m/s event" in p.auto
    # each speed's setting is auto's own choice for that speed alone
    for v, own in ((0.01, slow), (1.0, fast)):
        alone = plan_mod.resolve_auto(sc.derive(**{"striker.velocity": v}))
        assert (own.method, own.dt, own.tolerance) == (alone.method, alone.dt, alone.tolerance)
    res = simulate.run_scene(p)
    assert [r.member for r in res] == list(range(4))
    assert sorted((r.v_striker, r.method) for r in res) == [
        (0.01, "event"), (0.01, "event"), (1.0, fast.method), (1.0, fast.method)]
    for v in (0.01, 1.0):
        alone = simulate.run_scene(plan_mod.resolve_auto(sc.derive(**{"striker.velocity": v})))
        assert [r.v_max for r in res if r.v_striker == v] == [r.v_max for r in alone]
        assert [r.realisation for r in res if r.v_striker == v] == [0, 1]
    # LAMMPS runs the plan's one setting: its estimate is that setting's, per speed
    for sp in p.speeds:
        assert sp.seconds[1] == costmodel.member_seconds(p.scene, sp.v_striker, "lammps")
        assert sp.seconds[0] == costmodel.member_seconds(sp.scene, sp.v_striker, "reference")
    # one setting for every speed: no per-speed scenes
    one = plan_run(sc.derive(**{"striker.velocity": [0.01, 0.01]}))
    assert not one.per_speed


def summarize_all(trajs, sc):
    from granchain.observables import summarize
    return [summarize(t, sc.probes) for t in trajs]


def test_run_scene_cost_guard_reads_the_plan():
    """The per-chain guard refuses from the plan's estimates, naming the limit."""
    from granchain.simulate import run_scene
    sc = _scene("rk4", dt=1e-9, v=(1e-4,), gap_nm=190.0)
    steps = max(sp.steps for sp in plan_run(sc).speeds)
    with pytest.raises(GranchainError, match="--max-steps"):
        run_scene(sc, max_steps=steps / 2)


def _gap_study_preset(method: dict):
    cfg = gw.read_config("config/config.yaml", "tiny")
    _, preset = gw.select_preset(cfg)
    preset = {**preset, "base": {**preset["base"], **method},
              "batch": {**preset["batch"], "members_per_job": 8}}
    spec = {"materials": ["ss440c"], "gap_mean_nm": [10, 190], "v_striker": [0.02, 0.5],
            "realisations": 12}
    preset["studies"] = {**preset["studies"], "gap_sweep": spec}
    return preset


@pytest.mark.parametrize("method", [{"method": "rk4"}, {"method": "event", "tolerance": 1.0e-6}])
def test_batches_are_balanced_by_the_plans_cost(method):
    """A study whose realisations cost unlike amounts (10 and 190 nm gaps at a fixed step;
    equal under the event method) is cut into jobs of about equal estimated cost: each
    job's estimate is its members' run-plan cost, and no job is further from the mean
    than one realisation's cost."""
    preset = _gap_study_preset(method)
    scenes = gw.study_scenes(preset, "gap_sweep")
    jobs = gw.batches(preset, "gap_sweep", scenes=scenes)
    assert len(jobs) == math.ceil(sum(ss.members for ss in scenes) / 8)
    # a job's estimate is one core's: the cost model's wall times were measured on its
    # threads
    cores = costmodel.load_model().threads
    costs = {ss.index: ss.plan.member_seconds("reference") * cores for ss in scenes}
    if method["method"] == "rk4":
        assert costs[1] > 3 * costs[0]         # the wide gaps' flight costs fixed steps
    for b in jobs:
        assert b.est_seconds == pytest.approx(
            sum(costs[si] * len(reals) for si, reals in b.units), rel=1e-12)
    mean = sum(b.est_seconds for b in jobs) / len(jobs)
    assert max(abs(b.est_seconds - mean) for b in jobs) <= max(costs.values()) * (1 + 1e-9)


@pytest.mark.parametrize("study", ["adhesion", "plasticity", "dissipation", "gap_sweep"])
def test_a_law_that_can_hold_the_wave_gives_its_jobs_time_to_the_cap(study):
    """A chain whose law acts on the normal force after Hertz's (adhesion, yielding,
    damping) can stall or stay bound and run to its cap (``benchmarks/estimates.py``: up
    to 265x the estimate), so its job's runtime limit allows each such chain its cap:
    each speed's estimate times its cap over its expected duration. An elastic chain's
    limit is its estimate (the gap sweep's, and each study's chain without the law)."""
    from granchain.effects import may_hold_wave
    cfg = gw.read_config(Path(granchain.__file__).parents[1] / "config" / "config.yaml",
                         "tiny")
    _, preset = gw.select_preset(cfg)
    scenes = gw.study_scenes(preset, study)
    held_any = False
    for b in gw.batches(preset, study, scenes=scenes):
        want = 0.0
        for si, reals in b.units:
            ss = scenes[si]
            held = may_hold_wave(ss.scene.effects)
            held_any |= held
            gaps = np.full(ss.scene.n - 1, ss.gap_mean_nm * 1e-9)
            for sp in ss.plan.speeds:
                ratio = sp.run_length(gaps) / sp.duration_s if held else 1.0
                assert ratio > 5.0 or not held          # the cap: many passages
                want += sp.seconds[0] * ratio * len(reals)
        assert b.limit_seconds == pytest.approx(want * costmodel.load_model().threads,
                                                rel=1e-9)
    assert held_any == (study != "gap_sweep")


# One realisation (every striker speed, one thread) of full-preset adhesion scenes under
# the event method at 1e-6, measured by ``benchmarks/estimates.py --study adhesion
# --match ... --method event --tolerance 1e-6 --realisations 1`` (2026-12-01, 2-core
# machine, load 0.4-1.1): one or two chains of each stayed bound as a whole to their cap
MEASURED_BOUND = {"adhesion-ss316-gap190nm-jkr1": 61.47, "adhesion-ss440c-gap47nm-jkr2": 30.01}


def test_the_event_method_on_a_chain_that_can_bind_gets_its_cap_in_its_job_limit():
    """Under the event method, a chain that a law holding contacts closed binds as a
    whole (adhesion) vibrates in every contact until its cap; the event estimate counts
    one passage per contact, and scaled to the cap it was 2.9-5.3x below what such
    scenes measured. The job limit of one realisation allows at least the measured time
    (the workflow's runtime adds its margin on top), and at least every contact active
    to the cap (``costmodel.held_seconds``) at every speed; a scene without the law keeps
    its estimate."""
    cfg = gw.read_config(Path(granchain.__file__).parents[1] / "config" / "config.yaml",
                         "full")
    study = cfg["presets"]["full"]["studies"]["adhesion"]
    study.update(method="event", tolerance=1e-6)
    _, preset = gw.select_preset(cfg)
    scenes = {ss.scene.name: ss for ss in gw.study_scenes(preset, "adhesion")}
    threads = costmodel.load_model().threads
    for name, wall in MEASURED_BOUND.items():
        ss = scenes[name]
        assert {sp.scene.method for sp in ss.plan.speeds} == {"event"}
        limit = realisation_limit(ss, "reference")
        assert limit >= wall, (name, limit, wall)
        gaps = np.full(ss.scene.n - 1, ss.gap_mean_nm * 1e-9)
        held = sum(costmodel.held_seconds(sp.scene, sp.v_striker, sp.run_length(gaps))
                   for sp in ss.plan.speeds)
        assert limit >= threads * held * (1 - 1e-12)
    plain = [ss for ss in scenes.values() if "adhesion" not in ss.scene.effects]
    assert plain
    for ss in plain:
        assert realisation_limit(ss, "reference") == gw.realisation_cost(ss, "reference")


def test_a_laws_step_cost_scales_its_estimate():
    """The estimate of a chain with a law costlier per step than the cost model's chain
    (JKR's contact radius, Thornton's history: ``EffectSpec.step_cost``) is the same
    chain's without it times that cost."""
    from granchain.effects import SPECS
    base = {"name": "c", "material": "ss316", "chain": {"n": 15},
            "striker": {"velocity": 0.1}, "gaps": {"distribution": "uniform", "mean": 2e-8},
            "integrator": {"method": "verlet", "dt": 1e-9}, "probes": [2, 13]}
    for law, effects, section in (
            ("adhesion", ["hertz", "groove_friction", "air_drag", "rotation",
                          "particle_friction"], {"adhesion": {"model": "jkr",
                                                              "surface_energy": 0.1}}),
            ("plastic_contact", ["hertz", "groove_friction", "air_drag", "rotation"], {})):
        assert SPECS[law].step_cost > 1.0
        plain = scene_from_dict({**base, "effects": effects})
        with_law = scene_from_dict({**base, "effects": effects + [law], **section})
        assert costmodel.member_seconds(with_law, 0.1) == pytest.approx(
            SPECS[law].step_cost * costmodel.member_seconds(plain, 0.1), rel=1e-12)
