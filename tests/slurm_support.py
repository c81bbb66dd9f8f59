"""Helpers for tests that run the workflow on a real (one-node, local) SLURM cluster.

Use from a test module with::

    from slurm_support import run_snakemake_on_slurm, slurm_cluster  # noqa: F401

``slurm_cluster`` (session scope) runs ``scripts/slurm_cluster.sh up`` once per test
session and ``down`` at the end. The script installs Debian's slurmctld/slurmd/
slurm-client/munge if needed, so it needs root and apt; when the machine cannot host
the cluster the script exits 3 with a one-line reason and the tests are skipped with
that reason (set GRANCHAIN_REQUIRE_SLURM=1 to turn that skip into a failure, e.g. in CI).

Environment:
  GRANCHAIN_SLURM_STATE_DIR  state/log/pid folder of the cluster (default /tmp/granchain-slurm;
                             it must be reachable by the ``slurm`` user, so not under pytest's
                             0700 tmp folders)
  GRANCHAIN_REQUIRE_SLURM    "1": fail instead of skip when the machine cannot host SLURM
  GRANCHAIN_SLURM_KEEP       "1": leave the cluster running after the session
"""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Iterator, Sequence

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
CLUSTER_SCRIPT = REPO_ROOT / "scripts" / "slurm_cluster.sh"
SLURM_PROFILE = REPO_ROOT / "workflow" / "profiles" / "slurm"
PARTITION = "granchain"  # must match slurm_cluster.sh and the profile's slurm_partition
DEFAULT_STATE_DIR = "/tmp/granchain-slurm"

EXIT_CANNOT_HOST = 3
_TAIL_CHARS = 12_000

# Snakemake's log line per submitted job (snakemake-executor-plugin-slurm 2.x).
SUBMITTED_RE = re.compile(r"has been submitted with SLURM jobid (\d+)")

# The markers of the test that is running (set by conftest.py's pytest_runtest_setup,
# None outside a test): the helpers below refuse to start runs a test is not marked for.
RUNNING_TEST_MARKS: set[str] | None = None


def require_marks(what: str, *names: str) -> None:
    """Fail the running test if it starts *what* without the markers *names*: an
    unmarked test would run snakemake or SLURM in the quick tier."""
    if RUNNING_TEST_MARKS is None:
        return
    missing = [n for n in names if n not in RUNNING_TEST_MARKS]
    if missing:
        pytest.fail(f"this test runs {what} but is not marked {', '.join(missing)} "
                    "(add @pytest.mark.<name>, or use a fixture conftest.END_TO_END marks)",
                    pytrace=False)


@dataclasses.dataclass(frozen=True)
class SlurmCluster:
    """What the ``slurm_cluster`` fixture yields."""

    state_dir: Path
    partition: str = PARTITION
    script: Path = CLUSTER_SCRIPT
    profile: Path = SLURM_PROFILE

    @property
    def jobcomp_file(self) -> Path:
        """Slurm's job-completion log (JobCompType=jobcomp/filetxt): one line per finished job."""
        return self.state_dir / "log" / "jobcomp.txt"

    def status(self) -> subprocess.CompletedProcess:
        return _run_script("status", self.state_dir, timeout_s=30)


def _tail(text: str, n: int = _TAIL_CHARS) -> str:
    return text if len(text) <= n else "...\n" + text[-n:]


def _run_script(action: str, state_dir: Path, timeout_s: float) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["bash", str(CLUSTER_SCRIPT), action, str(state_dir)],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        env=_clean_env(),
    )


def _clean_env() -> dict[str, str]:
    # SLURM_CONF elsewhere than /etc/slurm/slurm.conf breaks the jobs' nested srun, and
    # stray SLURM_* variables (when pytest itself runs inside a job) confuse sbatch.
    return {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}


