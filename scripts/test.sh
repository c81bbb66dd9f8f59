#!/usr/bin/env bash
# The project's test command (README quick start, and .ci/run): installs the package with
# its test extras from this checkout, then runs the whole suite. The SLURM test installs
# and starts its own one-node cluster (Debian packages) and skips, with the reason, only
# on machines that cannot host it; under CI it is required.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet --disable-pip-version-check -e '.[test]'
if [ "${CI:-}" = "true" ]; then export GRANCHAIN_REQUIRE_SLURM=1; fi
exec python -m pytest -q -ra "$@"
