"""The run plan: everything decided about a scene before an engine starts, computed once.

:func:`plan_run` takes a scene (method auto or not) and returns one frozen
:class:`RunPlan`: the scene that runs (auto's choice from the packaged cost model), and
per striker speed (:class:`SpeedPlan`) its sample interval, expected duration, sample
count, integration steps, sample record, estimated wall time (``costmodel.member_seconds``,
the one per-member cost estimate) and physics warnings. ``simulate.run_scene`` runs from it
(cost guard, warnings), the workflow's batches balance and time their jobs with it, and
auto's choice reads its durations and sample intervals.

Both engines take their sampling and run length from it and compute neither themselves:
the reference engine each chain's sample interval (:attr:`SpeedPlan.sample_dt`, on a fixed
step :func:`step_grid`) and sample count (:meth:`SpeedPlan.sample_count`), and the
expected durations that size its chunks; the LAMMPS deck its cadence and run length
(``lammps.deckplan.plan``).

Method auto is chosen here and nowhere else: :func:`auto_setting` gives the setting of the
scene's class whose v_g error (``AUTO_OBSERVABLE``: arrival-time v_g on gapped chains)
meets ``integrator.tolerance`` with a margin (``AUTO_SAFETY``), and keeps meeting it at
every finer setting of its method (the envelope: a lucky cancellation at a coarse step is
never taken for accuracy), at the least wall time on this scene: the measured wall time
times the scene's work over the measurement's (``costmodel.chain_work``; a slow striker
over wide gaps multiplies the fixed-step cost, not the event method's). A run plans it
once, with the rest of its plan; the one setting for every striker speed is
``plan_run(scene, per_speed=False).scene``.

numpy only (no numba, scipy or engine), like the modules it draws on: ``stoprule``
(sampling, duration, the time cap), ``costmodel`` (the cost model, steps, wall time),
``guards`` (warnings).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from . import costmodel
from .effects import switching
from .errors import SceneError
from .guards import physics_warnings
from .scene import Scene
from .scenekeys import TOLERANCE_METHODS
from .stoprule import auto_t_max, expected_duration, sample_interval
from .costmodel import (DAMPED, DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_STEPS, SCENE_METHODS, CostModel,
                        check_cost, cost_estimate, fixed_step, load_model, scene_class,
                        work_ratio)

ENGINES = ("reference", "lammps")
# method auto takes the cheapest setting whose measured error is <= tolerance / AUTO_SAFETY:
# on other scenes (316 and 440C, 0.03-0.5 m/s, packed and 10-190 nm gaps) the error of a
# setting at the same N was up to 2.3x the model's (docs/explanation/physics.md, "What
# accuracy costs in time").
AUTO_SAFETY = 4.0
# the observable whose error auto bounds, per scene class: the peak-time v_g of a packed
# chain; the arrival-time v_g (half-peak crossings) of a gapped one, whose probes often
# peak on a flight plateau where the peak time is set to a few 1e-5 by the sample grid;
# on a damped one the arrival-time v_g, as its class holds gapped chains
AUTO_OBSERVABLE = {"packed": "v_g", "gapped": "v_g_front", DAMPED: "v_g_front"}


def step_grid(sample_dt: float, dt: float) -> tuple[int, float]:
    """(every, interval) of a sample grid on a fixed step ``dt``: a sample every ``every``
    steps (the whole number of steps nearest ``sample_dt``, at least one), which are
    ``every * dt`` s apart (the reference engine's fixed-step methods, the LAMMPS deck)."""
    every = max(1, int(round(sample_dt / dt)))
    return every, every * dt


@dataclass(frozen=True)
class SpeedPlan:
    """One striker speed of a run plan: what one chain (member) at that speed needs.
    ``scene``: the scene its chains run with on the reference engine (under method auto,
    the setting chosen for this speed alone). The engines read its sample interval,
    duration (sizing the reference engine's chunks), :meth:`run_length` and
    :meth:`sample_count`."""
    scene: Scene
    v_striker: float
    sample_dt: float            # s, stoprule.sample_interval
    duration_s: float           # simulated time, stoprule.expected_duration
    steps: float                # integration steps (costmodel.cost_estimate)
    samples: float              # expected samples, t = 0 included (costmodel.cost_estimate)
    record_bytes: float         # its sample record
    seconds: tuple[float, ...]  # estimated wall time of one chain, per engine (ENGINES)
    warnings: tuple[str, ...]   # guards.physics_warnings

    def estimate(self) -> dict:
        """Its ``costmodel.cost_estimate`` (duration_s, steps, samples, record_bytes)."""
        return {"duration_s": self.duration_s, "steps": self.steps, "samples": self.samples,
                "record_bytes": self.record_bytes}

    def run_length(self, gaps) -> float:
        """Simulated time (s) a chain at this speed with ``gaps`` (its n-1 gaps, m) runs
        at most: the scene's t_end or, with t_end auto, the stop rule's cap
        (``stoprule.auto_t_max``; 0 for a striker at rest)."""
        if self.scene.t_end is not None:
            return self.scene.t_end
        if not self.v_striker > 0:
            return 0.0
        return auto_t_max(self.scene, gaps, self.v_striker)

    def sample_count(self, gaps, sample_dt: float) -> int:
        """Samples (t = 0 included) of a chain with ``gaps`` on a grid of ``sample_dt``
        (s): its :meth:`run_length` over ``sample_dt``, rounded up, plus one. With t_end
        auto that is the cap, where the chain stops unless the wave has left it first;
        a striker at rest keeps its initial sample only."""
        if self.scene.t_end is not None:
            return int(math.ceil(self.scene.t_end / sample_dt - 1e-9)) + 1
        if not self.v_striker > 0:
            return 1
        return int(math.ceil(self.run_length(gaps) / sample_dt)) + 1


@dataclass(frozen=True)
class RunPlan:
    """The plan of one scene's run. ``scene``: the scene that runs (method auto
    resolved, one setting for every striker speed); ``auto``: auto's choice as text
    (:func:`describe_auto`), "" unless the scene asked for auto; ``scene_class``:
    the cost model's class (packed, gapped, damped); ``speeds``: one :class:`SpeedPlan` per
    striker speed, in the scene's order; ``model``: the cost model it was planned with
    (None: the packaged one).

    Under method auto each striker speed gets the cheapest setting for itself
    (``SpeedPlan.scene``), which the reference engine runs: a sweep may run its slow
    strikers with the event method and its fast ones with a fixed step. ``scene`` is the
    one setting for all of them, for what takes a single step (a LAMMPS deck, the
    comparison of engines); ``per_speed`` says whether the speeds' settings differ."""
    scene: Scene
    auto: str
    scene_class: str
    speeds: tuple[SpeedPlan, ...]
    model: CostModel | None = dataclasses.field(default=None, compare=False, repr=False)

    @property
    def method(self) -> str:
        return self.scene.method

    @property
    def dt(self) -> float:
        return self.scene.dt

    @property
    def tolerance(self) -> float | None:
        return self.scene.tolerance if self.scene.method in TOLERANCE_METHODS else None

    def at(self, v: float) -> SpeedPlan:
        """The plan of striker speed ``v``."""
        for sp in self.speeds:
            if sp.v_striker == float(v):
                return sp
        raise KeyError(f"scene '{self.scene.name}' has no striker speed {v:g} m/s")

    def speed(self, v: float) -> SpeedPlan:
        """The plan of striker speed ``v`` for an engine: the scene's own (:meth:`at`) or,
        for a speed the scene lacks (an engine given other speeds), one planned here for
        ``scene`` at ``v``."""
        v = float(v)
        for sp in self.speeds:
            if sp.v_striker == v:
                return sp
        return _speed_plan(self.scene, self.scene, v, sample_interval(self.scene, v),
                           expected_duration(self.scene, v), self.model)

    @property
    def per_speed(self) -> bool:
        return any(sp.scene is not self.scene for sp in self.speeds)

    @property
    def warnings(self) -> list[str]:
        """Warnings of every striker speed, in order, without repeats."""
        return list(dict.fromkeys(w for sp in self.speeds for w in sp.warnings))

    def member_seconds(self, engine: str = "reference") -> float:
        """Estimated wall time (s) of one realisation: every striker speed's chain."""
        k = ENGINES.index(engine)
        return sum(sp.seconds[k] for sp in self.speeds)

    def estimate(self, realisations=None, engine: str = "reference", *, trace: bool = False,
                 speeds_apart: bool = False) -> dict:
        """``costmodel.run_estimate`` of the run (``realisations``: a count or indices;
        the scene's own count if None) from this plan."""
        k = ENGINES.index(engine)
        return costmodel.estimate_run(self.scene, [sp.estimate() for sp in self.speeds],
                                      [sp.seconds[k] for sp in self.speeds], realisations,
                                      engine, trace=trace, speeds_apart=speeds_apart)

    def check(self, max_steps: float = DEFAULT_MAX_STEPS,
              max_memory_gb: float = DEFAULT_MAX_MEMORY_GB) -> None:
        """The per-chain cost guard (``costmodel.check_cost``) on this plan's estimates."""
        check_cost(self.scene, max_steps, max_memory_gb,
                   estimates=[sp.estimate() for sp in self.speeds])


def plan_run(scene: Scene | RunPlan, model: CostModel | None = None, *,
             per_speed: bool = True) -> RunPlan:
    """The run plan of ``scene`` (a plan is returned as it is). Each striker speed's
    sample interval and expected duration are computed once (neither depends on the
    integrator); auto's choice reads them; the steps, record, wall time and warnings
    follow for the scene that runs. ``per_speed``: under method auto, each striker speed
    of a sweep may get its own setting (the reference engine's run, ``SpeedPlan.scene``);
    False gives every speed the one setting (``RunPlan.scene``), for a caller that runs
    or writes that scene as it is (a LAMMPS deck, the comparison of engines, the
    inference's grid), so a setting that only one speed alone would get (and might
    refuse, e.g. a given dt) plays no part."""
    if isinstance(scene, RunPlan):
        return scene
    vs = [float(v) for v in scene.striker_velocities]
    sdt = {v: sample_interval(scene, v) for v in vs}
    dur = {v: expected_duration(scene, v) for v in vs}
    auto = ""
    own: dict[float, Scene] = {}
    if scene.method == "auto":
        model = model or load_model()
        setting = auto_setting(scene, model, durations=dur, sample_dts=sdt)
        whole = apply_auto(scene, setting)
        if per_speed and len(set(vs)) > 1:
            own = _auto_per_speed(scene, whole, model, dur, sdt)
        scene = whole
        auto = describe_auto(scene)
        if own:
            auto += "; per striker speed: " + ", ".join(
                f"{v:g} m/s {describe_auto(own[v]).split('-> ', 1)[1]}"
                for v in dict.fromkeys(vs))
    speeds = tuple(_speed_plan(scene, own.get(v, scene), v, sdt[v], dur[v], model)
                   for v in vs)
    return RunPlan(scene, auto, scene_class(scene, model), speeds, model)


def _speed_plan(scene: Scene, sc: Scene, v: float, sdt: float, dur: float,
                model: CostModel | None) -> SpeedPlan:
    """The plan of striker speed ``v`` whose chains run ``sc`` on the reference engine
    and ``scene`` (the plan's one setting) on LAMMPS; ``sdt``, ``dur``: its sample
    interval and expected duration."""
    c = cost_estimate(sc, v, duration=dur, sample_dt=sdt)
    # LAMMPS runs the plan's one setting for every speed
    lc = c if sc is scene else cost_estimate(scene, v, duration=dur, sample_dt=sdt)
    secs = (costmodel.member_seconds(sc, v, "reference", model, duration=dur,
                                     steps=c["steps"]),
            costmodel.member_seconds(scene, v, "lammps", model, duration=dur,
                                     steps=lc["steps"]))
    return SpeedPlan(sc, v, sdt, dur, c["steps"], c["samples"], c["record_bytes"], secs,
                     tuple(physics_warnings(sc, v)))


def _auto_per_speed(scene: Scene, whole: Scene, model, dur, sdt) -> dict[float, Scene]:
    """Striker speed -> its own resolved scene (that speed alone, auto's cheapest setting
    for it), or {} when every speed gets the setting of ``whole`` (the sweep's choice). A speed
    alone has one sample interval, so the fixed steps stay on offer where a sweep of
    several intervals could not align them."""
    own = {}
    for v in dict.fromkeys(scene.striker_velocities):
        v = float(v)
        if v <= 0:
            continue
        alone = scene.derive(**{"striker.velocity": v})
        pick = auto_setting(alone, model, durations={v: dur[v]}, sample_dts={v: sdt[v]})
        own[v] = apply_auto(alone, pick)
    if all(o.method == whole.method and o.dt == whole.dt and o.tolerance == whole.tolerance
           for o in own.values()):
        return {}
    return own


# ---------------------------------------------------------------------------------------
# method auto: the setting it chooses from the cost model
# ---------------------------------------------------------------------------------------
def _round_up(x: float) -> float:
    """x rounded up to two significant digits (a bound that prints as what it is)."""
    if not (x > 0 and math.isfinite(x)):
        return x
    e = math.floor(math.log10(x)) - 1
    return math.ceil(round(x / 10.0**e, 9)) * 10.0**e


def auto_setting(scene: Scene, model: CostModel | None = None, *,
                 durations: dict | None = None, sample_dts: dict | None = None
                 ) -> tuple[str, float, float | None]:
    """(method, dt, tolerance) of the cheapest setting meeting ``scene.tolerance`` on v_g
    (``AUTO_OBSERVABLE`` of the scene's class) with a margin: its measured error
    (envelope) is <= tolerance / AUTO_SAFETY. Cheapest on this scene: measured wall time
    times ``costmodel.work_ratio`` (the cost ``costmodel.member_seconds`` gives the scene
    at that setting, summed over its striker speeds). The event method is offered only on
    chains no longer than the model measured it on (its step count grows faster than n).
    On a scene with a law that switches (``effects.switching``) which the model did not
    measure (``CostModel.measured_effects``: adhesion, plastic_contact) it is the only
    method offered: a fixed step loses its order at each switch, while the event method
    ends a step on each one (no setting there if the event method is not offered:
    SceneError).

    Pure: reads only the scene and the cost model (rows of the scene's class: packed,
    gapped or damped, ``costmodel.scene_class``). dt = ``costmodel.fixed_step(scene,
    N)``, as in the measurement, so that the samples fall on the reference's. With
    several sample intervals (a sweep of striker speeds at auto sampling) that cannot
    hold for every member, so when the target is below the measured misalignment floor
    only the tolerance methods are used. They keep the scene's dt as their first step
    and get the model's tolerance as their rtol.
    ``durations`` and ``sample_dts`` (striker speed -> ``stoprule.expected_duration``,
    ``stoprule.sample_interval``): the run plan's, if already computed
    (:func:`plan_run`)."""
    model = model or load_model()
    tol = float(scene.tolerance)
    target = tol / AUTO_SAFETY
    cls = scene_class(scene, model)
    obs = AUTO_OBSERVABLE[cls]
    lo = _round_up(AUTO_SAFETY * model.achievable(obs, scene_class=cls))
    if tol < lo:
        raise SceneError("integrator.tolerance",
                         f"{tol:g} is tighter than method auto can deliver on {obs} "
                         f"({cls} chains: {lo:.2g} to 0.1, granchain/data/cost_model.csv)",
                         f"give a tolerance in [{lo:.2g}, 0.1], or choose method adaptive "
                         "with its own tolerance")
    vs = [v for v in scene.striker_velocities if v > 0]
    sdt = sample_dts or {v: sample_interval(scene, v) for v in vs}
    methods = list(SCENE_METHODS)
    if (len({sdt[v] for v in vs}) > 1
            and target < float(model.provenance["sampling_floor_v_g"][cls])):
        methods = list(TOLERANCE_METHODS)
    event_ok = scene.n <= model.event_max_n() and scene.wall is None
    if not event_ok:
        # not measured on chains this long; an end wall is not an event the method locates
        methods = [m for m in methods if m != "event"]
    switch = [e for e in switching(scene.effects) if e not in model.measured_effects()]
    if switch:
        # the model's errors hold for the switches it measured; only the event method
        # ends its steps on the others, and keeps its accuracy there
        if not event_ok:
            raise SceneError("integrator.method",
                             f"auto: {switch[0]}'s law switches inside a contact, where "
                             "only the event method keeps auto's accuracy, and it takes no "
                             f"end wall or chain over {model.event_max_n()} spheres",
                             "choose method adaptive with a tolerance, or rk4 or verlet "
                             "with a dt")
        methods = ["event"]
    pick = model.cheapest(target, obs, methods=methods, scene_class=cls,
                          work=work_ratio(scene, model, cls, durations))
    if pick is None:
        raise SceneError("integrator.tolerance", f"{tol:g}: no setting of the cost model meets it",
                         f"give a tolerance in [{lo:.2g}, 0.1]")
    if pick["method"] in TOLERANCE_METHODS:
        return pick["method"], scene.dt, pick["tolerance"]
    if not vs:                                   # nothing moves: any step will do
        return pick["method"], scene.dt, None
    return pick["method"], fixed_step(scene, pick["steps_per_contact"]), None


def apply_auto(scene: Scene, setting: tuple[str, float, float | None]) -> Scene:
    """The scene of method auto with ``setting`` ((method, dt, tolerance) of
    :func:`auto_setting`) in its spec, hence in its hash, and the requested tolerance as
    ``auto_tolerance``, checked like any scene with that setting (the step guard,
    sample_dt >= dt). A dt the scene file gave is refused when auto chooses a fixed step
    of its own."""
    m, dt, rtol = setting
    if "integrator.dt" in scene.given and m not in TOLERANCE_METHODS:
        raise SceneError("integrator.dt", f"has no effect: method auto chose {m} with its "
                         f"own step ({dt:.3g} s) for tolerance {scene.tolerance:g}",
                         "drop dt, or choose method rk4 or verlet to set the step")
    resolved = scene.derive({"integrator": {"method": m, "dt": dt, "tolerance": rtol}})
    return dataclasses.replace(resolved, auto_tolerance=scene.tolerance, given=scene.given)


def resolve_auto(scene: Scene, model: CostModel | None = None) -> Scene:
    """Auto's one setting for every striker speed, without the rest of a plan: ``scene``
    itself unless its method is auto; else :func:`apply_auto` of :func:`auto_setting`
    (what :func:`plan_run` gives as its ``scene``; the package plans a run with
    :func:`plan_run`)."""
    if scene.method != "auto":
        return scene
    return apply_auto(scene, auto_setting(scene, model))


def describe_auto(scene: Scene) -> str:
    """'auto (tolerance 0.0001) -> rk4, dt 1.23e-09 s' for a resolved auto scene."""
    if scene.auto_tolerance is None:
        return scene.method
    how = (f"tolerance {scene.tolerance:g}" if scene.method in TOLERANCE_METHODS
           else f"dt {scene.dt:.6g} s")
    return f"auto (tolerance {scene.auto_tolerance:g}) -> {scene.method}, {how}"
