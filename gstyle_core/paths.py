"""Where G-Style Studio keeps files it derives at run time (converted network weights, compiled kernels)."""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path:
    """Return the cache folder: ``$GSTYLE_CACHE``, else ``$XDG_CACHE_HOME/gstyle-studio``, else
    ``~/.cache/gstyle-studio``. The folder is not created here; writers create it when they need it."""
    explicit = os.environ.get("GSTYLE_CACHE")
    if explicit:
        return Path(explicit).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return Path(xdg).expanduser() / "gstyle-studio"
    return Path.home() / ".cache" / "gstyle-studio"
