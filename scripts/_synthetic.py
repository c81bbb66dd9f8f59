"""The command line both example-data scripts share: ``--out`` (default: the file in
measurements/ that the repository ships), ``--force`` to replace it, ``--help``; an
existing file or an unwritable place is one line on stderr (exit status 2). Before any
simulation, ``--out`` may not be the script's base scene, and ``--force`` replaces only an
earlier synthetic file (its first line says so), never a measurement."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from granchain.errors import GranchainError
from granchain.fileio import OutputKind, check_distinct, check_output_path, file_head

# what --force may replace: a file these scripts wrote (its first line)
SYNTHETIC = OutputKind("a synthetic example file these scripts wrote (first line "
                       "'# SYNTHETIC data')", lambda p: file_head(p, 64).startswith(
                           b"# SYNTHETIC data"))


def cli(main, doc: str, default_out: Path, base: Path) -> None:
    """Parse the command line and run ``main(out, force)``, which simulates from the
    scene file ``base``."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--out", type=Path, default=default_out,
                    help=f"the CSV to write (default: {default_out.name} in measurements/)")
    ap.add_argument("--force", action="store_true", help="replace an earlier synthetic file (never a measurement)")
    args = ap.parse_args()
    try:
        check_distinct([("--out", args.out)], [("the base scene", base)])
        check_output_path(args.out, args.force, "--out", kind=SYNTHETIC)
        print(main(args.out, args.force))
    except GranchainError as exc:
        print(f"{Path(sys.argv[0]).name}: error: {exc}", file=sys.stderr)
        sys.exit(2)
