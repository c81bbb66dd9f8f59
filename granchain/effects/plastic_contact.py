"""plastic_contact: Thornton's elastic-perfectly plastic normal contact, in place of Hertz.

Thornton, C. (1997), "Coefficient of restitution for collinear collisions of
elastic-perfectly plastic spheres", J. Appl. Mech. 64, 383-386. At a contact of E*, R*
(each contact's, as ``hertz``: the end wall's R* = R_n) and limiting contact pressure p_y
(the scene's ``plasticity.yield_pressure``, else the softer body's library value), with
overlap delta and the largest overlap it has reached, delta_max:

- elastic (Thornton's Hertzian loading) while delta_max <= delta_y: F = K delta^(3/2),
  K = (4/3) E* sqrt(R*), until the Hertzian peak pressure p0 = 2 E* a / (pi R*)
  (a = sqrt(R* delta)) reaches p_y, at delta_y = R* (pi p_y / (2 E*))^2 and
  F_y = K delta_y^(3/2) (= pi^3 p_y^3 R*^2 / (6 E*^2));
- plastic loading (delta = delta_max > delta_y): F = F_y + pi p_y R* (delta - delta_y),
  Thornton's linear law (its slope 2 E* a_y is Hertz's at delta_y: the force is smooth
  there);
- unloading and reloading below delta_max: Hertzian with the enlarged radius
  R_p = 4 E* a_max^3 / (3 F_max), a_max = sqrt(R* delta_max), F_max the loading force at
  delta_max (Thornton's R_p = R* (F_y/F_max) ((2 F_max + F_y)/(3 F_y))^(3/2), the same
  number), down to the plastic overlap delta_p = delta_max - a_max^2 / R_p:
  F = (4/3) E* sqrt(R_p) (delta - delta_p)^(3/2) = F_max ((delta - delta_p) / c)^(3/2),
  c = delta_max - delta_p = 3 F_max / (4 E* a_max), and 0 for delta <= delta_p.

delta_max is a per-contact block of the state (entry n-1: the end wall's), kept for the
whole run: a contact struck again reloads elastically along its unloading curve up to its
previous maximum, then plastically. The force is evaluated at max(delta_max, delta); the
block is raised to the overlap in each force call (velocity Verlet, as a LAMMPS fix would)
or after each step (the other methods), so a peak between two evaluations is missed by
O(h^2) of the step h.

The onset speed of two bodies of reduced mass m*: (1/2) m* v_y^2 = (8/15) E* sqrt(R*)
delta_y^(5/2); above it Thornton's closed form e(v/v_y) (his Eq. for the coefficient of
restitution, checked by tests/independent.py against the law's own energy integrals).

Energy: the contacts' elastic energy is the energy the unloading curve returns,
U = (8/15) E* sqrt(R_p) (delta - delta_p)^(5/2) (Hertz's (2/5) K delta^(5/2) while
elastic); this effect adds U - Hertz's to the ledger's potential column. Its work column
``work_plastic_contact`` is the work the plastic loading does on the particles,
-(F - dU_max/d delta_max) d delta_max, U_max = 3 F_max^2 / (10 E* a_max) the elastic energy
at delta_max (zero at yield: the law is smooth there): minus the energy the contacts
dissipated. Velocity Verlet books each force call's rise of delta_max with the energy it
dissipates in closed form (:func:`dissipated`), the other methods integrate the rate.

With ``contact_damping`` the dashpot acts as without plasticity (its prefactor from the
Hertz force at the overlap) and adds to Thornton's force. Not composed yet, and refused:
the contact and rolling friction (their Coulomb caps would need the history-dependent
normal force), ``damping.limit_damping`` (it holds Hertz's net force, not Thornton's) and
a dead load beyond a contact's F_y (the static state would be plastic).

The event method locates the law's switches (:func:`locate`): a step ends where a contact
reaches its loading curve (yield, or the end of an elastic reload), where it turns from
loading to unloading (its largest overlap) and where it opens or closes at delta_p.

LAMMPS has no Thornton law: the granchain plugin's ``fix thornton/chain``
(lammps_inputs/plugin/fix_thornton_chain.md) adds Thornton's force less Hertz's at every
contact i,i+1 (atom ids in chain order) and at the end wall to the force of ``pair
granular`` (``hertz/material`` and the damping, as without plasticity) and of ``fix
wall/gran``: the reference engine's composition. It keeps each contact's largest overlap
on the contact's left atom (the wall's on the last atom), raised and booked in each force
call as velocity Verlet does here, and reports per atom the plastic work, the elastic
energy beyond Hertz's and its part of the wall force, which the LAMMPS engine adds to the
ledger and to the recorded wall force. E* and p_y are each sphere's (its contact with
the next, the last sphere's the wall's), a section of the deck's data file.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..materials import effective_modulus
from ..units import lmp_float as _r, to_micro
from ..validate import Fit, Key
from . import slots as S
from .hertz import energy as hertz_energy, force as hertz_force
from .lanes import bit, closing_speed, contact_overlap
from .spec import DeckPart, EffectSpec, compiled, hermite3, hermite_root

SPEC = EffectSpec("plastic_contact", state=(("L_PLASTIC_DMAX", "particle"),),
                  work="work_plastic_contact", work_slot="L_WORK_PLASTIC",
                  table_column="work_plastic_J",
                  work_note="the plastic loading of the contacts (Thornton's law): minus the "
                            "energy their yielding dissipated",
                  lammps_ledger="f_thornton[2]", lammps_potential="f_thornton[3]",
                  lammps_wall_force="f_thornton[4]", flags=("F_PLASTIC_CONTACT",),
                  rows=("G_PLASTIC_EMIX", "G_PLASTIC_RSTAR", "G_PLASTIC_DY", "G_PLASTIC_SLOPE"),
                  step_cost=1.7)      # benchmarks/contacts.py --every: 1.70x

# left out of the warm-up's every-effect scene (engines.warmup): it refuses the contact
# friction and adhesion
WARM_UP_APART = "refuses the contact friction and adhesion"

MODELS = ("thornton",)
SECTION = "plasticity"
DEFAULTS = {"model": "thornton", "yield_pressure": None}
# the section stays out of a scene's normalised spec (and hash) unless the effect is on
# or a key of it is given
SECTION_OPTIONAL = True
KEYS = (
    Key("plasticity.model", "-", "The elastic-perfectly plastic normal law at the contacts "
        "and the end wall, in place of Hertz: `thornton`, Thornton (1997): Hertz until the "
        "peak pressure reaches `yield_pressure`, then linear loading, Hertzian unloading "
        "with an enlarged radius, each contact's largest overlap remembered. The work of "
        "its plastic loading is the ledger's `work_plastic_contact` (table column "
        "`work_plastic_J`).", choices=MODELS),
    Key("plasticity.yield_pressure", "Pa", "Thornton's limiting contact pressure p_y of "
        "every contact and of the end wall. Unset: each contact's is the smaller of its two "
        "materials' `yield_pressure` (granchain/data/materials.yaml: 1.6 times a sourced "
        "yield strength), the end wall's the sphere's (and the wall material's, if it has "
        "one); a material without one must be given it here. Fittable: the prior spans "
        "annealed 316's 4.6e8 Pa and hardened 440C's 3.0e9 Pa; at its top two 440C beads "
        "of 150 um yield above about 7.5 m/s (Thornton's onset speed).", lo=1e5, hi=1e11,
        allowed="unset: the materials' values",
        fit=Fit(1e8, 1e10, 8, "yield_pressure", "p_y", "limiting contact pressure",
                example="plasticity: {model: thornton, yield_pressure: 1.0e9}")),
)
_KEY = {k.name: k for k in KEYS}


@dataclass(frozen=True)
class Settings:
    model: str
    yield_pressure: float | None      # Pa; None: the materials'


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``plasticity`` section; ``on``: whether the effect is enabled."""
    model = _KEY["model"].choice(sec["model"], "model")
    py = _KEY["yield_pressure"].number(sec["yield_pressure"], allow_none=True,
                                       fix="give the limiting contact pressure in Pa, "
                                           "e.g. 3.04e9")
    return Settings(model, py)


