"""The adhesion effect's leaf laws and theory, which ``effects.adhesion`` imports: the
pull-off force and distance of LAMMPS's ``dmt`` and ``jkr`` laws, the antiderivative of
the JKR force, the depth of a contact's well, and Tabor's parameter with Johnson &
Greenwood (1997)'s adhesion map (J. Colloid Interface Sci. 192, 326-333), which
``granchain validate`` prints and warns by. The laws marked ``spec.compiled`` call no
other marked function: the kernels compile them where ``effects.adhesion``'s laws call
them."""
from __future__ import annotations

import math

from ..materials import effective_modulus
from .spec import compiled

# JKR's pull-off distance over (R* gamma^2 / E*^2)^(1/3): (3 pi^2 / 16)^(1/3)
PULLOFF_PREFIX = (3.0 * math.pi ** 2 / 16.0) ** (1.0 / 3.0)


# the equilibrium separation of the surfaces' Lennard-Jones potential in Tabor's parameter
# (Johnson & Greenwood 1997: 0.3-0.4 nm), and the regimes of their adhesion map: JKR holds
# above JKR_TABOR, DMT below DMT_TABOR
Z0 = 0.3e-9
JKR_TABOR, DMT_TABOR = 5.0, 0.1


@compiled
def pulloff_distance(Rs, E, g):
    """JKR's pull-off distance delta_po (m, > 0): a closed contact opens at delta < -delta_po."""
    return PULLOFF_PREFIX * (Rs * g * g / (E * E)) ** (1.0 / 3.0)


@compiled
def pulloff_force(Rs, g, jkr):
    """F_po (N): 3 pi gamma R* (jkr), 4 pi gamma R* (dmt)."""
    return (3.0 if jkr else 4.0) * math.pi * g * Rs


@compiled
def jkr_work(Rs, E, g, a):
    """The antiderivative V(a) (J) of the JKR force over the overlap along the law's
    branch, as a function of the contact radius a: dV/da = F(a) d delta/da, V(a) = 8 E* a^5
    / (15 R*^2) - (8/3) sqrt(pi g E*) a^(7/2) / R* + 2 pi g a^2."""
    return (8.0 * E * a ** 5 / (15.0 * Rs * Rs)
            - 8.0 / 3.0 * math.sqrt(math.pi * g * E) * a ** 3.5 / Rs + 2.0 * math.pi * g * a * a)


def well_depth(model: str, K: float, Rs: float, E: float, g: float) -> float:
    """The energy (J, > 0) a contact of Hertz constant K, R*, E* releases into the motion
    of its spheres from first touch (delta = 0, the force's jump onto the law) down to the
    bottom of its well, where the force vanishes: -int_0^{delta_eq} F d delta.
    dmt: delta_eq = (F_po / K)^(2/3), depth (3/5) F_po delta_eq. jkr: along the law's
    branch from a_0 = (4 pi gamma R*^2 / E*)^(1/3) (delta = 0) to a_eq = (9 pi gamma R*^2
    / E*)^(1/3) (F = 0), V(a_0) - V(a_eq) with V :func:`jkr_work`."""
    if model == "dmt":
        F_po = pulloff_force(Rs, g, False)
        return 0.6 * F_po * (F_po / K) ** (2.0 / 3.0)
    a0 = (4.0 * math.pi * g * Rs * Rs / E) ** (1.0 / 3.0)
    a_eq = (9.0 * math.pi * g * Rs * Rs / E) ** (1.0 / 3.0)
    return jkr_work(Rs, E, g, a0) - jkr_work(Rs, E, g, a_eq)


# ---------------------------------------------------------------------------------------
# Tabor's parameter and the adhesion map
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


def runs(what: str, values) -> list[tuple[str, float]]:
    """Consecutive equal values merged: ('contacts 1-14', mu), ('contact 15', mu)."""
    out, start = [], 0
    for k in range(1, len(values) + 1):
        if k == len(values) or values[k] != values[start]:
            span = f"{what} {start + 1}" if k - start == 1 else f"{what}s {start + 1}-{k}"
            out.append((span, values[start]))
            start = k
    return out


def tabor_note(model: str, gamma: float, contacts) -> str:
    """``granchain validate``'s line of the (name, mu) of each adhesive contact."""
    parts = "; ".join(f"{name} {mu:.3g}" for name, mu in contacts)
    return (f"adhesion ({model}, gamma = {gamma:g} J/m^2): Tabor's parameter "
            f"mu = (R* (2 gamma)^2 / (E*^2 z0^3))^(1/3), z0 = {Z0 * 1e9:g} nm: {parts}")


def regime_warnings(model: str, contacts) -> list[str]:
    """``granchain validate``'s warnings: the (name, mu) contacts where ``model`` is
    outside its regime on Johnson & Greenwood (1997)'s adhesion map (:func:`regime`)."""
    out = []
    for name, mu in contacts:
        why = regime(model, mu)
        if why:
            out.append(f"adhesion.model {model} at {name}: Tabor's parameter mu = {mu:.3g} "
                       f"is outside the model's regime on Johnson & Greenwood (1997)'s "
                       f"adhesion map; {why}")
    return out


def contact_mus(r: dict, chain, gamma: float, groove: bool) -> list[tuple[str, float]]:
    """(name, Tabor's mu) of a chain's adhesive contacts at surface energy gamma, alike
    ones merged (:func:`runs`), from the law's rows ``r`` (``G_ADHESION_RSTAR``,
    ``G_ADHESION_EMIX``; the end wall's last): the sphere-sphere contacts (``contacts
    1-14``), the end wall, and with ``groove`` the groove's flats (each sphere on a flat
    of its own material)."""
    Rs, E = r["G_ADHESION_RSTAR"], r["G_ADHESION_EMIX"]
    out = runs("contact", [tabor(Rs[k], E[k], gamma) for k in range(chain.n - 1)])
    if chain.wall is not None:
        out.append(("end wall", tabor(Rs[-1], E[-1], gamma)))
    if groove:
        flats = [tabor(R, effective_modulus(m, m), gamma)
                 for R, m in zip(chain.radii, chain.materials)]
        out += [(f"groove flats of {name.replace('contact', 'sphere')}", mu)
                for name, mu in runs("contact", flats)]
    return out
