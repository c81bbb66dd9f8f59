"""Run a scene: its members (striker speed x gap realisation) through an engine.

This is the one entry point the CLI and the workflow use:
scene -> run plan (method auto resolved, cost guard, warnings: ``granchain.runplan``, once)
-> physics terms -> engine -> trajectories -> observables.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np

from .errors import GranchainError
from .gaps import Member, member_gaps, member_radii, members
from .vibrometer import measure, needs_trace
from .collision import terms_of
from .observables import ChainResult, bounded, summarize
from .runplan import RunPlan, plan_run
from .costmodel import DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_STEPS
from .scene import Scene

ENGINES = ("reference", "lammps")


def trajectories(scene: Scene | RunPlan, mem: list[Member], engine: str = "reference", **kw):
    """Yield (member, Trajectory) in order (a scene with method auto runs resolved; a run
    plan runs its scene). The reference engine records the sampled trajectory of its
    event method only on request (``trace=True``); a measured scene requests it
    (``vibrometer.needs_trace``). On the reference engine each striker speed runs with
    its plan's setting (``SpeedPlan.scene``: under method auto, the speed's own), the
    speeds of one setting together; LAMMPS runs the plan's one setting."""
    plan = scene if isinstance(scene, RunPlan) else plan_run(scene)
    scene = plan.scene
    if engine == "reference":
        # one engine call per setting (all members when the speeds share one; a member at
        # a speed the plan lacks takes the plan's scene), yielded in member order as they
        # arrive
        own = {sp.v_striker: sp.scene for sp in plan.speeds}
        runs: dict[int, tuple[Scene, list[int]]] = {}
        for i, m in enumerate(mem):
            sc = own.get(float(m.v_striker), scene)
            runs.setdefault(id(sc), (sc, []))[1].append(i)
        if not runs:
            runs[id(scene)] = (scene, [])       # no members: the engine still checks the scene
        done: dict[int, object] = {}
        nxt = 0
        for sc, idx in runs.values():
            for i, traj in zip(idx, _reference(sc, plan, [mem[i] for i in idx], kw)):
                done[i] = traj
                while nxt in done:
                    yield mem[nxt], done.pop(nxt)
                    nxt += 1
        return
    if engine == "lammps":
        try:
            from .engines import lammps as lmp_engine
        except ImportError as exc:
            raise GranchainError(f"the LAMMPS engine is not available: {exc}") from None
        it = lmp_engine.run(scene, member_gaps(scene, mem), [m.v_striker for m in mem],
                            radii=member_radii(scene, mem), plan=plan, **kw)
    else:
        raise GranchainError(f"unknown engine '{engine}'; use one of {', '.join(ENGINES)}")
    yield from zip(mem, it)


def _reference(scene: Scene, plan: RunPlan, mem: list[Member], kw: dict):
    """The reference engine's trajectories of ``mem``, in order (``plan``: the run plan
    ``scene`` belongs to)."""
    from .engines import reference
    if needs_trace(scene):
        kw = {**kw, "trace": True}
    radii = member_radii(scene, mem)
    if radii is not None:
        kw = {**kw, "radii": radii}
    return reference.run(scene, member_gaps(scene, mem), np.array([m.v_striker for m in mem]),
                         plan=plan, **kw)


def run_scene(scene: Scene | RunPlan, engine: str = "reference", realisations=None, *,
              gaps=None,
              max_steps: float = DEFAULT_MAX_STEPS, max_memory_gb: float = DEFAULT_MAX_MEMORY_GB,
              progress: Callable[[int], None] | None = None, **kw) -> list[ChainResult]:
    """Observables of every member of the scene, one :class:`~granchain.observables.ChainResult`
    each, with its member fields set.

    ``scene``: a scene or its run plan (``runplan.plan_run``, built here from a scene, once).
    A scene with method auto runs with the setting its plan chose (each result's
    ``method`` and ``dt``). Before integrating, refuses (GranchainError) a scene whose
    chains need more than ``max_steps`` integration steps or ``max_memory_gb`` GB of
    sample record each (the plan's estimates, ``RunPlan.check``). Each result carries
    ``warnings``: the plan's one-line physics warnings for its striker speed (empty when
    none), and ``batch_wall_s``, the wall time of the whole call. A scene with a
    measurement block also gets the vibrometer's fields (``granchain.vibrometer``): it
    needs the probes' velocity histories (``vibrometer.needs_trace``).

    ``gaps``: (R, n-1) gaps (m) of realisations 0..R-1 in place of the scene's gap law
    (``gaps.members``; the inference's designed realisations).

    ``progress``: called with 1 as each member's result is done (members arrive as the
    engine finishes each of its chunks), e.g. a progress bar's ``update``
    (``granchain.progress``); the engine's own progress line is then off. It sees the
    results' count only, so it changes none of them."""
    plan = plan_run(scene)
    plan.check(max_steps, max_memory_gb)
    scene = plan.scene
    mem = members(scene, realisations, gaps)
    t0 = time.perf_counter()
    out = []
    warn = {sp.v_striker: sp.warnings for sp in plan.speeds}
    if engine == "reference" and "trace" not in kw:
        # observables only: the fixed-step kernels measure them on the fly (the event
        # method always does), with the same result as summarising the record
        kw = {**kw, "trace": False}
    if progress is not None:
        kw = {**kw, "progress": False}
    for m, traj in trajectories(plan, mem, engine, **kw):
        s = summarize(traj, scene.probes, terms_of(scene, traj))
        extra = {}
        if needs_trace(scene):
            # the vibrometer reads the probes' histories (traj.t, traj.v); its noise
            # stream is the member's own
            final = [s.final[p - 1] for p in scene.probes]
            extra = measure(traj, scene.probes, scene.measurement, key=(m.index,),
                            true_final=final).result_fields(scene.probes)
        # the plan's warnings first, then those of the result's bounds (summarize); the
        # vibrometer's values go through the same bounds
        out.append(bounded(dataclasses.replace(
            s, member=m.index, realisation=m.realisation, engine=engine,
            method=traj.info.method, dt=float(traj.info.dt),
            warnings=tuple(warn[m.v_striker]) + s.warnings, **extra), traj.limits))
        if progress is not None:
            progress(1)
    wall = time.perf_counter() - t0
    return [dataclasses.replace(s, batch_wall_s=wall) for s in out]
