"""Ground-truth image loading: any Pillow-readable file to float32 RGB in [0, 1].

Choices (documented here because every caller depends on them):
- RGBA / LA / palette-with-transparency images are composited on a solid background, black by
  default (``background=0.0``), the same as the reference 3DGS trainer without ``--white_background``;
  the result equals ``rgb * alpha``. Pass ``background=1.0`` for white.
- Greyscale is repeated to three channels; 16-bit images are divided by 65535, 32-bit float
  images are taken as already in [0, 1] and clipped.
- EXIF orientation is applied by default (``exif_orientation=True``), so photos display upright.
  Multi-view ground truth must NOT be rotated: COLMAP ignores the EXIF tag and calibrates on the
  stored pixel grid, so :meth:`CameraSet.load_images` passes ``exif_orientation=False``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError

from gstyle_core.errors import CameraFormatError, GStyleError

_SIXTEEN_BIT_MODES = ("I;16", "I;16L", "I;16B", "I;16N")


def image_size(path: str | os.PathLike, *, exif_orientation: bool = False,
               error: type[GStyleError] = CameraFormatError) -> tuple[int, int]:
    """Return ``(width, height)`` of an image file from its header (pixels are not decoded)."""
    try:
        with Image.open(path) as img:
            width, height = img.size
            if exif_orientation and img.getexif().get(0x0112, 1) in (5, 6, 7, 8):
                width, height = height, width
    except (OSError, UnidentifiedImageError, ValueError) as exc:
        raise error(f"cannot read image {Path(path).name}: {_short(exc)}") from None
    return int(width), int(height)


def load_image(path: str | os.PathLike, size: tuple[int, int] | None = None, *,
               background: float = 0.0, exif_orientation: bool = True,
               error: type[GStyleError] = CameraFormatError) -> np.ndarray:
    """Read an image as float32 ``[H, W, 3]`` RGB in [0, 1], optionally resized to ``size=(width, height)``.

    See the module docstring for alpha, bit depth and orientation handling. Unreadable files raise
    ``error`` (``CameraFormatError`` unless the caller passes e.g. ``StyleImageError``).
    """
    try:
        with Image.open(path) as img:
            img.load()
            if exif_orientation:
                img = ImageOps.exif_transpose(img)
            rgb = _to_float_rgb(img, float(background))
    except (OSError, UnidentifiedImageError, ValueError, SyntaxError) as exc:
        raise error(f"cannot read image {Path(path).name}: {_short(exc)}") from None
    if size is not None:
        rgb = resize_image(rgb, size)
    return rgb


def resize_image(rgb: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Resize float ``[H, W, 3]`` to ``size=(width, height)`` (antialiased bicubic, clipped to [0, 1])."""
    width, height = int(size[0]), int(size[1])
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    if rgb.shape[1] == width and rgb.shape[0] == height:
        return rgb
    channels = [
        np.asarray(Image.fromarray(np.ascontiguousarray(rgb[..., c]), mode="F")
                   .resize((width, height), Image.Resampling.BICUBIC))
        for c in range(3)
    ]
    return np.clip(np.stack(channels, axis=-1), 0.0, 1.0).astype(np.float32)


def _to_float_rgb(img: Image.Image, background: float) -> np.ndarray:
    """Convert any Pillow mode to float32 RGB in [0, 1], compositing alpha on ``background``."""
    mode = img.mode
    if mode in _SIXTEEN_BIT_MODES or mode == "I":
        grey = np.asarray(img.convert("I"), dtype=np.float64)
        scale = 65535.0 if mode != "I" or grey.max(initial=0) > 255 else 255.0
        grey = np.clip(grey / scale, 0.0, 1.0)
        return np.repeat(grey[..., None], 3, axis=-1).astype(np.float32)
    if mode == "F":
        grey = np.clip(np.nan_to_num(np.asarray(img, dtype=np.float32)), 0.0, 1.0)
        return np.repeat(grey[..., None], 3, axis=-1)
    has_alpha = mode in ("RGBA", "LA", "RGBa", "La", "PA") or (mode == "P" and "transparency" in img.info)
    if has_alpha:
        rgba = np.asarray(img.convert("RGBA"), dtype=np.float32) / 255.0
        alpha = rgba[..., 3:4]
        return (rgba[..., :3] * alpha + background * (1.0 - alpha)).astype(np.float32)
    return np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0


def _short(exc: BaseException) -> str:
    """First line of an exception message, for one-line errors."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
