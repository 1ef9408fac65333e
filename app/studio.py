"""The studio: scene, style and engine state around the renderers, and one frame of it (``StudioApp.frame``).

Its other concerns are mixins in their own modules: opening files (``open_files``), input (``studio_input``),
panel commands, exports and videos (``studio_commands``), per-frame engine and panel updates (``studio_sync``), the
region tool (``region_tool``), the takes (``takes_view``), undo of results (``result_undo``) and the paintings
(``paintings``)."""

from __future__ import annotations

import io
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import moderngl
import numpy as np

from gstyle_core.atomic import atomic_write_bytes
from gstyle_core.cameras.camera import Camera
from gstyle_core.engine.controls import cli_control_names
from gstyle_core.engine.plan import MachineRates
from gstyle_core.style.clip import clip_term_name

from .camera_control import CameraControl
from .edit_history import EditHistory
from .gl_io import read_rgb, target_size
from .keys import KeyPresses
from .open_files import LoadedScene, OpenFiles
from .paintings import Paintings
from .panels import Command, PanelState, draw_panel
from .region_tool import RegionTool
from .renderer import DIFFUSE_LAYER, SH_LAYER, SplatRenderer
from .result_files import ResultInfo, read_result
from .result_undo import ResultUndo
from .scene_view import SceneView, ViewPass
from .splat_data import scene_arrays
from .studio_commands import StudioCommands
from .studio_framing import StudioFraming
from .studio_input import StudioInput, imgui_input_pending
from .studio_sync import StudioSync
from .takes import TakeShelf
from .takes_view import TakesView
from .video_job import VideoJob
from .worker import ThreadWorkerBridge, WorkerBridge

DIVIDER_COLOUR = (1.0, 1.0, 1.0)
BACKGROUND = (0.0, 0.0, 0.0)
IDLE_GAP_S = 0.5


