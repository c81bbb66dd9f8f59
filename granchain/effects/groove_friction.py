"""groove_friction: Coulomb friction of the groove walls on every sphere.

Limit Fc = mu_pg N, N the normal load of the two walls: m g / s (each wall m g / (2 s),
s = sin(angle/2)), plus, with ``adhesion.groove``, the pull-off of the sphere's two
sphere-flat contacts (``adhesion.groove_load``: each flat's own pull adds to that flat's
load whatever the angle), on the slip u = v - s R omega (u = v if rotation is off: the
sphere slides without rolling). Stick is an elastic-plastic (Cundall-Strack)
spring-dashpot: F = -k_g xi - gamma_g u with xi' = u, and when |F| would exceed Fc the
force is Fc sgn(F) and the history is return-mapped to xi = -F/k_g: the spring alone
holds the cap and the dashpot is not stored (unlike LAMMPS ``linear_history``, whose
xi = -(F + gamma u)/k winds up a history during fast slides that later cancels the
friction while still sliding; sliding friction here is exactly Fc, tested against
-Fc * sum |slip|). gamma_g = 2 zeta sqrt(k_g m_u), zeta = groove.damping (default 1,
critical), with m_u = m / (1 + s^2 m R^2 / I) the mass the slip u sees: stick settles
within one period of the stick oscillator instead of ringing forever.

No sgn() of a velocity is ever evaluated, so nothing chatters; a sphere at rest or rolling
without slip feels exactly zero force. The chapter's F = -Fc sgn(u) is the limit
k_g -> inf. Default k_g: Mindlin stiffness of the two wall contacts under the static wall
load m g / (2 s) each: k_g = 2 * 8 G*_w a_w, a_w = (3 N R / (4 E*_w))^(1/3),
E*_w = E / (2 (1 - nu^2)), G*_w = G / (2 (2 - nu)) (sphere on a flat of the same steel).
Torque on the sphere: -s R F (with rotation on).

The same law, in C++, is ``fix groove/drag`` (lammps_inputs/plugin/fix_groove_drag.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..units import lmp_float as _r, to_micro
from ..validate import Key
from . import slots as S
from .adhesion import groove_load
from .lanes import clip_to_cap, moving
from .spec import DeckPart, EffectSpec, compiled, hermite_root

SPEC = EffectSpec("groove_friction", state=(("L_GROOVE_HIST", "particle"),),
                  work="work_groove_friction", work_slot="L_WORK_GROOVE",
                  table_column="work_groove_J", work_note="the groove friction", lammps_ledger="f_gd[2]",
                  params=("P_GROOVE_S", "P_GROOVE_LIMIT", "P_GROOVE_SPRING", "P_GROOVE_DASHPOT"),
                  flags=("F_GROOVE_FRICTION",),
                  rows=("G_GROOVE_LIMIT", "G_GROOVE_SPRING", "G_GROOVE_DASHPOT"))


# The scene section of this effect and its defaults: the chapter's mu_pg and g; s =
# sin(90deg/2) for a 90-degree groove (the thesis's Chapter 4, which fixes s, is not
# available); the Mindlin stick spring; critical damping.
SECTION = "groove"
DEFAULTS = {"s": None, "angle_deg": 90.0, "mu": 0.293, "g": 9.81, "kt": "mindlin",
            "damping": 1.0}
KEYS = (
    Key("groove.s", "1", "Groove geometry factor s = sin(opening angle / 2): the Coulomb limit "
        "is Fc = mu m g / s and the slip u = v - s R omega. null: from `groove.angle_deg`; "
        "refused together with it.", positive=True, hi=1.0),
    Key("groove.angle_deg", "deg", "Opening angle of the groove (s = sin(angle/2)). The "
        "default, a 90-degree groove (s = 0.7071), is assumed: the thesis's Chapter 4, which "
        "fixes s, is not available.", lo=1e-6, hi=180.0),
    Key("groove.mu", "1", "Coulomb coefficient mu_pg of the groove walls on every sphere; the "
        "default is the chapter's fit (its Chapter 4).", nonneg=True, hi=10.0),
    Key("groove.g", "m/s^2", "Gravitational acceleration, which loads the spheres onto the "
        "groove walls (at most 1000 g: beyond, the groove's forces overflow the steps).",
        nonneg=True, hi=1e4),
    Key("groove.kt", "N/m", "Stick spring k_g of the elastic-plastic (Cundall-Strack) groove "
        "contact. `mindlin`: the Mindlin stiffness of the two wall contacts under the static "
        "wall load m g / (2 s) each, k_g = 2 x 8 G*_w a_w (a sphere on a flat of its own "
        "material).", positive=True, allowed="or `mindlin`"),
    Key("groove.damping", "1", "Stick dashpot zeta as a fraction of critical damping (1: "
        "critical): gamma_g = 2 zeta sqrt(k_g m_u), m_u the mass the slip sees, so stick "
        "settles within one period of the stick oscillator instead of ringing.", nonneg=True),
)
_KEY = {k.name: k for k in KEYS}


@dataclass(frozen=True)
class Settings:
    s: float              # groove geometry factor, sin(opening angle / 2)
    mu: float             # Coulomb coefficient mu_pg
    g: float              # m/s^2
    kt: float | None      # stick spring (N/m); None: Mindlin stiffness from the material
    damping: float        # stick dashpot, fraction of critical


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``groove`` section (a merged mapping); ``given``: the dotted keys the
    scene wrote; ``on``: whether groove_friction is enabled."""
    if "groove.s" in given and "groove.angle_deg" in given:
        raise SceneError("groove.s", "given together with groove.angle_deg",
                         "give one of them (s = sin(angle/2))")
    if sec["s"] is not None:
        s = _KEY["s"].number(sec["s"], fix="the groove factor s lies in (0, 1]")
    else:
        ang = _KEY["angle_deg"].number(sec["angle_deg"],
                                       fix="give the groove opening angle in degrees (0, 180]")
        s = math.sin(math.radians(ang) / 2.0)
    mu = _KEY["mu"].number(sec["mu"])
    g = _KEY["g"].number(sec["g"])
    kt = None if sec["kt"] == "mindlin" else _KEY["kt"].number(
        sec["kt"], fix="give a stiffness in N/m or 'mindlin'")
    damping = _KEY["damping"].number(
        sec["damping"], fix="give the stick damping as a fraction of critical (default 1)")
    return Settings(s, mu, g, kt, damping)


