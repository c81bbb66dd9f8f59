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

from ..units import lmp_float as _r, to_micro
from .spec import EffectSpec

SPEC = EffectSpec("hertz", params=("P_HERTZ_K",))


def force(K, d):
    """Hertz force (N) of a contact of overlap d (m): K d^(3/2), 0 when open."""
    return K * d * math.sqrt(d) if d > 0.0 else 0.0


def energy(K, d):
    """Hertz potential energy (J) of a contact of overlap d (m): (2/5) K d^(5/2)."""
    return 0.4 * K * d * d * math.sqrt(d) if d > 0.0 else 0.0


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
    """(parameters, flags) of the reference kernels, by slot name (engines/kernels.py)."""
    return {"P_HERTZ_K": h.K}, {}


def lammps_pair(h: Hertz) -> tuple[str, str]:
    """(comment, pair_coeff part) of the deck."""
    return ("# pair_coeff: hertz/material E eta_n0 nu (eta_n0 = 0: no damping; 'damping "
            "viscoelastic' is then exactly zero)",
            f"pair_coeff      * * hertz/material {_r(to_micro(h.E, 'pressure'))} 0.0 {_r(h.nu)} "
            "damping viscoelastic")
