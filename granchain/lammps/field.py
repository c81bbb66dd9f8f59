"""What the field's chains add to a LAMMPS deck: spheres of their own size and material,
an end wall and a dead load (docs/explanation/lammps_laws.md section 12).

All of it comes from the chain record of :func:`granchain.effects.physics_terms`
(``terms.chain``, SI) and is converted once with :func:`~granchain.units.to_micro`.
A chain of identical spheres with a free end and no load gives the deck and data file
of the chapter's chain byte for byte (one atom type, ``pair_coeff * *``, x_1 = 0).

* Sizes and densities: per atom, in the data file (``atom_style sphere``: diameter and
  density; LAMMPS sets rmass = 4/3 pi r^3 rho). Geometry needs no atom type: pair
  granular takes R_i, R_j and R* = R_i R_j/(R_i + R_j) from the atoms.
* Materials: one atom type per distinct (E, nu), numbered in order of first appearance
  from the striker on. Every type pair gets its own ``pair_coeff I J``: I = J the
  type's own ``hertz/material E 0 nu`` (LAMMPS: E* = E/(2(1 - nu^2))); I != J
  ``hertz/material 2E* 0 0`` with 1/E* = (1 - nu_I^2)/E_I + (1 - nu_J^2)/E_J, which
  LAMMPS's one-material formula turns back into E*. LAMMPS's automatic mixing would get
  the Hertz E* right too (``mix_stiffnessE``), but ``tangential mindlin NULL`` then
  derives its stiffness from the mixed E* and the geometric mean of nu, not from the two
  materials: an unlike pair with Mindlin friction gets its k = 8 G* explicitly,
  1/G* = 2(2 - nu_I)(1 + nu_I)/E_I + 2(2 - nu_J)(1 + nu_J)/E_J (``mix_stiffnessG``).
* End wall: one ``fix wall/gran ... xplane NULL 0.0`` on the last sphere of every chain.
  Chains with an end wall are laid out right to left from the plane x = 0, so that the
  wall touches the last sphere of every chain of an ensemble whatever its gaps. The
  wall's law has no second material: ``hertz/material E 0 nu`` gives
  E* = E/(2(1 - nu^2)) and R* = R_n, so the fix gets E = 2 E*_w, nu = 0 with
  1/E*_w = (1 - nu_n^2)/E_n + (1 - nu_w^2)/E_w (a rigid wall: 1/E_w = 0). Its per-atom
  output (``contacts``) holds the wall's force on the sphere, summed per chain into the
  per-chain ledger.
* Dead load: ``fix addforce`` F0 along +x on particle 2 of every chain; the data file's
  positions hold the static overlaps (F0/K_k)^(2/3) of every contact from particle 2 to
  the wall (the striker touches particle 2 at zero overlap).
* A radius spread (``chain.radius_spread``): each chain of the deck is a member with its
  own radii, its own :class:`Spheres` (``member_terms``: the scene ``Scene.with_radii``
  gives it): its own diameters, hence masses, its static and wall overlaps (positions)
  and groove springs (the Groove section, per atom). Nothing in a ``pair_coeff`` depends
  on a radius: Hertz and Mindlin take R* from the atoms' radii (``mindlin NULL``, and
  the explicit k = 8 G* of an unlike pair, are per unit contact radius a), and
  ``linear_history`` k_t and the rolling constants are the scene's; the wall's E*_w is
  the materials'. So one atom type per material still serves every chain
  (docs/explanation/lammps_laws.md section 12.4).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from granchain.units import lmp_float as _r, to_micro
from granchain.materials import effective_modulus

WALL_FIX = "wall"                    # fix ID of the end wall
WALL_FORCE_INPUT = f"f_{WALL_FIX}[2]"   # its per-atom x force on the sphere (contacts col. 2)
WALL_STATE_INPUT = f"f_{WALL_FIX}[1]"   # its per-atom contact flag (contacts col. 1: 1 while
#                                        the fix's touch test holds the sphere)
WALL_X = 0.0                         # um: the wall plane of a chain with an end wall


@dataclass(frozen=True)
class Spheres:
    """The spheres of one chain as the deck writes them (micro units)."""
    radii: tuple[float, ...]          # um, particle 1 (the striker) first
    densities: tuple[float, ...]      # pg/um^3
    types: tuple[int, ...]            # atom type of each sphere (1-based)
    type_materials: tuple             # Material of each atom type
    wall: object                      # Material of the end wall, or None
    load: float                       # dead load on particle 2 (1e-9 N), 0: none
    static_overlap: tuple[float, ...]  # um, each contact at t = 0
    wall_overlap: float               # um

    @property
    def n(self) -> int:
        return len(self.radii)

    @property
    def ntypes(self) -> int:
        return len(self.type_materials)

    @property
    def uniform(self) -> bool:
        """One radius and one density: the deck's comments can name them."""
        return len(set(self.radii)) == 1 and len(set(self.densities)) == 1


