"""Materials are data (granchain/data/materials.yaml), not code."""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import yaml


@dataclass(frozen=True)
class Material:
    name: str
    E: float    # Young's modulus, Pa
    nu: float   # Poisson ratio
    rho: float  # density, kg/m^3

    @property
    def G(self) -> float:
        """Shear modulus, Pa."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def c0(self) -> float:
        """Nesterenko's c: c^2 = 2E / (pi rho (1 - nu^2)), m/s."""
        return math.sqrt(2.0 * self.E / (math.pi * self.rho * (1.0 - self.nu**2)))


@lru_cache(maxsize=1)
def library() -> dict[str, Material]:
    text = resources.files("granchain").joinpath("data/materials.yaml").read_text()
    raw = yaml.safe_load(text)
    return {k: Material(k, float(v["E"]), float(v["nu"]), float(v["rho"])) for k, v in raw.items()}
