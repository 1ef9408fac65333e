"""Where a SOG scene's files come from: a ``.sog`` bundle (a ZIP with the files at its root) or a folder holding
``meta.json`` and the images it names.

Reads are bounded before they happen: a ZIP member's declared size must fit the caller's limit and may not exceed
``MAX_MEMBER_RATIO`` times its compressed size (WebP images do not compress further, so only a bomb does that), and
only stored or deflated members are read. Names in ``meta.json`` are plain relative paths: no absolute paths, no
``..``, nothing outside the folder or the archive's root.
"""

from __future__ import annotations

import io
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from ..errors import SceneFormatError

META_NAME = "meta.json"
ZIP_MAGIC = b"PK\x03\x04"
MAX_META_BYTES = 4 << 20
MAX_MEMBER_RATIO = 64  # uncompressed / compressed size; lossless WebP stays near 1, meta.json near 3
MEMBER_SLACK = 1 << 20  # a small member may compress well (meta.json's codebooks)


def is_sog_folder(path: str | Path) -> bool:
    """True for a folder that holds a ``meta.json`` (an unbundled SOG scene)."""
    p = Path(path)
    return p.is_dir() and (p / META_NAME).is_file()


def _checked_name(name: object, label: str) -> str:
    if not isinstance(name, str) or not name.strip():
        raise SceneFormatError(f"{label}: a file name in meta.json is not a non-empty string")
    parts = PurePosixPath(name.replace("\\", "/")).parts
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise SceneFormatError(f"{label}: meta.json names {name[:80]!r}, with control characters")
    if name.startswith(("/", "\\")) or ".." in parts or (parts and ":" in parts[0]):
        raise SceneFormatError(f"{label}: meta.json names {name[:80]!r}, outside the scene's folder")
    return "/".join(parts)


class SogFiles:
    """The files of one SOG scene: ``meta()`` and ``read(name, what, limit)``; ``kind`` is "bundle" or "folder"."""

    kind = ""
    label = ""

    def meta(self) -> bytes:
        """The bytes of ``meta.json``."""
        return self.read(META_NAME, "meta.json", MAX_META_BYTES)

    def read(self, name: object, what: str, limit: int) -> bytes:
        """The bytes of the file ``name`` (what it holds: ``what``), at most ``limit`` of them."""
        raise NotImplementedError


class BundleFiles(SogFiles):
    """A ``.sog`` bundle held in memory."""

    kind = "bundle"

    def __init__(self, data: bytes, label: str) -> None:
        self.label = label
        try:
            self.archive = zipfile.ZipFile(io.BytesIO(data))
            self.members = {info.filename: info for info in self.archive.infolist()}
        except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError, OSError, NotImplementedError) as exc:
            raise SceneFormatError(f"{label}: not a readable .sog (ZIP) file ({exc})") from None

    def read(self, name: object, what: str, limit: int) -> bytes:
        key = _checked_name(name, self.label)
        info = self.members.get(key)
        if info is None:
            raise SceneFormatError(f"{self.label}: {what} ({key}) is missing from the bundle")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED) or info.flag_bits & 1:
            raise SceneFormatError(f"{self.label}: {key} is encrypted or compressed with an unsupported method")
        if info.file_size > limit:
            raise SceneFormatError(
                f"{self.label}: {key} unpacks to {info.file_size:,} bytes, more than the {limit:,} its part can need"
            )
        if info.file_size > MAX_MEMBER_RATIO * info.compress_size + MEMBER_SLACK:
            raise SceneFormatError(
                f"{self.label}: {key} unpacks to {info.file_size:,} bytes from {info.compress_size:,} "
                f"(more than {MAX_MEMBER_RATIO}:1, a zip bomb?)"
            )
        try:
            return self.archive.read(info)
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError) as exc:
            raise SceneFormatError(f"{self.label}: {key} is damaged in the bundle ({exc})") from None


class FolderFiles(SogFiles):
    """A folder with ``meta.json`` and the images it names."""

    kind = "folder"

    def __init__(self, folder: Path, label: str) -> None:
        self.folder, self.label = folder, label

    def read(self, name: object, what: str, limit: int) -> bytes:
        key = _checked_name(name, self.label)
        path = self.folder / key
        if not path.is_file():
            raise SceneFormatError(f"{self.label}: {what} ({key}) is missing from {self.folder}")
        try:
            size = path.stat().st_size
            if size > limit:
                raise SceneFormatError(f"{self.label}: {key} is {size:,} bytes, more than the {limit:,} it can need")
            return path.read_bytes()
        except OSError as exc:
            raise SceneFormatError(f"{self.label}: cannot read {key} ({exc.strerror or exc})") from None
