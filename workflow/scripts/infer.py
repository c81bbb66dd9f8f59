# The mean gap inferred from one measurement CSV and its base scene: granchain infer.
from granchain import workflow as gw
from granchain.cli import main

with gw.log_to(snakemake.log[0]):
    argv = ["infer", snakemake.input.csv, "--scene", snakemake.input.scene,
            "--out", snakemake.output.json, "--plot", snakemake.output.png, "--force",
            "--cache-dir", snakemake.params.cache]
    code = main(argv)
    if code:
        raise SystemExit(f"granchain infer failed (exit {code}); see the log")