def spheres(terms) -> Spheres:
    """The spheres of the scene's chain (``terms.chain``) in micro units."""
    ch = terms.chain
    key_of = [(m.E, m.nu) for m in ch.materials]
    keys: list = []
    mats: list = []
    for k, m in zip(key_of, ch.materials):
        if k not in keys:
            keys.append(k)
            mats.append(m)
    L = lambda v: to_micro(v, "length")  # noqa: E731
    return Spheres(radii=tuple(L(r) for r in ch.radii),
                   densities=tuple(to_micro(m.rho, "density") for m in ch.materials),
                   types=tuple(keys.index(k) + 1 for k in key_of), type_materials=tuple(mats),
                   wall=ch.wall, load=to_micro(ch.load, "force") if ch.load > 0 else 0.0,
                   static_overlap=tuple(L(s) for s in ch.static_overlap),
                   wall_overlap=L(ch.wall_overlap))


def positions(sp: Spheres, gaps) -> np.ndarray:
    """x (um) of the n spheres of one chain with gaps (n-1,) in m.

    Free end: x_1 = 0, x_{i+1} = x_i + (R_i + R_{i+1}) + g_i, left to right (for equal
    spheres exactly the chapter chain's x_i + 2R + g_i). End wall: right to left from
    the wall plane x = 0, x_n = -(R_n - w_0), x_i = x_{i+1} - ((R_i + R_{i+1} - s_i) + g_i),
    with s_i the static overlap of contact i and w_0 the wall's.

    A contact meant to touch at zero overlap (g_i = s_i = 0: the striker's, and every one
    of a packed chain without preload) is never written overlapping: right to left,
    x_i is lowered by ulps until x_{i+1} - x_i >= R_i + R_{i+1} as LAMMPS computes them
    (pair granular touches when r < R_i + R_j), so at most a gap of an ulp (~1e-13 um)
    is left. Left to right the striker's contact is exact (x_1 = 0). An overlap of an ulp
    would do nothing elastic (K delta^1.5) but, with contact damping, a closing contact's
    dashpot scales as delta^(1/4): the striker's spurious ~1e-13 um overlap kicked it at
    setup by ~7e-9 m/s (docs/explanation/lammps_laws.md section 13)."""
    R = sp.radii
    g = [to_micro(float(v), "length") for v in np.asarray(gaps, dtype=float)]
    n = len(R)
    if sp.wall is None:
        x = [0.0]
        for i in range(n - 1):
            x.append(x[-1] + (R[i] + R[i + 1]) + g[i])
        return np.array(x)
    x = [WALL_X - (R[-1] - sp.wall_overlap)]
    for i in range(n - 2, -1, -1):
        xi = x[-1] - ((R[i] + R[i + 1] - sp.static_overlap[i]) + g[i])
        if g[i] == 0.0 and sp.static_overlap[i] == 0.0:
            while x[-1] - xi < R[i] + R[i + 1]:
                xi = math.nextafter(xi, -math.inf)
        x.append(xi)
    return np.array(x[::-1])


