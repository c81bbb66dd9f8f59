"""Whole-process overhead of the reference engine, measured side by side in one run.

    python benchmarks/overhead.py [--repeats 5] [--chains 1000]

1. A one-chain ``granchain run`` of the chapter's packed chain (every effect of Eq. 5.1, RK4
   at 1 ns), as whole processes, alternating: with the ahead-of-time kernels
   (``granchain warm-up`` built for this machine, no numba imported) and with numba's JIT
   kernels from its warm cache (an empty ``GRANCHAIN_CACHE_DIR``). Prints the medians and
   their ratio.
2. A cold job: the same run with an empty numba cache and no ahead-of-time module (what
   every job of a workflow would pay without the ``jit_cache`` rule), and the warm-up itself
   (``granchain warm-up`` into empty caches: JIT compile plus ahead-of-time compile).
3. Integrating ``--chains`` chains (20 nm gaps, every effect, Verlet at 1 ns) against
   summarising their trajectories into observables, in one process, both ways: with the
   sampled record summarised in Python (``trace=True``, the summariser) and with the
   observables measured on the fly by the kernel (``trace=False``), side by side.
4. A ``--chains``-chain ``granchain run --json --out`` of that scene as a whole process
   against its parts, measured in one process: imports, kernel, summarise, JSON output.
The machines are shared and noisy: compare the ratios, not absolute times across runs.
"""
from __future__ import annotations

import argparse
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--chains", type=int, default=1000)
    ap.add_argument("--ensemble-only", action="store_true",
                    help="only parts 3 and 4 (no warm-up, no cold job)")
    args = ap.parse_args(argv)
    run = [sys.executable, "-m", "granchain.cli", "run", SCENE]
    warm = [sys.executable, "-m", "granchain.cli", "warm-up"]
    base = dict(os.environ, PYTHONPATH=str(ROOT))
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

    # 4. the whole granchain run against its parts
    import json

    from granchain import cli
    t0 = time.perf_counter()
    doc = {"scene": scene.name, "scene_hash": scene.hash, "runs": [r.to_json() for r in runs]}
    text = json.dumps(cli._jsonable(doc), indent=1) + "\n"
    t_out = time.perf_counter() - t0
    imp = [sys.executable, "-c", "import granchain.cli, granchain.simulate, "
           "granchain.engines.reference as r; r.backend.kernels(serial=False)"]
    t_imp = statistics.median(_timed(imp, base) for _ in range(3))
    sets = [f"--set=ensemble.realisations={args.chains}",
            "--set=effects=[hertz,groove_friction,air_drag,rotation,particle_friction]",
            "--set=integrator.method=verlet"]
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "granchain.cli", "run",
               str(ROOT / "granchain/scenes/gaps-20nm-440c.yaml"), *sets, "--json",
               "--out", str(Path(d) / "out.json"), "--force"]
        t_proc = statistics.median(_timed(cmd, base) for _ in range(args.repeats))
    print(f"granchain run of {args.chains} chains (--json --out), median of {args.repeats}: "
          f"whole process {t_proc:.2f} s; its parts: imports + kernel load {t_imp:.2f} s, "
          f"kernel {b_int:.2f} s, summarise {b_sum:.3f} s, JSON output {t_out:.3f} s "
          f"({len(text) / 1e6:.1f} MB); kernel / process {b_int / t_proc:.2f}, "
          f"everything but the kernel / kernel {(t_proc - b_int) / b_int:.2f}")


if __name__ == "__main__":
    main()
