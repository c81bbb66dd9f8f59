"""The LAMMPS engine: a batch of chains -> one LAMMPS run -> one Trajectory per chain.

``run(scene, gaps, v_striker)`` writes one deck holding every chain side by side
(``granchain.lammps.deck.write_deck``), runs it once through
``granchain.lammps.runner.run_lammps`` (``nprocs`` MPI ranks), reads the dump back with
MDAnalysis and yields a :class:`~granchain.trajectory.Trajectory` per chain, in order,
like ``granchain.engines.reference.run``. LAMMPS always integrates with velocity Verlet
(``fix nve`` / ``nve/sphere``) at the scene's dt; ``meta["method"] = "lammps-verlet"``.

Reading the dump (``read_dump``). MDAnalysis' ``LAMMPSDUMP`` reader (2.11) parses
positions and velocities as float32 and shifts positions by the box's xlo. Its
``additional_columns`` are parsed as float64 and not shifted, and an explicit list may
name the standard columns too, so every observable here is built from the float64
columns ``x``, ``vx`` (and ``omegay``, ``f_gd[2]``, ``f_gd[3]``), written by the deck
with ``%.17g``: the values LAMMPS holds, bit for bit. ``velocities="float32"`` uses
MDAnalysis' float32 velocities instead (only to measure what that would cost; see
docs/lammps_engine.md).

Energy ledger per chain (columns of ``granchain.trajectory.ENERGY_COLUMNS``), at every
sample, from the per-atom columns:

* kinetic translational 1/2 m sum v^2 and rotational 1/2 I sum omega^2 (SI m, I of
  ``granchain.effects``);
* Hertz potential (2/5) K delta^(5/2) per contact with delta = 2R - (x_{k+1} - x_k), the
  float64 positions LAMMPS integrates (the same law as ``effects.Hertz``);
* work of the groove friction and of the air drag: sums over the chain of the per-atom
  cumulative works of ``fix groove/drag`` (the same increments as its global vector,
  which ``energy.txt`` records for all chains together);
* the tangential (particle-particle) and rolling contact friction have no per-atom work
  output in LAMMPS: their sum is reported as the residual of the energy balance in
  ``work_particle_friction`` and ``work_rolling_friction`` is 0. Such a ledger balances
  by construction: ``meta["balance"] = "residual"`` (``"independent"`` otherwise).

With t_end auto the deck stops the batch when every chain has passed (fix halt) and each
chain's record is cut where the reference engine would have stopped that chain (same
rule, same per-chain cap), status ``passed`` (or ``timeout`` at the cap).
"""
from __future__ import annotations

import math
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from ..effects import physics_terms
from ..errors import GranchainError
from ..lammps import deck as deckmod
from ..scene import Scene
from ..trajectory import ENERGY_COLUMNS, Trajectory

METHOD = "lammps-verlet"
E_KT, E_KR, E_H, E_WG, E_WD, E_WT, E_WR = range(len(ENERGY_COLUMNS))
# SI factors of 'units micro' values (docs/lammps_laws.md section 1)
UM = 1e-6          # um -> m
ENERGY = 1e-15     # 1e-15 J -> J
RAD_PER_US = 1e6   # rad/us -> rad/s


