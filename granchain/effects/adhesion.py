"""adhesion: LAMMPS ``pair_style granular``'s cohesive normal laws ``dmt`` and ``jkr``.

The laws of LAMMPS 22 Jul 2025 (``gran_sub_mod_normal.cpp``, ``granular_model.cpp``),
with gamma the scene's ``adhesion.surface_energy`` (LAMMPS's cohesion coefficient; the work
of adhesion is 2 gamma), E* and R* each contact's (the end wall's: R* = R_n), at overlap
delta (m):

- ``dmt``: F = K delta^(3/2) - F_po, F_po = 4 pi gamma R*, while delta > 0 (the Hertz
  contact radius a = sqrt(R* delta)); the force jumps to -F_po at first touch and back to 0
  when the contact opens.
- ``jkr``: F = (4/3) E* a^3 / R* - 4 a sqrt(pi gamma E* a), a the JKR contact radius,
  the root of delta = a^2/R* - 2 sqrt(pi gamma a / E*). A contact closes at delta > 0
  (the force jumps to -(8/9) F_po there) and, once closed, stays closed in tension down to
  the pull-off distance delta = -delta_po, delta_po = (3 pi^2 / 16)^(1/3) (R* gamma^2 /
  E*^2)^(1/3), where F reaches its least value -F_po, F_po = 3 pi gamma R*; beyond it the
  contact opens (the force jumps to 0) and closes again only at delta > 0. The contact's
  state (closed or not) is a per-contact block of the state, 1 or 0 (entry n-1: the end
  wall's), updated as LAMMPS does in each force call (velocity Verlet) or after each step
  (the other methods). The end wall's recorded force is the law's, tensile (< 0) while
  the wall holds the sphere closed at delta <= 0 (:func:`history_normal`; LAMMPS's fix
  wall/gran reports the same); the wall's peak force stays the largest compressive one.
  With contact damping the LAMMPS engine evaluates the wall's law at each sample's x and
  v (the damping of the JKR radius included) in the closed state fix wall/gran reports
  there (its per-atom contact flag, ``EffectSpec.lammps_wall_state``).

With ``t_end: auto`` the run waits until each contact's outcome is decided
(:func:`bond`, the ``bond`` hook): a contact held closed (at d > 0, or a jkr contact in
tension above the pull-off distance) is captured when the energy of its spheres' relative
motion is below the work the law takes from it on the way to the opening
(:func:`opening_work`), undecided otherwise; the run does not stop while one is
undecided (``granchain.stoprule``).

Tabor's parameter of each contact and the adhesion map, which ``granchain validate``
prints and warns by (:func:`validate_notes`, :func:`validate_warnings`), are in
``effects.adhesion_theory``, beside the pull-off laws.

With ``groove: true`` each sphere also adheres to the groove's two flats, whose pull-off
(a sphere on a flat of its own material) adds to the groove's normal load in
``groove_friction``'s Coulomb limit on both engines (:func:`groove_load`). The damping of
``contact_damping`` adds to F; LAMMPS allows only ``viscoelastic`` (no ``limit_damping``)
with a cohesive law, and so does the scene.

A contact touches, for every sub-law, where LAMMPS's touch test says so
(``granular_model.cpp``'s check_contact, ``GranSubModNormalJKR::touch``): while delta > 0,
and for jkr also while a contact closed before is held closed in tension (-delta_po <
delta <= 0). On a touching contact, whatever the sign of delta, LAMMPS's
``GranularModel::calculate_forces`` takes the normal law's contact radius a (jkr's root;
dmt's sqrt(R* delta)) for F_ne, for ``viscoelastic``'s damping -eta_n0 m_eff a v_n
(:func:`normal`, :func:`jkr_net`) and for ``mindlin``'s stiffness 8 G_eff a
(:func:`contact_depth`); Fncrit = |F_ne + 2 F_po| caps the tangential and rolling laws
(:func:`contact_crit`), whose histories are kept while the contact touches.

So a jkr contact held closed in tension carries F_ne < 0, the damping of its JKR radius,
and the friction and rolling laws, capped by |F_ne + 2 F_po| (:func:`contact_held` tells
the friction laws, through ``spec.touching``). The end wall has no friction or rolling
law; its damping follows the same rule. The work the adhesive part of the force (the
law's force less Hertz's) does on the particles is the ledger's ``work_adhesion``; the
energy JKR loses at each pull-off (its hysteresis) shows there. LAMMPS has no per-atom
output of it (its ledger closes by construction).

The event method crosses each jump of the force (touch, dmt's opening, jkr's pull-off) in
a step of its own (:func:`locate`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..materials import effective_modulus
from ..units import lmp_float as _r, to_micro
from ..validate import Fit, Key, short
from . import slots as S
from .adhesion_theory import (contact_mus, jkr_work, pulloff_distance, pulloff_force,
                              regime_warnings, tabor_note, well_depth)
from .hertz import energy as hertz_energy, force as hertz_force
from .lanes import bit, closing_speed, contact_overlap
from .contact_damping import radius_damping
from .spec import (BOND_CAPTURED, BOND_NONE, BOND_UNDECIDED, DeckPart, EffectSpec, compiled,
                   hermite_root)

SPEC = EffectSpec("adhesion", state=(("L_ADHESION_TOUCH", "particle"),),
                  lammps_wall_state="L_ADHESION_TOUCH",
                  work="work_adhesion", work_slot="L_WORK_ADHESION",
                  table_column="work_adhesion_J",
                  work_note="the adhesive part of the normal force (the dmt or jkr law less "
                            "Hertz's)", lammps_reports_work=False,
                  params=("P_ADHESION_GAMMA",), flags=("F_ADHESION", "F_ADHESION_JKR"),
                  rows=("G_ADHESION_RSTAR", "G_ADHESION_EMIX"), step_cost=8.1)  # JKR's

MODELS = ("dmt", "jkr")
SECTION = "adhesion"
DEFAULTS = {"model": None, "surface_energy": None, "groove": False}
# the section stays out of a scene's normalised spec (and hash) unless the effect is on
# or a key of it is given
SECTION_OPTIONAL = True
KEYS = (
    Key("adhesion.model", "-", "LAMMPS `pair granular`'s cohesive normal law at the contacts "
        "and the end wall, in place of Hertz: `dmt`, F = K delta^(3/2) - 4 pi gamma R* while "
        "delta > 0; `jkr`, the JKR force of the JKR contact radius, held closed in tension "
        "down to LAMMPS's pull-off distance once touched (pull-off force 3 pi gamma R*). "
        "Required with the effect. The work of the adhesive part is the ledger's "
        "`work_adhesion` (table column `work_adhesion_J`).", choices=MODELS),
    Key("adhesion.surface_energy", "J/m^2", "gamma, LAMMPS's cohesion coefficient of `dmt` "
        "and `jkr` (the surface energy; the work of adhesion is 2 gamma). Required with the "
        "effect. Fittable: log-uniform prior "
        "from 1e-3 to 1 J/m^2.", positive=True, hi=100.0,
        fit=Fit(1e-3, 1.0, 10, "surface_energy", "gamma", "surface energy",
                example="adhesion: {model: jkr, surface_energy: 0.05}")),
    Key("adhesion.groove", "-", "`true`: each sphere also adheres to the two flats of the "
        "groove, and their pull-off (per flat 3 pi gamma R for `jkr`, 4 pi gamma R for "
        "`dmt`: a sphere on a flat) adds to the groove's normal load, Fc = mu (m g / s + "
        "2 F_po); needs `groove_friction`. The stick spring stays the Mindlin stiffness "
        "under the weight alone.", allowed="`true` or `false`"),
)
_KEY = {k.name: k for k in KEYS}
# the section of the engines' warm-up scene (every effect on; the kernels are the same
# for both models)
WARM_UP = {"model": "dmt", "surface_energy": 0.1}


@dataclass(frozen=True)
class Settings:
    model: str | None
    surface_energy: float | None   # J/m^2
    groove: bool = False           # the groove's flats adhere too (groove_load)


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``adhesion`` section; ``on``: whether the effect is enabled."""
    model = None if sec["model"] is None else _KEY["model"].choice(sec["model"], "model")
    gamma = _KEY["surface_energy"].number(sec["surface_energy"], allow_none=True,
                                          fix="give the surface energy gamma in J/m^2, > 0")
    if on and model is None:
        raise SceneError("adhesion.model", "missing", "give model: jkr or dmt")
    if on and gamma is None:
        raise SceneError("adhesion.surface_energy", "missing",
                         "give the surface energy gamma in J/m^2 (LAMMPS's cohesion)")
    groove = sec["groove"]
    if not isinstance(groove, bool):
        raise SceneError("adhesion.groove", f"expected true or false, got {short(groove)}",
                         "write groove: true or false")
    return Settings(model, gamma, groove)


