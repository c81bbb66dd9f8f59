# granchain main workflow. `snakemake --cores 2` runs the example scenes with the
# reference engine and writes their observables to results/examples/<scene>.json.
# (The gap ensembles, tables, figures, LAMMPS cross-validation and SLURM profile grow
# from here: see workflow/rules/.)
from pathlib import Path

SCENES = sorted(p.stem for p in Path("granchain/scenes").glob("*.yaml"))


rule all:
    input:
        expand("results/examples/{scene}.json", scene=SCENES),


rule run_example:
    input:
        "granchain/scenes/{scene}.yaml",
    output:
        "results/examples/{scene}.json",
    log:
        "results/logs/examples/{scene}.log",
    shell:
        "granchain run {input} --json --out {output} --force 2> {log}"
