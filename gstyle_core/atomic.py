"""Atomic file output: write to a temporary file beside the target, then rename into place."""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from .outputs import refuse_overwrites, writing


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary file name beside ``path`` (ending in ``suffix``) for writers that need a path, not a handle (e.g.
    ffmpeg, which picks the container from the extension); on success the file gets the usual permissions and is
    renamed over ``path``. On any exception it is removed and ``path`` is left untouched; an ``OSError`` (no space,
    permission denied, read-only file system, a directory at ``path``) is raised as a one-line ``OutputWriteError``
    naming ``path`` (``outputs.writing``)."""
    target = Path(path)
    with writing(target):
        if target.is_dir():  # found before any data is written
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(target))
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name[:80]}.", suffix=suffix, dir=target.parent)
        os.close(fd)
        try:
            yield Path(tmp)
            os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp makes 0600 files; outputs get the usual permissions
            os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
            raise


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb") -> Iterator[IO]:
    """Open a temporary file next to ``path``; on success fsync and rename it over ``path``.

    On any exception the temporary file is removed and ``path`` is left untouched.
    """
    with atomic_path(path) as tmp, open(tmp, mode) as fh:
        yield fh
        fh.flush()
        os.fsync(fh.fileno())


def current_umask() -> int:
    """The process umask (read by setting and restoring it): temporary files get the permissions of new ones."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def refuse_overwrite(output: str | os.PathLike, force: bool, inputs: list[str | os.PathLike] = ()) -> None:
    """Raise a one-line error if ``output`` exists (unless ``force``) or is one of the ``inputs`` (always); an
    output with companions: ``outputs.refuse_overwrites``."""
    refuse_overwrites([output], force, inputs)
