"""hertz: the normal contact force between neighbours.

f_k = K delta_k^(3/2) for delta_k > 0, K = (4/3) E* sqrt(R*), E* = E/(2(1-nu^2)),
R* = R/2; delta_k = (x_k - x_{k+1}) - g_k with x the displacement from the initial
(gapped) positions. Potential energy (2/5) K delta^(5/2). Identical to LAMMPS
``pair_style granular`` ``hertz/material`` with zero damping.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..materials import Material, effective_modulus
from ..units import lmp_float as _r
from . import slots as S
from .lanes import any_contact, overlap, wall_overlap
from .spec import DeckPart, EffectSpec, compiled

SPEC = EffectSpec("hertz", params=("P_HERTZ_K",), always="every chain needs hertz contacts")


@compiled
def force(K, d):
    """Hertz force (N) of a contact of overlap d (m): K d^(3/2), 0 when open."""
    return K * d * math.sqrt(d) if d > 0.0 else 0.0


@compiled
def energy(K, d):
    """Hertz potential energy (J) of a contact of overlap d (m): (2/5) K d^(5/2)."""
    return 0.4 * K * d * d * math.sqrt(d) if d > 0.0 else 0.0


def separation(term, chain, k: int, d: float) -> tuple[float, float]:
    """(d_open, Phi) of contact k (spheres k+1, k+2; 1-based) at overlap d (m): the
    contact opens at d_open = 0, and its force gives the relative motion of the two
    spheres Phi = int_0^d F ds = (2/5) K d^(5/2) (J, 0 when open) on the way there."""
    return 0.0, energy(chain.K[k], d)


def peak_overlap(m_red, K, v):
    """The largest overlap (m) of a head-on collision of reduced mass m_red (kg) at
    closing speed v (m/s): (5 m_red v^2 / (4 K))^(2/5)."""
    return (5.0 * m_red * v * v / (4.0 * K)) ** 0.4


def contact_time(mu, K, v):
    """Duration (s) of a head-on Hertz collision of reduced mass mu (kg) and constant K
    at closing speed v: 2.9432 delta_m / v, delta_m its :func:`peak_overlap`."""
    return 2.9432 * peak_overlap(mu, K, v) / v


def constant(a: Material, Ra: float, b: Material, Rb: float) -> float:
    """K (N/m^1.5) of f = K delta^(3/2) between bodies of materials a, b and radii Ra, Rb
    (Rb = inf: a flat wall): (4/3) E* sqrt(R*), R* = Ra Rb/(Ra + Rb)."""
    R_star = Ra if math.isinf(Rb) else (Ra / 2.0 if Ra == Rb else Ra * Rb / (Ra + Rb))
    return 4.0 / 3.0 * effective_modulus(a, b) * math.sqrt(R_star)


@compiled
def cap(coef, K, d):
    """The Coulomb cap coef K d^(3/2) (N) of a contact of overlap d > 0 (m), multiplied
    in this order (the return mappings' order of operations)."""
    return coef * K * d * math.sqrt(d)


# The compiled parts the engines compose (``spec.HOOKS``). The Hertz constant of contact k
# is row G_HERTZ_K (each contact's own; row n-1 the end wall's).
@compiled
def normal(y, G, P, FL, LO, dy, f, shut):
    """f (n, L): the Hertz force of every contact (row n-1: the end wall's, when there is
    one, else left as it is); returns the open-contact mask (bit k: contact k open in
    every lane, its row of f zero)."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    oK = S.G_HERTZ_K * n
    for k in range(n - 1):
        if any_contact(y, ox, G, k, L):
            for l in range(L):
                f[k, l] = force(G[oK + k, l], overlap(y, ox, G, k, l))
        else:
            for l in range(L):
                f[k, l] = 0.0
            if k < 63:
                shut |= 1 << k
    if FL[S.F_END_WALL] != 0:
        # the end wall: contact n-1, overlap x_n - G_{n-1}
        c = 0
        for l in range(L):
            d = wall_overlap(y, ox, G, n, l)
            c += 1 if d > 0.0 else 0
            f[n - 1, l] = force(G[oK + n - 1, l], d)
        if c == 0 and n - 1 < 63:
            shut |= 1 << (n - 1)
    return shut


@compiled
def contact_normal(F, d, w, G, P, FL, n, k, l):
    """The Hertz force of contact k in lane l at overlap d (the first normal law: F is
    not read)."""
    return force(G[S.G_HERTZ_K * n + k, l], d)


@compiled
def contact_cap(coef, d, G, n, k, l):
    """coef times the Hertz force of contact k in lane l at overlap d > 0 (:func:`cap`)."""
    return cap(coef, G[S.G_HERTZ_K * n + k, l], d)


@compiled
def energies(y, G, P, FL, LO, out):
    """out[E_POT]: the Hertz energy of the contacts and the end wall."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    oK = S.G_HERTZ_K * n
    for k in range(n - 1):
        if not any_contact(y, ox, G, k, L):
            continue
        for l in range(L):
            out[S.E_POT, l] += energy(G[oK + k, l], overlap(y, ox, G, k, l))
    if FL[S.F_END_WALL] != 0:
        for l in range(L):
            out[S.E_POT, l] += energy(G[oK + n - 1, l], wall_overlap(y, ox, G, n, l))


@dataclass(frozen=True)
class Hertz:
    K: float          # N / m^1.5
    R: float          # sphere radius, m
    E: float
    nu: float

    def force(self, delta):
        """The law of :func:`force` on an array of overlaps (m)."""
        d = np.maximum(np.asarray(delta, dtype=float), 0.0)
        return self.K * d * np.sqrt(d)

    def energy(self, delta):
        """The law of :func:`energy` on an array of overlaps (m)."""
        d = np.maximum(np.asarray(delta, dtype=float), 0.0)
        return 0.4 * self.K * d * d * np.sqrt(d)


def build(scene) -> Hertz:
    return Hertz(scene.hertz_k, scene.radius, scene.material.E, scene.material.nu)


def kernel(h: Hertz) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return {"P_HERTZ_K": h.K}, {}


def lammps(h: Hertz, deck) -> DeckPart:
    """The deck's normal law: ``hertz/material E eta_n0 nu`` with no damping (eta_n0 = 0,
    'damping viscoelastic': exactly zero) unless an effect after it gives one."""
    return DeckPart(pair={"normal": "hertz/material {E} {damp} {nu}", "damp": _r(0.0),
                          "damping": "damping viscoelastic"},
                    notes={"normal": "# pair_coeff: hertz/material E eta_n0 nu (eta_n0 = 0: no "
                                     "damping; 'damping viscoelastic' is then exactly zero)"},
                    contact="Hertz (zero viscoelastic damping)")
