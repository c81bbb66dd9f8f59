"""The command line both example-data scripts share: ``--out`` (default: the file in
measurements/ that the repository ships), ``--force`` to replace it, ``--help``; an
existing file or an unwritable place is one line on stderr (exit status 2)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from granchain.errors import GranchainError


def cli(main, doc: str, default_out: Path) -> None:
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--out", type=Path, default=default_out,
                    help=f"the CSV to write (default: {default_out.name} in measurements/)")
    ap.add_argument("--force", action="store_true", help="replace the file if it exists")
    args = ap.parse_args()
    try:
        print(main(args.out, args.force))
    except GranchainError as exc:
        print(f"{Path(sys.argv[0]).name}: error: {exc}", file=sys.stderr)
        sys.exit(2)
