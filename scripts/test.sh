#!/usr/bin/env bash
# The project's test command (README quick start, and .ci/run): installs the package with
# its test extras from this checkout, then runs the tests.
#
#   bash scripts/test.sh           everything (CI): about 15 min on an idle 2-core machine
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
rc=0
python -m pytest -q -ra "${marks[@]}" "$@" || rc=$?
if [ "$rc" -eq 5 ]; then
    # pytest's "no tests collected": a selection (-k, a path, a marker) that matches nothing
    # is a mistake in the command, not a pass
    echo "scripts/test.sh: no tests were collected for: pytest ${marks[*]} $*" >&2
fi
exit "$rc"
