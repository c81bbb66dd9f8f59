"""The joint fit's posterior from a given grid, two trees side by side.

    python benchmarks/inference_posterior.py OTHER_TREE [--repeats 3]
                                             [--grid GRID.pkl --rows ROWS.csv]

Runs ``inference.infer_joint`` (the posterior's two passes, the draws, the predictive and
model checks; nothing simulated) in a fresh process per run, taking turns between this tree
and OTHER_TREE, on a SYNTHETIC joint grid (21 mean gaps to 500 nm x 7 e x the rows' speeds
x 64 realisations; timings and peaks from a smooth law with a spread per realisation) and
the 20-row measurements of ``benchmarks/targets.py`` (four chains at five speeds), or on a
pickled ``JointGrid`` (``--grid``, e.g. ``res.grid`` of a run) and its rows (``--rows``).
Prints per tree the median CPU seconds (``resource.getrusage``) and the results, and the
largest difference of the medians and interval ends between the trees as a fraction of
the interval's width."""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, pickle, resource, sys
import numpy as np
from granchain.inference import JointGrid, fit_key, gap_nodes, infer_joint
from granchain.inference.measurements import read_measurements
from granchain.scene import load_scene
root, rows, gridfile = sys.argv[1], sys.argv[2], sys.argv[3]
meas = read_measurements(rows, peaks=True)
base = load_scene(root + "/measurements/example_restitution.yaml")
if gridfile:
    grid = pickle.load(open(gridfile, "rb"))
else:
    gaps, es = gap_nodes(500e-9, 21), fit_key("damping.e").nodes(0.7, 1.0, 7)
    speeds, R = np.array(sorted(set(meas.v.tolist()))), 64
    u = np.random.default_rng(1).uniform(0, 2, (1, 1, 1, R))
    G, E, S = (a[..., None] for a in np.meshgrid(gaps, es, speeds, indexing="ij"))
    dt = 11 * 1.1e-6 * (0.1 / S) ** 0.2 + 11 * G * u / (0.6 * S)
    values = {"dt_front_s": dt, "dt_peak_s": 1.1 * dt,
              "v_max_1": S * (0.6 + 0.1 * E) * (1 + 0.01 * u),
              "v_max_2": S * (0.3 + 0.3 * E - 0.2 * G / 5e-7) * (1 + 0.02 * u)}
    grid = JointGrid(gaps, es, speeds, values, ("0" * 16,) * gaps.size, 0)
r0 = resource.getrusage(resource.RUSAGE_SELF)
res = infer_joint(base, meas, grid=grid)
r1 = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"cpu": r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime,
                  "g": res.gap_mean_m, "g_ci": res.ci95_m, "p": res.param,
                  "p_ci": res.param_ci95, "flags": res.flags,
                  "outside": res.predictive_outside}))
"""


def _one(tree: Path, rows: Path, grid: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, str(tree), str(rows), grid], env=env,
                         check=True, capture_output=True, text=True, cwd=tree)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", type=Path)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--grid", default="")
    ap.add_argument("--rows", type=Path)
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from targets import _twenty_rows
    trees = {"this": ROOT, "other": a.other.resolve()}
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        rows = a.rows
        if rows is None:
            rows = Path(tmp) / "twenty.csv"
            _twenty_rows(rows)
        got = {k: [] for k in trees}
        for _ in range(a.repeats):
            for k, t in trees.items():
                got[k].append(_one(t, rows, a.grid))
    for k, runs in got.items():
        r = runs[0]
        print(f"{k} ({trees[k]}): CPU {statistics.median(x['cpu'] for x in runs):.2f} s (runs "
              f"{', '.join('%.2f' % x['cpu'] for x in runs)}); mean gap {r['g'] * 1e9:.3f} nm "
              f"[{r['g_ci'][0] * 1e9:.3f}, {r['g_ci'][1] * 1e9:.3f}], key {r['p']:.5f} "
              f"[{r['p_ci'][0]:.5f}, {r['p_ci'][1]:.5f}], flags {r['flags']}, predictive "
              f"outside {r['outside']}", flush=True)
    a_, b_ = got["this"][0], got["other"][0]
    wg, wp = b_["g_ci"][1] - b_["g_ci"][0], b_["p_ci"][1] - b_["p_ci"][0]
    dg = max(abs(x - y) for x, y in zip([a_["g"], *a_["g_ci"]], [b_["g"], *b_["g_ci"]])) / wg
    dp = max(abs(x - y) for x, y in zip([a_["p"], *a_["p_ci"]], [b_["p"], *b_["p_ci"]])) / wp
    print(f"largest difference of median and interval ends: mean gap {dg:.2e}, key {dp:.2e} "
          "of the other tree's interval width")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
