"""PlayCanvas SOG (Spatially Ordered Gaussians): ``meta.json`` and lossless WebP images, as a folder or zipped into
one ``.sog``; version 2 and the unversioned first layout (version 1), decoded as PlayCanvas's SOG specification and
its tools (the engine's SOG reader, ``@playcanvas/splat-transform`` 2.7-3.10) do.

Every per-Gaussian image is W x H with ``count <= W * H``; Gaussian ``i`` is pixel ``i`` in row-major order (x = i %
W, y = i // W); trailing pixels are ignored. Version 2:

* positions: ``means_l`` / ``means_u`` hold the low / high byte of a 16-bit q per axis (R, G, B = x, y, z);
  n = mins + (maxs - mins) * q / 65535 in the log domain, then x = sign(n) * (exp(|n|) - 1).
* rotations: ``quats`` R, G, B hold three components as (v / 255 - 0.5) * sqrt(2) (so within +-1/sqrt(2)); A - 252
  in 0..3 is the index of the omitted largest component in (w, x, y, z) order, the three stored being the others in
  that order; the omitted one is sqrt(1 - a^2 - b^2 - c^2), non-negative. Another A is reserved: such a Gaussian gets
  the identity rotation, with a warning (as the tools do).
* scales: ``scales`` R, G, B index ``scales.codebook`` (<= 256 float32 log-scales).
* colour and opacity: ``sh0`` R, G, B index ``sh0.codebook`` (DC SH coefficients, colour = 0.5 + C0 * value); A / 255
  is the opacity (0 and 255 become logits -40 and +40, as the compressed PLY reader does).
* higher SH (``shN``, optional; ``bands`` 1..3, so 3 / 8 / 15 coefficients per channel): ``shN_labels`` R + 256 G is a
  palette entry (< ``shN.count``); ``shN_centroids`` is 64 entries per row, each ``coefficients`` pixels wide (width
  64 * coefficients), pixel (u, v) = ((e % 64) * coefficients + j, e // 64) holding coefficient j of R, G, B as indices
  into ``shN.codebook``. A label past the palette gives zero coefficients, with a warning (as the tools do).

Version 1 (no ``version`` key; ``means.shape`` = [count, 3]): positions and rotations as above; scales, colour and
the opacity logit are per-channel lerps between ``mins`` and ``maxs`` of byte / 255 (sh0 A lerps the logit); the SH
palette's bytes lerp between the scalars ``shN.mins`` and ``shN.maxs``, its band count told by the centroid image's
width (192, 512, 960). Coordinates are stored as in a 3DGS PLY (the tools' PLY transform), so nothing is re-oriented.
Other versions are refused with one line.
"""

from __future__ import annotations

import json

import numpy as np

from ..errors import SceneFormatError
from ..scene import GaussianScene
from .lossless_image import decode_rgba
from .quantize import from_smallest_three, opacity_logits_of
from .sog_files import SogFiles

MAX_POINTS = 100_000_000
PIXEL_SLACK = 1 << 20  # images may be padded; more pixels than 4 x count + this is not a SOG image
PIXELS_PER_BYTE = 64  # a lossless WebP of real data holds about one pixel per byte; a bomb holds far more
BOMB_SLACK = 1 << 22
MAX_PALETTE = 1 << 16
SH_COEFFS = {1: 3, 2: 8, 3: 15}
V1_BANDS = {192: 1, 512: 2, 960: 3}


class _Meta:
    """``meta.json``'s fields, each read with a one-line error naming it."""

    def __init__(self, raw: bytes, label: str) -> None:
        self.label = label
        try:
            self.data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            raise SceneFormatError(f"{label}: meta.json is not JSON ({type(exc).__name__})") from None
        if not isinstance(self.data, dict):
            raise SceneFormatError(f"{label}: meta.json is not a JSON object")

    def get(self, path: str, required: bool = True) -> object:
        node: object = self.data
        for key in path.split("."):
            if not isinstance(node, dict) or key not in node:
                if required:
                    raise SceneFormatError(f"{self.label}: meta.json lacks {path}")
                return None
            node = node[key]
        return node

    def integer(self, path: str, lo: int, hi: int) -> int:
        value = self.get(path)
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise SceneFormatError(f"{self.label}: meta.json {path} is {repr(value)[:40]}, not a whole number in "
                                   f"{lo}..{hi:,}")
        return value

    def number(self, path: str) -> float:
        value = self.get(path)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneFormatError(f"{self.label}: meta.json {path} is not a number")
        return float(value)

    def numbers(self, path: str, length: int | None = None, most: int | None = None) -> np.ndarray:
        value = self.get(path)
        ok = isinstance(value, list) and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        if not ok or (length and len(value) != length) or (most and not 1 <= len(value) <= most):
            want = f"{length} numbers" if length else f"1 to {most} numbers"
            raise SceneFormatError(f"{self.label}: meta.json {path} is not a list of {want}")
        return np.asarray(value, np.float64)

    def files(self, path: str, count: int) -> list:
        value = self.get(path)
        if not isinstance(value, list) or len(value) < count:
            raise SceneFormatError(f"{self.label}: meta.json {path} does not name {count} file(s)")
        return value[:count]


