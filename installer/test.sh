#!/usr/bin/env bash
# Installs everything (system packages, .venv with the test tools), then runs the checks and tests:
# ruff, the import contracts (core has no GUI dependencies), mypy on core and widgets, and pytest (GUI tests
# offscreen/Xvfb).
# Usage: bash installer/test.sh [pytest arguments]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash installer/setup.sh --test
.venv/bin/ruff check __init__.py app core widgets tests
.venv/bin/lint-imports
.venv/bin/mypy
# one pytest worker per core (pytest-xdist), each taking whole test files (module fixtures, e.g. a Dask
# cluster, are built once); the slowest tests are listed at the end
options=(-q -p no:cacheprovider --numprocesses auto --dist loadfile --durations 15)
if [ -z "${DISPLAY:-}" ] && command -v xvfb-run >/dev/null 2>&1; then
  exec xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python -m pytest "${options[@]}" "$@"
fi
exec .venv/bin/python -m pytest "${options[@]}" "$@"
