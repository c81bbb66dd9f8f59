# LAMMPS cross-validation: the lammps_check study runs both engines on the same members.
# Reference batches go through run_batch (ensembles.smk); LAMMPS batches (many chains side
# by side in one LAMMPS run) through run_lammps_batch; tables.smk gathers both engines'
# rows into tables/lammps_check.csv, and compare_engines writes their differences.


localrules:
    compare_engines,


rule run_lammps_batch:
    output:
        table=f"{RESULTS}/work/lammps_check/lammps_{{index}}.csv",
        timing=f"{RESULTS}/work/lammps_check/lammps_{{index}}.timing.csv",
    params:
        batch=lambda w: batch_of("lammps_check", "lammps", w.index).key(),
        study="lammps_check",
        name=lambda w: f"lammps_{w.index}",
    log:
        f"{RESULTS}/logs/lammps_check/lammps_{{index}}.log",
    threads: BATCH_THREADS
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=lambda w: batch_runtime("lammps_check", "lammps", w.index),
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/run_batch.py"


rule compare_engines:
    input:
        table_path("lammps_check"),
    output:
        table=report(
            f"{RESULTS}/tables/lammps_vs_reference.csv",
            category="Tables",
            subcategory="lammps_check",
            labels={"table": "lammps_vs_reference", "kind": "engine differences"},
        ),
        provenance=f"{RESULTS}/tables/lammps_vs_reference.provenance.json",
    log:
        f"{RESULTS}/logs/lammps_check/compare.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/compare_engines.py"


ALL_TARGETS += [f"{RESULTS}/tables/lammps_vs_reference.csv"]
