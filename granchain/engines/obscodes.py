"""Slots of the fixed-step kernels' on-the-fly observables (``kernels.run_blocks`` with
observe), numba-free, shared with the engine's Python side (``engines.reference``).

Per particle, float slots of OF: the running maximum of its velocity (OF_MAX; the argmax
is its first sample), the samples just before and just after it (OF_BEFORE, OF_AFTER), and
the last PLATEAU_SAMPLES samples (a ring from OF_RECENT on). Int slots of OI: the argmax
sample (OI_ARGMAX); the near-maximum samples (within PEAK_TOL of the maximum) contiguous
before it and after it, each counted up to PLATEAU_SAMPLES (OI_NEAR_BEFORE, OI_NEAR_AFTER);
whether that run after it is still open (OI_AFTER_OPEN); whether the velocity fell below
PASS_FRACTION of the maximum after it (OI_PASSED); a NaN sampled (OI_NAN); the ring of
record samples (OI_RING_HEAD, OI_RING_COUNT); whether that ring overflowed
(OI_RING_OVERFLOW). Results per particle (OUT): v_max, t_peak, t_front, the maximum sample
(NaN once a NaN was sampled), plateau (1.0 / 0.0). The end wall's dynamic force: WF float
slots (maximum, the samples before and after it, the previous sample), WI int slots (argmax,
passed, NaN sampled), WOUT (F_max, t_peak, final 1.0 / 0.0). Energy balance (BAL): the total
mechanical energy of sample 0 (BAL_E0), the largest |balance| so far (BAL_MAX).
"""
from __future__ import annotations

from ..stoprule import PLATEAU_SAMPLES

OF_MAX, OF_BEFORE, OF_AFTER, OF_RECENT = 0, 1, 2, 3
OBS_F = OF_RECENT + PLATEAU_SAMPLES
(OI_ARGMAX, OI_NEAR_BEFORE, OI_NEAR_AFTER, OI_AFTER_OPEN, OI_PASSED, OI_NAN, OI_RING_HEAD,
 OI_RING_COUNT, OI_RING_OVERFLOW) = range(9)
OBS_I = 9
OUT_VMAX, OUT_T_PEAK, OUT_T_FRONT, OUT_MAX_SAMPLE, OUT_PLATEAU = range(5)
OBS_R = 5
WF_MAX, WF_BEFORE, WF_AFTER, WF_PREV = range(4)
WI_ARGMAX, WI_PASSED, WI_NAN = range(3)
OBS_WF, OBS_WI, OBS_WOUT = 4, 3, 3
BAL_E0, BAL_MAX = 0, 1
