"""What a block of the fixed-step kernels costs per lane, and small batches at full width
against ``chunks.width``, side by side.

    python benchmarks/lanes.py [--repeats 3] [--effects every|adhesion]
                               [--wide [--chains 1000] [--lanes 32 64] [--spread 1]
                                       [--methods verlet rk4]]

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

With ``--wide``, instead: the widest block (``chunks.LANES``) on a large ensemble, the
ensemble of ``benchmarks/kernels.py`` (``--chains`` chains of gaps-20nm-440c, every
effect and rolling friction, t_end auto), velocity Verlet and RK4 at 1 ns, with each
value of ``--lanes`` in turn (the blocks then as ``chunks.width`` cuts them): the
thread's CPU seconds of the run, fastest of ``--repeats`` and the per-turn ratios
against the first value; the trajectories compared bit for bit. A block steps until its
last chain stops, so a wide block of chains of unlike lengths steps its finished lanes
longer: ``--spread S`` scales each chain's gaps by its own factor, uniform on [0, S]
(mean gaps from 0 to S x 20 nm in one chunk, as a gap sweep's or an inference grid's
chunks hold them; the chains sorted by expected length, as always).
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

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


def wide(chains: int, lanes: list[int], repeats: int, spread: float = 1.0,
         methods=("verlet", "rk4")) -> None:
    from granchain.scene import load_scene
    from granchain.simulate import member_gaps, members
    every = "[" + ", ".join(EVERY + ["rolling_friction"]) + "]"
    print(f"{chains} chains of gaps-20nm-440c, every effect, 1 ns, one thread; blocks of "
          f"at most LANES lanes, LANES = {', '.join(map(str, lanes))} in turn"
          + (f"; each chain's gaps scaled by a factor uniform on [0, {spread:g}]"
             if spread != 1.0 else ""))
    for method in methods:
        sc = load_scene(Path(__file__).resolve().parents[1] / "granchain/scenes/gaps-20nm-440c.yaml",
                        [f"ensemble.realisations={chains}", f"effects={every}",
                         "rolling.k_roll=1000.0", f"integrator.method={method}"])
        mem = members(sc)
        gaps, vs = member_gaps(sc, mem), np.array([m.v_striker for m in mem])
        if spread != 1.0:   # chains of unlike lengths, as a gap sweep's chunks hold
            gaps = gaps * np.random.default_rng(5).uniform(0.0, spread, (chains, 1))
        times = {w: [] for w in lanes}
        outs = {}
        for turn in range(repeats + 1):               # the first turn loads the kernels
            for w in lanes:
                chunks.LANES = chunks.WIDE = w     # every chunk's blocks up to w
                t0 = time.thread_time()
                outs[w] = list(reference.run(sc, gaps, vs, progress=False, trace=False))
                if turn:
                    times[w].append(time.thread_time() - t0)
        base = lanes[0]
        for w in lanes:
            same = all(np.array_equal(x.v, y.v) and x.steps == y.steps
                       for x, y in zip(outs[base], outs[w]))
            turns = sorted(a / b for a, b in zip(times[base], times[w]))
            print(f"   {method:6s} LANES = {w:3d}: {min(times[w]):6.2f} s; against LANES = "
                  f"{base}: fastest x{min(times[base]) / min(times[w]):.3f}, per-turn median "
                  f"x{float(np.median(turns)):.3f} (x{turns[0]:.3f}-x{turns[-1]:.3f}); "
                  f"bit-identical {same}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--effects", choices=["every", "adhesion"], default="every")
    ap.add_argument("--wide", action="store_true",
                    help="the widest block's value on a large ensemble (--chains, --lanes)")
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--lanes", type=int, nargs="+", default=[32, 64])
    ap.add_argument("--spread", type=float, default=1.0,
                    help="--wide: scale each chain's gaps by a factor uniform on [0, SPREAD] "
                         "(chains of unlike lengths in one chunk; default 1: the scene's gaps)")
    ap.add_argument("--methods", nargs="+", choices=["verlet", "rk4"], default=["verlet", "rk4"],
                    help="--wide: the fixed-step methods to time")
    a = ap.parse_args(argv)
    if a.wide:
        wide(a.chains, a.lanes, a.repeats, a.spread, a.methods)
        return
    scene = _scene(a.effects)
    full, narrow = chunks.width, chunks.width
    _run(scene, 1)                                     # load the kernels
    print(f"1. one block of L chains, {a.effects} effects, one thread")
    for lanes in (1, 2, 4, 8, 16, 32):
        chunks.width = lambda chains, threads, cap=None, w=lanes: w
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
                    chunks.width = lambda c, t, cap=None: min(chunks.LANES, max(c, chunks.LANES))
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
