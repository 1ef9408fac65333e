"""How the studio's helpers run beside its UI (the engine worker, the turntable video): one compute thread, a lower
priority than the UI, Ctrl+C left to the studio (which stops them itself), errors as one line of text
(``gstyle_core.errors.one_line_error``)."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

from gstyle_core.machine import set_torch_threads

WORKER_NICE = 10  # default niceness increment of a helper process (env GSTYLE_WORKER_NICE overrides it)


def lower_priority(increment: int = WORKER_NICE) -> None:
    """Nice the helper process (+10 by default) so the UI thread wins the CPU."""
    try:
        if increment:
            os.nice(int(increment))
    except OSError:
        pass


def worker_nice() -> int:
    """The niceness increment of the engine worker: ``GSTYLE_WORKER_NICE`` if it is an integer, else the default."""
    try:
        return int(os.environ.get("GSTYLE_WORKER_NICE", WORKER_NICE))
    except ValueError:
        return WORKER_NICE


def worker_torch_threads() -> int:
    """Torch's threads in a helper: 1, or ``GSTYLE_WORKER_THREADS`` where that is a positive integer (a bench's
    experiment: ``bench/studio_rate.py --worker-threads``)."""
    try:
        return max(1, int(os.environ.get("GSTYLE_WORKER_THREADS", "1")))
    except ValueError:
        return 1


def single_compute_thread(in_thread: bool = False) -> None:
    """One compute thread in a helper: torch's (measured best on 2 cores, gl-stack.md §3) and numba's (the
    rasterizer's parallel loops). With two numba threads the worker kept 20 % of its stand-alone step rate beside
    the UI although the UI used under one core of two: every parallel loop waited for its thread that the UI had
    preempted (``bench/ui.py``).

    A spawned helper sets ``NUMBA_NUM_THREADS`` before numba is imported. A helper thread inside the UI (or test)
    process never writes the process environment: numba re-reads it on every compile and refuses a value that
    differs from its launched pool, so it uses numba's per-thread ``set_num_threads`` instead."""
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(worker_torch_threads())
    numba = sys.modules.get("numba")
    if numba is None and not in_thread:
        os.environ["NUMBA_NUM_THREADS"] = "1"  # numba reads it at import (the engine imports it lazily)
        if torch is not None:  # numba's pool launched now: launched later it would reset torch's count to its 1
            set_torch_threads(worker_torch_threads())
        return
    if numba is None:
        import numba
    try:
        numba.set_num_threads(1)  # applies to the calling thread only
    except (ValueError, RuntimeError):  # a threading layer that cannot change its size: keep it
        pass


@contextlib.contextmanager
def interrupts_ignored() -> Iterator[None]:
    """Start helper processes inside this block: they inherit SIGINT ignored from their first instruction on, so
    Ctrl+C in the terminal (sent to the whole process group) reaches only the studio, which then asks them to save
    and stop. Outside the main thread (where signals cannot be set): no change."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def exit_words(code: int, capacity: str = "") -> str:
    """Why a helper process ended by itself, in words: a signal's name (SIGKILL: most likely the kernel's
    out-of-memory killer, with ``capacity``, the run's capacity plan, for what it expected), else its exit status."""
    if code >= 0:
        return f"the engine process exited with code {code}"
    try:
        name = signal.Signals(-code).name
    except ValueError:
        name = f"signal {-code}"
    words = f"the engine process was killed ({name}, exit {code})"
    if -code == signal.SIGKILL:
        plan = f"; the run's plan: {capacity.removeprefix('capacity: ')}" if capacity else ""
        words += f": most likely the system ran out of memory{plan}"
    return words
