"""rolling_friction: LAMMPS ``rolling sds`` on the 1D line
(docs/explanation/lammps_laws.md section 5).

At each touching contact of spheres k, k+1 (``spec.touching``: delta > 0, or held closed
in tension by its normal law) the relative rolling velocity v_r = R* (omega_k -
omega_{k+1}) (R* = R/2) winds a history rho (rho' = v_r, erased when the contact stops
touching); the moment M = -k_roll rho - gamma_roll v_r is capped at mu_roll f,
and when the cap is exceeded rho is return-mapped to
-(mu_roll f sgn(M) + gamma_roll v_r) / k_roll (spring and dashpot hold the cap, as LAMMPS
stores it). Torque R* M on sphere k, -R* M on sphere k+1 (equal and opposite; opposes
relative spin, nothing for spheres rolling together). k_roll (N/m) has no default;
gamma_roll (N s/m) defaults to 0, mu_roll to 0.01. Its work is sum M v_r; LAMMPS has no
per-atom output of it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..units import lmp_float as _r, to_micro
from ..validate import Key
from . import slots as S
from .lanes import any_touching, bit, clip_to_cap, overlap
from .spec import (DeckPart, EffectSpec, compiled, normal_cap, normal_crit, switches,
                   touching)

SPEC = EffectSpec("rolling_friction", state=(("L_ROLLING_HIST", "contact"),),
                  work="work_rolling_friction", work_slot="L_WORK_ROLLING",
                  table_column="work_rolling_J", work_note="the rolling friction",
                  lammps_reports_work=False,
                  params=("P_ROLLING_SPRING", "P_ROLLING_DASHPOT", "P_ROLLING_MU"),
                  flags=("F_ROLLING_FRICTION",), rows=("G_ROLLING_REFF",),
                  requires=(("rotation", "acts through torques"),))


# The scene section of this effect and its defaults (no default k_roll: it is not in the
# chapter)
SECTION = "rolling"
DEFAULTS = {"k_roll": None, "gamma_roll": 0.0, "mu_roll": 0.01}
KEYS = (
    Key("rolling.k_roll", "N/m", "Rolling spring k_roll of LAMMPS `rolling sds`: the moment "
        "M = -k_roll rho - gamma_roll v_r on the rolling history rho (rho' = v_r, the "
        "relative rolling velocity R* (omega_k - omega_k+1)), capped at mu_roll f; torque "
        "R* M on the two spheres, equal and opposite (not in the chapter's Eq. 5.1; the same "
        "law in both engines). Required while rolling_friction is on: the chapter gives no "
        "value.", positive=True),
    Key("rolling.gamma_roll", "N s/m", "Rolling dashpot gamma_roll of the moment.",
        nonneg=True),
    Key("rolling.mu_roll", "1", "Coulomb coefficient of the rolling moment: |M| <= mu_roll "
        "f, f the contact's normal force.", nonneg=True),
)
_KEY = {k.name: k for k in KEYS}


@dataclass(frozen=True)
class Settings:
    k_roll: float | None      # N/m
    gamma_roll: float         # N s/m
    mu_roll: float


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``rolling`` section (a merged mapping); ``given``: the dotted keys the
    scene wrote; ``on``: whether rolling_friction is enabled."""
    k_roll = _KEY["k_roll"].number(sec["k_roll"], allow_none=True)
    if on and k_roll is None:
        raise SceneError("rolling.k_roll", "missing while rolling_friction is on",
                         "give the rolling spring stiffness in N/m")
    return Settings(k_roll, _KEY["gamma_roll"].number(sec["gamma_roll"]),
                    _KEY["mu_roll"].number(sec["mu_roll"]))


@compiled
def rolling_map(rho, vr, kr, gr, cap):
    """LAMMPS ``rolling sds`` return mapping: when the trial moment -kr rho - gr vr exceeds
    the cap, the moment is the cap and rho = -(cap sgn + gr vr)/kr (LAMMPS stores the
    dashpot in the rolling history)."""
    M = -kr * rho - gr * vr
    if abs(M) > cap:
        return -(math.copysign(cap, M) + gr * vr) / kr
    return rho


