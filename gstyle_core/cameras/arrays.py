"""Reading ``.npy`` / ``.npz`` camera files without trusting their headers.

``numpy.load`` allocates the array a header declares before reading it, so a 200-byte file claiming
10^8 rows asks for gigabytes. Here the declared size is checked against the bytes that actually follow
(for ``.npz`` members: against the member's size, which may be at most ``MAX_ZIP_RATIO`` times its
compressed size) before anything is allocated. Object (pickled) arrays are refused. Every failure is a
one-line ``CameraFormatError``.
"""

from __future__ import annotations

import lzma
import math
import struct
import zipfile
import zlib
from pathlib import Path
from tokenize import TokenError
from typing import BinaryIO

import numpy as np

from gstyle_core.errors import CameraFormatError

MAX_ZIP_RATIO = 1100  # deflate cannot expand more than ~1032:1
# What numpy's header parser and zipfile raise on malformed input.
_DECODE_ERRORS = (OSError, ValueError, EOFError, SyntaxError, TokenError, zipfile.BadZipFile, zlib.error,
                  lzma.LZMAError, NotImplementedError, RuntimeError, KeyError, IndexError, struct.error,
                  OverflowError)


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0][:200] if text else type(exc).__name__


def _read_array(fh: BinaryIO, size: int, name: str) -> np.ndarray:
    """One .npy stream of ``size`` bytes: header, size check, then the data."""
    version = np.lib.format.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
    else:
        raise CameraFormatError(f"{name}: unsupported .npy version {version[0]}.{version[1]}")
    if dtype.hasobject:
        raise CameraFormatError(f"{name}: holds Python objects (not loaded, for safety)")
    if any(s < 0 for s in shape):
        raise CameraFormatError(f"{name}: negative array shape {shape}")
    count = math.prod(shape)
    need, available = count * dtype.itemsize, size - fh.tell()
    if need > available:
        raise CameraFormatError(f"{name}: truncated: header declares {shape} {dtype} = {need:,} bytes, "
                                f"only {max(available, 0):,} follow")
    data = fh.read(need)
    if len(data) != need:
        raise CameraFormatError(f"{name}: truncated: {len(data):,} of {need:,} bytes of array data")
    flat = np.frombuffer(data, dtype, count).copy()
    return flat.reshape(shape[::-1]).T if fortran else flat.reshape(shape)


def load_npy(path: Path) -> np.ndarray:
    """Read a ``.npy`` file; ``CameraFormatError`` when it is malformed, truncated or holds objects."""
    try:
        with open(path, "rb") as fh:
            return _read_array(fh, path.stat().st_size, path.name)
    except _DECODE_ERRORS as exc:
        raise CameraFormatError(f"cannot read {path.name}: {_short(exc)}") from None


def load_npz(path: Path) -> dict[str, np.ndarray]:
    """Read every ``.npy`` member of an ``.npz`` (name without ``.npy`` -> array), checking sizes first."""
    arrays = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):  # also skips folders (and nameless members)
                    continue
                if info.file_size > MAX_ZIP_RATIO * info.compress_size + 4096:
                    raise CameraFormatError(f"{path.name}: member {info.filename} claims {info.file_size:,} bytes "
                                            f"from {info.compress_size:,} compressed")
                with archive.open(info) as fh:
                    arrays[info.filename[:-4]] = _read_array(fh, info.file_size, f"{path.name}/{info.filename}")
    except CameraFormatError:
        raise
    except _DECODE_ERRORS as exc:
        raise CameraFormatError(f"cannot read {path.name}: {_short(exc)}") from None
    return arrays
