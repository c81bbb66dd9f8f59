"""Materials are data (granchain/data/materials.yaml), not code.

Two bodies in Hertz contact see the effective modulus E* of
1/E* = (1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j (:func:`effective_modulus`); a rigid wall
(:data:`RIGID`, E infinite) adds nothing to the sum.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import yaml

from .validate import Key

#: The fields of a material a scene writes as a mapping (``material``,
#: ``chain.materials[i]``, ``striker.material``; a wall's ``walls.end`` takes E and nu),
#: with the range of solids they must lie in: a value outside is refused naming its key.
FIELDS = {k.name: k for k in (
    Key("E", "Pa", "Young's modulus, from a soft gel's (1e3 Pa) to beyond diamond's "
        "(1.2e12 Pa).", lo=1e3, hi=1e13),
    Key("nu", "1", "Poisson ratio, in (-1, 0.5).", lo=-0.999, hi=0.4999),
    Key("rho", "kg/m^3", "Density, from an aerogel's to beyond osmium's (22590 kg/m^3).",
        lo=1.0, hi=1e5),
)}
FIELD_FIX = {"E": "give Young's modulus in Pa, from 1e3 to 1e13 (steel: 200e9)",
             "nu": "a Poisson ratio lies in (-1, 0.5)",
             "rho": "give the density in kg/m^3, from 1 to 1e5 (steel: 7800)"}


@dataclass(frozen=True)
class Material:
    name: str
    E: float    # Young's modulus, Pa
    nu: float   # Poisson ratio
    rho: float  # density, kg/m^3
    source: str = field(default="", compare=False, repr=False)   # where the values come from
    # the limiting contact pressure p_y of Thornton's elastic-perfectly plastic contact
    # (Pa, ``effects.plastic_contact``), None where the library has no sourced value
    yield_pressure: float | None = None

    @property
    def G(self) -> float:
        """Shear modulus, Pa."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def c0(self) -> float:
        """Nesterenko's c: c^2 = 2E / (pi rho (1 - nu^2)), m/s."""
        return math.sqrt(2.0 * self.E / (math.pi * self.rho * (1.0 - self.nu**2)))

    @property
    def bar_speed(self) -> float:
        """The longitudinal bar speed c = sqrt(E/rho) (m/s): the speed of a long
        compression wave along a rod of the material, the limit a chain of its spheres
        approaches as their contacts flatten (no wave along the chain is faster)."""
        return math.sqrt(self.E / self.rho)

    @property
    def rigid(self) -> bool:
        return math.isinf(self.E)

    def compliance(self) -> float:
        """(1 - nu^2)/E (1/Pa), this body's share of 1/E*; 0 for a rigid body."""
        return 0.0 if self.rigid else (1.0 - self.nu**2) / self.E


#: A wall that does not deform: 1/E_w = 0.
RIGID = Material("rigid", math.inf, 0.0, 0.0, "infinite stiffness (1/E = 0)")


def effective_modulus(a: Material, b: Material) -> float:
    """E* (Pa) of a Hertz contact of bodies of materials a and b:
    1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b. For two bodies of one material this is
    E/(2(1 - nu^2)), computed in that form."""
    if a == b and not a.rigid:
        return a.E / (2.0 * (1.0 - a.nu**2))
    return 1.0 / (a.compliance() + b.compliance())


@lru_cache(maxsize=1)
def library() -> dict[str, Material]:
    text = resources.files("granchain").joinpath("data/materials.yaml").read_text()
    raw = yaml.safe_load(text)
    return {k: Material(k, float(v["E"]), float(v["nu"]), float(v["rho"]), str(v.get("source", "")),
                        float(v["yield_pressure"]) if v.get("yield_pressure") is not None else None)
            for k, v in raw.items()}
