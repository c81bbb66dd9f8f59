"""Independent references for the tests: written here from the equations with scipy,
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
found by root finding on the dense output after the integration (solve_ivp's rule with a
larger iteration cap, :func:`_locate`); a velocity still rising at ``t_end`` counts too.

``hertz_chain_general`` (below) solves the chains of the notes' "Beyond the chapter"
section the same way: spheres of their own radius and material (1/E* summed over the
pair, R* = R_i R_j / (R_i + R_j)), gaps, an end wall (R* = R_n; rigid or of its own E, nu)
and a dead load F0 on particle 2 with the chain starting from its static overlaps. Its
state is the displacements from that static state, its forces increments over the
static ones (no cancellation), and it restarts the integration at every contact that
closes or opens. It returns every particle's peak, the wall force's peak and its time,
and the energy and momentum along the solution. Its own errors, from
tests/test_field_chains.py (rtol 1e-12): energy 3e-12 of the striker's (free gapped
chain) and <= 7e-13 (walled and loaded), momentum 2e-15; one sphere on a wall and two
spheres against the closed forms: peak force 1.2e-12, contact time 2e-13, final
velocities 1.7e-12; the chapter chain: 1.7e-12 from ``hertz_chain_peaks``.

``hertz_chain_general(..., damping=...)`` adds the contact damping of LAMMPS pair granular
on hertz/material: F = F_el + eta w at
every contact and the end wall, coeff_restitution (e), tsuji (e) or viscoelastic
(eta_n0), optionally limit_damping; the work of the damping forces is integrated with
the motion. Undamped calls are unchanged (bit-identical results). Its own errors, from
tests/test_damped_chains.py: two-sphere e (coeff_restitution) within 1.9e-12 over
0.01-1 m/s, equal spheres and a tungsten carbide striker; a sphere on a wall rebounds
at -e v within 4e-13; weak viscoelastic loss against its first-order closed form
5.2e-8 (3.9e-7 unlike spheres); energy lost = work of the damping forces to <= 6.4e-12
of the striker's energy (1.1e-10 with limit_damping on a gapped chain, 2.2e-11 at rtol
1e-13).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from scipy.integrate import OdeSolution, quad, solve_ivp
from scipy.optimize import brentq

RTOL = 1e-12

# Handbook values of the materials: (E [Pa], nu, rho [kg/m^3]).
SS440C = (200e9, 0.28, 7800.0)
SS316 = (193e9, 0.30, 8000.0)


def _touch_or_overlap(d, n: int, a, loaded: bool = False) -> np.ndarray:
    """The peak events' function of n particles with contact overlaps d (contact i between
    particles i and i+1; a last entry n-1 is the end wall's) and accelerations a: a[i]
    while particle i touches (or, ``loaded``, particle 2 carries the load), else the
    largest overlap of its contacts (< 0). Both vanish where its last contact opens (the
    contact force is 0 at zero overlap, damped or not), so the function is continuous
    there: solve_ivp's root finding (brentq) failed to converge on the jump to a
    constant that stood here before, at an opening behind a particle still accelerating
    (a few gapped chains in a hundred)."""
    near = np.full(len(d) + 1, -np.inf)
    near[:-1] = d
    near[1:] = np.maximum(near[1:], d)
    near = near[:n]
    touching = near > 0.0
    if loaded:
        touching[1] = True
    return np.where(touching, a, near)


# solve_ivp locates an event by brentq with at most 100 iterations, which ends in "Failed
# to converge" where the event's function is flat on one side of its root: a particle
# leaving its last contact (its acceleration vanishes like delta^(3/2), its overlap
# linearly, and both dither in rounding within 1e-22 of the root) took 102 on a gapped
# 316 chain. The events are located after the integration instead (:func:`_locate`),
# over the same steps and by the same rule, with this cap.
EVENT_MAXITER = 1000


def _locate(events, sol, ts):
    """Per event (a function of (t, y), with solve_ivp's ``direction``): the times inside
    the steps ts of the dense output sol where it changes sign in its direction (solve_ivp's
    rule: a step whose ends' values have the sign change, a zero included), found by brentq
    as solve_ivp finds them but with EVENT_MAXITER iterations; and the states there. The
    functions are evaluated at each step end with one state array for all of them."""
    eps = np.finfo(float).eps
    Y = sol(ts)
    G = np.empty((len(ts), len(events)))
    for j in range(len(ts)):
        y = Y[:, j]
        for k, ev in enumerate(events):
            G[j, k] = ev(ts[j], y)
    t_events, y_events = [], []
    for k, ev in enumerate(events):
        g0, g1 = G[:-1, k], G[1:, k]
        d = getattr(ev, "direction", 0.0)
        up, down = (g0 <= 0.0) & (g1 >= 0.0), (g0 >= 0.0) & (g1 <= 0.0)
        hit = (up & (d > 0)) | (down & (d < 0)) | ((up | down) & (d == 0))
        roots = np.array([brentq(lambda t: ev(t, sol(t)), ts[j], ts[j + 1], xtol=4 * eps,
                                 rtol=4 * eps, maxiter=EVENT_MAXITER)
                          for j in np.flatnonzero(hit)])
        t_events.append(roots)
        y_events.append(sol(roots).T if len(roots) else np.zeros((0, Y.shape[0])))
    return t_events, y_events


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
        """Per particle: its acceleration while it touches a neighbour, else the largest
        overlap of its contacts (< 0): continuous where its last contact opens (the
        Hertz force and the overlap vanish together there), so an opening behind it
        (acceleration falling to 0 from above) is a root of the event like a peak
        inside a contact; computed once per state for all the probes' events."""
        if memo["t"] != t or memo["y"] is not y:    # the probes' events share one state
            d = overlaps(y[:n])
            memo.update(t=t, y=y, g=_touch_or_overlap(d, n, accel(y[:n])))
        return memo["g"]

    def peak_event(i):
        def ev(t, y):
            return peak_values(t, y)[i]
        ev.direction = -1.0
        return ev

    y0 = np.zeros(2 * n)
    y0[n] = 1.0
    sol = solve_ivp(rhs, (0.0, T), y0, method="DOP853", rtol=rtol, atol=1e-4 * rtol,
                    dense_output=True)
    if sol.status != 0:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    sol.t_events, sol.y_events = _locate([peak_event(p - 1) for p in probes], sol.sol, sol.t)
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



# ---------------------------------------------------------------------------------------
# The general chain: unequal spheres, mixed materials, an end wall, a dead load
# ---------------------------------------------------------------------------------------
# Written from the equations of the field chains (docs/explanation/physics.md) with scipy's DOP853, like
# the solver above, and sharing no code with granchain. Contact of spheres i and j:
#   f = k delta^(3/2) for delta > 0, else 0;   k = (4/3) E* sqrt(R*),
#   1/E* = (1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j,   R* = R_i R_j / (R_i + R_j);
# the last sphere on the end wall: R* = R_n and the wall's own E, nu (rigid: 1/E_w = 0).
# Dead load F0 on particle 2 toward the wall: in the static state every contact from
# particle 2 to the wall carries F0, delta_s = (F0 / k)^(2/3) with its own k, and the
# striker touches particle 2 at zero overlap.
#
# State: the displacements u_i from the static state (and the velocities). A contact's
# compression beyond its static overlap is x = u_i - u_{i+1} - g_i (x = u_n at the wall),
# its overlap delta = delta_s + x. Forces are written as increments over the static ones,
# and the load cancels against the static forces exactly: the net force on particle i is
# df_{i-1} - df_i with df = f(delta_s + x) - F0. For a loaded contact df is evaluated
# without cancellation, from s = sqrt(1 + x/delta_s) - 1 = r / (sqrt(1 + r) + 1), r = x/delta_s:
#   df = F0 (3 s + 3 s^2 + s^3)                        (delta > 0; -F0 when open),
# and its potential relative to the static state, (2/5) k (delta^(5/2) - delta_s^(5/2)) - F0 x,
#   phi = k delta_s^(5/2) (3 s^2 + 4 s^3 + 2 s^4 + (2/5) s^5)   (delta > 0).
# Summed over the contacts, the F0 x terms are F0 u_2, the dead load's potential. Written
# as f(delta_s + x) - f(delta_s) directly, the net forces on resting spheres carry the
# rounding noise of the static forces, which the step control (absolute tolerance) then
# follows: 40 440C spheres under 0.01 N took 94x more steps at v_s = 1e-4 m/s, and 1600x
# at 1e-5 m/s, than in this form (same peaks to 1e-12).
#
# Scaled units: reference mass m0 (particle 2's, or the striker's when it is alone),
# stiffness k0 (the contact of particles 1 and 2, or the wall's), length delta0 =
# (m0 v_s^2 / k0)^(2/5) (or (F0 / k0)^(2/3) for a striker at rest), time
# t0 = sqrt(m0 / (k0 delta0^(1/2))): velocity delta0 / t0 = v_s, force k0 delta0^(3/2).


def hertz_k(R1: float, E1: float, nu1: float, R2: float | None = None,
            E2: float | None = None, nu2: float | None = None) -> float:
    """k = (4/3) E* sqrt(R*) [N/m^1.5] of sphere 1 on sphere 2 (R2 None: on a flat wall,
    R* = R1; E2 None or inf: the other body rigid, (1 - nu2^2)/E2 = 0)."""
    inv_e = (1.0 - nu1 ** 2) / E1
    if E2 is not None and math.isfinite(E2):
        inv_e += (1.0 - nu2 ** 2) / E2
    r_star = R1 if R2 is None else R1 * R2 / (R1 + R2)
    return 4.0 / 3.0 * math.sqrt(r_star) / inv_e


def sphere_mass(R: float, rho: float) -> float:
    return rho * 4.0 / 3.0 * math.pi * R ** 3


@dataclass(frozen=True)
class _Contacts:
    """The contacts in scaled units: n - 1 between spheres, then the wall's (if any)."""
    n: int
    wall: bool
    kap: np.ndarray        # k / k0
    ds: np.ndarray         # static overlap / delta0 (0: not loaded)
    gs: np.ndarray         # gap / delta0
    fs: np.ndarray         # static force kap ds^(3/2)
    es: np.ndarray         # kap ds^(5/2)

    def _col(self, a, u):
        return a.reshape((-1,) + (1,) * (u.ndim - 1))

    def x(self, u):
        """Compression beyond the static overlap, per contact; u: (n, ...)."""
        ue = np.concatenate([u, np.zeros((1,) + u.shape[1:])]) if self.wall else u
        return ue[:-1] - ue[1:] - self._col(self.gs, u)

    def _s(self, x, u):
        ds = self._col(np.where(self.ds > 0.0, self.ds, 1.0), u)
        r = x / ds
        return r / (np.sqrt(np.maximum(1.0 + r, 0.0)) + 1.0)

    def df(self, u):
        """Contact force minus its static value, per contact; u: (n, ...)."""
        x = self.x(u)
        xp = np.maximum(x, 0.0)
        out = self._col(self.kap, u) * xp * np.sqrt(xp)
        loaded = self._col(self.ds > 0.0, u)
        if self.ds.any():
            s = self._s(x, u)
            fs = self._col(self.fs, u)
            inc = fs * s * (3.0 + s * (3.0 + s))
            closed = self._col(self.ds, u) + x > 0.0
            out = np.where(loaded, np.where(closed, inc, -fs), out)
        return out

    def phi(self, u):
        """Contact potential relative to the static state minus F0 x, per contact."""
        x = self.x(u)
        xp = np.maximum(x, 0.0)
        out = 0.4 * self._col(self.kap, u) * xp ** 2.5
        if self.ds.any():
            s = self._s(x, u)
            es, fs = self._col(self.es, u), self._col(self.fs, u)
            inc = es * s * s * (3.0 + s * (4.0 + s * (2.0 + 0.4 * s)))
            closed = self._col(self.ds, u) + x > 0.0
            out = np.where(self._col(self.ds > 0.0, u),
                           np.where(closed, inc, -0.4 * es - fs * x), out)
        return out

    def net(self, u):
        """Net force on each sphere (the load included), u: (n,)."""
        d = self.df(u)
        F = np.zeros(self.n + int(self.wall))
        F[:-1] -= d
        F[1:] += d
        return F[: self.n]

    def rate(self, v):
        """Overlap rate w = delta' of each contact (> 0 closing); v: the n velocities."""
        ve = np.append(v, 0.0) if self.wall else v
        return ve[:-1] - ve[1:]

    def net_of(self, f):
        """Net force on each sphere from the contact forces ``f`` (one per contact)."""
        F = np.zeros(self.n + int(self.wall))
        F[:-1] -= f
        F[1:] += f
        return F[: self.n]


@dataclass(frozen=True)
class GeneralChain:
    """Result of :func:`hertz_chain_general`, SI units unless named scaled.

    Per particle (index i: particle i + 1): ``v_max`` [m/s] (the striker's: v_s at t = 0;
    NaN for a sphere that never moved forward), ``t_peak`` [s], ``mass`` [kg]. Per contact
    between spheres: ``k`` [N/m^1.5], ``delta_static`` [m]; the wall's: ``k_wall``,
    ``delta_static_wall``. ``wall_force_max``: the largest wall force [N] over the run,
    static preload included (NaN without a wall); ``wall_force_static`` = F0;
    ``wall_force_dynamic``: ``wall_force_max`` - F0, computed as an increment (no
    cancellation); ``t_wall_peak`` [s]: its time, where the last sphere's velocity falls
    through zero in contact with the wall (``wall_peak_final`` False: the force was still
    rising at t_end, the values are those at t_end and the time is NaN); ``t_wall_open``:
    the times the wall contact opened. ``sol``: solve_ivp's result in scaled units (state:
    n displacements from the static state, then n velocities; damped: then the work W
    of the damping forces).

    Damped chains (``damping``: (model, e or eta_n0, limit_damping), None undamped): the
    wall force is the whole force F_el + eta w the wall exerts, and its peak is where
    dF/dt falls through zero in contact; ``wall_elastic_dynamic`` and
    ``t_wall_elastic_peak`` are the peak of its elastic part K_w delta^(3/2) alone (where
    the last sphere's velocity falls through zero), which undamped is the same peak.
    ``damp``: c(e) of the model (coeff_restitution, tsuji) or eta_n0 (viscoelastic).
    """
    n: int
    v_s: float
    preload: float
    has_wall: bool
    delta0: float
    t0: float
    force0: float
    mass: np.ndarray
    k: np.ndarray
    k_wall: float
    delta_static: np.ndarray
    delta_static_wall: float
    gaps: np.ndarray
    v_max: np.ndarray
    t_peak: np.ndarray
    wall_force_max: float
    wall_force_static: float
    wall_force_dynamic: float
    t_wall_peak: float
    wall_peak_final: bool
    t_wall_open: np.ndarray
    t_end: float
    sol: object
    contacts: _Contacts
    damping: tuple | None = None
    damp: float = 0.0
    wall_elastic_dynamic: float = math.nan
    t_wall_elastic_peak: float = math.nan
    forces: object = None   # damped: scaled state -> (F - F_static, F - F_el, w, unclamped F)

    @property
    def v0(self) -> float:
        """The velocity scale [m/s] (v_s when the striker moves)."""
        return self.delta0 / self.t0

    def _y(self, t):
        return self.sol.sol(np.asarray(t, dtype=float) / self.t0)

    def velocity(self, particle: int, t) -> np.ndarray:
        """Velocity [m/s] of ``particle`` (1-based) at times ``t`` [s]."""
        return self._y(t)[self.n + particle - 1] * self.v0

    def displacement(self, particle: int, t) -> np.ndarray:
        """Displacement [m] of ``particle`` (1-based) from its static position."""
        return self._y(t)[particle - 1] * self.delta0

    def overlaps(self, t) -> np.ndarray:
        """Overlaps [m] of the contacts (n - 1, then the wall's) at times ``t``, shape
        (contacts, len(t)); negative: open."""
        u = self._y(np.atleast_1d(np.asarray(t, dtype=float)))[: self.n]
        c = self.contacts
        return (c.ds[:, None] + c.x(u)) * self.delta0

    def wall_force(self, t) -> np.ndarray:
        """Wall force [N] at times ``t``, static preload included (damped: F_el + eta w)."""
        if not self.has_wall:
            raise ValueError("no wall")
        if self.damping is not None:
            y = self._y(np.atleast_1d(np.asarray(t, dtype=float)))
            f = np.array([self.forces(y[:, j])[0][-1] for j in range(y.shape[1])])
            return self.preload + f * self.force0
        u = self._y(np.atleast_1d(np.asarray(t, dtype=float)))[: self.n]
        return self.preload + self.contacts.df(u)[-1] * self.force0

    def damping_force(self, t) -> np.ndarray:
        """F - F_el [N] of every contact (n - 1, then the wall's) at times ``t``, shape
        (contacts, len(t)); zeros for an undamped chain."""
        y = self._y(np.atleast_1d(np.asarray(t, dtype=float)))
        if self.damping is None:
            return np.zeros((len(self.contacts.kap), y.shape[1]))
        return np.array([self.forces(y[:, j])[1] for j in range(y.shape[1])]).T * self.force0

    def work_damping(self, t) -> np.ndarray:
        """Work [J] the damping forces did on the spheres from 0 to ``t``, the integral of
        -(F - F_el) w summed over the contacts (<= 0), integrated with the motion."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.damping is None:
            return np.zeros(len(t))
        return self._y(t)[2 * self.n] * self.force0 * self.delta0

    def energy(self, t) -> np.ndarray:
        """Kinetic + Hertz potential (the wall's included) - F0 x_2, minus its static
        value [J], at times ``t``: constant (1/2 m_1 v_s^2) along an exact solution."""
        y = self._y(np.atleast_1d(np.asarray(t, dtype=float)))
        kin = 0.5 * (self.mass[:, None] * (y[self.n:2 * self.n] * self.v0) ** 2).sum(axis=0)
        return kin + self.contacts.phi(y[: self.n]).sum(axis=0) * self.force0 * self.delta0

    def momentum(self, t) -> np.ndarray:
        """Total momentum [kg m/s] at times ``t``."""
        y = self._y(np.atleast_1d(np.asarray(t, dtype=float)))
        return (self.mass[:, None] * y[self.n:2 * self.n] * self.v0).sum(axis=0)

    def crossing(self, particle: int, level: float) -> float:
        """First time [s] the velocity of ``particle`` (1-based) reaches ``level`` [m/s],
        located on the dense output to round-off. A level between the last step point
        below the peak and v_max (a broad peak) is bracketed by the peak itself."""
        lv = level / self.v0
        row = self.n + particle - 1
        t, v = self.sol.t, self.sol.y[row]
        hi = np.flatnonzero(v >= lv)
        t_hi = t[hi[0]] if hi.size else math.inf
        if self.v_max[particle - 1] >= level:
            t_hi = min(t_hi, self.t_peak[particle - 1] / self.t0)
        if not math.isfinite(t_hi):
            return math.nan
        below = np.flatnonzero((t < t_hi) & (v < lv))
        if t_hi == t[0] or not below.size:
            return float(t_hi * self.t0)
        f = lambda s: self.sol.sol(s)[row] - lv   # noqa: E731
        return float(brentq(f, t[below[-1]], t_hi, xtol=1e-15, rtol=1e-15) * self.t0)


def _is_material(x) -> bool:
    return isinstance(x, tuple) and len(x) == 3 and all(isinstance(v, (int, float)) for v in x)


def hertz_chain_general(radius, material, v_s: float, t_end: float, *, n: int | None = None,
                        gaps=None, wall=None, preload: float = 0.0,
                        rtol: float = RTOL, damping: str | None = None,
                        e: float | None = None, eta_n0: float | None = None,
                        limit_damping: bool = False) -> GeneralChain:
    """A chain of n Hertz spheres from t = 0 to ``t_end`` [s]: particle 1 (the striker)
    moving at ``v_s`` [m/s] toward the others, at rest.

    ``radius``: one radius [m] or a list of n (particle 1 first). ``material``: one tuple
    (E [Pa], nu, rho [kg/m^3]) or a list of n such tuples. ``n``: needed only when both are
    single values. ``gaps``: n - 1 gaps [m] >= 0 (default: touching). ``wall``: None (free
    end), ``"rigid"``, or (E, nu[, rho]) of a flat wall touching the last sphere at t = 0.
    ``preload``: dead load F0 [N] on particle 2 toward the wall (needs the wall and no
    gaps). ``rtol``: DOP853's relative tolerance (absolute: 1e-4 rtol, scaled units).

    ``damping``: None (elastic contacts), ``"coeff_restitution"`` or ``"tsuji"`` (give
    ``e``, 0 < e <= 1) or ``"viscoelastic"`` (give ``eta_n0`` [1/(m s)]): every contact and
    the wall then carries F = F_el + eta w (see "Contact damping" below);
    ``limit_damping``: F held at >= 0.
    Solves are cached: tests that ask for the same chain share one solve.
    """
    if damping is None:
        if e is not None or eta_n0 is not None or limit_damping:
            raise ValueError("e, eta_n0 and limit_damping need a damping model")
        dmp = None
    elif damping in ("coeff_restitution", "tsuji"):
        if e is None or not 0.0 < e <= 1.0 or eta_n0 is not None:
            raise ValueError(f"{damping} needs e in (0, 1] and no eta_n0")
        dmp = (damping, float(e), bool(limit_damping))
    elif damping == "viscoelastic":
        if eta_n0 is None or not eta_n0 >= 0.0 or e is not None:
            raise ValueError("viscoelastic needs eta_n0 >= 0 and no e")
        dmp = (damping, float(eta_n0), bool(limit_damping))
    else:
        raise ValueError(f"unknown damping model {damping!r}")
    if n is None:
        for x in (radius, material):
            if not (isinstance(x, (int, float)) or _is_material(x)):
                n = len(x)
                break
        else:
            raise ValueError("give n, or a list of radii or of materials")
    if isinstance(radius, (int, float)):
        radii = (float(radius),) * n
    else:
        radii = tuple(float(r) for r in radius)
    if _is_material(material):
        mats = (tuple(float(v) for v in material),) * n
    else:
        mats = tuple(tuple(float(v) for v in m) for m in material)
    if len(radii) != n or len(mats) != n:
        raise ValueError(f"give one radius and material, or lists of n = {n}")
    if wall is None:
        w = None
    elif wall == "rigid":
        w = (math.inf, 0.0)
    else:
        w = (float(wall[0]), float(wall[1]))
    g = None if gaps is None else tuple(float(x) for x in gaps)
    if dmp is None:
        return _solve_general(radii, mats, float(v_s), float(t_end), g, w, float(preload),
                              float(rtol))
    return _solve_general(radii, mats, float(v_s), float(t_end), g, w, float(preload),
                          float(rtol), dmp)


# Hysteresis of the contact-switch events, in scaled overlap (delta0 = 1): a contact counts
# as switched once its overlap is past 0 by SWITCH_EPS, so the next segment does not start
# on its root (~1e-21 m for the chains here).
SWITCH_EPS = 1e-13


def _integrate_by_contact(rhs, C, n, fixed, y0, T, rtol, extra_switches=None):
    """solve_ivp(DOP853) from 0 to T, restarted wherever a contact closes or opens.

    f = k delta^(3/2) is not smooth at delta = 0 (f'' ~ delta^(-1/2) is unbounded), and an
    embedded error estimate does not see that inside a step: measured on a 189 um
    tungsten-carbide sphere striking a 150 um 440C sphere, a step across the separation
    left the final velocities 3.7e-10 off at rtol 1e-12, and a gapped 15-sphere chain's
    energy 2e-9. So each switch ends a segment: a terminal event (hysteresis SWITCH_EPS)
    locates it, the step that crossed it is done again from its start up to the switch
    (no stage past it), and the next segment starts there. ``fixed``: the other
    (non-terminal) events, located on the whole dense output once it is integrated
    (:func:`_locate`). Returns a namespace like solve_ivp's result: t, y, t_events,
    y_events (per ``fixed`` event), sol (dense output over [0, T]),
    segments (their count). ``extra_switches``: None, or a function of the state at a
    segment's start giving more terminal events that end a segment (limit_damping's
    clamp). The state may carry more than the 2 n positions and velocities."""
    nc = len(C.kap)
    free = [c for c in range(nc) if not C.ds[c] > 0.0]     # preloaded contacts stay closed
    ts, ys, interps = [np.array([0.0])], [y0[:, None]], []     # step points, dense output

    def keep(sol, upto=None):
        """Append sol's steps (all, or those ending at or before ``upto``)."""
        knots = sol.sol.ts
        m = len(knots) - 1 if upto is None else int(np.searchsorted(knots, upto, "right")) - 1
        ts.append(knots[1:m + 1])
        ys.append(sol.sol(knots[1:m + 1]) if m else np.zeros((len(y0), 0)))
        interps.extend(sol.sol.interpolants[:m])

    t_cur, y_cur, segments = 0.0, y0, 0
    while True:
        g0 = C.ds + C.x(y_cur[:n])
        side = np.where(g0 > 0.0, 1.0, -1.0)

        def switch(c):
            s = side[c]

            def ev(_t, y):
                return C.ds[c] + C.x(y[:n])[c] + s * SWITCH_EPS
            ev.terminal = True
            ev.direction = -s
            return ev

        extra = [] if extra_switches is None else extra_switches(y_cur)
        sol = solve_ivp(rhs, (t_cur, T), y_cur, method="DOP853", rtol=rtol, atol=1e-4 * rtol,
                        dense_output=True, events=[switch(c) for c in free] + extra)
        if sol.status == -1:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        segments += 1
        if sol.status == 0:
            keep(sol)
            break
        t_e = float(sol.t[-1])
        t_prev = float(sol.sol.ts[-2])          # start of the step that crossed the switch
        keep(sol, upto=t_prev)
        if t_e > t_prev:
            redo = solve_ivp(rhs, (t_prev, t_e), sol.sol(t_prev), method="DOP853", rtol=rtol,
                             atol=1e-4 * rtol, dense_output=True)
            if redo.status != 0:
                raise RuntimeError(f"solve_ivp failed: {redo.message}")
            keep(redo)
            y_e = redo.y[:, -1]
        else:
            y_e = sol.y[:, -1]
        if not t_e > t_cur:
            raise RuntimeError(f"no progress at t = {t_cur} (scaled)")
        t_cur, y_cur = t_e, y_e.copy()
    t_all = np.concatenate(ts)
    dense = OdeSolution(t_all, interps)
    t_events, y_events = _locate(fixed, dense, t_all)
    return SimpleNamespace(t=t_all, y=np.concatenate(ys, axis=1), t_events=t_events,
                           y_events=y_events, sol=dense, segments=segments)


# ---------------------------------------------------------------------------------------
# Contact damping (LAMMPS pair granular's damping on
# hertz/material contacts). At a contact of overlap delta > 0 closing at the overlap
# rate w = delta' (m/s), the normal force is
#   F = F_el + eta w,    F_el = k delta^(3/2),
# with eta (kg/s) of the model:
#   coeff_restitution: eta = c(e) sqrt(m_eff F_el / delta),
#                      c(e) = -sqrt(3/2) 2 sqrt(5/6) ln e / sqrt(pi^2 + ln^2 e);
#   tsuji:             the same form, c(e) of Marshall (2009) Eq. 53 times sqrt(2)
#                      (LAMMPS's gran_sub_mod_damping.cpp);
#   viscoelastic:      eta = eta_n0 m_eff sqrt(R* delta)   (eta_n0 in 1/(m s));
# m_eff = m_i m_j / (m_i + m_j), R* as for F_el; at the end wall m_eff = m_n, R* = R_n.
# The net force may turn attractive near the end of a contact; limit_damping holds it
# at F >= 0. The work the damping does on the spheres is the integral of -(F - F_el) w
# over time, summed over the contacts; it is integrated with the motion as one more
# state variable (damped chains only), so energy(t) - energy(0) = work_damping(t) along
# an exact solution.
#
# In the scaled units eta w / (k0 delta0^(3/2)) = c sqrt(mu_eff F / d) w for the sqrt
# forms (F, d, w scaled, mu_eff = m_eff / m0; the units cancel exactly), and
# A d^(1/2) w with A = eta_n0 m_eff sqrt(R* delta0) v0 / (k0 delta0^(3/2)) for the
# viscoelastic one. With limit_damping the force is not smooth where F_el + eta w
# crosses zero: the integration restarts there too (terminal events, SWITCH_EPS).
# ---------------------------------------------------------------------------------------
def restitution_c(e: float) -> float:
    """c(e) of coeff_restitution on Hertz contacts (0 at e = 1)."""
    lg = math.log(e)
    return -math.sqrt(1.5) * 2.0 * math.sqrt(5.0 / 6.0) * lg / math.sqrt(math.pi ** 2 + lg ** 2)


def tsuji_c(e: float) -> float:
    """c(e) of tsuji: Marshall (2009) Eq. 53, a polynomial in e, times sqrt(2)."""
    coef = (1.2728, -4.2783, 11.087, -22.348, 27.467, -18.022, 4.8218)
    return math.sqrt(2.0) * sum(a * e ** j for j, a in enumerate(coef))


@functools.lru_cache(maxsize=32)
def _solve_general(radii, mats, v_s, t_end, gaps, wall, F0, rtol, damping=None):
    n = len(radii)
    has_wall = wall is not None
    if n < 1 or (n < 2 and not has_wall):
        raise ValueError("a free chain needs two spheres; a single sphere needs the wall")
    if v_s < 0 or F0 < 0 or t_end <= 0:
        raise ValueError("v_s >= 0, preload >= 0 and t_end > 0")
    R = radii
    E = [x[0] for x in mats]
    nu = [x[1] for x in mats]
    m = np.array([sphere_mass(r, x[2]) for r, x in zip(radii, mats)])
    k = np.array([hertz_k(R[i], E[i], nu[i], R[i + 1], E[i + 1], nu[i + 1])
                  for i in range(n - 1)])
    kw = hertz_k(R[-1], E[-1], nu[-1], None, wall[0], wall[1]) if has_wall else math.nan
    g = np.zeros(n - 1) if gaps is None else np.array(gaps)
    if g.shape != (n - 1,) or (g < 0).any():
        raise ValueError("gaps must be n - 1 values >= 0")
    ds = np.zeros(n - 1)
    dsw = 0.0
    if F0 > 0:
        if not has_wall or n < 2 or (g > 0).any():
            raise ValueError("a preload needs the wall, two spheres or more and no gaps")
        ds[1:] = (F0 / k[1:]) ** (2.0 / 3.0)
        dsw = (F0 / kw) ** (2.0 / 3.0)
    m0 = m[1] if n > 1 else m[0]
    k0 = k[0] if n > 1 else kw
    if v_s > 0:
        delta0 = (m0 * v_s ** 2 / k0) ** 0.4
    elif F0 > 0:
        delta0 = (F0 / k0) ** (2.0 / 3.0)
    else:
        raise ValueError("nothing moves: give v_s > 0 or a preload")
    t0 = math.sqrt(m0 / (k0 * math.sqrt(delta0)))
    force0 = k0 * delta0 ** 1.5
    v0 = delta0 / t0
    kap = np.append(k, kw) / k0 if has_wall else k / k0
    dss = (np.append(ds, dsw) if has_wall else ds) / delta0
    gs = (np.append(g, 0.0) if has_wall else g) / delta0
    C = _Contacts(n=n, wall=has_wall, kap=kap, ds=dss, gs=gs, fs=kap * dss ** 1.5,
                  es=kap * dss ** 2.5)
    mu = m / m0
    loaded = F0 > 0
    damped = damping is not None

    def rhs(_t, y):
        return np.concatenate([y[n:], C.net(y[:n]) / mu])

    forces = None
    if damped:
        model, coef, limit = damping
        # per contact (the wall's last): m_eff and R*
        m_eff = np.array([m[i] * m[i + 1] / (m[i] + m[i + 1]) for i in range(n - 1)]
                         + ([m[-1]] if has_wall else []))
        r_eff = np.array([R[i] * R[i + 1] / (R[i] + R[i + 1]) for i in range(n - 1)]
                         + ([R[-1]] if has_wall else []))
        mu_eff = m_eff / m0
        if model == "viscoelastic":
            damp = coef
            A = coef * m_eff * np.sqrt(r_eff * delta0) * v0 / force0
        else:
            damp = restitution_c(coef) if model == "coeff_restitution" else tsuji_c(coef)

        zero = np.zeros(len(C.kap))
        visco = model == "viscoelastic"

        def forces(y):
            """Per contact, scaled: (F - F_static, F - F_el, w, F_el + eta w unclamped)."""
            u, v = y[:n], y[n:2 * n]
            x = C.x(u)
            if loaded:
                df = C.df(u)
                d = C.ds + x
            else:                                              # df = F_el = k d^(3/2)
                d = x
                xp = np.maximum(x, 0.0)
                df = C.kap * xp * np.sqrt(xp)
            on = d > 0.0
            dp = np.maximum(d, 0.0)
            w = C.rate(v)
            if visco:
                eta = A * np.sqrt(dp)                          # eta_n0 m_eff sqrt(R* delta)
            else:
                fel = df if not loaded else C.kap * dp * np.sqrt(dp)
                q = np.divide(fel, d, out=zero.copy(), where=on)
                eta = damp * np.sqrt(mu_eff * q)               # c sqrt(m_eff F_el / delta)
            dmp = eta * w                                      # 0 where open (eta = 0)
            free_total = C.fs + df + dmp if loaded else df + dmp
            total = df + dmp
            if limit:
                total = np.maximum(total, -C.fs)               # F = F_s + total >= 0
            return total, total - df, w, free_total

        ev_memo = {"t": None, "y": None, "f": None}

        def ev_forces(t, y):
            """forces(y) once per state for all the events."""
            if ev_memo["t"] != t or ev_memo["y"] is not y:
                ev_memo.update(t=t, y=y, f=forces(y))
            return ev_memo["f"]

        def rhs(_t, y):                                          # noqa: F811
            total, fd, w, _ = forces(y)
            return np.concatenate([y[n:2 * n], C.net_of(total) / mu, [-(fd * w).sum()]])

        def clamp_switches(y):
            """limit_damping: a terminal event per closed contact where F_el + eta w
            crosses zero (past it by SWITCH_EPS, like the contact switches)."""
            if not limit:
                return []
            _, _, _, ft = forces(y)
            d = C.ds + C.x(y[:n])
            out = []
            for c in np.flatnonzero(d > 0.0):
                side = 1.0 if ft[c] > 0.0 else -1.0

                def ev(t, yy, c=c, side=side):
                    return ev_forces(t, yy)[3][c] + side * SWITCH_EPS
                ev.terminal = True
                ev.direction = -side
                out.append(ev)
            return out

        def accel(y):
            return C.net_of(forces(y)[0]) / mu
    else:
        clamp_switches = None

        def accel(y):
            return C.net(y[:n]) / mu

    memo = {"t": None, "y": None, "g": None}

    def peak_values(t, y):
        """Per particle: its acceleration while it touches a neighbour or the wall (or
        carries the load), else the largest overlap of its contacts (< 0), continuous
        where its last contact opens (:func:`_touch_or_overlap`); computed once per
        state for all the particles' events."""
        if memo["t"] != t or memo["y"] is not y:
            u = y[:n]
            a = accel(y) if damped else C.net(u) / mu
            memo.update(t=t, y=y, g=_touch_or_overlap(C.ds + C.x(u), n, a, loaded))
        return memo["g"]

    def peak_event(i):
        def ev(t, y):
            return peak_values(t, y)[i]
        ev.direction = -1.0
        return ev

    def wall_peak(_t, y):          # the last sphere's velocity falls through zero in contact
        return y[2 * n - 1] if C.ds[-1] + y[n - 1] > 0.0 else 1.0
    wall_peak.direction = -1.0

    def wall_open(_t, y):
        return C.ds[-1] + y[n - 1]
    wall_open.direction = -1.0

    def wall_total_peak(t, y):
        """Damped: dF/dt of the wall's whole force F = F_el + eta w while it is in contact
        and pushing (1 elsewhere). F_el = k d^(3/2), eta w = B d^p w (p = 1/4, B =
        c sqrt(mu_eff k), for the sqrt forms; p = 1/2, B = A viscoelastic), so
        dF/dt = (3/2) k d^(1/2) w + B (p d^(p-1) w^2 + d^p w'), w = v_n, w' = a_n."""
        d = C.ds[-1] + y[n - 1]
        total, _, w, ft = ev_forces(t, y)
        if not d > 0.0 or (limit and not ft[-1] > 0.0):
            return 1.0
        kap = C.kap[-1]
        a = C.net_of(total)[n - 1] / mu[n - 1]
        if model == "viscoelastic":
            B, p = A[-1], 0.5
        else:
            B, p = damp * math.sqrt(mu_eff[-1] * kap), 0.25
        w = w[-1]
        return 1.5 * kap * math.sqrt(d) * w + B * (p * d ** (p - 1.0) * w * w + d ** p * a)
    wall_total_peak.direction = -1.0

    fixed = [peak_event(i) for i in range(n)]
    if has_wall:
        fixed += [wall_peak, wall_open]
        if damped:
            fixed += [wall_total_peak]
    y0 = np.zeros(2 * n + int(damped))
    y0[n] = v_s / v0
    sol = _integrate_by_contact(rhs, C, n, fixed, y0, t_end / t0, rtol, clamp_switches)
    a_end = accel(sol.y[:, -1]) if damped else C.net(sol.y[:n, -1]) / mu
    vmax, tpk = np.full(n, math.nan), np.full(n, math.nan)
    for i in range(n):
        cands = [(y[n + i], t) for t, y in zip(sol.t_events[i], sol.y_events[i])]
        if y0[n + i] > 0.0:                              # the striker: fastest at t = 0
            cands.append((y0[n + i], 0.0))
        if a_end[i] > 0.0:                               # still rising at t_end
            cands.append((sol.y[n + i, -1], sol.t[-1]))
        cands = [c for c in cands if c[0] > 0.0]
        if cands:
            v, t = max(cands, key=lambda c: (c[0], -c[1]))   # the highest, the first of ties
            vmax[i], tpk[i] = v * v0, t * t0
    if has_wall:
        def dyn(y):
            return float(C.df(y[:n])[-1]) * force0
        cands = [(dyn(y), t * t0) for t, y in zip(sol.t_events[n], sol.y_events[n])]
        final = True
        f_end = dyn(sol.y[:, -1])
        if sol.y[2 * n - 1, -1] > 0.0 and (not cands or f_end > max(c[0] for c in cands)):
            cands.append((f_end, math.nan))
            final = False
        if not cands:                                    # never compressed: force at t = 0
            cands.append((0.0, 0.0))
        fdyn, twp = max(cands, key=lambda c: c[0])
        t_open = np.asarray(sol.t_events[n + 1]) * t0
        el_dyn, t_el = fdyn, twp
        if damped:             # the whole force's peak: where dF/dt falls through zero
            def whole(y):
                return float(forces(y)[0][-1]) * force0
            cands = [(whole(y), t * t0) for t, y in zip(sol.t_events[n + 2], sol.y_events[n + 2])]
            f_end = whole(sol.y[:, -1])
            final = not (wall_total_peak(0.0, sol.y[:, -1]) > 0.0 and C.ds[-1] + sol.y[n - 1, -1] > 0.0
                         and (not cands or f_end > max(c[0] for c in cands)))
            if not final:
                cands.append((f_end, math.nan))
            if not cands:
                cands.append((0.0, 0.0))
            fdyn, twp = max(cands, key=lambda c: c[0])
    else:
        fdyn, twp, final, t_open = math.nan, math.nan, False, np.zeros(0)
        el_dyn, t_el = math.nan, math.nan
    return GeneralChain(n=n, v_s=v_s, preload=F0, has_wall=has_wall, delta0=delta0, t0=t0,
                        force0=force0, mass=m, k=k, k_wall=kw, delta_static=ds,
                        delta_static_wall=dsw, gaps=g, v_max=vmax, t_peak=tpk,
                        wall_force_max=F0 + fdyn, wall_force_static=F0,
                        wall_force_dynamic=fdyn, t_wall_peak=twp, wall_peak_final=final,
                        t_wall_open=t_open, t_end=t_end, sol=sol, contacts=C,
                        damping=damping, damp=damp if damped else 0.0,
                        wall_elastic_dynamic=el_dyn, t_wall_elastic_peak=t_el,
                        forces=forces)


# ---------------------------------------------------------------------------------------
# Thornton's elastic-perfectly plastic contact (Thornton 1997, J. Appl. Mech. 64, 383),
# written here from the paper's law: Hertz until the peak pressure 2 E* a / (pi R*)
# reaches p_y (a = sqrt(R* delta)); then F = F_y + pi p_y R* (delta - delta_y); unloading
# Hertzian with the radius R_p = R* (F_y/F_max) ((2 F_max + F_y)/(3 F_y))^(3/2) (the
# paper's form) down to delta_p, where (4/3) E* sqrt(R_p) (delta_max - delta_p)^(3/2) =
# F_max. A collision of two bodies is 1-D and conservative on each branch, so its outcome
# follows from the branches' energies, by quadrature and root finding (no time stepping).
@dataclass
class ThorntonContact:
    Es: float       # E* (Pa)
    Rs: float       # R* (m)
    py: float       # limiting contact pressure (Pa)

    @property
    def dy(self) -> float:
        return self.Rs * (math.pi * self.py / (2.0 * self.Es)) ** 2

    @property
    def Fy(self) -> float:
        return math.pi ** 3 * self.py ** 3 * self.Rs ** 2 / (6.0 * self.Es ** 2)

    def loading(self, d: float) -> float:
        """The force on the virgin loading curve at overlap d."""
        if d <= self.dy:
            return 4.0 / 3.0 * self.Es * math.sqrt(self.Rs) * d ** 1.5
        return self.Fy + math.pi * self.py * self.Rs * (d - self.dy)

    def loading_work(self, d0: float, d1: float) -> float:
        """The work of the loading curve from d0 to d1 (quadrature)."""
        from scipy.integrate import quad
        pts = [p for p in (self.dy,) if d0 < p < d1]
        return quad(self.loading, d0, d1, points=pts or None, epsabs=0.0, epsrel=1e-13,
                    limit=200)[0]

    def unloading(self, dm: float):
        """(R_p, delta_p) of the unloading curve from the largest overlap dm."""
        if dm <= self.dy:
            return self.Rs, 0.0
        Fm = self.loading(dm)
        Rp = self.Rs * (self.Fy / Fm) * ((2.0 * Fm + self.Fy) / (3.0 * self.Fy)) ** 1.5
        dp = dm - (3.0 * Fm / (4.0 * self.Es * math.sqrt(Rp))) ** (2.0 / 3.0)
        return Rp, dp

    def stored(self, dm: float) -> float:
        """The energy the unloading curve from dm returns: its integral from delta_p."""
        Rp, dp = self.unloading(dm)
        return 8.0 / 15.0 * self.Es * math.sqrt(Rp) * (dm - dp) ** 2.5

    def collide(self, m_red: float, u: float, dmax: float = 0.0):
        """A head-on collision at closing speed u (m/s), bodies of reduced mass m_red, on
        a contact whose largest overlap so far is dmax: (rebound speed / u, the new
        largest overlap, the energy dissipated). Below the stored energy of the
        contact's unloading curve the collision runs along it and back (e = 1)."""
        K = 0.5 * m_red * u * u
        U0 = self.stored(dmax) if dmax > 0.0 else 0.0
        if K <= U0:
            return 1.0, dmax, 0.0
        rest = K - U0
        hi = max(dmax, 1e-15) * 2.0
        while self.loading_work(dmax, hi) < rest:
            hi *= 2.0
        dm = brentq(lambda d: self.loading_work(dmax, d) - rest, dmax, hi, xtol=1e-30,
                    rtol=1e-15, maxiter=500)
        U = self.stored(dm)
        return math.sqrt(U / K), dm, K - U

    def yield_speed(self, m_red: float) -> float:
        """v_y: (1/2) m_red v_y^2 = the Hertz energy at delta_y."""
        return math.sqrt(2.0 * 8.0 / 15.0 * self.Es * math.sqrt(self.Rs) * self.dy ** 2.5 / m_red)


def thornton_restitution(r: float) -> float:
    """Thornton's (1997) closed form of e at an impact speed r = v / v_y >= 1 times the
    yield speed: e = (6 sqrt(3)/5)^(1/2) [1 - (1/6)(v_y/v)^2]^(1/2)
    [(v_y/v) / ((v_y/v) + 2 sqrt(6/5 - (1/5)(v_y/v)^2))]^(1/4); 1 below."""
    if r <= 1.0:
        return 1.0
    x = 1.0 / r
    return (math.sqrt(6.0 * math.sqrt(3.0) / 5.0) * math.sqrt(1.0 - x * x / 6.0)
            * (x / (x + 2.0 * math.sqrt(6.0 / 5.0 - x * x / 5.0))) ** 0.25)

# Adhesion: LAMMPS pair granular's dmt and jkr normal laws, from the JKR and DMT theories
# (gamma LAMMPS's cohesion; the work of adhesion is 2 gamma), solved here with scipy.
def dmt_force(K: float, Rs: float, gamma: float, delta: float) -> float:
    """DMT: K delta^(3/2) - 4 pi gamma R* while delta > 0, else 0 (N)."""
    return K * delta ** 1.5 - 4.0 * np.pi * gamma * Rs if delta > 0 else 0.0


def dmt_pulloff(K: float, Rs: float, gamma: float) -> float:
    """The DMT pull-off force (N, > 0): minus the least force of :func:`dmt_force` over
    the overlaps of a closed contact (it falls to its least as delta -> 0+), found by
    bounded minimisation over delta in (0, 1e-6 R*]."""
    from scipy.optimize import minimize_scalar
    res = minimize_scalar(lambda x: dmt_force(K, Rs, gamma, x * 1e-6 * Rs), bounds=(1e-300, 1.0),
                          method="bounded", options={"xatol": 1e-14})
    return -min(res.fun, dmt_force(K, Rs, gamma, 1e-300))


def jkr_delta(a: float, Rs: float, E: float, gamma: float) -> float:
    """JKR's overlap at contact radius a: a^2/R* - sqrt(2 pi w a / E*), w = 2 gamma."""
    return a * a / Rs - np.sqrt(2.0 * np.pi * (2.0 * gamma) * a / E)


def jkr_force_of_radius(a: float, Rs: float, E: float, gamma: float) -> float:
    """JKR's force at contact radius a: 4 E* a^3 / (3 R*) - sqrt(8 pi w E* a^3)."""
    return 4.0 * E * a ** 3 / (3.0 * Rs) - np.sqrt(8.0 * np.pi * (2.0 * gamma) * E * a ** 3)


def jkr_turning_radius(Rs: float, E: float, gamma: float) -> float:
    """The contact radius at which the overlap is least (d delta / da = 0)."""
    return (np.pi * gamma * Rs * Rs / (4.0 * E)) ** (1.0 / 3.0)


def jkr_radius(Rs: float, E: float, gamma: float, delta: float) -> float:
    """The stable (larger) root a of jkr_delta(a) = delta, by brentq."""
    lo = jkr_turning_radius(Rs, E, gamma)
    hi = 2.0 * lo
    while jkr_delta(hi, Rs, E, gamma) < delta:
        hi *= 2.0
    return brentq(lambda a: jkr_delta(a, Rs, E, gamma) - delta, lo, hi, xtol=1e-30,
                  rtol=1e-15, maxiter=500)


def jkr_force(Rs: float, E: float, gamma: float, delta: float) -> float:
    return jkr_force_of_radius(jkr_radius(Rs, E, gamma, delta), Rs, E, gamma)


def jkr_pulloff(Rs: float, E: float, gamma: float) -> tuple[float, float, float]:
    """(a, delta, F) where the stable branch's force is least (dF/da = 0): the
    load-controlled pull-off point, at which LAMMPS opens a closed contact."""
    a = (9.0 * np.pi * gamma * Rs * Rs / (4.0 * E)) ** (1.0 / 3.0)
    return a, jkr_delta(a, Rs, E, gamma), jkr_force_of_radius(a, Rs, E, gamma)


def jkr_hysteresis(Rs: float, E: float, gamma: float) -> float:
    """The energy (J) one approach and separation loses: the work of the tension between
    first touch (delta = 0, where the force jumps onto the JKR curve) and the pull-off
    point (where it jumps to 0), -int_{delta_po}^{0} F d delta, integrated over a."""
    a_po, _, _ = jkr_pulloff(Rs, E, gamma)
    a0 = (4.0 * np.pi * gamma * Rs * Rs / E) ** (1.0 / 3.0)       # delta(a0) = 0
    ddelta = lambda a: 2.0 * a / Rs - np.sqrt(np.pi * gamma / (E * a))  # noqa: E731
    w, _ = quad(lambda a: -jkr_force_of_radius(a, Rs, E, gamma) * ddelta(a), a_po, a0,
                epsabs=0.0, epsrel=1e-13, limit=200)
    return w


def jkr_capture_velocity(Rs: float, E: float, gamma: float, m_red: float) -> float:
    """v_c = sqrt(2 W / m*): an undamped pair closing slower stays captured."""
    return np.sqrt(2.0 * jkr_hysteresis(Rs, E, gamma) / m_red)


def jkr_restitution(v: float, v_c: float) -> float:
    """e = sqrt(1 - v_c^2 / v^2) of an undamped JKR pair closing at v > v_c."""
    return np.sqrt(1.0 - (v_c / v) ** 2)
