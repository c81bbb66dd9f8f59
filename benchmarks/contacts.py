"""The kernels' throughput with yielding and adhesive contacts against a Hertz chain,
side by side in one run.

    python benchmarks/contacts.py [--chains 300] [--repeats 3]

The ensemble: gaps-20nm-440c's chains (v_s = 0.1 m/s, uniform gaps of mean 20 nm, 15
spheres) in 316, whose contacts yield at that speed, on the reference engine, velocity
Verlet at 1 ns, t_end auto, ``--chains`` realisations, in three settings: Hertz alone
(``hertz``), Thornton's contacts at 316's library p_y (``plastic``: effects hertz and
plastic_contact) and LAMMPS's JKR law at gamma = 0.1 J/m^2 (``adhesive``: hertz and
adhesion). Each setting runs in its own process after a warm-up on two chains (the
compile is not timed), the three taking turns ``--repeats`` times; the fastest of each
counts. Prints particle-steps per second (the settings' chains run different numbers of
steps: a yielding chain's slower wave runs longer) and each rate over the Hertz chain's.
The machines are shared: only these ratios, measured in the one run, are worth comparing.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from kernels import REPO, child  # noqa: E402

BASE = ["material=ss316", "integrator.method=verlet"]
SETTINGS = {
    "hertz": BASE + ["effects=[hertz]"],
    "plastic": BASE + ["effects=[hertz, plastic_contact]"],
    "adhesive": BASE + ["effects=[hertz, adhesion]", "adhesion.model=jkr",
                        "adhesion.surface_energy=0.1"],
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="granchain-contacts-"))
    print(f"{args.chains} chains x 15 spheres, gaps-20nm-440c in 316, Verlet at 1 ns; load "
          f"average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    best = {}
    for _ in range(args.repeats):
        for name, sets in SETTINGS.items():
            r = child(REPO, [f"ensemble.realisations={args.chains}"] + sets,
                      tmp / f"{name}.npz")
            r["rate"] = r["ps"] / r["wall"]
            if name not in best or r["wall"] < best[name]["wall"]:
                best[name] = r
    h = best["hertz"]["rate"]
    for name, r in best.items():
        print(f"{name:9s}: {r['wall']:.2f} s, {r['ps'] / 1e6:.1f} M particle-steps, "
              f"{r['rate'] / 1e6:.1f} M particle-steps/s: x{r['rate'] / h:.2f} of the Hertz "
              "chain's rate", flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
