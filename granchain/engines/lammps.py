"""The LAMMPS engine: a batch of chains -> one LAMMPS run -> one Trajectory per chain.

``run(scene, gaps, v_striker)`` writes one deck holding every chain side by side
(``granchain.lammps.deck.write_deck``), runs it once through
``granchain.lammps.runner.run_lammps`` (``nprocs`` MPI ranks), reads its output back and
yields a :class:`~granchain.trajectory.Trajectory` per chain, in order, like
``granchain.engines.reference.run``. LAMMPS always integrates with velocity Verlet
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
ledger; N, > 0 in compression), ``wall_static`` its static part K_w w_0^(3/2) as the
reference engine states it. With contact damping it is the force at the sample's state,
F_el + eta w of the dumped x and vx (``_damped_wall_force``), as the reference engine
records it: fix wall/gran's output is the force of the step, taken with the half-step
velocity. Spheres of different radii: ``Trajectory.radii``.

With t_end auto the deck stops the batch when every chain has passed (fix halt) and each
chain's record is cut where the reference engine would have stopped that chain (same
rule, same per-chain cap), status ``passed`` (or ``timeout`` at the cap).
"""
from __future__ import annotations

import math
import os
import shutil
import struct
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..effects import contact_damping, physics_terms, residual_work
from ..errors import GranchainError
from ..guards import require_resolved, result_limits
from ..lammps import deck as deckmod
from ..scene import Scene
from ..stoprule import auto_t_max, last_detached, wall_left
from ..trajectory import ENERGY_COLUMNS, RunInfo, Trajectory

METHOD = "lammps-verlet"
DUMP_READ = ("x", "vx")   # the dump columns read as MDAnalysis additional (float64) columns
# output path -> (trajectory file, reader)
READERS = {"binary": ("traj.bin", "read_binary"), "dump": ("traj.dump", "read_dump")}
(E_KIN_TRANS, E_KIN_ROT, E_HERTZ, E_WORK_GROOVE, E_WORK_DRAG, E_WORK_LOAD) = (
    ENERGY_COLUMNS.index(c) for c in (
        "kinetic_translational", "kinetic_rotational", "hertz_potential", "work_groove_friction",
        "work_air_drag", "work_load"))
# SI factors of 'units micro' values (docs/explanation/lammps_laws.md section 1)
UM = 1e-6          # um -> m
ENERGY = 1e-15     # 1e-15 J -> J
FORCE = 1e-9       # 1e-9 N -> N


@dataclass(frozen=True)
class Geometry:
    """What the readers need of a deck's spheres to build the ledger from the dumped
    positions and velocities (``geometry``): contact overlaps
    delta_k = (R_k + R_{k+1}) - (x_{k+1} - x_k) and the wall's x_n + R_n - x_wall (um),
    each contact's Hertz constant (``terms.chain``), the masses and the dead load. Under a
    radius spread (``pl.radii``) every per-sphere or per-contact entry is each chain's
    own, with a leading chain axis (B, ...), so the same arithmetic broadcasts over the
    (..., B, n) positions and velocities."""
    rsum: np.ndarray              # (n-1,) or (B, n-1) um: R_k + R_{k+1}
    K: np.ndarray                 # (n-1,) or (B, n-1) N/m^1.5
    masses: np.ndarray | float    # (n,) or (B, n) kg, or one float for identical spheres
    R_last: float | np.ndarray    # um (or (B,))
    K_wall: float | np.ndarray | None   # N/m^1.5 (or (B,)), None: free end
    load: float                   # N on particle 2 (0: none)
    x2_0: np.ndarray              # (B,) um: particle 2's initial x in each chain
    x_last0: float | np.ndarray   # um: the last sphere's initial x (the same in every
    #                               chain of a deck with an end wall; (B,) under a spread)
    # contact damping at the end wall (None: undamped or no wall): (model code of
    # contact_damping, its constant, limit_damping, m_eff = m_n kg, R* = R_n m), the last
    # two (B,) under a spread; the wall force is then F_el + eta w at each sample's state
    wall_damping: tuple | None = None


def chain_terms(scene: Scene, pl: "deckmod.DeckPlan") -> list:
    """Each chain's physics terms: the scene's for every chain, or under a radius spread
    (``pl.radii``) each member's own (``field.member_terms``)."""
    if pl.radii is None:
        return [physics_terms(scene)] * pl.n_chains
    return deckmod.field.member_terms(scene, pl.radii)