# the effects jkr does not act with (none: a contact held closed in tension carries the
# damping and the friction laws on both engines, as in LAMMPS)
JKR_NOT_WITH: tuple[str, ...] = ()


def not_with(model: str) -> tuple[str, ...]:
    """The effects the law ``model`` does not act with (the adhesion study leaves them out
    of its scenes): jkr's ``JKR_NOT_WITH``, none for dmt."""
    return JKR_NOT_WITH if model == "jkr" else ()


def check(scene) -> None:
    """What LAMMPS refuses beside a cohesive normal law: damping other than
    ``viscoelastic`` or with ``limit_damping``; and adhesion to the groove without the
    groove friction."""
    st = scene.setting(SPEC.name)
    if st.groove and not scene.has("groove_friction"):
        raise SceneError("adhesion.groove", "has no groove friction to load (groove_friction "
                         "is off)", "add groove_friction to effects, or drop adhesion.groove")
    if scene.has("contact_damping"):
        cd = scene.setting("contact_damping")
        if cd.model != "viscoelastic":
            raise SceneError("damping.model", f"{cd.model} cannot act with adhesion (LAMMPS "
                             "refuses it beside a cohesive normal law)",
                             "use damping model viscoelastic, or drop adhesion")
        if cd.limit_damping:
            raise SceneError("damping.limit_damping", "cannot act with adhesion (LAMMPS "
                             "refuses it beside a cohesive normal law)",
                             "write limit_damping: false, or drop adhesion")
    other = [e for e in not_with(st.model) if scene.has(e)]
    if other:
        raise SceneError("adhesion.model", f"{st.model} with {', '.join(other)} is not "
                         "implemented", f"use model dmt, or drop {', '.join(other)}")


