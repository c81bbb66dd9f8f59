"""The adhesion effect's scene-level theory, in plain Python (``effects.adhesion`` holds
the law and imports these): the energies of a contact's well (where a held contact
opens and the work to open it, the depth of the well, the most energy the contacts can
give the spheres' motion), and Tabor's parameter with Johnson & Greenwood (1997)'s
adhesion map, which ``granchain validate`` prints and warns by."""
from __future__ import annotations

import math

from ..materials import effective_modulus
from . import adhesion as law   # the law (it imports this module once it is defined)


# the equilibrium separation of the surfaces' Lennard-Jones potential in Tabor's parameter
# (Johnson & Greenwood 1997: 0.3-0.4 nm), and the regimes of their adhesion map: JKR holds
# above JKR_TABOR, DMT below DMT_TABOR
Z0 = 0.3e-9
JKR_TABOR, DMT_TABOR = 5.0, 0.1


def separation(ad, chain, k: int, d: float) -> tuple[float, float]:
    """(d_open, Phi) of contact k (spheres k+1, k+2; 1-based) held closed at overlap d (m):
    where it opens (dmt: 0; jkr: the pull-off distance -delta_po) and
    :func:`~granchain.effects.adhesion.opening_work`."""
    R, mats = chain.radii, chain.materials
    Rs = 0.5 * R[k] if R[k] == R[k + 1] else R[k] * R[k + 1] / (R[k] + R[k + 1])
    E = effective_modulus(mats[k], mats[k + 1])
    jkr = ad.model == "jkr"
    d_open = -law.pulloff_distance(Rs, E, ad.gamma) if jkr else 0.0
    return d_open, law.opening_work(chain.K[k], Rs, E, ad.gamma, jkr, d)


def well_depth(model: str, K: float, Rs: float, E: float, g: float) -> float:
    """The energy (J, > 0) a contact of Hertz constant K, R*, E* releases into the motion
    of its spheres from first touch (delta = 0, the force's jump onto the law) down to the
    bottom of its well, where the force vanishes: -int_0^{delta_eq} F d delta.
    dmt: delta_eq = (F_po / K)^(2/3), depth (3/5) F_po delta_eq. jkr: along the law's
    branch from a_0 = (4 pi gamma R*^2 / E*)^(1/3) (delta = 0) to a_eq = (9 pi gamma R*^2
    / E*)^(1/3) (F = 0), V(a_0) - V(a_eq) with V :func:`~granchain.effects.adhesion.jkr_work`."""
    if model == "dmt":
        F_po = law.pulloff_force(Rs, g, False)
        return 0.6 * F_po * (F_po / K) ** (2.0 / 3.0)
    a0 = (4.0 * math.pi * g * Rs * Rs / E) ** (1.0 / 3.0)
    a_eq = (9.0 * math.pi * g * Rs * Rs / E) ** (1.0 / 3.0)
    return law.jkr_work(Rs, E, g, a0) - law.jkr_work(Rs, E, g, a_eq)


def touch_energy(ad, chain) -> float:
    """The most energy (J) the adhesive contacts can give the spheres' motion: each
    contact's :func:`well_depth` (a contact gives it once on touching and takes at least
    as much back to open), summed over the sphere contacts and the end wall."""
    r = law.rows(ad, chain)
    K = tuple(chain.K) + ((chain.K_wall,) if chain.wall is not None else ())
    return sum(well_depth(ad.model, K[k], r["G_ADHESION_RSTAR"][k], r["G_ADHESION_EMIX"][k],
                          ad.gamma) for k in range(len(K)))


# ---------------------------------------------------------------------------------------
# Tabor's parameter and the groove's pull-off
def tabor(Rs: float, E: float, gamma: float, z0: float = Z0) -> float:
    """Tabor's parameter mu = (R* w^2 / (E*^2 z0^3))^(1/3) of a contact of R* (m), E* (Pa)
    and surface energy gamma (J/m^2; w = 2 gamma the work of adhesion), z0 (m)."""
    w = 2.0 * gamma
    return (Rs * w * w / (E * E * z0 ** 3)) ** (1.0 / 3.0)


