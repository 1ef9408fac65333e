"""PlayCanvas's splat-transform CLI for the interoperability tests: ``$GSTYLE_SPLAT_TRANSFORM`` or
``splat-transform`` on PATH (``npm install -g @playcanvas/splat-transform``; scripts/test.sh installs a pinned
version into .cache where npm is available). No network probe, so the tests are instant where it is absent."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

SKIP_REASON = ("PlayCanvas splat-transform is not installed (needs node and `npm install -g "
               "@playcanvas/splat-transform`, or $GSTYLE_SPLAT_TRANSFORM)")


def splat_transform() -> list[str] | None:
    """The command that runs splat-transform, or None where it (or node) is absent."""
    exe = os.environ.get("GSTYLE_SPLAT_TRANSFORM") or shutil.which("splat-transform")
    return [exe] if exe and shutil.which("node") else None


def convert(tool: list[str], source: Path, target: Path) -> None:
    """``splat-transform -w source target`` (on the CPU: SOG's k-means would otherwise look for a GPU)."""
    subprocess.run([*tool, "-q", "-w", *(["-g", "cpu"] if target.suffix == ".sog" else []), str(source),
                    str(target)], check=True, capture_output=True, timeout=300)
