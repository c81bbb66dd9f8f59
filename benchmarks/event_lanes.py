"""The event method in SIMD lanes against one chain per thread and against the fixed-step
block Verlet kernel, side by side in one run.

    python benchmarks/event_lanes.py [--chains 512] [--repeats 2] [--lanes 8 16]

Gap-sweep chains (440C, 15 spheres, every effect of Eq. 5.1, uniform gaps, t_end auto) at
three (mean gap, striker speed) points of the chapter's sweep. For each: the event method
at tolerance 1e-6 in lanes (``events.run_events_lanes``, each width of ``--lanes``) and one
chain per thread (``events.run_events``), which give the same result bit for bit (checked
here on v_max, steps and force evaluations), and velocity Verlet at 1 ns in blocks
(``kernels.run_blocks``, observables on the fly). The settings take turns ``--repeats``
times and the fastest run of each counts. Prints particle-force evaluations per second
(force evaluations x spheres / wall time) of each, the ratios lanes / one chain and
block Verlet / lanes (the event method's throughput against the fixed-step kernel's: its
Runge-Kutta stages and per-lane event logic cost more per force evaluation than Verlet's
kick-drift-kick), and the ratio of the wall times Verlet / lanes on the same chains (what
a run costs: the event method needs far fewer force evaluations). Every number printed is measured in this run; timings share the machine
with whatever else runs, compare ratios only.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from granchain.engines import reference
from granchain.scene import scene_from_dict

ALL = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
CASES = ((20e-9, 0.1), (190e-9, 0.01), (100e-9, 1.0))


def _scene(method: dict, v: float):
    return scene_from_dict({
        "name": "sweep", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
        "striker": {"velocity": v}, "effects": ALL, "probes": [2, 13],
        "gaps": {"distribution": "uniform", "mean": 20e-9, "seed": 1},
        "integrator": method})


def _run(scene, gaps, vs, **kw):
    t0 = time.perf_counter()
    out = list(reference.run(scene, gaps, vs, progress=False, trace=False, **kw))
    return time.perf_counter() - t0, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--lanes", type=int, nargs="+", default=[8, 16])
    a = ap.parse_args(argv)
    event = {"method": "event", "tolerance": 1e-6}
    verlet = {"method": "verlet", "dt": 1e-9}
    print(f"440C, 15 spheres, every effect, {a.chains} chains, t_end auto; particle-force "
          "evaluations per second (M/s), fastest of the repeats")
    head = "".join(f"{'lanes ' + str(w):>10}" for w in a.lanes)
    print(f"{'gap nm':>7} {'v m/s':>6} {'one chain':>10}{head} {'verlet':>9} "
          f"{'lanes/one':>10} {'verlet/lanes':>13} {'wall verlet/lanes':>18}")
    for gap, v in CASES:
        rng = np.random.default_rng(7)
        gaps = rng.uniform(0.0, 2 * gap, (a.chains, 14))
        vs = np.full(a.chains, v)
        se, sv = _scene(event, v), _scene(verlet, v)
        for s in (se, sv):                       # compile and load outside the timing
            _run(s, gaps[:2], vs[:2])
        _run(se, gaps[:2], vs[:2], lanes=False)
        settings = {"one": (se, {"lanes": False})}
        for w in a.lanes:
            settings[f"lanes{w}"] = (se, {"lanes": True, "width": w})
        settings["verlet"] = (sv, {})
        best = {k: np.inf for k in settings}
        work = {}
        keys = {}
        for _ in range(a.repeats):
            for k, (s, kw) in settings.items():
                kw = dict(kw)
                width = kw.pop("width", None)
                if width is not None:
                    reference.EVENT_LANES = width
                wall, out = _run(s, gaps, vs, **kw)
                best[k] = min(best[k], wall)
                work[k] = sum(t.force_evaluations for t in out) * 15
                if s is se:
                    keys[k] = [(t.observed.v_max.tobytes(), t.steps, t.force_evaluations)
                               for t in out]
        same = all(keys[k] == keys["one"] for k in keys)
        rate = {k: work[k] / best[k] / 1e6 for k in settings}
        top = max((k for k in settings if k.startswith("lanes")), key=lambda k: rate[k])
        cols = "".join(f"{rate['lanes' + str(w)]:10.1f}" for w in a.lanes)
        print(f"{gap * 1e9:7.0f} {v:6.2f} {rate['one']:10.1f}{cols} {rate['verlet']:9.1f} "
              f"{rate[top] / rate['one']:10.2f} {rate['verlet'] / rate[top]:13.2f} "
              f"{best['verlet'] / best[top]:18.2f}"
              + ("" if same else "  LANES DIFFER FROM ONE CHAIN PER THREAD"))


if __name__ == "__main__":
    main()