def run(scene: Scene, gaps, v_striker, *, workdir=None, nprocs: int = 1, keep: bool = False,
        force: bool = False, dt: float | None = None, progress: bool | None = None,
        timeout: float | None = None, velocities: str = "float64", readers: int = 1):
    """Yield one Trajectory per chain. gaps: (B, n-1) m; v_striker: (B,) m/s.

    workdir: directory for deck, dump and log; default a temporary directory, removed
    afterwards unless ``keep`` (and kept when the run fails, for the error message names
    its deck or dump). A given directory is kept; it must be empty or absent unless
    ``force``. ``dt`` overrides the scene's time step. ``nprocs``: MPI ranks of the
    one LAMMPS run. ``velocities``, ``readers``: see :func:`read_dump`.
    """
    gaps = np.atleast_2d(np.asarray(gaps, dtype=float))
    B = gaps.shape[0]
    vs = np.broadcast_to(np.asarray(v_striker, dtype=float), (B,)).copy()
    if dt is not None and dt != scene.dt:
        scene = derive_scene(scene, {"integrator.dt": float(dt)})
    if nprocs < 1:
        raise GranchainError(f"LAMMPS engine: nprocs must be >= 1 (got {nprocs})")
    if progress is None:
        progress = sys.stderr.isatty() and B > 1
    if B == 0:
        return
    tmp = workdir is None
    if tmp:
        wd = Path(tempfile.mkdtemp(prefix="granchain-lammps-"))
    else:
        wd = Path(workdir)
        if wd.exists() and not wd.is_dir():
            raise GranchainError(f"LAMMPS workdir '{wd}' is not a directory")
        if wd.is_dir() and any(wd.iterdir()) and not force:
            raise GranchainError(f"LAMMPS workdir '{wd}' is not empty; choose an empty "
                                 "directory or allow replacing its files (force / --force)")
        wd.mkdir(parents=True, exist_ok=True)
    try:
        from ..lammps.runner import lammps_version, run_lammps
        t0 = time.perf_counter()
        pl = deckmod.plan(scene, gaps=gaps, v_striker=vs)
        deck = deckmod.write_deck(scene, wd, gaps=gaps, v_striker=vs, force=True)
        for stale in (deckmod.DUMP_NAME, deckmod.ENERGY_NAME):
            (wd / stale).unlink(missing_ok=True)
        if progress:
            print(f"[granchain] {scene.name}: LAMMPS, {B} chain(s) x {scene.n} spheres, "
                  f"{pl.nsteps} steps max, {nprocs} rank(s) ...", file=sys.stderr, flush=True)
        lrun = run_lammps(deck, wd, nprocs=nprocs, timeout=timeout)
        if progress:
            print(f"[granchain] {scene.name}: LAMMPS done in {lrun.wall_time:.1f} s; reading "
                  f"{wd / deckmod.DUMP_NAME} ...", file=sys.stderr, flush=True)
        data = read_dump(wd / deckmod.DUMP_NAME, scene, pl, velocities=velocities,
                         readers=readers)
        wall = time.perf_counter() - t0
        meta_common = {"method": METHOD, "dt": scene.dt, "sample_dt": pl.sample_dt,
                       "nprocs": nprocs, "lammps_version": lammps_version(),
                       "lammps_wall_s": lrun.wall_time, "batch_wall_s": wall,
                       "read_wall_s": wall - lrun.wall_time, "readers": readers,
                       "velocities": velocities,
                       "balance": "residual" if residual_balance(scene) else "independent"}
        if keep or not tmp:
            meta_common["deck"] = str(deck)
        trajs = list(_trajectories(scene, pl, data, wall / B, meta_common))
    except GranchainError:
        # a failed run keeps its directory: the error message names its deck or dump
        if tmp and not keep and not (wd / deckmod.DECK_NAME).exists():
            shutil.rmtree(wd, ignore_errors=True)
        raise
    except BaseException:                       # interrupted (or a bug): clean up
        if tmp and not keep:
            shutil.rmtree(wd, ignore_errors=True)
        raise
    if tmp and not keep:
        shutil.rmtree(wd, ignore_errors=True)
    yield from trajs


def derive_scene(scene: Scene, changes: dict) -> Scene:
    """A copy of ``scene`` with dotted fields replaced (values as Python objects)."""
    import copy

    from ..scene import scene_from_dict
    spec = copy.deepcopy(scene.spec)
    for key, value in changes.items():
        node = spec
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return scene_from_dict(spec)


def residual_balance(scene: Scene) -> bool:
    """True if some effect's work is not output by LAMMPS (it is the balance residual)."""
    return scene.has("particle_friction") or scene.has("rolling_friction")


