"""What each feature of the field's chains costs the fixed-step block kernels, side by
side in one process.

    python benchmarks/heterogeneous.py [--chains 300] [--repeats 3]

The gaps-20nm-440c ensemble with every effect (rolling k_roll = 1e3 N/m), Verlet at 1 ns,
t_end auto, as the uniform chain and with one feature at a time: dimer radii (150/120 um),
alternating 440C / 52100 steel, a tungsten-carbide striker, an 440C end wall, then all
four. The settings take turns ``--repeats`` times and the fastest run of each counts (the
machines are shared). Prints particle-steps per second and the ratio to the uniform
chain. Every chain runs the same kernels (each sphere's parameters are rows of its
per-chain array in every case), so a ratio below 1 is the work the physics asks for
(contacts that stay closed run the friction laws), not an overhead of the rows; the
breakdown tells which feature brings it.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from granchain.engines import reference
from granchain.scene import load_scene
from granchain.simulate import member_gaps, members

R = ", ".join(["1.5e-4", "1.2e-4"] * 7 + ["1.5e-4"])
M = ", ".join(["ss440c", "chrome_steel_52100"] * 7 + ["ss440c"])
ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"
CASES = {"uniform": [], "dimer radii": [f"chain.radius=[{R}]"],
         "two steels": [f"chain.materials=[{M}]", "material=null"],
         "WC striker": ["striker.material=tungsten_carbide"], "end wall": ["walls.end=ss440c"]}
CASES["all four"] = [s for k in ("dimer radii", "two steels", "WC striker", "end wall")
                     for s in CASES[k]]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    base = [f"ensemble.realisations={args.chains}", f"effects={ALL}", "rolling.k_roll=1000.0",
            "integrator.method=verlet"]
    prep = {}
    for name, extra in CASES.items():
        sc = load_scene("granchain/scenes/gaps-20nm-440c.yaml", base + extra)
        mem = members(sc)
        gaps, vs = member_gaps(sc, mem), np.array([m.v_striker for m in mem])
        list(reference.run(sc, gaps[:2], vs[:2], progress=False))      # compile
        prep[name] = (sc, gaps, vs)
    best, work = {k: np.inf for k in CASES}, {}
    for _ in range(args.repeats):
        for name, (sc, gaps, vs) in prep.items():
            t0 = time.perf_counter()
            tr = list(reference.run(sc, gaps, vs, progress=False))
            best[name] = min(best[name], time.perf_counter() - t0)
            work[name] = sum(t.steps for t in tr) * sc.n
    rate0 = work["uniform"] / best["uniform"]
    print(f"{args.chains} chains x 15 spheres, every effect, Verlet 1 ns; fastest of "
          f"{args.repeats}")
    for name in CASES:
        rate = work[name] / best[name]
        print(f"{name:12s}: {best[name]:.2f} s, {rate / 1e6:.0f} M particle-steps/s, "
              f"{rate / rate0:.0%} of the uniform chain's rate", flush=True)


if __name__ == "__main__":
    main()
