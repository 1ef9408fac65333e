"""Niantic ``.spz`` (versions 1-4), decoded after the nianticlabs/spz reference library.

Header (little-endian): magic 0x5053474e ("NGSP"), version u32, numPoints u32, shDegree u8,
fractionalBits u8, flags u8 (1 = antialiased, 2 = extensions present), one more byte. Attribute streams follow
in this order: positions (v1: float16 x3; v2+: 24-bit signed fixed point x3 with ``fractionalBits``), alphas
(u8, sigmoid(opacity) * 255), colours (u8 x3, sh_dc = (b / 255 - 0.5) / 0.15), scales (u8 x3, log-scale =
b / 16 - 10), rotations (v1/v2: x, y, z as b / 127.5 - 1 with w = sqrt(1 - |xyz|^2) >= 0; v3+: "smallest
three" in 32 bits: top 2 bits = index of the largest of (x, y, z, w), then three 10-bit fields, each a
sign bit and a 9-bit magnitude scaled by 1/sqrt(2), lowest bits for the last component), SH (u8,
coefficient-major with RGB innermost, (b - 128) / 128).
- v1-v3: the header and the streams form one gzip stream.
- v4: the 32-byte header is not compressed; byte 15 is the stream count, bytes 16-19 the offset of a table of
  (compressed size u64, uncompressed size u64) per stream; each stream is a separate zstd frame, in the order
  above, right after the table. Bytes between the header and the table are extensions.
Extensions (Adobe SH quantisation, safe-orbit camera) are skipped with a warning.

Coordinates: SPZ stores RUB (x right, y up, z back). Like the reference loader asked for RDF, this reader
converts to the RDF / OpenCV axes of 3DGS PLY files: y and z of positions are negated, the quaternion's y and
z components are negated, and SH coefficients odd in y xor z change sign.
"""

from __future__ import annotations

import struct

import numpy as np

from ..errors import SceneFormatError
from ..scene import GaussianScene, logit
from .source import GZIP_MAGIC, gunzip_limited, zstd_decompress_exact

MAGIC = 0x5053474E
COLOR_SCALE = 0.15
MAX_POINTS = 100_000_000
MAX_GZIP_RATIO = 1100  # deflate cannot expand more than ~1032:1; v4 (zstd) files are held to the same bound
SH_DIMS = {0: 0, 1: 3, 2: 8, 3: 15, 4: 24}
# Sign of each SH coefficient (3DGS order) under (x, y, z) -> (x, -y, -z): RUB <-> RDF.
SH_FLIP_RUB_RDF = np.array([-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1], np.float32)


def is_spz(data: bytes) -> bool:
    """True for gzip data (checked further when decoding) or a raw NGSP header."""
    return data[:2] == GZIP_MAGIC or data[:4] == b"NGSP"


def _stream_sizes(n: int, version: int, dim: int) -> list[int]:
    return [n * (6 if version == 1 else 9), n, 3 * n, 3 * n, n * (3 if version < 3 else 4), n * dim * 3]


def _parse_header(head: bytes, name: str) -> tuple[int, int, int, int, int]:
    if len(head) < 16:
        raise SceneFormatError(f"{name}: SPZ header is truncated")
    magic, version, n, degree, frac, flags = struct.unpack_from("<IIIBBB", head)
    if magic != MAGIC:
        raise SceneFormatError(f"{name}: not an SPZ file (bad magic 0x{magic:08x})")
    if not 1 <= version <= 4:
        raise SceneFormatError(f"{name}: unsupported SPZ version {version}")
    if degree not in SH_DIMS:
        raise SceneFormatError(f"{name}: unsupported SPZ SH degree {degree}")
    if n > MAX_POINTS:
        raise SceneFormatError(f"{name}: SPZ header claims {n:,} points (more than {MAX_POINTS:,})")
    if frac > 23:
        raise SceneFormatError(f"{name}: SPZ fractional bits {frac} out of range")
    return version, n, degree, frac, flags


