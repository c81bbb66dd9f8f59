"""The speed targets of the reference engine and the workflow, every row measured side by
side in one run.

    python benchmarks/targets.py [--repeats 3] [--chains 1000] [--presets] [--full]
                                 [--no-inference | --only-inference]

Rows (whole processes unless said; each pair alternates ``--repeats`` times, medians):

1. ``granchain run`` of ``--chains`` chains (gaps-20nm-440c: 440C, 20 nm uniform gaps,
   0.1 m/s, every effect of Eq. 5.1, velocity Verlet at 1 ns, t_end auto) against LAMMPS
   on 2 MPI ranks on the same chains' deck with no output (``lmp -in deck``, mpich's
   ``mpirun``); the ratio LAMMPS / granchain.
2. ``granchain run --engine lammps`` of the same scene's 8 chains against ``lmp -in`` the
   same deck with no output, one rank; the ratio granchain / lmp (the LAMMPS path's
   overhead).
3. The event method's throughput on gap-sweep chains (15 spheres, every effect, 512
   chains at 20 nm/0.1 m/s, 190 nm/0.01 m/s and 100 nm/1 m/s): particle-force
   evaluations per second in lanes, against the block Verlet kernel on the same chains
   (in this process, fastest of the repeats); the ratio Verlet / event.
4. ``granchain infer`` of the shipped joint example (measurements/example_restitution.csv,
   ``--fit gap_mean,restitution``: 28,224 simulated chains) from a fresh state (empty
   kernel caches, JIT and ahead-of-time, and an empty grid cache: ``NUMBA_CACHE_DIR`` and
   ``GRANCHAIN_CACHE_DIR`` in a new temporary directory, compile included); then a
   20-row joint fit (synthetic: four chains at five striker speeds each, on the same base
   scene) from an empty grid cache with the kernels that run compiled. One process each,
   once (a repeat would find its caches warm).
5. With ``--presets``: the default preset from nothing (a fresh clone, empty kernel
   caches) and again with its kernels compiled (results removed), ``snakemake --cores 2``.
6. With ``--full``: the full preset from nothing (about half an hour on 2 cores).

The machines are shared and noisy: compare the ratios of one run, not absolute times across
runs. Every number printed is measured in this run.
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "granchain/scenes/gaps-20nm-440c.yaml")
ALL = "[hertz,groove_friction,air_drag,rotation,particle_friction]"


def _timed(cmd, env, cwd=None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def _alternate(cmds: dict, repeats: int) -> dict:
    for c, e, d in cmds.values():                 # compile, page cache, LAMMPS caches
        _timed(c, e, d)
    times = {k: [] for k in cmds}
    for _ in range(repeats):
        for k, (c, e, d) in cmds.items():
            times[k].append(_timed(c, e, d))
    return {k: statistics.median(v) for k, v in times.items()}


def _env():
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)      # as an installed package runs
    return env


def _deck(sets, wd):
    import numpy as np

    from granchain.lammps import deck as lammps_deck
    from granchain.scene import load_scene
    from granchain.simulate import member_gaps, members
    scene = load_scene(SCENE, sets)
    mem = members(scene)
    deck = lammps_deck.write_deck(scene, wd, gaps=member_gaps(scene, mem),
                                  v_striker=np.array([m.v_striker for m in mem]), output="none")
    return deck.name


def row_run_vs_lammps(chains: int, repeats: int) -> None:
    from granchain.lammps.runner import lmp_command, mpirun_executable
    sets = [f"ensemble.realisations={chains}", "integrator.method=verlet",
            "integrator.dt=1.0e-9", f"effects={ALL}"]
    env = _env()
    setargs = [a for s in sets for a in ("--set", s)]
    with tempfile.TemporaryDirectory(prefix="granchain-targets-") as tmp:
        wd = Path(tmp)
        deck = _deck(sets, wd)
        direct, denv = lmp_command()
        cmds = {
            "granchain": ([sys.executable, "-m", "granchain.cli", "run", SCENE, "--json",
                           *setargs], env, None),
            "lammps np 2": ([str(mpirun_executable()), "-np", "2", *direct, "-in", deck,
                             "-log", "none", "-nocite"], dict(env, **denv), wd),
        }
        med = _alternate(cmds, repeats)
    print(f"1. granchain run, {chains} chains, every effect, Verlet 1 ns, 20 nm: "
          f"{med['granchain']:.2f} s; LAMMPS np 2, no output: {med['lammps np 2']:.2f} s; "
          f"LAMMPS / granchain {med['lammps np 2'] / med['granchain']:.2f}x (target >= 3x, goal 5x)",
          flush=True)


def row_lammps_overhead(repeats: int) -> None:
    from granchain.lammps.runner import lmp_executable
    sets = ["integrator.method=verlet"]
    env = _env()
    with tempfile.TemporaryDirectory(prefix="granchain-targets-") as tmp:
        wd = Path(tmp)
        deck = _deck(sets, wd)
        cmds = {
            "granchain": ([sys.executable, "-m", "granchain.cli", "run", SCENE, "--engine",
                           "lammps", "--json", "--set", sets[0]], env, None),
            "lmp": ([str(lmp_executable()), "-in", deck, "-log", "none", "-nocite"], env, wd),
        }
        med = _alternate(cmds, repeats)
    print(f"2. granchain run --engine lammps (gaps-20nm-440c, 8 chains): "
          f"{med['granchain']:.2f} s; lmp -in the same deck, no output: {med['lmp']:.2f} s; "
          f"granchain / lmp {med['granchain'] / med['lmp']:.2f}x (target <= 1.5x)", flush=True)


def row_event_throughput(repeats: int) -> None:
    import numpy as np

    from granchain.engines import reference
    from granchain.scene import scene_from_dict

    def scene(method, v):
        return scene_from_dict({
            "name": "sweep", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
            "striker": {"velocity": v}, "probes": [2, 13],
            "effects": ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"],
            "integrator": method})

    parts = []
    for gap, v in ((20e-9, 0.1), (190e-9, 0.01), (100e-9, 1.0)):
        gaps = np.random.default_rng(7).uniform(0.0, 2 * gap, (512, 14))
        vs = np.full(512, v)
        rate = {}
        for name, method in (("event", {"method": "event", "tolerance": 1e-6}),
                             ("verlet", {"method": "verlet", "dt": 1e-9})):
            s = scene(method, v)
            list(reference.run(s, gaps[:2], vs[:2], progress=False, trace=False))
            best = np.inf
            for _ in range(repeats):
                t0 = time.perf_counter()
                out = list(reference.run(s, gaps, vs, progress=False, trace=False))
                best = min(best, time.perf_counter() - t0)
            rate[name] = sum(t.force_evaluations for t in out) * 15 / best / 1e6
        parts.append(f"{gap * 1e9:.0f} nm {v:g} m/s: event {rate['event']:.1f}, Verlet "
                     f"{rate['verlet']:.1f} M/s, Verlet / event {rate['verlet'] / rate['event']:.2f}x")
    print("3. particle-force evaluations/s (2 threads), " + "; ".join(parts)
          + " (target: within 2x)", flush=True)


EXAMPLE_CSV = ROOT / "measurements" / "example_restitution.csv"
EXAMPLE_SCENE = ROOT / "measurements" / "example_restitution.yaml"


def _twenty_rows(path: Path) -> None:
    """A SYNTHETIC 20-row measurement file for the joint fit: four chains of the shipped
    example's base scene (mean gap 47 nm, e = 0.92, gap seed 2025), each struck at five
    speeds in 0.03-0.1 m/s, the example's noise (0.2 us, 2 % of v_s)."""
    import numpy as np

    from granchain.inference import simulate_joint_rows
    from granchain.scene import load_scene
    base = load_scene(EXAMPLE_SCENE).derive({"gaps": {"seed": 2025}})
    speeds = np.tile([0.03, 0.045, 0.06, 0.08, 0.1], 4)
    reals = np.repeat(np.arange(4), 5)
    X = simulate_joint_rows(base, 47e-9, 0.92, speeds, reals, "dt_front_s")
    perr = 0.02 * speeds
    X = X + np.stack([np.full(speeds.size, 0.2e-6), perr, perr], axis=1) * \
        np.random.default_rng(3).standard_normal(X.shape)
    lines = ["# SYNTHETIC: benchmarks/targets.py, 47 nm, e = 0.92",
             "v_striker_m_s,dt_front_s,dt_err_s,vmax_1_m_s,vmax_2_m_s,vmax_err_m_s,chain_id"]
    lines += [f"{v:.6g},{x[0]:.6e},2.0e-07,{x[1]:.6e},{x[2]:.6e},{e:.2e},C{r}"
              for v, x, e, r in zip(speeds, X, perr, reals)]
    path.write_text("\n".join(lines) + "\n")


