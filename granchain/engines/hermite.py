"""Interpolation inside an integration step, for the event method (``engines.events``):
the quintic Hermite of a displacement (its value, velocity and acceleration at both step
ends) and the quartic velocity it gives (coefficients ``c`` of v(tau), tau in [0, 1]),
its maximum, bound and level crossings; the cubic Hermite of any other value and its
first crossing of a level (contact onsets and releases, the effects' own switches,
``locate``); the dense state inside a step."""
from __future__ import annotations

from numba import njit

from .backend import use_jit_cache

use_jit_cache()   # before the first @njit(cache=True)

from .codes import L_DISP, L_VEL  # noqa: E402


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


@njit(cache=True, inline="always")
def poly_v(c, tau):
    return c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * c[4])))


@njit(cache=True, inline="always")
def poly_dv(c, tau):
    return c[1] + tau * (2.0 * c[2] + tau * (3.0 * c[3] + tau * 4.0 * c[4]))


@njit(cache=True, inline="always")
def quintic(x0, v0, a0, x1, v1, a1, h):
    """(V0, A0, c3, c4, c5): the quintic Hermite interpolant of x over a step h (values,
    first and second derivatives at both ends) is x0 + tau (V0 + tau (A0/2 + tau (c3 +
    tau (c4 + tau c5)))), tau in [0, 1]."""
    V0 = h * v0
    A0 = h * h * a0
    R0 = (x1 - x0) - V0 - 0.5 * A0
    R1 = h * v1 - V0 - A0
    R2 = h * h * a1 - A0
    c3 = 10.0 * R0 - 4.0 * R1 + 0.5 * R2
    c4 = -15.0 * R0 + 7.0 * R1 - R2
    c5 = 6.0 * R0 - 3.0 * R1 + 0.5 * R2
    return V0, A0, c3, c4, c5


@njit(cache=True)
def vcoef(x0, v0, a0, x1, v1, a1, h, c):
    """Coefficients of v(tau), tau in [0, 1], the derivative of the quintic Hermite
    interpolant of x (values, first and second derivatives at both ends)."""
    V0, A0, c3, c4, c5 = quintic(x0, v0, a0, x1, v1, a1, h)
    c[0] = v0
    c[1] = A0 / h
    c[2] = 3.0 * c3 / h
    c[3] = 4.0 * c4 / h
    c[4] = 5.0 * c5 / h


@njit(cache=True)
def x_interp(x0, v0, a0, x1, v1, a1, h, tau):
    """(x, v) of the quintic Hermite interpolant at tau."""
    V0, A0, c3, c4, c5 = quintic(x0, v0, a0, x1, v1, a1, h)
    x = x0 + tau * (V0 + tau * (0.5 * A0 + tau * (c3 + tau * (c4 + tau * c5))))
    v = (V0 + tau * (A0 + tau * (3.0 * c3 + tau * (4.0 * c4 + tau * 5.0 * c5)))) / h
    return x, v


@njit(cache=True, inline="always")
def v_bound(c):
    """An upper bound of v(tau) on [0, 1] (each term c_k tau^k at most max(0, c_k)), above
    any value ``poly_v`` computes there: its margin, 1e-12 of the coefficients' magnitude,
    is far above their rounding errors (a few 1e-16)."""
    ub = c[0]
    mag = abs(c[0])
    for k in range(1, 5):
        ub += max(0.0, c[k])
        mag += abs(c[k])
    return ub + 1e-12 * mag


@njit(cache=True)
def turn(c, lo, hi):
    """Root of dv/dtau on [lo, hi], where it changes sign (bisection)."""
    glo = poly_dv(c, lo)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        gm = poly_dv(c, mid)
        if (gm > 0.0) == (glo > 0.0):
            lo, glo = mid, gm
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True)
def _bisect(c, level, sgn, a, b):
    """The crossing of ``level`` by v between a, where sgn (v - level) < 0, and b, where it
    is >= 0 (60 halvings)."""
    for _ in range(60):
        mid = 0.5 * (a + b)
        if sgn * (poly_v(c, mid) - level) >= 0.0:
            b = mid
        else:
            a = mid
    return 0.5 * (a + b)


@njit(cache=True)
def first_cross(c, level, lo, up):
    """First tau in [lo, 1] where v crosses ``level`` (upwards if up, else downwards);
    -1 if none is found on a 32-point scan."""
    M = 32
    sgn = 1.0 if up else -1.0
    a = lo
    fa = sgn * (poly_v(c, a) - level)
    if fa >= 0.0:
        return a
    for k in range(1, M + 1):
        b = lo + (1.0 - lo) * k / M
        fb = sgn * (poly_v(c, b) - level)
        if fb >= 0.0:
            return _bisect(c, level, sgn, a, b)
        a = b
    return -1.0


@njit(cache=True)
def last_cross_up(c, level):
    """The last tau in [0, 1] where v crosses ``level`` upwards, v(1) at or above it; -1
    if v is at or above it on the whole 32-point scan."""
    M = 32
    b = 1.0
    for k in range(M - 1, -1, -1):
        a = k / M
        if poly_v(c, a) < level:
            return _bisect(c, level, 1.0, a, b)
        b = a
    return -1.0


@njit(cache=True)
def dense(yp, kp, y1, k1, h, tau, LO, n, out):
    """State at t0 + tau h inside the step yp -> y1 (derivatives kp, k1)."""
    ny = yp.shape[0]
    ox = LO[L_DISP]
    ov = LO[L_VEL]
    for j in range(ny):
        out[j] = hermite3(yp[j], kp[j], y1[j], k1[j], h, tau)
    for i in range(n):
        x, v = x_interp(yp[ox + i], yp[ov + i], kp[ov + i], y1[ox + i], y1[ov + i],
                         k1[ov + i], h, tau)
        out[ox + i] = x
        out[ov + i] = v
