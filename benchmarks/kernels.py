"""Fixed-step reference kernels against the previous kernels and LAMMPS, side by side in one run.

    python benchmarks/kernels.py [--chains 1000] [--old-ref 41e9852] [--np 2] [--skip-lammps]
                                 [--repeats 3] [--cold-compile] [--threads 1] [--no-hetero]
                                 [--settings hertz-verlet all-verlet all-rk4 jkr-verlet]

The ensemble: gaps-20nm-440c (440C, v_s = 0.1 m/s, uniform gaps of mean 20 nm), t_end auto,
``--chains`` realisations, in three settings: Hertz-only Verlet, every effect Verlet
(hertz, groove, drag, rotation, particle friction, rolling friction with k_roll = 1e3 N/m),
every effect RK4 (the chapter's setting), all at dt = 1 ns (``--settings`` picks among
them and ``jkr-verlet``, every effect with JKR adhesion at 1 J/m^2, which trees before
the adhesion effect cannot run). Then the same ensemble as a
heterogeneous chain (``HETERO``: dimer radii 150/120 um, alternating 440C and 52100 steel,
a tungsten-carbide striker, an 440C end wall), Hertz-only and every effect, Verlet, on this
tree alone: its particle-step rate against the previous kernels' rate on the uniform
chain, which is the cost of per-sphere parameters and the wall. Each setting runs in its own
process for this tree and for ``--old-ref`` (extracted with ``git archive`` into a
temporary directory: the kernels as they were), after a warm-up compile; the trajectories
of the two are compared bit for bit (v, energies, steps, status). Then LAMMPS on ``--np``
ranks on the every-effect Verlet ensemble without per-sample output: its loop time (from
its log) and its process wall time. Prints particle-steps per second and the ratios, and
the fraction of the machine's division/sqrt peak: the divisions and square roots a
particle-step costs when every lane computes every law (counted from the effects'
laws, ``granchain/effects/``), times their throughput measured here by a numba probe, on all
cores. With ``--cold-compile``, first the one-time compile: ``granchain warm-up`` (the JIT
kernels in two processes, then the ahead-of-time module) as a whole process, for each tree
in turn, each time into empty caches (fresh ``$NUMBA_CACHE_DIR`` and
``$GRANCHAIN_CACHE_DIR``). With ``--threads N``, the kernels run on N numba threads
(``NUMBA_NUM_THREADS``) and each run is measured by its process CPU time around the run,
not its wall time: on a loaded machine one thread's CPU seconds move far less than the
wall time of two threads that wait for cores. The machines are shared: only ratios
measured in the one run are worth comparing.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"
SETTINGS = {
    "hertz-verlet": ["effects=[hertz]", "integrator.method=verlet"],
    "all-verlet": [f"effects={ALL}", "rolling.k_roll=1000.0", "integrator.method=verlet"],
    "all-rk4": [f"effects={ALL}", "rolling.k_roll=1000.0", "integrator.method=rk4"],
}
# divisions and square roots of one particle-step with every law computed in every lane
# (forces_block: acceleration 1 div; drag 3 div; groove 2 div + 1 in its return map;
# particle friction 1 div + 1 in its map, Mindlin sqrt; rolling 1 div + 1 in its map;
# Hertz 1 sqrt; RK4: four force calls without the maps, then project_block with the
# three maps and 3 sqrt)
OPS = {"hertz-verlet": (1, 1), "all-verlet": (11, 3), "all-rk4": (4 * 8 + 3, 4 * 2 + 3)}
# settings run only when asked for (``--settings``): trees before adhesion lack them.
# jkr-verlet: every effect with JKR adhesion at 1 J/m^2 (each contact's law: a cube root
# and three square roots besides the every-effect Verlet's operations, not counted in OPS)
EXTRA_SETTINGS = {
    "jkr-verlet": [f"effects={ALL[:-1]}, adhesion]", "rolling.k_roll=1000.0",
                   "adhesion.model=jkr", "adhesion.surface_energy=1.0",
                   "integrator.method=verlet"],
}
OPS["jkr-verlet"] = OPS["all-verlet"]
_R = ", ".join(["1.5e-4", "1.2e-4"] * 7 + ["1.5e-4"])
# the striker tungsten carbide, then 52100 and 440C in turn (the list gives every sphere's)
_M = ", ".join(["tungsten_carbide"] + ["chrome_steel_52100", "ss440c"] * 7)
HETERO = [f"chain.radius=[{_R}]", f"chain.materials=[{_M}]", "material=null",
          "walls.end=ss440c"]
# heterogeneous settings (this tree only) -> the uniform setting of the previous kernels
# they are compared with
HETERO_SETTINGS = {"het-hertz-verlet": ("hertz-verlet", SETTINGS["hertz-verlet"] + HETERO),
                   "het-all-verlet": ("all-verlet", SETTINGS["all-verlet"] + HETERO)}

CHILD = r"""
import json, sys, time
import numpy as np
from granchain.engines import reference
from granchain.scene import load_scene
from granchain.simulate import member_gaps, members
sets, out = json.loads(sys.argv[1]), sys.argv[2]
sc = load_scene("granchain/scenes/gaps-20nm-440c.yaml", sets)
mem = members(sc); gaps = member_gaps(sc, mem); vs = np.array([m.v_striker for m in mem])
list(reference.run(sc, gaps[:2], vs[:2], progress=False))
t0, c0 = time.perf_counter(), time.process_time()
tr = list(reference.run(sc, gaps, vs, progress=False))
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
np.savez(out, steps=[t.steps for t in tr], status=[t.status for t in tr],
         v=np.concatenate([t.v.ravel() for t in tr]),
         e=np.concatenate([t.energy for t in tr]))
