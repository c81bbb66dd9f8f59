"""Independent references for the tests: written here from the physics notes with scipy,
sharing no code (and no constants) with granchain's engines, effects or materials.

``hertz_chain_peaks`` integrates the chapter's chain with the Hertz contacts only:
f = (4/3) E* sqrt(R*) delta^(3/2) for delta > 0, E* = E / (2 (1 - nu^2)), R* = R/2 (equal
spheres), delta_i = 2R + g_i - (z_{i+1} - z_i); particle 1, the striker, starts at v_s, the
others at rest, touching or separated by gaps g_i. It uses
``scipy.integrate.solve_ivp(method="DOP853", rtol=1e-12)`` with dense output and returns
each probe's peak velocity, the time of that peak and the time the velocity first reaches
half of it (the arrival, or front), plus the solution itself. Its own error on the packed
15-sphere chain's v_max,2 (against rtol 1e-13): 1.4e-12 at rtol 1e-12, 4.8e-10 at 1e-10.

The equations are written in scaled units: length delta0 = (m v_s^2 / k)^(2/5), velocity
v_s, time t0 = delta0 / v_s, with k = (4/3) E* sqrt(R*). In them m u_i'' = k delta^(3/2)
becomes u_i'' = delta^(3/2): every number is of order one, so the tolerances mean what
they say, and a packed chain's v_max / v_s is the same for any material, radius and v_s.

A peak is where the probe's acceleration falls through zero while it touches a
neighbour, or where its last contact opens (a sphere that then flies freely across a
gap: the peak is a plateau, and its time is the moment the contact opened). Both are
found by solve_ivp's event root finding; a velocity still rising at ``t_end`` counts too.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

RTOL = 1e-12

# Handbook values of the physics notes' materials table: (E [Pa], nu, rho [kg/m^3]).
SS440C = (200e9, 0.28, 7800.0)
SS316 = (193e9, 0.30, 8000.0)


def hertz_scales(E: float, nu: float, rho: float, R: float, v_s: float):
    """(delta0 [m], t0 [s]) of the scaled equations."""
    m = rho * 4.0 / 3.0 * math.pi * R ** 3
    k = 4.0 / 3.0 * (E / (2.0 * (1.0 - nu ** 2))) * math.sqrt(R / 2.0)
    delta0 = (m * v_s ** 2 / k) ** 0.4
    return delta0, delta0 / v_s


@dataclass(frozen=True)
class ChainPeaks:
    """Result of :func:`hertz_chain_peaks`, in SI units. Per probe (same order as
    ``probes``): ``v_max`` [m/s], ``t_peak`` [s], ``t_front`` [s] (first time the velocity
    reaches v_max / 2). ``sol`` is solve_ivp's result in scaled units (state: the n
    displacements, then the n velocities); ``velocity`` and ``crossing`` read it in SI."""
    probes: tuple
    n: int
    v_s: float
    delta0: float
    t0: float
    v_max: np.ndarray
    t_peak: np.ndarray
    t_front: np.ndarray
    sol: object

    def velocity(self, particle: int, t) -> np.ndarray:
        """Velocity [m/s] of ``particle`` (1-based) at times ``t`` [s]."""
        return self.sol.sol(np.asarray(t, dtype=float) / self.t0)[self.n + particle - 1] * self.v_s

    def crossing(self, particle: int, level: float) -> float:
        """First time [s] the velocity of ``particle`` (1-based) reaches ``level`` [m/s],
        located on the dense interpolant to round-off."""
        lv = level / self.v_s
        v = self.sol.y[self.n + particle - 1]
        j = int(np.argmax(v >= lv))
        if v[j] < lv:
            return math.nan
        if j == 0:
            return float(self.sol.t[0] * self.t0)
        f = lambda s: self.sol.sol(s)[self.n + particle - 1] - lv   # noqa: E731
        s = brentq(f, self.sol.t[j - 1], self.sol.t[j], xtol=1e-15, rtol=1e-15)
        return float(s * self.t0)


def hertz_chain_peaks(E: float, nu: float, rho: float, R: float, n: int, v_s: float,
                      gaps=None, probes=(2, 13), t_end: float | None = None,
                      rtol: float = RTOL) -> ChainPeaks:
    """Peaks of the probes (1-based particle numbers, particle 1 the striker) from t = 0
    (the striker at v_s touching particle 2, or ``gaps[0]`` away from it) to ``t_end``
    (default: three times the time Nesterenko's solitary wave needs to cross the chain,
    plus the time the striker's speed needs to close all gaps).

    ``gaps``: n - 1 gaps [m] between particles i and i+1 (default: touching).
    ``rtol``: solve_ivp's relative tolerance (absolute: 1e-4 rtol, in scaled units).
    Solves are cached: tests that ask for the same chain share one solve.
    """
    key = None if gaps is None else tuple(float(x) for x in gaps)
    return _solve(float(E), float(nu), float(rho), float(R), int(n), float(v_s), key,
                  tuple(int(p) for p in probes), None if t_end is None else float(t_end),
                  float(rtol))


@functools.lru_cache(maxsize=32)
def _solve(E, nu, rho, R, n, v_s, gaps, probes, t_end, rtol):
    if n < 2 or any(not 1 <= p <= n for p in probes):
        raise ValueError(f"probes {probes} must lie in 1..{n}")
    delta0, t0 = hertz_scales(E, nu, rho, R, v_s)
    g = np.zeros(n - 1) if gaps is None else np.asarray(gaps, dtype=float) / delta0
    if g.shape != (n - 1,) or (g < 0).any():
        raise ValueError("gaps must be n - 1 values >= 0")
    if t_end is None:
        c = math.sqrt(2.0 * E / (math.pi * rho * (1.0 - nu ** 2)))
        V = (16.0 / 25.0) ** 0.2 * c ** 0.8 * (0.7 * v_s) ** 0.2   # peak ~0.7 v_s
        t_end = 3.0 * n * 2.0 * R / V + float(g.sum()) * delta0 / v_s
    T = t_end / t0

    def overlaps(u):
        return u[:-1] - u[1:] - g                  # overlap of contact i, i+1 (scaled)

    def accel(u):
        d = np.maximum(overlaps(u), 0.0)
        f = d * np.sqrt(d)                          # Hertz: delta^(3/2), 0 when open
        a = np.empty(n)
        a[0] = -f[0]
        a[1:-1] = f[:-1] - f[1:]
        a[-1] = f[-1]
        return a

    def rhs(_t, y):
        return np.concatenate([y[n:], accel(y[:n])])

    memo = {"t": None, "y": None, "g": None}

    def peak_values(t, y):
        """Per particle: its acceleration while it touches a neighbour, else -1 (its
        contact just opened); computed once per state for all the probes' events."""
        if memo["t"] != t or memo["y"] is not y:    # the probes' events share one state
            d = overlaps(y[:n])
            on = d > 0.0
            touching = np.zeros(n, dtype=bool)
            touching[:-1] |= on
            touching[1:] |= on
            memo.update(t=t, y=y, g=np.where(touching, accel(y[:n]), -1.0))
        return memo["g"]

    def peak_event(i):
        def ev(t, y):
            return peak_values(t, y)[i]
        ev.direction = -1.0
        return ev

    y0 = np.zeros(2 * n)
    y0[n] = 1.0
    sol = solve_ivp(rhs, (0.0, T), y0, method="DOP853", rtol=rtol, atol=1e-4 * rtol,
                    dense_output=True, events=[peak_event(p - 1) for p in probes])
    if sol.status != 0:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    vmax, tpk = [], []
    for k, p in enumerate(probes):
        cands = [(y[n + p - 1], t) for t, y in zip(sol.t_events[k], sol.y_events[k])]
        if y0[n + p - 1] > 0.0:                         # the striker: fastest at t = 0
            cands.append((y0[n + p - 1], 0.0))
        if accel(sol.y[:n, -1])[p - 1] > 0.0:
            cands.append((sol.y[n + p - 1, -1], sol.t[-1]))
        if not cands:
            raise RuntimeError(f"particle {p} never peaked before t_end = {t_end:g} s")
        v, t = max(cands, key=lambda c: (c[0], -c[1]))   # the highest, the first of ties
        vmax.append(v * v_s)
        tpk.append(t * t0)
    res = ChainPeaks(probes=probes, n=n, v_s=v_s, delta0=delta0, t0=t0,
                     v_max=np.array(vmax), t_peak=np.array(tpk),
                     t_front=np.full(len(probes), math.nan), sol=sol)
    for k, p in enumerate(probes):
        res.t_front[k] = res.crossing(p, 0.5 * vmax[k])
    return res
