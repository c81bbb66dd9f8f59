"""Where a grid node's CPU goes: the engine's trajectories against the Python that
``simulate.run_scene`` puts around them (summary, bounds, member fields).

    python benchmarks/inference_overhead.py [--gap-nm 20] [--realisations 256] [--repeats 3]

One node of the shipped joint example's grid (measurements/example_restitution.yaml at mean
gap ``--gap-nm``, e = 0.92, its three striker speeds, designed realisations, the integrator
its stated errors ask for: RK4 at 7.17e-8 s), kernels compiled (a first small call loads
them). Prints, as medians over ``--repeats``, CPU seconds per chain (``resource.getrusage``:
this process and the kernel's threads) of ``simulate.trajectories`` (the engine: kernel and
its own Python), of ``observables.summarize`` on those trajectories, of one
``dataclasses.replace`` and one ``observables.bounded`` per result, and of the whole
``simulate.run_scene``."""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics

from inference_setting import _cpu, example_setting  # noqa: E402  (this folder)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gap-nm", type=float, default=20.0)
    ap.add_argument("--realisations", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    base, chosen = example_setting()
    from granchain.collision import terms_of
    from granchain.gapdesign import EMPHASIS, design
    from granchain.gaps import members
    from granchain.inference.grid import joint_scene
    from granchain.observables import bounded, summarize
    from granchain.runplan import plan_run
    from granchain.simulate import run_scene, trajectories
    g, R = a.gap_nm * 1e-9, a.realisations
    scene = plan_run(joint_scene(base, g, 0.92, R), per_speed=False).scene
    gaps = design(base, R, EMPHASIS).gaps(g)
    plan = plan_run(scene)
    mem = members(plan.scene, None, gaps)
    list(trajectories(plan, mem[:2], trace=False, progress=False))    # load the kernel
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {len(mem)} "
          f"chains at {a.gap_nm:g} nm, {chosen['method']} at {chosen['dt_s']:.3g} s",
          flush=True)
    got: dict = {k: [] for k in ("trajectories", "summarize", "replace", "bounded",
                                 "run_scene")}
    n = len(mem)
    for _ in range(a.repeats):
        c = _cpu()
        trs = list(trajectories(plan, mem, trace=False, progress=False))
        got["trajectories"].append((_cpu() - c) / n)
        c = _cpu()
        ss = [summarize(t, scene.probes, terms_of(scene, t)) for _, t in trs]
        got["summarize"].append((_cpu() - c) / n)
        c = _cpu()
        rs = [dataclasses.replace(s, member=m.index, realisation=m.realisation)
              for s, (m, _) in zip(ss, trs)]
        got["replace"].append((_cpu() - c) / n)
        c = _cpu()
        [bounded(r, t.limits) for r, (_, t) in zip(rs, trs)]
        got["bounded"].append((_cpu() - c) / n)
        c = _cpu()
        run_scene(scene, gaps=gaps, progress=lambda k: None)
        got["run_scene"].append((_cpu() - c) / n)
    print("CPU per chain (median of the repeats): " + ", ".join(
        f"{k} {statistics.median(v) * 1e3:.3f} ms" for k, v in got.items()))
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