@compiled
def slip(v, omega, sR, rot):
    """Slip velocity (m/s) of a sphere on the groove walls: v - s R omega."""
    return v - sR * omega if rot else v


@compiled
def groove_map(xi, u, kg, gam, Fc):
    """Return mapping of a groove history when the trial force -kg xi - gam u exceeds the
    Coulomb cap: the spring alone holds the cap (xi = Fc sgn / kg)."""
    Ft = -kg * xi - gam * u
    if abs(Ft) > Fc:
        return -math.copysign(Fc, Ft) / kg
    return xi


@compiled
def groove_force(xi, u, kg, gam, Fc):
    """(F, xi') of a groove contact: the capped spring-dashpot force (N) and the history
    rate (u in stick, 0 while sliding at the cap)."""
    F = -kg * xi - gam * u
    rate = 0.0 if (abs(F) >= Fc and F * u < 0.0) else u
    return clip_to_cap(F, Fc), rate


# The compiled parts the engines compose (``spec.HOOKS``): each sphere's Coulomb limit,
# spring and dashpot are rows G_GROOVE_LIMIT, G_GROOVE_SPRING, G_GROOVE_DASHPOT; its
# history block L_GROOVE_HIST. With rotation off the slip is v alone (the spin row read in
# its place is never used).
@compiled
def forces(y, G, P, FL, LO, hist_dt, dy, f, shut):
    """The groove's force (and torque -s R F with rotation on) on every sphere that moves
    or holds a history, its history rate and its work rate."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ov = LO[S.L_VEL]
    ow = LO[S.L_SPIN]
    rot = FL[S.F_ROTATION] != 0
    owr = ow if rot else ov
    oM = S.G_MASS * n
    oI = S.G_INERTIA * n
    oR = S.G_RADIUS * n
    s_g = P[S.P_GROOVE_S]
    oFc = S.G_GROOVE_LIMIT * n
    oKg = S.G_GROOVE_SPRING * n
    oGg = S.G_GROOVE_DASHPOT * n
    og = LO[S.L_GROOVE_HIST]
    owg = LO[S.L_WORK_GROOVE]
    for l in range(L):
        dy[owg, l] = 0.0
    for i in range(n):
        if not (moving(y, ov + i, L) or moving(y, og + i, L)
                or (rot and moving(y, ow + i, L))):
            for l in range(L):
                dy[og + i, l] = 0.0
            continue
        if hist_dt > 0.0:
            for l in range(L):
                sR = s_g * G[oR + i, l]
                u = slip(y[ov + i, l], y[owr + i, l], sR, rot)
                xi = groove_map(y[og + i, l] + u * hist_dt, u, G[oKg + i, l],
                                G[oGg + i, l], G[oFc + i, l])
                y[og + i, l] = xi
        for l in range(L):
            sR = s_g * G[oR + i, l]
            u = slip(y[ov + i, l], y[owr + i, l], sR, rot)
            # history rate: xi' = u in stick; held while sliding at the cap
            F, rate = groove_force(y[og + i, l], u, G[oKg + i, l], G[oGg + i, l],
                                   G[oFc + i, l])
            dy[og + i, l] = rate
            dy[ov + i, l] += F / G[oM + i, l]
            dy[owg, l] += F * u
            if rot:
                dy[ow + i, l] += -sR * F / G[oI + i, l]


@compiled
def project(y, G, P, FL, LO):
    """Return mapping of the groove histories onto their Coulomb caps."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ov = LO[S.L_VEL]
    ow = LO[S.L_SPIN]
    rot = FL[S.F_ROTATION] != 0
    owr = ow if rot else ov
    oFc = S.G_GROOVE_LIMIT * n
    oKg = S.G_GROOVE_SPRING * n
    oGg = S.G_GROOVE_DASHPOT * n
    oR = S.G_RADIUS * n
    s_g = P[S.P_GROOVE_S]
    og = LO[S.L_GROOVE_HIST]
    for i in range(n):
        if not (moving(y, ov + i, L) or moving(y, og + i, L)
                or (rot and moving(y, ow + i, L))):
            continue
        for l in range(L):
            u = slip(y[ov + i, l], y[owr + i, l], s_g * G[oR + i, l], rot)
            y[og + i, l] = groove_map(y[og + i, l], u, G[oKg + i, l], G[oGg + i, l],
                                      G[oFc + i, l])


