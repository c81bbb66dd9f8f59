"""LAMMPS deck generator: a scene (and its members) -> ``deck.lmp`` + ``chain.data``.

``write_deck(scene, outdir)`` fills the one template ``lammps_inputs/templates/
chain.lmp.in`` (``string.Template``; LAMMPS' own ``$``-syntax is escaped there as
``$$``) and writes the initial configuration to ``chain.data``. The deck runs with the
plain wheel, from its directory: ``lmp -in deck.lmp``.

Choices (also stated in the deck's comments):

* Physics comes only from :func:`granchain.effects.physics_terms` (SI), converted once by
  :func:`to_micro` (``units micro``, docs/explanation/lammps_laws.md section 1).
* Ensembles: chain b (one member = one gap realisation x striker speed) lies on the line
  y = b * spacing, atom ids b*n + 1 ... b*n + n (particle 1 = striker). spacing = 4R >
  2R + skin, so no two chains ever share a neighbour-list pair.
* Positions: x_1 = 0, x_{i+1} = x_i + 2R + g_i in um, evaluated left to right in
  floating point from R and g converted by :func:`to_micro`; written with ``repr``.
* The field's chains (:mod:`granchain.lammps.field`): each sphere's own diameter and
  density, an atom type per material with a ``pair_coeff`` per type pair, an end wall
  (chains laid out right to left from the wall plane x = 0) and a dead load. A chain of
  identical spheres with a free end and no load gives the same bytes as before.
* A radius spread (``chain.radius_spread``, ``radii=``): each chain its own radii, so its
  own diameters and masses, static overlaps, wall overlap and groove springs (the data
  file); the pair_coeff lines hold no radius (pair granular takes R* from the atoms) and
  are every member's (checked); with an end wall the stop rule compares each last sphere
  with its own initial x (``fix store/state 0 x``).
* Rotation off: ``fix nve`` (omega is never integrated and stays exactly 0); the
  tangential law is then ``linear_history 0.0 0.0 0.0`` (k_t = 0, mu = 0: the force
  -k_t xi is exactly zero, and the cap test 0 > 0 never fires, so no division by k_t).
  Rotation on: ``fix nve/sphere``.
* Run length and cadence come from the scene's run plan (``granchain.runplan.RunPlan``), as
  the reference engine's. Run length: ``scene.t_end``, else the stop rule's cap
  (``SpeedPlan.run_length``, ``stoprule.auto_t_max``) of the slowest member (the largest
  cap over all members); rounded up to whole samples as the reference engine does, so
  the last sample falls at the same time. With t_end auto the run also stops (``fix halt``) at the first sample at which the wave has left
  every moving chain (its last particle moves and has no contact left,
  ``granchain.stoprule``): the reference engine's stop rule, applied to the whole batch. ``granchain.engines.lammps`` then cuts each chain's
  record where the reference engine would have stopped that chain.
* Cadence: every = round(sample_interval / dt) (``runplan.step_grid``, as the reference
  engine), from the member with the finest sampling (``SpeedPlan.sample_dt``). The
  LAMMPS engine and ``granchain deck`` (:func:`write_decks`) give a deck the members of
  one cadence (``cadence_groups``), so each is sampled on its own grid.
* Per-sample output, by the deck option ``output`` (:data:`OUTPUTS`, default ``"dump"``):
  ``"dump"`` the text trajectory dump (``traj.dump``, every sample, sorted by id,
  ``%.17g``: ``id x y z vx`` only, :data:`DUMP_COLUMNS`; the engine's ``output="dump"``
  reads it with MDAnalysis, x and vx as float64 additional columns) and the per-chain
  ledger ``ledger.txt``; ``"binary"`` the LAMMPS binary dumps ``traj.bin`` (``x vx``,
  sorted by id, :data:`BINARY_COLUMNS`) and ``ledger.bin``, what the engine reads by
  default (numpy); ``"none"`` neither (LAMMPS' own cost, for benchmarks). The physics
  lines are the same in all three.
* Per-chain ledger, computed inside LAMMPS at every sample: the atoms are binned by chain
  (``compute chunk/atom`` of the atom-style variable floor((id-1)/n)+1) and ``compute
  reduce/chunk`` sums, per chain, the rotational kinetic energy (``compute
  erotate/sphere/atom``, rotation on) and the per-atom cumulative works of ``fix
  groove/drag`` (``f_gd[2]`` groove, ``f_gd[3]`` drag); see :data:`LEDGER_INPUTS`.
  Output "dump": written by ``fix ave/time ... mode vector`` (``ledger.txt``, one row per
  chain, ``%.17g``); output "binary": spread back onto the atoms (``compute
  chunk/spread/atom``) and dumped for each chain's first atom (``ledger.bin``). Only the
  enabled effects' columns; no ledger when there are none (Hertz only). The
  translational kinetic energy and the Hertz potential come from vx and x.
* Box: room on each side for twice :func:`max_travel` (the farthest a sphere can move in
  the run, a propulsive air drag included) plus a diameter, so no sphere leaves it.
* The global energy ledger (``energy.txt``) holds sums over all chains: kinetic
  translational (``compute ke``), rotational (``compute erotate/sphere``, rotation
  only) and the cumulative works of ``fix groove/drag`` (groove, drag); a cross-check
  of the per-chain ledger. Pair granular tallies no Hertz energy (computed from the
  positions), nor the work of the tangential and rolling contact friction.
"""
from __future__ import annotations