def read_dump(path: Path, scene: Scene, pl: "deckmod.DeckPlan", *, velocities: str = "float64",
              readers: int = 1):
    """Read a deck's dump with MDAnalysis into per-chain arrays.

    Returns a dict: ``step`` (S,), ``v`` (S, B, n) m/s and ``energy`` (S, B, 7) J.
    ``readers`` > 1 splits the frames between that many processes (each opens the dump
    with MDAnalysis, scans it for the frame offsets and parses its share): it only pays
    with idle cores (on the shared 2-core test machine, 2 readers took 60 s for a 385 MB
    dump that 1 reader read in 57 s).
    Raises GranchainError (one line, naming the dump) if it is missing, truncated or
    does not match the plan.
    """
    if velocities not in ("float64", "float32"):
        raise GranchainError(f"read_dump: velocities must be 'float64' or 'float32' (got {velocities!r})")
    path = Path(path)
    B, n = pl.n_chains, pl.n
    if not path.is_file() or path.stat().st_size == 0:
        raise GranchainError(f"LAMMPS dump {path} is missing or empty: the run wrote no "
                             "trajectory (see log.lammps next to it)")
    terms = physics_terms(scene)
    rot = scene.has("rotation")
    wcols = {E_WG: deckmod.WORK_COLUMNS["groove_friction"] if scene.has("groove_friction") else None,
             E_WD: deckmod.WORK_COLUMNS["air_drag"] if scene.has("air_drag") else None}
    extra = ["x", "vx"] + (["omegay"] if rot else []) + [c for c in wcols.values() if c]
    missing = [c for c in extra if c not in pl.dump_columns]
    if missing:
        raise GranchainError(f"LAMMPS dump {path}: the deck does not dump {', '.join(missing)}")
    job = {"path": str(path), "B": B, "n": n, "extra": extra, "velocities": velocities,
           "rot": rot, "wcols": {k: v for k, v in wcols.items() if v},
           "D": 2.0 * deckmod.to_micro(scene.radius, "length"), "m": terms.m,
           "K": terms.hertz.K, "I": terms.rotation.inertia if rot else 0.0}
    readers = max(1, int(readers))
    if readers == 1:
        parts = [_read_part(job, 0, 1)]
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor
        # fork: the workers run only numpy and MDAnalysis; spawn would re-import the
        # caller's __main__ (and fail in scripts without a __main__ guard)
        with ProcessPoolExecutor(readers, mp_context=mp.get_context("fork")) as ex:
            parts = list(ex.map(_read_part, [job] * readers, range(readers), [readers] * readers))
    S = parts[0][0]
    step = np.concatenate([p[1] for p in parts])
    V = np.concatenate([p[2] for p in parts])
    E = np.concatenate([p[3] for p in parts])
    if S > pl.nsamples or (not pl.auto and S != pl.nsamples) or (
            pl.auto and S < pl.nsamples and not _halted(path)):
        raise GranchainError(f"LAMMPS dump {path} is truncated: {S} of {pl.nsamples} "
                             "samples and the run was not halted by its stop rule")
    expected = np.arange(S, dtype=np.int64) * pl.every
    if S == 0 or not np.array_equal(step, expected):
        raise GranchainError(f"LAMMPS dump {path}: its steps are not 0, {pl.every}, "
                             f"{2 * pl.every}, ... (was it written by this deck?)")
    if residual_balance(scene):
        mech = E[:, :, E_KT] + E[:, :, E_KR] + E[:, :, E_H]
        E[:, :, E_WT] = mech - mech[0] - E[:, :, E_WG] - E[:, :, E_WD]
    return {"step": step, "v": V, "energy": E}


def _halted(dump: Path) -> bool:
    """Did the run that wrote ``dump`` stop by its fix halt (log.lammps next to it)?"""
    try:
        return "Fix halt condition" in (dump.parent / "log.lammps").read_text(errors="replace")
    except OSError:
        return False


