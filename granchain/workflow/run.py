"""Running jobs: one batch of a study, the packed_trace study, and the packed reference.

A batch's rows are complete when it ends (with the Eq. 5.4 bound from its own packed
reference, run on the same engine as the rows), so gathering a study is pure table work
(:mod:`granchain.workflow.gather`). LAMMPS jobs run with ``threads`` MPI ranks.
"""
from __future__ import annotations

import contextlib
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .. import tables
from ..gaps import members as scene_members
from ..observables import ChainResult, status_summary
from ..simulate import run_scene, trajectories
from .batches import find_batch
from .studies import StudyScene, packed_scene, study_scenes, trace_scene


def set_threads(threads: int | None) -> None:
    """Threads for the numba kernels of this process (a job's ``threads``). Before numba is
    imported, by its environment variable: a job on one thread then runs the ahead-of-time
    kernels (``engines.backend``) without importing numba at all."""
    if not threads:
        return
    if "numba" not in sys.modules:
        from ..engines.backend import num_threads
        os.environ["NUMBA_NUM_THREADS"] = str(max(1, min(int(threads), num_threads())))
        return
    import numba
    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


@contextlib.contextmanager
def log_to(path):
    """Send this process's stdout and stderr (progress, warnings, and what compiled code
    such as LAMMPS prints) to a job's log file, as a shell rule's ``> {log} 2>&1``."""
    if path is None:
        yield
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    try:
        with open(path, "w") as f:
            os.dup2(f.fileno(), 1)
            os.dup2(f.fileno(), 2)
            try:
                yield
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
    finally:
        os.close(saved[0])
        os.close(saved[1])


def engine_options(engine: str, threads: int | None) -> dict:
    """Keyword arguments of ``run_scene`` for an engine in a job with ``threads`` cores:
    LAMMPS gets that many MPI ranks; the reference engine's numba threads are set per
    process (``set_threads``)."""
    return {"nprocs": max(1, int(threads or 1))} if engine == "lammps" else {}


def local_mpi(nprocs: int) -> None:
    """In a SLURM job, have mpich's mpirun start a LAMMPS run's ranks on the job's own node
    (``HYDRA_LAUNCHER=fork``, unless set): inside a SLURM job it would otherwise launch
    them through a nested srun, which waits for the CPUs the job's own step holds. A
    workflow job is one node and ``threads`` CPUs, so its ranks belong there."""
    if nprocs > 1 and "SLURM_JOB_ID" in os.environ:
        os.environ.setdefault("HYDRA_LAUNCHER", "fork")


def run_members(scene, engine: str, realisations=None, threads: int | None = None
                ) -> list[ChainResult]:
    """``run_scene`` of a scene's members (``realisations``: all if None) on ``engine``.

    LAMMPS runs each striker speed of the scene apart (one run per speed, its
    realisations side by side), each freeing its sample records before the next (the
    engine samples every chain on its own grid, as the reference engine, in any case).
    Results come in ``run_scene``'s order (speed, then realisation)."""
    opts = engine_options(engine, threads)
    local_mpi(opts.get("nprocs", 1))
    if engine != "lammps" or len(scene.striker_velocities) == 1:
        return run_scene(scene, engine=engine, realisations=realisations, **opts)
    out: list[ChainResult] = []
    for v in scene.striker_velocities:
        one = scene.derive(**{"striker.velocity": float(v)})
        out += run_scene(one, engine=engine, realisations=realisations, **opts)
    return out


def packed_reference(scenes: list[StudyScene], velocities=None, threads: int | None = None
                     ) -> pd.DataFrame:
    """Group velocity of the packed chain (arrival-time definition ``v_g_front``) per
    (material, striker speed): the v_g(no gaps) of chapter Eq. 5.4, run on each study
    scene's ``packed_engine`` (the engine of its rows; the reference engine for
    lammps_check) with ``threads`` cores.

    ``velocities`` restricts the speeds (e.g. to re-run one member alone).
    """
    rows, done = [], set()
    for ss in scenes:
        ps = packed_scene(ss)
        if velocities is not None:
            ps = ps.derive(**{"striker.velocity": [float(v) for v in velocities]})
        if (ps.hash, ss.packed_engine) in done:
            continue
        done.add((ps.hash, ss.packed_engine))
        for r in run_members(ps, ss.packed_engine, threads=threads):
            rows.append({"material": ss.material, "v_striker_m_s": float(r.v_striker),
                         "v_g_packed_m_s": float(r.v_g_front)})
    return pd.DataFrame(rows, columns=["material", "v_striker_m_s", "v_g_packed_m_s"]) \
        .drop_duplicates(["material", "v_striker_m_s"]).reset_index(drop=True)