import os
from pathlib import Path
from string import Template

import numpy as np

from granchain.effects import SPECS, holds_contacts, physics_terms
from granchain.errors import GranchainError
from granchain.fileio import OutputKind, file_head, atomic_write_text, check_output_path
from granchain.runplan import RunPlan, plan_run
from granchain.scene import Scene
from granchain.scenekeys import NAME_RE, NAME_RULE
from granchain.lammps.deckplan import (BINARY_COLUMNS, BINARY_NAME, DATA_NAME, DECK_NAME,
                                   DUMP_COLUMNS, DUMP_NAME, ENERGY_NAME, LEDGER_BINARY_NAME,
                                   LEDGER_INPUTS, LEDGER_NAME, LOG_NAME, OUTPUTS, SCREEN_NAME,
                                   WALL_FORCE_COLUMN, WORKDIR_FILES,
                                   WORK_COLUMNS, POTENTIAL_EXTRA_COLUMN, WALL_EXTRA_COLUMN,
                                   WALL_STATE_COLUMN,
                                   DeckPlan, batch_members, cadence_dir, cadence_groups,
                                   ledger_inputs,
                                   ledger_binary_columns, max_travel, plan)
from granchain.lammps import field
from granchain.lammps.parts import Parts
from granchain.units import MICRO_EXPONENT, lmp_float as _r, to_micro
from granchain.stoprule import ARRIVAL_FRACTION, arrival_speed

__all__ = ["MICRO_EXPONENT", "to_micro", "template_path", "chain_positions", "write_deck",
           "write_decks", "plan", "DeckPlan", "cadence_dir", "cadence_groups", "DECK_NAME", "DATA_NAME", "DUMP_NAME", "ENERGY_NAME",
           "LEDGER_NAME", "DUMP_COLUMNS", "WORK_COLUMNS", "LEDGER_INPUTS", "OUTPUTS",
           "BINARY_NAME", "LEDGER_BINARY_NAME", "BINARY_COLUMNS", "max_travel",
           "ledger_binary_columns", "WALL_FORCE_COLUMN", "field", "LOG_NAME", "SCREEN_NAME",
           "WORKDIR_FILES", "WORKDIR_KINDS", "check_workdir"]

def template_path() -> Path:
    return Path(__file__).resolve().parents[2] / "lammps_inputs" / "templates" / "chain.lmp.in"


def chain_positions(scene: Scene, gaps, radii=None) -> np.ndarray:
    """x (um) of the n spheres of one chain with gaps (n-1,) in m: x_1 = 0,
    x_{i+1} = x_i + (R_i + R_{i+1}) + g_i (2R + g_i for equal spheres); with an end wall,
    right to left from the wall plane x = 0 through the static overlaps
    (:func:`granchain.lammps.field.positions`). ``radii`` (n,) m: the chain's own (a
    member of a radius spread), else the scene's."""
    sc = scene if radii is None else scene.with_radii(radii)
    return field.positions(field.spheres(physics_terms(sc)), gaps)


def _id_ranges(ids) -> str:
    """LAMMPS id list with stride ranges: [13, 28, 43, 73] -> '13:43:15 73'."""
    ids = list(ids)
    out = []
    i = 0
    while i < len(ids):
        j = i
        if i + 1 < len(ids):
            step = ids[i + 1] - ids[i]
            while j + 1 < len(ids) and ids[j + 1] - ids[j] == step:
                j += 1
        if j > i:
            out.append(f"{ids[i]}:{ids[j]}:{ids[i + 1] - ids[i]}")
        else:
            out.append(str(ids[i]))
        i = j + 1
    return " ".join(out)


