"""Outputs that never lose work: one rule for the files written beside an output, one line for a write that fails.

* Companions (a summary JSON, before/after PNGs) are named from the full output name minus its format suffix
  (``FORMAT_SUFFIXES``), never cut at an inner dot: ``seal0.5.ply`` -> ``seal0.5.json``, ``x.compressed.ply`` ->
  ``x.json`` (``companion``). They are refused like the output itself when they exist (``refuse_overwrites``).
* Every ``OSError`` of a write (no space, permission denied, read-only file system, a directory in the way)
  becomes an ``OutputWriteError``: ``cannot write PATH: CAUSE`` (``writing``, ``write_error``); the atomic writers
  (``gstyle_core.atomic``) leave no partial file. ``check_writable`` finds a folder that refuses files before a
  long run; ``OutputGroup`` makes a scene and its companions appear together or not at all.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from .errors import GStyleError, OutputWriteError

FORMAT_SUFFIXES = (".compressed.ply", ".ply", ".splat", ".spz", ".sog", ".mp4", ".gif")  # longest first
SUMMARY = ".json"  # the summary written beside a scene output (gstyle stylize / fit, the studio's exports)
BATCH_TABLE = "batch.csv"  # the table gstyle batch writes in its folder, a row per job (batch/report.py)
STYLIZE_COMPANIONS = (SUMMARY, "_before.png", "_after.png")  # beside gstyle stylize's OUT.ply: summary, pictures

_CAUSES = {
    errno.ENOSPC: "no space left on the device",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "read-only file system",
    errno.EISDIR: "it is a directory",
    errno.ENOTDIR: "a part of its folder path is a file, not a directory",
    errno.EEXIST: "a part of its folder path is a file, not a directory",  # mkdir(exist_ok=True) over a file
    errno.ENAMETOOLONG: "the name is too long for the file system",
    errno.EFBIG: "the file is too large for the file system",
    errno.EIO: "input/output error",
}
if hasattr(errno, "EDQUOT"):  # not on every platform
    _CAUSES[errno.EDQUOT] = "disk quota exceeded"


def output_base(path: str | os.PathLike) -> Path:
    """``path`` minus its format suffix (``FORMAT_SUFFIXES``, any case; ``.compressed.ply`` as a whole); a name
    that has none of them, or would be left empty, ``.`` or ``..``, stays as it is."""
    p = Path(path)
    lower = p.name.lower()
    for suffix in FORMAT_SUFFIXES:
        if lower.endswith(suffix):
            base = p.name[: -len(suffix)]
            return p.with_name(base) if base not in ("", ".", "..") else p
    return p


def companion(path: str | os.PathLike, tail: str) -> Path:
    """The file ``tail`` (``".json"``, ``"_before.png"`` ...) names beside the output ``path``: its base
    (``output_base``) with ``tail`` appended, so ``out/seal0.5.ply`` -> ``out/seal0.5.json``."""
    base = output_base(path)
    return base.with_name(base.name + tail)


def companions(path: str | os.PathLike, tails: Iterable[str]) -> list[Path]:
    """``companion(path, tail)`` for each of ``tails``."""
    return [companion(path, tail) for tail in tails]


def unused_name(path: str | os.PathLike, tails: Iterable[str] = ()) -> Path:
    """For names the program picks itself (the studio's time-stamped exports): ``path`` or ``BASE_2.EXT``,
    ``BASE_3.EXT`` ... whichever comes first with neither the file nor its companions (``tails``) there yet."""
    p = Path(path)
    base = output_base(p)
    suffix = p.name[len(base.name):]
    candidate, n = p, 1
    while candidate.exists() or any(companion(candidate, tail).exists() for tail in tails):
        n += 1
        candidate = base.with_name(f"{base.name}_{n}{suffix}")
    return candidate


def refuse_overwrites(paths: Iterable[str | os.PathLike], force: bool,
                      inputs: Iterable[str | os.PathLike | None] = ()) -> None:
    """One-line ``GStyleError`` when any of ``paths`` is one of the ``inputs`` (always) or exists (unless
    ``force``); the message names every such file."""
    outs = [Path(p) for p in paths]
    for src in (Path(s) for s in inputs if s):
        for out in outs:
            if src.exists() and out.exists() and out.resolve() == src.resolve():
                raise GStyleError(f"refusing to overwrite the input file {out}")
    existing = [str(out) for out in outs if out.exists()]
    if existing and not force:
        verb, pronoun = ("exists", "it") if len(existing) == 1 else ("exist", "them")
        raise GStyleError(f"{', '.join(existing)} {verb}; pass --force to overwrite {pronoun}")


def write_cause(exc: OSError) -> tuple[str, int | None]:
    """A short cause for a failed write and its errno: by ``exc.errno``, else by a known reason in the message
    (e.g. ffmpeg's "No space left on device"), else the message's first line."""
    if exc.errno in _CAUSES:
        return _CAUSES[exc.errno], exc.errno
    text = str(exc)
    for code, cause in _CAUSES.items():
        if os.strerror(code) in text:
            return cause, code
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return (exc.strerror or (lines[0] if lines else type(exc).__name__)), exc.errno


def write_error(exc: OSError, path: str | os.PathLike) -> OutputWriteError:
    """``exc`` (raised while writing ``path``) as a one-line ``OutputWriteError`` naming ``path``, not a temp file."""
    if isinstance(exc, OutputWriteError):
        return exc
    cause, code = write_cause(exc)
    return OutputWriteError(path, cause, code)


@contextlib.contextmanager
def writing(path: str | os.PathLike) -> Iterator[None]:
    """Within the block, an ``OSError`` becomes ``write_error(exc, path)``."""
    try:
        yield
    except OSError as exc:
        raise write_error(exc, path) from exc


def check_writable(path: str | os.PathLike) -> None:
    """Fail early (``OutputWriteError``) when ``path`` cannot be written: a directory in its place, a file where a
    folder should be, or a folder that refuses new files (tried with a probe file in the nearest existing folder;
    nothing is created). A full disk shows only when the data is written."""
    target = Path(path)
    if target.is_dir():
        raise OutputWriteError(target, _CAUSES[errno.EISDIR], errno.EISDIR)
    folder = target.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise OutputWriteError(target, f"{folder} is a file, not a directory", errno.ENOTDIR)
    with writing(target):
        fd, probe = tempfile.mkstemp(prefix=".gstyle-probe.", dir=folder)
        os.close(fd)
        os.unlink(probe)


class OutputGroup:
    """Files that appear together or not at all (a scene and its summary): ``write`` puts each under a hidden
    temporary name beside its target, ``commit`` renames them all into place in the order written. Used as a
    context manager, a failure removes what was staged and leaves every target as it was (``--force``'s old
    files included)."""

    def __init__(self) -> None:
        self.staged: list[tuple[Path, Path]] = []  # (temporary, target)
        self.committed = 0

    def write(self, target: str | os.PathLike, writer: Callable[[Path], object]) -> Path:
        """Stage ``target``: ``writer(temporary_path)`` writes it; a failure names ``target``. Returns ``target``."""
        target = Path(target)
        tmp = target.with_name(f".{target.name[:80]}.{secrets.token_hex(4)}.part")  # (long names stay legal)
        self.staged.append((tmp, target))
        try:
            writer(tmp)
        except OSError as exc:
            cause, code = (exc.cause, exc.errno) if isinstance(exc, OutputWriteError) else write_cause(exc)
            raise OutputWriteError(target, cause, code) from exc
        return target

    @property
    def targets(self) -> list[Path]:
        """The files of the group, in the order written."""
        return [target for _tmp, target in self.staged]

    def commit(self) -> None:
        """Rename every staged file into place, in order."""
        for tmp, target in self.staged[self.committed:]:
            with writing(target):
                os.replace(tmp, target)
            self.committed += 1

    def discard(self) -> None:
        """Remove the staged files not yet renamed into place."""
        for tmp, _target in self.staged[self.committed:]:
            with contextlib.suppress(OSError):
                tmp.unlink()

    def __enter__(self) -> OutputGroup:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                self.commit()
        finally:
            self.discard()
