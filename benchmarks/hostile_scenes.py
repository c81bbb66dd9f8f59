"""What hostile scene files cost ``granchain validate``, side by side with the chapter's scene.

    python benchmarks/hostile_scenes.py [--repeats 3]

Each file is validated by a fresh ``granchain validate`` process (the fastest of
``--repeats`` runs counts: the machines are shared); the table gives its size, the exit
status, the wall time and peak resident memory of the whole process (interpreter start
included), and their ratios to the chapter's packed scene. Then the fuzzing strategies of
tests/test_fuzz_inputs.py, in this process: the time per example of the scene fuzz
(loader, validator and the CLI's validate) and of the measurement-CSV fuzz.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

ALIAS_BOMB = "chain:\n  n: [&a [1,1,1,1,1,1,1,1,1,1],\n" + "".join(
    f"      &{b} [{','.join(['*' + a] * 10)}]{']' if b == 'i' else ','}\n"
    for a, b in zip("abcdefgh", "bcdefghi"))
LIST = ",".join(["1.5e-4", "1.6e-4"] * 12450)
MATS = ",".join(["ss440c", "brass"] * 12450)
CASES = {
    "chapter scene": (REPO / "granchain/scenes/packed-440c.yaml").read_text(),
    "alias bomb (10^9 values)": ALIAS_BOMB,
    "deep nesting (3e5 levels)": "chain:\n  n: " + "[" * 300000 + "]" * 300000 + "\n",
    "sexagesimal int (1 MB)": "chain:\n  n: 1" + ":00" * 330000 + "\n",
    "list of 140000 radii (1 MB)": "chain:\n  radius: [" + ",".join(["1.5e-4"] * 140000)
                                   + "]\n",
    "string of 1 MB": "material: " + "x" * 1_000_000 + "\n",
    "n = 1e6, wall, preload, spread": "chain: {n: 1000000, radius_spread: {sd: 1.0e-6}}\n"
                                      "walls: {end: rigid}\nprecompression: {force: 0.01}\n",
    "24900 spheres, radius and material lists": f"chain: {{n: 24900, radius: [{LIST}], "
                                                f"materials: [{MATS}]}}\nwalls: {{end: rigid}}\n",
}


# the child's own peak resident memory (VmHWM, kB) to stderr's last line: getrusage's
# ru_maxrss would carry this process's size over fork and exec
CHILD = ("import sys\nfrom granchain.cli import main\nrc = main(sys.argv[1:])\n"
         "hwm = [ln for ln in open('/proc/self/status') if ln.startswith('VmHWM')]\n"
         "print(hwm[0].split()[1], file=sys.stderr)\nsys.exit(rc)\n")


def validate(path: str) -> tuple[int, float, float]:
    """(exit status, wall seconds, peak RSS in MB) of one ``granchain validate``."""
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", CHILD, "validate", path], capture_output=True,
                       text=True, cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)))
    secs = time.perf_counter() - t0
    return p.returncode, secs, float(p.stderr.split()[-1]) / 1024


def fuzz_times(n_scenes: int, n_csvs: int) -> dict[str, list[float]]:
    sys.path.insert(0, str(REPO / "tests"))
    from hypothesis import HealthCheck, given, settings
    import test_fuzz_inputs as fz
    fz.TIMES["scene"].clear()
    fz.TIMES["csv"].clear()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        opts = dict(deadline=None, database=None, suppress_health_check=list(HealthCheck))
        settings(max_examples=n_scenes, **opts)(given(fz.scenes(), fz.st.booleans(),
                                                      fz.st.booleans())(
            lambda raw, flow, alias: fz.check_scene_text(fz.yaml_text(raw, flow, alias),
                                                         tmp)))()
        settings(max_examples=n_csvs, **opts)(given(fz.csv_texts(), fz.st.booleans())(
            lambda data, peaks: fz.check_csv(data, peaks, tmp)))()
    return fz.TIMES


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--fuzz", type=int, default=1000, help="fuzz examples of each kind")
    args = ap.parse_args(argv)
    print(f"load {os.getloadavg()[0]:.1f}; peak RSS and wall time of a whole "
          "`granchain validate` process; ratios to the chapter scene")
    print(f"{'file':44s} {'bytes':>8s} {'exit':>4s} {'s':>6s} {'x':>5s} {'MB':>6s} {'x':>5s}")
    base = None
    with tempfile.TemporaryDirectory() as d:
        for name, text in CASES.items():
            path = Path(d) / "s.yaml"
            path.write_text(text)
            runs = [validate(str(path)) for _ in range(args.repeats)]
            rc, secs, mb = min(runs, key=lambda r: r[1])
            base = base or (secs, mb)
            print(f"{name:44s} {len(text.encode()):8d} {rc:4d} {secs:6.2f} "
                  f"{secs / base[0]:5.2f} {mb:6.0f} {mb / base[1]:5.2f}")
    if args.fuzz:
        for what, ts in fuzz_times(args.fuzz, args.fuzz).items():
            ts = sorted(ts)
            print(f"fuzz {what}: {len(ts)} examples, mean {sum(ts) / len(ts) * 1e3:.1f} ms, "
                  f"99th percentile {ts[int(0.99 * (len(ts) - 1))] * 1e3:.1f} ms, longest "
                  f"{ts[-1] * 1e3:.1f} ms")
    print(f"(this process: peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f}"
          " MB)")


if __name__ == "__main__":
    main()
