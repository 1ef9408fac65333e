"""Write a sequence of frames as an MP4 (H.264 through imageio's ffmpeg plugin), a GIF (Pillow) or numbered PNGs in
a folder, atomically: everything goes to a temporary file or folder beside the target and is renamed into place
only when the last frame is written, so a failure or a cancel never leaves partial output.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from .atomic import atomic_path, current_umask
from .errors import GStyleError
from .outputs import check_writable, writing

VIDEO_SUFFIXES = {".mp4": "mp4", ".gif": "gif"}
FRAME_PATTERN = "frame_{:05d}.png"
MP4_QUALITY = 8  # imageio-ffmpeg's 0-10 scale (10 = best)


class Cancelled(GStyleError):
    """The frames were cancelled before the last one; nothing was written."""


def output_kind(out: str | os.PathLike) -> str:
    """"mp4", "gif" or "dir" (a name ending in a slash, an existing folder, or no extension) for ``out``."""
    text = os.fspath(out)
    p = Path(text)
    if text.endswith(("/", os.sep)) or p.is_dir() or not p.suffix:
        return "dir"
    kind = VIDEO_SUFFIXES.get(p.suffix.lower())
    if kind is None:
        raise GStyleError(f"unknown video output {p.name}: use .mp4, .gif or a folder (ending in /) for PNG frames")
    return kind


def check_video_output(out: str | os.PathLike, force: bool) -> None:
    """Refuse an existing output unless ``force``; a folder is replaced only if it is empty or holds our frames;
    a place that refuses new files is refused now (``outputs.check_writable``), not after the frames."""
    p = Path(out)
    if output_kind(out) != "dir":
        if p.is_dir():
            raise GStyleError(f"{p} is a folder; name a .mp4 or .gif file")
        if p.exists() and not force:
            raise GStyleError(f"{p} exists; pass --force to overwrite it")
        check_writable(p)
        return
    check_writable(p.parent / f".{p.name}.frames")  # the frames are written in a folder beside it, then renamed
    if p.exists() and not p.is_dir():
        raise GStyleError(f"{p} exists and is not a folder")
    if p.is_dir():
        entries = list(p.iterdir())
        ours = all(e.is_file() and e.name.startswith("frame_") and e.suffix == ".png" for e in entries)
        if entries and not ours:
            raise GStyleError(f"{p} holds other files than frame_*.png; name a new folder")
        if entries and not force:
            raise GStyleError(f"{p} holds frames; pass --force to replace them")


def to_uint8(image: np.ndarray) -> np.ndarray:
    """[H, W, 3] float in [0, 1] (or uint8) -> contiguous uint8."""
    if image.dtype == np.uint8:
        return np.ascontiguousarray(image)
    return np.ascontiguousarray((np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8))


def even_size(frame: np.ndarray) -> np.ndarray:
    """Pad odd heights or widths by repeating the last row / column (H.264 in yuv420p needs even sides)."""
    h, w = frame.shape[:2]
    if h % 2 or w % 2:
        frame = np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    return frame


def write_frames(frames: Iterable[np.ndarray], out: str | os.PathLike, fps: float,
                 cancelled: Callable[[], bool] | None = None) -> int:
    """Write ``frames`` ([H, W, 3] float or uint8) to ``out`` (kind from ``output_kind``); returns the count.

    ``cancelled`` is asked before each frame; when it says True, ``Cancelled`` is raised and nothing is written.
    """
    if not 0 < fps <= 1000:
        raise GStyleError(f"fps must be in (0, 1000], got {fps}")
    kind = output_kind(out)
    target = Path(out)

    def checked() -> Iterable[np.ndarray]:
        for frame in frames:
            if cancelled is not None and cancelled():
                raise Cancelled("cancelled; nothing was written")
            yield to_uint8(frame)

    writer = {"mp4": _write_mp4, "gif": _write_gif, "dir": _write_dir}[kind]
    with writing(target):  # no space, permission denied, read-only: one line naming ``out`` (nothing is left)
        target.parent.mkdir(parents=True, exist_ok=True)
        count = writer(checked(), target, fps)
    if count == 0:
        raise GStyleError("no frames to write")
    return count


def _write_mp4(frames: Iterable[np.ndarray], target: Path, fps: float) -> int:
    """H.264 through imageio-ffmpeg's ffmpeg, fed raw frames on its stdin. Its messages are captured, not shown:
    when it fails (a full disk often shows only when it closes the file) the file is not renamed into place and
    its words become the error (``outputs.write_cause`` finds e.g. "No space left on device")."""
    try:
        from imageio_ffmpeg import get_ffmpeg_exe
    except ImportError as exc:  # a dependency (pyproject.toml); reported rather than a traceback
        raise GStyleError(f"MP4 needs imageio and imageio-ffmpeg ({exc}); write .gif or a folder instead") from None
    count, proc, size = 0, None, None
    with atomic_path(target, ".mp4") as tmp, tempfile.TemporaryFile() as log:  # (ffmpeg's container: the suffix)
        try:
            for frame in frames:
                frame = even_size(frame)
                if proc is None:
                    size = frame.shape
                    proc = subprocess.Popen(_ffmpeg_command(get_ffmpeg_exe(), frame, fps, tmp), stdin=subprocess.PIPE,
                                            stdout=subprocess.DEVNULL, stderr=log)
                if frame.shape != size:
                    raise GStyleError(f"frame {count} is {frame.shape[1]}x{frame.shape[0]}, the video "
                                      f"{size[1]}x{size[0]}")
                try:
                    proc.stdin.write(frame.tobytes())
                except BrokenPipeError:  # ffmpeg stopped: its own words say why (below)
                    break
                count += 1
        except BaseException:
            if proc is not None:
                proc.kill()
                proc.wait()
            raise
        if proc is None:
            raise GStyleError("no frames to write")  # (nothing is renamed into place)
        with contextlib.suppress(BrokenPipeError):
            proc.stdin.close()
        if proc.wait() != 0:
            log.seek(0)
            words = " ".join(log.read().decode("utf-8", "replace").split())
            raise OSError(f"ffmpeg failed (exit status {proc.returncode}): {words or 'no message'}")
    return count


def _ffmpeg_command(exe: str, frame: np.ndarray, fps: float, out: Path) -> list[str]:
    """ffmpeg reading raw RGB frames of ``frame``'s size on stdin, writing H.264 / yuv420p (what imageio-ffmpeg runs
    for ``quality=MP4_QUALITY``: CRF 10)."""
    from fractions import Fraction

    crf = int((1 - MP4_QUALITY / 10.0) * 51)
    return [exe, "-y", "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{frame.shape[1]}x{frame.shape[0]}",
            "-pix_fmt", "rgb24", "-r", str(Fraction(fps).limit_denominator()), "-i", "-", "-an",
            "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(crf), "-v", "error", str(out)]


def _write_gif(frames: Iterable[np.ndarray], target: Path, fps: float) -> int:
    from PIL import Image

    from .atomic import atomic_write_bytes

    images = [Image.fromarray(f) for f in frames]
    if not images:
        return 0
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], loop=0,
                   duration=max(int(round(1000.0 / fps)), 20), optimize=False)
    atomic_write_bytes(target, buf.getvalue())
    return len(images)


def _write_dir(frames: Iterable[np.ndarray], target: Path, fps: float) -> int:
    from PIL import Image

    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    count = 0
    try:
        for frame in frames:
            Image.fromarray(frame).save(tmp / FRAME_PATTERN.format(count), format="PNG")
            count += 1
        if count:
            os.chmod(tmp, 0o777 & ~current_umask())
            _replace_dir(tmp, target)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return count


def _replace_dir(tmp: Path, target: Path) -> None:
    """Rename the finished folder ``tmp`` to ``target``; an existing ``target`` is moved aside first, then removed."""
    old = None
    if target.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
        os.rmdir(old)
        os.rename(target, old)
    try:
        os.rename(tmp, target)
    except BaseException:
        if old is not None:
            with contextlib.suppress(OSError):
                os.rename(old, target)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
