"""The reference engine's numbering, shared by the numba kernels and their Python callers.

numba-free (numpy only), so that an engine running the ahead-of-time kernels
(``engines.backend``) never imports numba: the indices of the parameter vector P, the flags
FL, the layout offsets LO, the per-chain rows G and the energy columns that
``granchain.effects.slots`` numbers from what the chain and each effect declare (module
constants here too, so numba freezes them into the kernels like any other); the method
codes and the statuses; the Runge-Kutta tableaux (DOP853 from scipy's own coefficient file,
Dormand-Prince 5(4)); the event method's record-step buffer.
"""
from __future__ import annotations

import numpy as np

from ..effects import slots as _slots

P_SLOTS, F_SLOTS, G_SLOTS, L_SLOTS, E_SLOTS = (_slots.P_SLOTS, _slots.F_SLOTS, _slots.G_SLOTS,
                                              _slots.L_SLOTS, _slots.E_SLOTS)
NAMES = _slots.NAMES          # every numbered slot, by name
globals().update(NAMES)
P_LEN, F_LEN, G_LEN, L_LEN, E_LEN = (_slots.P_LEN, _slots.F_LEN, _slots.G_LEN, _slots.L_LEN,
                                     _slots.E_LEN)
# (layout slot, energy column) of every accumulated work, in registry order
WORK_SLOTS = _slots.WORK_SLOTS
# the effects' state blocks integrated as velocities (``EffectSpec.kicked``)
KICKED = _slots.KICKED
# the mechanical energy columns (kinetic translational and rotational, potential); the
# work columns follow them
E_MECHANICAL = 3

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
# DOP853's 7th-order dense output: three more stages after f(ynew) (rows NST + 1 ... of
# the extended tableau) and the interpolant's coefficients over all NST_DENSE stages
NST_DENSE = _dc.N_STAGES_EXTENDED
DOP_A_DENSE = np.ascontiguousarray(_dc.A[NST + 1:NST_DENSE, :NST_DENSE])
DOP_D = np.ascontiguousarray(_dc.D)
DENSE_POWER = _dc.INTERPOLATOR_POWER


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
