"""Prove the SLURM profile end to end on a real one-node SLURM cluster.

A tiny 3-rule workflow (python writes numbers, an aggregate sums them, `all`) runs
through workflow/profiles/slurm; every non-local job must go through sbatch.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import pytest

from slurm_support import (  # noqa: F401  (slurm_cluster is a fixture)
    SlurmCluster,
    run_snakemake_on_slurm,
    slurm_cluster,
    submitted_slurm_job_ids,
)

pytestmark = pytest.mark.slurm

N_VALUES = (3, 4)

SNAKEFILE = textwrap.dedent(
    """
    PY = {python!r}
    VALUES = {values!r}

    localrules: all

    rule all:
        input:
            "total.txt",

    # Runs python in a SLURM job: writes value**2 and the job's SLURM_JOB_ID.
    rule square:
        output:
            "squares/{{v}}.txt",
        resources:
            runtime=5,
        shell:
            PY + " -c \\"import os; v = {{wildcards.v}}; "
            "print(v * v); print(os.environ.get('SLURM_JOB_ID', ''))\\" > {{output}}"

    # Aggregates the squares, also in a SLURM job.
    rule total:
        input:
            expand("squares/{{v}}.txt", v=VALUES),
        output:
            "total.txt",
        resources:
            runtime=5,
        run:
            import os
            total = sum(int(open(f).read().split()[0]) for f in input)
            jobs = [open(f).read().split()[1] for f in input]
            with open(output[0], "w") as out:
                print(total, file=out)
                print(os.environ.get("SLURM_JOB_ID", ""), file=out)
                print(" ".join(jobs), file=out)
    """
).format(python=sys.executable, values=list(N_VALUES))


def _job_id(text: str) -> int:
    assert text.isdigit(), f"expected a SLURM job id, got {text!r}"
    return int(text)


def test_tiny_workflow_runs_through_slurm(slurm_cluster: SlurmCluster, tmp_path):
    snakefile = tmp_path / "Snakefile"
    snakefile.write_text(SNAKEFILE)

    t0 = time.monotonic()
    proc = run_snakemake_on_slurm(tmp_path, snakefile, targets=["all"], timeout_s=180)
    elapsed = time.monotonic() - t0
    print(f"tiny workflow on SLURM took {elapsed:.1f}s")

    # Outputs are right.
    for v in N_VALUES:
        lines = (tmp_path / "squares" / f"{v}.txt").read_text().split()
        assert int(lines[0]) == v * v
    total_lines = (tmp_path / "total.txt").read_text().splitlines()
    assert int(total_lines[0]) == sum(v * v for v in N_VALUES)

    # Each job ran inside SLURM: it saw a SLURM_JOB_ID, ...
    square_ids = [_job_id(x) for x in total_lines[2].split()]
    total_id = _job_id(total_lines[1].strip())
    seen = set(square_ids) | {total_id}
    assert len(seen) == len(N_VALUES) + 1, f"expected one SLURM job per rule instance, got {seen}"

    # ... which is exactly what snakemake says it submitted with sbatch, ...
    submitted = submitted_slurm_job_ids(proc)
    assert set(submitted) == seen, f"log says submitted {submitted}, jobs saw {sorted(seen)}"

    # ... and the controller recorded them as completed in our partition.
    sacct_like = slurm_cluster.jobcomp_file.read_text()
    for jid in seen:
        line = next((ln for ln in sacct_like.splitlines() if f"JobId={jid} " in ln), None)
        assert line is not None, f"job {jid} missing from {slurm_cluster.jobcomp_file}"
        assert "JobState=COMPLETED" in line and f"Partition={slurm_cluster.partition}" in line, line

    # The profile polls squeue (no slurmdbd here, so sacct fails); that relies on finished
    # jobs staying visible to squeue (MinJobAge=300 in slurm_cluster.sh).
    squeue = subprocess.run(
        ["squeue", "-h", "-t", "all", "-o", "%i %T"], capture_output=True, text=True, timeout=10
    )
    assert squeue.returncode == 0, squeue.stderr
    states = dict(ln.split() for ln in squeue.stdout.splitlines() if ln.strip())
    for jid in seen:
        assert states.get(str(jid)) == "COMPLETED", squeue.stdout
