"""Whole-process overhead of the reference engine, measured side by side in one run.

    python benchmarks/overhead.py [--repeats 5] [--chains 1000]

1. A one-chain ``granchain run`` of the chapter's packed chain (every effect of Eq. 5.1, RK4
   at 1 ns), as whole processes, alternating: with the ahead-of-time kernels
   (``granchain warm-up`` built for this machine, no numba imported) and with numba's JIT
   kernels from its warm cache (an empty ``GRANCHAIN_CACHE_DIR``). Prints the medians and
   their ratio.
2. A cold job: the same run with an empty numba cache and no ahead-of-time module (what
   every job of a workflow would pay without the ``aot_kernels`` rule), and the warm-up itself
   (``granchain warm-up`` into empty caches: JIT compile plus ahead-of-time compile).
3. Integrating ``--chains`` chains (20 nm gaps, every effect, Verlet at 1 ns) against
   summarising their trajectories into observables, in one process, both ways: with the
   sampled record summarised in Python (``trace=True``, the summariser) and with the
   observables measured on the fly by the kernel (``trace=False``), side by side.
4. A ``--chains``-chain ``granchain run --json --out`` of that scene as a whole process,
   and the same process timed inside (``_PROBE``: ``granchain.cli.main`` with timers
   wrapped around its parts): interpreter start and exit, imports, planning (scene load,
   cost checks, run plan), kernel load (numba, the kernels module, the dispatcher's type
   resolution and cache load), kernel, the engine around the kernel (chunks, Trajectory
   building, the members' fields of ``run_scene``), summarise, output (JSON documents and the file), other; and the ratio
   (process - kernel) / kernel. Medians over ``--repeats`` processes each.
The machines are shared and noisy: compare the ratios, not absolute times across runs.

    python benchmarks/overhead.py --process-only [--repeats 3]     # part 4 alone
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
SCENE = str(ROOT / "granchain/scenes/packed-440c.yaml")


def _timed(cmd, env) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def _one_chain_processes(args, run, warm, base):
    """Parts 1 and 2: one-chain processes, ahead-of-time against JIT kernels; a cold job."""
    with tempfile.TemporaryDirectory() as aot_dir, tempfile.TemporaryDirectory() as empty, \
            tempfile.TemporaryDirectory() as cold_nb, tempfile.TemporaryDirectory() as cold_gc:
        env_aot = dict(base, GRANCHAIN_CACHE_DIR=aot_dir)
        env_jit = dict(base, GRANCHAIN_CACHE_DIR=empty)
        subprocess.run(warm, env=env_aot, check=True, stderr=subprocess.DEVNULL)
        _timed(run, env_jit)                                   # numba's own cache warm
        t_aot, t_jit = [], []
        for _ in range(args.repeats):
            t_aot.append(_timed(run, env_aot))
            t_jit.append(_timed(run, env_jit))
        a, j = statistics.median(t_aot), statistics.median(t_jit)
        print(f"one-chain granchain run (packed 440C, every effect, RK4 1 ns), median of "
              f"{args.repeats}: ahead-of-time kernels {a:.3f} s, JIT kernels (warm cache) "
              f"{j:.3f} s, ratio JIT/AOT {j / a:.2f}")
        cold = _timed(run, dict(base, GRANCHAIN_CACHE_DIR=empty, NUMBA_CACHE_DIR=cold_nb))
        print(f"cold job (empty numba cache, no ahead-of-time module): {cold:.1f} s = "
              f"{cold / j:.1f}x a warm JIT job")
        w = _timed(warm, dict(base, GRANCHAIN_CACHE_DIR=cold_gc,
                              NUMBA_CACHE_DIR=tempfile.mkdtemp(dir=cold_gc)))
        print(f"granchain warm-up from empty caches (JIT compile + ahead-of-time compile): {w:.1f} s, "
              "once per machine")


# Runs ``granchain.cli.main(argv)`` with timers around its parts and prints them as one JSON
# line on stderr. Each part is exclusive: a wrapped call's time is not counted again in
# the part of a call that encloses it.
_PROBE = r"""
import sys, time
T0 = time.perf_counter()
import json
from collections import defaultdict
acc = defaultdict(float)
stack = []

def timed(owner, name, key):
    f = getattr(owner, name)
    def w(*a, **k):
        t = time.perf_counter()
        stack.append(0.0)
        try:
            return f(*a, **k)
        finally:
            dt = time.perf_counter() - t
            inner = stack.pop()
            acc[key] += dt - inner
            if stack:
                stack[-1] += dt
    setattr(owner, name, w)

import granchain.cli as cli
from granchain import runplan, simulate
from granchain.commands import run as run_command
from granchain.engines import backend
T1 = time.perf_counter()
acc["imports"] = T1 - T0
for name in ("load", "check_cost", "run_estimate", "check_whole_run"):
    timed(run_command, name, "planning")
timed(simulate, "plan_run", "planning")
timed(runplan.RunPlan, "check", "planning")
timed(simulate, "run_scene", "engine around the kernel")
timed(simulate, "summarize", "summarise")
timed(run_command, "cmd_run", "output")
timed(backend, "jit_entry", "kernel load")
_entry = backend.Kernels.__getattr__

