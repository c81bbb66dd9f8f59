"""Cost of the LAMMPS engine's output paths against LAMMPS alone and the reference engine,
side by side in one run.

    python benchmarks/lammps_vs_reference.py [--chains 1000] [--np 1,2] [--skip-dump]
                                             [--workdir DIR]

The ensemble: gaps-20nm-440c (440C, v_s = 0.1 m/s, uniform gaps of mean 20 nm) with
``--chains`` realisations and every effect both engines implement (hertz, groove
friction, air drag, rotation, particle friction, rolling friction with k_roll = 1e3 N/m),
velocity Verlet at dt = 1 ns, t_end auto, the default sample grid.

For each rank count in ``--np``, timed one after the other:

* ``none``: LAMMPS alone, the same deck with no per-sample output (``write_deck(...,
  output="none")``: no trajectory, no per-chain ledger; thermo and energy.txt as in every
  deck), run by ``run_lammps``: the process' wall time;
* ``binary``: ``granchain.engines.lammps.run(..., output="binary")`` end to end (deck,
  LAMMPS writing traj.bin and ledger.bin, numpy reading them, Trajectory objects): what
  ``granchain run --engine lammps`` does;
* ``dump``: the same with ``output="dump"`` (text dump read by MDAnalysis, ledger.txt);
* ``none`` and ``binary`` again after it, so that a drift of the machine's load shows.

and once the reference engine, batched (numba, after a warm-up compile). Prints the wall
times, the ratios and the agreement: binary against dump (bit for bit on v, energies),
binary against the reference (v_max, v_g, sample counts). Not a test: the machines are
shared, so only the ratios measured side by side in the one run are worth comparing.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from granchain.engines import lammps as lammps_engine  # noqa: E402
from granchain.engines import reference  # noqa: E402
from granchain.lammps import deck as lammps_deck  # noqa: E402
from granchain.lammps.runner import run_lammps  # noqa: E402
from granchain.observables import summarize  # noqa: E402
from granchain.scene import load_scene  # noqa: E402
from granchain.simulate import member_gaps, members  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
EFFECTS = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"


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


def sections(log: Path) -> str:
    text = log.read_text()
    m = re.search(r"Loop time of (\S+) on (\d+) procs for (\d+) steps", text)
    sec = {k: float(v) for k, v in re.findall(r"^(\w+)\s+\|\s*\S+\s*\|\s*(\S+)", text, re.M)}
    return (f"loop {float(m.group(1)):.2f} s for {m.group(3)} steps: Pair {sec.get('Pair', 0):.2f}, "
            f"Modify {sec.get('Modify', 0):.2f}, Output {sec.get('Output', 0):.2f}")


def lammps_alone(scene, gaps, vs, nprocs, wd):
    """The deck without per-sample output, run once: wall time of the LAMMPS process."""
    wd.mkdir(parents=True)
    deck = lammps_deck.write_deck(scene, wd, gaps=gaps, v_striker=vs, output="none")
    t0 = time.perf_counter()
    run_lammps(deck, wd, nprocs=nprocs)
    wall = time.perf_counter() - t0
    return wall, sections(wd / "log.lammps")


def engine(scene, gaps, vs, nprocs, output, wd):
    t0 = time.perf_counter()
    trajs = list(lammps_engine.run(scene, gaps, vs, nprocs=nprocs, output=output, workdir=wd))
    wall = time.perf_counter() - t0
    size = sum(f.stat().st_size for f in wd.iterdir()) / 1e6
    note = (f"LAMMPS process {trajs[0].info.lammps_wall_s:.2f} s, deck and read "
            f"{trajs[0].info.read_wall_s:.2f} s, files {size:.0f} MB; "
            + sections(wd / "log.lammps"))
    return wall, note, trajs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--np", default="1,2", help="MPI rank counts, comma separated (default 1,2)")
    ap.add_argument("--skip-dump", action="store_true", help="do not time the text dump path")
    ap.add_argument("--workdir", default=None, help="keep the runs' directories here")
    args = ap.parse_args(argv)
    ranks = [int(x) for x in args.np.split(",")]
    scene = load_scene(REPO / "granchain/scenes/gaps-20nm-440c.yaml",
                       [f"ensemble.realisations={args.chains}", f"effects={EFFECTS}",
                        "rolling.k_roll=1000.0", "integrator.method=verlet"])
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    vs = np.array([m.v_striker for m in mem])
    B, n = len(vs), scene.n
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs)
    print(f"scene {scene.name}: {B} chains x {n} particles, effects {','.join(sorted(scene.effects))}, "
          f"verlet dt {scene.dt:g} s, t_end auto (at most {pl.nsteps} steps), samples every "
          f"{pl.every} steps; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores",
          flush=True)
    list(reference.run(scene, gaps[:2], vs[:2], method="verlet", progress=False))   # compile
    import MDAnalysis  # noqa: F401  (imported before timing, as the compile above)

    t0 = time.perf_counter()
    ref = list(reference.run(scene, gaps, vs, method="verlet", progress=False, trace=True))
    t_ref = time.perf_counter() - t0
    print(f"reference engine, batched (numba): {t_ref:.2f} s", flush=True)

    rows = []
    tmp = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="granchain-bench-"))
    try:
        for nprocs in ranks:
            times = {}

            def step(label, fn):
                wd = tmp / f"np{nprocs}-{label}"
                out = fn(wd)
                times.setdefault(label.rstrip("2"), []).append(out[0])
                print(f"np {nprocs} {label:7s}: {out[0]:8.2f} s  ({out[1]})", flush=True)
                if not args.workdir:
                    shutil.rmtree(wd, ignore_errors=True)
                return out

            step("none", lambda wd: lammps_alone(scene, gaps, vs, nprocs, wd))
            _, _, binary = step("binary", lambda wd: engine(scene, gaps, vs, nprocs, "binary", wd))
            if not args.skip_dump:
                _, _, dump = step("dump", lambda wd: engine(scene, gaps, vs, nprocs, "dump", wd))
                same_v = all(np.array_equal(a.v, b.v) and np.array_equal(a.t, b.t)
                             for a, b in zip(binary, dump))
                de = max(float(np.abs(a.energy - b.energy).max() / b.energy[0, :3].sum())
                         for a, b in zip(binary, dump))
                print(f"np {nprocs} binary vs dump: v bit for bit {same_v}, energies max "
                      f"|diff|/E0 {de:.1e}", flush=True)
                del dump
            step("binary2", lambda wd: engine(scene, gaps, vs, nprocs, "binary", wd))
            step("none2", lambda wd: lammps_alone(scene, gaps, vs, nprocs, wd))
            d = worst(ref, binary, scene.probes)
            print(f"np {nprocs} binary vs reference over {B} chains: v_max {d['v_max']:.1e}, "
                  f"v_g {d['v_g']:.1e}, chains with another sample count {d['samples_differ']}",
                  flush=True)
            del binary
            rows.append((nprocs, times))
    finally:
        if not args.workdir:
            shutil.rmtree(tmp, ignore_errors=True)

    print(f"\n{B} chains, wall times (s) and ratios; load average at the end "
          f"{os.getloadavg()[0]:.1f}. 'none' and 'binary' ran twice (before and after the text "
          "dump): their mean, and the ratio of the faster runs (the ones least disturbed by "
          "other jobs on the shared cores)")
    print("| ranks | LAMMPS, no output | run --engine lammps (binary) | text dump + MDAnalysis "
          "| reference engine | binary / no output: means (fastest) | dump / no output "
          "| binary / reference |")
    print("|---|---|---|---|---|---|---|---|")
    for nprocs, t in rows:
        none, binary = np.mean(t["none"]), np.mean(t["binary"])
        dump = np.mean(t["dump"]) if "dump" in t else float("nan")
        print(f"| {nprocs} | {none:.2f} ({' / '.join(f'{x:.2f}' for x in t['none'])}) | "
              f"{binary:.2f} ({' / '.join(f'{x:.2f}' for x in t['binary'])}) | {dump:.1f} | "
              f"{t_ref:.2f} | **{binary / none:.2f}** ({min(t['binary']) / min(t['none']):.2f}) | "
              f"{dump / none:.1f} | {binary / t_ref:.1f} |")


if __name__ == "__main__":
    main()