# ---------------------------------------------------------------------------------------
# the laws
@compiled
def jkr_radius(Rs, E, g, d):
    """The JKR contact radius a (m) of a contact of R* (m), E* (Pa), gamma (J/m^2) at
    overlap d (m): the largest root of d = a^2/R* - 2 sqrt(pi g a / E*). With s = sqrt(a),
    s^4 - 2 c R* s - d R* = 0 (c = sqrt(pi g / E*)), solved by Ferrari's resolvent cubic
    m^3 + 3 B m - 2 A = 0 (A = c^2 R*^2 / 4, B = d R* / 3), whose real root is written
    2A / (u^2 + B + B^2/u^2), u^3 = A + sqrt(A^2 + B^3), free of cancellation."""
    c = math.sqrt(math.pi * g / E)
    A = 0.25 * c * c * Rs * Rs
    B = d * Rs / 3.0
    disc = A * A + B * B * B
    u = (A + math.sqrt(disc if disc > 0.0 else 0.0)) ** (1.0 / 3.0)
    m = 2.0 * A / (u * u + B + B * B / (u * u))
    q = math.sqrt(2.0 * m)
    t = 4.0 * c * Rs / q - 2.0 * m
    s = 0.5 * (q + math.sqrt(t if t > 0.0 else 0.0))
    return s * s


@compiled
def jkr_force_at(Rs, E, g, a):
    """The JKR force (N, > 0 repulsive) of contact radius a: (4/3) E* a^3 / R* - 4 a
    sqrt(pi g E* a)."""
    return (4.0 / 3.0) * E * a * a * a / Rs - 4.0 * a * math.sqrt(math.pi * g * E * a)


@compiled
def jkr_force(Rs, E, g, d):
    """The JKR force (N, > 0 repulsive) at overlap d: :func:`jkr_force_at` of a =
    :func:`jkr_radius`."""
    return jkr_force_at(Rs, E, g, jkr_radius(Rs, E, g, d))


@compiled
def closed(d, was, Rs, E, g, jkr):
    """Is a contact of overlap d closed, given whether it was (LAMMPS's touch test)?"""
    if d > 0.0:
        return True
    return jkr and was and d > -pulloff_distance(Rs, E, g)