def read_spz(data: bytes, name: str) -> tuple[GaussianScene, int, list[str], str]:
    """Decode any supported SPZ file; returns scene, count, warnings and a format name."""
    if data[:2] == GZIP_MAGIC:
        head, _ = gunzip_limited(data, 16, name)
        if head[:4] != b"NGSP":
            raise SceneFormatError(f"{name}: gzip data is not an SPZ stream")
        version, n, degree, frac, flags = _parse_header(head, name)
        if version == 4:
            raise SceneFormatError(f"{name}: SPZ version 4 must not be gzip-compressed")
        payload = sum(_stream_sizes(n, version, SH_DIMS[degree]))
        if payload > MAX_GZIP_RATIO * len(data):
            raise SceneFormatError(
                f"{name}: SPZ header claims {n:,} points but the file is only {len(data):,} bytes"
            )
        raw, more = gunzip_limited(data, 16 + payload + (1 << 16), name)
        return _decode_legacy(raw, more, version, n, degree, frac, flags, name)
    version, n, degree, frac, flags = _parse_header(data[:16], name)
    if version == 4:
        return _decode_v4(data, n, degree, frac, flags, name)
    return _decode_legacy(data, False, version, n, degree, frac, flags, name)


def _decode_legacy(
    raw: bytes, more: bool, version: int, n: int, degree: int, frac: int, flags: int, name: str
) -> tuple[GaussianScene, int, list[str], str]:
    sizes = _stream_sizes(n, version, SH_DIMS[degree])
    extra = len(raw) - 16 - sum(sizes)
    if extra < 0:
        raise SceneFormatError(
            f"{name}: truncated: SPZ header declares {n:,} points "
            f"({sum(sizes):,} bytes) but the stream holds {len(raw) - 16:,}"
        )
    warnings = []
    start = 16
    if flags & 2:
        warnings.append(f"skipped {extra:,} bytes of SPZ extensions")
        start += extra
    elif extra or more:
        warnings.append("ignored trailing data after the SPZ streams")
    streams = []
    for size in sizes:
        streams.append(raw[start : start + size])
        start += size
    scene, w = _decode_streams(streams, version, n, degree, frac)
    return scene, n, warnings + w, f"spz-v{version}"


def _decode_v4(
    data: bytes, n: int, degree: int, frac: int, flags: int, name: str
) -> tuple[GaussianScene, int, list[str], str]:
    if len(data) < 32:
        raise SceneFormatError(f"{name}: SPZ v4 header is truncated")
    count, toc = data[15], struct.unpack_from("<I", data, 16)[0]
    sizes = _stream_sizes(n, 4, SH_DIMS[degree])
    if count not in (5, 6) or (count == 5 and sizes[5]):
        raise SceneFormatError(f"{name}: SPZ v4 has {count} streams, expected {6 if sizes[5] else 5}")
    if sum(sizes) > MAX_GZIP_RATIO * len(data):  # zstd could expand further; no real splat data does
        raise SceneFormatError(f"{name}: SPZ header claims {n:,} points but the file is only {len(data):,} bytes")
    if toc < 32 or toc + 16 * count > len(data):
        raise SceneFormatError(f"{name}: truncated: SPZ v4 stream table at {toc} lies outside the file")
    table = struct.unpack_from(f"<{2 * count}Q", data, toc)
    warnings = [f"skipped {toc - 32:,} bytes of SPZ extensions"] if toc > 32 else []
    offset = toc + 16 * count
    if offset + sum(table[0::2]) > len(data):
        raise SceneFormatError(
            f"{name}: truncated: SPZ v4 streams need {offset + sum(table[0::2]):,} bytes, "
            f"file has {len(data):,}"
        )
    labels = ["positions", "alphas", "colours", "scales", "rotations", "SH"]
    streams = []
    for i in range(count):
        packed, unpacked = table[2 * i], table[2 * i + 1]
        if unpacked != sizes[i]:
            raise SceneFormatError(
                f"{name}: SPZ v4 {labels[i]} stream holds {unpacked:,} bytes, "
                f"expected {sizes[i]:,} for {n:,} points"
            )
        frame = data[offset : offset + packed]
        streams.append(zstd_decompress_exact(frame, unpacked, name, labels[i]) if unpacked else b"")
        offset += packed
    if count == 5:
        streams.append(b"")
    if offset < len(data):
        warnings.append(f"ignored {len(data) - offset:,} trailing bytes")
    scene, w = _decode_streams(streams, 4, n, degree, frac)
    return scene, n, warnings + w, "spz-v4"