def geometry(scene: Scene, pl: "deckmod.DeckPlan", members=None) -> Geometry:
    """The :class:`Geometry` of the deck of ``pl`` (its chains' spheres and positions);
    ``members``: :func:`chain_terms` if already at hand."""
    if pl.radii is not None:
        return _member_geometry(scene, pl, members or chain_terms(scene, pl))
    terms = physics_terms(scene)
    ch = terms.chain
    sp = deckmod.field.spheres(terms)
    R = np.asarray(sp.radii)
    x0 = [deckmod.field.positions(sp, g) for g in pl.gaps] if ch.load > 0 or ch.wall else []
    x2 = np.array([x[1] for x in x0]) if ch.load > 0 else np.zeros(pl.n_chains)
    masses = np.asarray(ch.masses, dtype=float) if ch.heterogeneous else terms.m
    return Geometry(rsum=R[:-1] + R[1:], K=np.asarray(ch.K, dtype=float), masses=masses,
                    R_last=float(R[-1]), K_wall=ch.K_wall, load=float(ch.load), x2_0=x2,
                    x_last0=float(x0[0][-1]) if ch.wall and x0 else math.nan,
                    wall_damping=_wall_damping(terms, float(ch.masses[-1]),
                                               float(ch.radii[-1])))


def _member_geometry(scene: Scene, pl: "deckmod.DeckPlan", members) -> Geometry:
    """:func:`geometry` of a radius-spread deck: each chain's radii, K, masses, K_w and
    initial positions its own (as the deck wrote them)."""
    sps = [deckmod.field.spheres(t) for t in members]
    R = np.array([s.radii for s in sps])
    ch0 = members[0].chain
    walled, loaded = ch0.K_wall is not None, ch0.load > 0
    x0 = [deckmod.field.positions(s, g) for s, g in zip(sps, pl.gaps)] \
        if loaded or walled else []
    return Geometry(rsum=R[:, :-1] + R[:, 1:],
                    K=np.array([t.chain.K for t in members], dtype=float),
                    masses=np.array([t.chain.masses for t in members], dtype=float),
                    R_last=R[:, -1].copy(),
                    K_wall=np.array([t.chain.K_wall for t in members], dtype=float)
                    if walled else None,
                    load=float(ch0.load),
                    x2_0=np.array([x[1] for x in x0]) if loaded else np.zeros(pl.n_chains),
                    x_last0=np.array([x[-1] for x in x0]) if walled else math.nan,
                    wall_damping=_wall_damping(
                        members[0], np.array([t.chain.masses[-1] for t in members]),
                        np.array([t.chain.radii[-1] for t in members])))


def _wall_damping(terms, m_last, R_last) -> tuple | None:
    """:attr:`Geometry.wall_damping` of a chain with these terms (m_last kg, R_last m: the
    last sphere's, or each chain's)."""
    cd = terms.contact_damping
    if cd is None or terms.chain.K_wall is None:
        return None
    params, flags = contact_damping.kernel(cd)
    return (flags["F_DAMPING_MODEL"], params["P_DAMPING_COEF"], cd.limit_damping, m_last, R_last)


def _damped_wall_force(x_last, v_last, geo: Geometry) -> np.ndarray:
    """The end wall's force (N, > 0 in compression) with contact damping at the samples'
    state: F_el + eta w of the overlap of the dumped x and the last sphere's dumped vx (its
    closing speed), held >= 0 under limit_damping, 0 off the wall. That is the force at
    the sample, as the reference engine records it; fix wall/gran's own output is the
    force of the step that ends there, which LAMMPS evaluates with the half-step velocity
    (it differs by eta (v_k - v_k-1/2): 6e-5 to 1.5e-4 of the peak at 1 ns)."""
    model, damp, limit, meff, Rs = geo.wall_damping
    d = np.maximum((x_last + geo.R_last - deckmod.field.WALL_X) * UM, 0.0)
    fel = geo.K_wall * d * np.sqrt(d)
    touching = d > 0.0
    if model == contact_damping.VISCOELASTIC:
        eta = damp * meff * np.sqrt(Rs * d)
    else:
        q = np.where(touching, meff * fel / np.where(touching, d, 1.0), 0.0)
        eta = damp * np.sqrt(np.maximum(q, 0.0))
    F = fel + eta * v_last
    if limit:
        F = np.maximum(F, 0.0)
    return np.where(touching, F, 0.0)