@compiled
def law(K, Rs, E, g, jkr, d):
    """The force F_ne (N) of a closed contact: the jkr or dmt law."""
    if jkr:
        return jkr_force(Rs, E, g, d)
    return hertz_force(K, d) - pulloff_force(Rs, g, False)


# The compiled parts the engines compose (``spec.HOOKS``): each contact's R* and E* are
# rows G_ADHESION_RSTAR and G_ADHESION_EMIX (the end wall's last), its closed state block
# L_ADHESION_TOUCH (entry n-1: the end wall's).
@compiled
def normal(y, G, P, FL, LO, dy, f, shut):
    """f of every closed contact becomes the law's force: dmt's added to the Hertz force
    and damping before it; jkr's F_ne (of the JKR contact radius a) plus, with contact
    damping, the viscoelastic force of that a (which replaces the damping of Hertz's
    radius, and so its work), also on a contact held closed in tension, which is then no
    longer shut; the work rate of the adhesive part."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    ot = LO[S.L_ADHESION_TOUCH]
    owa = LO[S.L_WORK_ADHESION]
    owc = LO[S.L_WORK_DAMPING]
    wall = FL[S.F_END_WALL] != 0
    jkr = FL[S.F_ADHESION_JKR] != 0
    damped = FL[S.F_CONTACT_DAMPING] != 0
    g = P[S.P_ADHESION_GAMMA]
    oK = S.G_HERTZ_K * n
    oR = S.G_ADHESION_RSTAR * n
    oE = S.G_ADHESION_EMIX * n
    for l in range(L):
        dy[owa, l] = 0.0
    for k in range(n):
        for l in range(L):
            dy[ot + k, l] = 0.0
    for k in range(n if wall else n - 1):
        if bit(shut, k) and not jkr:
            continue
        held = 0
        if jkr:
            for l in range(L):
                d = contact_overlap(y, ox, G, n, k, l)
                w = closing_speed(y, ov, n, k, l)
                Rs = G[oR + k, l]
                E = G[oE + k, l]
                on = closed(d, y[ot + k, l] != 0.0, Rs, E, g, True)
                if not on:          # open: f and the work rates stay, the law unevaluated
                    continue
                held += 1
                F = f[k, l]
                H = hertz_force(G[oK + k, l], d)
                a = jkr_radius(Rs, E, g, d)
                Fne = jkr_force_at(Rs, E, g, a)
                Fd = radius_damping(a, w, G, P, n, k, l) if damped else 0.0
                f[k, l] = Fne + Fd
                Fa = Fne - H
                c = dy[owa, l]
                dy[owa, l] = c - Fa * w
                if damped:
                    # the damping before (of Hertz's radius, d > 0) becomes Fd
                    c = dy[owc, l]
                    dy[owc, l] = c - (Fd - (F - H)) * w
        else:
            for l in range(L):
                d = contact_overlap(y, ox, G, n, k, l)
                w = closing_speed(y, ov, n, k, l)
                K = G[oK + k, l]
                on = d > 0.0
                held += 1 if on else 0
                F = f[k, l]
                Fa = (law(K, G[oR + k, l], G[oE + k, l], g, False, d) - hertz_force(K, d)) \
                    if on else 0.0
                f[k, l] = F + Fa
                c = dy[owa, l]
                dy[owa, l] = c - Fa * w
        if held > 0 and k < 63:
            shut &= ~(1 << k)
    return shut


@compiled
def forces(y, G, P, FL, LO, hist_dt, dy, f, shut):
    """Velocity Verlet (hist_dt > 0): each contact's closed state of this force call, for
    the next (LAMMPS keeps it per contact in each force call)."""
    if hist_dt > 0.0 and FL[S.F_ADHESION_JKR] != 0:
        _touch(y, G, P, FL, LO)


@compiled
def project(y, G, P, FL, LO):
    """After a step: each contact's closed state at the step's end."""
    if FL[S.F_ADHESION_JKR] != 0:
        _touch(y, G, P, FL, LO)


@compiled
def _touch(y, G, P, FL, LO):
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ot = LO[S.L_ADHESION_TOUCH]
    g = P[S.P_ADHESION_GAMMA]
    oR = S.G_ADHESION_RSTAR * n
    oE = S.G_ADHESION_EMIX * n
    for k in range(n):
        for l in range(L):
            d = contact_overlap(y, ox, G, n, k, l)
            on = closed(d, y[ot + k, l] != 0.0, G[oR + k, l], G[oE + k, l], g, True)
            y[ot + k, l] = 1.0 if on else 0.0


@compiled
def contact_normal(F, d, w, G, P, FL, n, k, l):
    """The force of contact k in lane l at overlap d > 0 (the end wall's, the caps), given
    F (Hertz's and the damping's): dmt's law added to F less Hertz's; jkr's F_ne and the
    viscoelastic damping of its contact radius (:func:`jkr_net`), in place of F. A jkr
    contact held closed in tension (d <= 0) is :func:`history_normal`'s."""
    if d <= 0.0:
        return F
    Rs = G[S.G_ADHESION_RSTAR * n + k, l]
    E = G[S.G_ADHESION_EMIX * n + k, l]
    g = P[S.P_ADHESION_GAMMA]
    if FL[S.F_ADHESION_JKR] != 0:
        return jkr_net(Rs, E, g, d, w, G, P, FL, n, k, l)
    K = G[S.G_HERTZ_K * n + k, l]
    return F + law(K, Rs, E, g, False, d) - hertz_force(K, d)


@compiled
def jkr_net(Rs, E, g, d, w, G, P, FL, n, k, l):
    """The net normal force of a closed jkr contact k in lane l at overlap d, closing at
    w: F_ne plus, with contact damping, eta_n0 m_eff a w of the JKR contact radius a
    (LAMMPS's viscoelastic damping takes the normal law's contact radius)."""
    a = jkr_radius(Rs, E, g, d)
    Fne = jkr_force_at(Rs, E, g, a)
    if FL[S.F_CONTACT_DAMPING] != 0:
        return Fne + radius_damping(a, w, G, P, n, k, l)
    return Fne


@compiled
def history_normal(F, d, y, LO, G, P, FL, n, k, l):
    """The force of contact k in lane l at overlap d <= 0 in the state y (the end wall's
    recorded force): the jkr law's tensile force while the contact is held closed (its
    closed state in y, as the last force call or step left it, and d above the pull-off
    distance), F otherwise (and at d > 0, where :func:`contact_normal` gave the law)."""
    if d > 0.0 or FL[S.F_ADHESION_JKR] == 0:
        return F
    Rs = G[S.G_ADHESION_RSTAR * n + k, l]
    E = G[S.G_ADHESION_EMIX * n + k, l]
    g = P[S.P_ADHESION_GAMMA]
    if not closed(d, y[LO[S.L_ADHESION_TOUCH] + k, l] != 0.0, Rs, E, g, True):
        return F
    return F + jkr_net(Rs, E, g, d, closing_speed(y, LO[S.L_VEL], n, k, l), G, P, FL, n, k, l)


@compiled
def contact_held(d, y, LO, G, P, FL, n, k, l):
    """Is contact k in lane l at overlap d closed (``spec.touching``): LAMMPS's touch of a
    jkr contact, from its closed state in y (held closed in tension down to the pull-off
    distance); d > 0 for dmt."""
    if FL[S.F_ADHESION_JKR] == 0:
        return d > 0.0
    return closed(d, y[LO[S.L_ADHESION_TOUCH] + k, l] != 0.0, G[S.G_ADHESION_RSTAR * n + k, l],
                  G[S.G_ADHESION_EMIX * n + k, l], P[S.P_ADHESION_GAMMA], True)


@compiled
def contact_depth(d, G, P, FL, n, k, l):
    """The overlap a^2 / R* of contact k's contact radius a at overlap d: jkr's radius
    (LAMMPS's Mindlin stiffness 8 G_eff a takes the normal law's contact radius); d for
    dmt (a = sqrt(R* d))."""
    if FL[S.F_ADHESION_JKR] == 0:
        return d
    Rs = G[S.G_ADHESION_RSTAR * n + k, l]
    a = jkr_radius(Rs, G[S.G_ADHESION_EMIX * n + k, l], P[S.P_ADHESION_GAMMA], d)
    return a * a / Rs


@compiled
def bond(y, G, P, FL, LO, n, k, l):
    """Contact k of lane l (n-1: the end wall, of infinite mass): BOND_NONE while the law
    does not hold it closed (:func:`closed` of its closed state in y); held, BOND_CAPTURED
    when the energy of its spheres' relative motion, (1/2) m* w^2 (m* their reduced mass,
    w the closing speed), is less than the law takes from it on the way to the opening
    (-:func:`opening_work`): no adhesive contact parts without that energy, and damping
    only takes more; BOND_UNDECIDED otherwise."""
    d = contact_overlap(y, LO[S.L_DISP], G, n, k, l)
    Rs = G[S.G_ADHESION_RSTAR * n + k, l]
    E = G[S.G_ADHESION_EMIX * n + k, l]
    g = P[S.P_ADHESION_GAMMA]
    jkr = FL[S.F_ADHESION_JKR] != 0
    if not closed(d, y[LO[S.L_ADHESION_TOUCH] + k, l] != 0.0, Rs, E, g, jkr):
        return BOND_NONE
    w = closing_speed(y, LO[S.L_VEL], n, k, l)
    m = G[S.G_MASS * n + k, l]
    if k < n - 1:
        m2 = G[S.G_MASS * n + k + 1, l]
        m = m * m2 / (m + m2)
    phi = opening_work(G[S.G_HERTZ_K * n + k, l], Rs, E, g, jkr, d)
    return BOND_CAPTURED if 0.5 * m * w * w + phi < 0.0 else BOND_UNDECIDED


@compiled
def contact_crit(F, d, G, P, FL, n, k, l):
    """LAMMPS's cohesive Fncrit = |F_ne + 2 F_po| of contact k at overlap d (F_ne the law's
    force, without the damping force)."""
    Rs = G[S.G_ADHESION_RSTAR * n + k, l]
    g = P[S.P_ADHESION_GAMMA]
    jkr = FL[S.F_ADHESION_JKR] != 0
    Fne = law(G[S.G_HERTZ_K * n + k, l], Rs, G[S.G_ADHESION_EMIX * n + k, l], g, jkr, d)
    return abs(Fne + 2.0 * pulloff_force(Rs, g, jkr))


@compiled
def locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau):
    """The event method's switches of the law, where its force jumps: a contact not
    closed at the step's start touches (its overlap rises through 0: the force jumps to
    -(8/9) F_po for jkr, to -F_po for dmt), a dmt contact opens (its overlap falls
    through 0), a jkr contact held closed pulls off (its overlap falls through
    -delta_po). A step that jumps is not one the Runge-Kutta pair integrates to its
    order (its stages on either side of the jump disagree), so a jump is crossed in a
    step of its own: a trial step that crosses one from further than the band before it
    is cut to end half a band before it, and one that starts within the band before it
    and ends more than a band past it, to end half a band past it (a step of about a band
    over the closing speed; one that ends within the band past it stands). The band
    is rtol times the contact's pull-off distance delta_po, the length of either law
    (DMT's overlap where its force vanishes is 3.1 times it).

    Per lane l with act[l], tau[l] the first tau in (0, 1) at which the lane's trial
    step y -> ynew of length h[l] is to end, -1 if none (and in every lane without
    act[l]). The test runs over all lanes at once (no branch per lane); the roots (of
    the cubic Hermite of the overlap on the step) are found only in the lanes where a
    jump is crossed."""
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    ot = LO[S.L_ADHESION_TOUCH]
    jkr = FL[S.F_ADHESION_JKR] != 0
    dmt = not jkr
    g = P[S.P_ADHESION_GAMMA]
    m = n if FL[S.F_END_WALL] != 0 else n - 1
    for l in range(L):
        tau[l] = -1.0
    for k in range(m):
        for l in range(L):
            d0 = contact_overlap(y, ox, G, n, k, l)
            d1 = contact_overlap(ynew, ox, G, n, k, l)
            turn = (closing_speed(y, ov, n, k, l) > 0.0) & (closing_speed(ynew, ov, n, k, l) < 0.0)
            po = pulloff_distance(G[S.G_ADHESION_RSTAR * n + k, l],
                                  G[S.G_ADHESION_EMIX * n + k, l], g)
            held = jkr & (y[ot + k, l] != 0.0)
            free = not held
            touch = free & (d0 <= 0.0) & ((d1 > 0.0) | turn)
            opens = dmt & (d0 > 0.0) & (d1 <= 0.0)
            pulls = held & (d0 > -po) & (d1 <= -po)
            tau[l] = 1.0 if (touch | opens | pulls) else tau[l]
    for l in range(L):
        if tau[l] > 0.0 and act[l]:
            tau[l] = _switch_time(y, ynew, G, n, m, h[l], rtol, ox, ov, ot, jkr, g, l)
        else:
            tau[l] = -1.0


