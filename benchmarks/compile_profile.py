"""Where the one-time kernel compile goes: each compiled function's own seconds.

    python benchmarks/compile_profile.py [--runs verlet rk4 adaptive event event:trace]
                                         [--top 25] [--passes]

Runs the warm-up runs named (``granchain.engines.warmup``: a small chain with every effect
through each method; ``event:trace`` the event method with a trace, its one-chain kernel)
in a fresh process into empty caches (``NUMBA_CACHE_DIR`` and ``GRANCHAIN_CACHE_DIR`` in a
new temporary directory, so that everything compiles), and records numba's compile events
(``numba.core.event``, ``numba:compile``): the seconds between each function's start and
end, less those of the functions compiled inside it, which is its own share. A function
inlined by numba (``inline="always"``) is compiled inside its caller and counts there.
Prints the whole-process seconds, the sum over functions, each run's CPU seconds in turn
(a run after others compiles only what they left: its marginal cost) and the ``--top``
largest shares. With ``--passes``, the shares are numba's compiler passes instead
(``numba:run_pass``: each pass of each function, its own seconds: typing, numba's own
inlining of ``inline="always"`` callees, lowering; the LLVM optimisation and code
emission of a function's linked library fall in its lowering pass), and the seconds
spent holding numba's LLVM lock (``numba:llvm_lock``: LLVM's own work) are printed
beside the total.
The machines are shared: compare the shares of one run, not seconds across runs.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

CHILD = r"""
import collections, json, sys, time
from numba.core import event as ev
own = collections.defaultdict(float)
stack = []
passes = sys.argv[2] == "1"
class Listener(ev.Listener):
    def on_start(self, e):
        if passes:
            name = e.data['name']          # the pass, [the function]
        else:
            d = e.data.get("dispatcher")
            name = d.py_func.__qualname__ if d is not None else "?"
        stack.append((name, time.perf_counter()))
    def on_end(self, e):
        name, t0 = stack.pop()
        dt = time.perf_counter() - t0
        own[name] += dt
        if stack:
            own[stack[-1][0]] -= dt
ev.register("numba:run_pass" if passes else "numba:compile", Listener())
llvm = [0.0, 0, 0.0]
class Lock(ev.Listener):
    def on_start(self, e):
        if llvm[1] == 0:
            llvm[2] = time.perf_counter()
        llvm[1] += 1
    def on_end(self, e):
        llvm[1] -= 1
        if llvm[1] == 0:
            llvm[0] += time.perf_counter() - llvm[2]
ev.register("numba:llvm_lock", Lock())
from granchain.engines.warmup import _warm_up_runs
cpu = []
for r in json.loads(sys.argv[1]):
    m, _, t = r.partition(":")
    c0 = time.process_time()
    _warm_up_runs([(m, t == "trace")])
    cpu.append(time.process_time() - c0)
print(json.dumps([own, cpu, llvm[0]]))
"""


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", default=["verlet"],
                    help="warm-up runs: rk4, verlet, adaptive, event, event:trace")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--passes", action="store_true",
                    help="shares by numba compiler pass, not by function")
    args = ap.parse_args(argv)
    known = {"rk4", "verlet", "adaptive", "event", "event:trace"}
    bad = [r for r in args.runs if r not in known]
    if bad:
        sys.exit(f"--runs: unknown {bad}; give any of {sorted(known)}")
    with tempfile.TemporaryDirectory(prefix="granchain-compile-") as tmp:
        env = dict(os.environ, PYTHONPATH=str(REPO), NUMBA_CACHE_DIR=f"{tmp}/numba",
                   GRANCHAIN_CACHE_DIR=f"{tmp}/granchain")
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(args.runs),
                              "1" if args.passes else "0"], cwd=REPO,
                             env=env, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - t0
    own, cpu, llvm = json.loads(out.stdout.strip().splitlines()[-1])
    total = sum(own.values())
    print(f"cold compile of {' '.join(args.runs)}: {wall:.1f} s whole process, {total:.1f} s "
          f"in numba's {'passes' if args.passes else 'compile events'} ({llvm:.1f} s holding "
          f"its LLVM lock); load average {load:.1f} at the start on "
          f"{os.cpu_count()} cores")
    print("CPU seconds of each run, in turn: " + ", ".join(
        f"{r} {c:.1f} s" for r, c in zip(args.runs, cpu)))
    for name, s in sorted(own.items(), key=lambda kv: -kv[1])[:args.top]:
        print(f"{s:8.1f} s {s / total:6.1%}  {name}")


if __name__ == "__main__":
    main()