# ---------------------------------------------------------------------------------------
# the law
@compiled
def loading(K, dy, Sl, dm):
    """F_max (N): the loading force at the largest overlap dm > dy: F_y + S (dm - dy),
    S = pi p_y R*."""
    return K * dy * math.sqrt(dy) + Sl * (dm - dy)


@compiled
def depth(Fm, Es, Rs, dm):
    """c = delta_max - delta_p (m): the depth of the unloading curve from the largest
    overlap dm > dy, of loading force Fm: 3 F_max / (4 E* a_max)."""
    return 0.75 * Fm / (Es * math.sqrt(Rs * dm))


@compiled
def force(K, Es, Rs, dy, Sl, d, dm):
    """Thornton's force (N) at overlap d of a contact whose largest overlap is dm >= d
    (K its Hertz constant, Es its E*, Rs its R*, dy its delta_y, Sl = pi p_y R*)."""
    if dm <= dy:
        return hertz_force(K, d)
    Fm = loading(K, dy, Sl, dm)
    c = depth(Fm, Es, Rs, dm)
    x = 1.0 - (dm - d) / c
    return Fm * x * math.sqrt(x) if x > 0.0 else 0.0


@compiled
def energy(K, Es, Rs, dy, Sl, d, dm):
    """The elastic energy (J) at overlap d, largest overlap dm >= d: (2/5) F_max c
    ((d - delta_p)/c)^(5/2), Hertz's while dm <= dy."""
    if dm <= dy:
        return hertz_energy(K, d)
    Fm = loading(K, dy, Sl, dm)
    c = depth(Fm, Es, Rs, dm)
    x = 1.0 - (dm - d) / c
    return 0.4 * Fm * c * x * x * math.sqrt(x) if x > 0.0 else 0.0