def regime(model: str, mu: float) -> str | None:
    """Why ``model`` is outside its regime at Tabor's parameter mu, and what to do; None
    inside it (Johnson & Greenwood 1997's map: JKR above JKR_TABOR, DMT below
    DMT_TABOR, Maugis-Dugdale's transition between)."""
    if (model == "jkr" and mu >= JKR_TABOR) or (model == "dmt" and mu <= DMT_TABOR):
        return None
    if mu < DMT_TABOR:
        return f"below {DMT_TABOR:g} DMT holds: use model dmt"
    if mu > JKR_TABOR:
        return f"above {JKR_TABOR:g} JKR holds: use model jkr"
    return (f"between {DMT_TABOR:g} and {JKR_TABOR:g} neither JKR nor DMT holds "
            "(Maugis-Dugdale's transition): read the results as the model's limit")


def contacts(scene) -> list[tuple[str, float]]:
    """(name, Tabor's mu) of a scene's adhesive contacts, alike ones merged: the
    sphere-sphere contacts (``contacts 1-14``), the end wall, and with ``groove: true``
    the groove's flats (each sphere on a flat of its own material)."""
    from .chain import build as chain_build
    st = scene.setting(law.SPEC.name)
    chain = chain_build(scene)
    r = law.rows(law.Adhesion(st.model, st.surface_energy, st.groove), chain)
    n = scene.n
    out: list[tuple[str, float]] = []
    mus = [tabor(r["G_ADHESION_RSTAR"][k], r["G_ADHESION_EMIX"][k], st.surface_energy)
           for k in range(n - 1)]
    out += _runs("contact", mus)
    if chain.wall is not None:
        out.append(("end wall", tabor(r["G_ADHESION_RSTAR"][-1], r["G_ADHESION_EMIX"][-1],
                                      st.surface_energy)))
    if st.groove:
        flats = [tabor(R, effective_modulus(m, m), st.surface_energy)
                 for R, m in zip(chain.radii, chain.materials)]
        out += [(f"groove flats of {name.replace('contact', 'sphere')}", mu)
                for name, mu in _runs("contact", flats)]
    return out


def _runs(what: str, values) -> list[tuple[str, float]]:
    """Consecutive equal values merged: ('contacts 1-14', mu), ('contact 15', mu)."""
    out, start = [], 0
    for k in range(1, len(values) + 1):
        if k == len(values) or values[k] != values[start]:
            span = f"{what} {start + 1}" if k - start == 1 else f"{what}s {start + 1}-{k}"
            out.append((span, values[start]))
            start = k
    return out


def validate_notes(scene) -> list[str]:
    """``granchain validate``'s lines: each adhesive contact's Tabor parameter."""
    st = scene.setting(law.SPEC.name)
    parts = "; ".join(f"{name} {mu:.3g}" for name, mu in contacts(scene))
    return [f"adhesion ({st.model}, gamma = {st.surface_energy:g} J/m^2): Tabor's parameter "
            f"mu = (R* (2 gamma)^2 / (E*^2 z0^3))^(1/3), z0 = {Z0 * 1e9:g} nm: {parts}"]


def validate_warnings(scene) -> list[str]:
    """``granchain validate``'s warnings: contacts where the chosen model is outside its
    regime on Johnson & Greenwood (1997)'s adhesion map."""
    st = scene.setting(law.SPEC.name)
    out = []
    for name, mu in contacts(scene):
        why = regime(st.model, mu)
        if why:
            out.append(f"adhesion.model {st.model} at {name}: Tabor's parameter mu = {mu:.3g} "
                       f"is outside the model's regime on Johnson & Greenwood (1997)'s "
                       f"adhesion map; {why}")
    return out
