"""Fault injection for writers: a folder that fills up (ENOSPC after a few bytes), refuses new files (EACCES) or is
read-only (EROFS), without root or a real tmpfs.

``Faults.arm(root, code)`` patches ``builtins.open`` / ``io.open`` (Python writers, Pillow, pathlib), ``os.open``
(``tempfile.mkstemp``) and ``os.mkdir`` (``tempfile.mkdtemp``, parent folders) for paths under ``root``. ENOSPC
lets files be created and fails the write after ``after_bytes`` bytes (some data reaches the disk first, as on a
real full disk); EACCES and EROFS fail at creation, as a real folder of that kind does. ``disarm()`` restores
normal writes.
"""

from __future__ import annotations

import builtins
import errno
import io
import os
from pathlib import Path

WRITE_MODES = ("w", "a", "x", "+")
CREATE_FLAGS = os.O_CREAT | os.O_WRONLY | os.O_RDWR


class FullFile:
    """A real file whose writes fail with ENOSPC once ``budget`` bytes are written."""

    def __init__(self, fh, budget: int) -> None:
        self._fh, self._budget = fh, budget

    def write(self, data) -> int:
        data = bytes(data) if not isinstance(data, str) else data
        room = max(self._budget, 0)
        if len(data) > room:
            self._fh.write(data[:room])
            self._fh.flush()
            self._budget = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._budget -= len(data)
        return self._fh.write(data)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self._fh.close()

    def __getattr__(self, name):
        return getattr(self._fh, name)


class Faults:
    """Failing writes under the armed folders (see the module docstring)."""

    def __init__(self, monkeypatch, after_bytes: int = 10) -> None:
        self.roots: dict[Path, int] = {}
        self.after_bytes = after_bytes
        self.hits = 0
        real_open, real_os_open, real_mkdir = builtins.open, os.open, os.mkdir

        def fake_open(file, mode="r", *args, **kwargs):
            code = self._code(file) if any(m in mode for m in WRITE_MODES) else None
            if code is None:
                return real_open(file, mode, *args, **kwargs)
            self.hits += 1
            if code != errno.ENOSPC:
                raise OSError(code, os.strerror(code), str(file))
            return FullFile(real_open(file, mode, *args, **kwargs), self.after_bytes)

        def fake_os_open(path, flags, *args, **kwargs):
            code = self._code(path) if flags & CREATE_FLAGS else None
            if code not in (None, errno.ENOSPC):
                self.hits += 1
                raise OSError(code, os.strerror(code), str(path))
            return real_os_open(path, flags, *args, **kwargs)

        def fake_mkdir(path, *args, **kwargs):
            code = self._code(path)
            if code not in (None, errno.ENOSPC):
                self.hits += 1
                raise OSError(code, os.strerror(code), str(path))
            return real_mkdir(path, *args, **kwargs)

        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(io, "open", fake_open)  # pathlib's Path.open / write_bytes
        monkeypatch.setattr(os, "open", fake_os_open)
        monkeypatch.setattr(os, "mkdir", fake_mkdir)

    def arm(self, root: str | os.PathLike, code: int) -> None:
        """Writes under ``root`` fail with ``code`` from now on."""
        self.roots[Path(os.path.abspath(root))] = code

    def disarm(self) -> None:
        """Writes succeed again (the disk was freed, the folder made writable)."""
        self.roots.clear()

    def _code(self, path) -> int | None:
        if not isinstance(path, (str, bytes, os.PathLike)):
            return None  # a file descriptor
        p = Path(os.path.abspath(os.fsdecode(path)))
        for root, code in self.roots.items():
            if p == root or root in p.parents:
                return code
        return None


def listing(folder: str | os.PathLike) -> list[str]:
    """Every file and folder under ``folder`` (relative, sorted), hidden temporaries included."""
    base = Path(folder)
    return sorted(str(p.relative_to(base)) for p in base.rglob("*")) if base.exists() else []
