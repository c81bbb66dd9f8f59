"""The LAMMPS engine's energy ledger, built from the dumped positions and velocities:
the deck's sphere :class:`Geometry`, each contact's and the end wall's Hertz energy, the
kinetic energy, the work of the dead load, the per-chain LAMMPS ledger's columns and the
balance residual of the works LAMMPS does not output (``granchain.engines.lammps``
describes the ledger)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...effects import MODULES, SPECS, physics_terms, residual_work
from ...errors import GranchainError
from ...lammps import deck as deckmod
from ...scene import Scene
from ...trajectory import ENERGY_COLUMNS
from .. import codes
from ..codes import E_KIN_ROT, E_KIN_TRANS, E_POT, E_WORK_LOAD

# the ledger columns of the works LAMMPS outputs (per-atom cumulative works), registry order
REPORTED_WORK = tuple(ENERGY_COLUMNS.index(s.work) for s in SPECS.values()
                      if s.work and s.lammps_reports_work)
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
    # the end wall's law when its force depends on the sphere's velocity (an effect on
    # declares EffectSpec.normal_speed: contact damping; None: none does, or no wall, and
    # the recorded force is fix wall/gran's own): the reference kernels' (P, FL, G (B, G_LEN * n)) of the deck's chains; the
    # wall force is then that law at each sample's state (:func:`sampled_wall_force`)
    wall_law: tuple | None = None
    # with wall_law, where LAMMPS reports the wall's state (an effect on declares
    # EffectSpec.lammps_wall_state; the ledger's WALL_STATE_COLUMN): the kernels' state
    # layout LO and the offsets of those state blocks; None: the law of x and v alone
    wall_state: tuple | None = None


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
                    wall_law=_wall_law(terms, [terms] * pl.n_chains),
                    wall_state=_wall_state(terms))


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
                    wall_law=_wall_law(members[0], members), wall_state=_wall_state(members[0]))


def _wall_law(terms, members) -> tuple | None:
    """:attr:`Geometry.wall_law` of a deck whose first chain has these terms (``members``:
    each chain's)."""
    if terms.chain.K_wall is None or not any(s.normal_speed for e, s in SPECS.items()
                                             if terms.has(e)):
        return None
    from ..reference import chain_rows, pack
    rows: dict = {}
    G = np.concatenate([rows.setdefault(id(t), chain_rows(t, np.zeros((1, t.n - 1))))
                        for t in members])
    return (*pack(terms), G)


def _wall_state(terms) -> tuple | None:
    """:attr:`Geometry.wall_state` of a deck whose first chain has these terms."""
    on = [m for m in MODULES if terms.has(m.SPEC.name)]
    if terms.chain.K_wall is None or not any(m.SPEC.normal_speed for m in on):
        return None
    blocks = [m.SPEC.lammps_wall_state for m in on if m.SPEC.lammps_wall_state]
    if not blocks:
        return None
    unknown = [m.SPEC.name for m in on
               if hasattr(m, "history_normal") and not m.SPEC.lammps_wall_state]
    if unknown:
        raise GranchainError(f"LAMMPS engine: the end wall's law of {', '.join(unknown)} "
                             "reads a history LAMMPS does not report beside "
                             f"{', '.join(m.SPEC.name for m in on if m.SPEC.lammps_wall_state)}")
    from ..reference import Layout
    LO = Layout.of(terms).LO
    return LO, np.array([LO[getattr(codes, b)] for b in blocks], dtype=np.int64)


def sampled_wall_force(x_last, v_last, geo: Geometry, state=None) -> np.ndarray:
    """The end wall's force (N, > 0 in compression) at the samples' state, with the
    reference engine's own law (``engines.compose.wall_force``: the effects' normal laws,
    e.g. F_el + eta w with contact damping, held >= 0 under limit_damping) of the overlap
    of the dumped x and of the last sphere's dumped vx (its closing speed); 0 off the wall.
    With ``geo.wall_state``, ``state`` (..., B) is the wall's state entry LAMMPS reported
    at each sample (fix wall/gran's contact flag, the ledger's WALL_STATE_COLUMN) and the
    law is ``engines.compose.wall_force_at`` in that state (a JKR wall holding the sphere
    closed in tension at d <= 0: the law's tensile force and its damping). That is the
    force at the sample, as the reference engine records it; fix wall/gran's own output
    is the force of the step that ends there, which LAMMPS evaluates with the half-step
    velocity (it differs by eta (v_k - v_k-1/2): 6e-5 to 1.5e-4 of the peak at 1 ns).
    x_last, v_last: (..., B)."""
    from ..integrators import wall_forces, wall_forces_at
    d = (x_last + geo.R_last - deckmod.field.WALL_X) * UM
    P, FL, G = geo.wall_law
    shape = np.shape(d)
    w2 = np.ascontiguousarray(np.reshape(np.broadcast_to(v_last, shape), (-1, shape[-1])),
                              dtype=np.float64)
    if geo.wall_state is None:
        d2 = np.ascontiguousarray(np.reshape(np.maximum(d, 0.0), (-1, shape[-1])),
                                  dtype=np.float64)
        out = np.empty_like(d2)
        wall_forces(d2, w2, G, P, FL, int(P[0]), out)
        return out.reshape(shape)
    LO, blocks = geo.wall_state
    d2 = np.ascontiguousarray(np.reshape(d, (-1, shape[-1])), dtype=np.float64)
    s2 = np.ascontiguousarray(np.repeat(np.reshape(state, d2.shape)[..., None], len(blocks),
                                        axis=2), dtype=np.float64)
    out = np.empty_like(d2)
    wall_forces_at(d2, w2, s2, G, P, FL, LO, blocks, int(P[0]), out)
    return out.reshape(shape)


def _potential(x, geo: Geometry):
    """From the positions x (..., B, n) in um: the Hertz energy per chain (J), the
    contacts' and the end wall's (the law of ``effects.hertz.energy``, each contact with
    its own K), the overlap of each contact (..., B, n-1; m) and the work of the dead
    load F0 (x_2 - x_2(0)) (J; None without load)."""
    overlap = (geo.rsum - (x[..., 1:] - x[..., :-1])) * UM
    d = np.maximum(overlap, 0.0)
    EH = np.sum(0.4 * geo.K * d * d * np.sqrt(d), axis=-1)
    if geo.K_wall is not None:
        dw = np.maximum((x[..., -1] + geo.R_last - deckmod.field.WALL_X) * UM, 0.0)
        EH = EH + 0.4 * geo.K_wall * dw * dw * np.sqrt(dw)
    WL = geo.load * (x[..., 1] - geo.x2_0) * UM if geo.load > 0 else None
    return EH, overlap, WL


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
    E[:, :, E_POT] = EH
    if WL is not None:
        E[:, :, E_WORK_LOAD] = WL


def _fill_ledger(E, WF, pl: "deckmod.DeckPlan", ledger, sampled=None) -> None:
    """The per-chain LAMMPS ledger (samples, B, k) into E's columns (1e-15 J; an effect's
    elastic energy beyond Hertz's added to the potential column) and the end wall's
    force on the last sphere into WF (samples, B) in N, as a compression (> 0), the
    effects' parts of it added; WF None: not wanted. ``sampled``: (x_last, v_last, geo)
    of the samples when the recorded force is fix wall/gran's law at the samples' state
    (:func:`sampled_wall_force`, a velocity-dependent wall law, in the wall's state the
    ledger reports), which replaces its own column."""
    cols = pl.ledger_columns
    if WF is not None and sampled is not None:
        state = (ledger[:, :, cols.index(deckmod.WALL_STATE_COLUMN)]
                 if deckmod.WALL_STATE_COLUMN in cols else None)
        WF[:] = sampled_wall_force(*sampled, state)
    for j, name in enumerate(cols):
        if name == deckmod.WALL_STATE_COLUMN:
            continue
        if name == deckmod.WALL_FORCE_COLUMN:
            if WF is not None and sampled is None:
                WF[:] = -ledger[:, :, j] * FORCE
        elif name == deckmod.WALL_EXTRA_COLUMN:
            if WF is not None:
                WF -= ledger[:, :, j] * FORCE
        elif name == deckmod.POTENTIAL_EXTRA_COLUMN:
            E[:, :, E_POT] += ledger[:, :, j] * ENERGY
        else:
            E[:, :, ENERGY_COLUMNS.index(name)] = ledger[:, :, j] * ENERGY


def _fill_residual(scene: Scene, E) -> None:
    """The works LAMMPS outputs none of (``effects.residual_work``: the contact frictions,
    contact damping) as the residual of the energy balance, in the first of their columns
    (registry order; the others stay 0)."""
    cols = residual_work(scene.effects)
    if cols:
        mech = E[:, :, E_KIN_TRANS] + E[:, :, E_KIN_ROT] + E[:, :, E_POT]
        res = mech - mech[0]
        for c in REPORTED_WORK + (E_WORK_LOAD,):
            res = res - E[:, :, c]
        E[:, :, ENERGY_COLUMNS.index(cols[0])] = res
