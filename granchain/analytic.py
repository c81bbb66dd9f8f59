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


# ---------------------------------------------------------------------------------------
# A precompressed chain (dead load F0 through every contact): Nesterenko's long-wave theory
# ---------------------------------------------------------------------------------------
def bead_constants(material: Material, radius: float) -> tuple[float, float]:
    """(K, m) of identical beads: K = (4/3) E* sqrt(R/2) (N/m^1.5) of f = K delta^(3/2),
    E* = E/(2(1 - nu^2)), and the bead mass m = (4/3) pi R^3 rho (kg)."""
    e_star = material.E / (2.0 * (1.0 - material.nu ** 2))
    mass = material.rho * 4.0 / 3.0 * np.pi * radius ** 3
    return 4.0 / 3.0 * e_star * np.sqrt(radius / 2.0), mass


def precompressed_sound_speed(material: Material, radius: float, force):
    """Long-wave sound speed c0 = 2R sqrt(k2/m) (m/s) of a chain of identical beads under a
    static contact force F0 (N): k2 = (3/2) K^(2/3) F0^(1/3) is the contact's stiffness
    df/ddelta at its static overlap delta0 = (F0/K)^(2/3), and the long-wave limit of the
    linearised chain's dispersion relation gives c0. 0 for F0 = 0."""
    K, m = bead_constants(material, radius)
    k2 = 1.5 * K ** (2.0 / 3.0) * np.asarray(force, dtype=float) ** (1.0 / 3.0)
    c0 = 2.0 * radius * np.sqrt(k2 / m)
    return float(c0) if c0.ndim == 0 else c0


def _ratio_of_strain(x):
    """V_s / c0 as a function of x = xi_m/xi0 (peak over static strain, >= 1):
    [(4/15)(3 + 2 x^(5/2) - 5 x)]^(1/2) / (x - 1). The bracket is d^2 + d^3/6 - d^4/48 +
    O(d^5) with d = x - 1 and cancels to rounding near x = 1, so below d = 1e-4 the series
    of the ratio, 1 + d/12 - d^2/72, is used (error O(d^3) < 1e-12; the closed form's
    rounding there < 2e-8)."""
    x = np.asarray(x, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = x - 1.0
        exact = np.sqrt(4.0 / 15.0 * (3.0 + 2.0 * x ** 2.5 - 5.0 * x)) / d
        series = 1.0 + d / 12.0 - d * d / 72.0
        out = np.where(np.abs(d) < 1e-4, series, exact)
    return np.where(x < 1.0, np.nan, out)


def precompressed_speed_ratio(f_r):
    """V_s / c0 of Nesterenko's solitary wave in a precompressed chain, as a function of
    f_r = F_m/F0 (the wave's largest contact force over the static one, >= 1), as
    Daraio, Nesterenko, Herbold & Jin, Phys. Rev. E 73, 026610 (2006), Eq. (3) plot it:

        V_s = c0 (1/(f_r^(2/3) - 1)) [ (4/15) (3 + 2 f_r^(5/3) - 5 f_r^(2/3)) ]^(1/2).

    Derivation (Nesterenko, Dynamics of Heterogeneous Materials, 2001, sec. 1.3): the
    long-wave equation of the Hertz chain, u_tt = -c^2 d/dx [xi^(3/2) + (a^2/10) xi^(1/4)
    (xi^(5/4))_xx] with strain xi = -u_x, a = 2R and c^2 = K a^(5/2)/m, for a travelling
    wave xi(x - V t) between xi0 (static) and xi_m gives, integrated twice,
    V^2 = c^2 [(4/5)(xi_m^(5/2) - xi0^(5/2)) - 2 xi0^(3/2) (xi_m - xi0)] / (xi_m - xi0)^2;
    with c0^2 = (3/2) c^2 xi0^(1/2) and xi_m/xi0 = f_r^(2/3) (Hertz: F ~ delta^(3/2)) this is
    the formula above (tests/test_field_studies.py checks it against the quadrature of
    that travelling wave). It tends to 1 as f_r -> 1 (a weak wave runs at c0; exactly 1 at
    f_r = 1) and to sqrt(8/15) f_r^(1/6) for f_r >> 1 (Nesterenko's uncompressed wave);
    NaN below 1."""
    out = _ratio_of_strain(np.asarray(f_r, dtype=float) ** (2.0 / 3.0))
    return float(out) if out.ndim == 0 else out


def precompressed_amplitude(material: Material, radius: float, force, v_m):
    """f_r = F_m/F0 of the solitary wave whose peak particle velocity is v_m (m/s) in a chain
    under static force F0 (N). In a wave travelling at V, particle velocity is V times the
    dynamic strain, v = V (xi - xi0); at the peak, with V = c0 (V_s/c0)(x) of
    :func:`precompressed_speed_ratio`, v_m = c0 xi0 d (V_s/c0)(1 + d), d = x - 1,
    x = xi_m/xi0 = f_r^(2/3), xi0 = (F0/K)^(2/3)/(2R): increasing in d, solved by
    bisection in log d (numpy only; relative error < 1e-12 in v_m, < 2e-8 near d = 1e-4).
    NaN where F0 <= 0 or v_m <= 0."""
    F0 = np.asarray(force, dtype=float)
    vm = np.asarray(v_m, dtype=float)
    F0, vm = np.broadcast_arrays(F0, vm)
    K, _ = bead_constants(material, radius)
    with np.errstate(invalid="ignore", divide="ignore"):
        xi0 = (F0 / K) ** (2.0 / 3.0) / (2.0 * radius)
        target = vm / (np.asarray(precompressed_sound_speed(material, radius, F0)) * xi0)
    lo = np.full(vm.shape, -60.0)                      # log d
    hi = np.full(vm.shape, 60.0)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        d = np.exp(mid)
        up = d * _ratio_of_strain(1.0 + d) < target
        lo = np.where(up, mid, lo)
        hi = np.where(up, hi, mid)
    x = 1.0 + np.exp(0.5 * (lo + hi))
    f = x ** 1.5
    f = np.where((F0 > 0) & (vm > 0) & np.isfinite(target), f, np.nan)
    return float(f) if f.ndim == 0 else f


def precompressed_solitary_speed(material: Material, radius: float, force, v_m):
    """Nesterenko's solitary-wave speed V_s (m/s) in a chain of identical beads under static
    force F0 (N), for the wave of peak particle velocity v_m (m/s):
    c0 * precompressed_speed_ratio(f_r) with f_r from :func:`precompressed_amplitude`
    (Daraio et al., Phys. Rev. E 73, 026610 (2006), Eq. (3)). For F0 = 0, the
    uncompressed wave :func:`nesterenko_speed` (its f_r -> infinity limit)."""
    F0 = np.asarray(force, dtype=float)
    vm = np.asarray(v_m, dtype=float)
    F0, vm = np.broadcast_arrays(F0, vm)
    c0 = np.asarray(precompressed_sound_speed(material, radius, F0))
    loaded = c0 * np.asarray(precompressed_speed_ratio(
        precompressed_amplitude(material, radius, F0, vm)))
    free = np.asarray(nesterenko_speed(material, vm))
    out = np.where(F0 > 0, loaded, free)
    return float(out) if out.ndim == 0 else out