print(json.dumps({"wall": wall, "cpu": cpu, "ps": int(sum(t.steps for t in tr)) * sc.n}))
"""


def child(tree: Path, sets, out: Path, threads: int | None = None):
    # a cache directory with no ahead-of-time module: both trees run numba's JIT kernels
    # (on one thread a tree with the module built would run it instead)
    env = dict(os.environ, PYTHONPATH=str(tree),
               GRANCHAIN_CACHE_DIR=str(out.parent / f"cache-{tree.name}"))
    if threads:
        env["NUMBA_NUM_THREADS"] = str(threads)
    r = subprocess.run([sys.executable, "-c", CHILD, json.dumps(sets), str(out)], cwd=tree,
                       env=env, capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def cold_compile(tree: Path, scratch: Path) -> dict:
    """Whole-process seconds of ``granchain warm-up`` of ``tree`` into empty caches."""
    if scratch.exists():
        shutil.rmtree(scratch)
    scratch.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(scratch / "numba"),
               GRANCHAIN_CACHE_DIR=str(scratch / "granchain"))
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "granchain.cli", "warm-up"], cwd=tree, env=env,
                   capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    shutil.rmtree(scratch, ignore_errors=True)
    return {"wall": wall}


def alternate(run_a, run_b, repeats: int, key: str = "wall"):
    """The fastest of ``repeats`` runs of each by ``key`` (their wall or CPU seconds), a
    and b taking turns, so that a change in the machine's load falls on both (shared
    machines); which of the two runs first alternates from turn to turn, so that what the
    first run of a pair leaves the second (or takes from it) falls on each as often. Each
    result also holds ``turns``: the ratios b / a of every turn's pair, sorted (a slow
    drift of the machine's speed falls on both runs of a turn, so their spread says how
    far the fastest runs' ratio can be trusted)."""
    best_a = best_b = None
    turns = []
    for i in range(repeats):
        if i % 2:
            b = run_b()
            a = run_a()
        else:
            a, b = run_a(), run_b()
        turns.append(b[key] / a[key])
        best_a = a if best_a is None or a[key] < best_a[key] else best_a
        best_b = b if best_b is None or b[key] < best_b[key] else best_b
    turns.sort()
    return dict(best_a, turns=turns), dict(best_b, turns=turns)


def median_interval(turns, level: float = 0.95):
    """A distribution-free interval of the median of the turns' ratios: the order
    statistics x_(k) and x_(n+1-k) (1-based, sorted), k the largest with
    P(k - 1 or fewer of n fall below the median) <= (1 - level) / 2, which holds the
    median with probability >= level whatever the ratios' distribution, as long as the
    turns are independent. None with too few turns (n < 6 at 95 %)."""
    x = sorted(turns)
    n = len(x)
    tail, k = 0.0, 0
    while True:
        tail += math.comb(n, k) / 2.0 ** n      # P(exactly k below the median)
        if tail > (1.0 - level) / 2.0:
            break
        k += 1
    if k == 0:
        return None
    return x[k - 1], x[n - k]


