"""What the studio writes: screenshots (saved by the frame loop), exports of the stylized scene (written by the engine
worker, or the result on show saved as it is), Save As and where it writes, and turntable videos (a background job,
``app/video_job.py``). ``Outputs`` is a part of ``StudioApp``."""

from __future__ import annotations

import io
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from gstyle_core.assets import DEMO_SCENE
from gstyle_core.atomic import atomic_write_bytes
from gstyle_core.engine.kept_runs import copy_result_state
from gstyle_core.errors import GStyleError
from gstyle_core.outputs import SUMMARY, unused_name
from gstyle_core.scene import GaussianScene

from .events import Handlers
from .export import EXPORT_SUFFIXES, export_shown_result, export_view
from .gl_io import read_rgb
from .panels import PanelState
from .snapshot import has_scene, scene_from_snapshot
from .status_line import StatusLine
from .video_job import VideoJob, turntable_path

if TYPE_CHECKING:
    from .engine_link import EngineLink
    from .session import Session
    from .worker import WorkerState

TURNTABLE_WIDTH = 640


def encode_png(rgb: np.ndarray) -> bytes:
    """uint8 [H, W, 3] -> PNG bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


class Outputs:
    """Owns the screenshots asked for, the video job and where Ctrl+S writes once Save As chose a place. Built with
    the GL context, the panel, the status line, the output folder, the session (the scene and result on show), the
    engine link (exports go through its worker), ``shelve`` (a saved result becomes a take; returns its name) and
    ``in_thread`` (videos render in a thread of this process: bench/ui.py)."""

    def __init__(self, ctx: moderngl.Context, panel: PanelState, status: StatusLine, output_dir: Path, *,
                 session: Session, engine: EngineLink, shelve: Callable[[list[str]], str], in_thread: bool) -> None:
        self.ctx, self.panel, self.status, self.output_dir = ctx, panel, status, output_dir
        self.session, self.engine, self.shelve, self.in_thread = session, engine, shelve, in_thread
        self.save_folder: Path | None = None  # where Ctrl+S writes once Save As chose a place (or --output-dir)
        self.screenshot_requests: list[tuple[Path, bool]] = []  # (where, scene view only), saved by the frame loop
        self.video_job: VideoJob | None = None

    # ----------------------------------------------------------------- screenshots
    def request_screenshot(self, scene_only: bool = False) -> Path:
        """Save a screenshot at the end of this frame: the whole window (``screenshot_STAMP.png``) or the scene view
        alone, without panel and overlays (``scene_only``: ``scene_STAMP.png``); never over an earlier one."""
        stamp = time.strftime("%Y%m%d_%H%M%S")
        path = unused_name(self.output_dir / f"{'scene' if scene_only else 'screenshot'}_{stamp}.png")
        if (path, scene_only) not in self.screenshot_requests:  # twice in one frame: one file
            self.screenshot_requests.append((path, scene_only))
        return path

    def save_png(self, path: str | Path, rgb: np.ndarray) -> Path:
        """Write uint8 [H, W, 3] as PNG atomically."""
        atomic_write_bytes(path, encode_png(rgb))
        return Path(path)

    def capture(self, fbo: moderngl.Framebuffer, viewport: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Read ``fbo`` (its ``viewport`` part, GL coordinates; default: its viewport) as uint8 RGB (row 0 = top);
        clears a GL error the default framebuffer read may leave."""
        rgb = read_rgb(fbo, viewport)
        _ = self.ctx.error
        return rgb

    def save_screenshots(self, fbo: moderngl.Framebuffer, scene_only: bool,
                         scene_viewport: tuple[int, int, int, int] | None) -> list[Path]:
        """Write the requested screenshots of one kind from ``fbo``: ``scene_only`` ones after the frame's scene was
        drawn and before the UI is (its part ``scene_viewport``), whole-window ones after the UI. The status line
        says where each went (or why it could not be written); returns the paths written."""
        written, left = [], []
        for path, scene in self.screenshot_requests:
            if scene != scene_only:
                left.append((path, scene))
                continue
            viewport = scene_viewport if scene_only else None
            try:
                written.append(self.save_png(path, self.capture(fbo, viewport)))
                self.status.say(f"screenshot {written[-1]}")
            except OSError as exc:  # OutputWriteError: "cannot write PATH: no space left on the device"
                self.status.say(f"screenshot: {exc}")
        self.screenshot_requests = left
        return written

    # ----------------------------------------------------------------- exports
    def export(self, path: str | Path | None = None, fmt: str = "ply") -> None:
        """Export the stylized scene (``fmt`` "ply", "spz", "compressed-ply" or "sog", + .json) through the worker; with
        no engine running, the result on show (reopened or brought back by undo) is saved as it is."""
        bridge = self.engine.bridge
        shown_result = self.session.result is not None and self.session.loaded is not None
        view = bridge.state.snapshot if bridge is not None and not bridge.alive and bridge.state.error else {}
        if (bridge is None or not bridge.alive) and not shown_result and not has_scene(view):
            self.status.say("export: no engine is running and no result is shown")
            return
        suffix = EXPORT_SUFFIXES[fmt]
        if not path:  # a name of its own: an earlier export of this second (another format) keeps its summary
            stamped = self.export_folder() / f"stylized_{time.strftime('%Y%m%d_%H%M%S')}{suffix}"
            path = unused_name(stamped, (SUMMARY,))
        path = Path(path)
        if bridge is None or not bridge.alive:
            if shown_result:
                self._save_shown_result(path)
            else:
                self._save_view(path, bridge.state)
            return
        bridge.export(path)
        self.status.say(f"exporting {path} ...")

    def _save_shown_result(self, path: Path) -> None:
        """Write the result on show (no engine) under ``path`` and shelve it as a take, as an engine's export is."""
        loaded, result = self.session.loaded, self.session.result
        try:
            export_shown_result(loaded.scene, result.summary, path)
        except GStyleError as exc:
            self.status.say(f"export: {exc}")
            return
        try:  # its run goes with it, so the copy can be continued too
            copy_result_state(loaded.path, path)
        except OSError as exc:
            print(f"gstyle-studio: saved, but its run was not copied: {exc}", flush=True)
        kept = self.shelve([str(path)])
        self.status.say(f"saved {path} (kept as {kept})")

    def _save_view(self, path: Path, st: WorkerState) -> None:
        """Write what the view shows of a run whose worker died (its last streamed geometry and colours) under
        ``path`` and shelve it as a take."""
        try:
            export_view(st.snapshot, path, self.engine.config, st.params, st.last_report, str(st.error))
        except GStyleError as exc:
            self.status.say(f"export: {exc}")
            return
        kept = self.shelve([str(path)])
        self.status.tell(f"saved what the view shows (step {(st.last_report or {}).get('step')}) to "
                         f"{path} (kept as {kept})")

    def export_folder(self) -> Path:
        """Where Ctrl+S and the export buttons write: the folder saved to last (Save As, or ``--output-dir``), else
        beside the scene the artist opened (not the bundled demo's folder; one that can be written), else the
        output folder."""
        if self.save_folder is not None:
            return self.save_folder
        loaded = self.session.loaded
        scene = Path(loaded.path) if loaded is not None else None
        if (scene is not None and scene.is_file() and scene.resolve().parent != DEMO_SCENE.resolve().parent
                and os.access(scene.parent, os.W_OK)):
            return scene.absolute().parent
        return self.output_dir

    def save_to(self, folder: str | Path) -> None:
        """Ctrl+S and the export buttons write into ``folder`` from now on."""
        self.save_folder = Path(os.path.abspath(Path(folder).expanduser()))

    def save_as(self, path: str | Path) -> None:
        """Save As: export to ``path`` (the engine writes the format its suffix names) and write there from now
        on."""
        path = Path(path)
        self.save_to(path.parent)
        self.export(path)

    # ----------------------------------------------------------------- turntable videos
    def current_scene(self) -> GaussianScene | None:
        """The stylized scene as the engine last sent it (diffuse colours), else the loaded scene (with its SH)."""
        snap = self.engine.bridge.state.snapshot if self.engine.bridge is not None else {}
        if has_scene(snap):
            return scene_from_snapshot(snap)
        return self.session.loaded.scene if self.session.loaded is not None else None

    def start_turntable(self, frames: int, fmt: str = "mp4", path: str | Path | None = None) -> Path | None:
        """Render a turntable of the current scene into the output folder in the background (``VideoJob``);
        the panel shows its progress. Returns where it will be written (None when it cannot start)."""
        from gstyle_core.render_video import cameras_up, turntable_cameras

        scene = self.current_scene()
        if scene is None or scene.count == 0:
            self.status.say("turntable: no scene")
            return None
        if self.video_job is not None and self.video_job.running:
            self.status.say("turntable: a video is already rendering")
            return None
        cameras = self.session.cameras
        size = (TURNTABLE_WIDTH, TURNTABLE_WIDTH * 3 // 4)
        if cameras:  # the scene cameras' aspect and the way they stand
            first = cameras[0].resized_to_width(TURNTABLE_WIDTH)
            size = (first.width, first.height)
        up = cameras_up(cameras) if cameras else "-y"
        try:
            cams = turntable_cameras(scene, int(frames), *size, up=up)
        except GStyleError as exc:
            self.status.say(f"turntable: {exc}")
            return None
        out = Path(path) if path else turntable_path(self.output_dir, fmt, time.strftime("%Y%m%d_%H%M%S"))
        self.video_job = VideoJob(scene, cams, out, in_thread=self.in_thread)
        self.status.say(f"rendering {out.name} ({len(cams)} frames) ...")
        return out

    def set_turntable(self, frames: int, fmt: str) -> None:
        """The turntable's settings in the panel: its frames and format."""
        self.panel.turntable_frames = frames
        self.panel.turntable_format = fmt

    def cancel_video(self) -> None:
        """Stop the video rendering (nothing is written)."""
        if self.video_job is not None:
            self.video_job.cancel()

    def close(self, timeout: float) -> None:
        """The studio closes: a half-rendered video is dropped (nothing is written)."""
        if self.video_job is not None:
            self.video_job.cancel()
            self.video_job.join(timeout)

    def fill_panel(self) -> None:
        """Where Ctrl+S writes now, and the video's progress (its last line to the status when it ends)."""
        p, job = self.panel, self.video_job
        p.save_folder, p.output_folder = str(self.export_folder()), str(self.output_dir)
        if job is None:
            p.video_running = False
            return
        progress = job.poll()
        p.video_running = job.running
        p.video_fraction = progress.fraction
        p.video_label = f"video {progress.done}/{progress.total}"
        if not job.running:
            self.status.say(progress.message)
            self.video_job = None

    def commands(self) -> Handlers:
        """The panel's commands this part carries out: screenshot, export, turntable video (start, settings,
        cancel)."""
        p = self.panel
        return {"screenshot": lambda args: self.request_screenshot(scene_only=bool(args.get("scene_only", False))),
                "export": lambda args: self.export(fmt=args.get("format", "ply")),
                "turntable": lambda args: self.start_turntable(args.get("frames", p.turntable_frames),
                                                               args.get("format", p.turntable_format)),
                "turntable_settings": lambda args: self.set_turntable(int(args.get("frames", p.turntable_frames)),
                                                                      str(args.get("format", p.turntable_format))),
                "cancel_video": lambda _args: self.cancel_video()}
