"""What a block of the fixed-step kernels costs per lane, and small batches at full width
against ``chunks.width``, side by side.

    python benchmarks/lanes.py [--repeats 3] [--effects every|adhesion]

The fixed-step methods step their chains in blocks of lanes, padding lanes included
(``engines.chunks``). On one thread, velocity Verlet at 1 ns on the packed 440C chain
(15 spheres, every effect of Eq. 5.1; with ``--effects adhesion`` also JKR adhesion at
1 J/m^2), run to a fixed 20 us:

1. one block of L lanes holding L chains, L = 1 .. 32: the time per block step and per
   chain step (best of ``--repeats``);
2. B chains (B = 1, 2, 5, 12) in blocks of ``chunks.LANES`` lanes (the last padded with
   lanes at rest) against blocks of ``chunks.width(B, 1)`` lanes, the two taking turns in
   this process: the ratio full / width (above 1: the narrow blocks are faster). Both
   give the same trajectories bit for bit (checked).
"""
from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from granchain.engines import chunks, reference  # noqa: E402
from granchain.scene import scene_from_dict  # noqa: E402

EVERY = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]


def _scene(effects: str):
    raw = {"name": "lanes", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
           "striker": {"velocity": 0.01}, "effects": list(EVERY), "probes": [2, 13],
           "integrator": {"method": "verlet", "dt": 1e-9}, "t_end": 2e-5}
    if effects == "adhesion":
        raw["effects"].append("adhesion")
        raw["adhesion"] = {"model": "jkr", "surface_energy": 1.0, "groove": False}
    return scene_from_dict(raw)


def _run(scene, chains: int):
    gaps = np.random.default_rng(3).uniform(0.0, 2e-9, (chains, scene.n - 1))
    vs = np.full(chains, 0.01)
    t0 = time.perf_counter()
    out = list(reference.run(scene, gaps, vs, progress=False, trace=False))
    return time.perf_counter() - t0, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--effects", choices=["every", "adhesion"], default="every")
    a = ap.parse_args(argv)
    scene = _scene(a.effects)
    full, narrow = chunks.width, chunks.width
    _run(scene, 1)                                     # load the kernels
    print(f"1. one block of L chains, {a.effects} effects, one thread")
    for lanes in (1, 2, 4, 8, 16, 32):
        chunks.width = lambda chains, threads, w=lanes: w
        best = min(_run(scene, lanes)[0] for _ in range(a.repeats))
        steps = 20_000
        print(f"   L = {lanes:2d}: {best / steps * 1e6:7.2f} us per block step, "
              f"{best / steps / lanes * 1e6:6.3f} us per chain step")
    print(f"2. B chains in blocks of {chunks.LANES} lanes against chunks.width(B, 1)")
    for chains in (1, 2, 5, 12):
        times = {"full": [], "width": []}
        outs = {}
        for _ in range(a.repeats):
            for name in ("full", "width"):
                if name == "full":
                    chunks.width = lambda c, t: min(chunks.LANES, max(c, chunks.LANES))
                else:
                    chunks.width = narrow
                dt, outs[name] = _run(scene, chains)
                times[name].append(dt)
        same = all(np.array_equal(x.v, y.v) and x.steps == y.steps
                   for x, y in zip(outs["full"], outs["width"]))
        f, w = min(times["full"]), min(times["width"])
        print(f"   B = {chains:2d}: full {f:6.3f} s, width {narrow(chains, 1):2d} lanes "
              f"{w:6.3f} s, full / width {f / w:5.2f}x, bit-identical {same}")
    chunks.width = full


if __name__ == "__main__":
    main()
