#!/usr/bin/env bash
# The GPU check, on a machine with an NVIDIA GPU, from the repository root (under 8 minutes on an H100/H200 with a
# module built before; about one more minute when it builds gsplat's):
#
#   bash bench/gpu_check.sh [quick|full|studio|atlas|batch]
#
# 1. the machine: the card, its driver, nvcc, torch;
# 2. packages: wheels in .whl/ are installed into /tmp/site first where the machine has no internet (gsplat 1.5.3,
#    zstandard; the project itself runs from the checkout, so its torch pin never replaces the machine's CUDA torch);
# 3. gsplat's CUDA module: loaded from $GSTYLE_CACHE (default .gpu/cache) when a build for this torch, CUDA, gsplat
#    and card is there, else built once and kept there (GSTYLE_GSPLAT_SLIM=1: only the channel counts G-Style uses
#    are compiled, about a minute on 16 cores instead of several);
# 4. the GPU tests: the twin test (gsplat against the numba rasterizer), the colour cache, a whole run on CUDA, a
#    real out-of-memory error on the card handed over to the CPU (tests/test_gpu_handover.py);
# 5. bench/device_stylize.py: the demo's preview on CUDA with the engine's rate at 512 px ("quick" stops here); with
#    "full" (the default) the studio's worker streaming on CUDA (bench/studio_rate.py), the demo's final tier on
#    CUDA, `gstyle fit` on CUDA (a copy of the LLFF fern in .gpu/fern), biker.spz's final tier, then the demo's
#    preview on CUDA and on the CPU side by side.
# "studio": after 1-3, most wanted first: the studio's worker streaming on CUDA (1 torch thread, as the studio runs
# it), tests/test_gpu_handover.py, the engine's own rate at 512 px, a profile of the stylize steps there with the
# operators a step dispatches and its waits for the GPU (bench/studio_rate.py, device_stylize.py,
# device_profile.py), the GPU's memory per Gaussian (bench/bench_memory_per_gaussian.py --device cuda), and the
# worker again at 4 torch threads. "full" also ends with the GPU's memory per Gaussian.
# "atlas" (issue #50): after 1-3, the atlas's CUDA groups (bench/tradeoff.py --devices cuda $ATLAS_ARGS, by default
# every tier, the demo and the fern x three paintings) into $OUT/atlas.csv with docs/atlas.csv's rows kept, each group
# written as it ends, for at most $ATLAS_SECONDS (330). On an H200 the previews' group took 186 s (the process's
# start on the card in its first job) and a group of three points after it 110-121 s: the whole 18 points need about
# 11 minutes, more than one call, so split them with ATLAS_ARGS (e.g. "--tiers final --scenes fern").
# "batch": after 1-2, gstyle batch on the machine's CPU cores (bench/batch_speedup.py: six runs one after another
# against 4 jobs at once, for at most $BATCH_SECONDS, 400; on the H200's 16-core host the six runs alone took more
# than 165 s). Both modes' data travel in .gpu/: shared/data (the fern's photos, the two paintings from ../shared),
# fern.ply (the fitted fern), cache/ (the VGG weights, and gsplat's built module once it came back: "atlas" returns
# it as $OUT/gsplat_module.tar, to unpack into .gpu/cache).
# Every figure is printed and kept in $OUT/gpu_check.log (OUT defaults to out/gpu_check).
set -uo pipefail
cd "$(dirname "$0")/.."
MODE=${1:-full}
OUT=${OUT:-out/gpu_check}
mkdir -p "$OUT"
LOG="$OUT/gpu_check.log"
exec > >(tee -a "$LOG") 2>&1
export PYTHONUNBUFFERED=1 GSTYLE_CACHE=${GSTYLE_CACHE:-$PWD/.gpu/cache} MAX_JOBS=${MAX_JOBS:-$(nproc)}
PY=${PYTHON:-python3}
stage() { echo; echo "== $* ($(date +%T))"; }

stage "machine"
nvidia-smi --query-gpu=name,driver_version,compute_cap,memory.total --format=csv,noheader || exit 1
nvcc --version | tail -1
"$PY" -c "import torch; print('torch', torch.__version__, 'CUDA', torch.version.cuda, 'sees', torch.cuda.device_count(), 'GPU')"

stage "packages"
if compgen -G ".whl/*.whl" >/dev/null; then
  "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    || exit 1
  export PYTHONPATH=/tmp/site:$PWD
else
  export PYTHONPATH=$PWD