def _ledger_block(scene: Scene, pl: DeckPlan, parts: Parts) -> str:
    """Deck lines of the per-chain ledger (ledger.txt with output "dump", ledger.bin with
    output "binary"), or a comment if it has no column or the deck writes no output."""
    if not pl.ledger_columns:
        return ("# (no per-chain ledger file: no effect of this scene has a per-atom LAMMPS "
                "output;\n# the engine computes the kinetic and contact energies from the "
                "trajectory)")
    if pl.output == "none":
        return "# (no per-chain ledger: this deck writes no per-sample output)"
    on = [(name, p) for name, p in zip(SPECS, parts.all) if scene.has(name)]
    notes = {LEDGER_INPUTS[name][0]: p.ledger_note for name, p in on if name in LEDGER_INPUTS}
    notes[WALL_FORCE_COLUMN] = (f"x force of the end wall on the last sphere "
                                f"({field.WALL_FORCE_INPUT}, 1e-9 N)")
    columns = ledger_inputs(scene)
    for c, q in columns:
        if c == POTENTIAL_EXTRA_COLUMN:
            notes[c] = f"the contacts' elastic energy beyond the pair style's ({q})"
        elif c == WALL_EXTRA_COLUMN:
            notes[c] = f"x force the plugin adds on the last sphere at the end wall ({q}, 1e-9 N)"
        elif c == WALL_STATE_COLUMN:
            notes[c] = (f"the end wall's contact flag on the last sphere ({q}: 1 while fix "
                        "wall/gran's touch test holds it, 0 else)")
    inputs = [q for _, q in columns]
    units = "1e-15 J" if WALL_FORCE_COLUMN not in pl.ledger_columns else "1e-15 J unless noted"
    k = len(inputs)
    values = 'c_ledger[*]' if k > 1 else 'c_ledger'
    if pl.output == "dump":
        lines = [f"# per-chain energy ledger ({LEDGER_NAME}): at every sample, one row per chain "
                 "(row b+1 =", f"# chain b), each column the sum over the chain's atoms ({units}) "
                 "of:"]
    else:
        lines = [f"# per-chain energy ledger ({LEDGER_BINARY_NAME}, LAMMPS binary dump): at every "
                 "sample, the sums", "# over each chain's atoms are spread onto its atoms (compute "
                 "chunk/spread/atom) and", "# dumped for the chain's first atom (group heads, "
                 f"ids b*{pl.n}+1), sorted by id; column j+1 ({units}):"]
    lines += [f"#   {j + 1}: {notes[c]}" for j, c in enumerate(pl.ledger_columns)]
    lines += [f'variable        chain atom "floor((id-1)/{pl.n})+1"',
              "compute         chain all chunk/atom v_chain nchunk once ids once compress no"]
    lines += [p.ledger_compute for _, p in on if p.ledger_compute]
    lines.append(f"compute         ledger all reduce/chunk chain sum {' '.join(inputs)}")
    if pl.output == "dump":
        lines.append(f"fix             ledger all ave/time {pl.every} 1 {pl.every} {values} "
                     f'mode vector file {LEDGER_NAME} format " %.17g"')
    else:
        heads = _id_ranges([b * pl.n + 1 for b in range(pl.n_chains)])
        lines += [f"compute         ledger_atom all chunk/spread/atom chain {values}",
                  f"group           heads id {heads}",
                  f"dump            ledger heads custom {pl.every} {LEDGER_BINARY_NAME} "
                  f"{'c_ledger_atom[*]' if k > 1 else 'c_ledger_atom'}",
                  "dump_modify     ledger sort id"]
    return "\n".join(lines)


def _pair_coeff(parts: Parts, sp) -> str:
    """The deck's pair_coeff lines: the effects' notes and ``pair_coeff * *`` with the
    sub-models' words (one material), or a line per pair of atom types
    (``field.pair_coeff``)."""
    if sp.ntypes > 1:
        return field.pair_coeff(sp, parts)
    m = sp.type_materials[0]
    return ("\n".join(parts.notes.values()) + "\npair_coeff      * * "
            + " &\n                ".join(parts.words(m.E, m.nu)))


def _member_spheres(members) -> list:
    """Each chain's :class:`field.Spheres` (chains sharing a Terms share it)."""
    seen: dict = {}
    for t in members:
        if id(t) not in seen:
            seen[id(t)] = field.spheres(t)
    return [seen[id(t)] for t in members]


