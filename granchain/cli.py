"""Command line: ``granchain validate|run|deck|compare SCENE.yaml``, ``granchain infer CSV --scene BASE.yaml``.

Errors a user can cause print one line, ``granchain: error: ...``, and exit with 2.
A scene with ``integrator.method: auto`` is resolved from the cost model as soon as it is
loaded (``granchain.commands.run.load``): every command shows and runs the resolved scene
and its hash. This module holds the parser and the entry point; the commands are in
``granchain.commands`` (``run``: validate, run, compare, deck, warm-up; ``infer``).
"""
from __future__ import annotations

import argparse
import math
import sys

from .commands import infer as infer_command, run as run_command
from .commands.output import one_line
from .costmodel import DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_STEPS, DEFAULT_MAX_TOTAL_STEPS
from .errors import GranchainError


def _no_progress(sp) -> None:
    sp.add_argument("--no-progress", action="store_true",
                    help="no progress bar on stderr (shown only when stderr is a terminal)")


def _default_cache() -> str:
    from .fileio import cache_dir
    return str(cache_dir() / "inference")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2), like every other granchain error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def _limit(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text!r} must be a number > 0")
    return value


def _run_limits(sp) -> None:
    sp.add_argument("--max-total-steps", type=_limit, default=DEFAULT_MAX_TOTAL_STEPS,
                    metavar="N", help=f"refuse a run needing more integration steps over all "
                    f"its chains (estimate; default {DEFAULT_MAX_TOTAL_STEPS:.0e})")
    sp.add_argument("--max-memory-gb", type=_limit, default=DEFAULT_MAX_MEMORY_GB, metavar="X",
                    help=f"refuse a run that would hold more GB: every chain's results and "
                         f"the sample records kept until it ends, or one chain's record "
                         f"(estimate; default {DEFAULT_MAX_MEMORY_GB:g})")


def _cost_args(sp) -> None:
    sp.add_argument("--max-steps", type=_limit, default=DEFAULT_MAX_STEPS, metavar="N",
                    help=f"refuse a scene needing more integration steps per chain "
                         f"(estimate; default {DEFAULT_MAX_STEPS:.0e})")
    _run_limits(sp)


