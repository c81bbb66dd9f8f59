"""Cost of the LAMMPS engine against the reference engine on one ensemble, side by side.

    python benchmarks/lammps_vs_reference.py [--chains 1000] [--per-process 10] [--np 1]

The ensemble: gaps-20nm-440c (440C, v_s = 0.1 m/s, uniform gaps of mean 20 nm) with
``--chains`` realisations and every effect both engines implement (hertz, groove
friction, air drag, rotation, particle friction, rolling friction with k_roll = 1e3 N/m),
velocity Verlet at dt = 1 ns in both, t_end auto (each engine's own stop: the reference
stops every chain once the wave has passed probe 13; LAMMPS stops the batch once every
chain has, and cuts each chain's record where the reference would).

Timed in one run: (a) the reference engine, batched (numba, parallel over chains, after
a warm-up compile); (b) one batched LAMMPS run of all chains (LAMMPS process, then the
dump read with MDAnalysis); (c) LAMMPS run one process per chain for ``--per-process``
chains, extrapolated linearly to the whole ensemble. Prints wall times, the simulated
particle-steps and the ratios, and how far the two engines' observables differ over the
whole ensemble. Not a test (minutes, GBs of dump); the machines are shared: the ratios
measured side by side are what to compare.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from granchain.engines import lammps as L  # noqa: E402
from granchain.engines import reference  # noqa: E402
from granchain.observables import summarize  # noqa: E402
from granchain.scene import load_scene  # noqa: E402
from granchain.simulate import member_gaps, members  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
EFFECTS = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"


def particle_steps(trajs, n):
    return sum(t.steps for t in trajs) * n


def worst(ref, lmp, probes):
    out = {"v_max": 0.0, "v_g": 0.0, "samples_differ": 0}
    for r, lt in zip(ref, lmp):
        a, b = summarize(r, probes), summarize(lt, probes)
        va, vb = np.array(a["v_max"]), np.array(b["v_max"])
        floor = 1e-3 * r.v_striker
        out["v_max"] = max(out["v_max"], float(np.max(np.abs(vb - va) / np.maximum(va, floor))))
        if np.isfinite(a["v_g"]):
            out["v_g"] = max(out["v_g"], abs(b["v_g"] - a["v_g"]) / a["v_g"])
        out["samples_differ"] += int(a["samples"] != b["samples"])
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--per-process", type=int, default=10, help="chains run one LAMMPS process each")
    ap.add_argument("--np", type=int, default=1, help="MPI ranks of the batched LAMMPS run")
    ap.add_argument("--readers", type=int, default=2, help="dump reader processes (default 2)")
    ap.add_argument("--workdir", default=None, help="where the batched run writes (default: a temp dir)")
    args = ap.parse_args(argv)
    scene = load_scene(REPO / "granchain/scenes/gaps-20nm-440c.yaml",
                       [f"ensemble.realisations={args.chains}", f"effects={EFFECTS}",
                        "rolling.k_roll=1000.0", "integrator.method=verlet"])
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    vs = np.array([m.v_striker for m in mem])
    B, n = len(mem), scene.n
    print(f"scene {scene.name}: {B} chains x {n} particles, effects {','.join(sorted(scene.effects))}, "
          f"verlet dt {scene.dt:g} s, t_end auto; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores", flush=True)

    # (a) reference, batched (warm-up compile first)
    list(reference.run(scene, gaps[:2], vs[:2], method="verlet", progress=False))
    t0 = time.perf_counter()
    ref = list(reference.run(scene, gaps, vs, method="verlet", progress=False))
    t_ref = time.perf_counter() - t0
    ps_ref = particle_steps(ref, n)
    print(f"reference batched : {t_ref:8.2f} s  {ps_ref:.3g} particle-steps  "
          f"{ps_ref / t_ref:.3g} particle-steps/s", flush=True)

    # (b) LAMMPS, one batched run
    with tempfile.TemporaryDirectory(prefix="granchain-bench-") as tmp:
        wd = Path(args.workdir) if args.workdir else Path(tmp) / "batch"
        t0 = time.perf_counter()
        lmp = list(L.run(scene, gaps, vs, nprocs=args.np, workdir=wd, force=True,
                         readers=args.readers, progress=True))
        t_lmp = time.perf_counter() - t0
        meta = lmp[0].meta
        dump_gb = (wd / "traj.dump").stat().st_size / 1e9
        log = (wd / "log.lammps").read_text()
        m = re.search(r"Loop time of (\S+) on (\d+) procs for (\d+) steps", log)
        out_t = re.search(r"^Output\s+\|\s*\S+\s*\|\s*(\S+)", log, re.M)
        loop_s, steps_run = float(m.group(1)), int(m.group(3))
        output_s = float(out_t.group(1)) if out_t else float("nan")
        if not args.workdir:
            (wd / "traj.dump").unlink()
    ps_lmp_run = B * n * steps_run              # what LAMMPS integrated (until the last chain passed)
    ps_lmp = particle_steps(lmp, n)             # the records kept (= the reference's)
    print(f"LAMMPS batched    : {t_lmp:8.2f} s  = LAMMPS process {meta['lammps_wall_s']:.2f} s "
          f"(loop {loop_s:.2f} s, of which dump output {output_s:.2f} s; {args.np} rank(s)) "
          f"+ deck and MDAnalysis read {meta['read_wall_s']:.2f} s ({meta['readers']} reader(s)); "
          f"dump {dump_gb:.2f} GB; {steps_run} steps for all chains = {ps_lmp_run:.3g} "
          f"particle-steps ({ps_lmp:.3g} kept)", flush=True)

    # (c) LAMMPS, one process per chain, for a sample
    k = min(args.per_process, B)
    t0 = time.perf_counter()
    lrun = rd = 0.0
    single = []
    for i in range(k):
        tr = next(L.run(scene, gaps[i:i + 1], vs[i:i + 1], nprocs=1, readers=1))
        lrun += tr.meta["lammps_wall_s"]
        rd += tr.meta["read_wall_s"]
        single.append(tr)
    t_single = time.perf_counter() - t0
    t_single_all = t_single / k * B
    same = all(np.array_equal(a.v, b.v) for a, b in zip(lmp[:k], single))
    print(f"LAMMPS per process: {t_single:8.2f} s for {k} chains (LAMMPS processes {lrun:.2f} s, "
          f"deck and read {rd:.2f} s) -> {t_single_all:.1f} s extrapolated to {B} chains; "
          f"records identical to the batched run's: {same}", flush=True)

    d = worst(ref, lmp, scene.probes)
    print(f"agreement over the {B} chains: max rel diff v_max {d['v_max']:.2e}, v_g {d['v_g']:.2e}; "
          f"chains with a different number of samples: {d['samples_differ']}")
    print("ratios (wall time):")
    print(f"  LAMMPS batched / reference batched           : {t_lmp / t_ref:8.2f}")
    print(f"  LAMMPS process only (batched) / reference    : {meta['lammps_wall_s'] / t_ref:8.2f}")
    print(f"  LAMMPS one process per chain / LAMMPS batched: {t_single_all / t_lmp:8.2f}  "
          f"(LAMMPS processes alone: {lrun / k * B / meta['lammps_wall_s']:.2f})")


if __name__ == "__main__":
    main()
