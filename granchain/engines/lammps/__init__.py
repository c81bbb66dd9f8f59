"""The LAMMPS engine: a batch of chains -> one LAMMPS run per sample cadence -> one
Trajectory per chain.

``run(scene, gaps, v_striker)`` writes one deck holding every chain side by side
(``granchain.lammps.deck.write_deck``), runs it once through
``granchain.lammps.runner.run_lammps`` (``nprocs`` MPI ranks), reads its output back and
yields a :class:`~granchain.trajectory.Trajectory` per chain, in order, like
``granchain.engines.reference.run``. A deck samples all its chains on one grid, so a
batch whose chains the reference engine samples on different grids (striker speeds at
auto sampling, ``deckplan.cadence_groups``) runs one deck per grid, one after the other:
each chain is then sampled, and its record cut, on its own grid, as the reference engine
does (a bound pair that oscillates to the end has the same last sample). LAMMPS always integrates with velocity Verlet
(``fix nve`` / ``nve/sphere``) at the scene's dt; ``info.method = "lammps-verlet"``.

Two output paths, the same Trajectory objects (tested bit for bit on v):

* ``output="binary"`` (default: ``granchain run --engine lammps``, ``granchain compare``):
  the deck writes LAMMPS binary dumps, ``traj.bin`` (``x vx`` of every atom, sorted by
  id) and ``ledger.bin`` (the per-chain ledger on each chain's first atom), read with
  numpy (``read_binary``): the doubles LAMMPS holds, without the text dump's printing
  and per-line parsing (costs: docs/explanation/lammps_engine.md).
* ``output="dump"``: the text dump ``traj.dump`` (``id x y z vx``, ``%.17g``) and
  ``ledger.txt``, read with MDAnalysis (``read_dump``): the path for full trajectories
  that other tools read (``granchain deck`` writes this deck by default).

Reading the text dump (``read_dump``). The trajectory dump holds ``id x y z vx`` only. It is
read with MDAnalysis' ``LAMMPSDUMP`` reader (2.11), which parses positions as float32 and
shifts them by the box's xlo; its ``additional_columns`` are parsed as float64 and not
shifted, so the observables are built from the float64 columns ``x`` and ``vx``, written
by the deck with ``%.17g``: the values LAMMPS holds, bit for bit. ``velocities="float32"``
rounds vx to float32, as MDAnalysis' own velocity parsing would (only to measure what
that would cost; see docs/explanation/lammps_engine.md).

Energy ledger per chain (columns of ``granchain.trajectory.ENERGY_COLUMNS``), at every
sample:

* kinetic translational 1/2 sum m_i v_i^2 (each sphere's SI mass, ``terms.chain``) from
  the dumped vx;
* Hertz potential per contact, (2/5) K_k delta^(5/2) (the law of ``effects.hertz``, each
  contact's own K_k) of delta = (R_k + R_{k+1}) - (x_{k+1} - x_k), the float64 positions
  LAMMPS integrates, plus the end wall's (2/5) K_w delta_w^(5/2), delta_w = x_n + R_n
  (the wall plane is x = 0);
* the work of the dead load F0 (x_2 - x_2(0)) (``work_load``), from the dumped x;
* kinetic rotational and the works of the groove friction and of the air drag: summed
  per chain inside LAMMPS (``compute chunk/atom`` + ``reduce/chunk`` of
  ``erotate/sphere/atom`` and of the per-atom cumulative works of ``fix groove/drag``),
  read from ``ledger.bin`` (binary path) or ``ledger.txt`` (``read_ledger``, text dump
  path), the same doubles; ``energy.txt`` holds the same sums over all
  chains, from LAMMPS' global computes and the fix's global vector;
* the tangential (particle-particle) and rolling contact friction and the contact damping
  have no per-atom work output in LAMMPS (``effects.residual_work``): their sum is
  reported as the residual of the energy balance in the first of their columns (registry
  order: ``work_particle_friction``, ``work_rolling_friction``, ``work_contact_damping``),
  the others 0. Such a ledger balances by construction: ``info.balance = "residual"``
  (``"independent"`` otherwise).

End wall: ``Trajectory.wall_force`` is the force fix wall/gran applied to the last
sphere at each sample (its per-atom ``contacts`` output, summed per chain into the
ledger; N, > 0 in compression, < 0 while a JKR contact is held closed in tension),
``wall_static`` its static part K_w w_0^(3/2) as the
reference engine states it. With contact damping it is the force at the sample's state,
F_el + eta w of the dumped x and vx (``ledger.sampled_wall_force``: the reference
kernels' own law, evaluated; a JKR wall in the closed state fix wall/gran's contact flag
reports, ``EffectSpec.lammps_wall_state``), as the reference engine
records it: fix wall/gran's output is the force of the step, taken with the half-step
velocity. Spheres of different radii: ``Trajectory.radii``.

With t_end auto the deck stops the batch when every chain has passed (fix halt) and each
chain's record is cut where the reference engine would have stopped that chain (same
rule, same per-chain cap), status ``passed`` (or ``timeout`` at the cap). A law that
holds contacts closed (``effects.holds_contacts``) leaves the deck without a halt: the
batch runs to its cap and each record is cut where every contact's outcome is decided
(``stoprule.settled_sample``, from every contact's overlap in the dump).

Modules: this one runs the engine (``run``, ``auto_stop``); ``dump`` reads a deck's
output back (``read_binary``, ``read_dump``, ``read_ledger``), ``binary`` parses LAMMPS
binary dumps (``read_binary_dump``) and ``ledger`` builds the energy ledger from the
dumped positions and velocities.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ...effects import holds_contacts, physics_terms, residual_work
from ...errors import GranchainError
from ...guards import require_resolved, result_limits
from ...lammps import deck as deckmod
from ...scene import Scene
from ...runplan import RunPlan, plan_run
from ...stoprule import last_detached, settled_sample, wall_left
from ...trajectory import RunInfo, Trajectory
from .dump import read_binary, read_dump
from .ledger import chain_terms
# the other two readers, importable from the engine like the two it runs
from .binary import read_binary_dump  # noqa: F401
from .dump import read_ledger  # noqa: F401

METHOD = "lammps-verlet"
# output path -> (trajectory file, reader)
READERS = {"binary": ("traj.bin", "read_binary"), "dump": ("traj.dump", "read_dump")}


def run(scene: Scene, gaps, v_striker, *, workdir=None, nprocs: int = 1, keep: bool = False,
        force: bool = False, dt: float | None = None, progress: bool | None = None,
        timeout: float | None = None, velocities: str = "float64", readers: int = 1,
        output: str = "binary", trace: bool = True, radii=None, plan: RunPlan | None = None):
    """Yield one Trajectory per chain. gaps: (B, n-1) m; v_striker: (B,) m/s; radii:
    (B, n) m, each chain's own (a radius spread, ``gaps.member_radii``: its own diameters
    and masses, contact constants, groove springs, static overlaps and wall overlap), or
    None (the scene's), as the reference engine's ``radii``. A LAMMPS
    run always records its sampled trajectory (``trace`` is accepted for the callers
    that ask every engine for one).

    output: ``"binary"`` (default) the deck writes LAMMPS binary dumps read with numpy
    (:func:`~granchain.engines.lammps.dump.read_binary`); ``"dump"`` the text dump read
    with MDAnalysis (:func:`~granchain.engines.lammps.dump.read_dump`), for full
    trajectories kept in ``workdir``. Both give the same
    Trajectory objects.

    workdir: directory for deck, dump and log; default a temporary directory, removed
    afterwards unless ``keep`` (and kept when the run fails, for the error message names
    its deck or dump). A given directory is kept; it must be empty or absent unless
    ``force``. A batch of several sample cadences runs a deck per cadence, each in a
    directory of its own (in a given workdir: ``cadence-<every>``,
    ``deckplan.cadence_dir``). ``dt`` overrides the scene's time step. ``nprocs``: MPI ranks of
    each LAMMPS run. ``velocities``, ``readers``: see
    :func:`~granchain.engines.lammps.dump.read_dump` (output "dump"
    only). The scene's
    method must not be auto (``simulate`` and ``compare`` resolve it). ``plan``: the
    scene's run plan (``granchain.runplan.plan_run``; planned here if None), from which the
    deck takes its cadence and run length (``lammps.deckplan.plan``).
    """
    require_resolved(scene, "LAMMPS engine")
    gaps = np.atleast_2d(np.asarray(gaps, dtype=float))
    B = gaps.shape[0]
    vs = np.broadcast_to(np.asarray(v_striker, dtype=float), (B,)).copy()
    if dt is not None and dt != scene.dt:
        scene = scene.derive(**{"integrator.dt": float(dt)})
    if nprocs < 1:
        raise GranchainError(f"LAMMPS engine: nprocs must be >= 1 (got {nprocs})")
    if output not in READERS:
        raise GranchainError(f"LAMMPS engine: output must be one of {', '.join(READERS)} "
                             f"(got {output!r})")
    if output != "dump" and (velocities != "float64" or readers != 1):
        raise GranchainError("LAMMPS engine: velocities and readers are options of the text "
                             "dump (output='dump')")
    if progress is None:
        progress = sys.stderr.isatty() and B > 1
    if B == 0:
        return
    tmp = workdir is None
    if not tmp:
        wd = Path(workdir)
        if wd.exists() and not wd.is_dir():
            raise GranchainError(f"LAMMPS workdir '{wd}' is not a directory")
        if wd.is_dir() and any(wd.iterdir()) and not force:
            raise GranchainError(f"LAMMPS workdir '{wd}' is not empty; choose an empty "
                                 "directory or allow replacing its files (force / --force)")
        deckmod.check_workdir(wd, force, "LAMMPS workdir")
        try:
            wd.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise GranchainError(f"LAMMPS workdir '{wd}' cannot be created "
                                 f"({exc.strerror or exc}); choose another directory") from None
    plan = plan_run(scene) if plan is None else plan
    groups = deckmod.cadence_groups(scene, vs, plan)
    if len(groups) > 1:
        # one deck per sample cadence, each chain on its own grid as the reference engine
        # samples it; a kept workdir holds each deck in a directory of its own
        if not tmp:
            # an earlier single deck's files (check_workdir recognised them) would be
            # mistaken for this run's
            for stale in deckmod.WORKDIR_FILES:
                (wd / stale).unlink(missing_ok=True)
        r = None if radii is None else np.asarray(radii, dtype=float)
        out: list = [None] * B
        for every, idx in groups:
            sub = None if tmp else wd / deckmod.cadence_dir(every)
            part = run(scene, gaps[idx], vs[idx], workdir=sub, nprocs=nprocs, keep=keep,
                       force=force, progress=progress, timeout=timeout,
                       velocities=velocities, readers=readers, output=output,
                       radii=None if r is None else (r[idx] if r.ndim == 2 else r),
                       plan=plan)
            for i, traj in zip(idx, part):
                out[int(i)] = traj
        yield from out
        return
    if tmp:
        wd = Path(tempfile.mkdtemp(prefix="granchain-lammps-"))
    try:
        from ...lammps.runner import lammps_version, run_lammps
        t0 = time.perf_counter()
        pl = deckmod.plan(scene, gaps=gaps, v_striker=vs, radii=radii, output=output,
                          run_plan=plan)
        deck = deckmod.write_deck(scene, wd, gaps=gaps, v_striker=vs, radii=pl.radii, force=True,
                                  output=output, durable=not tmp, run_plan=plan)
        # every earlier output goes (checked above): LAMMPS then writes new files, never
        # through a symlink left under one of their names
        for stale in (deckmod.DUMP_NAME, deckmod.ENERGY_NAME, deckmod.LEDGER_NAME,
                      deckmod.BINARY_NAME, deckmod.LEDGER_BINARY_NAME, deckmod.LOG_NAME,
                      deckmod.SCREEN_NAME):
            (wd / stale).unlink(missing_ok=True)
        if progress:
            print(f"[granchain] {scene.name}: LAMMPS, {B} chain(s) x {scene.n} spheres, "
                  f"{pl.nsteps} steps max, {nprocs} rank(s) ...", file=sys.stderr, flush=True)
        lrun = run_lammps(deck, wd, nprocs=nprocs, timeout=timeout,
                          log_name=deckmod.LOG_NAME, stdout_name=deckmod.SCREEN_NAME)
        if progress:
            print(f"[granchain] {scene.name}: LAMMPS done in {lrun.wall_time:.1f} s; reading "
                  f"{wd / READERS[output][0]} ...", file=sys.stderr, flush=True)
        if output == "binary":
            data = read_binary(wd / deckmod.BINARY_NAME, scene, pl)
        else:
            data = read_dump(wd / deckmod.DUMP_NAME, scene, pl, velocities=velocities,
                             readers=readers)
        wall = time.perf_counter() - t0
        info = RunInfo(METHOD, scene.dt, pl.sample_dt, nprocs=nprocs,
                       lammps_version=lammps_version(), lammps_wall_s=lrun.wall_time,
                       batch_wall_s=wall, read_wall_s=wall - lrun.wall_time, readers=readers,
                       velocities=velocities, output=output,
                       balance="residual" if residual_balance(scene) else "independent",
                       deck=str(deck) if keep or not tmp else None)
        trajs = list(_trajectories(scene, pl, data, wall / B, info))
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


def residual_balance(scene: Scene) -> bool:
    """True if some effect's work is not output by LAMMPS (it is the balance residual)."""
    return bool(residual_work(scene.effects))


def _trajectories(scene, pl, data, wall_each, info):
    step, V, E, OL = data["step"], data["v"], data["energy"], data["last_overlap"]
    WF, XL, OV = data.get("wall_force"), data.get("last_disp"), data.get("overlaps")
    eff = tuple(sorted(scene.effects))
    limits = result_limits(scene)
    terms = physics_terms(scene)
    members = chain_terms(scene, pl)
    for b in range(pl.n_chains):
        ch = members[b].chain
        vsb = float(pl.v_striker[b])
        v = V[:, b, :]
        keep, status = step.size, "done"
        if scene.t_end is None:
            keep, status = auto_stop(int(pl.chain_samples[b]), vsb, v[:, -1], OL[:, b],
                                     last_disp=None if XL is None else XL[:, b],
                                     terms=members[b], v=v,
                                     overlaps=None if OV is None else OV[:, b])
        bad = np.flatnonzero(~np.all(np.isfinite(v[:keep]), axis=1))
        if bad.size:
            keep, status = int(bad[0]) + 1, "nonfinite"
        extra = {}
        if terms.chain.heterogeneous:
            # each sphere's radius (a member's own under a radius spread)
            extra["radii"] = np.asarray(ch.radii if pl.radii is None else pl.radii[b],
                                        dtype=float)
        if ch.K_wall is not None:
            # the wall force LAMMPS applied (fix wall/gran 'contacts'; with contact damping
            # F_el + eta w at the sample's x and v, ledger.sampled_wall_force), and its static
            # part K_w w_0^1.5 as the reference engine states it (the chain's own K_w and
            # w_0 under a radius spread)
            extra["wall_force"] = WF[:keep, b].copy()
            extra["wall_static"] = float(ch.K_wall * ch.wall_overlap ** 1.5)
        # v and energy: views of the chain's contiguous block of the batch arrays
        yield Trajectory(
            t=step[:keep] * scene.dt, v=v[:keep], energy=E[:keep, b, :],
            gaps=pl.gaps[b].copy(), radius=scene.radius, v_striker=vsb, effects=eff,
            steps=int(step[keep - 1]), rejected=0, status=status, wall_s=wall_each,
            info=info, last_overlap=float(OL[keep - 1, b]), limits=limits,
            # one force computation per step, plus the one of LAMMPS's setup
            force_evaluations=int(step[keep - 1]) + 1, **extra)


def auto_stop(cap: int, v_striker: float, vlast, overlap_last,
              last_disp=None, terms=None, v=None, overlaps=None) -> tuple[int, str]:
    """(samples kept, status) of a t_end auto chain, by the stop rule of
    ``granchain.stoprule`` as ``engines.kernels.run_window`` applies it; ``cap``: its
    sample count at most (its run plan's, ``DeckPlan.chain_samples``).

    vlast, overlap_last: the last particle's velocity (m/s) and its contact's overlap (m)
    at every sample; last_disp: with an end wall, the last particle's displacement (m)
    from its initial position (None: free end). The chain stops (that sample included)
    at the first sample after t = 0 at which the wave has left it, status passed: its
    last particle has left (free end), or moves back from the end wall faster than the
    arrival speed and is back at or behind its initial position (the wave has reflected
    and the wall force is back at or below its static value; ``kernels._left``). A chain
    that never does stops at its cap (``stoprule.auto_t_max``), with status timeout. A
    chain at rest keeps its initial sample only.

    When a law of ``terms`` (the chain's physics) holds contacts closed
    (``effects.holds_contacts``), the chain stops instead at the first sample at which
    every contact's outcome is decided (``stoprule.settled_sample``), from its velocities
    ``v`` (S, n) and its contacts' ``overlaps`` (S, n-1).
    """
    S = len(vlast)
    if v_striker <= 0:
        return 1, "done"
    nt = min(S, cap)
    if terms is not None and holds_contacts(terms):
        s = settled_sample(terms, v_striker, v[:nt], overlaps[:nt],
                           None if last_disp is None else last_disp[:nt])
        return (nt, "timeout") if s is None else (s + 1, "passed")
    if last_disp is not None:
        hit = np.flatnonzero(wall_left(vlast[1:nt], last_disp[1:nt], v_striker))
    else:
        hit = np.flatnonzero(last_detached(vlast[1:nt], overlap_last[1:nt], v_striker))
    if hit.size:
        return int(hit[0]) + 2, "passed"
    return nt, "timeout"
