# The mean gap inferred from one measurement CSV and its base scene: granchain infer, with
# --fit gap_mean,restitution for a damped base scene whose CSV has both peaks
# (granchain.inference.fit_for).
import csv

from granchain import workflow as gw
from granchain.cli import main
from granchain.errors import GranchainError
from granchain.inference import fit_for
from granchain.scene import load_scene

with gw.log_to(snakemake.log[0]):
    try:
        with open(snakemake.input.csv, newline="") as f:
            header = next((r for r in csv.reader(f) if r and not r[0].startswith("#")), [])
        fit = ",".join(fit_for(load_scene(snakemake.input.scene), {c.strip() for c in header}))
    except (GranchainError, OSError, UnicodeDecodeError, csv.Error):
        fit = "gap_mean"      # granchain infer reports what is wrong with the files
    argv = ["infer", snakemake.input.csv, "--scene", snakemake.input.scene, "--fit", fit,
            "--out", snakemake.output.json, "--plot", snakemake.output.png, "--force",
            "--cache-dir", snakemake.params.cache]
    print(f"granchain {' '.join(argv)}")
    code = main(argv)
    if code:
        raise SystemExit(f"granchain infer failed (exit {code}); see the log")
