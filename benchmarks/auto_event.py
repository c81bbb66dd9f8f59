"""method auto on gapped chains: its pick against the fixed step it takes without the event
method, measured side by side.

For each case (316, 15 spheres, every effect, uniform gaps, 8 realisations) and each
tolerance, resolves ``integrator: {method: auto, tolerance}`` twice: with the packaged cost
model, and with the same model less its event rows. Runs both settings (a one-chain run of
each first, so no compile is timed) and prints the setting, the force evaluations and the
wall time per chain, and the ratios fixed / auto. Every number printed is measured in this
run; timings share the machine with whatever else runs, compare ratios only.

    PYTHONPATH=. python benchmarks/auto_event.py
"""
from __future__ import annotations

import time

from granchain import costmodel, runplan
from granchain.scene import scene_from_dict
from granchain.scenekeys import TOLERANCE_METHODS
from granchain.simulate import run_scene

ALL = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
CASES = ((190, 0.01), (1000, 0.1), (100, 0.01))      # (mean gap nm, striker m/s)
TOLERANCES = (1e-3, 1e-5)
CHAINS = 8


def without_event(model: costmodel.CostModel) -> costmodel.CostModel:
    keep = model.columns["method"] != "event"
    return costmodel.CostModel({k: v[keep] for k, v in model.columns.items()}, model.provenance)


def measure(scene):
    run_scene(scene.derive(ensemble={"realisations": 1}))       # compile outside the timing
    t = time.perf_counter()
    runs = run_scene(scene)
    wall = time.perf_counter() - t
    return sum(r.force_evaluations for r in runs) / len(runs), wall / len(runs)


def setting(scene) -> str:
    if scene.method in TOLERANCE_METHODS:
        return f"{scene.method} tol {scene.tolerance:g}"
    return f"{scene.method} dt {scene.dt:.3g} s"


def main() -> int:
    model = costmodel.load_model()
    models = (("auto", model), ("without event", without_event(model)))
    print(f"{'gap nm':>6} {'v m/s':>5} {'tol':>6}  {'model':14s} {'setting':28s} "
          f"{'evals/chain':>11} {'wall/chain s':>12}")
    for gap, v in CASES:
        for tol in TOLERANCES:
            raw = {"material": "ss316", "striker": {"velocity": v}, "effects": ALL,
                   "ensemble": {"realisations": CHAINS},
                   "gaps": {"distribution": "uniform", "mean": gap * 1e-9, "seed": 7},
                   "integrator": {"method": "auto", "tolerance": tol}}
            got = []
            for label, m in models:
                sc = runplan.resolve_auto(scene_from_dict(raw), m)
                evals, wall = measure(sc)
                got.append((evals, wall))
                print(f"{gap:6g} {v:5g} {tol:6g}  {label:14s} {setting(sc):28s} "
                      f"{evals:11.0f} {wall:12.4g}")
            (ea, wa), (ef, wf) = got
            print(f"{'':21s} without event / auto: force evaluations {ef / ea:.2f}x, wall {wf / wa:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
