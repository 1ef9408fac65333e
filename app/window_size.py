"""The studio window's size when it opens: as asked (``--size``), else as the artist left it last time (kept in the
cache folder, ``window.json``), else 80 % of the screen's work area, as desktop tools open (issue #35 item 6)."""

from __future__ import annotations

import json
from pathlib import Path

from gstyle_core.atomic import atomic_write_text
from gstyle_core.paths import cache_dir

DEFAULT_SIZE = (1280, 800)  # headless windows, and a screen glfw cannot measure
SCREEN_SHARE = 0.8
MIN_SIZE = (640, 480)
SIZE_FILE = "window.json"


def initial_size(asked: tuple[int, int] | None, remembered: tuple[int, int] | None,
                 workarea: tuple[int, int] | None) -> tuple[int, int]:
    """The size to open with: ``asked`` as given; else ``remembered`` no larger than the ``workarea`` (width,
    height of the screen less its task bars; None when unknown); else 80 % of the work area; else ``DEFAULT_SIZE``.
    Never smaller than ``MIN_SIZE`` unless asked."""
    if asked is not None:
        return asked
    if workarea is not None and min(workarea) > 0:
        limit = workarea
        size = remembered or (int(workarea[0] * SCREEN_SHARE), int(workarea[1] * SCREEN_SHARE))
    else:
        limit, size = None, remembered or DEFAULT_SIZE
    w, h = max(size[0], MIN_SIZE[0]), max(size[1], MIN_SIZE[1])
    if limit is not None:
        w, h = min(w, limit[0]), min(h, limit[1])
    return int(w), int(h)


def _size_file() -> Path:
    return cache_dir() / SIZE_FILE


def remembered_size() -> tuple[int, int] | None:
    """The window size kept when the studio last closed (None: none, or the file is unreadable)."""
    try:
        w, h = json.loads(_size_file().read_text())["size"]
        return (int(w), int(h)) if int(w) > 0 and int(h) > 0 else None
    except (OSError, ValueError, KeyError, TypeError):
        return None


def remember_size(size: tuple[int, int]) -> None:
    """Keep ``size`` for the next session (written to a temporary file and renamed; failures are ignored: the next
    session opens at 80 % of the screen)."""
    path = _size_file()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, json.dumps({"size": [int(size[0]), int(size[1])]}))
    except OSError:
        pass
