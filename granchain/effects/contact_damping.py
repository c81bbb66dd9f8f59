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
- ``tsuji``: the same form with Tsuji's c(e) (Marshall 2009, Eq. 53, times sqrt(2)),

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
from ..lammps.units import lmp_float as _r
from ..validate import choice, number
from .spec import EffectSpec

SPEC = EffectSpec("contact_damping", work="work_contact_damping", work_slot="L_WC",
                  table_column="work_damping_J", lammps_reports_work=False,
                  params=("P_DMP",), flags=("F_DAMP", "F_DMODEL", "F_DLIM"),
                  rows=("G_ME", "G_RS"))

MODELS = ("coeff_restitution", "viscoelastic", "tsuji")
# the kernels' codes of the models: the viscoelastic prefactor, or the sqrt(m F / delta)
# form of coeff_restitution and tsuji
VISCOELASTIC, SQRT_FORM = 0, 1

SECTION = "damping"
DEFAULTS = {"model": "coeff_restitution", "e": None, "eta": None, "limit_damping": False}
# the section stays out of a scene's normalised spec (and hash) unless the effect is on
# or a key of it is given: scenes from before the effect existed keep their hashes
SECTION_OPTIONAL = True


@dataclass(frozen=True)
class Settings:
    model: str
    e: float | None           # coefficient of restitution (coeff_restitution, tsuji)
    eta: float | None         # eta_n0, 1/(m s) (viscoelastic)
    limit_damping: bool


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``damping`` section (a merged mapping); ``given``: the dotted keys the
    scene wrote; ``on``: whether contact_damping is enabled."""
    model = choice(sec["model"], "damping.model", MODELS, "model")
    e = number(sec["e"], "damping.e", allow_none=True, positive=True, hi=1.0,
               fix="give a coefficient of restitution 0 < e <= 1")
    eta = number(sec["eta"], "damping.eta", allow_none=True, nonneg=True,
                 fix="give LAMMPS's viscoelastic coefficient eta_n0 in 1/(m s), >= 0")
    limit = sec["limit_damping"]
    if not isinstance(limit, bool):
        raise SceneError("damping.limit_damping", f"expected true or false, got {limit!r}",
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
    """c(e) of ``tsuji`` (LAMMPS's setup: Marshall 2009, Eq. 53, times sqrt(2))."""
    d = 1.2728 - 4.2783 * e + 11.087 * e**2
    d += -22.348 * e**3 + 27.467 * e**4
    d += -18.022 * e**5 + 4.8218 * e**6
    return d * math.sqrt(2.0)


def damping_force(fel, d, w, meff, Rs, model, damp):
    """Damping part eta w (N, > 0 while closing) of a contact of overlap d > 0 (m),
    overlap rate w (m/s) and elastic force fel (N)."""
    if model == 0:
        return damp * meff * math.sqrt(Rs * d) * w
    q = meff * fel / d if d > 0.0 else 0.0
    return damp * math.sqrt(q if q > 0.0 else 0.0) * w


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


def kernel(cd: ContactDamping) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (engines/kernels.py)."""
    return ({"P_DMP": cd.damp},
            {"F_DAMP": 1, "F_DMODEL": VISCOELASTIC if cd.model == "viscoelastic" else SQRT_FORM,
             "F_DLIM": int(cd.limit_damping)})


def rows(cd: ContactDamping, chain) -> dict:
    """Per-contact rows (the wall's last): m_eff = m_i m_j/(m_i + m_j) and R* (the wall:
    m_n and R_n)."""
    m, R = chain.masses, chain.radii
    n = len(m)
    meff = tuple(0.5 * m[k] if m[k] == m[k + 1] else m[k] * m[k + 1] / (m[k] + m[k + 1])
                 for k in range(n - 1)) + (m[-1],)
    rs = tuple(0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
               for k in range(n - 1)) + (R[-1],)
    return {"G_ME": meff, "G_RS": rs}


def lammps_damping(cd: ContactDamping | None) -> tuple[float, str]:
    """(hertz/material's second coefficient, the ``damping ...`` words) of the deck."""
    if cd is None:
        return 0.0, "damping viscoelastic"
    words = f"damping {cd.model}" + (" limit_damping" if cd.limit_damping else "")
    return cd.lammps_coefficient, words


def lammps_comment(cd: ContactDamping) -> str:
    what = (f"eta_n0 = {_r(cd.eta)} (1/(m s))" if cd.model == "viscoelastic"
            else f"e = {_r(cd.e)}")
    return f"# damping {cd.model}: {what}" + (", limit_damping" if cd.limit_damping else "")