@compiled
def dissipation(K, Es, Rs, dy, Sl, dm):
    """F_max - dU_max/d delta_max (N) on the loading curve at dm > dy: the energy the
    contact dissipates per metre of plastic loading, U_max = 3 F_max^2 / (10 E* a)."""
    Fm = loading(K, dy, Sl, dm)
    a = math.sqrt(Rs * dm)
    dU = 0.3 / Es * (2.0 * Fm * Sl / a - 0.5 * Fm * Fm * Rs / (a * a * a))
    return Fm - dU


@compiled
def dissipated(K, Es, Rs, dy, Sl, d0, d1):
    """The energy (J) a contact dissipates as its largest overlap rises from d0 to
    d1 >= d0: the loading curve's work from d0 to d1 less the rise of U_max (0 while
    elastic)."""
    if d1 <= dy:
        return 0.0
    lo = d0 if d0 > dy else dy
    W = hertz_energy(K, dy) - hertz_energy(K, d0) if d0 < dy else 0.0
    W += K * dy * math.sqrt(dy) * (d1 - lo) + 0.5 * Sl * ((d1 - dy) * (d1 - dy)
                                                          - (lo - dy) * (lo - dy))
    return W - (energy(K, Es, Rs, dy, Sl, d1, d1) - energy(K, Es, Rs, dy, Sl, d0, d0))


# The compiled parts the engines compose (``spec.HOOKS``): each contact's E*, R*, delta_y
# and pi p_y R* are rows G_PLASTIC_* (the end wall's last), its largest overlap the block
# L_PLASTIC_DMAX (entry n-1: the end wall's).
@compiled
def normal(y, G, P, FL, LO, dy, f, shut):
    """f of every closed contact gains Thornton's force less Hertz's at max(delta_max,
    delta); the work rate of the plastic loading."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    om = LO[S.L_PLASTIC_DMAX]
    owp = LO[S.L_WORK_PLASTIC]
    wall = FL[S.F_END_WALL] != 0
    oK = S.G_HERTZ_K * n
    oE = S.G_PLASTIC_EMIX * n
    oR = S.G_PLASTIC_RSTAR * n
    oY = S.G_PLASTIC_DY * n
    oS = S.G_PLASTIC_SLOPE * n
    for l in range(L):
        dy[owp, l] = 0.0
    for k in range(n):
        for l in range(L):
            dy[om + k, l] = 0.0
    for k in range(n if wall else n - 1):
        if bit(shut, k):
            continue
        for l in range(L):
            d = contact_overlap(y, ox, G, n, k, l)
            w = closing_speed(y, ov, n, k, l)
            K = G[oK + k, l]
            Es = G[oE + k, l]
            Rs = G[oR + k, l]
            dly = G[oY + k, l]
            Sl = G[oS + k, l]
            stored = y[om + k, l]
            dm = d if d > stored else stored
            plastic = dm > dly and d > 0.0
            Fa = force(K, Es, Rs, dly, Sl, d, dm) - hertz_force(K, d) if plastic else 0.0
            f[k, l] = f[k, l] + Fa
            # the plastic loading: the overlap beyond its stored maximum and beyond yield
            p = -dissipation(K, Es, Rs, dly, Sl, d) * w if (plastic and d >= stored) else 0.0
            a = dy[owp, l]
            dy[owp, l] = a + p
    return shut


@compiled
def _raise(y, G, P, FL, LO):
    """delta_max of every contact (and the end wall) raised to its overlap."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    om = LO[S.L_PLASTIC_DMAX]
    for k in range(n if FL[S.F_END_WALL] != 0 else n - 1):
        for l in range(L):
            d = contact_overlap(y, ox, G, n, k, l)
            m = y[om + k, l]
            y[om + k, l] = d if d > m else m


