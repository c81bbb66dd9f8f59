# What accuracy costs in time (granchain/accuracy/, called through granchain.accuracy.main): every
# integration setting (RK4, velocity Verlet, adaptive DOP853, LAMMPS) on the packed chain
# and gapped chains, errors against a converged reference, wall time per chain.
#   tables/accuracy_cost.csv (+ .provenance.json): errors and steps, deterministic
#   timing/accuracy_cost.csv (+ .provenance.json with the machine): the same rows with
#       wall times; timing/accuracy_cost_cheapest.csv: the cheapest setting per tolerance
#       (it depends on wall times, so it lives with them, out of the byte-identical tables)
#   figures/accuracy_cost.png/.pdf: error against wall time per chain, log-log
# The job takes the whole machine (threads = cost.threads, default 2): its timings must
# not share the cores with other jobs.
import json

COST = P.get("cost") or {}
COST_THREADS = int(COST.get("threads", 2))


rule accuracy_cost:
    input:
        rules.aot_kernels.output,
    output:
        table=report(
            f"{RESULTS}/tables/accuracy_cost.csv",
            category="Tables",
            subcategory="accuracy_cost",
            labels={"table": "accuracy_cost", "kind": "errors and steps per setting"},
        ),
        provenance=f"{RESULTS}/tables/accuracy_cost.provenance.json",
        timing=f"{RESULTS}/timing/accuracy_cost.csv",
        timing_provenance=f"{RESULTS}/timing/accuracy_cost.provenance.json",
        cheapest=report(
            f"{RESULTS}/timing/accuracy_cost_cheapest.csv",
            category="Tables",
            subcategory="accuracy_cost",
            labels={"table": "accuracy_cost", "kind": "cheapest setting per tolerance"},
        ),
    params:
        preset=PRESET,
        cost=json.dumps(COST, sort_keys=True),
        base=json.dumps(P["base"], sort_keys=True),
    log:
        f"{RESULTS}/logs/cost/accuracy_cost.log",
    threads: COST_THREADS
    resources:
        mem_mb=2000,
        runtime=30 if PRESET == "full" else 10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/accuracy_cost.py"


rule accuracy_cost_figure:
    input:
        timing=f"{RESULTS}/timing/accuracy_cost.csv",
    output:
        png=report(
            f"{RESULTS}/figures/accuracy_cost.png",
            caption="../report/accuracy_cost.rst",
            category="Figures",
            subcategory="accuracy vs cost",
            labels={"figure": "accuracy_cost", "material": "all"},
        ),
        pdf=f"{RESULTS}/figures/accuracy_cost.pdf",
    log:
        f"{RESULTS}/logs/cost/accuracy_cost_figure.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/accuracy_cost_figure.py"