def _read_part(job: dict, part: int, nparts: int):
    """Frames [part*S/nparts, (part+1)*S/nparts) of a dump: (S, step, V, E)."""
    import MDAnalysis as mda

    path, B, n = job["path"], job["B"], job["n"]
    m, K, inertia, D = job["m"], job["K"], job["I"], job["D"]
    wcols = {int(k): v for k, v in job["wcols"].items()}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")       # no masses/types in a dump: MDAnalysis warns
            u = mda.Universe(path, topology_format="LAMMPSDUMP", format="LAMMPSDUMP",
                             additional_columns=job["extra"])
            traj = u.trajectory
            S = traj.n_frames
            if u.atoms.n_atoms != B * n:
                raise GranchainError(f"LAMMPS dump {path} holds {u.atoms.n_atoms} atoms; the "
                                     f"deck has {B} chain(s) x {n} = {B * n}")
            lo, hi = part * S // nparts, (part + 1) * S // nparts
            step = np.empty(hi - lo, dtype=np.int64)
            V = np.empty((hi - lo, B, n))
            E = np.zeros((hi - lo, B, len(ENERGY_COLUMNS)))
            for s, ts in enumerate(traj[lo:hi]):
                data = ts.data
                step[s] = data["step"]
                if job["velocities"] == "float64":
                    v = data["vx"].reshape(B, n)
                else:
                    v = ts.velocities[:, 0].astype(np.float64).reshape(B, n)
                V[s] = v
                x = data["x"].reshape(B, n)
                E[s, :, E_KT] = 0.5 * m * np.sum(v * v, axis=1)
                if job["rot"]:
                    w = data["omegay"].reshape(B, n) * RAD_PER_US
                    E[s, :, E_KR] = 0.5 * inertia * np.sum(w * w, axis=1)
                delta = np.maximum((D - (x[:, 1:] - x[:, :-1])) * UM, 0.0)
                E[s, :, E_H] = np.sum(0.4 * K * delta * delta * np.sqrt(delta), axis=1)
                for col, name in wcols.items():
                    E[s, :, col] = np.sum(data[name].reshape(B, n), axis=1) * ENERGY
    except GranchainError:
        raise
    except (ValueError, IndexError, EOFError, OSError, KeyError, TypeError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GranchainError(f"LAMMPS dump {path} is truncated or unreadable: {msg}") from None
    return S, step, V, E


def _trajectories(scene, pl, data, wall_each, meta_common):
    step, V, E = data["step"], data["v"], data["energy"]
    probe = scene.probes[-1] - 1
    eff = tuple(sorted(scene.effects))
    for b in range(pl.n_chains):
        vsb = float(pl.v_striker[b])
        v = V[:, b, :]
        keep, status = step.size, "done"
        if scene.t_end is None:
            keep, status = auto_stop(scene, pl.gaps[b], vsb, v[:, probe], pl.sample_dt)
        bad = np.flatnonzero(~np.all(np.isfinite(v[:keep]), axis=1))
        if bad.size:
            keep, status = int(bad[0]) + 1, "nonfinite"
        yield Trajectory(
            t=step[:keep] * scene.dt, v=v[:keep].copy(), energy=E[:keep, b, :].copy(),
            gaps=pl.gaps[b].copy(), radius=scene.radius, v_striker=vsb, effects=eff,
            steps=int(step[keep - 1]), rejected=0, status=status, wall_s=wall_each,
            meta=dict(meta_common))


def auto_stop(scene: Scene, gaps, v_striker: float, vprobe, sample_dt: float) -> tuple[int, str]:
    """(samples kept, status) of a t_end auto chain, by the reference engine's rule.

    As ``engines.kernels.run_window``: after each sample but the first, the running peak
    of the last probe's velocity is updated; the chain has passed (and stops, that sample
    included) once the peak exceeds STOP_THRESHOLD * v_striker and the velocity is below
    STOP_FRACTION of it. A chain that never passes stops at its own cap, auto_t_max,
    with status timeout. A chain at rest keeps its initial sample only.
    """
    from .reference import auto_t_max
    S = len(vprobe)
    if v_striker <= 0:
        return 1, "done"
    nt = min(S, int(math.ceil(auto_t_max(scene, np.asarray(gaps), v_striker) / sample_dt)) + 1)
    vp = np.asarray(vprobe[1:nt], dtype=float)
    run_peak = np.maximum.accumulate(np.maximum(vp, 0.0))
    hit = np.flatnonzero((run_peak > deckmod.STOP_THRESHOLD * v_striker)
                         & (vp < deckmod.STOP_FRACTION * run_peak))
    if hit.size:
        return int(hit[0]) + 2, "passed"
    return nt, "timeout"
