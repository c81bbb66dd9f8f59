"""What a LAMMPS deck runs: its members (chains), run length and sample cadence.

The deck plan is built from the scene's run plan (``granchain.runplan.RunPlan``: each
striker speed's sample interval, each chain's run length and sample count, as the
reference engine takes them) for a batch of chains; the engine needs it again to read
the output back.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from granchain.effects import SPECS, physics_terms
from granchain.errors import GranchainError
from granchain.guards import require_resolved
from granchain.gaps import member_gaps, member_radii, members, realise
from granchain.lammps import field
from granchain.lammps.parts import Parts
from granchain.runplan import RunPlan, plan_run, step_grid
from granchain.scene import Scene

# The files a deck writes, and what the engine reads back from them.
DECK_NAME = "deck.lmp"
DATA_NAME = "chain.data"
DUMP_NAME = "traj.dump"
ENERGY_NAME = "energy.txt"
LEDGER_NAME = "ledger.txt"
BINARY_NAME = "traj.bin"
LEDGER_BINARY_NAME = "ledger.bin"
LOG_NAME = "log.lammps"          # LAMMPS' log and its screen output (lammps.runner)
SCREEN_NAME = "screen.lammps"
# every file the LAMMPS engine writes into its working directory (a kept --workdir)
WORKDIR_FILES = (DECK_NAME, DATA_NAME, DUMP_NAME, ENERGY_NAME, LEDGER_NAME, BINARY_NAME,
                 LEDGER_BINARY_NAME, LOG_NAME, SCREEN_NAME)
# the text trajectory dump: MDAnalysis needs id and x y z; the engine reads x and vx
DUMP_COLUMNS = ("id", "x", "y", "z", "vx")
# the binary trajectory dump (sorted by id, so no id column): what the engine reads
BINARY_COLUMNS = ("x", "vx")
#: What a deck writes at every sample (DeckPlan.output):
#:   "dump":   traj.dump (text, DUMP_COLUMNS, for MDAnalysis and people) and ledger.txt
#:   "binary": traj.bin (LAMMPS binary dump custom, BINARY_COLUMNS) and ledger.bin (the
#:             per-chain ledger on each chain's first atom, binary): the engine's default
#:   "none":   neither (only energy.txt and thermo): LAMMPS' own cost, for benchmarks
OUTPUTS = ("dump", "binary", "none")
# per-chain ledger (ledger.txt): effect -> (granchain.trajectory.ENERGY_COLUMNS entry,
# the per-atom LAMMPS quantity summed over the chain), in the file's column order; from the
# effects' declarations (rotation: its kinetic energy; groove and drag: the cumulative
# works of fix groove/drag, its per-atom array columns 2 and 3)
LEDGER_INPUTS = {name: (spec.work or "kinetic_rotational", spec.lammps_ledger)
                 for name, spec in SPECS.items() if spec.lammps_ledger}
# the per-atom cumulative works of the effects LAMMPS reports
WORK_COLUMNS = {name: spec.lammps_ledger for name, spec in SPECS.items()
                if spec.work and spec.lammps_ledger}
# the per-chain ledger's column of a chain with an end wall: the x force of the wall on
# the chain's last sphere (fix wall/gran's per-atom 'contacts' output, force units), after
# the energy columns
WALL_FORCE_COLUMN = "wall_force"
# the per-chain ledger's columns of what an effect adds beyond the pair style and fix
# wall/gran (``EffectSpec.lammps_potential``, ``lammps_wall_force``): its contacts' elastic
# energy beyond the Hertz energy the engine computes from the positions (added to the
# potential column) and its x force on the last sphere at the end wall (added to the
# wall force)
POTENTIAL_EXTRA_COLUMN = "potential_extra"
WALL_EXTRA_COLUMN = "wall_force_extra"
# the per-chain ledger's column of the end wall's contact flag (fix wall/gran's per-atom
# 'contacts' column 1), when an effect on keeps its wall state there
# (``EffectSpec.lammps_wall_state``) and the engine evaluates the wall's law itself (an
# effect on declares ``normal_speed``)
WALL_STATE_COLUMN = "wall_state"


def ledger_inputs(scene: Scene) -> tuple[tuple[str, str], ...]:
    """(column, the per-atom LAMMPS quantity summed per chain) of the per-chain ledger, in
    its order: the works and the rotational energy (``LEDGER_INPUTS``), the effects'
    elastic energies beyond Hertz's, then with an end wall its force (fix wall/gran's),
    its contact flag (where the engine evaluates the wall's law in the state LAMMPS
    reports: ``WALL_STATE_COLUMN``) and the effects' parts of it."""
    on = [s for name, s in SPECS.items() if scene.has(name)]
    out = [LEDGER_INPUTS[s.name] for s in on if s.name in LEDGER_INPUTS]
    out += [(POTENTIAL_EXTRA_COLUMN, s.lammps_potential) for s in on if s.lammps_potential]
    if scene.wall is not None:
        out.append((WALL_FORCE_COLUMN, field.WALL_FORCE_INPUT))
        if any(s.normal_speed for s in on) and any(s.lammps_wall_state for s in on):
            out.append((WALL_STATE_COLUMN, field.WALL_STATE_INPUT))
        out += [(WALL_EXTRA_COLUMN, s.lammps_wall_force) for s in on if s.lammps_wall_force]
    return tuple(out)