@compiled
def moment_lammps_order(rho, vr, kr, gr, cap, dt):
    """(rho, M) after one LAMMPS step: history += dt v_r, trial moment, strict cap test,
    return map with the dashpot stored; LAMMPS zeroes the moment of a zero history."""
    rho += vr * dt
    M = -kr * rho - gr * vr
    if abs(M) > cap:
        if rho != 0.0:
            rho = rolling_map(rho, vr, kr, gr, cap)
            M = math.copysign(cap, M)
        else:
            M = 0.0
    return rho, M


@compiled
def moment(rho, vr, kr, gr, cap):
    """Moment (N m / m) of the continuous law (RK4, DOP853): clipped to the cap; the
    history is return-mapped after the step. Not held at the cap: the cap mu_roll f(t) and
    the dashpot part move during a slide, and a held history lags them (first order in
    dt, 1e-5 at 1 ns; this way 2e-10, tests/test_rolling.py)."""
    return clip_to_cap(-kr * rho - gr * vr, cap)


# The compiled parts the engines compose (``spec.HOOKS``): each contact's R_eff is row
# G_ROLLING_REFF, its history block L_ROLLING_HIST (docs/explanation/lammps_laws.md
# sections 5 and 8).
@compiled
def forces(y, G, P, FL, LO, hist_dt, dy, f, shut):
    """The rolling moment M of every loaded contact: v_roll = R_eff (omega_k -
    omega_{k+1}), rho' = v_roll, M = -k_roll rho - gamma_roll v_roll capped at mu_roll |F|,
    torque +R_eff M on the left sphere and -R_eff M on the right one, its work rate M
    v_roll. With hist_dt > 0 (Verlet) LAMMPS's order with the half-step spins
    (:func:`moment_lammps_order`); else the continuous law (:func:`moment`), return-mapped
    after the step."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ow = LO[S.L_SPIN]
    oI = S.G_INERTIA * n
    kr = P[S.P_ROLLING_SPRING]
    gr = P[S.P_ROLLING_DASHPOT]
    mur = P[S.P_ROLLING_MU]
    oRe = S.G_ROLLING_REFF * n
    op = LO[S.L_ROLLING_HIST]
    owro = LO[S.L_WORK_ROLLING]
    on = switches(FL)
    for l in range(L):
        dy[owro, l] = 0.0
    for k in range(n - 1):
        if bit(shut, k) or (k >= 63 and not any_touching(y, ox, LO, G, P, FL, on, n, k, L)):
            for l in range(L):
                dy[op + k, l] = 0.0
            if hist_dt > 0.0:
                for l in range(L):
                    y[op + k, l] = 0.0
            continue
        if hist_dt > 0.0:
            for l in range(L):
                # Verlet: LAMMPS's order with the half-step spins
                fn = f[k, l]
                d = overlap(y, ox, G, k, l)
                loaded = touching(d, y, LO, G, P, FL, on, n, k, l)
                Reff = G[oRe + k, l]
                vr = Reff * (y[ow + k, l] - y[ow + k + 1, l])
                rho, M = moment_lammps_order(y[op + k, l], vr, kr, gr, mur * normal_crit(fn, d, G, P, FL, on, n, k, l),
                                                hist_dt)
                y[op + k, l] = rho if loaded else 0.0
                dy[op + k, l] = vr if loaded else 0.0
                tq = Reff * M / G[oI + k, l]
                tq1 = Reff * M / G[oI + k + 1, l]
                a = dy[ow + k, l]
                dy[ow + k, l] = a + tq if loaded else a
                a = dy[ow + k + 1, l]
                dy[ow + k + 1, l] = a - tq1 if loaded else a
                a = dy[owro, l]
                dy[owro, l] = a + M * vr if loaded else a
        else:
            for l in range(L):
                # continuous law (RK4, DOP853): rho' = v_roll, project() return-maps
                # rho after the step
                fn = f[k, l]
                d = overlap(y, ox, G, k, l)
                loaded = touching(d, y, LO, G, P, FL, on, n, k, l)
                Reff = G[oRe + k, l]
                vr = Reff * (y[ow + k, l] - y[ow + k + 1, l])
                M = moment(y[op + k, l], vr, kr, gr, mur * normal_crit(fn, d, G, P, FL, on, n, k, l))
                dy[op + k, l] = vr if loaded else 0.0
                tq = Reff * M / G[oI + k, l]
                tq1 = Reff * M / G[oI + k + 1, l]
                a = dy[ow + k, l]
                dy[ow + k, l] = a + tq if loaded else a
                a = dy[ow + k + 1, l]
                dy[ow + k + 1, l] = a - tq1 if loaded else a
                a = dy[owro, l]
                dy[owro, l] = a + M * vr if loaded else a


@compiled
def project(y, G, P, FL, LO):
    """Return mapping of the rolling histories onto mu_roll |F| (zero on an open contact)."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    ow = LO[S.L_SPIN]
    op = LO[S.L_ROLLING_HIST]
    oRe = S.G_ROLLING_REFF * n
    kr = P[S.P_ROLLING_SPRING]
    gr = P[S.P_ROLLING_DASHPOT]
    mur = P[S.P_ROLLING_MU]
    on = switches(FL)
    for k in range(n - 1):
        if not any_touching(y, ox, LO, G, P, FL, on, n, k, L):
            for l in range(L):
                y[op + k, l] = 0.0
            continue
        for l in range(L):
            d = overlap(y, ox, G, k, l)
            vr = G[oRe + k, l] * (y[ow + k, l] - y[ow + k + 1, l])
            rho = rolling_map(y[op + k, l], vr, kr, gr,
                               normal_cap(mur, y, G, P, FL, on, ov, n, k, l, d))
            y[op + k, l] = rho if touching(d, y, LO, G, P, FL, on, n, k, l) else 0.0


