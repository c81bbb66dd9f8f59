"""Analytic references used by tests, figures and the thesis comparison."""
from __future__ import annotations

import numpy as np

from .materials import Material


def nesterenko_speed(material: Material, v_m):
    """Long-wave solitary-wave speed V_s = (16/25)^(1/5) c^(4/5) v_m^(1/5) (m/s); a float
    for a scalar v_m, an array for an array."""
    vs = (16.0 / 25.0) ** 0.2 * material.c0 ** 0.8 * np.asarray(v_m, dtype=float) ** 0.2
    return float(vs) if vs.ndim == 0 else vs


def pulse_width(material: Material, radius: float, v_m) -> float:
    """Temporal width of the solitary wave, about 5 diameters over V_s (s)."""
    return 5.0 * 2.0 * radius / nesterenko_speed(material, v_m)


def eq54_group_velocity(v_g_packed, mean_gap, v_striker, radius):
    """Chapter Eq. 5.4, the upper bound of v_g with mean gap gbar:
    (2R + gbar)/v_g = 2R/v_g(no gaps) + gbar/v_s."""
    two_r = 2.0 * radius
    mean_gap = np.asarray(mean_gap, dtype=float)
    return (two_r + mean_gap) / (two_r / np.asarray(v_g_packed) + mean_gap / np.asarray(v_striker))


def coulomb_energy_fraction(g, mu_pg, dx, v_striker):
    """Eq. 5.2: dE_coulomb/E ~ -2 g mu_pg dx / v_s^2."""
    return -2.0 * g * mu_pg * dx / v_striker**2


def air_energy_fraction(dt, T0):
    """Eq. 5.3: dE_air/E ~ -2 dt / T0."""
    return -2.0 * dt / T0
