"""The run plan: everything decided about a scene before an engine starts, computed once.

:func:`plan_run` takes a scene (method auto or not) and returns one frozen
:class:`RunPlan`: the scene that runs (auto's choice from the packaged cost model), and
per striker speed its sample interval, expected duration, integration steps, sample
record, estimated wall time (``costmodel.member_seconds``, the one per-member cost
estimate) and physics warnings. ``simulate.run_scene`` runs from it (cost guard,
warnings), the workflow's batches balance and time their jobs with it, and auto's choice
reads its durations and sample intervals.

numpy only (no numba, scipy or engine), like the modules it draws on: ``stoprule``
(sampling, duration, steps), ``costmodel`` (auto, wall time), ``guards`` (warnings).
"""
from __future__ import annotations

from dataclasses import dataclass

from . import costmodel
from .guards import physics_warnings
from .scene import TOLERANCE_METHODS, Scene
from .stoprule import expected_duration, sample_interval
from .costmodel import DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_STEPS, check_cost, cost_estimate

ENGINES = ("reference", "lammps")


@dataclass(frozen=True)
class SpeedPlan:
    """One striker speed of a run plan: what one chain (member) at that speed needs.
    ``scene``: the scene its chains run with on the reference engine (under method auto,
    the setting chosen for this speed alone)."""
    scene: Scene
    v_striker: float
    sample_dt: float            # s, stoprule.sample_interval
    duration_s: float           # simulated time, stoprule.expected_duration
    steps: float                # integration steps (costmodel.cost_estimate)
    samples: float
    record_bytes: float         # its sample record
    seconds: tuple[float, ...]  # estimated wall time of one chain, per engine (ENGINES)
    warnings: tuple[str, ...]   # guards.physics_warnings

    def estimate(self) -> dict:
        """Its ``costmodel.cost_estimate`` (duration_s, steps, samples, record_bytes)."""
        return {"duration_s": self.duration_s, "steps": self.steps, "samples": self.samples,
                "record_bytes": self.record_bytes}


@dataclass(frozen=True)
class RunPlan:
    """The plan of one scene's run. ``scene``: the scene that runs (method auto
    resolved, one setting for every striker speed); ``auto``: auto's choice as text
    (``costmodel.describe_auto``), "" unless the scene asked for auto; ``scene_class``:
    the cost model's class (packed, gapped); ``speeds``: one :class:`SpeedPlan` per
    striker speed, in the scene's order.

    Under method auto each striker speed gets the cheapest setting for itself
    (``SpeedPlan.scene``), which the reference engine runs: a sweep may run its slow
    strikers with the event method and its fast ones with a fixed step. ``scene`` is the
    one setting for all of them, for what takes a single step (a LAMMPS deck, the
    comparison of engines); ``per_speed`` says whether the speeds' settings differ."""
    scene: Scene
    auto: str
    scene_class: str
    speeds: tuple[SpeedPlan, ...]

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

    @property
    def per_speed(self) -> bool:
        return any(sp.scene is not self.scene for sp in self.speeds)

    @property
    def warnings(self) -> list[str]:
        """Warnings of every striker speed, in order, without repeats."""
        return list(dict.fromkeys(w for sp in self.speeds for w in sp.warnings))

    @property
    def sampling(self) -> dict[float, tuple[float, float]]:
        """Striker speed -> (sample interval, expected duration) s, as the engines take
        it (``engines.reference.run``'s ``sampling``)."""
        return {sp.v_striker: (sp.sample_dt, sp.duration_s) for sp in self.speeds}

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


def plan_run(scene: Scene | RunPlan, model: costmodel.CostModel | None = None) -> RunPlan:
    """The run plan of ``scene`` (a plan is returned as it is). Each striker speed's
    sample interval and expected duration are computed once (neither depends on the
    integrator); auto's choice reads them; the steps, record, wall time and warnings
    follow for the scene that runs."""
    if isinstance(scene, RunPlan):
        return scene
    vs = [float(v) for v in scene.striker_velocities]
    sdt = {v: sample_interval(scene, v) for v in vs}
    dur = {v: expected_duration(scene, v) for v in vs}
    auto = ""
    own: dict[float, Scene] = {}
    if scene.method == "auto":
        model = model or costmodel.load_model()
        setting = costmodel.auto_setting(scene, model, durations=dur, sample_dts=sdt)
        whole = costmodel.apply_auto(scene, setting)
        if len(set(vs)) > 1:
            own = _auto_per_speed(scene, whole, model, dur, sdt)
        scene = whole
        auto = costmodel.describe_auto(scene)
        if own:
            auto += "; per striker speed: " + ", ".join(
                f"{v:g} m/s {costmodel.describe_auto(own[v]).split('-> ', 1)[1]}"
                for v in dict.fromkeys(vs))
    speeds = []
    for v in vs:
        sc = own.get(v, scene)
        c = cost_estimate(sc, v, duration=dur[v], sample_dt=sdt[v])
        # LAMMPS runs the plan's one setting for every speed
        lc = c if sc is scene else cost_estimate(scene, v, duration=dur[v], sample_dt=sdt[v])
        secs = (costmodel.member_seconds(sc, v, "reference", model, duration=dur[v],
                                         steps=c["steps"]),
                costmodel.member_seconds(scene, v, "lammps", model, duration=dur[v],
                                         steps=lc["steps"]))
        speeds.append(SpeedPlan(sc, v, sdt[v], dur[v], c["steps"], c["samples"],
                                c["record_bytes"], secs, tuple(physics_warnings(sc, v))))
    return RunPlan(scene, auto, costmodel.scene_class(scene), tuple(speeds))


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
        pick = costmodel.auto_setting(alone, model, durations={v: dur[v]},
                                      sample_dts={v: sdt[v]})
        own[v] = costmodel.apply_auto(alone, pick)
    if all(o.method == whole.method and o.dt == whole.dt and o.tolerance == whole.tolerance
           for o in own.values()):
        return {}
    return own
