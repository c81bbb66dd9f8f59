"""particle_friction: Coulomb friction mu_pp at each loaded contact on the slip
w = R (omega_k + omega_{k+1}).

Stick through a tangential history spring exactly as LAMMPS ``tangential mindlin``
(k_t = 8 G_eff a, a = sqrt(R* delta), G_eff = G/(2(2-nu)); a normal law with its own
contact radius gives a through ``spec.radius_depth``) or ``linear_history`` (constant
k_t): T = -k_t xi, xi' = w, |T| <= mu_pp f, history rescaled to the cap when exceeded and
erased when the contact stops touching (``spec.touching``: delta > 0, or held closed in
tension by its normal law). Torque (R - delta/2) T on both spheres
(LAMMPS's lever arm to the contact point; the slip w uses full radii, as LAMMPS does), so
both particle-particle terms of Eq. 5.1 carry a minus sign (friction opposes slip on both
sides). LAMMPS has no per-atom output of this work: its ledger closes by construction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..units import lmp_float as _r, to_micro
from ..validate import Key
from . import slots as S
from .lanes import any_touching, bit, clip_to_cap, overlap
from .spec import (DeckPart, EffectSpec, compiled, normal_cap, normal_crit, radius_depth,
                   switches, touching)

SPEC = EffectSpec("particle_friction", state=(("L_PARTICLE_HIST", "contact"),),
                  work="work_particle_friction", work_slot="L_WORK_PARTICLE",
                  table_column="work_particle_friction_J",
                  work_note="the tangential friction between spheres",
                  lammps_reports_work=False,
                  params=("P_PARTICLE_MU", "P_PARTICLE_SPRING"),
                  flags=("F_PARTICLE_FRICTION", "F_PARTICLE_MINDLIN"), rows=("G_PARTICLE_SPRING",),
                  requires=(("rotation", "acts through torques"),))


# The scene section of this effect and its defaults: the chapter's mu_pp; LAMMPS's
# Mindlin tangential law, so that both engines share one law.
SECTION = "contact"
DEFAULTS = {"mu_pp": 1.4, "tangential": "mindlin", "kt": None}
MODELS = ("mindlin", "linear_history")
KEYS = (
    Key("contact.mu_pp", "1", "Coulomb coefficient mu_pp of the friction between neighbouring "
        "spheres, on the slip w = R (omega_k + omega_k+1): |T| <= mu_pp f at each loaded "
        "contact; the default is the chapter's fit (its Chapter 4).", nonneg=True, hi=10.0),
    Key("contact.tangential", "-", "The stick law, as LAMMPS's: `mindlin`, k_t = 8 G_eff a "
        "(a = sqrt(R* delta), G_eff = G/(2(2-nu))), so that both engines share one law; "
        "`linear_history`, a constant k_t (`contact.kt`).", choices=MODELS),
    Key("contact.kt", "N/m", "The tangential spring of `tangential: linear_history`; required "
        "there, refused with `mindlin` (its stiffness follows from the material).",
        positive=True),
)
_KEY = {k.name: k for k in KEYS}


@dataclass(frozen=True)
class Settings:
    mu_pp: float
    tangential: str       # mindlin | linear_history
    kt: float | None      # linear_history's spring (N/m)


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``contact`` section (a merged mapping); ``given``: the dotted keys the
    scene wrote; ``on``: whether particle_friction is enabled."""
    mu = _KEY["mu_pp"].number(sec["mu_pp"])
    model = _KEY["tangential"].choice(sec["tangential"], "model")
    kt = _KEY["kt"].number(sec["kt"], allow_none=True, fix="give the tangential stiffness in N/m")
    if on and model == "linear_history" and kt is None:
        raise SceneError("contact.kt", "missing for tangential: linear_history",
                         "give the tangential spring stiffness in N/m, or use tangential: mindlin")
    if on and model == "mindlin" and "contact.kt" in given:
        raise SceneError("contact.kt", "has no effect with tangential: mindlin (its stiffness "
                         "follows from the material)",
                         "drop it, or use tangential: linear_history")
    return Settings(mu, model, kt)


@compiled
def contact_map(xi, kt, cap):
    """Return mapping of a contact history onto the Coulomb cap |kt xi| <= cap."""
    if kt * abs(xi) > cap:
        return math.copysign(cap / kt, xi)
    return xi


@compiled
def contact_force(xi, w, kt, cap):
    """(T, xi') of a loaded contact: the capped spring force (N) and the history rate
    (w, or 0 while sliding at the cap away from the origin)."""
    T = -kt * xi
    rate = 0.0 if (abs(T) >= cap and w * xi > 0.0) else w
    return clip_to_cap(T, cap), rate


