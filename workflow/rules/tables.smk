# Gather: a study's batch tables -> tables/<study>.csv (one row per member, with the
# Eq. 5.4 bound from a packed reference) and its typed Parquet copy <study>.parquet (which
# the figures read), <study>_summary.csv (percentile bands), <study>.provenance.json, and
# timing/<study>.csv (wall times, kept out of the tables).

# Light jobs: on a cluster they run on the submitting node instead of waiting in the queue.
localrules:
    gather_study,


rule gather_study:
    input:
        batches=lambda w: batch_outputs(w.study),
        timings=lambda w: batch_outputs(w.study, ".timing.csv"),
    output:
        table=report(
            f"{RESULTS}/tables/{{study}}.csv",
            caption="../report/study_table.rst",
            category="Tables",
            subcategory="{study}",
            labels={"table": "{study}", "kind": "one row per member"},
        ),
        summary=report(
            f"{RESULTS}/tables/{{study}}_summary.csv",
            caption="../report/study_table.rst",
            category="Tables",
            subcategory="{study}",
            labels={"table": "{study}", "kind": "summary (percentile bands)"},
        ),
        parquet=parquet_path("{study}"),
        provenance=f"{RESULTS}/tables/{{study}}.provenance.json",
        timing=f"{RESULTS}/timing/{{study}}.csv",
    params:
        plan=lambda w: [b.key() for b in PLAN.batches[w.study]],
        describe=lambda w: DESCRIBE[w.study],
    log:
        f"{RESULTS}/logs/{{study}}/gather.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/gather_study.py"