@compiled
def _switch_time(y, ynew, G, n, m, h, rtol, ox, ov, ot, jkr, g, l):
    """Where the trial step of lane l is to end (``locate``), -1 if it may stand."""
    best = 2.0
    for k in range(m):
        d0 = contact_overlap(y, ox, G, n, k, l)
        d1 = contact_overlap(ynew, ox, G, n, k, l)
        w0 = closing_speed(y, ov, n, k, l)
        w1 = closing_speed(ynew, ov, n, k, l)
        po = pulloff_distance(G[S.G_ADHESION_RSTAR * n + k, l], G[S.G_ADHESION_EMIX * n + k, l],
                              g)
        band = rtol * po
        held = jkr and y[ot + k, l] != 0.0
        t = -1.0
        up = True
        s = po                  # the overlap of the jump crossed (none: po)
        if not held and d0 <= 0.0 and (d1 > 0.0 or (w0 > 0.0 and w1 < 0.0)):
            s = 0.0             # touch
        elif not jkr and d0 > 0.0 and d1 <= 0.0:
            s, up = 0.0, False  # dmt's opening
        elif held and d0 > -po and d1 <= -po:
            s, up = -po, False  # jkr's pull-off
        sg = 1.0 if up else -1.0
        if s < po and sg * (s - d0) > band:
            t = hermite_root(d0, w0, d1, w1, h, s - 0.5 * sg * band, up)
        elif s < po and hermite_root(d0, w0, d1, w1, h, s + sg * band, up) > 0.0:
            # from within the band: past the jump unless the step ends within a band
            # past it (a step cut to end half a band past it may end a rounding beyond;
            # cut again, its length would not change)
            t = hermite_root(d0, w0, d1, w1, h, s + 0.5 * sg * band, up)
        if t > 0.0 and t < best:
            best = t
    return best if best < 1.0 else -1.0


