"""Write measurements/example_synthetic.csv: SYNTHETIC measurements (not from an
experiment) with a known mean gap, for ``granchain infer`` and the workflow's inference
rule.

Chains of measurements/example_synthetic.yaml at a mean gap of 47 nm (the chapter's 440C
reading), drawn with gap seed 2024 (the inference's grid uses the scene's seed 0, so these
realisations are not in it): one chain measured at four striker speeds (chain_id A) and
four independent chains, arrival (half-peak) delays with Gaussian noise of 0.2 us
(dt_err_s). Usage: python scripts/make_example_measurements.py [--out FILE] [--force]
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from granchain.fileio import atomic_write_text
from granchain.inference import simulate_rows
from granchain.scene import load_scene

REPO = Path(__file__).resolve().parents[1]
# the base scene the chains are drawn from
BASE = REPO / "measurements" / "example_synthetic.yaml"
TRUE_GAP = 47e-9
NOISE = 0.2e-6
SEED = 2024


def main(out: Path = REPO / "measurements" / "example_synthetic.csv", force: bool = False) -> Path:
    # the true chains are simulated as when the file was written: method auto at 1e-3
    # on v_g (the base scene leaves its tolerance to the inference)
    base = load_scene(BASE).derive(
        {"gaps": {"seed": SEED}, "integrator": {"method": "auto", "tolerance": 1e-3}})
    rng = np.random.default_rng(7)
    speeds = [0.03, 0.045, 0.07, 0.1, 0.035, 0.05, 0.08, 0.095]
    reals = [0, 0, 0, 0, 1, 2, 3, 4]
    ids = ["A", "A", "A", "A", "", "", "", ""]
    t = simulate_rows(base, TRUE_GAP, speeds, reals, "dt_front_s")
    t = t + NOISE * rng.standard_normal(t.size)
    lines = [f"# SYNTHETIC data, not a measurement: written by scripts/make_example_measurements.py "
             f"with a known mean gap of {TRUE_GAP * 1e9:g} nm (uniform law, gap seed {SEED}), "
             f"noise {NOISE * 1e6:g} us",
             "v_striker_m_s,dt_front_s,dt_err_s,chain_id"]
    lines += [f"{v:.6g},{x:.6e},{NOISE:.1e},{c}" for v, x, c in zip(speeds, t, ids)]
    return atomic_write_text(out, "\n".join(lines) + "\n", force, "--out")


if __name__ == "__main__":
    from _synthetic import cli
    cli(main, __doc__, REPO / "measurements" / "example_synthetic.csv", BASE)
