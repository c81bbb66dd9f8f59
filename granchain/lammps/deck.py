"""LAMMPS deck generator: a scene (and its members) -> ``deck.lmp`` + ``chain.data``.

``write_deck(scene, outdir)`` fills the one template ``lammps_inputs/templates/
chain.lmp.in`` (``string.Template``; LAMMPS' own ``$``-syntax is escaped there as
``$$``) and writes the initial configuration to ``chain.data``. The deck runs with the
plain wheel, from its directory: ``lmp -in deck.lmp``.

Choices (also stated in the deck's comments):

* Physics comes only from :func:`granchain.effects.physics_terms` (SI), converted once by
  :func:`to_micro` (``units micro``, docs/lammps_laws.md section 1).
* Ensembles: chain b (one member = one gap realisation x striker speed) lies on the line
  y = b * spacing, atom ids b*n + 1 ... b*n + n (particle 1 = striker). spacing = 4R >
  2R + skin, so no two chains ever share a neighbour-list pair.
* Positions: x_1 = 0, x_{i+1} = x_i + 2R + g_i in um, evaluated left to right in
  floating point from R and g converted by :func:`to_micro`; written with ``repr``.
* Rotation off: ``fix nve`` (omega is never integrated and stays exactly 0); the
  tangential law is then ``linear_history 0.0 0.0 0.0`` (k_t = 0, mu = 0: the force
  -k_t xi is exactly zero, and the cap test 0 > 0 never fires, so no division by k_t).
  Rotation on: ``fix nve/sphere``.
* Run length: ``scene.t_end``, else the reference engine's ``auto_t_max`` of the slowest
  member (the largest cap over all members); rounded up to whole samples as the
  reference engine does, so the last sample falls at the same time. With t_end auto
  the run also stops (``fix halt``) at the first sample at which the wave has left
  every moving chain (its last particle moves and has no contact left,
  ``granchain.schedule``): the reference engine's stop rule, applied to the whole batch. ``granchain.engines.lammps`` then cuts each chain's
  record where the reference engine would have stopped that chain.
* Cadence: every = round(sample_interval / dt) (as the reference engine), from the
  member with the finest sampling.
* Trajectory dump (``traj.dump``, every sample, sorted by id, ``%.17g``): ``id x y z
  vx`` only (:data:`DUMP_COLUMNS`). The engine reads it with MDAnalysis (x and vx as
  float64 additional columns): the velocities, and the Hertz energy from the positions.
  y and z are constant and print in a few characters; vy, vz and omega are not dumped.
* Per-chain ledger (``ledger.txt``, :data:`LEDGER_NAME`), computed inside LAMMPS at every
  sample: the atoms are binned by chain (``compute chunk/atom`` of the atom-style
  variable floor((id-1)/n)+1) and ``compute reduce/chunk`` sums, per chain, the
  rotational kinetic energy (``compute erotate/sphere/atom``, rotation on) and the
  per-atom cumulative works of ``fix groove/drag`` (``f_gd[2]`` groove, ``f_gd[3]``
  drag), written by ``fix ave/time ... mode vector`` (one row per chain, ``%.17g``); see
  :data:`LEDGER_INPUTS`. Only the enabled effects' columns; no ledger file when there
  are none (Hertz only). The translational kinetic energy and the Hertz potential come
  from the dumped vx and x.
* The global energy ledger (``energy.txt``) holds sums over all chains: kinetic
  translational (``compute ke``), rotational (``compute erotate/sphere``, rotation
  only) and the cumulative works of ``fix groove/drag`` (groove, drag); a cross-check
  of the per-chain ledger. Pair granular tallies no Hertz energy (computed from the
  positions), nor the work of the tangential and rolling contact friction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from string import Template

import numpy as np

from granchain.effects import physics_terms
from granchain.errors import GranchainError
from granchain.fileio import atomic_write_text, check_output_path
from granchain.guards import require_resolved
from granchain.scene import NAME_RE, Scene
from granchain.schedule import ARRIVAL_FRACTION, arrival_speed

__all__ = ["MICRO_EXPONENT", "to_micro", "template_path", "chain_positions", "write_deck",
           "plan", "DeckPlan", "DECK_NAME", "DATA_NAME", "DUMP_NAME", "ENERGY_NAME",
           "LEDGER_NAME", "DUMP_COLUMNS", "WORK_COLUMNS", "LEDGER_INPUTS"]

DECK_NAME = "deck.lmp"
DATA_NAME = "chain.data"
DUMP_NAME = "traj.dump"
ENERGY_NAME = "energy.txt"
LEDGER_NAME = "ledger.txt"
# the trajectory dump: MDAnalysis needs id and x y z; the engine reads x and vx
DUMP_COLUMNS = ("id", "x", "y", "z", "vx")
# the per-atom cumulative works of fix groove/drag (per-atom array columns 2 and 3;
# column 1 is the spring history)
WORK_COLUMNS = {"groove_friction": "f_gd[2]", "air_drag": "f_gd[3]"}
# per-chain ledger (ledger.txt): effect -> (granchain.trajectory.ENERGY_COLUMNS entry,
# the per-atom LAMMPS quantity summed over the chain), in the file's column order
LEDGER_INPUTS = {"rotation": ("kinetic_rotational", "c_erot_atom"),
                 "groove_friction": ("work_groove_friction", WORK_COLUMNS["groove_friction"]),
                 "air_drag": ("work_air_drag", WORK_COLUMNS["air_drag"])}

# SI value * 10**e = value in LAMMPS 'units micro' (docs/lammps_laws.md section 1).
MICRO_EXPONENT = {
    "length": 6,          # m -> um
    "time": 6,            # s -> us
    "velocity": 0,        # m/s -> um/us
    "acceleration": -6,   # m/s^2 -> um/us^2            (g = 9.81 -> 9.81e-6)
    "mass": 15,           # kg -> pg
    "force": 9,           # N -> 1e-9 N
    "energy": 15,         # J -> 1e-15 J
    "stiffness": 3,       # N/m -> 1e-3 N/m
    "damping": 9,         # kg/s (N s/m) -> 1e-9 kg/s = pg/us
    "pressure": -3,       # Pa -> 1e3 Pa                (E = 200e9 -> 2e8)
    "density": -3,        # kg/m^3 -> 1e3 kg/m^3         (7800 -> 7.8)
}


def to_micro(value: float, quantity: str) -> float:
    """Convert an SI value to micro units by shifting the decimal exponent of its repr.

    The shift is exact in decimal and rounded once, so 150e-6 m -> 150.0 um and
    1e-9 s -> 0.001 us (multiplying by 1e6 in binary may be off by one ulp).
    """
    e = MICRO_EXPONENT[quantity]
    return float(Decimal(repr(float(value))).scaleb(e))


def template_path() -> Path:
    return Path(__file__).resolve().parents[2] / "lammps_inputs" / "templates" / "chain.lmp.in"


def _r(x: float) -> str:
    """A float with repr precision (shortest string that round-trips)."""
    return repr(float(x))


def chain_positions(scene: Scene, gaps) -> np.ndarray:
    """x (um) of the n spheres of one chain: x_1 = 0, x_{i+1} = x_i + 2R + g_i."""
    R = to_micro(scene.radius, "length")
    x = [0.0]
    for g in np.asarray(gaps, dtype=float):
        x.append(x[-1] + 2.0 * R + to_micro(float(g), "length"))
    return np.array(x)


def _members(scene: Scene, gaps, v_striker):
    if gaps is None and v_striker is None:
        from granchain.simulate import member_gaps, members
        mem = members(scene)
        return member_gaps(scene, mem), np.array([m.v_striker for m in mem], dtype=float)
    if gaps is None:
        v = np.atleast_1d(np.asarray(v_striker, dtype=float))
        from granchain.gaps import realise
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
    return gaps, v


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
    dump_columns: tuple[str, ...]
    ledger_columns: tuple[str, ...]   # ENERGY_COLUMNS entries of ledger.txt, in order
    gaps: np.ndarray           # (B, n-1) m
    v_striker: np.ndarray      # (B,) m/s

    @property
    def nsamples(self) -> int:
        """Samples of a run that is not halted early (including t = 0)."""
        return self.nsteps // self.every + 1


def plan(scene: Scene, *, gaps=None, v_striker=None) -> DeckPlan:
    """Run length and cadence of the deck for these members (as the reference engine);
    the scene's method must not be auto (resolve it first)."""
    from granchain.engines.reference import auto_t_max
    from granchain.schedule import sample_interval

    require_resolved(scene, "LAMMPS deck")
    gaps, vs = _members(scene, gaps, v_striker)
    B = gaps.shape[0]
    sdts = [sample_interval(scene, float(v)) for v in vs]
    sample_si = min(sdts) if sdts else sample_interval(scene, 0.0)
    every = max(1, int(round(sample_si / scene.dt)))
    sdt = every * scene.dt
    auto = scene.t_end is None
    if not auto:
        t_si, t_note = scene.t_end, "scene t_end"
    else:
        caps = [auto_t_max(scene, gaps[b], float(vs[b])) for b in range(B) if vs[b] > 0]
        t_si = max(caps) if caps else 0.0
        t_note = ("t_end auto: the reference engine's auto_t_max cap of the slowest member; "
                  "fix halt stops earlier once the wave has left every chain"
                  if caps else "t_end auto: no striker moves")
    nsamples = int(math.ceil(t_si / sdt - 1e-9)) if t_si > 0 else 0
    nsteps = nsamples * every
    ledger = tuple(col for eff, (col, _) in LEDGER_INPUTS.items() if scene.has(eff))
    return DeckPlan(n_chains=B, n=scene.n, every=every, nsteps=nsteps, sample_dt=sdt,
                    dt=scene.dt, t_run=nsteps * scene.dt, auto=auto and nsteps > 0,
                    t_note=t_note, dump_columns=DUMP_COLUMNS, ledger_columns=ledger,
                    gaps=gaps, v_striker=vs)


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