def batch_members(scene: Scene, gaps, v_striker, radii=None):
    """(gaps (B, n-1), v_striker (B,), radii (B, n) or None) of the chains a deck runs.

    Neither gaps nor v_striker: every member of the scene (``granchain.gaps.members``),
    and under ``chain.radius_spread`` each member's own radii (``gaps.member_radii``)
    unless ``radii`` are given. v_striker alone: realisation 0 for every speed (its radii
    under a spread). gaps given: ``radii`` as given, None meaning the scene's own radii
    (the reference engine's ``radii=None``)."""
    implicit = gaps is None
    if gaps is None and v_striker is None:
        mem = members(scene)
        gaps, v = member_gaps(scene, mem), np.array([m.v_striker for m in mem], dtype=float)
        if radii is None:
            radii = member_radii(scene, mem)
        return gaps, v, _check_radii(scene, radii, len(v))
    if gaps is None:
        v = np.atleast_1d(np.asarray(v_striker, dtype=float))
        gaps = np.stack([realise(scene, 0)] * len(v))
    gaps = np.atleast_2d(np.asarray(gaps, dtype=float))
    if v_striker is None:
        if len(scene.striker_velocities) != 1:
            raise GranchainError("write_deck: give v_striker with gaps for a scene with several "
                                 "striker speeds")
        v_striker = np.full(gaps.shape[0], scene.striker_velocities[0])
    v = np.broadcast_to(np.asarray(v_striker, dtype=float), (gaps.shape[0],)).copy()
    if gaps.shape[1] != scene.n - 1:
        raise GranchainError(f"write_deck: gaps has {gaps.shape[1]} columns; the chain has "
                             f"n-1 = {scene.n - 1} contacts")
    if not (np.all(np.isfinite(gaps)) and np.all(gaps >= 0)):
        raise GranchainError("write_deck: gaps must be finite and >= 0 (m)")
    if not (np.all(np.isfinite(v)) and np.all(v >= 0)):
        raise GranchainError("write_deck: striker speeds must be finite and >= 0 (m/s)")
    if implicit and radii is None and scene.radius_spread is not None:
        radii = np.repeat(member_radii(scene, members(scene, [0])[:1]), len(v), axis=0)
    return gaps, v, _check_radii(scene, radii, len(v))


def _check_radii(scene: Scene, radii, B: int):
    """radii as a (B, n) float array (m), or None."""
    if radii is None:
        return None
    r = np.asarray(radii, dtype=float)
    if r.ndim == 1:
        r = np.broadcast_to(r, (B, r.size))
    if r.shape != (B, scene.n):
        raise GranchainError(f"write_deck: radii has shape {r.shape}; expected ({B}, "
                             f"{scene.n}), one radius per sphere of each chain")
    if not (np.all(np.isfinite(r)) and np.all(r > 0)):
        raise GranchainError("write_deck: radii must be finite and > 0 (m)")
    return np.array(r)


def cadence_dir(every: int) -> str:
    """The directory of one deck of a batch of several sample cadences (the engine's kept
    workdir, ``granchain deck``), named by its steps between samples: ``cadence-20``."""
    return f"cadence-{int(every)}"


def cadence_groups(scene: Scene, v_striker,
                   run_plan: RunPlan | None = None) -> list[tuple[int, np.ndarray]]:
    """The chains of a batch (striker speeds ``v_striker``, (B,) m/s) grouped by sample
    cadence: (steps between samples, the indices of its chains) for each grid on which
    the reference engine samples some of them (each chain's own ``SpeedPlan.sample_dt``
    on the scene's step, ``runplan.step_grid``), in order of their first chain. A deck
    samples all its chains on one grid, so the LAMMPS engine runs each group as a deck
    of its own."""
    run_plan = plan_run(scene) if run_plan is None else run_plan
    vs = np.atleast_1d(np.asarray(v_striker, dtype=float)).tolist()
    every = {v: step_grid(run_plan.speed(v).sample_dt, scene.dt)[0] for v in set(vs)}
    keys = np.array([every[v] for v in vs], dtype=np.int64)
    return [(int(k), np.flatnonzero(keys == k)) for k in dict.fromkeys(keys.tolist())]


def max_travel(scene: Scene, v_max: float, t: float) -> float:
    """A bound (m) on how far any sphere of a chain can move in a run of length t (s)
    whose fastest striker starts at v_max (m/s): v_max t, unless an effect can speed
    spheres up, which gives the bound (``DeckPart.travel``; it raises GranchainError when
    a sphere would speed up without bound within t)."""
    if v_max <= 0 or t <= 0:
        return 0.0
    bounds = Parts(physics_terms(scene)).collect("travel")
    return bounds[0](v_max, t) if bounds else v_max * t


