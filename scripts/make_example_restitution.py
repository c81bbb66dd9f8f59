"""Write measurements/example_restitution.csv: SYNTHETIC measurements (not from an
experiment) with a known mean gap and coefficient of restitution, for ``granchain infer
--fit gap_mean,restitution``.

Chains of measurements/example_restitution.yaml at a mean gap of 47 nm (the chapter's 440C
reading) with contact damping of coefficient of restitution e = 0.92, drawn with gap seed
2024 (the inference's grid uses the scene's seed 0, so these realisations are not in it):
one chain measured at four striker speeds (chain_id A) and four independent chains;
arrival (half-peak) delays with Gaussian noise of 0.2 us (dt_err_s) and both probes' peaks
with Gaussian noise of 2 % of the striker speed (vmax_err_m_s).
Usage: python scripts/make_example_restitution.py [--out FILE] [--force]
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from granchain.costmodel import fixed_step
from granchain.fileio import atomic_write_text
from granchain.inference import simulate_joint_rows
from granchain.scene import load_scene

REPO = Path(__file__).resolve().parents[1]
# the base scene the chains are drawn from
BASE = REPO / "measurements" / "example_restitution.yaml"
TRUE_GAP = 47e-9
TRUE_E = 0.92
NOISE = 0.2e-6
PEAK_NOISE = 0.02          # x v_s
SEED = 2024


def main(out: Path = REPO / "measurements" / "example_restitution.csv", force: bool = False) -> Path:
    # the true chains are simulated as when the file was written: RK4 at 20 steps per
    # contact time, what method auto took for 1e-3 on v_g from the cost model of then
    # (without its damped class). On these damped chains it differs from the event
    # method at 1e-7 by at most 3.1e-4 on the delay, 3.6e-4 on v_max,1 and 1.2e-3 on
    # v_max,2: a few hundredths of the stated noise.
    base = load_scene(BASE).derive({"gaps": {"seed": SEED}})
    base = base.derive({"integrator": {"method": "rk4", "dt": fixed_step(base, 20)}})
    rng = np.random.default_rng(7)
    speeds = np.array([0.03, 0.045, 0.07, 0.1, 0.035, 0.05, 0.08, 0.095])
    reals = [0, 0, 0, 0, 1, 2, 3, 4]
    ids = ["A", "A", "A", "A", "", "", "", ""]
    X = simulate_joint_rows(base, TRUE_GAP, TRUE_E, speeds, reals, "dt_front_s")
    perr = PEAK_NOISE * speeds
    X = X + np.stack([np.full(speeds.size, NOISE), perr, perr], axis=1) * \
        rng.standard_normal(X.shape)
    lines = [f"# SYNTHETIC data, not a measurement: written by "
             f"scripts/make_example_restitution.py with a known mean gap of "
             f"{TRUE_GAP * 1e9:g} nm (uniform law, gap seed {SEED}) and coefficient of "
             f"restitution {TRUE_E:g} (contact_damping coeff_restitution), timing noise "
             f"{NOISE * 1e6:g} us, peak noise {PEAK_NOISE * 100:g} % of v_s",
             "v_striker_m_s,dt_front_s,dt_err_s,vmax_1_m_s,vmax_2_m_s,vmax_err_m_s,chain_id"]
    lines += [f"{v:.6g},{x[0]:.6e},{NOISE:.1e},{x[1]:.6e},{x[2]:.6e},{e:.2e},{c}"
              for v, x, e, c in zip(speeds, X, perr, ids)]
    return atomic_write_text(out, "\n".join(lines) + "\n", force, "--out")


if __name__ == "__main__":
    from _synthetic import cli
    cli(main, __doc__, REPO / "measurements" / "example_restitution.csv", BASE)