# The compiled parts the engines compose (``spec.HOOKS``): each contact's spring constant
# is row G_PARTICLE_SPRING (Mindlin: k_t / sqrt(delta)), its history block
# L_PARTICLE_HIST; the Coulomb cap is mu_pp times the contact's Fncrit (``normal_crit``:
# LAMMPS's, the net normal force |F| unless a normal law says otherwise; F < 0 only damped).
@compiled
def forces(y, G, P, FL, LO, hist_dt, dy, f, shut):
    """The tangential force T of every loaded contact: torques (R - delta/2) T on both
    spheres, the history rate and the work rate (with hist_dt > 0 the history is first
    advanced by the slip and return-mapped, as LAMMPS does inside its force call)."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ow = LO[S.L_SPIN]
    oI = S.G_INERTIA * n
    oR = S.G_RADIUS * n
    mu = P[S.P_PARTICLE_MU]
    oKt = S.G_PARTICLE_SPRING * n
    mindlin = FL[S.F_PARTICLE_MINDLIN] != 0
    ot = LO[S.L_PARTICLE_HIST]
    owt = LO[S.L_WORK_PARTICLE]
    on = switches(FL)
    for l in range(L):
        dy[owt, l] = 0.0
    for k in range(n - 1):
        if bit(shut, k) or (k >= 63 and not any_touching(y, ox, LO, G, P, FL, on, n, k, L)):
            for l in range(L):
                dy[ot + k, l] = 0.0
            if hist_dt > 0.0:
                for l in range(L):
                    y[ot + k, l] = 0.0
            continue
        if hist_dt > 0.0:
            for l in range(L):
                fn = f[k, l]
                d = overlap(y, ox, G, k, l)
                held = touching(d, y, LO, G, P, FL, on, n, k, l)
                ktc = G[oKt + k, l]
                # the stiffness of an open contact is not used (its history becomes 0)
                kt = ktc * math.sqrt(radius_depth(d, G, P, FL, on, n, k, l)) \
                    if mindlin and held else ktc
                Ra = G[oR + k, l]
                Rb = G[oR + k + 1, l]
                wk = y[ow + k, l]
                wk1 = y[ow + k + 1, l]
                w = Ra * (wk + wk1) if Ra == Rb else Ra * wk + Rb * wk1
                # the Coulomb cap on Fncrit (LAMMPS's; |F| unless a law says otherwise)
                xi = contact_map(y[ot + k, l] + w * hist_dt, kt, mu * normal_crit(fn, d, G, P, FL, on, n, k, l))
                y[ot + k, l] = xi if held else 0.0
        for l in range(L):
            fn = f[k, l]
            d = overlap(y, ox, G, k, l)
            loaded = touching(d, y, LO, G, P, FL, on, n, k, l)
            ktc = G[oKt + k, l]
            # an open contact's T is not used
            kt = ktc * math.sqrt(radius_depth(d, G, P, FL, on, n, k, l)) \
                if mindlin and loaded else ktc
            Ra = G[oR + k, l]
            Rb = G[oR + k + 1, l]
            wk = y[ow + k, l]
            wk1 = y[ow + k + 1, l]
            # slip R_k omega_k + R_k+1 omega_k+1 (LAMMPS: radi omega_i + radj omega_j)
            w = Ra * (wk + wk1) if Ra == Rb else Ra * wk + Rb * wk1
            T, rate = contact_force(y[ot + k, l], w, kt, mu * normal_crit(fn, d, G, P, FL, on, n, k, l))
            # LAMMPS applies the tangential force at the contact point: lever arm
            # R_i - delta/2 on each sphere (the slip above uses full radii, as LAMMPS
            # does)
            arm = Ra - 0.5 * d
            arm1 = Rb - 0.5 * d
            tq = arm * T / G[oI + k, l]
            tq1 = arm1 * T / G[oI + k + 1, l]
            pw = T * arm * (wk + wk1) if Ra == Rb else T * (arm * wk + arm1 * wk1)
            dy[ot + k, l] = rate if loaded else 0.0
            a = dy[ow + k, l]
            dy[ow + k, l] = a + tq if loaded else a
            a = dy[ow + k + 1, l]
            dy[ow + k + 1, l] = a + tq1 if loaded else a
            a = dy[owt, l]
            dy[owt, l] = a + pw if loaded else a


@compiled
def project(y, G, P, FL, LO):
    """Return mapping of the contact histories onto mu_pp |F| (zero on an open contact)."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    ot = LO[S.L_PARTICLE_HIST]
    mu = P[S.P_PARTICLE_MU]
    oKt = S.G_PARTICLE_SPRING * n
    mindlin = FL[S.F_PARTICLE_MINDLIN] != 0
    on = switches(FL)
    for k in range(n - 1):
        if not any_touching(y, ox, LO, G, P, FL, on, n, k, L):
            for l in range(L):
                y[ot + k, l] = 0.0
            continue
        for l in range(L):
            d = overlap(y, ox, G, k, l)
            held = touching(d, y, LO, G, P, FL, on, n, k, l)
            ktc = G[oKt + k, l]
            kt = ktc * math.sqrt(radius_depth(d, G, P, FL, on, n, k, l)) \
                if mindlin and held else ktc
            xi = contact_map(y[ot + k, l], kt, normal_cap(mu, y, G, P, FL, on, ov, n, k, l, d))
            y[ot + k, l] = xi if held else 0.0


