"""Physical effects of chapter Eq. 5.1, each defined once, engine-neutral.

``physics_terms(scene)`` returns a :class:`Terms` holding one object per enabled effect,
with its parameters in SI units. Both engines take the physics from here: the reference
integrator packs these parameters into its kernel arrays (``engines/reference.py``), the
LAMMPS deck generator turns them into commands. No engine reads scene fields for physics.

Conventions (../shared/physics.md): z along the chain, theta the rotation about the
horizontal axis perpendicular to it (LAMMPS: x and omega_y); a sphere rolling forward has
omega > 0. Slip at the groove: u = v - s R omega. Slip at the contact of spheres k, k+1:
w = R (omega_k + omega_{k+1}).

Laws
----
hertz
    f_k = K delta_k^(3/2) for delta_k > 0, K = (4/3) E* sqrt(R*), E* = E/(2(1-nu^2)),
    R* = R/2; delta_k = (x_k - x_{k+1}) - g_k with x the displacement from the initial
    (gapped) positions. Potential energy (2/5) K delta^(5/2). Identical to LAMMPS
    ``pair_style granular`` ``hertz/material`` with zero damping.
air_drag
    F = -m (v/T0 - v^2/L) (``as_printed``, the chapter's form) or -m (v/T0 - v|v|/L)
    (``odd``). The printed form turns propulsive for v > L/T0 ~ 0.048 m/s.
groove_friction
    Coulomb friction of the groove walls, limit Fc = mu_pg m g / s, on the slip u
    (u = v if rotation is off: the sphere slides without rolling). Stick is an
    elastic-plastic (Cundall-Strack) spring-dashpot: F = -k_g xi - gamma_g u with
    xi' = u, and when |F| would exceed Fc the force is Fc sgn(F) and the history is
    return-mapped to xi = -F/k_g: the spring alone holds the cap and the dashpot is not
    stored (unlike LAMMPS ``linear_history``, whose xi = -(F + gamma u)/k winds up a
    history during fast slides that later cancels the friction while still sliding;
    sliding friction here is exactly Fc, tested against -Fc * sum |slip| ).
    gamma_g = 2 zeta sqrt(k_g m_u), zeta = groove.damping (default 1, critical), with
    m_u = m / (1 + s^2 m R^2 / I) the mass the slip u sees: stick settles within one
    period of the stick oscillator instead of ringing forever.
    No sgn() of a velocity is ever evaluated, so nothing chatters; a sphere at rest or
    rolling without slip feels exactly zero force. The chapter's F = -Fc sgn(u) is the
    limit k_g -> inf. Default k_g: Mindlin stiffness of the two wall contacts under the
    static wall load m g / (2 s) each: k_g = 2 * 8 G*_w a_w, a_w = (3 N R / (4 E*_w))^(1/3),
    E*_w = E / (2 (1 - nu^2)), G*_w = G / (2 (2 - nu)) (sphere on a flat of the same
    steel). Torque on the sphere: -s R F (with rotation on).
rotation
    Adds omega to the state, with I = (2/5) m R^2.
particle_friction
    Coulomb friction mu_pp at each loaded contact on the slip w, with stick through a
    tangential history spring exactly as LAMMPS ``tangential mindlin`` (k_t = 8 G_eff a,
    a = sqrt(R* delta), G_eff = G/(2(2-nu))) or ``linear_history`` (constant k_t):
    T = -k_t xi, xi' = w, |T| <= mu_pp f, history rescaled to the cap when exceeded and
    erased when the contact opens. Torque (R - delta/2) T on both spheres (LAMMPS's lever
    arm to the contact point; the slip w uses full radii, as LAMMPS does), so both
    particle-particle terms of Eq. 5.1 carry a minus sign (friction opposes slip on both
    sides).
rolling_friction
    LAMMPS ``rolling sds`` (docs/lammps_laws.md section 5) on the 1D line: at each loaded
    contact of spheres k, k+1 the relative rolling velocity v_r = R* (omega_k -
    omega_{k+1}) (R* = R/2) winds a history rho (rho' = v_r, erased when the contact
    opens); the moment M = -k_roll rho - gamma_roll v_r is capped at mu_roll f, and when
    the cap is exceeded rho is return-mapped to -(mu_roll f sgn(M) + gamma_roll v_r) /
    k_roll (spring and dashpot hold the cap, as LAMMPS stores it). Torque R* M on sphere k,
    -R* M on sphere k+1 (equal and opposite; opposes relative spin, nothing for spheres
    rolling together). k_roll (N/m) has no default; gamma_roll (N s/m) defaults to 0,
    mu_roll to 0.01. Its work is sum M v_r.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .scene import Scene


@dataclass(frozen=True)
class Hertz:
    K: float          # N / m^1.5
    R: float          # sphere radius, m
    E: float
    nu: float

    def force(self, delta):
        import numpy as np
        d = np.maximum(np.asarray(delta, dtype=float), 0.0)
        return self.K * d * np.sqrt(d)

    def energy(self, delta):
        import numpy as np
        d = np.maximum(np.asarray(delta, dtype=float), 0.0)
        return 0.4 * self.K * d * d * np.sqrt(d)


@dataclass(frozen=True)
class AirDrag:
    T0: float
    L: float
    odd: bool

    def force(self, m, v):
        import numpy as np
        v = np.asarray(v, dtype=float)
        quad = v * np.abs(v) if self.odd else v * v
        return -m * (v / self.T0 - quad / self.L)


@dataclass(frozen=True)
class GrooveFriction:
    s: float
    mu: float
    g: float
    Fc: float         # Coulomb limit mu m g / s, N
    kt: float         # stick spring stiffness, N/m
    kt_source: str    # "mindlin" or "scene"
    gamma: float      # stick dashpot, N s/m
    damping: float    # its ratio to critical damping


@dataclass(frozen=True)
class Rotation:
    inertia: float    # kg m^2


@dataclass(frozen=True)
class ParticleFriction:
    mu: float
    model: str        # "mindlin" | "linear_history"
    kt: float         # linear_history: k_t (N/m); mindlin: 8 G_eff sqrt(R*) (N/m^1.5)
    G_eff: float


@dataclass(frozen=True)
class RollingFriction:
    k_roll: float
    gamma_roll: float
    mu_roll: float


@dataclass(frozen=True)
class Terms:
    """The physics of one scene: the chain and its enabled effects."""
    n: int
    R: float
    m: float
    hertz: Hertz
    air_drag: AirDrag | None = None
    groove_friction: GrooveFriction | None = None
    rotation: Rotation | None = None
    particle_friction: ParticleFriction | None = None
    rolling_friction: RollingFriction | None = None

    @property
    def dissipative(self) -> tuple[str, ...]:
        """Effects that do work on the particles (each gets a work entry in the ledger)."""
        return tuple(k for k in ("groove_friction", "air_drag", "particle_friction",
                                 "rolling_friction") if getattr(self, k) is not None)


def groove_mindlin_stiffness(scene: Scene) -> float:
    """Tangential stiffness of the two groove-wall contacts under the sphere's weight."""
    E, nu = scene.material.E, scene.material.nu
    G = scene.material.G
    N_wall = scene.mass * scene.gravity / (2.0 * scene.groove_s)
    E_w = E / (2.0 * (1.0 - nu * nu))
    G_w = G / (2.0 * (2.0 - nu))
    if N_wall <= 0:
        raise ValueError("groove stiffness needs g > 0")
    a = (3.0 * N_wall * scene.radius / (4.0 * E_w)) ** (1.0 / 3.0)
    return 2.0 * 8.0 * G_w * a


