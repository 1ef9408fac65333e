"""Where the bundled demo scene and default painting live (shared by ``gstyle render``, its videos, ``gstyle
stylize`` and the studio)."""

from __future__ import annotations

from pathlib import Path

_CHECKOUT_ASSETS = Path(__file__).resolve().parents[1] / "assets"  # the repository's assets/ (editable install)
# A regular install carries assets/ inside the package as gstyle_core.bundled (pyproject.toml).
ASSETS = _CHECKOUT_ASSETS if _CHECKOUT_ASSETS.is_dir() else Path(__file__).resolve().parent / "bundled"
DEMO_SCENE = ASSETS / "demo" / "fountain.splat"
DEFAULT_STYLE = ASSETS / "styles" / "starry_night.jpg"
