# LAMMPS cross-validation: the lammps_check study runs both engines on the same members.
# Reference batches go through run_batch (ensembles.smk), LAMMPS batches (many chains side
# by side in one LAMMPS run) through run_lammps_batch; gather_study (tables.smk) puts both
# engines' rows into tables/lammps_check.csv. compare_engines runs granchain.compare on
# every lammps_check scene: tables/lammps_vs_reference.csv (differences and tolerances).


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
    output:
        table=report(
            f"{RESULTS}/tables/lammps_vs_reference.csv",
            caption="../report/lammps_vs_reference.rst",
            category="Tables",
            subcategory="lammps_check",
            labels={"table": "lammps_vs_reference", "kind": "engine differences"},
        ),
        provenance=f"{RESULTS}/tables/lammps_vs_reference.provenance.json",
    params:
        scenes=PLAN.scene_hashes("lammps_check"),
        describe=DESCRIBE["lammps_check"],
    log:
        f"{RESULTS}/logs/lammps_check/compare.log",
    threads: BATCH_THREADS
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=gw.runtime_minutes(
            sum(b.est_seconds for b in PLAN.batches["lammps_check"]), BATCH_THREADS
        ),
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/compare_engines.py"
