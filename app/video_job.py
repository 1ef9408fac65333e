"""A turntable video rendered away from the UI: a spawned process (default; the CPU rasterizer's kernels hold the
GIL, so a thread would stall the UI) or a thread (tests), reporting progress through a queue; cancellable.

The output appears complete or not at all (``gstyle_core.video.write_frames``).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import threading
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import one_line_error
from gstyle_core.scene import GaussianScene

from .child_process import WORKER_NICE, interrupts_ignored, lower_priority, single_compute_thread

TURNTABLE_SUFFIXES = {"mp4": ".mp4", "gif": ".gif", "png frames": ""}


def video_main(scene: GaussianScene, cameras: list[Camera], out: str, fps: float, events: Any, cancel: Any,
               in_thread: bool = False) -> None:
    """Entry point of the job: render and write, sending ("progress", (done, total)), then ("done", path),
    ("cancelled", None) or ("error", one line)."""
    from gstyle_core.render_video import render_video
    from gstyle_core.video import Cancelled

    single_compute_thread(in_thread)
    if not in_thread:
        lower_priority(WORKER_NICE)
    try:
        render_video(scene, cameras, out, fps, progress=lambda done, total: events.put(("progress", (done, total))),
                     cancelled=cancel.is_set)
    except Cancelled:
        events.put(("cancelled", None))
    except Exception as exc:  # noqa: BLE001 - reported as one line in the panel
        traceback.print_exc()
        events.put(("error", one_line_error(exc)))
    else:
        events.put(("done", out))


@dataclass
class VideoProgress:
    """What the panel shows: state is "running", "done", "cancelled" or "error"."""

    state: str = "running"
    done: int = 0
    total: int = 0
    message: str = ""

    @property
    def fraction(self) -> float:
        return self.done / self.total if self.total else 0.0


class VideoJob:
    """Render ``scene`` from ``cameras`` into ``out`` in the background; ``poll()`` each UI frame, ``cancel()``
    any time."""

    def __init__(self, scene: GaussianScene, cameras: list[Camera], out: str | os.PathLike, fps: float = 30.0,
                 *, in_thread: bool = False) -> None:
        self.out = str(out)
        self.progress = VideoProgress(total=len(cameras))
        if in_thread:
            self._events: Any = queue.Queue()
            self._cancel: Any = threading.Event()
            runner: Any = threading.Thread
        else:
            ctx = mp.get_context("spawn")
            self._events, self._cancel, runner = ctx.Queue(), ctx.Event(), ctx.Process
        self._runner = runner(target=video_main, name="gstyle-video", daemon=True,
                              args=(scene, cameras, self.out, fps, self._events, self._cancel),
                              kwargs={"in_thread": in_thread})
        with interrupts_ignored():  # Ctrl+C stops the studio, which cancels the job
            self._runner.start()

    @property
    def running(self) -> bool:
        return self.progress.state == "running"

    def cancel(self) -> None:
        """Ask the job to stop before its next frame (nothing is written)."""
        self._cancel.set()

    def poll(self) -> VideoProgress:
        """Apply the job's pending messages; a runner that ended without a last word is reported as an error."""
        self._drain(wait=0.0)
        if self.running and not self._runner.is_alive():
            self._drain(wait=0.5)  # its last messages may still be on their way through the queue
            if self.running:
                code = getattr(self._runner, "exitcode", None)
                self.progress.state, self.progress.message = "error", f"video: the renderer stopped (exit {code})"
        return self.progress

    def _drain(self, wait: float) -> None:
        while True:
            try:
                kind, payload = self._events.get(timeout=wait) if wait else self._events.get_nowait()
            except (queue.Empty, OSError, ValueError):
                return
            wait = 0.0
            if kind == "progress":
                self.progress.done, self.progress.total = payload
                continue
            self.progress.state = kind
            self.progress.message = {"done": f"wrote {payload}", "cancelled": "video cancelled; nothing written",
                                     "error": f"video: {payload}"}[kind]

    def join(self, timeout: float | None = None) -> None:
        """Wait for the runner to end (tests, closing the studio)."""
        self._runner.join(timeout)


def turntable_path(output_dir: Path, fmt: str, stamp: str) -> Path:
    """Where the studio writes a turntable of format ``fmt`` ("mp4", "gif" or "png frames"): never over an earlier
    one (``outputs.unused_name``)."""
    from gstyle_core.outputs import unused_name

    return unused_name(output_dir / f"turntable_{stamp}{TURNTABLE_SUFFIXES[fmt]}")