def spread(turns) -> str:
    """The turns' ratios: their median with its 95 % interval (``median_interval``), and
    the range of the middle half and of all."""
    import numpy as np
    q = np.quantile(turns, [0.0, 0.25, 0.5, 0.75, 1.0])
    ci = median_interval(turns)
    ci = (f" (95 % interval of the median x{ci[0]:.3f}-x{ci[1]:.3f})" if ci else
          " (too few turns for a 95 % interval of the median: 6 or more)")
    return (f"per-turn ratios median x{q[2]:.3f}{ci}, middle half x{q[1]:.3f}-x{q[3]:.3f}, "
            f"all x{q[0]:.3f}-x{q[4]:.3f} ({len(turns)} turns)")


def same(a: Path, b: Path) -> bool:
    import numpy as np
    x, y = np.load(a), np.load(b)
    # the ledger columns both trees have (a newer tree may append columns, e.g. work_load)
    cols = min(x["e"].shape[1], y["e"].shape[1])
    return all(np.array_equal(x[k], y[k]) for k in ("steps", "status", "v")) and \
        np.array_equal(x["e"][:, :cols], y["e"][:, :cols])


def peak_ops():
    """Seconds per double-precision division and per square root on one core (zmm)."""
    import math

    import numpy as np
    from numba import njit

    @njit(error_model="numpy")
    def pdiv(a, b, out, N):
        for _ in range(N):
            for i in range(a.shape[0]):
                out[i] = a[i] / b[i] + out[i] / b[i]

    @njit(error_model="numpy")
    def psqrt(a, out, N):
        for _ in range(N):
            for i in range(a.shape[0]):
                out[i] = math.sqrt(a[i]) + math.sqrt(out[i])

    a, b, o = (np.random.rand(512) + 1 for _ in range(3))
    pdiv(a, b, o, 1)
    psqrt(a, o, 1)
    N = 100000
    t0 = time.thread_time()
    pdiv(a, b, o, N)
    t_div = (time.thread_time() - t0) / (N * 1024)
    t0 = time.thread_time()
    psqrt(a, o, N)
    t_sqrt = (time.thread_time() - t0) / (N * 1024)
    return t_div, t_sqrt


