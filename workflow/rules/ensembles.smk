# Ensembles: each job runs a batch of members (striker speed x gap realisation) of one
# study with the reference engine and writes a partial table (granchain.workflow.run);
# batches of studies on the LAMMPS engine go through run_lammps_batch (lammps.smk).
# packed_trace runs each material's packed chain, on its study's engine, and saves its v(t)
# trace (a LAMMPS packed_trace takes the batch threads as MPI ranks).
# aot_kernels compiles the reference engine's ahead-of-time module for this machine
# (granchain.engines.warmup; its parts in the rule's threads as processes at once), which
# every job's calls run (granchain.engines.backend): a job on one thread calls it directly,
# one on more threads cuts its parallel loops between forked processes
# (granchain.engines.forked), so no job compiles anything and jobs starting together do
# not each pay the cold compile. Without numba.pycc the rule warms numba's JIT cache
# instead. The cache is per machine (under $GRANCHAIN_CACHE_DIR or ~/.cache/granchain, and
# numba's beside the package); on a cluster whose nodes differ in CPU, a job on another
# CPU type compiles for it once.


rule aot_kernels:
    output:
        f"{RESULTS}/work/aot_kernels.done",
    log:
        f"{RESULTS}/logs/aot_kernels.log",
    threads: 2
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/aot_kernels.py"


rule run_batch:
    input:
        rules.aot_kernels.output,
    output:
        table=f"{RESULTS}/work/{{study}}/reference_{{index}}.csv",
        timing=f"{RESULTS}/work/{{study}}/reference_{{index}}.timing.csv",
    wildcard_constraints:
        study="packed_sweep|gap_profile|gap_sweep|extra_length|lammps_check|precompression|wall|radius_spread|dissipation|plasticity|adhesion|capture",
    params:
        batch=lambda w: batch_of(w.study, "reference", w.index).key(),
        study=lambda w: w.study,
        name=lambda w: f"reference_{w.index}",
    log:
        f"{RESULTS}/logs/{{study}}/reference_{{index}}.log",
    threads: BATCH_THREADS
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=lambda w: batch_runtime(w.study, "reference", w.index),
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/run_batch.py"


rule packed_trace:
    input:
        rules.aot_kernels.output,
    output:
        table=f"{RESULTS}/work/packed_trace/trace.csv",
        timing=f"{RESULTS}/work/packed_trace/trace.timing.csv",
        traces=[trace_path(m) for m in trace_materials()],
    params:
        materials=trace_materials(),
        scenes=PLAN.scene_hashes("packed_trace"),
    log:
        f"{RESULTS}/logs/packed_trace/trace.log",
    threads: BATCH_THREADS if PLAN.engines("packed_trace") == ["lammps"] else 1
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/packed_trace.py"
