#!/usr/bin/env bash
# The project's test command (README quick start, and .ci/run): installs the package with
# its test extras from this checkout, then runs the tests.
#
#   bash scripts/test.sh           everything (CI), in two parts: the tests that are neither
#                                  workflow nor SLURM tests on two pytest-xdist workers, each
#                                  test file on one worker (--dist loadfile: a module's fixtures
#                                  are built once), then the workflow and SLURM tests one at a
#                                  time (they run snakemake on both cores, LAMMPS on two ranks
#                                  and one SLURM cluster). Serially the whole suite took 104 min
#                                  on the 2-core machine (1512 tests), over CI's 90.
#   bash scripts/test.sh --fast    the quick tier: -m "not slow and not workflow and not slurm"
#                                  (quick LAMMPS tests stay in) on two pytest-xdist workers,
#                                  at most 2 min with warm caches
#   bash scripts/test.sh [--fast] ARGS...   ARGS go to pytest (e.g. -k name, a test file)
#
# The SLURM tests install and start their own one-node cluster (Debian packages) and skip,
# with the reason, only on machines that cannot host it; with GRANCHAIN_REQUIRE_SLURM=1
# (set by .ci/run, and here when CI=true) that is a failure.
set -euo pipefail
cd "$(dirname "$0")/.."
marks=()
if [ "${1:-}" = "--fast" ]; then
    shift
    # two workers (pytest-xdist), each its own session with its own cache directory
    # (tests/conftest.py): the quick tier's tests are many and short, and a 2-core machine
    # runs two at once
    marks=(-m "not slow and not workflow and not slurm" -n 2)
fi
python -m pip install --quiet --disable-pip-version-check -e '.[test]'
if [ "${CI:-}" = "true" ]; then export GRANCHAIN_REQUIRE_SLURM=1; fi
run() {
    local rc=0
    python -m pytest -q -ra "$@" || rc=$?
    if [ "$rc" -eq 5 ]; then
        # pytest's "no tests collected": a selection (-k, a path, a marker) that matches
        # nothing is a mistake in the command, not a pass
        echo "scripts/test.sh: no tests were collected for: pytest $*" >&2
    fi
    return "$rc"
}
rc=0
if [ ${#marks[@]} -eq 0 ] && [ $# -eq 0 ]; then
    run -m "not workflow and not slurm" -n 2 --dist loadfile || rc=$?
    run -m "workflow or slurm" || rc=$((rc > 0 ? rc : $?))
else
    run "${marks[@]}" "$@" || rc=$?
fi
exit "$rc"