def _cannot_host_reason(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    marked = [ln for ln in lines if "cannot host" in ln]
    return (marked or lines or ["slurm_cluster.sh exited 3 without a reason"])[-1].strip()


@pytest.fixture(scope="session")
def slurm_cluster() -> Iterator[SlurmCluster]:
    """A running one-node SLURM cluster (partition ``granchain``) for the whole session."""
    state_dir = Path(os.environ.get("GRANCHAIN_SLURM_STATE_DIR", DEFAULT_STATE_DIR))
    cluster = SlurmCluster(state_dir=state_dir)
    # A cluster someone started by hand before the session is left running afterwards.
    was_up = cluster.status().returncode == 0
    try:
        up = _run_script("up", state_dir, timeout_s=900)
    except subprocess.TimeoutExpired as exc:
        _run_script("down", state_dir, timeout_s=120)
        pytest.fail(f"slurm_cluster.sh up timed out after {exc.timeout}s:\n{_tail(str(exc.stderr or ''))}")
    if up.returncode == EXIT_CANNOT_HOST:
        reason = _cannot_host_reason(up.stderr)
        if os.environ.get("GRANCHAIN_REQUIRE_SLURM") == "1":
            pytest.fail(f"GRANCHAIN_REQUIRE_SLURM=1 but {reason}")
        pytest.skip(reason)
    if up.returncode != 0:
        pytest.fail(
            f"slurm_cluster.sh up failed (exit {up.returncode}):\n"
            f"--- stdout ---\n{_tail(up.stdout)}\n--- stderr ---\n{_tail(up.stderr)}"
        )
    # e.g. "slurm_cluster: up in 9s: node vm idle in partition granchain (...)" (seen with -s)
    print((up.stderr.strip().splitlines() or [""])[-1])
    try:
        yield cluster
    finally:
        if not was_up and os.environ.get("GRANCHAIN_SLURM_KEEP") != "1":
            down = _run_script("down", state_dir, timeout_s=120)
            if down.returncode != 0:
                # Raising in teardown reports an error for the last test using the fixture.
                raise RuntimeError(
                    f"slurm_cluster.sh down failed (exit {down.returncode}):\n{_tail(down.stderr)}"
                )


def run_snakemake_on_slurm(
    workdir: os.PathLike | str,
    snakefile: os.PathLike | str,
    targets: Sequence[str] = (),
    extra_args: Sequence[str] = (),
    timeout_s: int = 300,
    check: bool = True,
) -> subprocess.CompletedProcess:
    """Run ``snakemake --profile workflow/profiles/slurm`` in *workdir* and return the process.

    It runs under ``timeout -k 30 timeout_s`` because the SLURM plugin can poll forever
    (and ignore SIGTERM) when job status cannot be read. stdout/stderr are captured;
    with ``check`` (the default) a non-zero exit fails the test showing both.
    """
    workdir = Path(workdir)
    cmd = slurm_snakemake_command(workdir, snakefile, targets, extra_args, timeout_s)
    proc = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, env=_clean_env())
    if check and proc.returncode != 0:
        what = {124: "timed out (SIGTERM)", 137: "timed out and was killed (SIGKILL)"}.get(
            proc.returncode, f"exited {proc.returncode}"
        )
        pytest.fail(
            f"snakemake on SLURM {what} after at most {timeout_s}s\n$ {' '.join(cmd)}\n"
            f"--- stdout ---\n{_tail(proc.stdout)}\n--- stderr ---\n{_tail(proc.stderr)}",
            pytrace=False,
        )
    return proc


def slurm_snakemake_command(workdir, snakefile, targets=(), extra_args=(), timeout_s=300):
    """The command line :func:`run_snakemake_on_slurm` runs (for a run started with
    :func:`start_snakemake_on_slurm`)."""
    require_marks("snakemake through SLURM", "workflow", "slurm")
    return [
        "timeout", "-k", "30", str(int(timeout_s)),
        sys.executable, "-m", "snakemake",
        "--profile", str(SLURM_PROFILE),
        "--snakefile", str(Path(snakefile).resolve()),
        "--directory", str(Path(workdir).resolve()),
        *extra_args,
        *targets,
    ]


def start_snakemake_on_slurm(workdir, snakefile, log_path, targets=(), extra_args=(),
                             timeout_s=300) -> subprocess.Popen:
    """Start the same run in the background, stdout and stderr to *log_path*, in a
    session of its own (``os.killpg(proc.pid, ...)`` reaches snakemake and ``timeout``)."""
    cmd = slurm_snakemake_command(workdir, snakefile, targets, extra_args, timeout_s)
    with open(log_path, "w") as log:
        return subprocess.Popen(cmd, cwd=workdir, stdout=log, stderr=subprocess.STDOUT,
                                env=_clean_env(), start_new_session=True)


def squeue_jobs(states: str = "all") -> dict[int, tuple[str, str]]:
    """{job id: (state, comment)} of the jobs squeue lists in *states*. The SLURM
    executor plugin puts ``rule_<rule>_wildcards_<...>`` in each job's comment."""
    proc = subprocess.run(["squeue", "-h", "-t", states, "-o", "%i|%T|%k"], capture_output=True,
                          text=True, timeout=30, env=_clean_env())
    assert proc.returncode == 0, proc.stderr
    out = {}
    for ln in proc.stdout.splitlines():
        if ln.strip():
            jid, state, comment = ln.strip().split("|", 2)
            out[int(jid)] = (state, comment)
    return out


def scancel(job_id: int) -> None:
    proc = subprocess.run(["scancel", str(job_id)], capture_output=True, text=True, timeout=30,
                          env=_clean_env())
    assert proc.returncode == 0, f"scancel {job_id}: {proc.stderr}"


def submitted_slurm_job_ids(proc: subprocess.CompletedProcess) -> list[int]:
    """SLURM job ids that snakemake's log says it submitted."""
    return [int(m) for m in SUBMITTED_RE.findall(proc.stdout + proc.stderr)]