@compiled
def locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau):
    """Per lane l of a block with act[l]: tau[l], the first tau in (0, 1) at which a
    sphere's groove contact switches between stick and slip inside the lane's trial step
    of length h[l], i.e. its trial force q = k_g xi + gamma_g u crosses +-Fc beyond a band
    of rtol times the bead's Fc, or -1 if none does (-1 in every other lane). The test
    runs over all lanes at once (no branch per lane); the root is found only in the lanes
    where a force crosses."""
    band = rtol * P[S.P_GROOVE_LIMIT]
    s_g = P[S.P_GROOVE_S]
    rot = FL[S.F_ROTATION] != 0
    og = LO[S.L_GROOVE_HIST]
    ov = LO[S.L_VEL]
    owr = LO[S.L_SPIN] if rot else ov
    L = y.shape[1]
    # tau[l] > 0: some force of lane l crosses a cap beyond the band
    for l in range(L):
        tau[l] = -1.0
    for i in range(n):
        for l in range(L):
            kg = G[S.G_GROOVE_SPRING * n + i, l]
            gam = G[S.G_GROOVE_DASHPOT * n + i, l]
            Fc = G[S.G_GROOVE_LIMIT * n + i, l]
            sR = s_g * G[S.G_RADIUS * n + i, l]
            q0 = kg * y[og + i, l] + gam * slip(y[ov + i, l], y[owr + i, l], sR, rot)
            q1 = kg * ynew[og + i, l] + gam * slip(ynew[ov + i, l], ynew[owr + i, l], sR, rot)
            mFc = -Fc
            cross = (((q0 < Fc - band) & (q1 > Fc + band)) | ((q0 > Fc + band) & (q1 < Fc - band))
                     | ((q0 < mFc - band) & (q1 > mFc + band))
                     | ((q0 > mFc + band) & (q1 < mFc - band)))
            tau[l] = 1.0 if cross else tau[l]
    for l in range(L):
        if tau[l] > 0.0 and act[l]:
            tau[l] = _switch_time(y, ynew, K0, K1, G, n, h[l], band, s_g, rot, og, ov, owr, l)
        else:
            tau[l] = -1.0


