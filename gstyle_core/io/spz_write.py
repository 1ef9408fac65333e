"""Write Niantic ``.spz`` (version 3, or 2 on request): the inverse of ``spz.read_spz`` within its quantisation.

What each field keeps (the decoder's step, see ``spz``): positions 24-bit fixed point with the most fractional
bits the largest coordinate allows (step 2^-frac, error <= half of it); alpha = round(sigmoid * 255); colour
round(sh_dc * 0.15 * 255 + 127.5) (sh_dc within 0.5 / 38.25, clamped to [-3.33, 3.33]); log-scale
round((s + 10) * 16) (within 1/32, clamped to [-10, 5.94]); rotation: v3 "smallest three" (the three smaller
components of the unit quaternion signed so the largest is positive, 9-bit magnitudes in units of
sqrt(0.5)/511), v2 x, y, z of the quaternion with w >= 0 as round((q + 1) * 127.5); SH round(c * 128 + 128)
(within 1/256, clamped to [-1, 0.99]). SH bands are written only up to the highest degree holding a non-zero
coefficient. Axes: the scene's RDF (OpenCV / 3DGS) is stored as SPZ's RUB.
"""

from __future__ import annotations

import gzip
import struct
from typing import IO

import numpy as np

from ..errors import SceneFormatError
from ..scene import GaussianScene, sigmoid, used_sh_degree
from .quantize import to_uint, unit_quats
from .spz import COLOR_SCALE, MAGIC, SH_DIMS, SH_FLIP_RUB_RDF

MAX_FIXED = (1 << 23) - 1
MAX_FRACTIONAL_BITS = 23  # the most ``spz.read_spz`` accepts


def fractional_bits(means: np.ndarray) -> int:
    """The most fractional bits that keep every coordinate of ``means`` inside 24-bit signed fixed point."""
    largest = float(np.max(np.abs(means))) if means.size else 0.0
    if not np.isfinite(largest):
        raise SceneFormatError("cannot save .spz: positions are not finite")
    if largest == 0.0:
        return MAX_FRACTIONAL_BITS
    bits = int(np.floor(np.log2(MAX_FIXED / largest)))
    if bits < 0:
        raise SceneFormatError(f"cannot save .spz: a coordinate of {largest:.4g} exceeds the format's range")
    return min(bits, MAX_FRACTIONAL_BITS)


def _positions(means: np.ndarray, frac: int) -> bytes:
    fixed = np.rint(means.astype(np.float64) * (1 << frac)).astype(np.int64)
    fixed = np.clip(fixed, -MAX_FIXED - 1, MAX_FIXED) & 0xFFFFFF
    out = np.stack([(fixed >> shift) & 0xFF for shift in (0, 8, 16)], axis=-1)
    return out.astype(np.uint8).tobytes()


def _rotations_first_three(wxyz: np.ndarray) -> bytes:
    q = np.where(wxyz[:, :1] < 0, -wxyz, wxyz)
    return to_uint((q[:, 1:] + 1.0) * 127.5, 255).astype(np.uint8).tobytes()


def _rotations_smallest_three(wxyz: np.ndarray) -> bytes:
    xyzw = wxyz[:, [1, 2, 3, 0]]
    largest = np.argmax(np.abs(xyzw), axis=1)
    rows = np.arange(len(xyzw))
    xyzw = np.where(xyzw[rows, largest][:, None] < 0, -xyzw, xyzw)
    others = np.array([[j for j in range(4) if j != i] for i in range(4)])[largest]  # [N, 3] in order
    packed = largest.astype(np.uint32)
    for slot in range(3):  # the first of the three smaller components lands in the highest bits
        value = xyzw[rows, others[:, slot]]
        magnitude = to_uint(np.abs(value) / np.sqrt(0.5) * 511.0, 511)
        sign = (value < 0).astype(np.uint32) & (magnitude > 0)
        packed = (packed << np.uint32(10)) | (sign << np.uint32(9)) | magnitude
    return packed.astype("<u4").tobytes()


def encode_spz(scene: GaussianScene, version: int = 3) -> bytes:
    """The gzip-compressed SPZ file of ``scene`` (version 2 or 3)."""
    if version not in (2, 3):
        raise SceneFormatError(f"cannot save .spz version {version}: only versions 2 and 3 are written")
    n = scene.count
    degree = used_sh_degree(scene.sh_rest)
    dim = SH_DIMS[degree]
    means = scene.means.astype(np.float64) * np.array([1.0, -1.0, -1.0])  # RDF -> RUB
    quats = unit_quats(scene.quats) * np.array([1.0, 1.0, -1.0, -1.0])
    frac = fractional_bits(means)
    alphas = to_uint(sigmoid(scene.opacity_logits).astype(np.float64) * 255.0, 255)
    colours = to_uint(scene.sh_dc.astype(np.float64) * (COLOR_SCALE * 255.0) + 127.5, 255)
    scales = to_uint((scene.log_scales.astype(np.float64) + 10.0) * 16.0, 255)
    rotations = _rotations_first_three(quats) if version == 2 else _rotations_smallest_three(quats)
    sh = scene.sh_rest[:, :dim].astype(np.float64) * SH_FLIP_RUB_RDF[:dim, None]
    sh_bytes = to_uint(sh * 128.0 + 128.0, 255)
    header = struct.pack("<IIIBBBB", MAGIC, version, n, degree, frac, 0, 0)
    body = b"".join([
        header,
        _positions(means, frac),
        alphas.astype(np.uint8).tobytes(),
        colours.astype(np.uint8).tobytes(),
        scales.astype(np.uint8).tobytes(),
        rotations,
        sh_bytes.astype(np.uint8).tobytes(),
    ])
    return gzip.compress(body, compresslevel=9, mtime=0)


def write_spz(fh: IO[bytes], scene: GaussianScene, version: int = 3) -> None:
    """Write the SPZ encoding of ``scene`` to an open binary file."""
    fh.write(encode_spz(scene, version))
