"""Write PlayCanvas / SuperSplat "compressed PLY": the inverse of ``ply_compressed.read_compressed_ply`` within its
quantisation.

Gaussians are put in Morton (Z-curve) order of their positions first, so each chunk of 256 covers a small box.
Per chunk the file stores the min/max of position, of log-scale (clamped to [-20, 20]) and of colour
(0.5 + C0 * sh_dc); each Gaussian stores them as 11-10-11-bit unorms between those bounds (error <= half a step,
(max - min) / 2047 or / 1023), its rotation as "smallest three" (2-bit index of the largest of (w, x, y, z), made
positive, then three 10-bit unorms of q * sqrt(2)/2 + 0.5), colour and opacity (sigmoid) as 8-bit unorms, and SH
(only up to the highest degree holding a non-zero coefficient) as uint8 round((c + 4) * 255 / 8), within 4/255.
"""

from __future__ import annotations

from typing import IO

import numpy as np

from ..scene import SH_C0, GaussianScene, sigmoid, used_sh_degree
from .ply_compressed import CHUNK, CHUNK_BASE, CHUNK_COLOUR, PACKED
from .quantize import smallest_three, to_uint

SCALE_LIMIT = 20.0
MIN_RANGE = 1e-5  # a chunk range below this stores every value at the chunk minimum


def morton_order(means: np.ndarray) -> np.ndarray:
    """Indices that sort ``means`` [N, 3] along a 3D Z-curve (10 bits per axis over their bounding box)."""
    if len(means) == 0:
        return np.zeros(0, np.int64)
    pts = np.asarray(means, np.float64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    cells = to_uint((pts - lo) / np.where(hi > lo, hi - lo, 1.0) * 1023.0, 1023).astype(np.uint64)
    code = np.zeros(len(pts), np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + 2 - axis)
    return np.argsort(code, kind="stable")


def _chunk_bounds(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-chunk min and max of ``values`` [N, C] (the last chunk may be partial)."""
    n = len(values)
    if n == 0:
        return values[:0], values[:0]
    starts = np.arange(0, n, CHUNK)
    return np.minimum.reduceat(values, starts, axis=0), np.maximum.reduceat(values, starts, axis=0)


def _unorms(values: np.ndarray, lo: np.ndarray, hi: np.ndarray, bits: tuple[int, ...]) -> np.ndarray:
    """Quantise ``values`` [N, C] between per-chunk bounds to unorms of ``bits`` each (uint32 [N, C])."""
    n = len(values)
    lo_v, hi_v = np.repeat(lo, CHUNK, axis=0)[:n], np.repeat(hi, CHUNK, axis=0)[:n]
    span = hi_v - lo_v
    t = np.where(span >= MIN_RANGE, (values - lo_v) / np.where(span > 0, span, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.stack([to_uint(t[:, i] * ((1 << b) - 1), (1 << b) - 1) for i, b in enumerate(bits)], axis=1)


def _pack(fields: np.ndarray, bits: tuple[int, ...]) -> np.ndarray:
    packed = np.zeros(len(fields), np.uint32)
    for i, b in enumerate(bits):
        packed = (packed << np.uint32(b)) | fields[:, i]
    return packed


def _pack_rotations(quats: np.ndarray) -> np.ndarray:
    largest, small = smallest_three(quats)
    packed = largest.astype(np.uint32)
    for slot in range(3):
        value = small[:, slot] * (np.sqrt(2.0) * 0.5) + 0.5
        packed = (packed << np.uint32(10)) | to_uint(value * 1023.0, 1023)
    return packed


def encode_compressed_ply(scene: GaussianScene) -> bytes:
    """The compressed PLY of ``scene`` (Gaussians in ``morton_order``)."""
    s = scene.subset(morton_order(scene.means))
    n = s.count
    degree = used_sh_degree(s.sh_rest)
    k = (degree + 1) ** 2 - 1
    means = s.means.astype(np.float64)
    log_scales = np.clip(s.log_scales.astype(np.float64), -SCALE_LIMIT, SCALE_LIMIT)
    rgb = 0.5 + SH_C0 * s.sh_dc.astype(np.float64)
    p_lo, p_hi = _chunk_bounds(means)
    s_lo, s_hi = _chunk_bounds(log_scales)
    c_lo, c_hi = _chunk_bounds(rgb)
    chunks = np.concatenate([p_lo, p_hi, s_lo, s_hi, c_lo, c_hi], axis=1).astype("<f4")
    alpha = to_uint(sigmoid(s.opacity_logits).astype(np.float64) * 255.0, 255)[:, None]
    vertex = np.stack([
        _pack(_unorms(means, p_lo, p_hi, (11, 10, 11)), (11, 10, 11)),
        _pack_rotations(s.quats),
        _pack(_unorms(log_scales, s_lo, s_hi, (11, 10, 11)), (11, 10, 11)),
        _pack(np.concatenate([_unorms(rgb, c_lo, c_hi, (8, 8, 8)), alpha], axis=1), (8, 8, 8, 8)),
    ], axis=1).astype("<u4")
    lines = ["ply", "format binary_little_endian 1.0", "comment written by G-Style Studio",
             f"element chunk {len(chunks)}"]
    lines += [f"property float {p}" for p in CHUNK_BASE + CHUNK_COLOUR]
    lines.append(f"element vertex {n}")
    lines += [f"property uint {p}" for p in PACKED]
    sh = b""
    if k:
        lines.append(f"element sh {n}")
        lines += [f"property uchar f_rest_{i}" for i in range(3 * k)]
        channel_major = s.sh_rest[:, :k].astype(np.float64).transpose(0, 2, 1).reshape(n, 3 * k)
        sh = to_uint((channel_major + 4.0) * (255.0 / 8.0), 255).astype(np.uint8).tobytes()
    lines.append("end_header")
    header = ("\n".join(lines) + "\n").encode("ascii")
    return header + chunks.tobytes() + vertex.tobytes() + sh


def write_compressed_ply(fh: IO[bytes], scene: GaussianScene) -> None:
    """Write the compressed PLY of ``scene`` to an open binary file."""
    fh.write(encode_compressed_ply(scene))