@compiled
def forces(y, G, P, FL, LO, hist_dt, dy, f, shut):
    """Velocity Verlet (hist_dt > 0): the work rate becomes the energy dissipated as
    delta_max rises to this force call's overlaps (:func:`dissipated`) over hist_dt, so
    that the step's work is exactly it, and delta_max is raised (the force above already
    used it)."""
    if hist_dt <= 0.0:
        return
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    om = LO[S.L_PLASTIC_DMAX]
    owp = LO[S.L_WORK_PLASTIC]
    for l in range(L):
        dy[owp, l] = 0.0
    for k in range(n if FL[S.F_END_WALL] != 0 else n - 1):
        for l in range(L):
            d = contact_overlap(y, ox, G, n, k, l)
            m = y[om + k, l]
            q = dissipated(G[S.G_HERTZ_K * n + k, l], G[S.G_PLASTIC_EMIX * n + k, l],
                           G[S.G_PLASTIC_RSTAR * n + k, l], G[S.G_PLASTIC_DY * n + k, l],
                           G[S.G_PLASTIC_SLOPE * n + k, l], m, d) if d > m else 0.0
            a = dy[owp, l]
            dy[owp, l] = a - q / hist_dt
    _raise(y, G, P, FL, LO)


@compiled
def project(y, G, P, FL, LO):
    """After a step: delta_max raised to the step's end overlaps."""
    _raise(y, G, P, FL, LO)


@compiled
def history_normal(F, d, y, LO, G, P, FL, n, k, l):
    """The force of contact k in lane l at overlap d in the state y: F (Hertz's and
    the damping's) with Thornton's force in place of Hertz's; F itself at d <= 0."""
    if d <= 0.0:
        return F
    stored = y[LO[S.L_PLASTIC_DMAX] + k, l]
    dm = d if d > stored else stored
    dly = G[S.G_PLASTIC_DY * n + k, l]
    if dm <= dly:
        return F
    K = G[S.G_HERTZ_K * n + k, l]
    return F + force(K, G[S.G_PLASTIC_EMIX * n + k, l], G[S.G_PLASTIC_RSTAR * n + k, l], dly,
                     G[S.G_PLASTIC_SLOPE * n + k, l], d, dm) - hertz_force(K, d)