def run(scene: Scene, gaps, v_striker, *, workdir=None, nprocs: int = 1, keep: bool = False,
        force: bool = False, dt: float | None = None, progress: bool | None = None,
        timeout: float | None = None, velocities: str = "float64", readers: int = 1,
        output: str = "binary", trace: bool = True, radii=None):
    """Yield one Trajectory per chain. gaps: (B, n-1) m; v_striker: (B,) m/s; radii:
    (B, n) m, each chain's own (a radius spread, ``gaps.member_radii``: its own diameters
    and masses, contact constants, groove springs, static overlaps and wall overlap), or
    None (the scene's), as the reference engine's ``radii``. A LAMMPS
    run always records its sampled trajectory (``trace`` is accepted for the callers
    that ask every engine for one).

    output: ``"binary"`` (default) the deck writes LAMMPS binary dumps read with numpy
    (:func:`read_binary`); ``"dump"`` the text dump read with MDAnalysis
    (:func:`read_dump`), for full trajectories kept in ``workdir``. Both give the same
    Trajectory objects.

    workdir: directory for deck, dump and log; default a temporary directory, removed
    afterwards unless ``keep`` (and kept when the run fails, for the error message names
    its deck or dump). A given directory is kept; it must be empty or absent unless
    ``force``. ``dt`` overrides the scene's time step. ``nprocs``: MPI ranks of the
    one LAMMPS run. ``velocities``, ``readers``: see :func:`read_dump` (output "dump"
    only). The scene's
    method must not be auto (``simulate`` and ``compare`` resolve it).
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
    if tmp:
        wd = Path(tempfile.mkdtemp(prefix="granchain-lammps-"))
    else:
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
    try:
        from ..lammps.runner import lammps_version, run_lammps
        t0 = time.perf_counter()
        pl = deckmod.plan(scene, gaps=gaps, v_striker=vs, radii=radii, output=output)
        deck = deckmod.write_deck(scene, wd, gaps=gaps, v_striker=vs, radii=pl.radii, force=True,
                                  output=output, durable=not tmp)
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


def read_dump(path: Path, scene: Scene, pl: "deckmod.DeckPlan", *, velocities: str = "float64",
              readers: int = 1):
    """Read a deck's output into per-chain arrays: the dump with MDAnalysis, and the
    per-chain ledger (``ledger.txt`` next to the dump, if the deck writes one).

    Returns a dict: ``step`` (S,), ``v`` (S, B, n) m/s, ``energy`` (S, B, 7) J and
    ``last_overlap`` (S, B) m, the Hertz overlap of each chain's last contact.
    ``readers`` > 1 splits the dump's frames between that many processes (each opens the
    dump with MDAnalysis, scans it for the frame offsets and parses its share): it only
    pays with idle cores (on the shared 2-core test machine, 2 readers read a 200-chain
    dump 1.8x faster at load ~1, and no faster at load ~4).
    Raises GranchainError (one line, naming the file) if the dump or the ledger is
    missing, truncated or does not match the plan.
    """
    if velocities not in ("float64", "float32"):
        raise GranchainError(f"read_dump: velocities must be 'float64' or 'float32' (got {velocities!r})")
    path = Path(path)
    B, n = pl.n_chains, pl.n
    if not path.is_file() or path.stat().st_size == 0:
        raise GranchainError(f"LAMMPS dump {path} is missing or empty: the run wrote no "
                             "trajectory (see log.lammps next to it)")
    missing = [c for c in DUMP_READ if c not in pl.dump_columns]
    if missing:
        raise GranchainError(f"LAMMPS dump {path}: the deck does not dump {', '.join(missing)}")
    job = {"path": str(path), "B": B, "n": n, "velocities": velocities,
           "geometry": geometry(scene, pl)}
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
    step = np.concatenate([p[1] for p in parts])
    _check_steps(f"LAMMPS dump {path}", pl, step, path.parent)
    V = _chain_major(np.concatenate([p[2] for p in parts]).reshape(len(step), B * n), B, n)
    EH = np.concatenate([p[3] for p in parts])
    last_overlap = np.concatenate([p[4] for p in parts])
    KE = np.concatenate([p[5] for p in parts])
    WL = None if parts[0][6] is None else np.concatenate([p[6] for p in parts])
    ledger = read_ledger(path.with_name(deckmod.LEDGER_NAME), pl, step) if pl.ledger_columns else None
    E = _new_energies(*EH.shape)
    _fill_mechanical(E, KE, EH, WL)
    walled = deckmod.WALL_FORCE_COLUMN in pl.ledger_columns
    damped = parts[0][8] is not None      # the wall force from x and v (contact damping)
    WF = (np.concatenate([p[8] for p in parts]) if damped else np.empty(EH.shape)) \
        if walled else None
    XL = np.concatenate([p[7] for p in parts]) if walled else None
    if ledger is not None:
        _fill_ledger(E, None if damped else WF, pl, ledger)
    _fill_residual(scene, E)
    return {"step": step, "v": V, "energy": E, "last_overlap": last_overlap, "wall_force": WF,
            "last_disp": XL}


def read_binary(path: Path, scene: Scene, pl: "deckmod.DeckPlan"):
    """Read a deck's binary output (``output="binary"``) into per-chain arrays: the
    trajectory ``traj.bin`` and the per-chain ledger ``ledger.bin`` next to it (if the
    deck writes one), both LAMMPS binary ``dump custom`` files sorted by id.

    Returns the dict of :func:`read_dump`, from the same doubles: ``step`` (S,), ``v``
    (S, B, n) m/s, ``energy`` (S, B, 7) J and ``last_overlap`` (S, B) m. Raises
    GranchainError (one line, naming the file) if a file is missing, truncated or does
    not match the plan.
    """
    path = Path(path)
    B, n = pl.n_chains, pl.n
    what = f"LAMMPS binary dump {path}"
    missing = [c for c in DUMP_READ if c not in pl.dump_columns]
    if pl.output != "binary" or missing:
        raise GranchainError(f"{what}: the deck does not write the binary trajectory "
                             f"(output {pl.output!r}, columns {' '.join(pl.dump_columns)})")
    geo = geometry(scene, pl)
    walled = deckmod.WALL_FORCE_COLUMN in pl.ledger_columns
    out = {}

    def consume(lo, block, frames):
        """A block of samples: each chain's velocities into its contiguous record, the
        Hertz energy, last overlap, kinetic energy and load work straight into the result
        arrays (sized for ``frames`` samples at the first block)."""
        if not out:
            out.update(V=_zeros((B, frames, n)), E=_new_energies(frames, B),
                       OL=np.empty((frames, B)), WF=np.empty((frames, B)) if walled else None,
                       XL=np.empty((frames, B)) if walled else None)
        hi = lo + len(block["x"])
        x = block["x"].reshape(-1, B, n)
        EH, out["OL"][lo:hi], WL = _hertz(x, geo)
        if walled:
            out["XL"][lo:hi] = (x[..., -1] - geo.x_last0) * UM
        v = block["vx"].reshape(-1, B, n)
        if walled and geo.wall_damping is not None:
            out["WF"][lo:hi] = _damped_wall_force(x[..., -1], v[..., -1], geo)
        _fill_mechanical(out["E"][lo:hi], _kinetic(v, geo), EH, WL)
        out["V"][:, lo:hi] = v.transpose(1, 0, 2)

    step, _ = read_binary_dump(path, pl.dump_columns, B * n, pl.nsamples, what, consume=consume)
    _check_steps(what, pl, step, path.parent)
    S = len(step)
    V = out["V"][:, :S].transpose(1, 0, 2)           # (S, B, n) view, each chain contiguous
    E, OL = out["E"][:S], out["OL"][:S]
    WF = out["WF"][:S] if walled else None
    XL = out["XL"][:S] if walled else None
    if pl.ledger_columns:
        lpath = path.with_name(deckmod.LEDGER_BINARY_NAME)
        lwhat = f"LAMMPS ledger {lpath}"
        lcols = deckmod.ledger_binary_columns(pl)
        damped = geo.wall_damping is not None     # the wall force is from x and v, above

        def ledger(lo, block, frames):
            hi = lo + len(block[lcols[0]])
            if hi > S:
                raise GranchainError(f"{lwhat} does not match the trajectory: more than {S} "
                                     f"samples; {path.name} has {S}")
            _fill_ledger(E[lo:hi], None if WF is None or damped else WF[lo:hi], pl,
                         np.stack([block[c] for c in lcols], axis=2))

        lstep, _ = read_binary_dump(lpath, lcols, B, pl.nsamples, lwhat, consume=ledger)
        if not np.array_equal(lstep, step):
            raise GranchainError(f"{lwhat} does not match the trajectory: {len(lstep)} samples; "
                                 f"{path.name} has {S}")
    _fill_residual(scene, E)
    return {"step": step, "v": V, "energy": E, "last_overlap": OL, "wall_force": WF,
            "last_disp": XL}


_BIN_MAGIC = b"DUMPCUSTOM"


def read_binary_dump(path: Path, columns, natoms: int, max_frames: int, what: str, *,
                     consume=None, block: int = 64):
    """Frames of a LAMMPS binary ``dump custom`` file (format revision 2, this machine's
    byte order, rows sorted by id): ``(step (S,) int64, {column: (S, natoms) float64})``.

    Each frame: a header (magic string, endianness, revision, step, atom count, box,
    columns per atom, unit style, time flag, column names, number of chunks) and one
    chunk per writing rank (its count of doubles, then the doubles, one row per atom).
    Checks the atom count and column names against ``columns``/``natoms`` and that there
    are at most ``max_frames``; ``what`` names the file in the one-line errors.

    With ``consume``, the columns are handed over in blocks of ``block`` samples instead,
    ``consume(first_sample, {column: (k, natoms)}, frames)`` (``frames``: an upper bound
    on the number of samples, known from the first frame), and the returned dict is
    empty. When every frame has the first one's header (but its step) and chunk sizes,
    as LAMMPS writes them sorted by id on any number of ranks, the doubles are copied
    block by block from strided views of the file; otherwise frame by frame.
    """
    import mmap

    path = Path(path)
    columns = tuple(columns)
    try:
        fh = open(path, "rb")
    except OSError:
        fh = None
    if fh is None or os.fstat(fh.fileno()).st_size == 0:
        if fh is not None:
            fh.close()
        raise GranchainError(f"{what} is missing or empty: the run wrote no output (see "
                             "log.lammps next to it)")
    with fh:     # MAP_POPULATE: the file's pages mapped in one go, not fault by fault
        mm = mmap.mmap(fh.fileno(), 0, flags=mmap.MAP_SHARED | getattr(mmap, "MAP_POPULATE", 0),
                       prot=mmap.PROT_READ)
    try:
        layout = _frame_layout(mm, columns, natoms, max_frames, what)
        if layout is not None:
            return _read_regular(mm, columns, natoms, layout, consume, block)
        return _read_frames(mm, columns, natoms, max_frames, what, consume, block)
    except (struct.error, ValueError, EOFError, IndexError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GranchainError(f"{what} is truncated or unreadable: {msg}") from None
    finally:
        try:
            mm.close()
        except BufferError:                           # a view still alive: closed by GC
            pass


def _frame_header(mm, off: int, columns, natoms: int, s: int, what: str):
    """Parse the header of the frame at ``off``: (step, number of chunks, offset of the
    first chunk, offset of the step field)."""
    mlen, = struct.unpack_from("<q", mm, off)
    mlen = -mlen
    magic = mm[off + 8:off + 8 + mlen]
    off += 8 + mlen
    endian, rev = struct.unpack_from("=ii", mm, off)
    step_at = off + 8
    step, nat, tric = struct.unpack_from("=qqi", mm, step_at)
    off += 28 + 24 + 48 + (24 if tric else 0)          # ..., boundary 6i, box 6d (+3d)
    if magic != _BIN_MAGIC or endian != 1 or rev != 2:
        raise GranchainError(f"{what} is not a LAMMPS binary dump custom file of revision 2 "
                             f"in this byte order (magic {magic!r}, endian {endian}, "
                             f"revision {rev})")
    size_one, ulen = struct.unpack_from("=ii", mm, off)
    off += 8 + ulen                                    # unit style (its name if given)
    off += 1 + (8 if mm[off] else 0)                   # time flag (and time)
    clen, = struct.unpack_from("=i", mm, off)
    cols = mm[off + 4:off + 4 + clen]
    off += 4 + clen
    nchunk, = struct.unpack_from("=i", mm, off)
    off += 4
    names = " ".join(columns).encode()
    if nat != natoms or size_one != len(columns) or cols != names:
        raise GranchainError(f"{what} does not match the deck: frame {s} has {nat} atoms x "
                             f"columns {cols.decode(errors='replace')!r}; expected {natoms} x "
                             f"{names.decode()!r}")
    return step, nchunk, off, step_at


def _frame_layout(mm, columns, natoms: int, max_frames: int, what: str):
    """(steps, chunks [(offset, rows)], frame size) if every frame repeats the first
    one's layout, else None."""
    size = len(mm)
    ncol = len(columns)
    _, nchunk, off, step_at = _frame_header(mm, 0, columns, natoms, 0, what)
    chunks, rows_total = [], 0
    for _ in range(nchunk):
        m, = struct.unpack_from("=i", mm, off)
        if m % ncol or rows_total + m // ncol > natoms:
            return None
        chunks.append((off, off + 4, m // ncol))
        rows_total += m // ncol
        off += 4 + 8 * m
    fb = off
    if rows_total != natoms or size % fb or size // fb > max_frames:
        return None
    S = size // fb
    frames = np.ndarray((S, fb), np.uint8, buffer=mm)
    same = np.ones(fb, dtype=bool)                     # bytes every frame repeats:
    same[chunks[0][1] if chunks else fb:] = False      # not the doubles ...
    for at, _, rows in chunks:
        same[at:at + 4] = True                         # ... but the chunk sizes
    same[step_at:step_at + 8] = False                  # ... nor the step
    idx = np.flatnonzero(same)
    ok = bool(np.all(frames[:, idx] == frames[0, idx]))
    steps = np.ndarray((S,), np.int64, buffer=mm, offset=step_at, strides=(fb,)).copy()
    del frames
    if not ok:
        return None
    return steps, [(data, rows) for _, data, rows in chunks], fb


def _read_regular(mm, columns, natoms: int, layout, consume, block: int):
    steps, chunks, fb = layout
    S, ncol = len(steps), len(columns)
    full = {} if consume else {c: np.empty((S, natoms)) for c in columns}
    buf = {c: np.empty((min(block, S), natoms)) for c in columns} if consume else None
    for lo in range(0, S, block):
        hi = min(S, lo + block)
        dst = {c: buf[c][:hi - lo] for c in columns} if consume else \
            {c: full[c][lo:hi] for c in columns}
        r = 0
        for data, rows in chunks:
            view = np.ndarray((hi - lo, rows, ncol), np.float64, buffer=mm,
                              offset=data + lo * fb, strides=(fb, 8 * ncol, 8))
            for j, c in enumerate(columns):
                dst[c][:, r:r + rows] = view[:, :, j]
            del view
            r += rows
        if consume:
            consume(lo, dst, S)
    return steps, full


def _read_frames(mm, columns, natoms: int, max_frames: int, what: str, consume, block: int):
    size, ncol = len(mm), len(columns)
    out, steps, off, lo = None, [], 0, 0
    while off < size:
        s = len(steps)
        start = off
        step, nchunk, off, _ = _frame_header(mm, off, columns, natoms, s, what)
        if s == max_frames:
            raise GranchainError(f"{what} does not match the deck: more than {max_frames} "
                                 "samples")
        if out is None:   # every frame has the first one's size (header + chunks)
            frames = min(max_frames, size // (off - start + nchunk * 4 + 8 * natoms * ncol) + 1)
            out = {c: np.empty((min(block, frames) if consume else frames, natoms))
                   for c in columns}
        row_s = s - lo if consume else s
        row = 0
        for _ in range(nchunk):
            m, = struct.unpack_from("=i", mm, off)
            off += 4
            if m % ncol or row + m // ncol > natoms or off + 8 * m > size:
                raise EOFError(f"frame {s} (step {step}) ends early")
            a = np.frombuffer(mm, np.float64, m, off).reshape(-1, ncol)
            for j, c in enumerate(columns):
                out[c][row_s, row:row + len(a)] = a[:, j]
            del a
            row += m // ncol
            off += 8 * m
        if row != natoms:
            raise EOFError(f"frame {s} (step {step}) holds {row} of {natoms} atoms")
        steps.append(step)
        if consume and (row_s + 1 == len(out[columns[0]]) or off >= size):
            consume(lo, {c: a[:row_s + 1] for c, a in out.items()}, frames)
            lo = s + 1
    S = len(steps)
    full = {} if consume else {c: a[:S] for c, a in (out or {}).items()}
    return np.array(steps, dtype=np.int64), full


def _chain_major(a, B: int, n: int):
    """(S, B*n) sample-major values -> the same values as an (S, B, n) view of a
    chain-major (B, S, n) array, so that each chain's record is contiguous. Transposed in
    blocks of samples (cache-friendly)."""
    S = a.shape[0]
    out = np.empty((B, S, n))
    for lo in range(0, S, 64):
        out[:, lo:lo + 64] = a[lo:lo + 64].reshape(-1, B, n).transpose(1, 0, 2)
    return out.transpose(1, 0, 2)


def _check_steps(what: str, pl: "deckmod.DeckPlan", step, rundir: Path) -> None:
    """The samples of a run: 0, every, 2 every, ... up to the plan's, or fewer if the run
    was halted by its stop rule (log.lammps in ``rundir``)."""
    S = len(step)
    if S > pl.nsamples or (not pl.auto and S != pl.nsamples) or (
            pl.auto and S < pl.nsamples and not _halted(rundir / "log.lammps")):
        raise GranchainError(f"{what} is truncated: {S} of {pl.nsamples} "
                             "samples and the run was not halted by its stop rule")
    expected = np.arange(S, dtype=np.int64) * pl.every
    if S == 0 or not np.array_equal(step, expected):
        raise GranchainError(f"{what}: its steps are not 0, {pl.every}, "
                             f"{2 * pl.every}, ... (was it written by this deck?)")


def _hertz(x, geo: Geometry):
    """From the positions x (..., B, n) in um: the Hertz energy per chain (J), the
    contacts' and the end wall's (the law of ``effects.hertz.energy``, each contact with
    its own K), the overlap of each chain's last contact (m) and the work of the dead
    load F0 (x_2 - x_2(0)) (J; None without load)."""
    overlap = (geo.rsum - (x[..., 1:] - x[..., :-1])) * UM
    d = np.maximum(overlap, 0.0)
    EH = np.sum(0.4 * geo.K * d * d * np.sqrt(d), axis=-1)
    if geo.K_wall is not None:
        dw = np.maximum((x[..., -1] + geo.R_last - deckmod.field.WALL_X) * UM, 0.0)
        EH = EH + 0.4 * geo.K_wall * dw * dw * np.sqrt(dw)
    WL = geo.load * (x[..., 1] - geo.x2_0) * UM if geo.load > 0 else None
    return EH, overlap[..., -1], WL


def _kinetic(v, geo: Geometry):
    """Translational kinetic energy per chain (J) of velocities v (..., B, n) in m/s."""
    if np.ndim(geo.masses) == 0:
        return 0.5 * geo.masses * np.sum(v * v, axis=-1)
    return 0.5 * np.sum(geo.masses * v * v, axis=-1)


def _zeros(shape) -> np.ndarray:
    """A zeroed float64 array whose memory the kernel maps in one call (an anonymous
    ``mmap`` with ``MAP_POPULATE``), instead of one page fault per page at first touch:
    on the test machine a fresh process took ~0.5 s to first touch 200 MB page by page,
    ~0.07 s populated."""
    import mmap
    size = 8 * int(np.prod(shape))
    flags = getattr(mmap, "MAP_POPULATE", 0)
    if size == 0 or not flags:
        return np.zeros(shape)
    buf = mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | flags)
    return np.frombuffer(buf, dtype=np.float64).reshape(shape)


def _new_energies(S: int, B: int) -> np.ndarray:
    """Zeroed energy ledger (S, B, 7): a view of a (B, S, 7) array, each chain contiguous."""
    return _zeros((B, S, len(ENERGY_COLUMNS))).transpose(1, 0, 2)


def _fill_mechanical(E, KE, EH, WL) -> None:
    """Kinetic translational energy, Hertz energy and the work of the dead load (or None)
    per chain into E (samples, B, len(ENERGY_COLUMNS))."""
    E[:, :, E_KIN_TRANS] = KE
    E[:, :, E_HERTZ] = EH
    if WL is not None:
        E[:, :, E_WORK_LOAD] = WL


def _fill_ledger(E, WF, pl: "deckmod.DeckPlan", ledger) -> None:
    """The per-chain LAMMPS ledger (samples, B, k) into E's columns (1e-15 J) and the end
    wall's force on the last sphere into WF (samples, B) in N, as a compression (> 0);
    WF None: not wanted (with contact damping it comes from the samples' state,
    :func:`_damped_wall_force`)."""
    for j, name in enumerate(pl.ledger_columns):
        if name == deckmod.WALL_FORCE_COLUMN:
            if WF is not None:
                WF[:] = -ledger[:, :, j] * FORCE
        else:
            E[:, :, ENERGY_COLUMNS.index(name)] = ledger[:, :, j] * ENERGY


def _fill_residual(scene: Scene, E) -> None:
    """The works LAMMPS outputs none of (``effects.residual_work``: the contact frictions,
    contact damping) as the residual of the energy balance, in the first of their columns
    (registry order; the others stay 0)."""
    cols = residual_work(scene.effects)
    if cols:
        mech = E[:, :, E_KIN_TRANS] + E[:, :, E_KIN_ROT] + E[:, :, E_HERTZ]
        E[:, :, ENERGY_COLUMNS.index(cols[0])] = (mech - mech[0] - E[:, :, E_WORK_GROOVE]
                                                  - E[:, :, E_WORK_DRAG] - E[:, :, E_WORK_LOAD])


def read_ledger(path: Path, pl: "deckmod.DeckPlan", step) -> np.ndarray:
    """The per-chain ledger ``ledger.txt`` (``fix ave/time ... mode vector``) at the dump's
    samples ``step``: (S, B, k) in LAMMPS energy units (1e-15 J), columns
    ``pl.ledger_columns``. One-line GranchainError if missing, truncated or not this deck's.
    """
    path = Path(path)
    B, k = pl.n_chains, len(pl.ledger_columns)
    try:
        text = path.read_text()
    except OSError:
        text = ""
    if not text:
        raise GranchainError(f"LAMMPS ledger {path} is missing or empty: the run wrote no "
                             "per-chain energies (see log.lammps next to it)")
    # header: three '#' lines; then per sample 'step B' and B rows 'row value*k'
    body = 0
    for _ in range(3):
        if text.startswith("#", body):
            body = text.find("\n", body) + 1 or len(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")        # numpy warns (not raises) at unparsable text
        try:
            vals = np.fromstring(text[body:], sep=" ")
        except (ValueError, DeprecationWarning):
            vals = None
    per = 2 + B * (1 + k)
    S = len(step)
    if vals is None or vals.size % per or not text.endswith("\n"):
        raise GranchainError(f"LAMMPS ledger {path} is truncated or unreadable")
    a = vals.reshape(-1, per)
    rows = a[:, 2:].reshape(-1, B, 1 + k)
    if (len(a) != S or not np.array_equal(a[:, 0], step) or np.any(a[:, 1] != B)
            or np.any(rows[:, :, 0] != np.arange(1, B + 1))):
        raise GranchainError(f"LAMMPS ledger {path} does not match the dump: {len(a)} samples "
                             f"of {B} rows; the dump has {S} samples of {B} chains")
    return rows[:, :, 1:]


def _halted(log: Path) -> bool:
    """Did the run that wrote ``log`` (its log.lammps) stop by its fix halt?"""
    try:
        return "Fix halt condition" in Path(log).read_text(errors="replace")
    except OSError:
        return False


def _read_part(job: dict, part: int, nparts: int):
    """Frames [part*S/nparts, (part+1)*S/nparts) of a dump: (S, step, V, E_hertz,
    overlap of the last contact in m, kinetic energy, work of the dead load (None
    without), displacement of the last sphere in m (NaN without an end wall), the damped
    wall force in N (None without contact damping at a wall)), per chain."""
    import MDAnalysis as mda

    path, B, n, geo = job["path"], job["B"], job["n"], job["geometry"]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")       # no masses/types in a dump: MDAnalysis warns
            u = mda.Universe(path, topology_format="LAMMPSDUMP", format="LAMMPSDUMP",
                             additional_columns=list(DUMP_READ))
            traj = u.trajectory
            S = traj.n_frames
            if u.atoms.n_atoms != B * n:
                raise GranchainError(f"LAMMPS dump {path} holds {u.atoms.n_atoms} atoms; the "
                                     f"deck has {B} chain(s) x {n} = {B * n}")
            lo, hi = part * S // nparts, (part + 1) * S // nparts
            step = np.empty(hi - lo, dtype=np.int64)
            V = np.empty((hi - lo, B, n))
            EH = np.empty((hi - lo, B))
            OL = np.empty((hi - lo, B))
            KE = np.empty((hi - lo, B))
            WL = np.zeros((hi - lo, B))
            XL = np.empty((hi - lo, B))
            WD = np.empty((hi - lo, B)) if geo.wall_damping is not None else None
            for s, ts in enumerate(traj[lo:hi]):
                data = ts.data
                step[s] = data["step"]
                v = data["vx"].reshape(B, n)
                if job["velocities"] == "float32":
                    v = v.astype(np.float32).astype(np.float64)
                V[s] = v
                KE[s] = _kinetic(v, geo)
                x = data["x"].reshape(B, n)
                EH[s], OL[s], wl = _hertz(x, geo)
                XL[s] = (x[:, -1] - geo.x_last0) * UM
                if WD is not None:
                    WD[s] = _damped_wall_force(x[:, -1], v[:, -1], geo)
                if wl is not None:
                    WL[s] = wl
    except GranchainError:
        raise
    except (ValueError, IndexError, EOFError, OSError, KeyError, TypeError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GranchainError(f"LAMMPS dump {path} is truncated or unreadable: {msg}") from None
    return S, step, V, EH, OL, KE, WL if geo.load > 0 else None, XL, WD


def _trajectories(scene, pl, data, wall_each, info):
    step, V, E, OL = data["step"], data["v"], data["energy"], data["last_overlap"]
    WF, XL = data.get("wall_force"), data.get("last_disp")
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
            keep, status = auto_stop(scene, pl.gaps[b], vsb, v[:, -1], OL[:, b], pl.sample_dt,
                                     last_disp=None if XL is None else XL[:, b])
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
            # F_el + eta w at the sample's x and v, _damped_wall_force), and its static
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


def auto_stop(scene: Scene, gaps, v_striker: float, vlast, overlap_last,
              sample_dt: float, last_disp=None) -> tuple[int, str]:
    """(samples kept, status) of a t_end auto chain, by the stop rule of
    ``granchain.stoprule`` as ``engines.kernels.run_window`` applies it.

    vlast, overlap_last: the last particle's velocity (m/s) and its contact's overlap (m)
    at every sample; last_disp: with an end wall, the last particle's displacement (m)
    from its initial position (None: free end). The chain stops (that sample included)
    at the first sample after t = 0 at which the wave has left it, status passed: its
    last particle has left (free end), or moves back from the end wall faster than the
    arrival speed and is back at or behind its initial position (the wave has reflected
    and the wall force is back at or below its static value; ``kernels._left``). A chain
    that never does stops at its own cap, auto_t_max, with status timeout. A chain at
    rest keeps its initial sample only.
    """
    S = len(vlast)
    if v_striker <= 0:
        return 1, "done"
    nt = min(S, int(math.ceil(auto_t_max(scene, np.asarray(gaps), v_striker) / sample_dt)) + 1)
    if last_disp is not None:
        hit = np.flatnonzero(wall_left(vlast[1:nt], last_disp[1:nt], v_striker))
    else:
        hit = np.flatnonzero(last_detached(vlast[1:nt], overlap_last[1:nt], v_striker))
    if hit.size:
        return int(hit[0]) + 2, "passed"
    return nt, "timeout"
