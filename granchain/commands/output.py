"""What every command shares: one-line messages, the refusal of output paths that are
inputs or other outputs, numbers and warnings as printed, and the progress switch."""
from __future__ import annotations

import math
import re
from pathlib import Path

from ..fileio import atomic_write_text, check_distinct, json_text


def one_line(text: str) -> str:
    """A message on one line: control characters (newlines, ...) shown escaped."""
    return re.sub(r"[\x00-\x1f\x7f]", lambda m: repr(m.group())[1:-1], text)


def _workdir_files(args) -> list:
    """(--workdir, path) of every file the LAMMPS engine writes into a kept --workdir."""
    if not getattr(args, "workdir", None):
        return []
    from ..lammps.deckplan import WORKDIR_FILES
    return [("--workdir", Path(args.workdir) / name) for name in WORKDIR_FILES]


def check_paths(args, outputs, inputs=()) -> None:
    """Refuse, before any work, an output of a command that is one of its inputs (the
    scene file, the measurement file) or another of its outputs (``--out``, ``--plot``, the
    files of a kept ``--workdir``), with or without --force (``fileio.check_distinct``),
    and a kept ``--workdir`` holding a file the run would replace that is not an earlier
    run's (``lammps.deck.check_workdir``)."""
    check_distinct(_workdir_files(args) + list(outputs),
                   [("the scene file", getattr(args, "scene", None)), *inputs])
    if getattr(args, "workdir", None):
        from ..lammps.deck import check_workdir
        check_workdir(args.workdir, args.force)


def emit(args, doc: dict, print_human) -> None:
    """A command's result: the human summary (``print_human()``) unless --json, the JSON
    document ``doc`` on stdout with --json and no --out, and the document in the file
    --out (written atomically; --force replaces an earlier one)."""
    if not args.json:
        print_human()
    elif not args.out:
        print(json_text(doc))
    if args.out:
        atomic_write_text(args.out, json_text(doc, indent=1) + "\n", args.force, "--out")


def fmt(x, unit="", digits=4):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}{unit}"


def print_warnings(warnings, out) -> None:
    shown = []
    for w in warnings:
        if w not in shown:
            shown.append(w)
            print(f"warning: {one_line(w)}", file=out)


def show_progress(args) -> bool | None:
    """Progress bars: off with --no-progress, else when stderr is a terminal (None)."""
    return False if args.no_progress else None
