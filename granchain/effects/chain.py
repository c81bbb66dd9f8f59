"""chain: the spheres themselves, their sizes, masses and contacts, before any effect.

Every sphere has its own radius R_i, material and mass m_i = rho_i (4/3) pi R_i^3, and
inertia I_i = (2/5) m_i R_i^2; particle 1 is the striker. Contact k joins spheres k and
k+1 with the Hertz constant K_k = (4/3) E* sqrt(R*) (``Scene.contact_k``); an end wall
touches the last sphere with K_w (R* = R_n, ``Scene.wall_k``). A dead load F0 on
particle 2 pushes the chain onto the wall; the chain starts at rest in its static state,
every contact from particle 2 to the wall overlapping by (F0/K)^(2/3), and the state
holds displacements from there (so no coordinate of ~1e-2 m turns rounding into force
noise).

For the kernels (``engines.integrators``) a chain is a block of rows of its per-chain
array G, one row per sphere or contact (``slots.G_*``): the kernel gaps (the
physical gaps less the static overlaps; the wall's in the last row), masses, inertias,
radii and Hertz constants (the wall's last).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..materials import Material
from .spec import EffectSpec

# Not an effect a scene switches: the spheres themselves, declared as the effects are.
# Its ledger column is the dead load's work F0 x_2, computed from the state (no
# accumulated work slot).
SPEC = EffectSpec("chain", params=("P_N_SPHERES", "P_RADIUS", "P_MASS", "P_DEAD_LOAD"),
                  flags=("F_END_WALL", "F_DEAD_LOAD", "F_HETEROGENEOUS"),
                  rows=("G_GAP", "G_MASS", "G_INERTIA", "G_RADIUS", "G_HERTZ_K"), work="work_load",
                  state=(("L_DISP", "particle"), ("L_VEL", "particle")))


@dataclass(frozen=True)
class Chain:
    radii: tuple[float, ...]          # m, particle 1 (the striker) first
    masses: tuple[float, ...]         # kg
    inertias: tuple[float, ...]       # kg m^2
    K: tuple[float, ...]              # Hertz constant of each contact k, k+1 (N/m^1.5)
    K_wall: float | None              # of the last sphere on the end wall; None: free end
    static_overlap: tuple[float, ...]  # overlap of each contact at t = 0 (m)
    wall_overlap: float               # of the wall contact at t = 0 (m)
    load: float                       # dead load on particle 2 (N)
    materials: tuple[Material, ...]
    wall: Material | None
    heterogeneous: bool               # spheres differ in radius or material

    @property
    def n(self) -> int:
        return len(self.radii)

    def kernel_gaps(self, gaps: np.ndarray) -> np.ndarray:
        """(B, n) kernel gaps of chains with physical gaps (B, n-1): overlap_k =
        x_k - x_{k+1} - G_k, G_k = g_k - static overlap; the wall's G_{n-1} = -its
        static overlap (overlap = x_n - G_{n-1})."""
        gaps = np.atleast_2d(gaps)
        out = np.empty((gaps.shape[0], self.n))
        static = np.asarray(self.static_overlap)
        out[:, :-1] = gaps - static if np.any(static) else gaps
        out[:, -1] = -self.wall_overlap
        return out


def build(scene) -> Chain:
    inner, wall = scene.static_overlaps
    return Chain(radii=tuple(scene.radii), masses=tuple(scene.masses),
                 inertias=tuple(scene.inertias), K=tuple(scene.contact_k), K_wall=scene.wall_k,
                 static_overlap=inner, wall_overlap=wall, load=scene.precompression,
                 materials=tuple(scene.materials), wall=scene.wall,
                 heterogeneous=scene.heterogeneous)


def rows(ch: Chain) -> dict:
    """Per-sphere / per-contact rows of the kernels' per-chain array (by G slot name);
    a contact row's last entry is the wall's."""
    return {"G_MASS": ch.masses, "G_INERTIA": ch.inertias, "G_RADIUS": ch.radii,
            "G_HERTZ_K": ch.K + (ch.K_wall if ch.K_wall is not None else 0.0,)}


def kernel(ch: Chain) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name."""
    return ({"P_DEAD_LOAD": ch.load},
            {"F_END_WALL": int(ch.K_wall is not None), "F_DEAD_LOAD": int(ch.load > 0.0),
             "F_HETEROGENEOUS": int(ch.heterogeneous)})