class _Images:
    """Decodes the per-Gaussian images, all of one size with room for ``count`` Gaussians."""

    def __init__(self, files: SogFiles, count: int) -> None:
        self.files, self.count, self.shape = files, count, None

    def rgba(self, name: object, what: str) -> np.ndarray:
        """The first ``count`` pixels of image ``name`` as uint8 [count, 4]."""
        most = 4 * self.count + PIXEL_SLACK
        data = self.files.read(name, what, 5 * most + PIXEL_SLACK)
        label = f"{self.files.label}: {what} ({name})"
        pixels = decode_rgba(data, label, min(most, PIXELS_PER_BYTE * len(data) + BOMB_SLACK))
        if pixels.shape[0] * pixels.shape[1] < self.count:
            raise SceneFormatError(f"{self.files.label}: meta.json claims {self.count:,} Gaussians but {what} "
                                   f"({name}) holds only {pixels.shape[0] * pixels.shape[1]:,} pixels")
        if self.shape is not None and pixels.shape != self.shape:
            raise SceneFormatError(f"{label} is {pixels.shape[1]}x{pixels.shape[0]}, the other images "
                                   f"{self.shape[1]}x{self.shape[0]}")
        self.shape = pixels.shape
        return pixels.reshape(-1, 4)[: self.count]