fi
if [[ ${GSTYLE_GSPLAT_SLIM:-0} == 1 ]]; then  # compile the 1-5 channel kernels only (G-Style blends 3 or 4)
  site=$("$PY" -c "import gsplat, os; print(os.path.dirname(gsplat.__file__))")
  sed -i -E '/^\s*__(INS|LAUNCH_KERNEL)__\((8|9|16|17|32|33|64|65|128|129|256|257|512|513)\)\s*$/d' \
    "$site"/cuda/csrc/*.cu "$site"/cuda/csrc/*.cpp
fi

export GSTYLE_SHARED_DATA=${GSTYLE_SHARED_DATA:-$PWD/.gpu/shared/data}  # the atlas's and the batch's data
FERN=${FERN:-.gpu/fern.ply}
if [[ $MODE == batch ]]; then  # the batch on the machine's cores: no GPU, no gsplat module
  stage "gstyle batch on the CPU: 2 scenes x 3 paintings at preview, one after another against 4 jobs at once"
  timeout "${BATCH_SECONDS:-400}" "$PY" bench/batch_speedup.py --jobs 4 --threads 4 --fern "$FERN"
  stage "done"
  exit 0
fi

stage "gsplat module"
"$PY" -c "
import time, torch
from gstyle_core.raster.gsplat_module import ensure_gsplat, built_module_path
t = time.perf_counter(); ensure_gsplat(); print(f'gsplat ready in {time.perf_counter() - t:.1f} s: {built_module_path()}')
" || exit 1

if [[ $MODE == atlas ]]; then  # the GPU's cells of the atlas
  tar -cf "$OUT/gsplat_module.tar" -C "$GSTYLE_CACHE" gsplat && ls -la "$OUT/gsplat_module.tar"
  stage "the atlas on CUDA: ${ATLAS_ARGS:-every tier, the demo and the fern x three paintings}"
  cp docs/atlas.csv "$OUT/atlas.csv"
  # shellcheck disable=SC2086  # ATLAS_ARGS: options, split on purpose
  timeout "${ATLAS_SECONDS:-330}" "$PY" bench/tradeoff.py --devices cuda --fern "$FERN" --merge --out "$OUT/atlas.csv" \
    ${ATLAS_ARGS:-}
  rm -f "$OUT"/atlas_*.png  # the plots are redrawn from the CSV where it lands (bench/tradeoff.py --replot)
  stage "done"
  exit 0
fi

gpu_memory() {  # the card's memory per Gaussian (what a cap on Gaussians from the card's memory needs)
  stage "GPU memory per Gaussian: the demo x1 and x4 at 512 px, a stand-in objective"
  timeout 150 "$PY" bench/bench_memory_per_gaussian.py --width 512 --device cuda 1 4
}

if [[ $MODE == studio ]]; then  # the studio's live rate first, then the hand-over tests, the engine, its profile
  stage "the studio's worker on CUDA at 512 px, preview preset, 1 torch thread (the studio's)"
  timeout 100 "$PY" bench/studio_rate.py --device cuda --working-width 512 --preset preview --skip 2 --seconds 15 \
    --worker-threads 1
  stage "a real out-of-memory error on the card, the run handed over to the CPU (the studio's Continue on the CPU)"
  timeout 90 "$PY" -m pytest -q -p no:cacheprovider tests/test_gpu_handover.py 2>&1 | tail -15
  stage "the engine alone at 512 px (the same figure as quick's: a change's effect side by side with earlier logs)"
  timeout 120 "$PY" bench/device_stylize.py --preset preview --devices cuda --rate-width 512
  stage "profile: 8 stylize steps at 512 px on CUDA"
  timeout 100 "$PY" bench/device_profile.py --device cuda --preset preview --working-width 512 --skip 2 --steps 8
  gpu_memory
  stage "the studio's worker on CUDA at 512 px, preview preset, 4 torch threads"
  timeout 100 "$PY" bench/studio_rate.py --device cuda --working-width 512 --preset preview --skip 2 --seconds 15 \
    --worker-threads 4
  stage "done"
  exit 0
fi

stage "GPU tests"
"$PY" -m pytest -q -p no:cacheprovider tests/test_raster_gsplat.py tests/test_gpu_handover.py 2>&1 | tail -25

stage "demo preview: CUDA, and the studio's rate at 512 px"
timeout 120 "$PY" bench/device_stylize.py --preset preview --devices cuda --rate-width 512
if [[ $MODE == full ]]; then  # most wanted first: a cut-short run still brings back the earlier figures
  stage "the studio's worker on CUDA at 512 px (spawned, streaming snapshots)"
  timeout 120 "$PY" bench/studio_rate.py --device cuda --working-width 512 --skip 2 --seconds 20
  stage "demo final: CUDA"
  timeout 150 "$PY" bench/device_stylize.py --preset final --devices cuda
  if [[ -d .gpu/fern ]]; then
    stage "gstyle fit on CUDA: fern (images_8), the default 1,500 iterations"
    t0=$SECONDS
    timeout 150 "$PY" -m gstyle_core.cli fit .gpu/fern --device cuda --out /tmp/fern_cuda.ply --force 2>&1 \
      | tr '\r' '\n' | grep -v "it/s]$" | grep -v "^fit:" | tail -6
    echo "fit: $((SECONDS - t0)) s wall (the process, imports and writing included)"
    cat /tmp/fern_cuda*.json 2>/dev/null | head -40
  fi
  if [[ -f .gpu/biker.spz ]]; then
    stage "biker.spz final: CUDA"
    timeout 200 "$PY" bench/device_stylize.py .gpu/biker.spz --preset final --devices cuda
  fi
  stage "demo preview: CUDA beside the CPU (fp32), one process"
  timeout 200 "$PY" bench/device_stylize.py --preset preview --devices cuda,cpu
  gpu_memory
fi
stage "done"