def lammps(chains, nprocs, wd: Path):
    import numpy as np  # noqa: F401
    sys.path.insert(0, str(REPO))
    from granchain.lammps import deck as lammps_deck
    from granchain.lammps.runner import run_lammps
    from granchain.scene import load_scene
    from granchain.simulate import member_gaps, members
    sc = load_scene(REPO / "granchain/scenes/gaps-20nm-440c.yaml",
                    [f"ensemble.realisations={chains}"] + SETTINGS["all-verlet"])
    mem = members(sc)
    gaps = member_gaps(sc, mem)
    vs = [m.v_striker for m in mem]
    wd.mkdir(parents=True)
    deck = lammps_deck.write_deck(sc, wd, gaps=gaps, v_striker=vs, output="none")
    t0 = time.perf_counter()
    run_lammps(deck, wd, nprocs=nprocs)
    wall = time.perf_counter() - t0
    m = re.search(r"Loop time of (\S+) on (\d+) procs for (\d+) steps",
                  (wd / "log.lammps").read_text())
    return float(m.group(1)), wall, int(m.group(3))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--old-ref", default="41e9852",
                    help="git ref of the previous kernels (default: the last ones with one "
                         "mass and radius per run)")
    ap.add_argument("--np", type=int, default=2, help="LAMMPS MPI ranks")
    ap.add_argument("--skip-lammps", action="store_true")
    ap.add_argument("--cold-compile", action="store_true",
                    help="also time the one-time compile of each tree into empty caches")
    ap.add_argument("--repeats", type=int, default=3,
                    help="runs of each tree, taking turns; the fastest counts (default 3)")
    ap.add_argument("--threads", type=int, default=None,
                    help="numba threads of the runs; measure their CPU time, not wall time")
    ap.add_argument("--settings", nargs="+", choices=[*SETTINGS, *EXTRA_SETTINGS],
                    default=list(SETTINGS),
                    help=f"the settings to run (default: {' '.join(SETTINGS)})")
    ap.add_argument("--no-hetero", action="store_true",
                    help="skip the heterogeneous chains (this tree against the previous "
                         "kernels' uniform chain)")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="granchain-kernels-"))
    try:
        old = tmp / "old"
        old.mkdir()
        arch = subprocess.run(["git", "-C", str(REPO), "archive", args.old_ref],
                              capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=arch, check=True)
        print(f"{args.chains} chains x 15 spheres, gaps-20nm-440c, dt 1 ns, t_end auto; "
              f"previous kernels: {args.old_ref}; load average {os.getloadavg()[0]:.1f} on "
              f"{os.cpu_count()} cores", flush=True)
        t_div, t_sqrt = peak_ops()
        cores = os.cpu_count()
        print(f"probe: {t_div * 1e9:.3f} ns per division, {t_sqrt * 1e9:.3f} ns per sqrt "
              "(one core, vectorised)", flush=True)
        if args.cold_compile:
            new, prev = alternate(lambda: cold_compile(REPO, tmp / "cold-new"),
                                  lambda: cold_compile(old, tmp / "cold-old"), args.repeats)
            print(f"cold compile (granchain warm-up into empty caches, fastest of "
                  f"{args.repeats}): new {new['wall']:.1f} s, previous {prev['wall']:.1f} s: "
                  f"new / previous x{new['wall'] / prev['wall']:.2f}", flush=True)
        key = "cpu" if args.threads else "wall"
        if args.threads:
            cores = args.threads
            print(f"{args.threads} numba thread(s); times are each run's process CPU seconds",
                  flush=True)
        rows = {}
        for name in args.settings:
            sets = [f"ensemble.realisations={args.chains}"] + {**SETTINGS,
                                                               **EXTRA_SETTINGS}[name]
            new, prev = alternate(lambda: child(REPO, sets, tmp / f"{name}-new.npz", args.threads),
                                  lambda: child(old, sets, tmp / f"{name}-old.npz", args.threads),
                                  args.repeats, key)
            ident = same(tmp / f"{name}-new.npz", tmp / f"{name}-old.npz")
            nd, ns = OPS[name]
            peak = cores / (nd * t_div + ns * t_sqrt)
            rows[name] = (new, prev, ident, peak)
            print(f"{name:13s}: new {new[key]:.2f} s ({new['ps'] / new[key] / 1e6:.0f} M "
                  f"particle-steps/s), previous {prev[key]:.2f} s "
                  f"({prev['ps'] / prev[key] / 1e6:.0f} M/s): x{prev[key] / new[key]:.2f}; "
                  f"bit-identical {ident}; all-lanes div/sqrt peak {peak / 1e6:.0f} M/s, "
                  f"reached {new['ps'] / new[key] / peak:.0%}; {spread(new['turns'])}",
                  flush=True)
        for name, (base, sets) in HETERO_SETTINGS.items():
            if args.no_hetero:
                break
            sets = [f"ensemble.realisations={args.chains}"] + sets
            base_sets = [f"ensemble.realisations={args.chains}"] + SETTINGS[base]
            het, prev = alternate(lambda: child(REPO, sets, tmp / f"{name}-new.npz", args.threads),
                                  lambda: child(old, base_sets, tmp / f"{name}-old.npz",
                                                args.threads),
                                  args.repeats, key)
            rate, rate0 = het["ps"] / het[key], prev["ps"] / prev[key]
            print(f"{name:16s}: {het['wall']:.2f} s ({rate / 1e6:.0f} M particle-steps/s) against "
                  f"the previous kernels' uniform {base} ({rate0 / 1e6:.0f} M/s): "
                  f"{rate / rate0:.0%} of their throughput", flush=True)
        if not args.skip_lammps and "all-verlet" in rows:
            loop, wall, steps = lammps(args.chains, args.np, tmp / "lammps")
            new = rows["all-verlet"][0]
            print(f"LAMMPS -np {args.np}, every effect Verlet, no output: loop {loop:.2f} s "
                  f"({steps} steps), process {wall:.2f} s; reference every-effect Verlet "
                  f"{new['wall']:.2f} s: LAMMPS loop / reference x{loop / new['wall']:.2f}, "
                  f"LAMMPS process / reference x{wall / new['wall']:.2f}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
