#!/usr/bin/env bash
# Set up (idempotent) and run the test suite headless. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
GSTYLE_EXTRAS=ray bash scripts/setup.sh  # the tests of gstyle batch --ray need the ray extra
export GSTYLE_CACHE=${GSTYLE_CACHE:-$PWD/.cache/gstyle}
# numba compiles the rasterizer's kernels once a checkout (about 40 s on a 2-core VM; cached in __pycache__, keyed by
# the sources' contents) and the VGG-16 weights are converted once into $GSTYLE_CACHE: one smoke run of the demo does
# both while npm and ruff run, rather than both test processes compiling the same kernels at once.
warm_dir=$(mktemp -d)
GSTYLE_SMOKE=1 GSTYLE_PRECISION=fp32 .venv/bin/python -m gstyle_core.cli stylize --out "$warm_dir/warm.ply" \
  --checkpoint-every 0 >"$warm_dir/log" 2>&1 &
warm_pid=$!
warm_done() {
  wait "$warm_pid" || { echo "test: the warm-up run failed (the tests compiled the kernels themselves):"; tail -5 \
    "$warm_dir/log"; }
  rm -rf "$warm_dir"
}
trap warm_done EXIT
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
# The test processes start and collect meanwhile, and wait for it before their first test (tests/conftest.py).
export GSTYLE_WARMUP_PID=$warm_pid
# Two test processes (pytest-xdist), one torch/numba thread each: one process alone kept the 2-core VM 45 % busy (a test
# waits on its subprocesses, windows and sockets much of the time); two of one thread each took the suite from
# 1,013 to 657 s (docs/notes/performance.md). GSTYLE_TEST_WORKERS=0 runs it in one process.
workers=${GSTYLE_TEST_WORKERS:-2}
if [[ $workers != 0 ]]; then
  export GSTYLE_TEST_THREADS=${GSTYLE_TEST_THREADS:-1}
  set -- -n "$workers" --dist load --maxschedchunk 2 "$@"  # handed out a test or two at a time, the slow first
fi
env -u DISPLAY .venv/bin/python -m pytest -q -p no:cacheprovider "$@"
