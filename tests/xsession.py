"""A private X server for tests that use the studio as a person does: Xvfb on a display of its own choosing,
screenshots of its screen (Pillow), real input events (xdotool), and the panel's buttons found on a screenshot."""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

Box = tuple[int, int, int, int]  # x0, y0, x1, y1 (exclusive), screen pixels


class XServer:
    """A running Xvfb (stopped by its PID) with helpers for xdotool and screenshots."""

    def __init__(self, proc: subprocess.Popen, display: str) -> None:
        self.proc, self.display = proc, display

    def env(self, **extra: str) -> dict[str, str]:
        """This environment, on this display (and without a Wayland one), plus ``extra``."""
        env = {k: v for k, v in os.environ.items() if k != "WAYLAND_DISPLAY"}
        env.update(DISPLAY=self.display, **extra)
        return env

    def xdotool(self, *args: str, timeout: float = 10.0) -> str:
        """Run xdotool on this display; its output."""
        res = subprocess.run(["xdotool", *args], env=self.env(), capture_output=True, text=True, timeout=timeout)
        return res.stdout.strip()

    def find_window(self, name: str, timeout: float = 20.0) -> str | None:
        """The id of the first window whose name matches the regular expression ``name`` (None on time-out)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            found = self.xdotool("search", "--name", name).split()
            if found:
                return found[0]
            time.sleep(0.2)
        return None

    def origin(self, window: str) -> tuple[int, int]:
        """Where ``window`` is on the screen."""
        shell = dict(line.split("=", 1) for line in self.xdotool("getwindowgeometry", "--shell", window).split())
        return int(shell["X"]), int(shell["Y"])

    def click(self, window: str, x: float, y: float, away: tuple[float, float] | None = None) -> None:
        """Move the pointer to (x, y) in ``window``, click the left button and (``away``) move on there."""
        self.xdotool("mousemove", "--window", window, str(int(x)), str(int(y)))
        time.sleep(0.15)  # the app sees the pointer arrive before the button goes down, as with a hand on a mouse
        self.xdotool("click", "1")
        if away is not None:
            time.sleep(0.15)
            self.xdotool("mousemove", "--window", window, str(int(away[0])), str(int(away[1])))

    def type(self, text: str) -> None:
        """Type ``text`` into the focused window."""
        self.xdotool("type", "--delay", "8", text, timeout=30.0)

    def key(self, *keys: str) -> None:
        self.xdotool("key", *keys)

    def screenshot(self) -> np.ndarray:
        """The whole screen, uint8 [H, W, 3]."""
        from PIL import ImageGrab

        return np.asarray(ImageGrab.grab(xdisplay=self.display).convert("RGB"))

    def stop(self) -> None:
        stop_process(self.proc, 5.0)


def stop_process(proc: subprocess.Popen, grace: float) -> None:
    """Ask ``proc`` to end (SIGTERM); kill it if it has not within ``grace`` seconds."""
    proc.terminate()
    try:
        proc.wait(grace)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)


def start_xvfb(size: tuple[int, int] = (1024, 768), timeout: float = 10.0) -> XServer:
    """Start Xvfb on the first free display (``-displayfd``); ``-noreset``: a client that connects just after the
    last one left finds the server up, not resetting. Raises RuntimeError when it cannot."""
    if shutil.which("Xvfb") is None:
        raise RuntimeError("Xvfb is not installed (apt-get install xvfb; scripts/setup.sh does)")
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(write_fd), "-screen", "0", f"{size[0]}x{size[1]}x24",
                             "-nolisten", "tcp", "-noreset"], pass_fds=(write_fd,), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    os.close(write_fd)
    number = b""
    deadline = time.monotonic() + timeout
    with os.fdopen(read_fd, "rb", buffering=0) as pipe:
        while not number.endswith(b"\n") and time.monotonic() < deadline and proc.poll() is None:
            chunk = pipe.read(16)
            if not chunk:
                break
            number += chunk
    if not number.strip().isdigit():
        proc.kill()
        raise RuntimeError("Xvfb did not start")
    return XServer(proc, f":{int(number)}")


def is_button_blue(rgb: np.ndarray) -> np.ndarray:
    """Pixels of ImGui's (dark style) button, hovered button, header and title bar colours: blue well above red."""
    r, g, b = (rgb[..., i].astype(int) for i in range(3))
    return (b - r > 50) & (b > 100) & (g > 60) & (g < b)


def find_buttons(rgb: np.ndarray, region: Box, min_width: int = 30, max_width: int = 300) -> list[Box]:
    """Button-sized blue boxes in ``region`` of a screenshot, in reading order: bands of rows with blue pixels, split
    into runs of columns (gaps over 3 px split). Title bars and section headers are wider than ``max_width``."""
    x0, y0, x1, y1 = region
    mask = is_button_blue(rgb[y0:y1, x0:x1])
    rows = mask.any(axis=1)
    boxes: list[Box] = []
    y = 0
    while y < len(rows):
        if not rows[y]:
            y += 1
            continue
        top = y
        while y < len(rows) and rows[y]:
            y += 1
        if 12 <= y - top <= 30:
            boxes += [(x0 + a, y0 + top, x0 + b, y0 + y) for a, b in _runs(mask[top:y].any(axis=0), 3)
                      if min_width <= b - a <= max_width]
    return boxes


def _runs(columns: np.ndarray, max_gap: int) -> list[tuple[int, int]]:
    """Runs of True (gaps up to ``max_gap`` joined) as (start, end)."""
    idx = np.flatnonzero(columns)
    if idx.size == 0:
        return []
    splits = np.flatnonzero(np.diff(idx) > max_gap + 1)
    starts = np.concatenate([[idx[0]], idx[splits + 1]])
    ends = np.concatenate([idx[splits], [idx[-1]]]) + 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def wait_for(condition: Callable[[], object], timeout: float, every: float = 0.2) -> object:
    """Poll ``condition`` until it returns something true (returned) or ``timeout`` seconds pass (None)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(every)
    return None


def log_lines(path: Path) -> list[str]:
    """The lines a process has written to ``path`` so far."""
    return path.read_text(errors="replace").splitlines() if path.exists() else []
