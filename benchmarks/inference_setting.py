"""The integrator of an inference grid, node by node: CPU per chain and error of each
setting against a fine reference, on the shipped joint example's nodes.

    python benchmarks/inference_setting.py [--realisations 32] [--gaps-nm 0,20,80,245,500]
                                           [--event 1e-4,1e-3]

For each mean gap (e = 0.92, the example's three striker speeds, designed realisations as
the grid's) runs the setting the example's stated errors ask for (``choose_setting``: RK4
at 7.17e-8 s), RK4 at twice that step, Verlet at a half and a quarter of it, and with
``--event`` the event method at those tolerances (its kernel compiles on first use:
minutes), and RK4 at an eighth of the step as the reference. Prints per node and setting
the CPU seconds per chain (``resource.getrusage`` around ``simulate.run_scene``: the
kernel's threads and the Python around it) and the 95th percentile and maximum over the
chains of the relative error of dt_front, v_max_1 and v_max_2 against the reference, next
to what the data ask for (``v_g_tolerance``: 0.1 x the smallest stated relative error)."""
from __future__ import annotations

import argparse
import os
import resource
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _cpu() -> float:
    """This process's CPU seconds (user + system)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def example_setting():
    """The shipped joint example's completed base scene with the integrator its stated
    errors ask for, and that choice (``setting.choose_setting``)."""
    sys.path.insert(0, str(ROOT))
    from granchain.inference.grid import complete_base
    from granchain.inference.measurements import read_measurements
    from granchain.inference.setting import choose_setting
    from granchain.scene import load_scene
    meas = read_measurements(ROOT / "measurements/example_restitution.csv", peaks=True)
    base, _ = complete_base(load_scene(ROOT / "measurements/example_restitution.yaml"), meas)
    base, chosen = choose_setting(base, meas, peaks=True)
    return base, chosen


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realisations", type=int, default=32)
    ap.add_argument("--gaps-nm", default="0,20,80,245,500")
    ap.add_argument("--event", default="", help="event tolerances, comma-separated")
    a = ap.parse_args(argv)
    base, chosen = example_setting()
    from granchain.gapdesign import EMPHASIS, design
    from granchain.inference.grid import joint_scene
    from granchain.runplan import plan_run
    from granchain.simulate import run_scene
    dt, R = chosen["dt_s"], a.realisations
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; chosen: "
          f"{chosen['reason']}", flush=True)
    settings = {f"rk4 {dt:.3g}": {"method": "rk4", "dt": dt},
                f"verlet {dt:.3g}": {"method": "verlet", "dt": dt},
                f"verlet {dt / 2:.3g}": {"method": "verlet", "dt": dt / 2},
                f"verlet {dt / 4:.3g}": {"method": "verlet", "dt": dt / 4}}
    for tol in filter(None, a.event.split(",")):
        settings[f"event {float(tol):g}"] = {"method": "event", "tolerance": float(tol)}
    designed = design(base, R, EMPHASIS)

    def run(g, integ):
        scene = plan_run(joint_scene(base, g, 0.92, R).derive({"integrator": integ}),
                         per_speed=False).scene
        run_scene(scene.derive({"ensemble": {"realisations": 1}}), gaps=designed.gaps(g)[:1],
                  progress=lambda k: None)                    # compile / load the kernel
        c0 = _cpu()
        res = run_scene(scene, gaps=designed.gaps(g), progress=lambda k: None)
        cpu = (_cpu() - c0) / len(res)
        X = np.array([[r.dt_front, r.v_max_1, r.v_max_2] for r in res])
        return cpu, X

    ask = chosen["v_g_tolerance"]
    for gnm in (float(x) for x in a.gaps_nm.split(",")):
        g = gnm * 1e-9
        _, ref = run(g, {"method": "rk4", "dt": dt / 8})
        parts = []
        for name, integ in settings.items():
            cpu, X = run(g, integ)
            with np.errstate(invalid="ignore", divide="ignore"):
                e = np.abs(X - ref) / np.abs(ref)
            both = np.isfinite(X) == np.isfinite(ref)
            e = np.where(np.isfinite(e), e, np.where(both, 0.0, np.inf))
            p95, mx = np.percentile(e, 95, axis=0), e.max(axis=0)
            parts.append(f"  {name:<16} {cpu * 1e3:6.2f} ms CPU/chain; rel. error p95 / max "
                         f"dt_front {p95[0]:.1e} / {mx[0]:.1e}, v_max_1 {p95[1]:.1e} / "
                         f"{mx[1]:.1e}, v_max_2 {p95[2]:.1e} / {mx[2]:.1e}")
        print(f"mean gap {gnm:g} nm ({3 * R} chains; asked: {ask:.2g} on v_g):", flush=True)
        print("\n".join(parts), flush=True)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
