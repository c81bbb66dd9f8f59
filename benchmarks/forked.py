"""The ahead-of-time module in forked workers against numba's JIT threads, side by side.

    python benchmarks/forked.py [--chains 400] [--repeats 5]

Both run the same chains (gaps-20nm-440c: 20 nm uniform gaps, 0.1 m/s, every effect of
Eq. 5.1, t_end auto) by each method, measured on the fly (no trace), on all of this
machine's threads, each run a process of its own, the two ways taking turns:

- ``forked``: the ahead-of-time module built for this machine (``granchain warm-up`` into
  the usual cache), its parallel loop cut between forked processes (``engines.forked``);
- ``jit``: an empty ``$GRANCHAIN_CACHE_DIR`` (no module), so the same call runs numba's
  JIT kernels in threads, loaded from numba's cache (warmed before the turns).

For each it prints the kernels' wall time (the engine's own timer around its kernel calls,
``Trajectory.wall_s`` summed) and the whole process's, the medians over ``--repeats``
turns and their ratios jit / forked (above 1: the forked module is faster). Every
trajectory is compared too: the two ways must agree bit for bit.
"""
from __future__ import annotations

import argparse
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "granchain/scenes/gaps-20nm-440c.yaml")
METHODS = {"verlet": {"method": "verlet", "dt": 1e-9}, "rk4": {"method": "rk4", "dt": 1e-9},
           "adaptive": {"method": "adaptive", "tolerance": 1e-8},
           "event": {"method": "event", "tolerance": 1e-6}}

_RUN = """
import pickle, sys, time
import numpy as np
from granchain.engines import reference
from granchain.scene import load_scene
scene = load_scene(sys.argv[1]).derive(
    integrator=eval(sys.argv[2]),
    effects=["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"])
gaps = np.random.default_rng(11).uniform(0, 40e-9, (int(sys.argv[3]), scene.n - 1))
out = list(reference.run(scene, gaps, np.full(gaps.shape[0], 0.1), progress=False,
                         trace=False))
pickle.dump(([(t.status, t.steps, t.v, t.energy) for t in out],
             sum(t.wall_s for t in out), "numba" in sys.modules), open(sys.argv[4], "wb"))
"""


def _once(method: str, chains: int, env: dict, out: Path) -> tuple[float, float, list, bool]:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", _RUN, SCENE, repr(METHODS[method]), str(chains),
                    str(out)], env=env, check=True)
    wall = time.perf_counter() - t0
    res, kernel, numba = pickle.loads(out.read_bytes())
    return kernel, wall, res, numba


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--chains", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--methods", default=",".join(METHODS))
    args = ap.parse_args(argv)
    subprocess.run([sys.executable, "-m", "granchain.cli", "warm-up"], check=True,
                   stderr=subprocess.DEVNULL)
    with tempfile.TemporaryDirectory() as tmp:
        envs = {"forked": dict(os.environ),
                "jit": dict(os.environ, GRANCHAIN_CACHE_DIR=str(Path(tmp, "empty")))}
        print(f"{args.chains} chains, {os.cpu_count()} CPUs, load "
              f"{os.getloadavg()[0]:.1f}; medians of {args.repeats} turns")
        print(f"{'method':10s} {'kernel forked':>14s} {'kernel jit':>11s} {'ratio':>6s} "
              f"{'process forked':>15s} {'process jit':>12s} {'ratio':>6s}  same")
        for method in args.methods.split(","):
            for way, env in envs.items():           # numba's cache, the page cache
                _once(method, 8, env, Path(tmp, "warm.pkl"))
            times = {w: ([], []) for w in envs}
            same, numba = True, {}
            for _ in range(args.repeats):
                got = {}
                for way, env in envs.items():
                    k, w, res, numba[way] = _once(method, args.chains, env, Path(tmp, "o.pkl"))
                    times[way][0].append(k)
                    times[way][1].append(w)
                    got[way] = res
                import numpy as np
                same = same and all(
                    a[0] == b[0] and a[1] == b[1] and np.array_equal(a[2], b[2])
                    and np.array_equal(a[3], b[3]) for a, b in zip(got["forked"], got["jit"]))
            kf, kj = (statistics.median(times[w][0]) for w in envs)
            pf, pj = (statistics.median(times[w][1]) for w in envs)
            print(f"{method:10s} {kf:13.2f}s {kj:10.2f}s {kj / kf:6.2f} {pf:14.2f}s "
                  f"{pj:11.2f}s {pj / pf:6.2f}  {'yes' if same else 'NO'}"
                  f"{'' if not numba['forked'] else '  (numba imported on the forked side)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