def physics_terms(scene: Scene) -> Terms:
    mat = scene.material
    m, R = scene.mass, scene.radius
    kw = {}
    if scene.has("air_drag"):
        kw["air_drag"] = AirDrag(scene.drag_T0, scene.drag_L, scene.drag_form == "odd")
    if scene.has("groove_friction"):
        Fc = scene.groove_mu * m * scene.gravity / scene.groove_s
        if scene.groove_kt is None:
            kt, src = (groove_mindlin_stiffness(scene) if scene.gravity > 0 else 1.0), "mindlin"
        else:
            kt, src = scene.groove_kt, "scene"
        m_u = m / (1.0 + scene.groove_s**2 * m * R * R / scene.inertia) if scene.has("rotation") else m
        gamma = 2.0 * scene.groove_damping * math.sqrt(kt * m_u)
        kw["groove_friction"] = GrooveFriction(scene.groove_s, scene.groove_mu, scene.gravity,
                                               Fc, kt, src, gamma, scene.groove_damping)
    if scene.has("rotation"):
        kw["rotation"] = Rotation(scene.inertia)
    if scene.has("particle_friction"):
        G_eff = mat.G / (2.0 * (2.0 - mat.nu))
        if scene.tangential == "mindlin":
            kt = 8.0 * G_eff * math.sqrt(R / 2.0)
        else:
            kt = scene.contact_kt
        kw["particle_friction"] = ParticleFriction(scene.mu_pp, scene.tangential, kt, G_eff)
    if scene.has("rolling_friction"):
        kw["rolling_friction"] = RollingFriction(scene.k_roll, scene.gamma_roll, scene.mu_roll)
    return Terms(n=scene.n, R=R, m=m, hertz=Hertz(scene.hertz_k, R, mat.E, mat.nu), **kw)