@dataclass(frozen=True)
class RollingFriction:
    k_roll: float
    gamma_roll: float
    mu_roll: float


def build(scene) -> RollingFriction:
    st = scene.setting(SPEC.name)
    return RollingFriction(st.k_roll, st.gamma_roll, st.mu_roll)


def rows(rf: RollingFriction, chain) -> dict:
    """Per-contact rows of the kernels' per-chain array: each contact's R_eff =
    R_i R_j/(R_i + R_j) (R/2 for equal spheres; the wall contact has no rolling
    friction)."""
    R = chain.radii
    reff = tuple(0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
                 for k in range(len(R) - 1))
    return {"G_ROLLING_REFF": reff + (0.0,)}


def kernel(rf: RollingFriction) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return ({"P_ROLLING_SPRING": rf.k_roll, "P_ROLLING_DASHPOT": rf.gamma_roll,
             "P_ROLLING_MU": rf.mu_roll}, {"F_ROLLING_FRICTION": 1})


def error_scale(rf: RollingFriction, terms, delta: float, v: float) -> float:
    """Absolute error scale of the rolling histories for the adaptive method: their value
    at the cap, mu_roll f(delta) / k_roll, at most the peak overlap delta (m)."""
    rho_cap = rf.mu_roll * terms.hertz.K * delta**1.5 / rf.k_roll
    return min(delta, rho_cap) if rho_cap > 0 else delta


def lammps(rf: RollingFriction | None, deck) -> DeckPart:
    """pair granular's rolling sub-model: ``rolling sds``, the same law (none when off)."""
    if rf is None:
        return DeckPart()
    return DeckPart(pair={"rolling": f"rolling sds {_r(to_micro(rf.k_roll, 'stiffness'))} "
                                     f"{_r(to_micro(rf.gamma_roll, 'damping'))} {_r(rf.mu_roll)}"},
                    notes={"rolling": "# rolling sds k_roll gamma_roll mu_roll: rolling_friction "
                                      "on"})
