"""The one-time kernel compile of several trees, side by side: ``granchain warm-up`` cold.

    python benchmarks/cold_compile.py [--trees HEAD main 76a7b88] [--repeats 1]

Each tree (a git ref, or ``.`` for this checkout as it is, uncommitted changes included)
is extracted with ``git archive <ref> | tar -x`` into a temporary directory and runs
``python -m granchain.cli warm-up`` (the JIT kernels in ``backend.num_threads()`` worker
processes, then the ahead-of-time module) as a process of its own, into empty caches
(fresh ``$NUMBA_CACHE_DIR`` and ``$GRANCHAIN_CACHE_DIR`` each time). The trees take turns,
``--repeats`` rounds of them, so that a change in the machine's load falls on each. Each
run is measured by its wall time and by the CPU seconds (user + system) of the process
and its children (``resource.getrusage(RUSAGE_CHILDREN)`` before and after): on a shared
machine the CPU seconds move far less than the wall time. Prints every run with the load
average at its start and end, then each tree's fastest run and its ratios to the first
tree's (a ratio below 1: the tree compiles faster than the first).
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def extract(ref: str, dest: Path) -> Path:
    """The tree of ``ref`` in ``dest`` (``.``: this checkout itself); returns its path."""
    if ref == ".":
        return REPO
    dest.mkdir(parents=True)
    arch = subprocess.run(["git", "-C", str(REPO), "archive", ref], capture_output=True,
                          check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=arch, check=True)
    return dest


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def warm_up(tree: Path, scratch: Path) -> dict:
    """Wall and CPU seconds of ``granchain warm-up`` of ``tree`` into empty caches."""
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(scratch / "numba"),
               GRANCHAIN_CACHE_DIR=str(scratch / "granchain"))
    load0 = os.getloadavg()[0]
    c0, t0 = children_cpu(), time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "granchain.cli", "warm-up"],
                       cwd=tree, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, children_cpu() - c0
    shutil.rmtree(scratch, ignore_errors=True)
    if r.returncode != 0:
        sys.exit(f"warm-up of {tree} failed (exit {r.returncode}):\n{r.stderr[-3000:]}")
    return {"wall": wall, "cpu": cpu, "load": (load0, os.getloadavg()[0])}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trees", nargs="+", default=["HEAD", "main"],
                    help="git refs (or . for this checkout); ratios are to the first")
    ap.add_argument("--repeats", type=int, default=1,
                    help="rounds of the trees taking turns; the fastest run counts")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        sys.exit("--repeats: give 1 or more")
    shas = {}
    for ref in args.trees:
        if ref == ".":
            shas[ref] = "checkout"
            continue
        r = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", ref],
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"--trees: {ref!r} is not a git ref here; give a commit, branch or .")
        shas[ref] = r.stdout.strip()
    tmp = Path(tempfile.mkdtemp(prefix="granchain-cold-compile-"))
    try:
        trees = {ref: extract(ref, tmp / f"tree{j}") for j, ref in enumerate(args.trees)}
        print(f"granchain warm-up into empty caches; trees {', '.join(f'{r} ({s})' for r, s in shas.items())}; "
              f"{args.repeats} round(s) taking turns; {os.cpu_count()} cores", flush=True)
        best: dict[str, dict] = {}
        for k in range(args.repeats):
            for ref, tree in trees.items():
                m = warm_up(tree, tmp / "scratch")
                print(f"round {k + 1} {ref:>10s} ({shas[ref]}): wall {m['wall']:7.1f} s, "
                      f"CPU {m['cpu']:7.1f} s; load {m['load'][0]:.1f} -> {m['load'][1]:.1f}",
                      flush=True)
                if ref not in best or m["cpu"] < best[ref]["cpu"]:
                    best[ref] = m
        first = best[args.trees[0]]
        for ref in args.trees:
            m = best[ref]
            print(f"{ref:>10s} ({shas[ref]}): wall {m['wall']:7.1f} s, CPU {m['cpu']:7.1f} s; "
                  f"/ {args.trees[0]}: wall x{m['wall'] / first['wall']:.2f}, "
                  f"CPU x{m['cpu'] / first['cpu']:.2f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
