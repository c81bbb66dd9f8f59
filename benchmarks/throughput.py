"""Reference-engine throughput on an ensemble, measured side by side in one run.

    python benchmarks/throughput.py [--chains 1000] [--scene SCENE] [--method rk4]

Prints particle-steps per second for (a) the whole ensemble in one batched call
(parallel over chains) and (b) the same chains one call each, and their ratio. The
machines are shared and noisy: compare the ratio, not absolute numbers across runs.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from granchain.engines import reference
from granchain.scene import load_scene
from granchain.simulate import member_gaps, members


def particle_steps(trajs, n):
    return sum(t.steps for t in trajs) * n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="granchain/scenes/gaps-20nm-440c.yaml")
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--serial", type=int, default=100, help="chains timed one call each")
    ap.add_argument("--method", default=None)
    args = ap.parse_args(argv)
    scene = load_scene(args.scene, [f"ensemble.realisations={args.chains}"])
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    vs = np.array([m.v_striker for m in mem])
    # warm-up: compile outside the timed region
    list(reference.run(scene, gaps[:2], vs[:2], method=args.method, progress=False))

    t0 = time.perf_counter()
    batch = list(reference.run(scene, gaps, vs, method=args.method, progress=False))
    t_batch = time.perf_counter() - t0
    ps_batch = particle_steps(batch, scene.n) / t_batch

    k = min(args.serial, len(mem))
    t0 = time.perf_counter()
    serial = []
    for i in range(k):
        serial.extend(reference.run(scene, gaps[i:i + 1], vs[i:i + 1], method=args.method,
                                    progress=False))
    t_serial = time.perf_counter() - t0
    ps_serial = particle_steps(serial, scene.n) / t_serial
    same = all(np.array_equal(a.v, b.v) for a, b in zip(batch[:k], serial))
    print(f"scene {scene.name}: {len(mem)} chains x {scene.n} particles, effects "
          f"{','.join(sorted(scene.effects))}, method {batch[0].info.method}, dt {batch[0].info.dt:g} s")
    print(f"batched : {len(mem)} chains in {t_batch:.2f} s, {sum(t.steps for t in batch) / len(mem):.0f} steps/chain, "
          f"{ps_batch:.3g} particle-steps/s")
    print(f"serial  : {k} chains in {t_serial:.2f} s, {ps_serial:.3g} particle-steps/s")
    print(f"ratio batched/serial throughput: {ps_batch / ps_serial:.2f}; "
          f"batched and serial trajectories identical: {same}")


if __name__ == "__main__":
    main()