def _ledger_block(scene: Scene, pl: DeckPlan) -> str:
    """Deck lines of the per-chain ledger (ledger.txt), or a comment if it has no column."""
    if not pl.ledger_columns:
        return ("# (no per-chain ledger file: this scene has no rotation, groove friction or "
                "air drag;\n# the engine computes the kinetic and Hertz energies from the dump)")
    notes = {"kinetic_rotational": "rotational kinetic energy (compute erotate/sphere/atom)",
             "work_groove_friction": f"cumulative work of the groove friction "
                                     f"({WORK_COLUMNS['groove_friction']})",
             "work_air_drag": f"cumulative work of the air drag ({WORK_COLUMNS['air_drag']})"}
    inputs = [LEDGER_INPUTS[eff][1] for eff in LEDGER_INPUTS if scene.has(eff)]
    k = len(inputs)
    lines = ["# per-chain energy ledger (ledger.txt): at every sample, one row per chain (row b+1 =",
             "# chain b), each column the sum over the chain's atoms (1e-15 J) of:"]
    lines += [f"#   {j + 1}: {notes[c]}" for j, c in enumerate(pl.ledger_columns)]
    lines += [f'variable        chain atom "floor((id-1)/{pl.n})+1"',
              "compute         chain all chunk/atom v_chain nchunk once ids once compress no"]
    if scene.has("rotation"):
        lines.append("compute         erot_atom all erotate/sphere/atom")
    lines += [f"compute         ledger all reduce/chunk chain sum {' '.join(inputs)}",
              f"fix             ledger all ave/time {pl.every} 1 {pl.every} "
              f"{'c_ledger[*]' if k > 1 else 'c_ledger'} mode vector file {LEDGER_NAME} "
              'format " %.17g"']
    return "\n".join(lines)


