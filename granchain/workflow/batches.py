"""Job batches: many members per job, balanced by estimated cost.

The members of a study (per engine) are cut into ``ceil(members / batch.members_per_job)``
jobs of about equal *estimated cost*, in whole realisations of a scene, so a job calls
:func:`granchain.simulate.run_scene` with ``realisations=[...]`` once per scene it holds.
The cost of a realisation is its scene's run plan's (``StudyScene.plan``,
:meth:`granchain.runplan.RunPlan.member_seconds`): the one per-member estimate of
``costmodel.member_seconds``, from the packaged cost model and ``stoprule``'s expected
duration, that auto ranks its settings by and the cost guard reports. The estimates
balance jobs; a job's runtime limit also allows for chains held to their cap
(:func:`realisation_limit`). They never enter a result.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..costmodel import DEFAULT_MAX_TOTAL_STEPS, add_estimates, held_seconds, load_model
from ..effects import binding, may_hold_wave
from ..errors import GranchainError
from ..guards import check_run, gap_total
from ..runplan import ENGINES
from .config import ConfigError
from .studies import ENGINE_ORDER, StudyScene, study_scenes

JOB_OVERHEAD_S = 5.0       # interpreter start, imports, numba cache load


def _cores(engine: str) -> int:
    """The cores behind a run plan's estimate on ``engine``: the reference engine's is the
    cost model's wall time, measured on ``CostModel.threads`` threads; LAMMPS's, one
    process's."""
    return load_model().threads if engine == "reference" else 1


def realisation_cost(ss: StudyScene, engine: str) -> float:
    """Estimated seconds on one core of one realisation (all striker speeds) of a study
    scene on ``engine``, from its run plan."""
    return ss.plan.member_seconds(engine) * _cores(engine)


def realisation_limit(ss: StudyScene, engine: str) -> float:
    """Seconds of one realisation if each striker speed's chain ran to its cap (t_end
    auto: ``SpeedPlan.run_length`` at the expected gaps), for a scene with a law on the
    contacts' normal force after Hertz's (``effects.may_hold_wave``: damping, yielding,
    adhesion), which can stall the wave or hold the chain together until the cap
    (``benchmarks/estimates.py`` measured such scenes at up to 265x their estimate);
    :func:`realisation_cost` otherwise, or with a fixed t_end. Each speed's estimate
    scaled by its cap over its expected duration; under the event method with a law
    that can bind the chain as a whole (``effects.binding``), at least every contact
    active to the cap (``costmodel.held_seconds``)."""
    sc = ss.scene
    if sc.t_end is not None or not may_hold_wave(sc.effects):
        return realisation_cost(ss, engine)
    k = ENGINES.index(engine)
    gaps = np.full(sc.n - 1, gap_total(sc, sc.n - 1) / max(1, sc.n - 1))
    bound = engine == "reference" and bool(binding(sc.effects))
    total = 0.0
    for sp in ss.plan.speeds:
        cap = sp.run_length(gaps)
        s = sp.seconds[k] * max(1.0, cap / sp.duration_s) if sp.duration_s > 0 \
            else sp.seconds[k]
        if bound and sp.scene.method == "event" and cap > 0:
            s = max(s, held_seconds(sp.scene, sp.v_striker, cap))
        total += s
    return _cores(engine) * total


@dataclass(frozen=True)
class Batch:
    """One job: consecutive realisations of one or more scenes of a study, one engine."""
    study: str
    engine: str
    index: int
    units: tuple[tuple[int, tuple[int, ...]], ...]   # (scene index, realisations)
    members: int
    est_seconds: float
    hashes: tuple[str, ...] = ()                      # scene hash of each unit
    limit_seconds: float = 0.0                        # every chain at its cap

    @property
    def name(self) -> str:
        return f"{self.engine}_{self.index:03d}"

    def key(self) -> str:
        """Its scenes (hash: any change of physics, speeds, seed...) and realisations: a
        Snakemake param, so a changed plan or scene re-runs the job."""
        parts = []
        for (i, reals), h in zip(self.units, self.hashes):
            lo, hi = reals[0], reals[-1]
            parts.append(f"{h}:r{lo}-{hi}" if len(reals) > 1 else f"{h}:r{lo}")
        return f"{self.study}/{self.name}[" + ",".join(parts) + "]"


def members_per_job(preset: dict) -> int:
    return int(preset["batch"]["members_per_job"])


def batches(preset: dict, study: str, engine: str | None = None,
            scenes: list[StudyScene] | None = None) -> list[Batch]:
    """Job batches of a study (every engine, or one), balanced by estimated cost;
    ``scenes``: the study's scenes if already built (``study_scenes(preset, study)``)."""
    if scenes is None:
        scenes = study_scenes(preset, study)
    engs = [e for e in ENGINE_ORDER if any(e in s.engines for s in scenes)]
    if engine is not None:
        engs = [e for e in engs if e == engine]
    k = members_per_job(preset)
    out: list[Batch] = []
    for eng in engs:
        units = []          # (scene index, realisation, members, cost)
        limit = {}          # scene index -> realisation_limit
        for ss in scenes:
            if eng not in ss.engines:
                continue
            c = realisation_cost(ss, eng)
            limit[ss.index] = realisation_limit(ss, eng)
            nv = len(ss.scene.striker_velocities)
            units += [(ss.index, r, nv, c) for r in range(ss.scene.realisations)]
        total_members = sum(u[2] for u in units)
        total_cost = sum(u[3] for u in units)
        njobs = max(1, math.ceil(total_members / k))
        target = total_cost / njobs
        bins: list[list] = [[] for _ in range(njobs)]
        cum = 0.0
        for u in units:
            j = min(njobs - 1, int((cum + 0.5 * u[3]) / target)) if target > 0 else 0
            bins[j].append(u)
            cum += u[3]
        index = 0
        for b in bins:
            if not b:
                continue
            grouped: dict[int, list[int]] = {}
            for si, r, _, _ in b:
                grouped.setdefault(si, []).append(r)
            out.append(Batch(study, eng, index,
                             tuple((si, tuple(rs)) for si, rs in grouped.items()),
                             sum(u[2] for u in b), sum(u[3] for u in b),
                             tuple(scenes[si].scene.hash for si in grouped),
                             sum(limit[u[0]] for u in b)))
            index += 1
    return out