def member_rows(ss: StudyScene, runs: list[ChainResult], threads: int | None = None
                ) -> pd.DataFrame:
    """Table rows of a study scene's runs, with the Eq. 5.4 bound from its packed chain
    (run here, on the scene's ``packed_engine``, for the speeds these runs have: a few
    cheap chains); NaN for a scene without the bound (``StudyScene.eq54``: the field's
    packed chains on a wall)."""
    df = tables.study_table([tables.member_row(ss.meta, r, ss.scene.n) for r in runs],
                            ss.scene.n)
    if not ss.eq54:
        return df
    speeds = sorted({float(r.v_striker) for r in runs})
    return tables.add_eq54_bound(df, packed_reference([ss], velocities=speeds, threads=threads),
                                 ss.scene.radius)


def _timing_row(study: str, engine: str, batch: str, ss: StudyScene, runs: list[ChainResult],
                wall: float) -> dict:
    return {"study": study, "engine": engine, "batch": batch, "scene_hash": ss.scene.hash,
            "members": len(runs), "steps": int(sum(r.steps for r in runs)), "wall_s": wall,
            "wall_per_member_s": wall / max(1, len(runs))}


def run_batch(preset: dict, study: str, name: str, threads: int | None = None
              ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run one batch: (its rows, complete with the Eq. 5.4 bound; timing rows)."""
    scenes = study_scenes(preset, study)
    batch = find_batch(preset, study, name, scenes)
    rows, timing = [], []
    for si, reals in batch.units:
        ss = scenes[si]
        t0 = time.perf_counter()
        runs = run_members(ss.scene, batch.engine, list(reals), threads)
        wall = time.perf_counter() - t0
        rows.append(member_rows(ss, runs, threads))
        timing.append(_timing_row(study, batch.engine, batch.name, ss, runs, wall))
        how = (f"LAMMPS on {engine_options(batch.engine, threads)['nprocs']} rank(s)"
               if batch.engine == "lammps" else "reference engine")
        ended = status_summary(r.status for r in runs)
        print(f"[granchain] {study} {batch.name}: {ss.scene.name} {len(runs)} members "
              f"in {wall:.2f} s ({how})" + (f"; {ended} (the table's status and warnings "
                                             "columns say which)" if ended else ""),
              file=sys.stderr, flush=True)
    return pd.concat(rows, ignore_index=True), tables.timing_table(timing)


def write_batch(preset: dict, study: str, name: str, out_csv, timing_csv,
                threads: int | None = None) -> None:
    df, timing = run_batch(preset, study, name, threads)
    tables.write_csv(timing, timing_csv)
    tables.write_csv(df, out_csv)


def run_traces(preset: dict, trace_paths: dict[str, str], out_csv, timing_csv,
               threads: int | None = None) -> None:
    """packed_trace: each material's row, and its v(t) trace as .npz
    (t_s (S,), v_m_s (S, n), v_striker_m_s, material), on the study's engine."""
    rows, timing = [], []
    for ss in study_scenes(preset, "packed_trace"):
        engine = ss.engines[0]
        t0 = time.perf_counter()
        runs = run_members(ss.scene, engine, threads=threads)
        rows.append(member_rows(ss, runs, threads))
        # The table row stops once the wave has left the chain (t_end auto); the trace
        # for Fig. 5.1a runs for a fixed 1.5x the crossing time, the same for every speed.
        opts = engine_options(engine, threads)
        if engine == "lammps":
            # a full trajectory is the product here: LAMMPS writes its text dump and
            # MDAnalysis reads it (the same samples as the binary path, bit for bit)
            opts["output"] = "dump"
        local_mpi(opts.get("nprocs", 1))
        # the sampled v(t) is the product: ask the engine for its trace
        (m, traj), = list(trajectories(trace_scene(ss), scene_members(ss.scene), engine,
                                       trace=True, **opts))
        tables.write_npz(trace_paths[ss.material], t_s=traj.t, v_m_s=traj.v,
                         v_striker_m_s=np.float64(m.v_striker), material=np.str_(ss.material))
        wall = time.perf_counter() - t0
        timing.append(_timing_row("packed_trace", engine, ss.material, ss, runs, wall))
    tables.write_csv(tables.timing_table(timing), timing_csv)
    tables.write_csv(pd.concat(rows, ignore_index=True), out_csv)
