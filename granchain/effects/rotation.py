"""rotation: adds the spins omega to the state, with I = (2/5) m R^2.

Nothing else: the torques come from the friction effects.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import slots as S
from .spec import EffectSpec, compiled

SPEC = EffectSpec("rotation", state=(("L_SPIN", "particle"),), kicked=("L_SPIN",),
                  lammps_ledger="c_erot_atom", params=("P_INERTIA",), flags=("F_ROTATION",))


@compiled
def energies(y, G, P, FL, LO, out):
    """out[E_KIN_ROT]: the rotational kinetic energy (1/2) I_i omega_i^2 of the spheres
    (one inertia: (1/2) I sum omega_i^2)."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ow = LO[S.L_SPIN]
    oI = S.G_INERTIA * n
    if FL[S.F_HETEROGENEOUS] != 0:
        for i in range(n):
            for l in range(L):
                out[S.E_KIN_ROT, l] += 0.5 * G[oI + i, l] * y[ow + i, l] * y[ow + i, l]
    else:
        for i in range(n):
            for l in range(L):
                out[S.E_KIN_ROT, l] += y[ow + i, l] * y[ow + i, l]
        for l in range(L):
            out[S.E_KIN_ROT, l] *= 0.5 * G[oI, l]


@dataclass(frozen=True)
class Rotation:
    inertia: float    # kg m^2


def build(scene) -> Rotation:
    return Rotation(scene.inertia)


def kernel(rot: Rotation) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return {"P_INERTIA": rot.inertia}, {"F_ROTATION": 1}


def error_scale(rot: Rotation, terms, delta: float, v: float) -> float:
    """Absolute error scale of the spins for the adaptive method (rad/s)."""
    return v / terms.R


def lammps_integrator(rot: Rotation | None) -> str:
    """The deck's time integrator: translation and rotation, or translation only."""
    if rot is not None:
        return ("# rotation on: translation and rotation about y (I = 0.4 m R^2)\n"
                "fix             nve all nve/sphere")
    return ("# rotation off: fix nve integrates translation only, omega stays exactly 0\n"
            "fix             nve all nve")