def _positions(buf: bytes, n: int, version: int, frac: int) -> np.ndarray:
    if version == 1:
        return np.frombuffer(buf, "<f2").reshape(n, 3).astype(np.float32)
    b = np.frombuffer(buf, np.uint8).reshape(n * 3, 3).astype(np.int32)
    fixed = b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)
    fixed = (fixed ^ 0x800000) - 0x800000  # sign-extend 24 bits
    return (fixed.astype(np.float64) / (1 << frac)).astype(np.float32).reshape(n, 3)


def _rotations_first_three(buf: bytes, n: int) -> np.ndarray:
    xyz = np.frombuffer(buf, np.uint8).reshape(n, 3).astype(np.float32) / 127.5 - 1.0
    w = np.sqrt(np.maximum(0.0, 1.0 - np.square(xyz).sum(axis=1)))
    return np.concatenate([w[:, None], xyz], axis=1)


def _rotations_smallest_three(buf: bytes, n: int) -> np.ndarray:
    comp = np.frombuffer(buf, "<u4", n).astype(np.int64)
    largest = comp >> 30
    xyzw = np.empty((n, 4), np.float32)
    others = np.array([[j for j in range(4) if j != i] for i in range(4)])
    rows = np.arange(n)
    total = np.zeros(n, np.float64)
    for slot in (2, 1, 0):  # the lowest 10 bits hold the last of the three smaller components
        magnitude = (comp & 511).astype(np.float64) / 511.0 * np.sqrt(0.5)
        value = np.where((comp >> 9) & 1, -magnitude, magnitude)
        xyzw[rows, others[largest, slot]] = value
        total += value * value
        comp = comp >> 10
    xyzw[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - total))
    return xyzw[:, [3, 0, 1, 2]]


def _decode_streams(
    streams: list[bytes], version: int, n: int, degree: int, frac: int
) -> tuple[GaussianScene, list[str]]:
    positions, alphas, colours, scales, rotations, sh = streams
    warnings = []
    means = _positions(positions, n, version, frac)
    quats = _rotations_first_three(rotations, n) if version < 3 else _rotations_smallest_three(rotations, n)
    dim = SH_DIMS[degree]
    sh_rest = (np.frombuffer(sh, np.uint8).reshape(n, dim, 3).astype(np.float32) - 128.0) / 128.0
    if dim > 15:
        sh_rest = sh_rest[:, :15]
        warnings.append("dropped SH degree 4 coefficients (degree 3 is the most supported)")
    # RUB -> RDF
    means[:, 1:] *= -1.0
    quats[:, 2:] *= -1.0
    sh_rest *= SH_FLIP_RUB_RDF[: sh_rest.shape[1], None]
    scene = GaussianScene(
        means=means,
        log_scales=(np.frombuffer(scales, np.uint8).reshape(n, 3).astype(np.float32) / 16.0 - 10.0),
        quats=quats.astype(np.float32),
        opacity_logits=logit(np.frombuffer(alphas, np.uint8).astype(np.float32) / 255.0),
        sh_dc=(
            (np.frombuffer(colours, np.uint8).reshape(n, 3).astype(np.float32) / 255.0 - 0.5) / COLOR_SCALE
        ).astype(np.float32),
        sh_rest=np.ascontiguousarray(sh_rest, np.float32),
    )
    return scene, warnings
