"""The reference engine's numbering, shared by the numba kernels and their Python callers.

numba-free (numpy only), so that an engine running the ahead-of-time kernels
(``engines.backend``) never imports numba: indices of the parameter vector P, the flags FL,
the layout offsets LO, the per-chain rows G and the energy columns, numbered from what the
chain and each effect declare (``EffectSpec``: params, flags, rows, state, work_slot) in
registry order; the method codes and the statuses; the Runge-Kutta tableaux (DOP853 from
scipy's own coefficient file, Dormand-Prince 5(4)); the event method's record-step buffer.

The generated names (``P_HERTZ_K``, ``F_GROOVE_FRICTION``, ``G_MASS``, ``L_GROOVE_HIST``,
``E_WORK_GROOVE``, ...) are module constants, so numba freezes them into the kernels like any
other. Their prefix names the array they index: P parameters, F flags, G per-chain rows,
L layout offsets (state blocks and accumulated works), E energy columns.
"""
from __future__ import annotations

import numpy as np

from ..effects import ENERGY_COLUMNS, MODULES, chain as _chain


def _number(names) -> dict[str, int]:
    """Consecutive indices of names in order of first appearance."""
    out: dict[str, int] = {}
    for name in names:
        out.setdefault(name, len(out))
    return out


_SPECS = (_chain.SPEC,) + tuple(m.SPEC for m in MODULES)
# parameter vector P (scalars of a run) and flags FL
P_SLOTS = _number(p for s in _SPECS for p in s.params)
F_SLOTS = _number(f for s in _SPECS for f in s.flags)
# rows of a chain's per-chain array G (B, G_LEN * n), each block n rows long: row
# G_X * n + i is entry i of block G_X. Per contact (G_GAP, G_HERTZ_K, G_PARTICLE_SPRING,
# G_ROLLING_REFF, G_DAMPING_MEFF, G_DAMPING_RSTAR): contacts 0 .. n-2 (spheres k, k+1), then
# the end wall at n-1. Per sphere: the rest.
# G_GAP: kernel gaps (overlap_k = x_k - x_{k+1} - G_GAP_k; the wall's x_n - G_GAP_{n-1})
G_SLOTS = _number(r for s in _SPECS for r in s.rows)
# layout offsets LO (-1: absent): the state blocks (displacements and velocities, then
# each effect's), then one accumulated-work entry per effect that does work, then
# L_STATE_SIZE (the state's length)
L_SLOTS = _number([b for s in _SPECS for b, _ in s.state]
                  + [s.work_slot for s in _SPECS if s.work_slot] + ["L_STATE_SIZE"])
# sample columns of the energy array, in ENERGY_COLUMNS order: kinetic translational,
# kinetic rotational, Hertz potential, then the works (each effect's, then the dead load's)
E_SLOTS = {"E_KIN_TRANS": 0, "E_KIN_ROT": 1, "E_HERTZ": 2,
           **{s.work_code: ENERGY_COLUMNS.index(s.work) for s in _SPECS if s.work_code},
           "E_WORK_LOAD": ENERGY_COLUMNS.index(_chain.SPEC.work)}
globals().update({**P_SLOTS, **F_SLOTS, **G_SLOTS, **L_SLOTS, **E_SLOTS})
P_LEN, F_LEN, G_LEN, L_LEN, E_LEN = (len(P_SLOTS), len(F_SLOTS), len(G_SLOTS), len(L_SLOTS),
                                     len(ENERGY_COLUMNS))
# (layout slot, energy column) of every accumulated work, in registry order
WORK_SLOTS = tuple((L_SLOTS[s.work_slot], E_SLOTS[s.work_code]) for s in _SPECS if s.work_slot)

# methods
M_RK4, M_VERLET, M_DOP853 = 0, 1, 2
# status
S_RUNNING, S_DONE, S_PASSED, S_TIMEOUT, S_NONFINITE, S_STEPFAIL = 0, 1, 2, 3, 4, 5



def _dop853_tableau():
    """scipy's Dormand-Prince 8(5,3) coefficients, loaded from their own file: importing
    them through ``scipy.integrate`` would also load its quadrature and ODE packages
    (0.35 s a process, for a table of numbers). Falls back to the normal import if
    scipy's layout differs."""
    import importlib.util
    import os
    spec = importlib.util.find_spec("scipy")
    path = os.path.join(os.path.dirname(spec.origin or ""), "integrate", "_ivp",
                        "dop853_coefficients.py")
    if os.path.isfile(path):
        mod_spec = importlib.util.spec_from_file_location("granchain_dop853_coefficients", path)
        mod = importlib.util.module_from_spec(mod_spec)
        mod_spec.loader.exec_module(mod)
        return mod
    from scipy.integrate._ivp import dop853_coefficients
    return dop853_coefficients


_dc = _dop853_tableau()
NST = _dc.N_STAGES
DOP_A = np.ascontiguousarray(_dc.A[:NST, :NST])
DOP_B = np.ascontiguousarray(_dc.B)
DOP_C = np.ascontiguousarray(_dc.C[:NST])
DOP_E3 = np.ascontiguousarray(_dc.E3)
DOP_E5 = np.ascontiguousarray(_dc.E5)


# Dormand-Prince 5(4) (as in scipy's RK45), FSAL: 6 force evaluations per step
_DP5_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])
_DP5_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 5, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3 / 40, 9 / 40, 0.0, 0.0, 0.0, 0.0],
    [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0, 0.0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0, 0.0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0.0]])
_DP5_B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
_DP5_E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])

# pairs: code -> (A, B, C, E5, E3, error exponent, DOP853-style error norm)
PAIRS = {
    "dop853": (DOP_A, DOP_B, DOP_C, DOP_E5, DOP_E3, 1.0 / 8.0, 1),
    "dp54": (_DP5_A, _DP5_B, _DP5_C, _DP5_E, np.zeros(_DP5_E.shape[0]), 1.0 / 5.0, 0),
}
DEFAULT_PAIR = "dop853"

RB_SIZE = 48               # record steps kept per particle
# record-step buffer columns: t0, h, max over the step, then 5 coefficients of v(tau)
RB_T0, RB_H, RB_MAX, RB_C = 0, 1, 2, 3
RB_LEN = 8
