# LAMMPS batches: many chains side by side in one LAMMPS run per striker speed, on as many
# MPI ranks as the rule's threads (the preset's batch.threads; on SLURM its cpus-per-task).
# They serve the lammps_check study (both engines on the same members; its reference
# batches go through run_batch, ensembles.smk) and every ensemble study whose engine is
# lammps (the study's `engine` key, or `--config engine=lammps` for all of them).
# gather_study (tables.smk) puts a study's rows into tables/<study>.csv. compare_engines
# runs granchain.compare on every lammps_check scene and on its field chains (`chains`: a
# dimer, a wall, a preload; compared only): tables/lammps_vs_reference.csv (differences
# and tolerances). Both wait for aot_kernels (ensembles.smk): the LAMMPS engine's energy
# ledger and the comparison's reference runs call the reference engine's compiled kernels,
# which a job started before the module would compile for itself (minutes of numba's JIT).


rule run_lammps_batch:
    input:
        rules.aot_kernels.output,
    output:
        table=f"{RESULTS}/work/{{study}}/lammps_{{index}}.csv",
        timing=f"{RESULTS}/work/{{study}}/lammps_{{index}}.timing.csv",
    wildcard_constraints:
        study="packed_sweep|gap_profile|gap_sweep|extra_length|lammps_check|precompression|wall|radius_spread|dissipation|plasticity|adhesion|capture",
    params:
        batch=lambda w: batch_of(w.study, "lammps", w.index).key(),
        study=lambda w: w.study,
        name=lambda w: f"lammps_{w.index}",
    log:
        f"{RESULTS}/logs/{{study}}/lammps_{{index}}.log",
    threads: BATCH_THREADS
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=lambda w: batch_runtime(w.study, "lammps", w.index),
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/run_batch.py"


rule compare_engines:
    input:
        rules.aot_kernels.output,
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
        scenes=PLAN.scene_hashes("lammps_check") + [ss.scene.hash for ss in PLAN.chains],
        describe=DESCRIBE["lammps_check"],
    log:
        f"{RESULTS}/logs/lammps_check/compare.log",
    threads: BATCH_THREADS
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=gw.runtime_minutes(
            sum(b.est_seconds for b in PLAN.batches["lammps_check"])
            + sum(
                (gw.realisation_cost(ss, "reference") + gw.realisation_cost(ss, "lammps"))
                * ss.scene.realisations
                for ss in PLAN.chains
            ),
            BATCH_THREADS,
        ),
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/compare_engines.py"