def _check_shared_laws(members, sps, pair_coeff: str, terms, sp) -> None:
    """The lines a deck states once for every chain must be every member's: the atom
    types (materials), the pair_coeff lines (materials and the contact laws' own
    constants; R* comes from the atoms, the explicit Mindlin k = 8 G* holds no radius),
    the end wall's E*_w and the dead load. Raises GranchainError if a member's differ."""
    pairs_of = {}
    for t, s in zip(members, sps):
        if id(t) in pairs_of:
            continue
        pc = _pair_coeff(Parts(t), s)
        same = (pc == pair_coeff and s.types == sp.types and s.type_materials == sp.type_materials
                and s.wall == sp.wall and s.load == sp.load and s.densities == sp.densities
                and (sp.wall is None or field.wall_modulus(t) == field.wall_modulus(terms)))
        if not same:
            raise GranchainError("chain.radius_spread: a member's contact laws differ from "
                                 "the first member's in a way one LAMMPS deck cannot hold per "
                                 "chain; run it with --engine reference")
        pairs_of[id(t)] = pc


def _trajectory_block(pl: DeckPlan, spacing: str) -> str:
    """Deck lines of the trajectory output (pl.output)."""
    cols = " ".join(pl.dump_columns)
    if pl.output == "dump":
        return "\n".join([
            f"# trajectory ({DUMP_NAME}): every sample, sorted by id, full precision. Only what "
            "the", "# observables need: granchain reads it with MDAnalysis, x and vx as float64 "
            "'additional", "# columns' (MDAnalysis' own positions are float32 and shifted): vx is "
            "the trajectory, x", f"# gives the contact energy. y (= b * {spacing}) and z (= 0) are "
            "constant (MDAnalysis needs", "# them); vy = vz = 0 and omega are not dumped.",
            f"dump            d all custom {pl.every} {DUMP_NAME} {cols}",
            "dump_modify     d sort id format float %.17g"])
    if pl.output == "binary":
        return "\n".join([
            f"# trajectory ({BINARY_NAME}, LAMMPS binary dump: the doubles LAMMPS holds): every "
            "sample,", f"# sorted by id, columns {cols}: vx is the trajectory, x gives the contact "
            "energy", "# (granchain.engines.lammps.read_binary; tools/binary2txt converts it to "
            "text).",
            f"dump            d all custom {pl.every} {BINARY_NAME} {cols}",
            "dump_modify     d sort id"])
    return ("# (no trajectory output: this deck measures LAMMPS alone; write it with output "
            "'dump' or\n# 'binary' to read the chains back)")


def _halt_block(n: int, vs: np.ndarray, every: int, x_last: str | None = None) -> str:
    """Deck lines of the t_end auto stop rule (granchain.stoprule): halt at the first
    sample at which the wave has left every moving chain. Free end: its last particle
    moves forward faster than the arrival speed with no contact left; end wall: its last
    particle moves back from the wall faster than the arrival speed and is back at or
    behind its initial position x_last (um, as written in chain.data: the same in every
    chain; or :data:`X0_PER_ATOM` when the chains' last spheres start at different x, a
    radius spread: each its own initial x, stored by ``fix store/state 0 x`` when the fix
    is defined, before the run). Chains are grouped by striker speed, each group with
    its own arrival speed, as the engines apply it."""
    wall = x_last is not None
    speeds = sorted({float(v) for v in vs if v > 0})
    if wall and x_last == X0_PER_ATOM:
        lines = [
            "# t_end auto: stop at the first sample at which the wave has left every moving "
            "chain:",
            f"# the chain's last particle (particle {n}) moves back from the end wall faster "
            f"than {ARRIVAL_FRACTION:g} x",
            "# its striker speed and is back at or behind its initial x (the wave has reflected "
            "and",
            "# the wall force is back at its static value), the stop rule of the reference "
            "engine.",
            "# The chains' spheres have their own radii, so their last spheres start at their "
            "own x:",
            f"# fix {X0_FIX} stores each one's x as read from chain.data (store/state 0: once, "
            "when",
            "# defined). One group of last particles per striker speed.",
            f"fix             {X0_FIX} lasts store/state 0 x",
        ]
    elif wall:
        lines = [
            "# t_end auto: stop at the first sample at which the wave has left every moving "
            "chain:",
            f"# the chain's last particle (particle {n}) moves back from the end wall faster "
            f"than {ARRIVAL_FRACTION:g} x",
            f"# its striker speed and is back at or behind its initial x = {x_last} um (the wave "
            "has",
            "# reflected and the wall force is back at its static value), the stop rule of the",
            "# reference engine. One group of last particles per striker speed.",
        ]
    else:
        lines = [
            "# t_end auto: stop at the first sample at which the wave has left every moving chain:",
            f"# the chain's last particle (particle {n}) moves faster than {ARRIVAL_FRACTION:g} x its",
            "# striker speed and has no contact left (compute contact/atom = 0), the stop rule of",
            "# the reference engine. One group of last particles per striker speed.",
            "compute         contacts all contact/atom",
        ]
    waiting = []
    for k, v in enumerate(speeds, start=1):
        ids = [b * n + n for b in range(len(vs)) if float(vs[b]) == v]
        thr = _r(to_micro(arrival_speed(v), "velocity"))
        x0 = f"f_{X0_FIX}" if x_last == X0_PER_ATOM else x_last
        rule = f"!((vx<-{thr})&&(x<={x0}))" if wall else f"!((vx>{thr})&&(c_contacts==0))"
        lines += [f"group           last{k} id {_id_ranges(ids)}",
                  f'variable        waiting{k} atom "{rule}"',
                  f"compute         nwaiting{k} last{k} reduce sum v_waiting{k}"]
        waiting.append(f"c_nwaiting{k}")
    lines += [f'variable        nwaiting equal "{"+".join(waiting)}"',
              f"fix             halt all halt {every} v_nwaiting == 0 error continue message yes"]
    return "\n".join(lines)


