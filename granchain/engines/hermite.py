"""Cubic Hermite interpolation inside a step, and its first crossing of a level: the event
method's location of contact onsets and releases, and of the effects' own switches
(``locate``)."""
from __future__ import annotations

from numba import njit

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True)


@njit(cache=True, inline="always")
def hermite3(d0, w0, d1, w1, h, tau):
    """Cubic Hermite of a value with its time derivatives at both ends of a step h."""
    t2 = tau * tau
    t3 = t2 * tau
    return ((2 * t3 - 3 * t2 + 1) * d0 + (t3 - 2 * t2 + tau) * h * w0
            + (-2 * t3 + 3 * t2) * d1 + (t3 - t2) * h * w1)


@njit(cache=True)
def hermite_root(d0, w0, d1, w1, h, level, up):
    """First tau in (0, 1] where the cubic Hermite of d crosses level (up: from below)."""
    M = 32
    sgn = 1.0 if up else -1.0
    a = 0.0
    for k in range(1, M + 1):
        b = k / M
        if sgn * (hermite3(d0, w0, d1, w1, h, b) - level) >= 0.0:
            for _ in range(60):
                mid = 0.5 * (a + b)
                if sgn * (hermite3(d0, w0, d1, w1, h, mid) - level) >= 0.0:
                    b = mid
                else:
                    a = mid
            return 0.5 * (a + b)
        a = b
    return -1.0