def pair_coeff(sp: Spheres, parts) -> str:
    """The deck's pair_coeff lines for a chain of several materials (sp.ntypes > 1), from
    the effects' parts (``lammps.parts.Parts``): per pair of atom types I <= J the
    sub-models' words, I = J of the type's material, I != J of E = 2 E*_IJ, nu = 0 and the
    unlike pair's own entries (``DeckPart.unlike``)."""
    lines = ["# pair_coeff I J per pair of atom types (materials below): the normal model of E "
             "<damp> nu damping <model>,",
             "# the damping's coefficient holding no material (m_eff and R* come from the "
             "atoms). I = J: the type's",
             "# own E and nu (LAMMPS: E* = E/(2(1-nu^2))). I != J: E = 2 E*_IJ, nu = 0, with",
             "# 1/E*_IJ = (1-nu_I^2)/E_I + (1-nu_J^2)/E_J, which LAMMPS's one-material formula "
             "turns",
             "# back into E*_IJ (docs/explanation/lammps_laws.md section 12)."]
    lines += [ln for notes in parts.collect("unlike_notes") for ln in notes]
    for t, m in enumerate(sp.type_materials, start=1):
        lines.append(f"# type {t}: {m.name} (E {_r(m.E)} Pa, nu {_r(m.nu)})")
    lines += list(parts.notes.values())
    mats = sp.type_materials
    for i in range(1, sp.ntypes + 1):
        for j in range(i, sp.ntypes + 1):
            a, b = mats[i - 1], mats[j - 1]
            words = (parts.words(a.E, a.nu) if i == j
                     else parts.words(2.0 * effective_modulus(a, b), 0.0, unlike=(a, b)))
            lines.append(f"pair_coeff      {i} {j} " + " &\n                ".join(words))
    return "\n".join(lines)


def wall_modulus(terms) -> float:
    """E*_w (Pa) of the last sphere on the end wall."""
    ch = terms.chain
    return effective_modulus(ch.materials[-1], ch.wall)


def end_fixes(terms, sp: Spheres, parts, n_chains: int, id_ranges) -> str:
    """Deck lines of the end wall and the dead load ('' for neither); the wall's normal
    law and damping are the pairs' (``parts``: ``lammps.parts.Parts``); id_ranges formats
    an atom id list."""
    if sp.wall is None and sp.load <= 0:
        return ""
    n = sp.n
    out = []
    if sp.wall is not None:
        w = sp.wall
        Ew = wall_modulus(terms)
        kind = "rigid, 1/E_w = 0" if math.isinf(w.E) else f"{w.name}: E {_r(w.E)} Pa, nu {_r(w.nu)}"
        out += [
            f"# end wall ({kind}): the plane x = {_r(WALL_X)} touches the last sphere "
            "of every chain",
            "# (chains are laid out right to left from it). fix wall/gran's normal model of E "
            "and nu gives",
            "# E* = E/(2(1-nu^2)) and R* = R_n (the wall takes the fix's own material): E = "
            "2 E*_w, nu = 0,",
            f"# 1/E*_w = (1-nu_n^2)/E_n + (1-nu_w^2)/E_w, E*_w = {_r(Ew)} Pa. No tangential "
            "force at the wall.",
            "# 'contacts': per-atom wall force (f_wall[2] = its x component on the sphere)."]
        out += [ln for notes in parts.collect("wall_notes") for ln in notes]
        out += [
            f"group           lasts id {id_ranges([b * n + n for b in range(n_chains)])}",
            f"fix             {WALL_FIX} lasts wall/gran granular "
            f"{parts.words(2.0 * Ew, 0.0)[0]} &",
            "                tangential linear_history 0.0 0.0 0.0 "
            f"xplane NULL {_r(WALL_X)} contacts"]
    if sp.load > 0:
        out += [
            f"# dead load (precompression): F0 = {_r(terms.chain.load)} N on particle 2 of every "
            "chain, toward",
            "# the end wall (+x); chain.data holds the static overlaps (F0/K)^(2/3) it causes",
            f"group           second id {id_ranges([b * n + 2 for b in range(n_chains)])}",
            f"fix             load second addforce {_r(sp.load)} 0.0 0.0"]
    return "\n" + "\n".join(out) + "\n"


def member_terms(scene, radii) -> list:
    """The physics terms of each chain of a radius-spread deck (``radii`` (B, n) m): the
    scene each member runs (``Scene.with_radii``: its own masses, contact constants K,
    Mindlin k_t, groove springs and static overlaps), as the reference engine builds its
    rows (``engines.reference.chain_rows``). Members with equal radii share one Terms."""
    from granchain.effects import physics_terms
    seen: dict = {}
    out = []
    for r in np.asarray(radii, dtype=float):
        key = r.tobytes()
        if key not in seen:
            seen[key] = physics_terms(scene.with_radii(r))
        out.append(seen[key])
    return out
