"""air_drag: the chapter's empirical air drag on every sphere.

F = -m (v/T0 - v^2/L) (``as_printed``, the chapter's form) or -m (v/T0 - v|v|/L)
(``odd``). The printed form turns propulsive for v > L/T0 ~ 0.048 m/s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..units import lmp_float as _r, to_micro
from ..validate import Key
from . import slots as S
from .lanes import moving
from .spec import EffectSpec, compiled

# order -1: the drag is added to a sphere's force before the groove friction
SPEC = EffectSpec("air_drag", work="work_air_drag", work_slot="L_WORK_DRAG",
                  table_column="work_air_J", lammps_ledger="f_gd[3]",
                  params=("P_DRAG_T0", "P_DRAG_L"), flags=("F_AIR_DRAG", "F_DRAG_ODD"),
                  order=-1)


# The scene section of this effect, its defaults (the chapter's Chapter-4 constants), its
# keys' declarations and its validated settings (``settings``).
SECTION = "drag"
DEFAULTS = {"T0": 0.052, "L": 2.5e-3, "form": "as_printed"}
FORMS = ("as_printed", "odd")
KEYS = (
    Key("drag.T0", "s", "Time constant T0 of the drag law F = -m (v/T0 - v^2/L); the "
        "default is the chapter's fit (its Chapter 4). A drag that stops a sphere within a "
        "microsecond is no air drag (and overflows the explicit steps).", lo=1e-6),
    Key("drag.L", "m", "Length L of the drag law; the default is the chapter's fit (its "
        "Chapter 4). Below a micrometre the printed form's propulsive term v^2/L runs away.",
        lo=1e-6),
    Key("drag.form", "-", "`as_printed`: the chapter's Eq. 5.1 as printed, F = -m (v/T0 - "
        "v^2/L), which turns propulsive for v > L/T0 (about 0.048 m/s); `odd`: F = -m (v/T0 "
        "- v|v|/L), the form odd in v.", choices=FORMS),
)
_KEY = {k.name: k for k in KEYS}


@dataclass(frozen=True)
class Settings:
    T0: float         # s
    L: float          # m
    form: str         # as_printed | odd


def settings(sec: dict, given: frozenset, on: bool) -> Settings:
    """The validated ``drag`` section (a merged mapping); ``given``: the dotted keys the
    scene wrote; ``on``: whether air_drag is enabled."""
    return Settings(_KEY["T0"].number(sec["T0"]), _KEY["L"].number(sec["L"]),
                    _KEY["form"].choice(sec["form"], "form"))


@compiled
def force(m, v, T0, L, odd):
    """Drag force (N) on a sphere of mass m (kg) moving at v (m/s); scalar or array v."""
    q = v * abs(v) if odd else v * v
    return -m * (v / T0 - q / L)


@compiled
def forces(y, G, P, FL, LO, hist_dt, dy, f, shut):
    """The drag on every moving sphere (``spec.HOOKS['force']``) and its work rate."""
    n = int(P[S.P_N_SPHERES])
    L = y.shape[1]
    ov = LO[S.L_VEL]
    oM = S.G_MASS * n
    T0 = P[S.P_DRAG_T0]
    Ld = P[S.P_DRAG_L]
    odd = FL[S.F_DRAG_ODD] != 0
    owd = LO[S.L_WORK_DRAG]
    for l in range(L):
        dy[owd, l] = 0.0
    for i in range(n):
        if not moving(y, ov + i, L):
            continue
        for l in range(L):
            v = y[ov + i, l]
            m = G[oM + i, l]
            F = force(m, v, T0, Ld, odd)
            dy[ov + i, l] += F / m
            dy[owd, l] += F * v


@dataclass(frozen=True)
class AirDrag:
    T0: float
    L: float
    odd: bool

    def force(self, m, v):
        return force(m, np.asarray(v, dtype=float), self.T0, self.L, self.odd)


def build(scene) -> AirDrag:
    st = scene.setting(SPEC.name)
    return AirDrag(st.T0, st.L, st.form == "odd")


def kernel(ad: AirDrag) -> tuple[dict, dict]:
    """(parameters, flags) of the reference kernels, by slot name (``slots``)."""
    return {"P_DRAG_T0": ad.T0, "P_DRAG_L": ad.L}, {"F_AIR_DRAG": 1, "F_DRAG_ODD": int(ad.odd)}


def lammps_fix(ad: AirDrag) -> tuple[str, str]:
    """(comment, fix groove/drag arguments) of the deck."""
    return ("# drag: F = -m (v/T0 - v^2/L)" + (" with v|v| (odd)" if ad.odd else " (as printed)"),
            f"drag T0 {_r(to_micro(ad.T0, 'time'))} L {_r(to_micro(ad.L, 'length'))} "
            f"form {'odd' if ad.odd else 'as_printed'}")
