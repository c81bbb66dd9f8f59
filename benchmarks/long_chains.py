"""The event method on long gapped chains against the fixed-step Verlet block kernel, side by
side in one run.

    python benchmarks/long_chains.py [--n 15 100 500] [--chains 8] [--window-us 60]

For each chain length n: 440C, every effect of Eq. 5.1, uniform gaps of mean 20 nm,
v_s = 0.1 m/s, ``--chains`` realisations, the same simulated window (``--window-us`` us,
about the time the wave takes to cross 60 spheres, so every length does the same
physical work up to the length of chain the wave reaches). Runs the event method
(tolerance 1e-6, in lanes) and velocity Verlet at 1 ns (the presets' fixed step, blocks of
chains), after a warm-up call of each, and prints per method the steps per chain (trials
for the event method), force evaluations per chain and wall time, and the ratio
event / Verlet of the wall times.

The event method steps the whole chain at once: every contact onset and release anywhere
in the chain clips the common step, so its steps per simulated microsecond grow with the
number of contacts the wave has opened, while Verlet's do not. ``method: auto`` offers the
event method only on chains as long as the cost model measured it on
(``costmodel.CostModel.event_max_n``); this prints whether that rule is right at these
lengths. Every number printed is measured in this run; timings share the machine with
whatever else runs, compare ratios only.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from granchain.engines import reference
from granchain.scene import scene_from_dict

ALL = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]


def _scene(n: int, method: dict, t_end: float):
    return scene_from_dict({
        "name": f"long-{n}", "material": "ss440c", "chain": {"n": n, "radius": 150e-6},
        "striker": {"velocity": 0.1}, "effects": ALL, "probes": [2, n - 1],
        "gaps": {"distribution": "uniform", "mean": 20e-9, "seed": 1},
        "integrator": method, "t_end": t_end})


def _timed(scene, gaps, vs):
    list(reference.run(scene, gaps[:2], vs[:2], progress=False, trace=False))
    t0 = time.perf_counter()
    trajs = list(reference.run(scene, gaps, vs, progress=False, trace=False))
    wall = time.perf_counter() - t0
    steps = np.mean([t.steps + t.rejected for t in trajs])
    nev = np.mean([t.force_evaluations for t in trajs])
    return wall, steps, nev, {t.status for t in trajs}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[15, 100, 500])
    ap.add_argument("--chains", type=int, default=8)
    ap.add_argument("--window-us", type=float, default=60.0)
    a = ap.parse_args(argv)
    t_end = a.window_us * 1e-6
    print(f"440C, every effect, 20 nm uniform gaps, 0.1 m/s, {a.chains} chains, "
          f"simulated window {a.window_us:g} us")
    print(f"{'n':>5} {'method':>12} {'trials/chain':>13} {'f-evals/chain':>14} "
          f"{'wall s':>8} {'event/verlet':>13}")
    for n in a.n:
        rng = np.random.default_rng(n)
        gaps = rng.uniform(0.0, 40e-9, (a.chains, n - 1))
        vs = np.full(a.chains, 0.1)
        rows = {}
        for label, method in (("event 1e-6", {"method": "event", "tolerance": 1e-6}),
                              ("verlet 1 ns", {"method": "verlet", "dt": 1e-9})):
            rows[label] = _timed(_scene(n, method, t_end), gaps, vs)
        ratio = rows["event 1e-6"][0] / rows["verlet 1 ns"][0]
        for label, (wall, steps, nev, status) in rows.items():
            tail = f"{ratio:13.2f}" if label.startswith("event") else ""
            print(f"{n:5d} {label:>12} {steps:13.0f} {nev:14.0f} {wall:8.2f} {tail}"
                  + ("" if status <= {"done", "passed"} else f"  status {sorted(status)}"))


if __name__ == "__main__":
    main()