@dataclass(frozen=True)
class DeckPlan:
    """Run length, cadence and layout of a deck (what the engine needs to read it back)."""
    n_chains: int
    n: int
    every: int                 # steps between samples
    nsteps: int                # steps of the run (the cap, with t_end auto)
    sample_dt: float           # s, = every * dt
    dt: float                  # s
    t_run: float               # s, = nsteps * dt
    auto: bool                 # t_end auto: fix halt stops the run when every chain passed
    t_note: str
    output: str                # one of OUTPUTS
    dump_columns: tuple[str, ...]   # columns of the trajectory file (() if output "none")
    ledger_columns: tuple[str, ...]   # the columns of ledger.txt, in order
    #                                   (:func:`ledger_inputs`)
    gaps: np.ndarray           # (B, n-1) m
    v_striker: np.ndarray      # (B,) m/s
    # (B, n) m: each chain's own radii (a radius spread, ``gaps.member_radii``), or None:
    # every chain has the scene's
    radii: np.ndarray | None = None
    # (B,) each chain's sample count on this cadence, t = 0 included
    # (``SpeedPlan.sample_count``): with t_end auto, where a chain that the wave has not
    # left stops (its cap)
    chain_samples: np.ndarray | None = None

    @property
    def nsamples(self) -> int:
        """Samples of a run that is not halted early (including t = 0)."""
        return self.nsteps // self.every + 1


def ledger_binary_columns(pl: DeckPlan) -> tuple[str, ...]:
    """Column names of ledger.bin (output "binary"), as LAMMPS writes them: the per-chain
    sums spread onto the atoms by ``compute ledger_atom`` (chunk/spread/atom)."""
    k = len(pl.ledger_columns)
    return ("c_ledger_atom",) if k == 1 else tuple(f"c_ledger_atom[{j + 1}]" for j in range(k))


def plan(scene: Scene, *, gaps=None, v_striker=None, radii=None,
         output: str = "dump", run_plan: RunPlan | None = None) -> DeckPlan:
    """Run length and cadence of the deck for these members (as the reference engine);
    the scene's method must not be auto (resolve it first). ``output``: what the deck
    writes at every sample, one of :data:`OUTPUTS`. ``radii`` (B, n) m: each chain's own
    (:func:`batch_members` says which radii a deck gets when they are not given).
    Run length and cadence come from ``run_plan``, the scene's run plan
    (``granchain.runplan.plan_run``; planned here if None): the finest member's sample
    interval on the scene's step (``runplan.step_grid``), and each member's run length
    (``SpeedPlan.run_length``: the scene's, its nominal radii under a spread), as the
    reference engine's."""
    require_resolved(scene, "LAMMPS deck")
    if output not in OUTPUTS:
        raise GranchainError(f"LAMMPS deck: output must be one of {', '.join(OUTPUTS)} "
                             f"(got {output!r})")

    gaps, vs, radii = batch_members(scene, gaps, v_striker, radii)
    B = gaps.shape[0]
    run_plan = plan_run(scene) if run_plan is None else run_plan
    own = {v: run_plan.speed(v) for v in set(vs.tolist())}
    sps = [own[v] for v in vs.tolist()]
    sample_si = (min(sp.sample_dt for sp in sps) if sps else run_plan.speed(0.0).sample_dt)
    every, sdt = step_grid(sample_si, scene.dt)
    auto = scene.t_end is None
    if not auto:
        t_si, t_note = scene.t_end, "scene t_end"
    else:
        caps = [sp.run_length(gaps[b]) for b, sp in enumerate(sps) if vs[b] > 0]
        t_si = max(caps) if caps else 0.0
        t_note = ("t_end auto: the auto_t_max cap (granchain.stoprule) of the slowest member; "
                  "fix halt stops earlier once the wave has left every chain"
                  if caps else "t_end auto: no striker moves")
    nsamples = int(math.ceil(t_si / sdt - 1e-9)) if t_si > 0 else 0
    nsteps = nsamples * every
    ledger = tuple(col for col, _ in ledger_inputs(scene))
    return DeckPlan(n_chains=B, n=scene.n, every=every, nsteps=nsteps, sample_dt=sdt,
                    dt=scene.dt, t_run=nsteps * scene.dt, auto=auto and nsteps > 0,
                    t_note=t_note, output=output,
                    dump_columns={"dump": DUMP_COLUMNS, "binary": BINARY_COLUMNS,
                                  "none": ()}[output], ledger_columns=ledger,
                    gaps=gaps, v_striker=vs, radii=radii,
                    chain_samples=np.array([sp.sample_count(gaps[b], sdt)
                                            for b, sp in enumerate(sps)], dtype=np.int64))
