"""Write PlayCanvas SOG version 2 (the inverse of ``sog.read_sog`` within its quantisation): a ``.sog`` bundle (a ZIP,
members stored) or a folder (``meta.json`` beside the images).

Gaussians go in Morton order of their positions (``ply_compressed_write.morton_order``); the images are W x H with W
= 4 * ceil(sqrt(n) / 4) and H = 4 * ceil(n / W / 4) (at least 4 x 4). What each field keeps:

* positions: per axis, n = sign(x) * log(|x| + 1) between the scene's min and max, as round(65535 * t) split into two
  bytes (error <= half a step, (max - min) / 131070 in the log domain);
* rotations: the unit quaternion signed so its largest component (in w, x, y, z order) is positive, the other three
  as round((q * sqrt(2) / 2 + 0.5) * 255) (within sqrt(2) / 510 each), the largest's index as 252 + index;
* log-scales and DC colours: a 256-entry codebook each (``sog_quantize.codebook_1d``: exact when a field has 256
  distinct values or fewer), each Gaussian storing the nearest entry; opacity round(sigmoid * 255);
* higher SH, only up to the highest degree holding a non-zero coefficient: a palette of at most 65,536 vectors
  (``sog_quantize.sh_palette``: exact up to that many distinct ones), its values through a 256-entry codebook.
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path
from typing import IO

import numpy as np

from ..atomic import atomic_write_bytes
from ..errors import SceneFormatError
from ..outputs import OutputGroup
from ..scene import GaussianScene, sigmoid, used_sh_degree
from .lossless_image import encode_lossless_webp
from .ply_compressed_write import morton_order
from .quantize import smallest_three, to_uint
from .sog import SH_COEFFS
from .sog_files import META_NAME
from .sog_quantize import codebook_1d, sh_palette

GENERATOR = "G-Style Studio"
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
WEBP_MAX_SIDE = 16383


def texture_size(n: int) -> tuple[int, int]:
    """(width, height) of the per-Gaussian images for ``n`` Gaussians: multiples of 4, at least 4 x 4."""
    width = max(4, int(np.ceil(np.sqrt(n) / 4)) * 4)
    return width, max(4, int(np.ceil(n / width / 4)) * 4)


def _image(values: np.ndarray, size: tuple[int, int], alpha: np.ndarray | int = 255) -> np.ndarray:
    """uint8 [H, W, 4] with ``values`` [n, 3] in RGB of the first n pixels and ``alpha`` in A (padding all zero)."""
    width, height = size
    pixels = np.zeros((width * height, 4), np.uint8)
    n = len(values)
    pixels[:n, :3] = values
    pixels[:n, 3] = alpha
    return pixels.reshape(height, width, 4)


def _log_positions(means: np.ndarray) -> tuple[list[float], list[float], np.ndarray, np.ndarray]:
    """Per-axis mins and maxs of the log-domain positions and the low and high bytes of each 16-bit step."""
    n = np.sign(means) * np.log1p(np.abs(means))
    lo = n.min(axis=0) if len(n) else np.zeros(3)
    hi = n.max(axis=0) if len(n) else np.zeros(3)
    span = np.where(hi > lo, hi - lo, 1.0)
    q = to_uint((n - lo) / span * 65535.0, 65535)
    return lo.tolist(), hi.tolist(), (q & 0xFF).astype(np.uint8), (q >> 8).astype(np.uint8)


def _rotations(quats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    largest, small = smallest_three(quats)
    return to_uint((small * (np.sqrt(2.0) * 0.5) + 0.5) * 255.0, 255).astype(np.uint8), (252 + largest)


def _floats(codebook: np.ndarray) -> list[float]:
    """float32 values as the shortest decimals that read back to them."""
    return [float(str(v)) for v in codebook.astype(np.float32)]


def _sh_palette_images(rest: np.ndarray, size: tuple[int, int]) -> tuple[dict, dict[str, np.ndarray]]:
    """shN's meta entry and its two images for ``rest`` [n, k, 3] (k = 3, 8 or 15)."""
    n, k = rest.shape[:2]
    vectors = rest.transpose(0, 2, 1).reshape(n, 3 * k)  # channel-major, as a PLY's f_rest
    palette, labels = sh_palette(vectors)
    codebook, index = codebook_1d(palette)
    entries = len(palette)
    rows = -(-entries // 64)
    centroids = np.zeros((rows * 64, k, 4), np.uint8)
    centroids[:entries, :, :3] = index.reshape(entries, 3, k).transpose(0, 2, 1)
    centroids[:entries, :, 3] = 255
    label_bytes = np.stack([labels & 0xFF, labels >> 8, np.zeros_like(labels)], axis=1).astype(np.uint8)
    meta = {"count": entries, "bands": {3: 1, 8: 2, 15: 3}[k], "codebook": _floats(codebook),
            "files": ["shN_centroids.webp", "shN_labels.webp"]}
    images = {"shN_centroids.webp": centroids.reshape(rows, 64 * k, 4), "shN_labels.webp": _image(label_bytes, size)}
    return meta, images


def encode_sog(scene: GaussianScene) -> tuple[bytes, dict[str, bytes]]:
    """``meta.json`` (bytes) and the WebP images (name -> bytes) of ``scene`` as SOG version 2."""
    s = scene.subset(morton_order(scene.means))
    n = s.count
    if not (np.isfinite(s.means).all() and np.isfinite(s.log_scales).all()):
        raise SceneFormatError("cannot save .sog: positions or scales are not finite")
    size = texture_size(n)
    if max(size) > WEBP_MAX_SIDE:
        raise SceneFormatError(f"cannot save .sog: {n:,} Gaussians need {size[0]}x{size[1]} images, more than WebP's "
                               f"{WEBP_MAX_SIDE} pixels a side")
    mins, maxs, low, high = _log_positions(s.means.astype(np.float64))
    small, mode = _rotations(s.quats)
    scale_book, scale_index = codebook_1d(s.log_scales)
    colour_book, colour_index = codebook_1d(s.sh_dc)
    alpha = to_uint(sigmoid(s.opacity_logits).astype(np.float64) * 255.0, 255)
    images = {
        "means_l.webp": _image(low, size), "means_u.webp": _image(high, size),
        "quats.webp": _image(small, size, mode), "scales.webp": _image(scale_index, size),
        "sh0.webp": _image(colour_index, size, alpha),
    }
    meta = {
        "version": 2, "asset": {"generator": GENERATOR}, "count": n, "antialias": False,
        "means": {"mins": mins, "maxs": maxs, "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"codebook": _floats(scale_book), "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"codebook": _floats(colour_book), "files": ["sh0.webp"]},
    }
    degree = used_sh_degree(s.sh_rest)
    if degree:
        meta["shN"], palette_images = _sh_palette_images(s.sh_rest[:, : SH_COEFFS[degree]].astype(np.float32), size)
        images.update(palette_images)
    encoded = {name: encode_lossless_webp(pixels) for name, pixels in images.items()}
    return json.dumps(meta, separators=(",", ":")).encode("utf-8"), encoded


def write_sog_bundle(fh: IO[bytes], scene: GaussianScene) -> None:
    """Write ``scene`` as a ``.sog`` bundle (a ZIP of ``meta.json`` and the images, stored) to an open binary file."""
    meta, images = encode_sog(scene)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for name, data in [(META_NAME, meta), *images.items()]:
            archive.writestr(zipfile.ZipInfo(name, ZIP_DATE), data)
    fh.write(buffer.getvalue())


def write_sog_folder(meta_path: str | Path, scene: GaussianScene) -> None:
    """Write ``scene`` as ``meta_path`` (a ``meta.json``) with its images beside it, all appearing together or none
    (``OutputGroup``); images of another SOG scene in that folder with the same names are replaced."""
    target = Path(meta_path)
    meta, images = encode_sog(scene)
    target.parent.mkdir(parents=True, exist_ok=True)
    with OutputGroup() as group:
        for name, data in images.items():
            group.write(target.with_name(name), lambda tmp, data=data: atomic_write_bytes(tmp, data))
        group.write(target, lambda tmp: atomic_write_bytes(tmp, meta))
