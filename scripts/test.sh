#!/usr/bin/env bash
# Set up (idempotent) and run the test suite headless. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
GSTYLE_EXTRAS=ray bash scripts/setup.sh  # the tests of gstyle batch --ray need the ray extra
export GSTYLE_CACHE=${GSTYLE_CACHE:-$PWD/.cache/gstyle}
.venv/bin/ruff check gstyle_core app tests bench
env -u DISPLAY .venv/bin/python -m pytest -q -p no:cacheprovider "$@"