@dataclass(frozen=True)
class ParticleFriction:
    mu: float
    model: str        # "mindlin" | "linear_history"
    kt: float         # linear_history: k_t (N/m); mindlin: 8 G_eff sqrt(R*) (N/m^1.5)
    G_eff: float
    # each contact's k_t (its spheres' materials and radii; the scalars above are two
    # beads'): mindlin mixes 1/G_eff = 2(2-nu_i)(1+nu_i)/E_i + 2(2-nu_j)(1+nu_j)/E_j and
    # R* = R_i R_j/(R_i + R_j), as LAMMPS's mix_stiffnessG
    kt_each: tuple[float, ...] = ()


def shear_mix(a, b) -> float:
    """G* (Pa) of materials a and b, as LAMMPS's ``mix_stiffnessG``:
    1/G* = 2(2 - nu_a)(1 + nu_a)/E_a + 2(2 - nu_b)(1 + nu_b)/E_b (Mindlin's k_t = 8 G* a)."""
    return 1.0 / (2.0 * (2.0 - a.nu) * (1.0 + a.nu) / a.E + 2.0 * (2.0 - b.nu) * (1.0 + b.nu) / b.E)


def _mindlin(a, Ra, b, Rb) -> float:
    if a == b and Ra == Rb:
        return 8.0 * (a.G / (2.0 * (2.0 - a.nu))) * math.sqrt(Ra / 2.0)
    return 8.0 * shear_mix(a, b) * math.sqrt(Ra * Rb / (Ra + Rb))


def build(scene) -> ParticleFriction:
    st = scene.setting(SPEC.name)
    mat = scene.material
    G_eff = mat.G / (2.0 * (2.0 - mat.nu))
    if st.tangential == "mindlin":
        kt = 8.0 * G_eff * math.sqrt(scene.radius / 2.0)
        each = tuple(_mindlin(scene.materials[k], scene.radii[k], scene.materials[k + 1],
                              scene.radii[k + 1]) for k in range(scene.n - 1)) \
            if scene.heterogeneous else (kt,) * (scene.n - 1)
    else:
        kt = st.kt
        each = (kt,) * (scene.n - 1)
    return ParticleFriction(st.mu_pp, st.tangential, kt, G_eff, each)


def rows(pf: ParticleFriction, chain) -> dict:
    """Per-contact rows of the kernels' per-chain array (the wall contact has no
    tangential friction)."""
    return {"G_PARTICLE_SPRING": pf.kt_each + (0.0,)}


def kernel(pf: ParticleFriction) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return ({"P_PARTICLE_MU": pf.mu, "P_PARTICLE_SPRING": pf.kt},
            {"F_PARTICLE_FRICTION": 1, "F_PARTICLE_MINDLIN": int(pf.model == "mindlin")})


def error_scale(pf: ParticleFriction, terms, delta: float, v: float) -> float:
    """Absolute error scale of the contact histories for the adaptive method: the peak
    overlap delta (m)."""
    return delta


def lammps(pf: ParticleFriction | None, deck) -> DeckPart:
    """pair granular's tangential sub-model: the same law, or a zero one when off (k_t = 0,
    mu = 0: the force -k_t xi is exactly zero, and the cap test 0 > 0 never fires, so no
    division by k_t). ``mindlin NULL`` takes k = 8 G* a from the pair's E and nu, right for
    one material; an unlike pair gets its k = 8 G* from both materials (:func:`shear_mix`:
    LAMMPS's own mixing would derive it from the mixed E* and the mean nu)."""
    if pf is None:
        return DeckPart(pair={"tangential": "tangential linear_history 0.0 0.0 0.0"},
                        notes={"tangential": "# tangential: particle_friction off -> "
                                             "linear_history k_t = 0, mu = 0: zero tangential "
                                             "force"})
    note = {"tangential": f"# tangential: particle_friction on, {pf.model} (mu_pp = {_r(pf.mu)})"}
    if pf.model != "mindlin":
        return DeckPart(pair={"tangential": f"tangential linear_history "
                                            f"{_r(to_micro(pf.kt, 'stiffness'))} 0.0 {_r(pf.mu)}"},
                        notes=note)
    return DeckPart(
        pair={"tangential": f"tangential mindlin NULL 0.0 {_r(pf.mu)}"}, notes=note,
        unlike=lambda a, b: {"tangential": f"tangential mindlin "
                                           f"{_r(to_micro(8.0 * shear_mix(a, b), 'pressure'))} "
                                           f"0.0 {_r(pf.mu)}"},
        unlike_notes=("# Mindlin stiffness of an unlike pair given explicitly, k = 8 G*_IJ with "
                      "1/G*_IJ =", "# 2(2-nu_I)(1+nu_I)/E_I + 2(2-nu_J)(1+nu_J)/E_J (LAMMPS's own "
                      "mixing would derive it", "# from the mixed E*_IJ)."))