@compiled
def opening_work(K, Rs, E, g, jkr, d):
    """Phi (J): the work the law's force does on the relative motion of a contact held
    closed at overlap d (m) from d to where it opens (dmt: 0; jkr: the pull-off distance
    -delta_po), Phi = int_{d_open}^d F ds (negative: its spheres need that much energy of
    relative motion to part); 0 at or beyond the opening."""
    if not jkr:
        return hertz_energy(K, d) - pulloff_force(Rs, g, False) * d if d > 0.0 else 0.0
    d_open = -pulloff_distance(Rs, E, g)
    if d <= d_open:
        return 0.0
    return jkr_work(Rs, E, g, jkr_radius(Rs, E, g, d)) - jkr_work(Rs, E, g,
                                                                  jkr_radius(Rs, E, g, d_open))


def separation(ad, chain, k: int, d: float) -> tuple[float, float]:
    """(d_open, Phi) of contact k (spheres k+1, k+2; 1-based) held closed at overlap d (m):
    where it opens (dmt: 0; jkr: the pull-off distance -delta_po) and
    :func:`opening_work`."""
    R, mats = chain.radii, chain.materials
    Rs = 0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
    E = effective_modulus(mats[k], mats[k + 1])
    jkr = ad.model == "jkr"
    d_open = -pulloff_distance(Rs, E, ad.gamma) if jkr else 0.0
    return d_open, opening_work(chain.K[k], Rs, E, ad.gamma, jkr, d)


