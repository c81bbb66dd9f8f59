"""The event method in SIMD lanes against one chain per thread and against the fixed-step
block Verlet kernel, side by side in one run.

    python benchmarks/event_lanes.py [--chains 512] [--repeats 2] [--lanes 8 16]
    python benchmarks/event_lanes.py --old-ref main [--chains 512] [--repeats 3]

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

With ``--old-ref REF``: the event method in lanes (the default width) and block Verlet of
this tree against the tree at REF (extracted with ``git archive`` into a temporary
directory), each case in its own process per tree, the trees taking turns ``--repeats``
times after a warm-up run of each tree (the compile); prints each tree's particle-force
evaluations per second (fastest run), their ratio new / old, each tree's Verlet / event
ratio, the process CPU seconds of the event runs, and whether the two trees give the
same chains bit for bit (v_max, steps, force evaluations).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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


def _worker(case: int, chains: int) -> None:
    """One case on the tree on sys.path: prints the event method's (lanes) and block
    Verlet's wall and CPU seconds, their work and a digest of the event chains."""
    gap, v = CASES[case]
    gaps = np.random.default_rng(7).uniform(0.0, 2 * gap, (chains, 14))
    vs = np.full(chains, v)
    out = {}
    for name, method in (("event", {"method": "event", "tolerance": 1e-6}),
                         ("verlet", {"method": "verlet", "dt": 1e-9})):
        s = _scene(method, v)
        _run(s, gaps[:2], vs[:2])                 # compile and load outside the timing
        c0 = time.process_time()
        wall, res = _run(s, gaps, vs)
        out[name] = {"wall": wall, "cpu": time.process_time() - c0,
                     "work": sum(t.force_evaluations for t in res) * 15}
        if name == "event":
            h = hashlib.sha256()
            for t in res:
                h.update(t.observed.v_max.tobytes())
                h.update(np.array([t.steps, t.force_evaluations]).tobytes())
            out["digest"] = h.hexdigest()
    print(json.dumps(out))


def _compare(ref: str, chains: int, repeats: int) -> None:
    """This tree against the tree at ref, case by case, each run in its own process."""
    root = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory(prefix="granchain-event-lanes-") as tmp:
        old = Path(tmp) / "old"
        old.mkdir()
        arch = subprocess.run(["git", "-C", str(root), "archive", ref], check=True,
                              capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=arch, check=True)
        trees = {"new": root, "old": old}

        def run(tree, case):
            # a cache directory with no ahead-of-time module: both trees run numba's JIT
            # kernels (on one thread a tree with the module built would run it instead)
            env = dict(os.environ, PYTHONPATH=str(trees[tree]),
                       GRANCHAIN_CACHE_DIR=str(Path(tmp) / f"cache-{tree}"))
            got = subprocess.run([sys.executable, __file__, "--worker", str(case),
                                  "--chains", str(chains)], env=env, check=True,
                                 capture_output=True, text=True).stdout
            return json.loads(got.strip().splitlines()[-1])

        print(f"440C, 15 spheres, every effect, {chains} chains, t_end auto; this tree "
              f"against {ref}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
              "cores; particle-force evaluations per second (M/s), fastest of "
              f"{repeats}; event CPU s: the event run's process CPU time, fastest")
        print(f"{'gap nm':>7} {'v m/s':>6} {'event new':>10} {'event old':>10} "
              f"{'new/old':>8} {'verlet':>8} {'verlet/event new':>17} "
              f"{'verlet/event old':>17} {'event CPU s new/old':>20}")
        for tree in trees:                        # the compile, outside the timing
            run(tree, 0)
        for case, (gap, v) in enumerate(CASES):
            best = {(t, k): np.inf for t in trees for k in ("event", "verlet", "cpu")}
            work, digest = {}, {}
            for _ in range(repeats):
                for tree in trees:
                    r = run(tree, case)
                    for k in ("event", "verlet"):
                        best[tree, k] = min(best[tree, k], r[k]["wall"])
                        work[tree, k] = r[k]["work"]
                    best[tree, "cpu"] = min(best[tree, "cpu"], r["event"]["cpu"])
                    digest[tree] = r["digest"]
            rate = {key: work[key] / best[key] / 1e6 for key in work}
            vr = max(rate["new", "verlet"], rate["old", "verlet"])
            print(f"{gap * 1e9:7.0f} {v:6.2f} {rate['new', 'event']:10.1f} "
                  f"{rate['old', 'event']:10.1f} "
                  f"{rate['new', 'event'] / rate['old', 'event']:8.2f} {vr:8.1f} "
                  f"{rate['new', 'verlet'] / rate['new', 'event']:17.2f} "
                  f"{rate['old', 'verlet'] / rate['old', 'event']:17.2f} "
                  f"{best['new', 'cpu']:9.2f} / {best['old', 'cpu']:.2f}"
                  + ("" if digest["new"] == digest["old"] else "  TREES DIFFER"), flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--lanes", type=int, nargs="+", default=[8, 16])
    ap.add_argument("--old-ref", default=None,
                    help="compare with the tree at this git revision (git archive)")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker is not None:
        _worker(a.worker, a.chains)
        return
    if a.old_ref:
        _compare(a.old_ref, a.chains, a.repeats)
        return
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
