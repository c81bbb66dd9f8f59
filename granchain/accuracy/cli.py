"""Command line of the accuracy-vs-cost study: ``python -m granchain.accuracy
measure|figure|model``."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..costmodel import MODEL_FILE
from ..errors import GranchainError
from ..fileio import OutputKind, check_distinct, check_output_path, file_head, json_output
from .harness import measure
from .report import plot, write_model, write_outputs

DESCRIPTION = "What accuracy costs in time, and the cost model behind method: auto."
# what model --force may replace: an earlier cost model (its header) and its provenance
COST_MODEL = OutputKind("a cost model table (header scene_class,method,...)",
                        lambda p: file_head(p, 64).startswith(b"scene_class,method,"))
COST_PROVENANCE = json_output("a cost model provenance document", {"scene_class", "source"})


def preset_blocks(config: dict, preset: str | None = None) -> tuple[dict, dict, str]:
    """(cost block, base, preset name) of a workflow configuration mapping."""
    preset = preset or config.get("preset", "default")
    p = config["presets"][preset]
    return p.get("cost") or {}, p.get("base") or {}, preset


def build_parser(prog: str = "python -m granchain.accuracy") -> argparse.ArgumentParser:
    """The argument parser of ``measure``, ``figure`` and ``model``."""
    ap = argparse.ArgumentParser(prog=prog, description=DESCRIPTION)
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("measure", help="run the accuracy-vs-cost study of a preset")
    m.add_argument("--config", default="config/config.yaml",
                   help="workflow configuration to take the preset's cost and base blocks from")
    m.add_argument("--preset")
    m.add_argument("--cost-json", help="the cost block as JSON (instead of --config)")
    m.add_argument("--base-json", help="the base block as JSON (instead of --config)")
    m.add_argument("--table", help="deterministic table (errors and steps, no wall times)")
    m.add_argument("--provenance", help="provenance JSON of the deterministic table")
    m.add_argument("--timing", help="the full table, with wall times")
    m.add_argument("--cheapest", help="the cheapest settings for cost.cheapest_tolerances")
    f = sub.add_parser("figure", help="plot a measured table (with wall times)")
    f.add_argument("timing")
    f.add_argument("png")
    f.add_argument("pdf", nargs="?")
    mo = sub.add_parser("model", help="write the packaged cost model from a measured table")
    mo.add_argument("timing", help="timing/accuracy_cost.csv of a run (and its .provenance.json)")
    mo.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / MODEL_FILE))
    mo.add_argument("--force", action="store_true", help="replace an earlier cost model and its provenance")
    return ap


def _provenance(path) -> Path | None:
    """The provenance JSON written (or read) beside a measured table."""
    return None if path is None else Path(path).with_suffix(".provenance.json")


def check_paths(args) -> None:
    """Refuse, before any work, an output that is an input of the subcommand or another of
    its outputs (``fileio.check_distinct``); with ``model --force``, an existing model
    that is not an earlier cost model."""
    if args.cmd == "measure":
        check_distinct([("--table", args.table), ("--provenance", args.provenance),
                        ("--timing", args.timing),
                        ("--timing (its provenance)", _provenance(args.timing)),
                        ("--cheapest", args.cheapest)],
                       [] if args.cost_json is not None else [("the --config file", args.config)])
    elif args.cmd == "figure":
        check_distinct([("png", args.png), ("pdf", args.pdf)], [("the timing table", args.timing)])
    else:
        out = Path(args.out)
        prov = out.with_name(out.stem + ".provenance.json")
        check_distinct([("--out", out), ("--out (its provenance)", prov)],
                       [("the timing table", args.timing),
                        ("the timing table's provenance", _provenance(args.timing))])
        if args.force:
            check_output_path(out, True, "--out", probe=False, kind=COST_MODEL)
            check_output_path(prov, True, "--out", probe=False, kind=COST_PROVENANCE)


def main(argv=None, prog: str = "python -m granchain.accuracy") -> int:
    """Run a subcommand; errors a user can cause are one line on stderr, exit status 2."""
    args = build_parser(prog).parse_args(argv)
    try:
        check_paths(args)
        if args.cmd == "measure":
            if args.cost_json is not None:
                cost, base = json.loads(args.cost_json), json.loads(args.base_json or "{}")
                preset = args.preset
            else:
                import yaml
                cost, base, preset = preset_blocks(yaml.safe_load(Path(args.config).read_text()),
                                                   args.preset)
            rows, info = measure(cost, base)
            write_outputs(rows, info, cost, base, preset=preset, table=args.table,
                          provenance=args.provenance, timing=args.timing,
                          cheapest_csv=args.cheapest)
        elif args.cmd == "figure":
            from ..tables import read_csv
            plot(read_csv(args.timing), args.png, args.pdf)
        else:
            write_model(args.timing, args.out, force=args.force)
    except GranchainError as exc:
        print(f"{prog.split()[-1]}: error: {exc}", file=sys.stderr)
        return 2
    return 0
