#!/usr/bin/env bash
# Set up (idempotent) and run the test suite headless. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
GSTYLE_EXTRAS=ray bash scripts/setup.sh  # the tests of gstyle batch --ray need the ray extra
export GSTYLE_CACHE=${GSTYLE_CACHE:-$PWD/.cache/gstyle}
# PlayCanvas's splat-transform for the interoperability tests (tests/test_io_sog_interop.py, test_io_web_export.py),
# pinned, into .cache where npm is there (about 10 s the first time); without it those tests skip. 2.7.1 runs on
# node >= 18 (3.x asks for node 22) and agrees with our .spz axes (3.10.2 reads .spz without the y/z flip).
st_dir=.cache/splat-transform-2.7.1
if [[ -z ${GSTYLE_SPLAT_TRANSFORM:-} ]] && command -v npm >/dev/null 2>&1; then
  [[ -x $st_dir/node_modules/.bin/splat-transform ]] || npm install --silent --no-audit --no-fund --prefix "$st_dir" \
    @playcanvas/splat-transform@2.7.1 >/dev/null 2>&1 || echo "test: splat-transform not installed; its tests skip"
  if [[ -x $st_dir/node_modules/.bin/splat-transform ]]; then
    export GSTYLE_SPLAT_TRANSFORM=$PWD/$st_dir/node_modules/.bin/splat-transform
  fi
fi
.venv/bin/ruff check gstyle_core app tests bench
env -u DISPLAY .venv/bin/python -m pytest -q -p no:cacheprovider "$@"