@compiled
def energies(y, G, P, FL, LO, out):
    """out[E_POT] gains each plastically deformed contact's elastic energy less Hertz's."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    om = LO[S.L_PLASTIC_DMAX]
    for k in range(n if FL[S.F_END_WALL] != 0 else n - 1):
        for l in range(L):
            d = contact_overlap(y, ox, G, n, k, l)
            stored = y[om + k, l]
            dm = d if d > stored else stored
            dly = G[S.G_PLASTIC_DY * n + k, l]
            if dm > dly:
                K = G[S.G_HERTZ_K * n + k, l]
                out[S.E_POT, l] += energy(K, G[S.G_PLASTIC_EMIX * n + k, l],
                                          G[S.G_PLASTIC_RSTAR * n + k, l], dly,
                                          G[S.G_PLASTIC_SLOPE * n + k, l], d, dm) \
                    - hertz_energy(K, d)


@compiled
def locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau):
    """The event method's switches of the law: per lane l with act[l], tau[l] the first
    tau in (0, 1) inside the lane's trial step y -> ynew of length h[l] at which a
    contact of largest overlap delta_max (its value at the step's start)

    - reaches the loading curve: its overlap rises through max(delta_max, delta_y) (a
      virgin contact's yield; the end of an elastic reload);
    - unloads from it: its closing speed turns from closing to opening at an overlap
      more than the band above max(delta_max, delta_y) (the largest overlap: the force
      inside a step reads delta_max at its start, so the step must end there);
    - with delta_max > delta_y, opens or closes again at the plastic overlap delta_p,

    each beyond a band of rtol times max(delta_max, delta_y); -1 if none (and in every
    lane without act[l]). The test runs over all lanes at once (no branch per lane); the
    roots (of the cubic Hermites of the overlap and of the closing speed on the step) are
    found only in the lanes where a switch happens."""
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    om = LO[S.L_PLASTIC_DMAX]
    m = n if FL[S.F_END_WALL] != 0 else n - 1
    for l in range(L):
        tau[l] = -1.0
    for k in range(m):
        for l in range(L):
            d0 = contact_overlap(y, ox, G, n, k, l)
            d1 = contact_overlap(ynew, ox, G, n, k, l)
            turn = (closing_speed(y, ov, n, k, l) > 0.0) & (closing_speed(ynew, ov, n, k, l) < 0.0)
            lev, band, dp = _levels(y, G, om, n, k, l, rtol)
            up = (d0 < lev - band) & ((d1 > lev + band) | turn)
            top = (d0 >= lev - band) & turn
            yielded = dp > -math.inf
            opens = (d0 > dp + band) & (d1 < dp - band)
            shuts = (d0 < dp - band) & ((d1 > dp + band) | turn)
            cross = up | top | (yielded & (opens | shuts))
            tau[l] = 1.0 if cross else tau[l]
    for l in range(L):
        if tau[l] > 0.0 and act[l]:
            tau[l] = _switch_time(y, ynew, K0, K1, G, n, m, h[l], rtol, ox, ov, om, l)
        else:
            tau[l] = -1.0


@compiled
def _levels(y, G, om, n, k, l, rtol):
    """(level, band, delta_p) of contact k in lane l (``locate``): the overlap of the
    loading curve's start max(delta_max, delta_y), rtol times it, and the plastic
    overlap (-inf while delta_max <= delta_y: no unloading curve of its own)."""
    stored = y[om + k, l]
    dly = G[S.G_PLASTIC_DY * n + k, l]
    lev = stored if stored > dly else dly
    Fm = loading(G[S.G_HERTZ_K * n + k, l], dly, G[S.G_PLASTIC_SLOPE * n + k, l], lev)
    c = depth(Fm, G[S.G_PLASTIC_EMIX * n + k, l], G[S.G_PLASTIC_RSTAR * n + k, l], lev)
    dp = lev - c if stored > dly else -math.inf
    return lev, rtol * lev, dp


@compiled
def _switch_time(y, ynew, K0, K1, G, n, m, h, rtol, ox, ov, om, l):
    """The first switch inside the trial step of lane l (``locate``), -1 if none."""
    best = 2.0
    for k in range(m):
        d0 = contact_overlap(y, ox, G, n, k, l)
        d1 = contact_overlap(ynew, ox, G, n, k, l)
        w0 = closing_speed(y, ov, n, k, l)
        w1 = closing_speed(ynew, ov, n, k, l)
        turn = w0 > 0.0 and w1 < 0.0
        lev, band, dp = _levels(y, G, om, n, k, l, rtol)
        t = -1.0
        if d0 < lev - band and (d1 > lev + band or turn):
            t = hermite_root(d0, w0, d1, w1, h, lev, True)
        elif d0 >= lev - band and turn:
            # the largest overlap, where the closing speed (its rate: the closing
            # acceleration) turns, if it is beyond the band
            s = hermite_root(w0, closing_speed(K0, ov, n, k, l), w1,
                             closing_speed(K1, ov, n, k, l), h, 0.0, False)
            if s > 0.0 and hermite3(d0, w0, d1, w1, h, s) > lev + band:
                t = s
        if t > 0.0 and t < best:
            best = t
        if dp > -math.inf:
            t = -1.0
            if d0 > dp + band and d1 < dp - band:
                t = hermite_root(d0, w0, d1, w1, h, dp, False)
            elif d0 < dp - band and (d1 > dp + band or turn):
                t = hermite_root(d0, w0, d1, w1, h, dp, True)
            if t > 0.0 and t < best:
                best = t
    return best if best < 1.0 else -1.0


# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlasticContact:
    model: str
    yield_pressure: float | None     # the scene's p_y (Pa), None: the materials'
    pressures: tuple[float, ...]     # each contact's p_y (Pa), the end wall's last (0: none)


def _contact_pressure(a, b, given, where):
    """p_y (Pa) of a contact of materials a and b (b None: a rigid wall)."""
    if given is not None:
        return given
    known = [m.yield_pressure for m in (a, b) if m is not None and m.yield_pressure is not None]
    missing = [m.name for m in (a, b) if m is not None and not m.rigid and m.yield_pressure is None]
    if missing:
        raise SceneError("plasticity.yield_pressure", f"missing: the material library has no "
                         f"yield pressure for {missing[0]} ({where})",
                         "give plasticity.yield_pressure in Pa")
    return min(known)


def pressures(scene) -> tuple[float, ...]:
    """Each contact's p_y (Pa), the end wall's last (0.0 without a wall)."""
    given = scene.setting(SPEC.name).yield_pressure
    mats = scene.materials
    out = [_contact_pressure(mats[k], mats[k + 1], given, f"contact {k + 1}")
           for k in range(scene.n - 1)]
    if scene.wall is None:
        out.append(0.0)
    else:
        wall = None if scene.wall.rigid else scene.wall
        out.append(_contact_pressure(mats[-1], wall, given, "the end wall"))
    return tuple(out)


def build(scene) -> PlasticContact:
    st = scene.setting(SPEC.name)
    return PlasticContact(st.model, st.yield_pressure, pressures(scene))


def _star(chain, k):
    """(E*, R*) of contact k (k = n-1: the end wall)."""
    R, mats = chain.radii, chain.materials
    n = len(R)
    if k == n - 1:
        if chain.wall is None:
            return 1.0, R[-1]
        return effective_modulus(mats[-1], chain.wall), R[-1]
    rs = 0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
    return effective_modulus(mats[k], mats[k + 1]), rs


def yield_overlap(E, Rs, py):
    """delta_y (m): R* (pi p_y / (2 E*))^2."""
    return Rs * (math.pi * py / (2.0 * E)) ** 2


def rows(pc: PlasticContact, chain) -> dict:
    """Per-contact rows (the wall's last): E*, R*, delta_y and pi p_y R*."""
    n = len(chain.radii)
    es, rs, dys, sl = [], [], [], []
    for k in range(n):
        E, Rs = _star(chain, k)
        py = pc.pressures[k]
        es.append(E)
        rs.append(Rs)
        dys.append(yield_overlap(E, Rs, py) if py > 0.0 else math.inf)
        sl.append(math.pi * py * Rs)
    return {"G_PLASTIC_EMIX": tuple(es), "G_PLASTIC_RSTAR": tuple(rs),
            "G_PLASTIC_DY": tuple(dys), "G_PLASTIC_SLOPE": tuple(sl)}


def kernel(pc: PlasticContact) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return {}, {"F_PLASTIC_CONTACT": 1}


def error_scale(pc: PlasticContact, terms, delta: float, v: float) -> float:
    """Absolute error scale of the largest overlaps for the adaptive method: the peak
    overlap delta (m)."""
    return delta


def yield_force(E, Rs, py):
    """F_y (N) of a contact: (4/3) E* sqrt(R*) delta_y^(3/2)."""
    return 4.0 / 3.0 * E * math.sqrt(Rs) * yield_overlap(E, Rs, py) ** 1.5


# the effects the law does not act with yet (module docstring); the plasticity study leaves
# them out of its scenes
NOT_WITH = ("particle_friction", "rolling_friction", "adhesion")


def check(scene) -> None:
    """What the law does not yet act with (module docstring), each refused in one line."""
    pressures(scene)
    for other, what in (("particle_friction", "contact"), ("rolling_friction", "rolling")):
        if scene.has(other):
            raise SceneError("effects", f"plastic_contact with {other} is not implemented (the "
                             f"{what} friction's Coulomb cap needs the history-dependent normal "
                             "force)", f"drop {other} or plastic_contact")
    if scene.has("adhesion"):
        raise SceneError("effects", "plastic_contact with adhesion is not implemented (each "
                         "replaces Hertz's normal law)", "drop adhesion or plastic_contact")
    if scene.has("contact_damping") and scene.setting("contact_damping").limit_damping:
        raise SceneError("damping.limit_damping", "cannot act with plastic_contact (it holds "
                         "Hertz's net force at >= 0, not Thornton's)",
                         "write limit_damping: false, or drop plastic_contact")
    if scene.precompression > 0.0:
        pc = build(scene)
        R, mats, n = scene.radii, scene.materials, scene.n
        fys = [yield_force(effective_modulus(mats[k], mats[k + 1]),
                           R[k] * R[k + 1] / (R[k] + R[k + 1]), pc.pressures[k])
               for k in range(1, n - 1)]
        if scene.wall is not None:
            fys.append(yield_force(effective_modulus(mats[-1], scene.wall), R[-1],
                                   pc.pressures[-1]))
        fy = min(fys)
        if scene.precompression >= fy:
            raise SceneError("precompression.force", f"{scene.precompression:g} N yields a "
                             f"contact (its yield force F_y is {fy:.3g} N): the static state "
                             "would be plastic", f"give a force below {fy:.3g} N or a larger "
                             "plasticity.yield_pressure")


# the deck's names: the fix, its per-atom E* and p_y vectors, their fix property/atom and
# the data file's section holding them
FIX_ID = "thornton"
PROPS = "thornton_props"
VECTORS = ("d_thornton_estar", "d_thornton_yield")
DATA_SECTION = "Thornton"


def _deck_values(terms) -> list[tuple[float, float]]:
    """(E*, p_y) in Pa of each sphere's right contact (the last sphere's: the end wall's,
    (0, 0) without one)."""
    pc, ch = terms.plastic_contact, terms.chain
    n = len(ch.radii)
    out = [(_star(ch, k)[0], pc.pressures[k]) for k in range(n - 1)]
    out.append((_star(ch, n - 1)[0], pc.pressures[-1]) if ch.wall is not None else (0.0, 0.0))
    return out


def lammps(pc: PlasticContact | None, deck) -> DeckPart:
    """The granchain plugin's ``fix thornton/chain`` (Thornton's force less Hertz's at
    every contact and at the end wall, added to the pair style's and fix wall/gran's), each
    sphere's E* and p_y (a section of chain.data, read into fix property/atom vectors), its
    per-atom plastic work, elastic energy beyond Hertz's and wall force for the ledger."""
    if pc is None:
        return DeckPart()
    n = deck.terms.n
    data = ["", DATA_SECTION, ""]
    for b in range(deck.n_chains):
        t = deck.terms if deck.members is None else deck.members[b]
        data += [f"{b * n + i + 1} {_r(to_micro(E, 'pressure'))} {_r(to_micro(py, 'pressure'))}"
                 for i, (E, py) in enumerate(_deck_values(t))]
    walled = deck.terms.chain.wall is not None
    given = sorted({p for p in pc.pressures if p > 0.0})
    fix = (f"fix             {FIX_ID} all thornton/chain chain {n} estar {VECTORS[0]} "
           f"yield {VECTORS[1]}" + (f" wall {_r(deck.wall_x)}" if walled else ""))
    lines = (
        "# plastic contact (effects/plastic_contact.py; lammps_inputs/plugin/fix_thornton_chain.md):",
        "# Thornton (1997): Hertz until the peak pressure reaches p_y, then F = F_y + pi p_y R* "
        "(delta - delta_y);",
        "# unloading Hertzian with R_p = 4 E* a_max^3/(3 F_max) down to delta_p. fix "
        "thornton/chain adds F_Thornton",
        "# - F_Hertz at each contact i,i+1 (atom ids in chain order)"
        + (" and at the end wall" if walled else "") + " to the pair style's",
        "# force (the damping acts as without plasticity); each contact's largest overlap is "
        "kept on its left",
        "# atom. E*, p_y: chain.data's " + DATA_SECTION + " section; p_y = "
        + ", ".join(f"{_r(p)}" for p in given) + " Pa.",
        fix)
    return DeckPart(
        contact="Thornton's elastic-perfectly plastic law (the pair style's force plus fix "
                "thornton/chain's correction)",
        plugin_lines=lines, data=tuple(data), read_data=f" fix {PROPS} NULL {DATA_SECTION}",
        ledger_note=f"cumulative work of the plastic loading ({SPEC.lammps_ledger})",
        atoms=("\n# per-sphere E* and p_y (1e3 Pa) of the sphere's contact with the next (the "
               "last sphere's: the end wall's),\n# read from chain.data's "
               f"{DATA_SECTION} section (fix thornton/chain)\nfix             {PROPS} all "
               f"property/atom {' '.join(VECTORS)} ghost yes"))