# the stop rule with an end wall when the chains' last spheres start at different x (a
# radius spread): each compares with its own initial x, stored by this fix
X0_FIX = "x0"
X0_PER_ATOM = "per-atom"


def needs_plugin(scene: Scene) -> bool:
    """Does the scene's deck load the groove/drag plugin (an effect's part of its fix)?"""
    return Parts(physics_terms(scene)).plugin


def render(scene: Scene, *, gaps=None, v_striker=None, radii=None, plugin: str | None = None,
           output: str = "dump", run_plan: RunPlan | None = None) -> tuple[str, str]:
    """The texts of deck.lmp and chain.data (no files written). ``run_plan``: the scene's
    run plan (``granchain.runplan.plan_run``; planned here if None), see :func:`plan`.

    ``radii`` (B, n) m: each chain's own radii (a radius spread; default for a scene's
    own members: ``gaps.member_radii``, see :func:`granchain.lammps.deckplan.batch_members`).
    Each chain then has its own diameters and masses (chain.data), its own contacts (pair
    granular takes R* from the atoms; no pair_coeff depends on a radius), its own groove
    springs (the Groove section), static overlaps and wall overlap (its positions).

    The only text from the scene in either file is its name (in comments and the data
    file's title line), which must match ``granchain.scenekeys.NAME_RE``: no newline, ``$``,
    ``&`` or quote can reach LAMMPS' input parser."""
    if not NAME_RE.fullmatch(scene.name):
        raise GranchainError(f"deck: scene name {scene.name!r} is not a valid name; {NAME_RULE}")
    pl = plan(scene, gaps=gaps, v_striker=v_striker, radii=radii, output=output,
              run_plan=run_plan)
    gaps, vs = pl.gaps, pl.v_striker
    B, n = gaps.shape[0], scene.n
    # each chain's terms under a radius spread (None: every chain has the scene's)
    members = None if pl.radii is None else field.member_terms(scene, pl.radii)
    terms = physics_terms(scene) if members is None else members[0]

    sp = field.spheres(terms)
    sps = [sp] * B if members is None else _member_spheres(members)
    # the largest sphere sets the skin and the chain spacing
    R = max(sp.radii) if members is None else max(max(s.radii) for s in sps)
    D = 2.0 * R
    dt = to_micro(scene.dt, "time")
    skin = 0.1 * R
    spacing = 4.0 * R
    assert spacing > D + skin

    # ---- run length and cadence (as the reference engine) ---------------------------
    every, nsteps, t_note = pl.every, pl.nsteps, pl.t_note
    t_run_us = nsteps * dt

    # ---- positions, velocities, box --------------------------------------------------
    xs = [field.positions(sps[b], gaps[b]) for b in range(B)]
    # no sphere can leave the box: each side has room for twice the farthest any sphere
    # can travel in the run (max_travel: the fastest striker, sped up by a propulsive
    # air drag) plus a diameter
    vmax = float(vs.max()) if B else 0.0
    margin = 2.0 * to_micro(max_travel(scene, vmax, pl.t_run), "length") + 2.0 * D
    xlo = min(float(x[0]) for x in xs) - R - margin if B else -R - margin
    xhi = max(float(x[-1]) for x in xs) + R + margin
    ylo, yhi = -spacing, B * spacing
    zlo, zhi = -D, D

    data = [f"granchain chain.data: scene '{scene.name}' ({scene.hash}), {B} chain(s) x {n} "
            "spheres; atom-ID type diameter density x y z (micro units)",
            "",
            f"{B * n} atoms",
            f"{sp.ntypes} atom types",
            "",
            f"{_r(xlo)} {_r(xhi)} xlo xhi",
            f"{_r(ylo)} {_r(yhi)} ylo yhi",
            f"{_r(zlo)} {_r(zhi)} zlo zhi",
            "",
            "Atoms # sphere",
            ""]
    cols_of = {}
    for b in range(B):
        y = b * spacing
        s = sps[b]
        if id(s) not in cols_of:
            cols_of[id(s)] = [f"{t} {_r(2.0 * r)} {_r(rho)}"
                              for t, r, rho in zip(s.types, s.radii, s.densities)]
        cols = cols_of[id(s)]
        for i in range(n):
            data.append(f"{b * n + i + 1} {cols[i]} {_r(xs[b][i])} {_r(y)} 0.0")
    data += ["", "Velocities", ""]
    for b in range(B):
        for i in range(n):
            vx = to_micro(float(vs[b]), "velocity") if i == 0 else 0.0
            data.append(f"{b * n + i + 1} {_r(vx)} 0.0 0.0 0.0 0.0 0.0")
    # ---- physics: every effect's part of the deck (effects.spec.DeckPart) -------------
    parts = Parts(terms, members, B)
    data += [ln for lines in parts.collect("data") for ln in lines]
    data_text = "\n".join(data) + "\n"
    pair_coeff = _pair_coeff(parts, sp)
    if members is not None:
        _check_shared_laws(members, sps, pair_coeff, terms, sp)

    if parts.plugin:
        if plugin is None:
            raise GranchainError("deck: this scene needs the groove/drag plugin; pass "
                                 "plugin=PATH (write_deck builds it)")
        what = "fix groove/drag plugin" if parts.has_fix else "granchain plugin"
        plugin_variable = (f"# path of the {what} (cached build); 'index' style, so\n"
                           "# 'lmp -var plugin PATH -in deck.lmp' overrides it\n"
                           f"variable        plugin index {plugin}")
        if parts.has_fix:
            fixes = parts.collect("fix")
            args = [a for _, a in fixes] + parts.collect("fix_option")
            plugin_fix = ("\n# fix groove/drag: the granchain plugin "
                          "(lammps_inputs/plugin/fix_groove_drag.md), the laws LAMMPS lacks\n"
                          "plugin          load ${plugin}\n" + "\n".join(c for c, _ in fixes)
                          + "\nfix             gd all groove/drag "
                          + " &\n                ".join(args) + "\n")
        else:
            plugin_fix = ("\n# the granchain plugin (lammps_inputs/plugin/), the laws LAMMPS "
                          "lacks\nplugin          load ${plugin}\n")
        plugin_fix += "".join(ln + "\n" for lines in parts.collect("plugin_lines")
                              for ln in lines)
    else:
        plugin_variable = "# (this scene needs no LAMMPS plugin)"
        plugin_fix = ""

    energies = parts.collect("energy")
    computes = ["compute         ke all ke"] + [c for c, _, _ in energies]
    values = ["c_ke"] + [v for _, v, _ in energies]
    ledger_note = "".join(f", {what}" for _, _, what in energies)
    if parts.has_fix:
        fix_energies = parts.collect("fix_energy")
        values += [v for v, _ in fix_energies]
        ledger_note += ", cumulative work of the " + " and of the ".join(w for _, w in fix_energies)
    ledger_note += " (energy 1e-15 J)"

    if pl.auto and holds_contacts(terms):
        halt = ("# t_end auto: a contact law here holds contacts closed beyond their touching "
                "overlap,\n# which the deck cannot test: the run lasts to its cap, and the "
                "engine cuts each chain's\n# record at the first sample at which every "
                "contact's outcome is decided (granchain.stoprule).")
    elif pl.auto:
        x_last = None
        if sp.wall is not None:
            lasts = {_r(x[-1]) for x in xs}
            x_last = lasts.pop() if len(lasts) == 1 else X0_PER_ATOM
        halt = _halt_block(n, vs, every, x_last=x_last)
    else:
        halt = "# (t_end given: the run has a fixed length)"

    mass_expected = to_micro(terms.chain.masses[0], "mass")
    if members is not None:
        atoms_note = ("each sphere's own diameter and density, each chain's radii its own "
                      "(chain.radius_spread;\n# chain.data; rmass = 4/3 pi r^3 rho)")
    elif sp.uniform:
        atoms_note = (f"diameter {_r(D)} um, density {_r(sp.densities[0])} pg/um^3 (rmass = 4/3 pi "
                      "r^3 rho)")
    else:
        atoms_note = ("each sphere's own diameter and density (chain.data; rmass = 4/3 pi r^3 "
                      "rho)")
    atoms_note += "".join(parts.collect("atoms"))
    read_data_fix = "".join(parts.collect("read_data"))
    subs = dict(
        name=scene.name, scene_hash=scene.hash, n_chains=B, n=n, spacing=_r(spacing),
        min_spacing=_r(D + skin), effects=", ".join(sorted(scene.effects)),
        plugin_variable=plugin_variable, atoms_note=atoms_note, read_data_fix=read_data_fix,
        skin=_r(skin),
        mass_note=("scene.mass" if not terms.chain.heterogeneous else "the striker's mass"
                   if members is None else "chain 0's striker's mass"),
        mass_expected=f"{mass_expected:.17g}", pair_coeff=pair_coeff, plugin_fix=plugin_fix,
        contact_note=parts.contact, end_fixes=field.end_fixes(terms, sp, parts, B, _id_ranges),
        integrator=parts.integrator, timestep=_r(dt), nsteps=nsteps, t_run=_r(t_run_us),
        t_run_note=t_note, every=every, sample_us=f"{every * dt:.15g}",
        sample_note="round(sample_interval/dt) of the reference engine, finest member",
        trajectory=_trajectory_block(pl, _r(spacing)), ledger_note=ledger_note, energy_computes="\n".join(computes),
        energy_values=" ".join(values), thermo_values=" ".join(values),
        thermo_every=max(1, nsteps // 10), halt=halt,
        chain_ledger=_ledger_block(scene, pl, parts),
    )
    deck_text = Template(template_path().read_text()).substitute(subs)
    return deck_text, data_text


# what force may replace: the deck and data files of an earlier write_deck (their first
# lines, written by render)
DECK_FILES = OutputKind("a deck.lmp or chain.data granchain wrote",
                        lambda p: file_head(p, 64).startswith((b"# granchain LAMMPS deck",
                                                           b"granchain chain.data")))


def _starts(*heads: bytes, empty: bool = False):
    def looks_like(p) -> bool:
        head = file_head(p, 64)
        return head.startswith(heads) or (empty and head == b"")
    return looks_like


_AVE_TIME = OutputKind("a LAMMPS fix ave/time file", _starts(b"# Time-averaged data for fix"))
_BINARY = OutputKind("a LAMMPS binary dump",
                     lambda p: file_head(p, 18)[8:18] == b"DUMPCUSTOM")
# an empty log: LAMMPS did not start (nothing to lose)
_LOG = OutputKind("a LAMMPS log", _starts(b"LAMMPS (", empty=True))
# what force may replace in a kept working directory: each file the engine writes there,
# an earlier run's (recognised by its first bytes), never a file of the user's that
# happens to bear the name
WORKDIR_KINDS = {DECK_NAME: DECK_FILES, DATA_NAME: DECK_FILES,
                 DUMP_NAME: OutputKind("a LAMMPS text dump", _starts(b"ITEM: TIMESTEP")),
                 ENERGY_NAME: _AVE_TIME, LEDGER_NAME: _AVE_TIME, BINARY_NAME: _BINARY,
                 LEDGER_BINARY_NAME: _BINARY, LOG_NAME: _LOG, SCREEN_NAME: _LOG}


def check_workdir(workdir, force: bool, field: str = "--workdir") -> None:
    """Refuse (one line naming ``field``) a kept working directory whose files a run
    would replace: a non-empty one without ``force``; with it, any of ``WORKDIR_FILES``
    there that is not an earlier output of its kind (``WORKDIR_KINDS``), a directory or
    a special file; a path that is not a directory. A missing directory is fine (the run
    creates it)."""
    wd = Path(workdir)
    if os.path.lexists(wd) and not wd.is_dir():
        raise GranchainError(f"{field}: '{wd}' is not a directory; give a directory for the "
                             "LAMMPS files (it is created if missing)")
    if not wd.is_dir():
        return
    if not force:
        if any(wd.iterdir()):
            raise GranchainError(f"{field}: '{wd}' is not empty; choose an empty directory or "
                                 "allow replacing its files (--force)")
        return
    for name in WORKDIR_FILES:
        check_output_path(wd / name, True, field, probe=False, kind=WORKDIR_KINDS[name],
                          inside=True)


def write_deck(scene: Scene, outdir: Path, *, gaps=None, v_striker=None, radii=None,
               force: bool = False, plugin: str | None = None, output: str = "dump",
               durable: bool = True, run_plan: RunPlan | None = None) -> Path:
    """Write ``deck.lmp`` and ``chain.data`` into ``outdir``; return the path of deck.lmp.

    output: what the deck writes at every sample (:data:`OUTPUTS`): ``"dump"`` (default)
    the text dump ``traj.dump`` and ``ledger.txt``, readable by people and MDAnalysis;
    ``"binary"`` the LAMMPS binary dumps ``traj.bin`` and ``ledger.bin`` that the engine
    reads by default; ``"none"`` no per-sample output (LAMMPS' own cost).

    gaps: (B, n-1) in m and v_striker: (B,) in m/s, one chain each; default: every member
    of the scene (``granchain.simulate.members``). radii: (B, n) in m, each chain's own
    (a radius spread); default: the members' draws (``gaps.member_radii``) for the scene's
    own members, else the scene's radii (``plan.batch_members``). Refuses to replace
    existing files unless ``force``. ``plugin``: path of the groove/drag plugin (default:
    built/cached). ``durable``: each file written atomically and synced to disk
    (``fileio.atomic_write_text``); False writes them plainly, for a private directory
    that only this process reads and that is removed after the run (the engine's
    temporary directory). ``run_plan``: the scene's run plan (planned here if None).
    """
    outdir = Path(outdir)
    targets = [outdir / DECK_NAME, outdir / DATA_NAME]
    if outdir.exists() and not outdir.is_dir():
        raise GranchainError(f"deck: {str(outdir)!r} is a file, not a directory; give a "
                             "directory for the deck (it is created if missing)")
    if outdir.is_dir():
        for t in targets:                     # refuse before rendering (plugin build, plan)
            check_output_path(t, force, "deck", probe=False, kind=DECK_FILES, inside=True)
    if plugin is None and needs_plugin(scene):
        from granchain.lammps.plugin import build_plugin
        plugin = str(build_plugin())
    deck_text, data_text = render(scene, gaps=gaps, v_striker=v_striker, radii=radii,
                                  plugin=plugin, output=output, run_plan=run_plan)
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GranchainError(f"deck: cannot create the directory {str(outdir)!r} "
                             f"({exc.strerror or exc}); choose another directory") from None
    for t in targets:
        check_output_path(t, force, "deck", kind=DECK_FILES, inside=True)
    for t, text in zip(targets[::-1], (data_text, deck_text)):
        if durable:
            atomic_write_text(t, text, force, "deck")
        else:
            t.write_text(text)
    return targets[0]


def write_decks(scene: Scene, outdir: Path, *, force: bool = False, plugin: str | None = None,
                output: str = "dump", run_plan: RunPlan | None = None) -> list[Path]:
    """Write the decks the LAMMPS engine runs for every member of ``scene``, one per
    sample cadence (:func:`cadence_groups`; each chain sampled on its own grid, as the
    reference engine samples it): ``outdir/deck.lmp`` when the members share one,
    else ``outdir/cadence-<every>/deck.lmp`` (:func:`cadence_dir`), one per cadence, in
    order of their first member. Returns the paths of deck.lmp; every file is checked
    before any is written (:func:`write_deck`'s rules)."""
    outdir = Path(outdir)
    run_plan = plan_run(scene) if run_plan is None else run_plan
    gaps, vs, radii = batch_members(scene, None, None)
    groups = cadence_groups(scene, vs, run_plan)
    if len(groups) <= 1:
        return [write_deck(scene, outdir, force=force, plugin=plugin, output=output,
                           run_plan=run_plan)]
    if outdir.exists() and not outdir.is_dir():
        raise GranchainError(f"deck: {str(outdir)!r} is a file, not a directory; give a "
                             "directory for the decks (it is created if missing)")
    dirs = [outdir / cadence_dir(every) for every, _ in groups]
    for d in dirs:
        if d.exists() and not d.is_dir():
            raise GranchainError(f"deck: {str(d)!r} is a file, not a directory; remove it or "
                                 "choose another directory for the decks")
        if d.is_dir():
            for t in (d / DECK_NAME, d / DATA_NAME):
                check_output_path(t, force, "deck", probe=False, kind=DECK_FILES, inside=True)
    if plugin is None and needs_plugin(scene):
        from granchain.lammps.plugin import build_plugin
        plugin = str(build_plugin())
    return [write_deck(scene, d, gaps=gaps[idx], v_striker=vs[idx],
                       radii=None if radii is None else radii[idx], force=force,
                       plugin=plugin, output=output, run_plan=run_plan)
            for (_, idx), d in zip(groups, dirs)]