def _lerp(lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    return lo + (hi - lo) * t


def _positions(meta: _Meta, images: _Images) -> np.ndarray:
    names = meta.files("means.files", 2)
    low = images.rgba(names[0], "means_l").astype(np.uint32)
    high = images.rgba(names[1], "means_u").astype(np.uint32)
    q = (low[:, :3] | (high[:, :3] << 8)).astype(np.float64) / 65535.0
    n = _lerp(meta.numbers("means.mins", 3), meta.numbers("means.maxs", 3), q)
    return np.sign(n) * np.expm1(np.abs(n))


def _rotations(meta: _Meta, images: _Images, warnings: list[str]) -> np.ndarray:
    px = images.rgba(meta.files("quats.files", 1)[0], "quats")
    small = (px[:, :3].astype(np.float64) / 255.0 - 0.5) * np.sqrt(2.0)
    mode = px[:, 3].astype(np.int64) - 252
    bad = (mode < 0) | (mode > 3)
    quats = from_smallest_three(np.where(bad, 0, mode), small)
    if bad.any():
        quats[bad] = (1.0, 0.0, 0.0, 0.0)
        warnings.append(f"{int(bad.sum()):,} rotations had a reserved mode (alpha not 252-255): identity used")
    return quats


def _lookup(codebook: np.ndarray, index: np.ndarray, label: str, what: str) -> np.ndarray:
    top = int(index.max()) if index.size else -1
    if top >= len(codebook):
        raise SceneFormatError(f"{label}: {what} holds index {top} but its codebook has {len(codebook)} entries")
    return codebook.astype(np.float32)[index]


def _palette_bytes(labels: np.ndarray, centroids: np.ndarray, entries: int, coeffs: int,
                   warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The palette bytes of each Gaussian's label, uint8 [count, coeffs, 3] (R, G, B of coefficient j), and which
    labels lay past the palette (``entries``, or the image's 64 entries per row): those get zeros and a warning."""
    bad = labels >= min(entries, 64 * centroids.shape[0])
    safe = np.where(bad, 0, labels)
    u = (safe % 64)[:, None] * coeffs + np.arange(coeffs)[None, :]
    v = np.repeat((safe // 64)[:, None], coeffs, axis=1)
    out = centroids[v, u, :3] if centroids.shape[0] else np.zeros((len(labels), coeffs, 3), np.uint8)
    if bad.any():
        out = np.where(bad[:, None, None], 0, out).astype(np.uint8)
        warnings.append(f"{int(bad.sum()):,} SH palette labels lay past the palette: no view-dependent colour")
    return out, bad


def _sh_rest_v2(meta: _Meta, files: SogFiles, images: _Images, warnings: list[str]) -> np.ndarray:
    count = images.count
    if meta.get("shN", required=False) is None:
        return np.zeros((count, 0, 3), np.float32)
    bands = meta.integer("shN.bands", 0, 3)
    if bands == 0:
        return np.zeros((count, 0, 3), np.float32)
    coeffs, entries = SH_COEFFS[bands], meta.integer("shN.count", 1, MAX_PALETTE)
    codebook = meta.numbers("shN.codebook", most=256)
    names = meta.files("shN.files", 2)
    centroids = _centroids(files, names[0], coeffs)
    labels = images.rgba(names[1], "shN_labels").astype(np.int64)
    index, bad = _palette_bytes(labels[:, 0] | (labels[:, 1] << 8), centroids, entries, coeffs, warnings)
    rest = _lookup(codebook, index, files.label, "shN_centroids")
    rest[bad] = 0.0
    return rest


def _centroids(files: SogFiles, name: object, coeffs: int | None) -> np.ndarray:
    most = 64 * 15 * (MAX_PALETTE // 64)
    data = files.read(name, "shN_centroids", 5 * most + PIXEL_SLACK)
    pixels = decode_rgba(data, f"{files.label}: shN_centroids ({name})", most)
    if coeffs is not None and pixels.shape[1] != 64 * coeffs:
        raise SceneFormatError(f"{files.label}: shN_centroids is {pixels.shape[1]} pixels wide, expected "
                               f"{64 * coeffs} for {coeffs} coefficients per channel")
    return pixels


def _decode_v2(meta: _Meta, files: SogFiles, warnings: list[str]) -> tuple[GaussianScene, int]:
    count = meta.integer("count", 0, MAX_POINTS)
    images = _Images(files, count)
    means = _positions(meta, images)
    quats = _rotations(meta, images, warnings)
    scales = images.rgba(meta.files("scales.files", 1)[0], "scales")
    log_scales = _lookup(meta.numbers("scales.codebook", most=256), scales[:, :3], files.label, "scales")
    sh0 = images.rgba(meta.files("sh0.files", 1)[0], "sh0")
    sh_dc = _lookup(meta.numbers("sh0.codebook", most=256), sh0[:, :3], files.label, "sh0")
    rest = _sh_rest_v2(meta, files, images, warnings)
    return _scene(means, log_scales, quats, opacity_logits_of(sh0[:, 3] / 255.0), sh_dc, rest), count


def _decode_v1(meta: _Meta, files: SogFiles, warnings: list[str]) -> tuple[GaussianScene, int]:
    shape = meta.numbers("means.shape", 2)
    count = int(shape[0]) if shape[0].is_integer() and 0 <= shape[0] <= MAX_POINTS else -1
    if count < 0:
        raise SceneFormatError(f"{files.label}: meta.json means.shape[0] is not a Gaussian count")
    images = _Images(files, count)
    means = _positions(meta, images)
    quats = _rotations(meta, images, warnings)
    scales = images.rgba(meta.files("scales.files", 1)[0], "scales")[:, :3] / 255.0
    log_scales = _lerp(meta.numbers("scales.mins", 3), meta.numbers("scales.maxs", 3), scales)
    sh0 = images.rgba(meta.files("sh0.files", 1)[0], "sh0") / 255.0
    colour = _lerp(meta.numbers("sh0.mins", 4), meta.numbers("sh0.maxs", 4), sh0)
    rest = np.zeros((count, 0, 3), np.float32)
    if meta.get("shN", required=False) is not None:
        names = meta.files("shN.files", 2)
        centroids = _centroids(files, names[0], None)
        bands = V1_BANDS.get(centroids.shape[1])
        if bands is None:
            raise SceneFormatError(f"{files.label}: shN_centroids is {centroids.shape[1]} pixels wide, not 192, "
                                   "512 or 960")
        coeffs = SH_COEFFS[bands]
        labels = images.rgba(names[1], "shN_labels").astype(np.int64)
        entries = (centroids.shape[1] // coeffs) * centroids.shape[0]
        index, bad = _palette_bytes(labels[:, 0] | (labels[:, 1] << 8), centroids, entries, coeffs, warnings)
        rest = _lerp(meta.number("shN.mins"), meta.number("shN.maxs"), index / 255.0)
        rest[bad] = 0.0
    return _scene(means, log_scales, quats, colour[:, 3], colour[:, :3], rest), count


def _scene(means, log_scales, quats, opacity, sh_dc, rest) -> GaussianScene:
    return GaussianScene(
        means=np.asarray(means, np.float32), log_scales=np.asarray(log_scales, np.float32),
        quats=np.asarray(quats, np.float32), opacity_logits=np.asarray(opacity, np.float32),
        sh_dc=np.asarray(sh_dc, np.float32), sh_rest=np.ascontiguousarray(rest, np.float32),
    )


def read_sog(files: SogFiles) -> tuple[GaussianScene, int, list[str], str]:
    """Decode the SOG scene ``files`` hold; returns scene, count, warnings and a format name."""
    meta = _Meta(files.meta(), files.label)
    version = meta.get("version", required=False)
    warnings: list[str] = []
    if version is None:
        scene, count = _decode_v1(meta, files, warnings)
        version = 1
    elif version == 2 and not isinstance(version, bool):
        scene, count = _decode_v2(meta, files, warnings)
    else:
        raise SceneFormatError(f"{files.label}: SOG version {repr(version)[:20]} is not supported (versions 1 and "
                               "2 are read, as PlayCanvas's tools read them)")
    model, antialias = meta.get("model", required=False), meta.get("antialias", required=False)
    if antialias is True or model not in (None, "default"):
        kind = "antialiased" if antialias is True else f"model {str(model)[:20]!r}"
        warnings.append(f"meta.json marks the scene {kind}: it is read and drawn as plain 3DGS")
    return scene, count, warnings, f"sog-v{version} ({files.kind})"