def encode_png(rgb: np.ndarray) -> bytes:
    """uint8 [H, W, 3] -> PNG bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


class StudioApp(RegionTool, TakesView, OpenFiles, StudioInput, StudioCommands, StudioSync, StudioFraming,
                ResultUndo, Paintings):
    """Owns the renderers and the worker bridge; ``frame()`` draws one frame into the current framebuffer."""

    result: ResultInfo | None = None  # the scene shown is a stylized result (set_scene): it opens as one
    save_folder: Path | None = None  # where Ctrl+S writes once Save As chose a place (or --output-dir was given)

    def __init__(self, ctx: moderngl.Context, *, loaded: LoadedScene | None = None, style_path: str | None = None,
                 engine_factory: Callable[..., Any] | None = None, engine_config: dict[str, Any] | None = None,
                 output_dir: str | Path = "out", show_ui: bool = True, worker_mode: str = "process",
                 keys: KeyPresses | None = None) -> None:
        self.ctx = ctx
        self.keys = keys if keys is not None else KeyPresses()  # the window's key presses (app/keys.py)
        self.quit_requested = False  # Ctrl+Q: the frame loop ends as for the window's close button
        self.history = EditHistory()  # Ctrl+Z / Ctrl+Shift+Z over the parameter changes (app/edit_history.py)
        self.worker_mode = worker_mode  # "process" (the default, measured better) or "thread" (bench/ui.py)
        self.original = SplatRenderer(ctx)
        self.stylized = SplatRenderer(ctx)
        self.take_view = SplatRenderer(ctx)  # the take being looked at or compared with (app/takes.py)
        self.take_shown: str | None = None  # its file (None: no take loaded)
        self.view = SceneView(ctx)
        self.progressive = True  # pace the scene render (see app/scene_view.py); False: full frames always
        self.control = CameraControl()
        self.panel = PanelState()
        self.output_dir = Path(output_dir)
        self.takes, self._take_textures = TakeShelf(self.output_dir), {}  # takes and their thumbnails (GL)
        self.compare_with_take = False  # compare view: stylized left, the loaded take (True) or the original right
        self.show_ui = show_ui
        self.view_mode = "stylized"
        self.divider = 0.5  # compare split position, fraction of the width
        self._dragging: str | None = None
        self._last_mouse: tuple[float, float] | None = None
        self._scene_fbo: moderngl.Framebuffer | None = None
        self._style_textures: list[moderngl.Texture | None] = [None, None]  # thumbnails of the first and second style
        self._dialog: tuple[str, Any, str, float] | None = None  # a native file dialog (app/open_files.py)
        self._frame_times: list[float] = []
        self._last_frame = time.perf_counter()
        self._snapshots_seen = 0
        self._geometry_version: Any = None
        self._colour_key: Any = None  # (colour_version, geometry_version) of the colours last uploaded
        self._init_engine(engine_factory, engine_config)
        self.loaded: LoadedScene | None = None
        self.cameras: list[Camera] = []
        self.last_frame_rgb: np.ndarray | None = None
        self.screenshot_requests: list[tuple[Path, bool]] = []  # (where, scene view only), saved by the frame loop
        self.video_job: VideoJob | None = None
        self._exports_seen: tuple[int, int] = (0, 0)
        self._setup_note_seen = ""
        self._export_failures_seen: tuple[int, int] = (0, 0)  # the same for failed exports (their one line)
        self.init_region_state()
        self._view_size: tuple[int, int] = (1, 1)
        self._scene_box: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.ones(3))  # robust box of the centres
        self._framed: tuple[tuple[int, int] | None, int] | None = None  # (view size, camera version) of the framed
        # home pose (``_keep_framed``); None: the home pose is a scene camera's
        self.scene_viewport: tuple[int, int, int, int] | None = None  # the last frame's scene view (GL viewport)
        if loaded is not None:
            self.set_scene(loaded)
        if style_path:
            self.set_style(style_path)

    def _init_engine(self, engine_factory: Callable[..., Any] | None, engine_config: dict[str, Any] | None) -> None:
        """The engine's side of the studio before one starts: its factory and config, no bridge, nothing seen."""
        self.engine_factory = engine_factory
        self.engine_config = dict(engine_config or {})
        self.panel.clip_name = clip_term_name(self.engine_config.get("clip_weights"))
        self.panel.quality = str(self.engine_config.get("preset") or "preview")
        self.bridge: WorkerBridge | None = None
        self._rates: dict[tuple[str, str], MachineRates] = {}  # step rates per (scene, device) (``session_rates``)
        self._bridge_seen: tuple[bool, str | None] | None = None  # (alive, error) last seen by ``busy``
        self._resumed_from: Path | None = None  # the session checkpoint this engine continued from
        self._resume_seen: Any = None  # the last resume report shown in the status line
        self._moving: tuple[str, int] | None = None  # a move to another device asked: the device and the reports
        # received then (its resume report, or a step without one, says how it went on)
        self._resume_probe: tuple[float, Path | None, bool] = (0.0, None, False)  # (time, path, exists)

    # ----------------------------------------------------------------- scene, style, engine
    def set_scene(self, loaded: LoadedScene) -> None:
        """Show a new scene (original with SH, stylized starting from its diffuse colours), frame the view."""
        arrays = scene_arrays(loaded.scene)
        self.original.set_scene(arrays)
        self.stylized.set_scene({k: v for k, v in arrays.items() if k != "sh_rest"})
        self.loaded, self.cameras = loaded, list(loaded.cameras)
        self._geometry_version = self._colour_key = None
        self.panel.scene_path = loaded.path
        self.panel.gaussians = loaded.scene.count
        self.panel.camera_count = len(self.cameras)
        self.panel.camera_names = [c.name or f"camera {i + 1}" for i, c in enumerate(self.cameras)]
        self.panel.camera_index = 0 if self.cameras else -1
        self._frame_scene()
        self.engine_config["scene"] = loaded.path
        self.region_box, self.region_rect_mask, self.region_enabled = None, None, False
        self._region_version += 1
        self.panel.defaults = self._preset_params(with_overrides=False)
        self.panel.params = self._preset_params(with_overrides=True)
        self.panel.switched_off.clear()
        self.result = read_result(loaded.path)  # a stylized result opens as one: no engine starts on it by itself
        p, info = self.panel, self.result
        p.result_line = info.line if info else ""
        p.result_source = (str(info.source or info.source_named)) if info else ""
        p.result_source_found = bool(info and info.source)
        p.result_continuable = bool(info and info.source and info.state)
        if info is not None:
            p.params.update({k: v for k, v in info.params.items() if k in p.params})
            p.phase = "result (nothing running)"
            p.levels, p.width = list(info.levels), (info.levels[-1] if info.levels else 0)  # the result's own

    def _preset_params(self, with_overrides: bool) -> dict[str, float]:
        """The preset's slider values for this scene's kind (``resolve_settings`` + ``ui_params``): what "reset"
        restores, and (``with_overrides``: with the engine config's values) the sliders before the worker reports
        its engine's."""
        from gstyle_core.cameras import classify_scene_kind
        from gstyle_core.engine.settings import resolve_settings, ui_params

        kind = self.engine_config.get("scene_kind", "auto")
        if kind == "auto":
            kind = classify_scene_kind(self.cameras)
        preset = self.engine_config.get("preset") or "preview"
        keys = (*cli_control_names(), "style_weights")  # the engine config's controls (ENGINE_OPTIONS)
        overrides = {k: self.engine_config.get(k) for k in keys} if with_overrides else {}
        overrides["clip_weights"] = self.engine_config.get("clip_weights")  # CLIP or not sets 360° λ_CLIP
        try:
            return ui_params(resolve_settings(preset, kind, max(1, len(self.cameras)),
                                              defaults=self.engine_config.get("defaults"), **overrides))
        except ValueError:  # an unknown preset: the worker reports the error when it starts
            return dict(self.panel.params)

    def session_checkpoint(self) -> Path | None:
        """Where the session of this scene + style is saved when the studio closes (cache folder), or None."""
        from gstyle_core.engine.checkpoint import studio_checkpoint_path

        scene = self.engine_config.get("scene")
        return studio_checkpoint_path(scene, self.engine_config.get("style")) if scene else None

    def resume_available(self) -> bool:
        """True when a saved session of this scene + style exists and this engine did not start from it."""
        now, path = time.monotonic(), self.session_checkpoint()
        when, probed, exists = self._resume_probe
        if probed != path or now - when > 1.0:  # one stat a second at most
            exists = path is not None and path.is_file()
            self._resume_probe = (now, path, exists)
        return exists and self.engine_factory is not None and self._resumed_from != path

    def start_engine(self, resume: bool = False, action: str = "restart", resume_from: Path | None = None) -> bool:
        """Spawn the engine worker with the current scene/style config (restarts it if running; a stylized result
        it replaces is saved first and becomes a step back, ``action`` naming what replaced it).

        ``resume``: continue from the saved session of this scene + style; returns False when there is none (the
        engine then starts afresh). ``resume_from``: continue from that checkpoint instead (a result's kept run).
        Whether the checkpoint fits (same inputs and settings) the worker checks."""
        if self.engine_factory is None:
            return False
        self.keep_result(action)
        self.end_run_status()
        self._region_to_config()
        path = self.session_checkpoint()
        if resume_from is None and resume and path is not None and path.is_file():
            resume_from = path
        self._resumed_from = resume_from
        if self.bridge is None:
            bridge_class = ThreadWorkerBridge if self.worker_mode == "thread" else WorkerBridge
            self.bridge = bridge_class(self.engine_factory, self.engine_config, checkpoint_path=path,
                                       resume_from=resume_from, rates=self.session_rates())
            self.bridge.start()
        else:
            self.bridge.set_checkpoint_path(path)
            self.bridge.rates = self.session_rates()
            self.bridge.restart(self.engine_config, resume_from=resume_from)
        if resume_from is not None:
            what = "the last session" if resume_from == path else "this result's run"
            self.say_of_run(f"resuming {what} ({resume_from.name}) ...")
        self._snapshots_seen = 0
        self._geometry_version = self._colour_key = None  # a new engine counts its versions from 0 again
        p = self.panel  # the run before's progress goes with it (the new run's first report says its own)
        p.phase, p.step, p.total_steps, p.eta_seconds = "starting", 0, 0, None
        return resume_from is not None

    def session_rates(self) -> MachineRates:
        """This machine's step rates for the scene and the device the engine runs with now, kept over the session
        (restarts, other qualities, results opened in between): what the quality choice prices the presets at."""
        key = (str(self.engine_config.get("scene") or ""), str(self.engine_config.get("device") or "auto"))
        return self._rates.setdefault(key, MachineRates())

    def stop_engine(self, timeout: float = 20.0) -> None:
        """Stop the running engine (its session is saved as on close; a stylized result becomes a step back); the
        view keeps what it shows."""
        if self.bridge is not None:
            self.keep_result("stop")
            self.bridge.quit(timeout)
            self.bridge = None
            p = self.panel  # what the stopped run showed goes with it
            p.step, p.total_steps, p.eta_seconds, p.loss_history = 0, 0, None, []
            p.phase = "result (nothing running)" if self.result is not None else "stopped"
            p.summary_line, p.grain, p.refine_note, p.next_width = "", "", "", None
            if self.result is None:  # no run's width to show (a result on show shows its own, set_scene)
                p.width, p.levels = 0, []
            self.end_run_status()

    def close(self, timeout: float = 20.0) -> bool:
        """Stop the engine (it saves the session in the cache folder; killed after ``timeout`` s) and free GL
        objects. Returns False when the engine had to be killed (nothing saved)."""
        clean = True
        if self.video_job is not None:  # a half-rendered video is dropped (nothing is written)
            self.video_job.cancel()
            self.video_job.join(timeout)
        if self.bridge is not None:
            clean = self.bridge.quit(timeout)
        self.forget_results()  # the undo stack ends with the session
        self.view.release()
        self.original.release()
        self.stylized.release()
        self.take_view.release()
        for texture in self._take_textures.values():
            if texture is not None:
                texture.release()
        return clean

    # ----------------------------------------------------------------- per frame
    def frame(self, target: moderngl.Framebuffer, with_ui: bool = True) -> list[Command]:
        """Update from the engine, handle input, render the scene into ``target`` and (if with_ui) build the UI.

        The scene is laid out in the part of ``target`` beside the docked panel (``view_rect``): the whole of it
        when the panel is collapsed or hidden. The caller has started the ImGui frame (when with_ui) and renders
        ImGui afterwards.
        """
        now = time.perf_counter()
        dt, self._last_frame = now - self._last_frame, now
        if dt < IDLE_GAP_S:  # a gap after waiting for events (render on demand) is not a frame time
            self._frame_times = (self._frame_times + [dt])[-60:]
        self._apply_engine_updates()
        self._apply_selection()
        self._poll_dialog()
        commands: list[Command] = []
        full = tuple(target.viewport)
        view = self.view_rect(full, with_ui)
        self._view_size = (view[2], view[3])
        presses = self.keys.take()  # taken every frame: a press acts in the frame after it, or never
        if with_ui:
            self._handle_input(view, dt)
            self._fill_panel()
            if self.show_ui:
                commands = draw_panel(self.panel, presses)
            for cmd in commands:
                self.execute(cmd)
            view = self.view_rect(full, with_ui)  # the panel may have collapsed or opened this frame
            self._view_size = (view[2], view[3])
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

    def render_view(self, target: moderngl.Framebuffer) -> None:
        """Show the current view mode in ``target`` (its viewport), paced by ``SceneView`` (app/scene_view.py)."""
        width, height = target_size(target)
        self._keep_framed((width, height))
        camera = self.control.camera(width, height)
        if self.original.count == 0:
            target.use()
            target.clear(*BACKGROUND, 1.0)
            return
        mode = self.view_mode
        divider = float(np.clip(self.divider, 0.0, 1.0))
        take = self.take_shown is not None and self.take_view.count > 0
        if mode == "original":
            passes = [ViewPass(self.original, self._original_layer())]
        elif mode == "ground truth" and "gt" in self.stylized.layers:
            passes = [ViewPass(self.stylized, "gt")]
        elif mode == "take" and take:
            passes = [ViewPass(self.take_view, self._take_layer())]
        elif mode == "compare":
            right = (self.take_view, self._take_layer()) if take and self.compare_with_take else (
                self.original, self._original_layer())
            passes = [ViewPass(self.stylized, DIFFUSE_LAYER, 0.0, divider), ViewPass(*right, divider, 1.0)]
        else:
            passes = [ViewPass(self.stylized, DIFFUSE_LAYER)]
        # Screenshots and the last frame of a --frames run show the exact current state at full resolution.
        self.view.progressive = self.progressive and not self.screenshot_requests
        mode_key = (mode, divider, tuple(p.layer for p in passes), tuple(id(p.renderer) for p in passes))
        self.view.draw(target, camera, passes, mode_key, BACKGROUND)
        if mode == "compare":
            x0, y0 = target.viewport[:2]
            split = int(round(divider * width))
            self.ctx.scissor = (x0 + max(split - 1, 0), y0, 2, height)
            target.clear(*DIVIDER_COLOUR, 1.0)
            self.ctx.scissor = None

    def busy(self) -> bool:
        """Something needs frames although no input arrived (render on demand, ``app/on_demand.py``): news from
        the engine, a view still building its full-resolution image, a video, an open dialog, a screenshot, input
        ImGui has not handed on yet."""
        news = False
        if self.bridge is not None:
            news = bool(self.bridge.poll())
            key = (self.bridge.state.alive, self.bridge.state.error)
            news, self._bridge_seen = news or key != self._bridge_seen, key
        video = self.video_job is not None
        return (news or video or self.view.building or self._dialog is not None or bool(self.screenshot_requests)
                or imgui_input_pending())

    def _original_layer(self) -> str:
        return SH_LAYER if SH_LAYER in self.original.layers else DIFFUSE_LAYER

    def _take_layer(self) -> str:
        return SH_LAYER if SH_LAYER in self.take_view.layers else DIFFUSE_LAYER

    # ----------------------------------------------------------------- output
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

    def save_screenshots(self, fbo: moderngl.Framebuffer, scene_only: bool) -> list[Path]:
        """Write the requested screenshots of one kind from ``fbo``: ``scene_only`` ones after the frame's scene was
        drawn and before the UI is (the scene view's part of it), whole-window ones after the UI. The status line
        says where each went (or why it could not be written); returns the paths written."""
        written, left = [], []
        for path, scene in self.screenshot_requests:
            if scene != scene_only:
                left.append((path, scene))
                continue
            viewport = self.scene_viewport if scene_only else None
            try:
                written.append(self.save_png(path, self.capture(fbo, viewport)))
                self.panel.status = f"screenshot {written[-1]}"
            except OSError as exc:  # OutputWriteError: "cannot write PATH: no space left on the device"
                self.panel.status = f"screenshot: {exc}"
        self.screenshot_requests = left
        return written
