"""LAMMPS 'units micro' for granchain's decks: SI values converted exactly.

micro: mass pg, length um, time us, velocity um/us = m/s, force 1e-9 N, energy 1e-15 J
(docs/explanation/lammps_laws.md section 1).
"""
from __future__ import annotations

from decimal import Decimal

# SI value * 10**e = value in LAMMPS 'units micro' (docs/explanation/lammps_laws.md section 1).
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
    # 1/(m s) -> 1/(um us): pair granular's viscoelastic eta_n0, whose damping force
    # eta_n0 m_eff a v (a the contact radius) is a force: 1/(m s) kg m m/s = N
    "inverse_length_time": -12,
}


def to_micro(value: float, quantity: str) -> float:
    """Convert an SI value to micro units by shifting the decimal exponent of its repr.

    The shift is exact in decimal and rounded once, so 150e-6 m -> 150.0 um and
    1e-9 s -> 0.001 us (multiplying by 1e6 in binary may be off by one ulp).
    """
    e = MICRO_EXPONENT[quantity]
    return float(Decimal(repr(float(value))).scaleb(e))


def lmp_float(x: float) -> str:
    """A float with repr precision (shortest string that round-trips)."""
    return repr(float(x))