def _halt_block(n: int, vs: np.ndarray, every: int) -> str:
    """Deck lines of the t_end auto stop rule (granchain.schedule): halt at the first
    sample at which the last particle of every moving chain has left. Chains are grouped
    by striker speed, each group with its own arrival speed, as the engines apply it."""
    speeds = sorted({float(v) for v in vs if v > 0})
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
        lines += [f"group           last{k} id {_id_ranges(ids)}",
                  f'variable        waiting{k} atom "!((vx>{thr})&&(c_contacts==0))"',
                  f"compute         nwaiting{k} last{k} reduce sum v_waiting{k}"]
        waiting.append(f"c_nwaiting{k}")
    lines += [f'variable        nwaiting equal "{"+".join(waiting)}"',
              f"fix             halt all halt {every} v_nwaiting == 0 error continue message yes"]
    return "\n".join(lines)


def _plugin_path() -> str:
    from granchain.lammps.plugin import build_plugin
    return str(build_plugin())


def render(scene: Scene, *, gaps=None, v_striker=None, plugin: str | None = None) -> tuple[str, str]:
    """The texts of deck.lmp and chain.data (no files written).

    The only text from the scene in either file is its name (in comments and the data
    file's title line), which must match ``granchain.scene.NAME_RE``: no newline, ``$``,
    ``&`` or quote can reach LAMMPS' input parser."""
    if not NAME_RE.fullmatch(scene.name):
        raise GranchainError(f"deck: scene name {scene.name!r} is not a valid name; "
                             "use 1-64 characters from A-Z a-z 0-9 . _ -")
    terms = physics_terms(scene)
    pl = plan(scene, gaps=gaps, v_striker=v_striker)
    gaps, vs = pl.gaps, pl.v_striker
    B, n = gaps.shape[0], scene.n

    L = lambda v: to_micro(v, "length")  # noqa: E731
    R = L(terms.R)
    D = 2.0 * R
    rho = to_micro(scene.material.rho, "density")
    dt = to_micro(scene.dt, "time")
    skin = 0.1 * R
    spacing = 4.0 * R
    assert spacing > D + skin

    # ---- run length and cadence (as the reference engine) ---------------------------
    every, nsteps, t_note = pl.every, pl.nsteps, pl.t_note
    t_run_us = nsteps * dt

    # ---- positions, velocities, box --------------------------------------------------
    xs = [chain_positions(scene, gaps[b]) for b in range(B)]
    vmax = float(vs.max()) if B else 0.0
    margin = 2.0 * vmax * t_run_us + 2.0 * D
    xlo = -R - margin
    xhi = max(float(x[-1]) for x in xs) + R + margin
    ylo, yhi = -spacing, B * spacing
    zlo, zhi = -D, D

    data = [f"granchain chain.data: scene '{scene.name}' ({scene.hash}), {B} chain(s) x {n} "
            "spheres; atom-ID type diameter density x y z (micro units)",
            "",
            f"{B * n} atoms",
            "1 atom types",
            "",
            f"{_r(xlo)} {_r(xhi)} xlo xhi",
            f"{_r(ylo)} {_r(yhi)} ylo yhi",
            f"{_r(zlo)} {_r(zhi)} zlo zhi",
            "",
            "Atoms # sphere",
            ""]
    for b in range(B):
        y = b * spacing
        for i in range(n):
            data.append(f"{b * n + i + 1} 1 {_r(D)} {_r(rho)} {_r(xs[b][i])} {_r(y)} 0.0")
    data += ["", "Velocities", ""]
    for b in range(B):
        for i in range(n):
            vx = to_micro(float(vs[b]), "velocity") if i == 0 else 0.0
            data.append(f"{b * n + i + 1} {_r(vx)} 0.0 0.0 0.0 0.0 0.0")
    data_text = "\n".join(data) + "\n"

    # ---- physics from the terms ------------------------------------------------------
    h = terms.hertz
    E = to_micro(h.E, "pressure")
    parts = [f"pair_coeff      * * hertz/material {_r(E)} 0.0 {_r(h.nu)} damping viscoelastic"]
    pf = terms.particle_friction
    if pf is None:
        parts.append("tangential linear_history 0.0 0.0 0.0")
    elif pf.model == "mindlin":
        parts.append(f"tangential mindlin NULL 0.0 {_r(pf.mu)}")
    else:
        parts.append(f"tangential linear_history {_r(to_micro(pf.kt, 'stiffness'))} 0.0 {_r(pf.mu)}")
    rf = terms.rolling_friction
    if rf is not None:
        parts.append(f"rolling sds {_r(to_micro(rf.k_roll, 'stiffness'))} "
                     f"{_r(to_micro(rf.gamma_roll, 'damping'))} {_r(rf.mu_roll)}")
    pair_comment = ["# pair_coeff: hertz/material E eta_n0 nu (eta_n0 = 0: no damping; 'damping "
                    "viscoelastic' is then exactly zero)"]
    if pf is None:
        pair_comment.append("# tangential: particle_friction off -> linear_history k_t = 0, "
                            "mu = 0: zero tangential force")
    else:
        pair_comment.append(f"# tangential: particle_friction on, {pf.model} (mu_pp = {_r(pf.mu)})")
    if rf is not None:
        pair_comment.append("# rolling sds k_roll gamma_roll mu_roll: rolling_friction on")
    pair_coeff = "\n".join(pair_comment) + "\n" + " &\n                ".join(parts)

    rot = terms.rotation is not None
    gf, ad = terms.groove_friction, terms.air_drag
    need_plugin = gf is not None or ad is not None
    if need_plugin:
        if plugin is None:
            plugin = _plugin_path()
        plugin_variable = ("# path of the fix groove/drag plugin (cached build); 'index' style, so\n"
                           "# 'lmp -var plugin PATH -in deck.lmp' overrides it\n"
                           f"variable        plugin index {plugin}")
        args = []
        notes = []
        if gf is not None:
            args.append(f"groove s {_r(gf.s)} mu {_r(gf.mu)} g {_r(to_micro(gf.g, 'acceleration'))} "
                        f"kt {_r(to_micro(gf.kt, 'stiffness'))} gamma {_r(to_micro(gf.gamma, 'damping'))}")
            notes.append(f"# groove: Coulomb limit mu m g / s, stick spring kt ({gf.kt_source}) + "
                         f"dashpot gamma ({_r(gf.damping)} x critical)")
        if ad is not None:
            args.append(f"drag T0 {_r(to_micro(ad.T0, 'time'))} L {_r(to_micro(ad.L, 'length'))} "
                        f"form {'odd' if ad.odd else 'as_printed'}")
            notes.append("# drag: F = -m (v/T0 - v^2/L)" + (" with v|v| (odd)" if ad.odd else
                                                             " (as printed)"))
        args.append(f"rotation {'yes' if rot else 'no'}")
        groove_fix = ("\n# groove friction / air drag: fix groove/drag (granchain plugin, "
                      "lammps_inputs/plugin/fix_groove_drag.md)\n"
                      "plugin          load ${plugin}\n" + "\n".join(notes) + "\n"
                      "fix             gd all groove/drag " + " &\n                ".join(args) + "\n")
    else:
        plugin_variable = "# (this scene needs no LAMMPS plugin)"
        groove_fix = ""

    if rot:
        integrator = ("# rotation on: translation and rotation about y (I = 0.4 m R^2)\n"
                      "fix             nve all nve/sphere")
    else:
        integrator = ("# rotation off: fix nve integrates translation only, omega stays exactly 0\n"
                      "fix             nve all nve")

    dump_cols = " ".join(pl.dump_columns)
    computes = ["compute         ke all ke"]
    values = ["c_ke"]
    ledger_note = ""
    if rot:
        computes.append("compute         erot all erotate/sphere")
        values.append("c_erot")
        ledger_note += ", rotational kinetic"
    if need_plugin:
        values += ["f_gd[1]", "f_gd[2]"]
        ledger_note += ", cumulative work of the groove friction and of the air drag"
    ledger_note += " (energy 1e-15 J)"

    if pl.auto:
        halt = _halt_block(n, vs, every)
    else:
        halt = "# (t_end given: the run has a fixed length)"

    mass_expected = to_micro(scene.mass, "mass")
    subs = dict(
        name=scene.name, scene_hash=scene.hash, n_chains=B, n=n, spacing=_r(spacing),
        min_spacing=_r(D + skin), effects=", ".join(sorted(scene.effects)),
        plugin_variable=plugin_variable, diameter=_r(D), density=_r(rho), skin=_r(skin),
        mass_expected=f"{mass_expected:.17g}", pair_coeff=pair_coeff, groove_fix=groove_fix,
        integrator=integrator, timestep=_r(dt), nsteps=nsteps, t_run=_r(t_run_us),
        t_run_note=t_note, every=every, sample_us=f"{every * dt:.15g}",
        sample_note="round(sample_interval/dt) of the reference engine, finest member",
        dump_columns=dump_cols, ledger_note=ledger_note, energy_computes="\n".join(computes),
        energy_values=" ".join(values), thermo_values=" ".join(values),
        thermo_every=max(1, nsteps // 10), halt=halt, chain_ledger=_ledger_block(scene, pl),
    )
    deck_text = Template(template_path().read_text()).substitute(subs)
    return deck_text, data_text


def write_deck(scene: Scene, outdir: Path, *, gaps=None, v_striker=None, force: bool = False,
               plugin: str | None = None) -> Path:
    """Write ``deck.lmp`` and ``chain.data`` into ``outdir``; return the path of deck.lmp.

    gaps: (B, n-1) in m and v_striker: (B,) in m/s, one chain each; default: every member
    of the scene (``granchain.simulate.members``). Refuses to replace existing files
    unless ``force``. ``plugin``: path of the groove/drag plugin (default: built/cached).
    """
    outdir = Path(outdir)
    targets = [outdir / DECK_NAME, outdir / DATA_NAME]
    if outdir.exists() and not outdir.is_dir():
        raise GranchainError(f"deck: {str(outdir)!r} is a file, not a directory; give a "
                             "directory for the deck (it is created if missing)")
    if outdir.is_dir():
        for t in targets:                     # refuse before rendering (plugin build, plan)
            check_output_path(t, force, "deck", probe=False)
    deck_text, data_text = render(scene, gaps=gaps, v_striker=v_striker, plugin=plugin)
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GranchainError(f"deck: cannot create the directory {str(outdir)!r} "
                             f"({exc.strerror or exc}); choose another directory") from None
    for t in targets:
        check_output_path(t, force, "deck")
    for t, text in zip(targets[::-1], (data_text, deck_text)):
        atomic_write_text(t, text, force, "deck")
    return targets[0]