def _kernel_attr(self, name):
    f = _entry(self, name)
    def call(*a, **k):
        from numba.core.dispatcher import Dispatcher
        if not getattr(Dispatcher, "_probe", False):
            timed(Dispatcher, "_compile_for_args", "kernel load")
            Dispatcher._probe = True
        t = time.perf_counter()
        stack.append(0.0)
        try:
            return f(*a, **k)
        finally:
            dt = time.perf_counter() - t
            inner = stack.pop()
            acc["kernel"] += dt - inner
            if stack:
                stack[-1] += dt
    return call
backend.Kernels.__getattr__ = _kernel_attr
cli.main(sys.argv[1:])
acc["in process"] = time.perf_counter() - T0
print("PROBE " + json.dumps(acc), file=sys.stderr)
"""

PARTS = ("imports", "planning", "kernel load", "kernel", "engine around the kernel",
         "summarise", "output")


def _probe(cmd_args, env) -> dict:
    """One probed process: its wall time ("process") and the probe's parts."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", _PROBE, *cmd_args], env=env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    line = [ln for ln in r.stderr.splitlines() if ln.startswith("PROBE ")][-1]
    parts = json.loads(line[len("PROBE "):])
    parts["process"] = wall
    parts["start and exit"] = wall - parts.pop("in process")
    return parts


def _whole_process(args, base) -> None:
    """Part 4: the whole ``granchain run`` of ``--chains`` chains, plain and probed."""
    sets = [f"--set=ensemble.realisations={args.chains}",
            "--set=effects=[hertz,groove_friction,air_drag,rotation,particle_friction]",
            "--set=integrator.method=verlet"]
    with tempfile.TemporaryDirectory() as d:
        cli_args = ["run", str(ROOT / "granchain/scenes/gaps-20nm-440c.yaml"), *sets,
                    "--json", "--out", str(Path(d) / "out.json"), "--force"]
        plain = [sys.executable, "-m", "granchain.cli", *cli_args]
        _timed(plain, base)                               # kernel cache warm
        t_plain, probes = [], []
        for _ in range(args.repeats):
            t_plain.append(_timed(plain, base))
            probes.append(_probe(cli_args, base))
        size = (Path(d) / "out.json").stat().st_size
    med = {k: statistics.median(p[k] for p in probes) for k in probes[0]}
    proc, kern = med["process"], med["kernel"]
    known = sum(med[k] for k in PARTS) + med["start and exit"]
    print(f"granchain run of {args.chains} chains (verlet 1 ns, every effect, 20 nm gaps; "
          f"--json --out, {size / 1e6:.1f} MB), medians of {args.repeats}, alternating: "
          f"plain process {statistics.median(t_plain):.2f} s, probed process {proc:.2f} s")
    for k in ("start and exit",) + PARTS:
        print(f"  {k:<26s} {med[k]:6.3f} s  {med[k] / proc:6.1%}")
    print(f"  {'other':<26s} {proc - known:6.3f} s  {(proc - known) / proc:6.1%}")
    print(f"(process - kernel) / kernel = {(proc - kern) / kern:.2f}  "
          f"(probed process; plain: {(statistics.median(t_plain) - kern) / kern:.2f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--ensemble-only", action="store_true",
                    help="only parts 3 and 4 (no warm-up, no cold job)")
    ap.add_argument("--process-only", action="store_true",
                    help="only part 4 (the whole granchain run and its breakdown)")
    args = ap.parse_args(argv)
    run = [sys.executable, "-m", "granchain.cli", "run", SCENE]
    warm = [sys.executable, "-m", "granchain.cli", "warm-up"]
    base = dict(os.environ, PYTHONPATH=str(ROOT))
    if args.process_only:
        _whole_process(args, base)
        return
    if not args.ensemble_only:
        _one_chain_processes(args, run, warm, base)

    import numpy as np

    from granchain.engines import reference
    from granchain.gaps import member_gaps, members
    from granchain.observables import summarize
    from granchain.scene import load_scene
    scene = load_scene(str(ROOT / "granchain/scenes/gaps-20nm-440c.yaml"),
                       [f"ensemble.realisations={args.chains}",
                        "effects=[hertz,groove_friction,air_drag,rotation,particle_friction]",
                        "integrator.method=verlet"])
    mem = members(scene)
    g = member_gaps(scene, mem)
    vs = np.array([m.v_striker for m in mem])
    for trace in (True, False):
        list(reference.run(scene, g[:2], vs[:2], progress=False, trace=trace))  # compile/load
    parts = {}
    for trace in (True, False):
        t0 = time.perf_counter()
        trajs = list(reference.run(scene, g, vs, progress=False, trace=trace))
        t_int = time.perf_counter() - t0
        t0 = time.perf_counter()
        runs = [summarize(tr, scene.probes) for tr in trajs]
        t_sum = time.perf_counter() - t0
        parts[trace] = (t_int, t_sum, runs)
        how = "sampled record + Python summariser" if trace else "observables on the fly"
        print(f"{len(trajs)} chains, {how}: integrate {t_int:.2f} s, summarize {t_sum:.3f} s, "
              f"ratio summarize/integrate {t_sum / t_int:.3f}")
        del trajs
    (a_int, a_sum, _), (b_int, b_sum, runs) = parts[True], parts[False]
    print(f"on the fly / record: integrate {b_int / a_int:.2f}, integrate + summarize "
          f"{(b_int + b_sum) / (a_int + a_sum):.2f}")

    _whole_process(args, base)


if __name__ == "__main__":
    main()
