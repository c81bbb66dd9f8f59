"""The kernels' throughput with yielding and adhesive contacts against a Hertz chain,
side by side in one run.

    python benchmarks/contacts.py [--chains 300] [--repeats 3] [--every]

The ensemble: gaps-20nm-440c's chains (v_s = 0.1 m/s, uniform gaps of mean 20 nm, 15
spheres) in 316, whose contacts yield at that speed, on the reference engine, velocity
Verlet at 1 ns, t_end auto, ``--chains`` realisations, in three settings: Hertz alone
(``hertz``), Thornton's contacts at 316's library p_y (``plastic``: effects hertz and
plastic_contact) and LAMMPS's JKR law at gamma = 0.1 J/m^2 (``adhesive``: hertz and
adhesion). Each setting runs in its own process after a warm-up on two chains (the
compile is not timed), the three taking turns ``--repeats`` times; the fastest of each
counts. Prints particle-steps per second (the settings' chains run different numbers of
steps: a yielding chain's slower wave runs longer) and each rate over the Hertz chain's.
With ``--every``, also the chain with every effect of Eq. 5.1 (the packaged cost model's
chain) alone, with Thornton's contacts (and without the contact friction, which they
refuse) and with JKR's: the cost of a particle-step of
each over the every-effect chain's (what each law's ``EffectSpec.step_cost`` declares).
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
EVERY = "hertz, groove_friction, air_drag, rotation, particle_friction"
JKR = ["adhesion.model=jkr", "adhesion.surface_energy=0.1"]
SETTINGS = {
    "hertz": BASE + ["effects=[hertz]"],
    "plastic": BASE + ["effects=[hertz, plastic_contact]"],
    "adhesive": BASE + ["effects=[hertz, adhesion]"] + JKR,
}
# with every effect of Eq. 5.1 (the packaged cost model's chain): each law's per-step cost
# over that chain's, which its EffectSpec.step_cost declares for the estimates
EVERY_SETTINGS = {
    "every": BASE + [f"effects=[{EVERY}]"],
    # Thornton's law refuses the contact friction: the effects it acts with
    "every+plastic": BASE + ["effects=[hertz, groove_friction, air_drag, rotation, "
                             "plastic_contact]"],
    "every+adhesive": BASE + [f"effects=[{EVERY}, adhesion]"] + JKR,
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--every", action="store_true",
                    help="also every effect of Eq. 5.1 alone, with Thornton's and with JKR "
                         "contacts: each law's per-step cost over the every-effect chain's")
    args = ap.parse_args(argv)
    settings = {**SETTINGS, **(EVERY_SETTINGS if args.every else {})}
    tmp = Path(tempfile.mkdtemp(prefix="granchain-contacts-"))
    print(f"{args.chains} chains x 15 spheres, gaps-20nm-440c in 316, Verlet at 1 ns; load "
          f"average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    best = {}
    for _ in range(args.repeats):
        for name, sets in settings.items():
            r = child(REPO, [f"ensemble.realisations={args.chains}"] + sets,
                      tmp / f"{name}.npz")
            r["rate"] = r["ps"] / r["wall"]
            if name not in best or r["wall"] < best[name]["wall"]:
                best[name] = r
    h = best["hertz"]["rate"]
    for name, r in best.items():
        print(f"{name:14s}: {r['wall']:.2f} s, {r['ps'] / 1e6:.1f} M particle-steps, "
              f"{r['rate'] / 1e6:.1f} M particle-steps/s: x{r['rate'] / h:.2f} of the Hertz "
              "chain's rate", flush=True)
    if args.every:
        e = best["every"]["rate"]
        for name in ("every+plastic", "every+adhesive"):
            print(f"{name}: a particle-step costs {e / best[name]['rate']:.2f}x the "
                  "every-effect chain's", flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
