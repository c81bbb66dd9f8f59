"""The workflow's cost estimates against measured run times, per study scene.

    python benchmarks/estimates.py [--preset full] [--study adhesion] [--scenes 6]
                                   [--realisations 2] [--seed 0] [--match TEXT]
                                   [--method event --tolerance 1e-6]

The workflow cuts each study into jobs balanced by estimated cost, and on SLURM a job's
wall-clock limit is three times its estimate (``workflow.batches.runtime_minutes``): an
estimate far below the truth gets a job killed. For each chosen study of the preset, a
random sample of ``--scenes`` of its scenes (the most expensive by estimate always
among them) runs ``--realisations`` realisations at every striker speed, as a batch job
runs them (``workflow.run.run_members``, reference engine, one thread), each scene in
turn in this process; a scene whose integrator method (under auto, any speed's) is new
to the process runs once untimed first, which compiles its kernels. ``--scenes 0``: every
scene, and the whole study's time projected from them, each scene's measured time per
realisation times its realisations. ``--method``/``--tolerance`` run the studies with
another setting than the preset's; ``--match`` keeps the scenes whose name holds the
text. Prints per scene the estimate (``workflow.batches.realisation_cost`` x
realisations), the measured wall time, their ratio measured / estimated, the measured
time over the job limit's allowance (``realisation_limit``: every chain at its cap where
a law can hold it there) and the runs' statuses, then per study the median and largest
ratios. Every number is measured in this run on this machine; the estimates are the
package's as shipped.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from collections import Counter

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from granchain.errors import GranchainError  # noqa: E402
from granchain.workflow.batches import realisation_cost, realisation_limit  # noqa: E402
from granchain.workflow.config import read_config  # noqa: E402
from granchain.workflow.presetplan import Plan  # noqa: E402
from granchain.workflow.run import run_members  # noqa: E402

CONFIG = os.path.join(os.path.dirname(__file__), "..", "config", "config.yaml")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="full")
    ap.add_argument("--study", nargs="+", default=None,
                    help="studies to sample (default: every ensemble study of the preset)")
    ap.add_argument("--scenes", type=int, default=6,
                    help="scenes sampled per study (0: every scene, and the study's time "
                         "projected from them)")
    ap.add_argument("--realisations", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--method", default=None,
                    help="run the chosen studies with this integrator method instead of "
                         "the preset's (with --tolerance for adaptive, event and auto)")
    ap.add_argument("--tolerance", type=float, default=None)
    ap.add_argument("--match", default=None,
                    help="run only the scenes whose name contains this text")
    a = ap.parse_args(argv)
    config = read_config(CONFIG, a.preset)
    if a.method is not None:
        studies = config["presets"][a.preset]["studies"]
        for study in a.study or list(studies):
            studies[study]["method"] = a.method
            if a.tolerance is not None:
                studies[study]["tolerance"] = a.tolerance
    try:
        plan = Plan.build(config)
    except GranchainError as e:         # a --method the study does not take, say
        raise SystemExit(f"estimates.py: {e}") from None
    rng = np.random.default_rng(a.seed)
    print(f"preset {a.preset}; load average {os.getloadavg()[0]:.1f}; one thread; "
          f"{a.realisations} realisation(s) per scene, every striker speed", flush=True)
    warmed: set[str] = set()
    for study in a.study or [s for s in plan.studies if s != "packed_trace"]:
        scenes = [ss for ss in plan.scenes[study] if "reference" in ss.engines
                  and (a.match is None or a.match in ss.scene.name)]
        if not scenes:
            continue
        est = np.array([realisation_cost(ss, "reference") for ss in scenes])
        pick = {int(np.argmax(est))}
        rest = [i for i in range(len(scenes)) if i not in pick]
        every = a.scenes <= 0 or a.scenes >= len(scenes)
        pick = set(range(len(scenes))) if every else pick | set(
            rng.choice(rest, a.scenes - 1, replace=False).tolist())
        ratios, over, whole = [], [], 0.0
        for i in sorted(pick):
            ss = scenes[i]
            reals = list(range(min(a.realisations, ss.scene.realisations)))
            methods = {sp.scene.method for sp in ss.plan.speeds}
            if not methods <= warmed:       # a method's first call compiles its kernel
                run_members(ss.scene, "reference", realisations=reals[:1], threads=1)
                warmed |= methods
            t0 = time.perf_counter()
            runs = run_members(ss.scene, "reference", realisations=reals, threads=1)
            wall = time.perf_counter() - t0
            e = est[i] * len(reals)
            cap = realisation_limit(ss, "reference") * len(reals)
            ratios.append(wall / e)
            over.append(wall / cap)
            whole += wall / len(reals) * ss.scene.realisations
            status = Counter(r.status for r in runs)
            print(f"{study:15s} {ss.scene.name:45s} estimate {e:8.2f} s, measured "
                  f"{wall:8.2f} s, measured / estimate {wall / e:7.2f}, measured / limit "
                  f"{wall / cap:5.2f}; {dict(status)}", flush=True)
        print(f"{study:15s} measured / estimate: median {statistics.median(ratios):.2f}, "
              f"largest {max(ratios):.2f}; measured / limit: largest {max(over):.2f} "
              f"({len(ratios)} scenes; the study's estimate "
              f"{sum(b.est_seconds for b in plan.batches[study]) / 60:.1f} core-min)",
              flush=True)
        if every:
            print(f"{study:15s} every scene at its realisations, projected from those run: "
                  f"{whole / 60:.1f} core-min", flush=True)


if __name__ == "__main__":
    main()
