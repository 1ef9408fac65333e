"""8-bit RGBA images that must keep their values exactly: lossless WebP (or PNG) in, lossless WebP out (for SOG).

A lossy WebP (a ``VP8 `` bitstream, with or without an ``ALPH`` chunk) or an animation is refused before decoding,
since lossy compression changes the stored integers; so is any image whose pixel count exceeds the caller's bound,
which is checked from the header before a pixel is decoded (Pillow's own decompression-bomb guard is a later,
looser net).
"""

from __future__ import annotations

import io
import struct
import warnings

import numpy as np

from ..errors import SceneFormatError

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# libwebp's lossless effort: on biker's five SOG images (152,746 Gaussians, a 2-core VM) quality 50 / method 2 wrote
# 1.80 MB in 0.2 s, quality 100 / method 4 the same size in 14 s.
WEBP_QUALITY, WEBP_METHOD = 50, 2
EIGHT_BIT_MODES = ("RGBA", "RGB", "LA", "L", "P", "PA", "1")  # 8 bits (or fewer) per channel: exact in RGBA


def webp_bitstream(data: bytes) -> str | None:
    """The kind of a RIFF/WEBP file from its chunks: "lossless" (VP8L), "lossy" (VP8), "animated" (ANIM), or None
    when ``data`` is not a WebP file or holds no image chunk."""
    if len(data) < 16 or data[:4] != b"RIFF" or data[8:12] != b"WEBP":
        return None
    offset = 12
    while offset + 8 <= len(data):
        fourcc, size = data[offset : offset + 4], struct.unpack_from("<I", data, offset + 4)[0]
        if fourcc == b"VP8L":
            return "lossless"
        if fourcc == b"VP8 ":
            return "lossy"
        if fourcc in (b"ANIM", b"ANMF"):
            return "animated"
        offset += 8 + size + (size & 1)
    return None


def check_lossless(data: bytes, label: str) -> None:
    """One-line ``SceneFormatError`` unless ``data`` is a lossless WebP or a PNG file."""
    if data[:8] == PNG_MAGIC:
        return
    kind = webp_bitstream(data)
    if kind == "lossless":
        return
    if kind == "lossy":
        raise SceneFormatError(f"{label} is a lossy WebP: its values are not the ones written (SOG needs lossless)")
    if kind == "animated":
        raise SceneFormatError(f"{label} is an animated WebP, not one lossless image")
    raise SceneFormatError(f"{label} is not a lossless WebP or PNG image")


def decode_rgba(data: bytes, label: str, max_pixels: int) -> np.ndarray:
    """The pixels of a lossless WebP or PNG as uint8 [height, width, 4] (RGBA; alpha 255 where the file has none).

    Refuses a lossy or animated WebP, any other format, more than ``max_pixels`` pixels (from the header, before
    decoding), more than 8 bits per channel and a file that does not decode, each with a one-line
    ``SceneFormatError`` naming ``label``.
    """
    from PIL import Image

    check_lossless(data, label)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # the bound below is ours, and tighter
        try:
            with Image.open(io.BytesIO(data), formats=["WEBP", "PNG"]) as img:
                width, height = img.size
                if width * height > max_pixels:
                    raise SceneFormatError(
                        f"{label} is {width}x{height} pixels, more than the {max_pixels:,} this scene can use"
                    )
                if img.mode not in EIGHT_BIT_MODES:
                    raise SceneFormatError(f"{label} has {img.mode} pixels, not 8 bits per channel")
                img.load()
                rgba = img if img.mode == "RGBA" else img.convert("RGBA")
                pixels = np.asarray(rgba, dtype=np.uint8)
        except SceneFormatError:
            raise
        except (OSError, ValueError, SyntaxError, EOFError, struct.error, Image.DecompressionBombError) as exc:
            raise SceneFormatError(f"{label} does not decode as an image ({type(exc).__name__}: {exc})") from None
    if pixels.shape != (height, width, 4):
        raise SceneFormatError(f"{label} decoded to {pixels.shape}, expected ({height}, {width}, 4)")
    return pixels


def encode_lossless_webp(rgba: np.ndarray) -> bytes:
    """uint8 [height, width, 4] as a lossless WebP that keeps every value, the RGB of fully transparent pixels
    included (``exact``)."""
    from PIL import Image

    buffer = io.BytesIO()
    image = Image.fromarray(np.ascontiguousarray(rgba, np.uint8), "RGBA")
    image.save(buffer, format="WEBP", lossless=True, quality=WEBP_QUALITY, method=WEBP_METHOD, exact=True)
    return buffer.getvalue()