def row_inference() -> None:
    with tempfile.TemporaryDirectory(prefix="granchain-targets-") as tmp:
        tmp = Path(tmp)
        # as a user runs it: numpy's BLAS with its own threads
        env = dict(_env(), NUMBA_CACHE_DIR=str(tmp / "numba"),
                   GRANCHAIN_CACHE_DIR=str(tmp / "cache"))
        env.pop("OMP_NUM_THREADS")
        cmd = [sys.executable, "-m", "granchain.cli", "infer", "--scene", str(EXAMPLE_SCENE),
               "--fit", "gap_mean,restitution", "--json", "--no-progress"]
        fresh = _timed([*cmd[:4], str(EXAMPLE_CSV), *cmd[4:], "--cache-dir",
                        str(tmp / "grids-example")], env)
        rows = tmp / "twenty.csv"
        _twenty_rows(rows)
        twenty = _timed([*cmd[:4], str(rows), *cmd[4:], "--cache-dir", str(tmp / "grids-20")],
                        env)
    print(f"4. granchain infer, shipped joint example from a fresh state (compile included): "
          f"{fresh:.0f} s (target 60 s); a 20-row joint fit from an empty grid cache: "
          f"{twenty:.0f} s (target 120 s)", flush=True)


def _preset(preset: str, clone: Path, cache: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(clone), GRANCHAIN_CACHE_DIR=str(cache))
    t0 = time.perf_counter()
    subprocess.run(["snakemake", "--cores", "2", "--config", f"preset={preset}"], cwd=clone,
                   env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def row_presets(full: bool, presets: bool) -> None:
    with tempfile.TemporaryDirectory(prefix="granchain-targets-") as tmp:
        clone, cache = Path(tmp) / "clone", Path(tmp) / "cache"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        if presets:
            cold = _preset("default", clone, cache)
            shutil.rmtree(clone / "results")
            warm = _preset("default", clone, cache)
            print(f"5. default preset, snakemake --cores 2: {cold:.0f} s from nothing "
                  f"(target 90 s), {warm:.0f} s with compiled kernels (target 45 s)", flush=True)
        if full:
            t = _preset("full", clone, cache)
            print(f"6. full preset, snakemake --cores 2: {t / 60:.1f} min "
                  f"{'with compiled kernels' if presets else 'from nothing'} "
                  "(target 15 min)", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--presets", action="store_true", help="time the default preset")
    ap.add_argument("--full", action="store_true", help="time the full preset")
    ap.add_argument("--no-inference", action="store_true",
                    help="leave out row 4 (two granchain infer runs, minutes)")
    ap.add_argument("--only-inference", action="store_true", help="row 4 alone")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; "
          f"{time.strftime('%Y-%m-%d %H:%M')}", flush=True)
    if a.only_inference:
        row_inference()
        return
    row_run_vs_lammps(a.chains, a.repeats)
    row_lammps_overhead(a.repeats)
    row_event_throughput(a.repeats)
    if not a.no_inference:
        row_inference()
    if a.presets or a.full:
        row_presets(a.full, a.presets)


if __name__ == "__main__":
    main()
