"""Fuzz cases for ``load_style_image``: small images in many modes and formats, mutated.

Mutations are byte-level, plus PNG headers whose size lies (with a correct CRC, so Pillow believes it).
The checker uses small size limits (``max_side`` 64, ``max_pixels`` 4M) to keep every case cheap.
"""

from __future__ import annotations

import io
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np
from PIL import Image

from gstyle_core.errors import StyleImageError
from gstyle_core.images import load_style_image
from tests.fuzzcases.common import HUGE_COUNTS, Draw, FuzzFailure, mutate_bytes, one_line

IMAGE_FORMATS = ["png", "jpeg", "gif", "bmp", "tiff", "webp"]
MODES = {"png": ["RGB", "RGBA", "L", "LA", "P", "I;16", "1"], "jpeg": ["RGB", "L", "CMYK"],
         "gif": ["P", "L"], "bmp": ["RGB", "L", "P"], "tiff": ["RGB", "RGBA", "L", "I;16", "F", "CMYK", "1"],
         "webp": ["RGB", "RGBA"]}
MAX_SIDE, MIN_SIDE, MAX_PIXELS = 64, 8, 4_000_000


def valid_image(fmt: str, draw: Draw) -> bytes:
    """A small random image of format ``fmt`` in a drawn mode, as file bytes."""
    rng = np.random.default_rng(draw.integer(0, 2**16))
    w, h = draw.integer(1, 40), draw.integer(1, 40)
    mode = draw.choice(MODES[fmt])
    rgba = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    if draw.integer(0, 4) == 0:
        rgba[:] = rgba[0, 0]  # a uniform image
    image = Image.fromarray(rgba, "RGBA")
    if mode == "I;16":
        image = Image.fromarray(rng.integers(0, 65536, (h, w), dtype=np.uint16))
    elif mode == "F":
        image = Image.fromarray(rng.normal(0.5, 0.5, (h, w)).astype(np.float32), "F")
    elif mode == "P":
        image = image.convert("RGB").convert("P", palette=Image.Palette.ADAPTIVE, colors=16)
    elif mode != "RGBA":
        image = image.convert(mode)
    buffer = io.BytesIO()
    extra = {}
    if fmt == "jpeg" and draw.integer(0, 2) == 0:
        exif = Image.Exif()
        exif[0x0112] = draw.integer(0, 9)  # EXIF orientation, including invalid values
        extra["exif"] = exif
    image.save(buffer, format=fmt.upper(), **extra)
    return buffer.getvalue()


def _lie_png_size(data: bytes, draw: Draw) -> bytes:
    """Give the IHDR chunk another width/height and a matching CRC."""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR" or len(data) < 33:
        return data
    ihdr = bytearray(data[16:29])
    struct.pack_into(">I", ihdr, draw.choice([0, 4]), draw.choice(HUGE_COUNTS + [60000, 100000]) % 2**32)
    return data[:16] + bytes(ihdr) + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)) + data[33:]


def write_image_case(fmt: str, draw: Draw, path: Path) -> Path:
    """Write a mutated image of format ``fmt`` to ``path`` (its suffix is set from the format)."""
    data = valid_image(fmt, draw)
    for _ in range(draw.integer(0, 3)):
        data = _lie_png_size(data, draw) if draw.integer(0, 4) == 0 else mutate_bytes(data, draw)
    path = path.with_suffix("." + fmt)
    path.write_bytes(data)
    return path


def check_style_image(path: Path) -> str:
    """Load ``path`` as a style image: "ok" for a valid RGB array, "error" for a one-line StyleImageError."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            img = load_style_image(path, max_side=MAX_SIDE, min_side=MIN_SIDE, max_pixels=MAX_PIXELS)
    except StyleImageError as exc:
        one_line(exc)
        return "error"
    if img.dtype != np.float32 or img.ndim != 3 or img.shape[2] != 3 or not img.flags.c_contiguous:
        raise FuzzFailure(f"style image array {img.dtype} {img.shape}")
    if not (np.isfinite(img).all() and img.min() >= 0.0 and img.max() <= 1.0):
        raise FuzzFailure("style image values outside [0, 1]")
    if max(img.shape[:2]) > MAX_SIDE or min(img.shape[:2]) < MIN_SIDE:
        raise FuzzFailure(f"style image size {img.shape[:2]} outside [{MIN_SIDE}, {MAX_SIDE}]")
    return "ok"
