#!/usr/bin/env bash
# Builds the documentation site into docs/_build/html: installs the package with its docs
# extras from this checkout (as scripts/test.sh does), then runs Sphinx with every warning
# an error (-W, reported all at once with --keep-going) and every cross-reference checked
# (-n). The reference pages (scene keys, table columns, configuration) are generated from
# the code during the build.
#
#   bash scripts/docs.sh            build, then open docs/_build/html/index.html
#   bash scripts/docs.sh ARGS...    ARGS go to sphinx-build (e.g. -E to rebuild everything)
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet --disable-pip-version-check -e '.[docs]'
python -m sphinx -W --keep-going -n -b html "$@" docs docs/_build/html
