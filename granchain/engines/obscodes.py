"""Slots of the fixed-step kernels' on-the-fly observables (``kernels.run_blocks`` with
observe), numba-free, shared with the engine's Python side (``engines.reference``).

Per particle, float slots of OF: the running maximum of its velocity (the argmax is its
first sample), the samples just before and just after it, and the last PLATEAU_SAMPLES
samples (from O_H on). Int slots of OI: the argmax sample; the near-maximum samples
(within PEAK_TOL of the maximum) contiguous before it and after it, each counted up to
PLATEAU_SAMPLES; whether that run after it is still open; whether the velocity fell below
PASS_FRACTION of the maximum after it; a NaN sampled; the ring of record samples (head,
count); whether that ring overflowed. Results per particle (OUT): v_max, t_peak, t_front,
the maximum sample (NaN once a NaN was sampled), plateau (1.0 / 0.0). The end wall's
dynamic force: WF float slots (maximum, the samples before and after it, the previous
sample), WI int slots (argmax, passed, NaN sampled), WOUT (F_max, t_peak, final 1.0 / 0.0).
Energy balance (BAL): the total mechanical energy of sample 0, the largest |balance| so far.
"""
from __future__ import annotations

from ..schedule import PLATEAU_SAMPLES

O_M, O_Y0, O_Y2, O_H = 0, 1, 2, 3
OBS_F = O_H + PLATEAU_SAMPLES
I_J, I_BWD, I_FWD, I_FOPEN, I_PASS, I_NAN, I_RHEAD, I_RCOUNT, I_OVF = range(9)
OBS_I = 9
R_VMAX, R_TPK, R_TFR, R_TOP, R_PLAT = range(5)
OBS_R = 5
W_M, W_Y0, W_Y2, W_PREV = range(4)
WI_J, WI_PASS, WI_NAN = range(3)
OBS_WF, OBS_WI, OBS_WOUT = 4, 3, 3
B_E0, B_MAX = 0, 1
