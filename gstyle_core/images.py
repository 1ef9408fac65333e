"""Loading style images robustly: any Pillow-readable file → float32 RGB [H, W, 3] in [0, 1].

Documented repairs:
* EXIF orientation is applied (the image is shown the way a photo viewer shows it).
* Transparency (RGBA, LA, palette with transparency) is composited on **white**, like paper under paint.
* Greyscale, palette, CMYK, YCbCr, LAB, HSV and 1-bit images are converted to RGB; 16-bit greyscale
  (mode I;16 / I) keeps its precision (divided by 65535); float images (mode F) are clipped to [0, 1].
* Images whose longest side exceeds ``max_side`` are downscaled (Lanczos) so that it equals ``max_side``.
* Images whose shortest side is below ``min_side`` (including 1×1) are upscaled (bicubic) so that it equals
  ``min_side``; if that makes the longest side exceed ``max_side`` (extreme aspect ratios), the long side is
  centre-cropped to ``max_side``.
* A uniform (single-colour) image is accepted with a warning: it carries only a colour, no texture.
* Animated images: the first frame is used.
Errors (missing, not an image, truncated or corrupt, more than ``max_pixels`` pixels — a decompression-bomb
guard checked before decoding) raise :class:`StyleImageError` with a one-line message.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError

from .errors import StyleImageError

DEFAULT_MAX_SIDE = 1024
DEFAULT_MIN_SIDE = 64
DEFAULT_MAX_PIXELS = 100_000_000
UNIFORM_TOLERANCE = 1.0 / 255.0
# The usual names of the image files ``load_style_image`` reads (it opens whatever Pillow can): what file dialogs offer.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tif", ".tiff")


class UniformStyleWarning(UserWarning):
    """The style image has a single colour."""


def _open(path: Path, max_pixels: int) -> Image.Image:
    if not path.exists():
        raise StyleImageError(f"style image {path} does not exist")
    if not path.is_file():
        raise StyleImageError(f"style image {path} is not a file")
    # Decode from memory: Pillow skips chunks with fp.read(claimed length), which for a file object
    # allocates the claimed length up front (4 GB for one lying PNG chunk); from memory a read is bounded
    # by what is there. No image of ``max_pixels`` pixels needs more than 8 bytes per pixel on disk.
    limit = 8 * max_pixels + (16 << 20)
    if path.stat().st_size > limit:
        raise StyleImageError(f"style image {path} is {path.stat().st_size:,} bytes, more than {limit:,} "
                              f"(8 bytes per pixel of the {max_pixels:,}-pixel limit)")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise StyleImageError(f"cannot read style image {path}: {exc.strerror or exc}") from None
    try:
        with warnings.catch_warnings():
            # Pillow's own (smaller) warning limit would override ``max_pixels``, checked below before decoding
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(io.BytesIO(data))
    except Image.DecompressionBombError as exc:
        raise StyleImageError(f"style image {path} is too large to decode safely ({exc.__class__.__name__})") from exc
    except UnidentifiedImageError as exc:
        raise StyleImageError(f"{path} is not an image file Pillow can read") from exc
    except (OSError, ValueError, EOFError) as exc:  # ValueError: e.g. Pillow's "Truncated IHDR chunk"
        reason = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise StyleImageError(f"cannot open style image {path}: {reason}") from exc
    width, height = image.size
    if width * height > max_pixels:
        image.close()
        raise StyleImageError(f"style image {path} has {width}x{height} pixels, more than the limit of "
                              f"{max_pixels:,} (decompression-bomb guard)")
    if width < 1 or height < 1:
        raise StyleImageError(f"style image {path} is empty ({width}x{height})")
    return image


def _decode(image: Image.Image, path: Path, max_side: int) -> Image.Image:
    """Fully decode (first frame), honouring EXIF orientation; JPEGs are decoded at reduced size if huge."""
    try:
        if image.format == "JPEG" and max(image.size) > 2 * max_side:
            image.draft(image.mode, (max_side, max_side))
        image.load()
        return ImageOps.exif_transpose(image)
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        raise StyleImageError(f"style image {path} is corrupt or truncated ({reason})") from exc


def _downscaled(image: Image.Image, max_side: int) -> Image.Image:
    """Lanczos-downscale an 8-bit RGB/RGBA image so its longest side is at most ``max_side``."""
    width, height = image.size
    if max(width, height) <= max_side:
        return image
    scale = max_side / max(width, height)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    return image.resize(size, Image.Resampling.LANCZOS)


def _to_rgb_array(image: Image.Image, max_side: int) -> np.ndarray:
    """Any mode → float32 RGB in [0, 1]; transparency composited on white. 8-bit images are downscaled to
    ``max_side`` before conversion to float so huge images never exist as float arrays."""
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        grey = np.asarray(image, dtype=np.float32)
        scale = 65535.0 if mode.startswith("I;16") or grey.max(initial=0) > 255 else 255.0
        grey = np.clip(grey / scale, 0.0, 1.0)
        return np.repeat(grey[..., None], 3, axis=2)
    if mode == "F":
        grey = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float32)), 0.0, 1.0)
        return np.repeat(grey[..., None], 3, axis=2)
    has_alpha = mode in ("RGBA", "LA", "PA", "RGBa", "La") or "transparency" in image.info
    if has_alpha:
        rgba = np.asarray(_downscaled(image.convert("RGBA"), max_side), dtype=np.float32) / 255.0
        alpha = rgba[..., 3:4]
        return rgba[..., :3] * alpha + (1.0 - alpha)
    return np.asarray(_downscaled(image.convert("RGB"), max_side), dtype=np.float32) / 255.0


def _fit_size(rgb: np.ndarray, max_side: int, min_side: int) -> np.ndarray:
    """Downscale to ``max_side`` / upscale to ``min_side`` as documented in the module docstring."""
    height, width = rgb.shape[:2]
    scale = 1.0
    if max(height, width) > max_side:
        scale = max_side / max(height, width)
    if min(height, width) * scale < min_side:
        scale = min_side / min(height, width)
    if scale != 1.0:
        new_w, new_h = max(1, round(width * scale)), max(1, round(height * scale))
        resample = Image.Resampling.LANCZOS if scale < 1 else Image.Resampling.BICUBIC
        channels = [Image.fromarray(rgb[..., c].astype(np.float32), mode="F").resize((new_w, new_h), resample)
                    for c in range(3)]
        rgb = np.clip(np.stack([np.asarray(c) for c in channels], axis=2), 0.0, 1.0)
    height, width = rgb.shape[:2]
    if height > max_side:
        top = (height - max_side) // 2
        rgb = rgb[top:top + max_side]
    if width > max_side:
        left = (width - max_side) // 2
        rgb = rgb[:, left:left + max_side]
    return rgb


def load_style_image(path: str | Path, max_side: int = DEFAULT_MAX_SIDE, min_side: int = DEFAULT_MIN_SIDE,
                     max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Read a style image → contiguous float32 RGB [H, W, 3] in [0, 1] (see the module docstring for the
    repairs applied). Raises :class:`StyleImageError` with a one-line reason when it cannot be used."""
    if min_side < 1 or max_side < min_side:
        raise ValueError(f"need 1 <= min_side <= max_side, got min_side={min_side}, max_side={max_side}")
    path = Path(path)
    with _open(path, max_pixels) as image:
        decoded = _decode(image, path, max_side)
        rgb = _to_rgb_array(decoded, max_side)
    rgb = _fit_size(rgb, max_side, min_side)
    if np.ptp(rgb.reshape(-1, 3), axis=0).max() <= UNIFORM_TOLERANCE:
        colour = ", ".join(f"{v:.3f}" for v in rgb.reshape(-1, 3)[0])
        warnings.warn(f"style image {path.name} is a single colour ({colour}); only its colour can be "
                      "transferred", UniformStyleWarning, stacklevel=2)
    return np.ascontiguousarray(rgb, dtype=np.float32)
