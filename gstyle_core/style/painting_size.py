"""The size at which a painting is matched: the stroke size's check, the painting's long side for a working width and
stroke size (``style_side``), and the resize to it (``resize_long_side``). Torch-free: the command line's argument
types and the controls' table check stroke sizes here too."""

from __future__ import annotations

import math

import numpy as np

from ..cameras.images import resize_image

MIN_STYLE_SIDE = 16  # below this the painting has next to no relu3 feature vectors (2 poolings: 4 × 4)
MAX_STYLE_SIDE = 1024  # above this the style features outgrow a CPU's memory and time (768 × 65k vectors at 1024²)


def check_style_scale(scale: float) -> float:
    """``scale`` as a float if it is a usable stroke size (finite, > 0), else ``ValueError`` saying why."""
    try:
        value = float(scale)
    except (TypeError, ValueError):
        raise ValueError(f"style scale must be a number, got {scale!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"style scale must be a finite number above 0 (1 = the painting at the working "
                         f"resolution, 2 = the painting at twice that size), got {scale}")
    return value


def style_side(working_width: int, scale: float) -> tuple[int, bool]:
    """Long side in pixels at which the painting is matched for a stroke size ``scale`` (``check_style_scale``):
    ``scale`` × max(64, working width), clamped to [MIN_STYLE_SIDE, MAX_STYLE_SIDE]; True when it was clamped."""
    wanted = round(max(64, int(working_width)) * check_style_scale(scale))
    side = min(max(wanted, MIN_STYLE_SIDE), MAX_STYLE_SIDE)
    return int(side), side != wanted


def resize_long_side(img: np.ndarray, long_side: int) -> np.ndarray:
    """Resize an [H, W, 3] float image so its longer side is ``long_side`` pixels (aspect kept)."""
    h, w = img.shape[:2]
    s = long_side / max(h, w)
    return resize_image(img, (max(1, int(round(w * s))), max(1, int(round(h * s)))))
