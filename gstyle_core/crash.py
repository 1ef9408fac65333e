"""Unexpected errors (a bug, not a bad input): one line for the artist, the traceback in a crash log.

A crash log is a text file in ``cache_dir()/crashes/`` named by the time it was written
(``YYYYmmdd-HHMMSS-ffffff-WHAT.log``): where the error happened, what failed, the caller's details (the command, the
controls in force, what was kept) and the full traceback. Writing one never raises: a cache folder that refuses files
becomes a few words on the line instead. ``gstyle`` prints ``crash_line`` for any error that is not a
``GStyleError``, an ``OSError`` or an interrupt (exit status 1); the studio's worker words its failures with
``what_failed`` and ``log_crash`` the same way.
"""

from __future__ import annotations

import datetime
import platform
import re
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path

from .errors import GStyleError
from .paths import cache_dir

CRASHES = "crashes"  # the crash logs' folder in the cache folder
MAX_MESSAGE = 300  # characters of an error's first line kept on the one line (the log has it all)


class RunCrashed(Exception):
    """An unexpected ``error`` during a run with what the artist needs beside it: ``where`` it happened (e.g. "in
    phase stylize at step 38 of 257"), the ``controls`` in force, what was ``kept`` and how to go on, and ``details``
    for the crash log only. ``gstyle`` prints it as one line (``crash_line``)."""

    def __init__(self, error: BaseException, where: str = "", controls: str = "", kept: str = "",
                 details: Sequence[str] = ()) -> None:
        super().__init__(f"unexpected error{f' {where}' if where else ''}: {what_failed(error)}")
        self.error, self.where, self.controls, self.kept = error, where, controls, kept
        self.details = list(details)


def crashes_dir() -> Path:
    """``cache_dir()/crashes`` (created when a log is written)."""
    return cache_dir() / CRASHES


def what_failed(exc: BaseException) -> str:
    """``Type: message`` with the message's first line only (cut at ``MAX_MESSAGE`` characters); a ``GStyleError``
    is already worded for the user: its message alone."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    text = lines[0] if lines else "(no message)"
    if len(text) > MAX_MESSAGE:
        text = text[:MAX_MESSAGE - 1] + "…"
    return text if isinstance(exc, GStyleError) else f"{type(exc).__name__}: {text}"


def write_crash_log(error: BaseException, label: str, header: Sequence[str]) -> Path:
    """Write a crash log of ``error`` (``header``'s lines, then its traceback) named by the time and ``label`` (e.g.
    the command); returns its path. Raises what the write raised (``log_crash`` does not)."""
    now = datetime.datetime.now()
    folder = crashes_dir()
    folder.mkdir(parents=True, exist_ok=True)
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", label)[:40] or "crash"
    lines = [f"G-Style Studio crash log, {now.isoformat(timespec='seconds')}", *header,
             f"python {platform.python_version()} on {platform.platform()}", "",
             *traceback.format_exception(error)]
    text = "\n".join(line.rstrip("\n") for line in lines) + "\n"
    for attempt in range(100):  # two crashes in the same microsecond (threads): the second gets a suffix
        path = folder / f"{now:%Y%m%d-%H%M%S-%f}-{slug}{f'-{attempt}' if attempt else ''}.log"
        try:
            with open(path, "x", encoding="utf-8") as fh:
                fh.write(text)
            return path
        except FileExistsError:
            continue
    raise FileExistsError(f"no free crash log name in {folder}")


def log_crash(error: BaseException, label: str, header: Sequence[str]) -> str:
    """``write_crash_log``, worded for the one line: ``traceback in PATH``, or why it could not be kept."""
    try:
        return f"traceback in {write_crash_log(error, label, header)}"
    except Exception as exc:  # noqa: BLE001 - a full or read-only cache: the line says so, nothing else is lost
        return f"the traceback could not be saved ({what_failed(exc)})"


def crash_line(command: str, exc: BaseException, argv: Sequence[str] | None = None) -> str:
    """The one line ``gstyle COMMAND`` prints for an unexpected ``exc`` (a ``RunCrashed`` says where and what was
    kept), after writing its crash log (the command given, the line itself and the traceback)."""
    import shlex

    crash = exc if isinstance(exc, RunCrashed) else RunCrashed(exc)
    where = f" {crash.where}" if crash.where else ""
    head = f"gstyle {command}: unexpected error{where}: {what_failed(crash.error)}"
    told = [part for part in (head, crash.controls, crash.kept) if part]
    given = f"gstyle {shlex.join(argv)}" if argv is not None else " ".join(sys.argv)
    note = log_crash(crash.error, command, [f"command: {given}", *told, *crash.details])
    return "; ".join([*told, note])
