# The mean gap inferred from measured wave timing (granchain infer, granchain/inference/;
# with the coefficient of restitution, --fit gap_mean,restitution, when the base scene has
# contact_damping coeff_restitution and the CSV both peaks: inference.fit_for) for every
# measurements/<name>.csv at the top of the repository, with its base scene
# measurements/<name>.yaml: results/<preset>/inference/<name>.json and <name>.png.
# `snakemake --cores 2 inference` runs them all; the default target includes them for real
# measurements only (files not named example_*: the shipped example is synthetic). The
# simulated grids are cached under results/inference_cache, keyed by scene hash, for all
# presets.
# MEASUREMENTS and inference_targets() are in common.smk (all_targets lists the real ones).
INFER_CODE = sorted(
    str(p) for p in (Path(workflow.basedir) / "granchain" / "inference").glob("*.py")) + [
    str(Path(workflow.basedir) / "granchain" / f)
    for f in ("gapdesign.py", "modelcheck.py", "figures/inference.py")]


wildcard_constraints:
    measurement=r"[A-Za-z0-9_][A-Za-z0-9._-]*",


rule inference:
    input:
        inference_targets(),


rule infer_gap:
    input:
        csv=str(MEAS_DIR / "{measurement}.csv"),
        scene=str(MEAS_DIR / "{measurement}.yaml"),
        code=INFER_CODE,
        kernels=rules.aot_kernels.output,
    output:
        json=f"{RESULTS}/inference/{{measurement}}.json",
        png=report(
            f"{RESULTS}/inference/{{measurement}}.png",
            caption="../report/inference.rst",
            category="Inference",
            labels={"measurements": "{measurement}"},
        ),
    params:
        cache="results/inference_cache",
    log:
        f"{RESULTS}/logs/inference/{{measurement}}.log",
    threads: BATCH_THREADS
    resources:
        mem_mb=BATCH_MEM_MB,
        runtime=60,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/infer.py"