def build_parser() -> argparse.ArgumentParser:
    from .inference import E_MIN, E_POINTS, GAP_MAX, GAP_POINTS, REALISATIONS, fittable
    p = _Parser(prog="granchain", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def scene_args(sp):
        sp.add_argument("scene", help="scene YAML file")
        sp.add_argument("--set", action="append", default=[], metavar="KEY.SUB=VALUE",
                        help="override a scene field (value parsed as YAML); repeatable")

    sp = sub.add_parser("validate", help="check a scene file")
    scene_args(sp)
    sp.set_defaults(func=run_command.cmd_validate)

    sp = sub.add_parser("run", help="simulate a scene and print its observables")
    scene_args(sp)
    sp.add_argument("--engine", default="reference", choices=["reference", "lammps"])
    sp.add_argument("--json", action="store_true", help="print one JSON object")
    sp.add_argument("--out", help="also write the JSON results to this new file")
    sp.add_argument("--force", action="store_true",
                    help="allow --out to replace an earlier run JSON (never an input) and a "
                         "non-empty --workdir's files to be replaced")
    sp.add_argument("--np", type=int, default=None, metavar="N",
                    help="LAMMPS engine: MPI ranks (mpirun -np N; default 1)")
    sp.add_argument("--workdir", metavar="DIR",
                    help="LAMMPS engine: keep deck, dump and log in DIR (must be empty)")
    sp.add_argument("--lammps-output", choices=["binary", "dump"], default=None,
                    help="LAMMPS engine: what the run writes and reads back; binary (default): "
                         "LAMMPS binary dumps read with numpy; dump: the text dump traj.dump "
                         "(id x y z vx) read with MDAnalysis, for a full trajectory kept with "
                         "--workdir. Same results")
    _cost_args(sp)
    _no_progress(sp)
    sp.set_defaults(func=run_command.cmd_run)

    sp = sub.add_parser("compare", help="run a scene through the reference engine and LAMMPS "
                                        "and tabulate the differences")
    scene_args(sp)
    sp.add_argument("--json", action="store_true", help="print one JSON object (every row)")
    sp.add_argument("--out", help="also write the JSON document to this new file")
    sp.add_argument("--force", action="store_true",
                    help="allow --out to replace an earlier compare JSON (never an input) and "
                         "a non-empty --workdir's files to be replaced")
    sp.add_argument("--np", type=int, default=1, metavar="N", help="LAMMPS MPI ranks (default 1)")
    sp.add_argument("--workdir", metavar="DIR", help="keep the LAMMPS deck, dump and log in DIR")
    sp.add_argument("--traces", type=int, default=1, metavar="N",
                    help="also compare the whole trajectories (every particle's v(t) at every "
                         "sample) of the first N members (default 1; the observables are "
                         "compared for every member)")
    sp.add_argument("--trajectory", action="store_true",
                    help="compare the whole trajectories of every member (LAMMPS writes its "
                         "text dump, read with MDAnalysis)")
    _cost_args(sp)
    sp.set_defaults(func=run_command.cmd_compare)

    sp = sub.add_parser("deck", help="write a LAMMPS input deck for a scene")
    scene_args(sp)
    sp.add_argument("-o", "--output", required=True, help="directory for the deck")
    sp.add_argument("--force", action="store_true",
                    help="replace the deck.lmp and chain.data an earlier deck wrote")
    sp.add_argument("--write", choices=["dump", "binary", "none"], default="dump",
                    help="what the deck writes at every sample: dump (default) the text dump "
                         "traj.dump and ledger.txt; binary the LAMMPS binary dumps traj.bin and "
                         "ledger.bin (what granchain run reads); none no per-sample output")
    sp.set_defaults(func=run_command.cmd_deck)

    sp = sub.add_parser("warm-up", help="compile the reference engine's kernels for this machine "
                                        "(the ahead-of-time module, then numba's JIT cache "
                                        "where numba runs more than one thread)")
    _no_progress(sp)
    sp.set_defaults(func=run_command.cmd_warm_up)

    sp = sub.add_parser("infer", help="infer the mean gap of a chain (and its coefficient of "
                                      "restitution) from measured wave timing (and peaks)")
    sp.add_argument("measurements", help="CSV: v_striker_m_s, dt_peak_s or dt_front_s, "
                                         "optional dt_err_s, chain_id, vmax_1_m_s, vmax_2_m_s, "
                                         "vmax_err_m_s (SI units)")
    sp.add_argument("--fit", default="gap_mean", metavar="NAMES",
                    help="what to infer: gap_mean (default; from the timing) or gap_mean,KEY "
                         "(the mean gap and a fittable scene key, from the timing and both "
                         "probes' peaks): KEY one of " + ", ".join(
                             f"{p} ({k.name})" for p, k in fittable().items())
                         + "; gap_mean,restitution is gap_mean,damping.e")
    sp.add_argument("--scene", required=True, help="base scene YAML: material, chain, effects, "
                    "integrator, gap law (gaps.distribution; default the chapter's uniform "
                    "law), simulated speeds (striker.velocity; default the data's)")
    sp.add_argument("--set", action="append", default=[], metavar="KEY.SUB=VALUE",
                    help="override a field of the base scene; repeatable")
    sp.add_argument("--json", action="store_true", help="print one JSON object")
    sp.add_argument("--out", help="also write the JSON result to this new file")
    sp.add_argument("--plot", metavar="FILE", help="draw v_g vs v_s (data, inferred band, "
                    "Eq. 5.4) into this new file (.png or .pdf); with restitution fitted: "
                    "the joint posterior, its marginals and the data against the fitted model")
    sp.add_argument("--force", action="store_true",
                    help="allow --out and --plot to replace an earlier infer JSON and image "
                         "(never an input)")
    sp.add_argument("--gap-max-nm", type=_limit, default=GAP_MAX * 1e9, metavar="NM",
                    help=f"largest simulated mean gap in nm (default {GAP_MAX * 1e9:g})")
    sp.add_argument("--gap-points", type=int, default=GAP_POINTS, metavar="N",
                    help=f"simulated mean gaps from 0 to --gap-max-nm (default {GAP_POINTS})")
    sp.add_argument("--realisations", type=int, default=REALISATIONS, metavar="R",
                    help=f"gap realisations per mean gap and speed (default {REALISATIONS})")
    sp.add_argument("--fit-range", metavar="LO,HI",
                    help="--fit gap_mean,KEY: the simulated values of KEY, from LO to HI (the "
                         "prior's range; default the range declared with the key)")
    sp.add_argument("--fit-points", type=int, metavar="N",
                    help="--fit gap_mean,KEY: simulated values of KEY over its range, evenly "
                         "spaced (in log KEY where the range spans a decade or more; default "
                         "the number declared with the key)")
    sp.add_argument("--e-min", type=float, metavar="E",
                    help=f"--fit ...,restitution: smallest simulated e (default {E_MIN:g}; "
                         "the largest is 1)")
    sp.add_argument("--e-points", type=int, metavar="N",
                    help=f"--fit ...,restitution: simulated e from --e-min to 1 (default "
                         f"{E_POINTS})")
    sp.add_argument("--prior", choices=["scale", "uniform"], default="scale",
                    help="prior of the mean gap: scale (1/(g + 2 nm), default) or uniform")
    sp.add_argument("--cache-dir", default=_default_cache(), metavar="DIR",
                    help="where simulated grids are kept, keyed by scene hash "
                         "(default $GRANCHAIN_CACHE_DIR/inference, else $XDG_CACHE_HOME/granchain/inference)")
    sp.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    _run_limits(sp)
    _no_progress(sp)
    sp.set_defaults(func=infer_command.cmd_infer)

    return p


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:        # argparse: --help (0) or a bad option (2, one line)
        return exc.code if isinstance(exc.code, int) else 2
    try:
        for flag, dest in (("--out", "out"), ("-o/--output", "output"), ("--workdir", "workdir")):
            if getattr(args, dest, None) == "":
                raise GranchainError(f"{flag}: the path is empty; give a path")
        return args.func(args)
    except GranchainError as exc:
        print(f"granchain: error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("granchain: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
