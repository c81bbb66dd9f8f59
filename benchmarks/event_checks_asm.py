"""The event method's per-lane tests in the machine code: are their loops over the lanes
vectorised?

    python benchmarks/event_checks_asm.py [--lanes 16]

Compiles, for a block of ``--lanes`` chains (440C, 15 spheres, every effect of Eq. 5.1),
the event tests the lane kernel runs over a whole block (``events._predict``,
``events._straddle``, ``compose.locate`` with the groove's law inlined,
``eventobs._peak_inside``) afresh with numba's options of the lane kernel (no cache: a
function loaded from numba's cache cannot be inspected), and counts in each one's
assembly (numba's ``inspect_asm``) the packed double-precision instructions on 256- and
512-bit registers: compares (``vcmp*pd``), blends (``vblendm*``), arithmetic
(``vmul/vadd/vsub/vdiv/vsqrt pd``). A loop with a branch per lane compiles to scalar
``*sd`` instructions only; these counts are what shows that the tests run in SIMD.
Nothing is timed.
"""
from __future__ import annotations

import argparse
import re
from collections import Counter

import numpy as np
from numba import njit

from granchain.effects import physics_terms
from granchain.engines import codes, compose, eventobs, events
from granchain.engines.reference import Layout, chain_rows, pack
from granchain.scene import scene_from_dict

ALL = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
KINDS = {"compare": r"vcmp\w*pd", "blend": r"vblendm\w*", "arith": r"v(mul|add|sub|div|sqrt)pd"}


def _counts(asm: str) -> Counter:
    out = Counter()
    for line in asm.splitlines():
        if not re.search(r"%[yz]mm", line):
            continue
        for k, pat in KINDS.items():
            if re.search(r"\b" + pat + r"\b", line):
                out[k] += 1
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, default=16)
    a = ap.parse_args(argv)
    scene = scene_from_dict({
        "name": "asm", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
        "striker": {"velocity": 0.01}, "effects": ALL, "probes": [2, 13],
        "integrator": {"method": "event", "tolerance": 1e-6}})
    terms = physics_terms(scene)
    L = a.lanes
    P, FL = pack(terms)
    LO = Layout.of(terms).LO
    ny, n = Layout.of(terms).ny, terms.n
    G = np.ascontiguousarray(chain_rows(terms, np.zeros((L, n - 1)), scene, None).T)
    y = np.zeros((ny, L))
    h = np.full(L, 1e-9)
    act = np.ones(L, dtype=np.bool_)
    tau = np.empty(L)
    VMAX = np.zeros((L, n))
    lane_b = np.arange(L, dtype=np.int64)
    c = np.empty(5)
    opts = {"error_model": "numpy", "boundscheck": False}
    locate = compose.locate

    def run_locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau):
        locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau)

    probes = {
        "events._predict": (events._predict.py_func, (y, y, G, LO, n, 1e-15, 1e-9, tau)),
        "events._straddle": (events._straddle.py_func, (y, y, G, LO, n, 1e-15, h, act, tau)),
        "compose.locate (groove_friction)": (run_locate, (y, y, y, y, G, P, FL, LO, n, h,
                                                          1e-6, act, tau)),
        "eventobs._peak_inside": (eventobs._peak_inside.py_func,
                                  (y, y, y, y, LO, n, h, VMAX, lane_b, 1e-12, c, act, tau)),
    }
    print(f"packed double-precision instructions on ymm/zmm registers, {L} lanes "
          f"(every effect, 15 spheres; groove friction on: {bool(FL[codes.F_GROOVE_FRICTION])})")
    print(f"{'function':34} {'compares':>9} {'blends':>7} {'arithmetic':>11}")
    for name, (fn, args) in probes.items():
        jf = njit(**opts)(fn)
        jf(*args)
        asm = "\n".join(jf.inspect_asm().values())
        k = _counts(asm)
        print(f"{name:34} {k['compare']:9d} {k['blend']:7d} {k['arith']:11d}")


if __name__ == "__main__":
    main()