def touch_energy(ad, chain) -> float:
    """The most energy (J) the adhesive contacts can give the spheres' motion: each
    contact's :func:`well_depth` (a contact gives it once on touching and takes at least
    as much back to open), summed over the sphere contacts and the end wall."""
    r = rows(ad, chain)
    K = tuple(chain.K) + ((chain.K_wall,) if chain.wall is not None else ())
    return sum(well_depth(ad.model, K[k], r["G_ADHESION_RSTAR"][k], r["G_ADHESION_EMIX"][k],
                          ad.gamma) for k in range(len(K)))


# ---------------------------------------------------------------------------------------
# Tabor's parameter and the groove's pull-off
def contacts(scene) -> list[tuple[str, float]]:
    """(name, Tabor's mu) of a scene's adhesive contacts, alike ones merged
    (:func:`~granchain.effects.adhesion_theory.contact_mus`)."""
    from .chain import build as chain_build
    st = scene.setting(SPEC.name)
    chain = chain_build(scene)
    return contact_mus(rows(Adhesion(st.model, st.surface_energy, st.groove), chain), chain,
                       st.surface_energy, st.groove)


def validate_notes(scene) -> list[str]:
    """``granchain validate``'s lines: each adhesive contact's Tabor parameter."""
    st = scene.setting(SPEC.name)
    return [tabor_note(st.model, st.surface_energy, contacts(scene))]


