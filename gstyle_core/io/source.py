"""Reading a scene file's bytes safely, and format-neutral error helpers."""

from __future__ import annotations

import os
import zlib
from pathlib import Path

from ..errors import SceneFormatError

GZIP_MAGIC = b"\x1f\x8b"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


def read_scene_bytes(path: str | os.PathLike) -> bytes:
    """Return the whole file; one-line ``SceneFormatError`` for missing, directory, device, unreadable or empty."""
    p = Path(path)
    if p.is_dir():
        raise SceneFormatError(f"{p} is a directory, not a scene file")
    if not p.exists():
        raise SceneFormatError(f"{p}: no such file")
    if not p.is_file():  # a FIFO or a device (/dev/zero) would block or never end
        raise SceneFormatError(f"{p} is not a regular file")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise SceneFormatError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not data:
        raise SceneFormatError(f"{p.name}: empty file")
    return data


def gunzip_limited(data: bytes, limit: int, name: str) -> tuple[bytes, bool]:
    """Inflate a gzip stream, returning at most ``limit`` bytes and whether more output was left.

    Corrupt or truncated streams raise ``SceneFormatError``.
    """
    inflater = zlib.decompressobj(16 + zlib.MAX_WBITS)
    try:
        out = inflater.decompress(data, limit)
    except zlib.error as exc:
        raise SceneFormatError(f"{name}: unreadable gzip data ({exc})") from None
    more = bool(inflater.unconsumed_tail)
    if not more and not inflater.eof:
        raise SceneFormatError(f"{name}: gzip stream is truncated")
    return out, more


def zstd_decompress_exact(frame: bytes, size: int, name: str, what: str) -> bytes:
    """Decompress one zstd frame that must produce exactly ``size`` bytes."""
    import zstandard

    try:
        # the frame header's content size is what decompress() allocates: check it before trusting it
        declared = zstandard.frame_content_size(frame)
        if declared not in (zstandard.CONTENTSIZE_UNKNOWN, size):
            raise SceneFormatError(f"{name}: {what} zstd frame declares {declared:,} bytes, expected {size:,}")
        out = zstandard.ZstdDecompressor().decompress(frame, max_output_size=max(size, 1))
    except zstandard.ZstdError as exc:
        raise SceneFormatError(f"{name}: unreadable zstd data in {what} ({exc})") from None
    if len(out) != size:
        raise SceneFormatError(f"{name}: {what} decompressed to {len(out)} bytes, expected {size}")
    return out