@compiled
def _switch_time(y, ynew, K0, K1, G, n, h, band, s_g, rot, og, ov, owr, l):
    """The first switch inside the trial step of lane l (``locate``), -1 if none."""
    best = 2.0
    for i in range(n):
        kg = G[S.G_GROOVE_SPRING * n + i, l]
        gam = G[S.G_GROOVE_DASHPOT * n + i, l]
        Fc = G[S.G_GROOVE_LIMIT * n + i, l]
        sR = s_g * G[S.G_RADIUS * n + i, l]
        # the slip and its rate at both ends of the step
        u0 = slip(y[ov + i, l], y[owr + i, l], sR, rot)
        u1 = slip(ynew[ov + i, l], ynew[owr + i, l], sR, rot)
        du0 = slip(K0[ov + i, l], K0[owr + i, l], sR, rot)
        du1 = slip(K1[ov + i, l], K1[owr + i, l], sR, rot)
        q0 = kg * y[og + i, l] + gam * u0
        q1 = kg * ynew[og + i, l] + gam * u1
        w0 = kg * K0[og + i, l] + gam * du0
        w1 = kg * K1[og + i, l] + gam * du1
        for lev in (Fc, -Fc):
            tau = -1.0
            if q0 < lev - band and q1 > lev + band:
                tau = hermite_root(q0, w0, q1, w1, h, lev, True)
            elif q0 > lev + band and q1 < lev - band:
                tau = hermite_root(q0, w0, q1, w1, h, lev, False)
            if tau > 0.0 and tau < best:
                best = tau
    return best if best < 1.0 else -1.0


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
    # each sphere's own Fc, kt and gamma (its mass, radius and material), particle 1 first;
    # the scalars above are a bead's
    Fc_each: tuple[float, ...] = ()
    kt_each: tuple[float, ...] = ()
    gamma_each: tuple[float, ...] = ()
    # the walls' normal load beyond the weight's m g / s (N; the adhesive pull-off of the
    # flats, adhesion.groove_load), a bead's and each sphere's
    load: float = 0.0
    load_each: tuple[float, ...] = ()


def mindlin_stiffness(scene, material=None, radius=None, mass=None) -> float:
    """Tangential stiffness (N/m) of the two groove-wall contacts under a sphere's weight
    (the chain's bead unless material, radius and mass are given; the groove is of the
    sphere's own material)."""
    st = scene.setting(SPEC.name)
    material = material or scene.material
    radius = scene.radius if radius is None else radius
    mass = scene.mass if mass is None else mass
    E, nu = material.E, material.nu
    G = material.G
    N_wall = mass * st.g / (2.0 * st.s)
    E_w = E / (2.0 * (1.0 - nu * nu))
    G_w = G / (2.0 * (2.0 - nu))
    if N_wall <= 0:
        raise ValueError("groove stiffness needs g > 0")
    a = (3.0 * N_wall * radius / (4.0 * E_w)) ** (1.0 / 3.0)
    return 2.0 * 8.0 * G_w * a


def _sphere(scene, material, R, m, I):
    """(Fc, kt, gamma, load) of one sphere: load the walls' normal load beyond its weight's
    (the flats' pull-off, ``adhesion.groove_load``)."""
    st = scene.setting(SPEC.name)
    load = groove_load(scene, R)
    # mu m g / s as without the load, then mu load (bit for bit the chain without adhesion)
    Fc = st.mu * m * st.g / st.s + st.mu * load
    if st.kt is None:
        kt = mindlin_stiffness(scene, material, R, m) if st.g > 0 else 1.0
    else:
        kt = st.kt
    m_u = m / (1.0 + st.s**2 * m * R * R / I) if scene.has("rotation") else m
    return Fc, kt, 2.0 * st.damping * math.sqrt(kt * m_u), load


def build(scene) -> GrooveFriction:
    Fc, kt, gamma, load = _sphere(scene, scene.material, scene.radius, scene.mass,
                                  scene.inertia)
    if scene.heterogeneous:
        each = [_sphere(scene, *a) for a in zip(scene.materials, scene.radii, scene.masses,
                                                 scene.inertias)]
    else:
        each = [(Fc, kt, gamma, load)] * scene.n
    st = scene.setting(SPEC.name)
    Fcs, kts, gammas, loads = (tuple(c) for c in zip(*each))
    return GrooveFriction(st.s, st.mu, st.g, Fc, kt, "mindlin" if st.kt is None else "scene",
                          gamma, st.damping, Fcs, kts, gammas, load, loads)


def kernel(gf: GrooveFriction) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return ({"P_GROOVE_S": gf.s, "P_GROOVE_LIMIT": gf.Fc, "P_GROOVE_SPRING": gf.kt,
             "P_GROOVE_DASHPOT": gf.gamma}, {"F_GROOVE_FRICTION": 1})


def rows(gf: GrooveFriction, chain) -> dict:
    """Per-sphere rows of the kernels' per-chain array, by G slot name."""
    return {"G_GROOVE_LIMIT": gf.Fc_each, "G_GROOVE_SPRING": gf.kt_each,
            "G_GROOVE_DASHPOT": gf.gamma_each}


def error_scale(gf: GrooveFriction, terms, delta: float, v: float) -> float:
    """Absolute error scale of the groove histories for the adaptive method: the spring
    stretch at the Coulomb cap (m)."""
    return gf.Fc / gf.kt