def find_batch(preset: dict, study: str, name: str,
               scenes: list[StudyScene] | None = None) -> Batch:
    """The batch called ``name`` (e.g. reference_000) of a study."""
    for b in batches(preset, study, scenes=scenes):
        if b.name == name:
            return b
    raise GranchainError(f"study '{study}' has no batch '{name}' in this configuration")


# A study cut into more jobs than this is refused before its jobs are listed (the
# Snakemake graph and the plan's own lists grow with the number of jobs and members).
MAX_JOBS_PER_STUDY = 10000


def _job_limits(preset: dict, name: str, job: str, est: dict, size: str) -> None:
    """Refuse a job (or a study's average job) beyond the preset's memory per job
    (``batch.mem_mb``) or the whole-run step limit, as a one-line ConfigError naming the
    preset's keys."""
    key = f"presets.{name}.batch"
    try:
        check_run(job, est, size=size,
                  fix=f"lower {key}.members_per_job or the study's realisations",
                  max_total_steps=DEFAULT_MAX_TOTAL_STEPS,
                  max_memory_gb=preset["batch"].get("mem_mb", 1000) / 1e3,
                  steps_option=None, steps_key=f"{key}.members_per_job",
                  memory_option=f"{key}.mem_mb", memory_unit="MB")
    except GranchainError as exc:
        where, _, rest = str(exc).partition(": ")
        raise ConfigError(f"invalid configuration at '{where.split(' ')[0]}': {rest}") from None


def _unit_estimate(ss: StudyScene, realisations, engine: str) -> dict:
    """The run estimate of one scene's realisations in a job, from its run plan
    (``run.run_members``: LAMMPS runs each striker speed apart)."""
    return ss.plan.estimate(realisations, engine, speeds_apart=engine == "lammps")


def check_study(preset: dict, name: str, study: str, scenes: list[StudyScene]) -> None:
    """The whole-run guard of a study of preset ``name``, before its jobs are listed:
    per engine, its members over ``batch.members_per_job`` jobs (at most
    ``MAX_JOBS_PER_STUDY``), and its average job within the job limits (the largest job
    is at least the average)."""
    k = members_per_job(preset)
    for eng in ENGINE_ORDER:
        mine = [ss for ss in scenes if eng in ss.engines]
        if not mine:
            continue
        ests = [_unit_estimate(ss, None, eng) for ss in mine]
        est = add_estimates(*ests)
        members = int(est["members"])
        njobs = max(1, math.ceil(members / k))
        where = f"presets.{name}.studies.{study}.realisations"
        if njobs > MAX_JOBS_PER_STUDY:
            raise ConfigError(
                f"invalid configuration at '{where}': study {study} has {members} members on "
                f"{eng}, {njobs} jobs of presets.{name}.batch.members_per_job = {k}, above "
                f"{MAX_JOBS_PER_STUDY} jobs per study; lower {where} or raise "
                f"presets.{name}.batch.members_per_job")
        avg = {key: v / njobs for key, v in est.items() if key != "worst_chain_steps"}
        avg["worst_chain_steps"] = est["worst_chain_steps"]
        # a job holds the records of one scene's run at a time: at least one realisation's
        avg["record_bytes"] = min(e["record_bytes"] / max(1, e["members"]) for e in ests)
        avg["bytes"] = avg["result_bytes"] + avg["record_bytes"]
        _job_limits(preset, name, f"an average job of study {study} ({eng})", avg,
                    f"{members / njobs:.0f} of its {members} members, "
                    f"{len(mine)} scene{'s' if len(mine) != 1 else ''}")


def check_jobs(preset: dict, name: str, study: str, jobs: list[Batch],
               scenes: list[StudyScene]) -> None:
    """Each job of a study within the job limits: its members' results, all held until
    the job writes its table, and the sample records of the largest of its scenes' runs
    (``run.run_batch`` runs its scenes one after another)."""
    for b in jobs:
        ests = [_unit_estimate(scenes[si], reals, b.engine) for si, reals in b.units]
        est = add_estimates(*ests)
        est["record_bytes"] = max(e["record_bytes"] for e in ests)
        est["bytes"] = est["result_bytes"] + est["record_bytes"]
        _job_limits(preset, name, f"job {study} {b.name}", est,
                    f"{b.members} members of {len(b.units)} scene{'s' if len(b.units) != 1 else ''}")


def runtime_minutes(seconds: float, threads: int = 1) -> int:
    """A generous wall-clock limit (minutes) for a job estimated at ``seconds`` on 1 core."""
    return int(max(10, math.ceil(3.0 * (JOB_OVERHEAD_S + seconds / max(1, threads)) / 60.0)))