def validate_warnings(scene) -> list[str]:
    """``granchain validate``'s warnings: contacts where the chosen model is outside its
    regime on the adhesion map (:func:`~granchain.effects.adhesion_theory.regime`)."""
    return regime_warnings(scene.setting(SPEC.name).model, contacts(scene))


def groove_load(scene, radius: float) -> float:
    """The groove's extra normal load (N) on a sphere of ``radius`` (m): the pull-off of
    its two sphere-flat contacts with the groove, 2 x (3 pi gamma R (jkr) or 4 pi gamma R
    (dmt)) with ``adhesion.groove``, 0 without it or with the effect off: each flat's pull
    is balanced by its own contact force whatever the groove's angle."""
    if not scene.has(SPEC.name):
        return 0.0
    st = scene.setting(SPEC.name)
    if not st.groove:
        return 0.0
    return 2.0 * pulloff_force(radius, st.surface_energy, st.model == "jkr")


# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Adhesion:
    model: str            # "dmt" | "jkr"
    gamma: float          # J/m^2, LAMMPS's cohesion
    groove: bool = False  # the groove's flats adhere (groove_load)


def build(scene) -> Adhesion:
    st = scene.setting(SPEC.name)
    return Adhesion(st.model, st.surface_energy, st.groove)


def kernel(ad: Adhesion) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return {"P_ADHESION_GAMMA": ad.gamma}, {"F_ADHESION": 1,
                                            "F_ADHESION_JKR": int(ad.model == "jkr")}


def rows(ad: Adhesion, chain) -> dict:
    """Per-contact rows (the wall's last): R* and E* (the wall: R_n and the sphere's E* on
    the wall's material)."""
    R, mats = chain.radii, chain.materials
    n = len(R)
    rs = tuple(0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
               for k in range(n - 1)) + (R[-1],)
    es = tuple(effective_modulus(mats[k], mats[k + 1]) for k in range(n - 1)) + (
        effective_modulus(mats[-1], chain.wall) if chain.wall is not None else 1.0,)
    return {"G_ADHESION_RSTAR": rs, "G_ADHESION_EMIX": es}


def error_scale(ad: Adhesion, terms, delta: float, v: float) -> float:
    """The closed-state block is 0 or 1, and its rate 0."""
    return 1.0


def lammps(ad: Adhesion | None, deck) -> DeckPart:
    """The deck's normal law: ``dmt|jkr E <damp> nu gamma`` on every pair_coeff and on the
    end wall (gamma in 1e-3 N/m, LAMMPS 'units micro'), in place of hertz/material."""
    if ad is None:
        return DeckPart()
    gamma = _r(to_micro(ad.gamma, "stiffness"))
    law = (f"F = K delta^1.5 - 4 pi gamma R* while delta > 0" if ad.model == "dmt" else
           "F = 4/3 E* a^3/R* - 4 a sqrt(pi gamma E* a), a the JKR\n# contact radius; held "
           "closed in tension to the pull-off distance once touched")
    return DeckPart(
        pair={"normal": f"{ad.model} {{E}} {{damp}} {{nu}} {gamma}"},
        notes={"normal": f"# adhesion (effects/adhesion.py): {ad.model}, gamma = {_r(ad.gamma)} "
                         f"J/m^2 = {gamma} (1e-3 N/m):\n# {law}. Caps: Fncrit = |F + 2 F_po|."
                         f"\n# pair_coeff: {ad.model} E <damp> nu gamma"},
        contact=f"{ad.model.upper()} adhesion",
        wall_notes=(f"# adhesion at the wall: {ad.model} with the pairs' gamma, R* = R_n.",))