# per-sphere stick springs in a LAMMPS deck: fix property/atom vectors, read from the data
# file
GROOVE_PROPS = "groove_props"        # its fix ID
GROOVE_SECTION = "Groove"            # chain.data section: atom-ID kt gamma


def _springs(t) -> list[str]:
    """'kt gamma' (1e-3 N/m, 1e-9 kg/s), and 'load' (1e-9 N) when the flats adhere, of
    every sphere of a chain with terms t."""
    gf = getattr(t, SPEC.name)
    loads = gf.load_each if _loaded(gf) else (None,) * len(gf.kt_each)
    return [f"{_r(to_micro(k, 'stiffness'))} {_r(to_micro(g, 'damping'))}"
            + ("" if f is None else f" {_r(to_micro(f, 'force'))}")
            for k, g, f in zip(gf.kt_each, gf.gamma_each, loads)]


def _loaded(gf: GrooveFriction) -> bool:
    """Does the groove carry a normal load beyond the weight (``adhesion.groove``)?"""
    return any(f > 0.0 for f in gf.load_each)


def _per_sphere(deck) -> bool:
    """Do the spheres' stick springs (or extra loads) differ (each sphere's mass, radius
    and material), within a chain or, under a radius spread (``deck.members``), between
    chains? Then fix groove/drag reads kt, gamma (and load) per atom; else it gets the one
    value of every sphere."""
    chains = deck.members if deck.members is not None else [deck.terms]
    each = [getattr(t, SPEC.name) for t in chains]
    return any(len({x for gf in each for x in getattr(gf, f)}) > 1
               for f in ("kt_each", "gamma_each", "load_each"))


def lammps(gf: GrooveFriction | None, deck) -> DeckPart:
    """Its part of fix groove/drag (the granchain plugin, the same law in C++:
    lammps_inputs/plugin/fix_groove_drag.md), its global and per-chain work, and when the
    spheres' springs differ, each sphere's kt and gamma (a section of chain.data, read into
    fix property/atom vectors). With ``adhesion.groove`` the fix's ``load`` is the walls'
    normal load beyond the weight (``GrooveFriction.load``, the one place both engines take
    it from): Fc = mu (m g / s + load)."""
    energy = ("f_gd[1]", "groove friction")
    if gf is None:
        return DeckPart(fix_energy=energy)
    loaded = _loaded(gf)
    comment = (f"# groove: Coulomb limit mu m g / s, stick spring kt ({gf.kt_source}) + "
               f"dashpot gamma ({_r(gf.damping)} x critical)")
    if loaded:
        comment = comment.replace("mu m g / s", "mu (m g / s + load), load the adhesive "
                                  "pull-off of the groove's flats")
    args = (f"groove s {_r(gf.s)} mu {_r(gf.mu)} g {_r(to_micro(gf.g, 'acceleration'))} "
            f"kt {_r(to_micro(gf.kt, 'stiffness'))} gamma {_r(to_micro(gf.gamma, 'damping'))}")
    if loaded:
        args += f" load {_r(to_micro(gf.load, 'force'))}"
    note = f"cumulative work of the groove friction ({SPEC.lammps_ledger})"
    if not _per_sphere(deck):
        return DeckPart(fix=(comment, args), fix_energy=energy, ledger_note=note)
    args = args[:args.index(" kt ")] + " kt d_groove_kt gamma d_groove_gamma" + (
        " load d_groove_load" if loaded else "")
    props = "d_groove_kt d_groove_gamma" + (" d_groove_load" if loaded else "")
    n = deck.terms.n
    data = ["", GROOVE_SECTION, ""]
    for b in range(deck.n_chains):
        v = _springs(deck.terms if deck.members is None else deck.members[b])
        data += [f"{b * n + i + 1} {v[i]}" for i in range(n)]
    return DeckPart(
        fix=(comment + "; kt and gamma each sphere's own", args), fix_energy=energy,
        ledger_note=note, data=tuple(data), read_data=f" fix {GROOVE_PROPS} NULL {GROOVE_SECTION}",
        atoms=("\n# per-sphere groove stick spring kt (1e-3 N/m) and dashpot gamma (1e-9 kg/s)"
               + (" and load (1e-9 N)" if loaded else "") + ", "
               f"read from\n# chain.data's {GROOVE_SECTION} section (fix groove/drag kt "
               f"d_groove_kt gamma d_groove_gamma{' load d_groove_load' if loaded else ''})"
               f"\nfix             {GROOVE_PROPS} all property/atom {props}"))
