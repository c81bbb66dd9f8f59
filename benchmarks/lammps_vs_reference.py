"""Cost of the LAMMPS engine against the reference engine on one ensemble, side by side.

    python benchmarks/lammps_vs_reference.py [--chains 1000] [--per-process 10] [--np 1]
                                             [--readers 1] [--coarser 4]

The ensemble: gaps-20nm-440c (440C, v_s = 0.1 m/s, uniform gaps of mean 20 nm) with
``--chains`` realisations and every effect both engines implement (hertz, groove
friction, air drag, rotation, particle friction, rolling friction with k_roll = 1e3 N/m),
velocity Verlet at dt = 1 ns in both, t_end auto (each engine's own stop: the reference
stops every chain once the wave has passed probe 13; LAMMPS stops the batch once every
chain has, and cuts each chain's record where the reference would).

Timed in one run, at the default sample grid and again with ``output.sample_dt``
``--coarser`` times coarser (0: skip): (a) the reference engine, batched (numba,
parallel over chains, after a warm-up compile); (b) one batched LAMMPS run of all chains
(the LAMMPS process, with its loop's Pair / Modify / Output split from log.lammps, then
the dump read with MDAnalysis and the per-chain ledger); (c) LAMMPS run one process per
chain for ``--per-process`` chains, extrapolated linearly to the whole ensemble. Prints
wall times, the simulated particle-steps and the ratios, and how far the two engines'
observables differ over the whole ensemble. Not a test (minutes, a GB of dump); the
machines are shared: the ratios measured side by side are what to compare.
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
        va, vb = np.array(a.v_max), np.array(b.v_max)
        floor = 1e-3 * r.v_striker
        out["v_max"] = max(out["v_max"], float(np.max(np.abs(vb - va) / np.maximum(va, floor))))
        if np.isfinite(a.v_g):
            out["v_g"] = max(out["v_g"], abs(b.v_g - a.v_g) / a.v_g)
        out["samples_differ"] += int(a.samples != b.samples)
    return out


def lammps_batched(scene, gaps, vs, args, wd):
    """One batched LAMMPS run: trajectories and its timings (log.lammps sections)."""
    t0 = time.perf_counter()
    lmp = list(L.run(scene, gaps, vs, nprocs=args.np, workdir=wd, force=True,
                     readers=args.readers, progress=True))
    wall = time.perf_counter() - t0
    log = (wd / "log.lammps").read_text()
    m = re.search(r"Loop time of (\S+) on (\d+) procs for (\d+) steps", log)
    sec = {k: float(v) for k, v in re.findall(r"^(\w+)\s+\|\s*\S+\s*\|\s*(\S+)", log, re.M)}
    size = {f.name: f.stat().st_size / 1e6 for f in wd.iterdir()}
    for f in ("traj.dump", "ledger.txt"):
        if not args.workdir:
            (wd / f).unlink(missing_ok=True)
    return lmp, {"wall": wall, "loop": float(m.group(1)), "steps": int(m.group(3)), "sec": sec,
                 "size": size, "meta": lmp[0].meta}


def per_process(scene, gaps, vs, k):
    """LAMMPS one process per chain for the first k chains: (wall, LAMMPS, read, trajs)."""
    t0 = time.perf_counter()
    lrun = rd = 0.0
    single = []
    for i in range(k):
        tr = next(L.run(scene, gaps[i:i + 1], vs[i:i + 1], nprocs=1, readers=1))
        lrun += tr.meta["lammps_wall_s"]
        rd += tr.meta["read_wall_s"]
        single.append(tr)
    return time.perf_counter() - t0, lrun, rd, single


def measure(scene, gaps, vs, args, tmp, label):
    B, n = len(vs), scene.n
    print(f"--- {label}: sample_dt {L.deckmod.plan(scene, gaps=gaps[:1], v_striker=vs[:1]).sample_dt:.3g} s",
          flush=True)
    t0 = time.perf_counter()
    ref = list(reference.run(scene, gaps, vs, method="verlet", progress=False))
    t_ref = time.perf_counter() - t0
    ps_ref = particle_steps(ref, n)
    print(f"reference batched : {t_ref:8.2f} s  {ps_ref:.3g} particle-steps  "
          f"{ps_ref / t_ref:.3g} particle-steps/s", flush=True)

    wd = Path(args.workdir) / label if args.workdir else Path(tmp) / label
    lmp, b = lammps_batched(scene, gaps, vs, args, wd)
    meta, sec = b["meta"], b["sec"]
    lines = B * n * (b["steps"] // round(meta["sample_dt"] / scene.dt) + 1)
    print(f"LAMMPS batched    : {b['wall']:8.2f} s  = LAMMPS process {meta['lammps_wall_s']:.2f} s "
          f"(loop {b['loop']:.2f} s: Pair {sec.get('Pair', 0):.2f}, Modify {sec.get('Modify', 0):.2f} "
          f"incl. the per-chain ledger, Output {sec.get('Output', 0):.2f} = dump writing; "
          f"{args.np} rank(s)) + deck, MDAnalysis read and ledger {meta['read_wall_s']:.2f} s "
          f"({meta['readers']} reader(s)); dump {b['size'].get('traj.dump', 0):.0f} MB "
          f"({lines:.3g} atom-lines: {sec.get('Output', 0) / lines * 1e6:.2f} us/line to write, "
          f"{meta['read_wall_s'] / lines * 1e6:.2f} us/line to read), ledger "
          f"{b['size'].get('ledger.txt', 0):.0f} MB; {b['steps']} steps for all chains = "
          f"{B * n * b['steps']:.3g} particle-steps ({particle_steps(lmp, n):.3g} kept)", flush=True)

    k = min(args.per_process, B)
    t_single, lrun, rd, single = per_process(scene, gaps, vs, k)
    t_single_all = t_single / k * B
    same = all(np.array_equal(a.v, s.v) and np.array_equal(a.energy, s.energy)
               for a, s in zip(lmp[:k], single))
    print(f"LAMMPS per process: {t_single:8.2f} s for {k} chains (LAMMPS processes {lrun:.2f} s, "
          f"deck and read {rd:.2f} s) -> {t_single_all:.1f} s extrapolated to {B} chains; "
          f"records identical to the batched run's: {same}", flush=True)

    d = worst(ref, lmp, scene.probes)
    print(f"agreement over the {B} chains: max rel diff v_max {d['v_max']:.2e}, v_g {d['v_g']:.2e}; "
          f"chains with a different number of samples: {d['samples_differ']}")
    print("ratios (wall time):")
    print(f"  LAMMPS batched / reference batched           : {b['wall'] / t_ref:8.2f}")
    print(f"  LAMMPS process only (batched) / reference    : {meta['lammps_wall_s'] / t_ref:8.2f}")
    print(f"  LAMMPS one process per chain / LAMMPS batched: {t_single_all / b['wall']:8.2f}  "
          f"(LAMMPS processes alone: {lrun / k * B / meta['lammps_wall_s']:.2f})", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--per-process", type=int, default=10, help="chains run one LAMMPS process each")
    ap.add_argument("--np", type=int, default=1, help="MPI ranks of the batched LAMMPS run")
    ap.add_argument("--readers", type=int, default=1, help="dump reader processes (default 1)")
    ap.add_argument("--coarser", type=int, default=4,
                    help="also time output.sample_dt this many times the default (0: skip)")
    ap.add_argument("--workdir", default=None, help="where the batched runs write (default: a temp dir)")
    args = ap.parse_args(argv)
    scene = load_scene(REPO / "granchain/scenes/gaps-20nm-440c.yaml",
                       [f"ensemble.realisations={args.chains}", f"effects={EFFECTS}",
                        "rolling.k_roll=1000.0", "integrator.method=verlet"])
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    vs = np.array([m.v_striker for m in mem])
    print(f"scene {scene.name}: {len(mem)} chains x {scene.n} particles, effects "
          f"{','.join(sorted(scene.effects))}, verlet dt {scene.dt:g} s, t_end auto; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    list(reference.run(scene, gaps[:2], vs[:2], method="verlet", progress=False))   # compile
    import MDAnalysis  # noqa: F401  (imported once before timing, as the compile above)
    with tempfile.TemporaryDirectory(prefix="granchain-bench-") as tmp:
        measure(scene, gaps, vs, args, tmp, "default")
        if args.coarser > 1:
            sdt = args.coarser * L.deckmod.plan(scene, gaps=gaps, v_striker=vs).sample_dt
            coarse = scene.derive(**{"output.sample_dt": sdt})
            measure(coarse, gaps, vs, args, tmp, f"coarser{args.coarser}")
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
