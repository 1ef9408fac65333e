"""The studio: its parts, built with what each needs, and one frame of it (``StudioApp.frame``).

The parts (each a plain class that owns its state; they speak through the panel's ``Command``s, a few events of
``app/events.py`` and callables handed down, never by writing each other's attributes):

* ``status`` (``StatusLine``, ``app/status_line.py``): the one writer of the panel's status line;
* ``session`` (``Session``, ``app/session.py``): the scene on show, its cameras, the result it is, the edit history;
* ``paintings`` (``Paintings``, ``app/paintings.py``): the painting(s) and their thumbnails;
* ``undo`` (``ResultUndo``, ``app/result_undo.py``): undo and redo over the history, replaced results kept;
* ``engine`` (``EngineLink``, ``app/engine_link.py``): the engine's config and the worker bridge that runs it;
* ``sync`` (``EngineSync``, ``app/studio_sync.py``): the worker's news into the renderer and the panel each frame;
* ``views`` (``Views``, ``app/studio_views.py``): the renderers, the scene view, the view mode, the divider;
* ``takes`` (``TakesView``, ``app/takes_view.py``): the shelf of takes, showing and comparing them;
* ``region`` (``RegionTool``, ``app/region_tool.py``): the selected region;
* ``framing`` (``Framing``, ``app/studio_framing.py``): the view beside the panel and the home pose;
* ``input`` (``StudioInput``, ``app/studio_input.py``): mouse and keys in the view;
* ``files`` (``OpenFiles``, ``app/open_files.py``): opening scenes, paintings and batches;
* ``outputs`` (``Outputs``, ``app/studio_outputs.py``): screenshots, exports, Save As, turntable videos;
* ``runs`` (``SessionCommands``, ``app/studio_commands.py``): the commands that span the session's parts.

``execute`` carries out a panel command through the part that declares it (each part's ``commands()``)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import moderngl

from .camera_control import CameraControl
from .engine_link import EngineLink
from .events import Events, Handlers
from .gl_io import target_size
from .keys import KeyPresses
from .open_files import LoadedScene, OpenFiles
from .paintings import Paintings
from .panels import Command, PanelState, draw_panel
from .region_tool import RegionTool
from .result_undo import ResultUndo
from .session import Session
from .splat_data import scene_arrays
from .status_line import StatusLine
from .studio_commands import SessionCommands
from .studio_framing import Framing
from .studio_input import StudioInput, imgui_input_pending
from .studio_outputs import Outputs, encode_png
from .studio_sync import EngineSync
from .studio_views import BACKGROUND, Views
from .takes_view import TakesView

__all__ = ["LoadedScene", "StudioApp", "encode_png", "scene_arrays"]

IDLE_GAP_S = 0.5


class StudioApp:
    """The studio's parts (listed above) and its frame: ``frame()`` draws one frame into the current framebuffer."""

    def __init__(self, ctx: moderngl.Context, *, loaded: LoadedScene | None = None, style_path: str | None = None,
                 engine_factory: Callable[..., Any] | None = None, engine_config: dict[str, Any] | None = None,
                 output_dir: str | Path = "out", show_ui: bool = True, worker_mode: str = "process",
                 keys: KeyPresses | None = None) -> None:
        self.ctx = ctx
        self.keys = keys if keys is not None else KeyPresses()  # the window's key presses (app/keys.py)
        self.quit_requested = False  # Ctrl+Q: the frame loop ends as for the window's close button
        self.show_ui = show_ui
        self.progressive = True  # pace the scene render (see app/scene_view.py); False: full frames always
        self.panel = PanelState()
        self.events = Events()
        self.status = StatusLine(self.panel)
        self.control = CameraControl()
        output = Path(os.path.abspath(Path(output_dir).expanduser()))  # absolute from the start: exports, takes
        self._build_parts(ctx, output, engine_factory, engine_config, worker_mode)
        self._handlers: Handlers = {
            "toggle_help": lambda _args: self._toggle_help(), "quit": lambda _args: self._quit()}
        for part in (self.engine, self.runs, self.undo, self.takes, self.framing, self.region, self.outputs,
                     self.files):
            self._handlers.update(part.commands())
        self._frame_times: list[float] = []
        self._last_frame = time.perf_counter()
        self.scene_viewport: tuple[int, int, int, int] | None = None  # the last frame's scene view (GL viewport)
        if loaded is not None:
            self.session.set_scene(loaded)
        if style_path:
            self.paintings.set_style(style_path)

    def _build_parts(self, ctx: moderngl.Context, output_dir: Path, engine_factory: Callable[..., Any] | None,
                     engine_config: dict[str, Any] | None, worker_mode: str) -> None:
        """Each part with what it needs; a part built later is reached through a callable handed down."""
        panel, status, events, control = self.panel, self.status, self.events, self.control
        self.views = Views(ctx, panel, control, events)
        self.engine = EngineLink(panel, status, events, factory=engine_factory, config=engine_config,
                                 worker_mode=worker_mode, region_entries=lambda: self.region.engine_entries())
        self.session = Session(panel, events, self.engine)
        self.region = RegionTool(panel, status, control, self.session.history, lambda: self.session.loaded,
                                 (("original", self.views.original), ("stylized", self.views.stylized)), events)
        self.framing = Framing(panel, status, control, lambda: self.session.cameras, events)
        self.paintings = Paintings(ctx, panel, self.engine.set_style)
        self.takes = TakesView(ctx, panel, status, output_dir, views=self.views, control=control,
                               view_key=self.engine.view_key, input_path=self.session.input_path,
                               open_path=lambda path: self.files.open_path(path))
        self.sync = EngineSync(panel, status, events, self.engine, self.views.stylized,
                               showing_result=lambda: self.session.result is not None,
                               shelve=self.takes.shelve_exports)
        self.outputs = Outputs(ctx, panel, status, output_dir, session=self.session, engine=self.engine,
                               shelve=self.takes.shelve_exports, in_thread=worker_mode == "thread")
        self.undo = ResultUndo(status, events, self.session, self.engine, self.paintings, self.region,
                               open_path=lambda path: self.files.open_path(path),
                               apply_params=lambda values: self.runs.apply_params(values))
        self.files = OpenFiles(panel, status, self.session, self.engine, self.paintings, self.undo, self.takes,
                               self.outputs)
        self.runs = SessionCommands(panel, status, self.session, self.engine, self.paintings, self.region, self.undo,
                                    open_path=self.files.open_path)
        self.input = StudioInput(panel, self.keys, control, self.region, self.views,
                                 has_scene=lambda: self.session.loaded is not None)

    # ----------------------------------------------------------------- commands
    def execute(self, cmd: Command) -> None:
        """Carry out one panel command (through the part that declares it; an unknown one does nothing)."""
        handler = self._handlers.get(cmd.name)
        if handler is not None:
            handler(cmd.args)

    def _toggle_help(self) -> None:
        self.panel.show_help = not self.panel.show_help

    def _quit(self) -> None:
        """The frame loop ends as for the close button (the session is saved on close)."""
        self.quit_requested = True

    # ----------------------------------------------------------------- per frame
    def frame(self, target: moderngl.Framebuffer, with_ui: bool = True) -> list[Command]:
        """Update from the engine, handle input, render the scene into ``target`` and (if with_ui) build the UI.

        The scene is laid out in the part of ``target`` beside the docked panel (``Framing.view_rect``): the whole
        of it when the panel is collapsed or hidden. The caller has started the ImGui frame (when with_ui) and
        renders ImGui afterwards.
        """
        now = time.perf_counter()
        dt, self._last_frame = now - self._last_frame, now
        if dt < IDLE_GAP_S:  # a gap after waiting for events (render on demand) is not a frame time
            self._frame_times = (self._frame_times + [dt])[-60:]
        self.sync.apply_updates()
        self.region.apply_selection()
        self.files.poll_dialog()
        commands: list[Command] = []
        full = tuple(target.viewport)
        view = self.framing.view_rect(full, with_ui and self.show_ui)
        presses = self.keys.take()  # taken every frame: a press acts in the frame after it, or never
        if with_ui:
            self.input.handle(view, dt)
            self.fill_panel()
            if self.show_ui:
                commands = draw_panel(self.panel, presses)
            for cmd in commands:
                self.execute(cmd)
            view = self.framing.view_rect(full, with_ui and self.show_ui)  # the panel may have collapsed or opened
        self.scene_viewport = view
        if view != full:
            target.use()
            target.clear(*BACKGROUND, 1.0)
        target.viewport = view
        try:
            self.render_view(target)
        finally:
            target.viewport = full
        return commands

    def fill_panel(self) -> None:
        """Every part's fields of the panel, as they are now (the status lines of the video, the run and the takes
        in that order)."""
        self.panel.fps = len(self._frame_times) / max(sum(self._frame_times), 1e-6)
        self.views.fill_panel()
        self.engine.fill_panel()
        self.takes.fill_panel()
        self.session.fill_panel()
        self.region.fill_panel(self.framing.view_size, engine_running=self.engine.bridge is not None)
        self.outputs.fill_panel()
        self.sync.fill_panel()
        self.takes.show_write_error()  # (renaming or forgetting takes needs no engine)

    def render_view(self, target: moderngl.Framebuffer) -> None:
        """Show the current view mode in ``target`` (its viewport) from the camera, framed for its size. Screenshots
        and the last frame of a --frames run show the exact current state at full resolution."""
        width, height = target_size(target)
        self.framing.keep_framed((width, height))
        camera = self.control.camera(width, height)
        self.views.render(target, camera, progressive=self.progressive and not self.outputs.screenshot_requests)

    def save_screenshots(self, fbo: moderngl.Framebuffer, scene_only: bool) -> list[Path]:
        """Write the requested screenshots of one kind from ``fbo`` (``Outputs.save_screenshots``; a scene view's
        from the last frame's scene viewport)."""
        return self.outputs.save_screenshots(fbo, scene_only, self.scene_viewport)

    def busy(self) -> bool:
        """Something needs frames although no input arrived (render on demand, ``app/on_demand.py``): news from
        the engine, a view still building its full-resolution image, a video, an open dialog, a screenshot, input
        ImGui has not handed on yet."""
        news = self.engine.news()
        return (news or self.outputs.video_job is not None or self.views.view.building or self.files.dialog is not None
                or bool(self.outputs.screenshot_requests) or imgui_input_pending())

    def close(self, timeout: float = 20.0) -> bool:
        """Stop the engine (it saves the session in the cache folder; killed after ``timeout`` s) and free GL
        objects. Returns False when the engine had to be killed (nothing saved)."""
        self.outputs.close(timeout)
        clean = self.engine.quit(timeout)
        self.undo.forget_results()  # the undo stack ends with the session
        self.views.release()
        self.takes.release()
        return clean
