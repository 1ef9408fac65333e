"""The studio: scene + engine state, view modes, input handling and command execution around the renderers."""

from __future__ import annotations

import io
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import moderngl
import numpy as np
from imgui_bundle import imgui

from gstyle_core.atomic import atomic_write_bytes
from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import GStyleError
from gstyle_core.pipeline.controls import cli_control_names, painting_controls
from gstyle_core.scene import GaussianScene
from gstyle_core.style.clip import clip_term_name

from .camera_control import CameraControl
from .panels import Command, PanelState, draw_panel
from .region_tool import RegionTool
from .renderer import DIFFUSE_LAYER, SH_LAYER, SplatRenderer, read_rgb, target_size
from .scene_view import SceneView, ViewPass
from .splat_data import scene_arrays
from .takes import TakeShelf
from .takes_view import TakesView
from .video_job import VideoJob, turntable_path
from .worker import GEOMETRY_FIELDS, ThreadWorkerBridge, WorkerBridge

SCENE_SUFFIXES = (".ply", ".splat", ".spz")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tif", ".tiff")
BOX_WHEEL_STEP = 1.1  # Alt + one wheel notch resizes the region box by this factor
DIVIDER_GRAB_PIXELS = 6
DIVIDER_COLOUR = (1.0, 1.0, 1.0)
BACKGROUND = (0.0, 0.0, 0.0)
EXPORT_SUFFIXES = {"ply": ".ply", "spz": ".spz", "compressed-ply": ".compressed.ply"}
TURNTABLE_WIDTH = 640


@dataclass
class LoadedScene:
    """The scene being stylized, with the cameras that came with it (or were generated)."""

    path: str
    scene: GaussianScene
    cameras: list[Camera]


def load_scene_with_cameras(scene_path: str | None, cameras_path: str | None) -> LoadedScene:
    """Load a scene file (default: the bundled demo) and its cameras (given, else generated)."""
    from gstyle_core.render_cli import DEMO_SCENE, load_scene_and_cameras

    path = Path(scene_path) if scene_path else DEMO_SCENE
    if not path.exists():
        what = "scene file" if scene_path else "bundled demo scene"
        raise GStyleError(f"{what} not found: {path}")
    scene, _report, cams = load_scene_and_cameras(scene_path, cameras_path)
    return LoadedScene(str(scene_path or DEMO_SCENE), scene, list(cams.cameras))


def encode_png(rgb: np.ndarray) -> bytes:
    """uint8 [H, W, 3] -> PNG bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


class StudioApp(RegionTool, TakesView):
    """Owns the renderers and the worker bridge; ``frame()`` draws one frame into the current framebuffer."""

    def __init__(self, ctx: moderngl.Context, *, loaded: LoadedScene | None = None, style_path: str | None = None,
                 engine_factory: Callable[..., Any] | None = None, engine_config: dict[str, Any] | None = None,
                 output_dir: str | Path = "out", show_ui: bool = True, worker_mode: str = "process") -> None:
        self.ctx = ctx
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
        self.takes = TakeShelf(self.output_dir)
        self.compare_with_take = False  # compare view: stylized left, the loaded take (True) or the original right
        self.show_ui = show_ui
        self.view_mode = "stylized"
        self.divider = 0.5  # compare split position, fraction of the width
        self._dragging: str | None = None
        self._last_mouse: tuple[float, float] | None = None
        self._scene_fbo: moderngl.Framebuffer | None = None
        self._style_textures: list[moderngl.Texture | None] = [None, None]  # thumbnails of the first and second style
        self._dialog: tuple[str, Any] | None = None
        self._frame_times: list[float] = []
        self._last_frame = time.perf_counter()
        self._snapshots_seen = 0
        self._geometry_version: Any = None
        self._colour_key: Any = None  # (colour_version, geometry_version) of the colours last uploaded
        self.engine_factory = engine_factory
        self.engine_config = dict(engine_config or {})
        self.panel.clip_name = clip_term_name(self.engine_config.get("clip_weights"))
        self.bridge: WorkerBridge | None = None
        self._resumed_from: Path | None = None  # the session checkpoint this engine continued from
        self._resume_seen: Any = None  # the last resume report shown in the status line
        self._resume_probe: tuple[float, Path | None, bool] = (0.0, None, False)  # (time, path, exists)
        self.loaded: LoadedScene | None = None
        self.cameras: list[Camera] = []
        self.last_frame_rgb: np.ndarray | None = None
        self.screenshot_requests: list[Path] = []
        self.video_job: VideoJob | None = None
        self._exports_seen: tuple[int, int] = (0, 0)
        # Selection tool (issue #15 item 4): a box in scene coordinates or a screen rectangle's mask of the input's
        # Gaussians; highlighted in both renderers; handed to the engine when it (re)starts.
        self.region_enabled = False
        self.region_box: tuple[float, ...] | None = None
        self.region_rect_mask: np.ndarray | None = None  # the last rectangle's selection (mode "rectangle")
        self._region_version = 0
        self._box_mask_cache: tuple[tuple, np.ndarray] | None = None  # (scene and box, its selection)
        self._selection_shown: dict[str, Any] = {}
        self._rect_start: tuple[float, float] | None = None
        self._view_size: tuple[int, int] = (1, 1)
        self.engine_region: str = ""
        if loaded is not None:
            self.set_scene(loaded)
        if style_path:
            self.set_style(style_path)

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
        self.region_box, self.region_rect_mask = None, None
        self._region_version += 1
        self.panel.defaults = self._preset_params(with_overrides=False)
        self.panel.params = self._preset_params(with_overrides=True)
        self.panel.switched_off.clear()

    def _preset_params(self, with_overrides: bool) -> dict[str, float]:
        """The preset's slider values for this scene's kind (``resolve_settings`` + ``ui_params``): what "reset"
        restores, and (``with_overrides``: with the engine config's values) the sliders before the worker reports
        its engine's."""
        from gstyle_core.cameras import classify_scene_kind
        from gstyle_core.pipeline.settings import resolve_settings, ui_params

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

    def _frame_scene(self) -> None:
        from gstyle_core.cameras.generate import finite_points, robust_centre_radius

        centre, radius = robust_centre_radius(finite_points(self.loaded.scene.means))
        if self.cameras:
            cam = self.cameras[0]
            self.control.snap_to(cam, float(np.linalg.norm(cam.position - centre)))
            self.control.home = self.control.pose.copy()
            self.control.fly_speed = max(radius, 1e-3)
        else:
            self.control.frame(centre, radius)

    def set_style(self, path: str, slot: int = 0, mix: float | None = None) -> None:
        """Use a new style image (``slot`` 0: the painting; 1: a second painting mixed in with the mix slider, at
        ``mix``, by default the slider's value or an even mix): thumbnail in the panel; the caller restarts the
        engine with it."""
        from gstyle_core.images import load_style_image

        rgb = load_style_image(path)
        thumb = np.ascontiguousarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8))
        self._release_style_texture(slot)
        h, w = thumb.shape[:2]
        texture = self.ctx.texture((w, h), 3, thumb.tobytes(), alignment=1)
        self._style_textures[slot] = texture
        if slot == 0:
            self.panel.style_texture, self.panel.style_size, self.panel.style_path = texture.glo, (w, h), str(path)
        else:
            self.panel.style2_texture, self.panel.style2_size, self.panel.style2_path = texture.glo, (w, h), str(path)
            if mix is not None:
                self.panel.params["style_mix"] = float(mix)
            elif not self.panel.params.get("style_mix"):  # a new second painting starts at an even mix
                self.panel.params["style_mix"] = 0.5
        self._update_style_config()

    def remove_second_style(self) -> None:
        """Back to one painting (the caller restarts the engine)."""
        self._release_style_texture(1)
        self.panel.style2_texture, self.panel.style2_path = None, ""
        self.panel.params["style_mix"] = 0.0
        self._update_style_config()

    def _release_style_texture(self, slot: int) -> None:
        if self._style_textures[slot] is not None:
            self._style_textures[slot].release()
            self._style_textures[slot] = None

    def _update_style_config(self) -> None:
        """The engine config's style: the painting's path, or both paths with their weights (the mix slider)."""
        p = self.panel
        if p.style2_path and p.style_path:
            mix = float(p.params.get("style_mix", 0.5))
            self.engine_config["style"] = [p.style_path, p.style2_path]
            self.engine_config["style_weights"] = (1.0 - mix, mix)
        else:
            self.engine_config["style"] = p.style_path or None
            self.engine_config.pop("style_weights", None)

    def session_checkpoint(self) -> Path | None:
        """Where the session of this scene + style is saved when the studio closes (cache folder), or None."""
        from gstyle_core.pipeline.checkpoint import studio_checkpoint_path

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

    def start_engine(self, resume: bool = False) -> bool:
        """Spawn the engine worker with the current scene/style config (restarts it if running).

        ``resume``: continue from the saved session of this scene + style; returns False when there is none (the
        engine then starts afresh). Whether the checkpoint fits (same inputs and settings) the worker checks."""
        if self.engine_factory is None:
            return False
        self._region_to_config()
        path = self.session_checkpoint()
        resume_from = path if resume and path is not None and path.is_file() else None
        self._resumed_from = resume_from
        if self.bridge is None:
            bridge_class = ThreadWorkerBridge if self.worker_mode == "thread" else WorkerBridge
            self.bridge = bridge_class(self.engine_factory, self.engine_config, checkpoint_path=path,
                                       resume_from=resume_from)
            self.bridge.start()
        else:
            self.bridge.set_checkpoint_path(path)
            self.bridge.restart(self.engine_config, resume_from=resume_from)
        if resume_from is not None:
            self.panel.status = f"resuming the last session ({resume_from.name}) ..."
        self._snapshots_seen = 0
        self._geometry_version = self._colour_key = None  # a new engine counts its versions from 0 again
        return resume_from is not None

    def close(self, timeout: float = 20.0) -> bool:
        """Stop the engine (it saves the session in the cache folder; killed after ``timeout`` s) and free GL
        objects. Returns False when the engine had to be killed (nothing saved)."""
        clean = True
        if self.video_job is not None:  # a half-rendered video is dropped (nothing is written)
            self.video_job.cancel()
            self.video_job.join(timeout)
        if self.bridge is not None:
            clean = self.bridge.quit(timeout)
        self.view.release()
        self.original.release()
        self.stylized.release()
        self.take_view.release()
        return clean

    # ----------------------------------------------------------------- per frame
    def frame(self, target: moderngl.Framebuffer, with_ui: bool = True) -> list[Command]:
        """Update from the engine, handle input, render the scene into ``target`` and (if with_ui) build the UI.

        The caller has started the ImGui frame (when with_ui) and renders ImGui afterwards.
        """
        now = time.perf_counter()
        dt, self._last_frame = now - self._last_frame, now
        self._frame_times = (self._frame_times + [dt])[-60:]
        self._apply_engine_updates()
        self._apply_selection()
        self._poll_dialog()
        commands: list[Command] = []
        self._view_size = target_size(target)
        if with_ui:
            self._handle_input(target_size(target), dt)
            self._fill_panel()
            if self.show_ui:
                commands = draw_panel(self.panel)
            for cmd in commands:
                self.execute(cmd)
        self.render_view(target)
        return commands

    def render_view(self, target: moderngl.Framebuffer) -> None:
        """Show the current view mode in ``target`` (its viewport), paced by ``SceneView`` (app/scene_view.py)."""
        width, height = target_size(target)
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
            split = int(round(divider * width))
            self.ctx.scissor = (max(split - 1, 0), 0, 2, height)
            target.clear(*DIVIDER_COLOUR, 1.0)
            self.ctx.scissor = None

    def _original_layer(self) -> str:
        return SH_LAYER if SH_LAYER in self.original.layers else DIFFUSE_LAYER

    def _take_layer(self) -> str:
        return SH_LAYER if SH_LAYER in self.take_view.layers else DIFFUSE_LAYER

    def _apply_engine_updates(self) -> None:
        if self.bridge is None:
            return
        self.bridge.poll()
        st = self.bridge.state
        if st.snapshots_received == self._snapshots_seen or not st.snapshot:
            return
        self._snapshots_seen = st.snapshots_received
        snap = st.snapshot
        try:  # upload only what changed: geometry by its version, colours by theirs (c_gt changes with geometry)
            new_geometry = snap.get("geometry_version") != self._geometry_version and "means" in snap
            if new_geometry:
                self.stylized.update_geometry(snap)
                self._geometry_version = snap.get("geometry_version")
            colour_key = (snap.get("colour_version"), self._geometry_version)
            new_colours = colour_key != self._colour_key or colour_key[0] is None
            if new_colours and "colors" in snap and len(snap["colors"]) == self.stylized.count:
                self.stylized.update_colors(snap["colors"], DIFFUSE_LAYER)
                self._colour_key = colour_key
            gt_stale = new_geometry or "gt" not in self.stylized.layers or self._geometry_version is None
            if gt_stale and "colors_gt" in snap and len(snap["colors_gt"]) == self.stylized.count:
                self.stylized.update_colors(snap["colors_gt"], "gt")
        except ValueError as exc:
            self.panel.status = f"snapshot ignored: {exc}"

    def _fill_panel(self) -> None:
        p = self.panel
        p.fps = len(self._frame_times) / max(sum(self._frame_times), 1e-6)
        p.view_mode = self.view_mode
        p.fov_deg = self.control.pose.fov_y_deg
        p.has_ground_truth = "gt" in self.stylized.layers
        p.gaussians = self.stylized.count
        p.viewer_notes = self.viewer_notes()
        p.resume_available = self.resume_available()
        p.take_names = [t.name for t in self.takes.takes]
        p.take_labels = [t.label for t in self.takes.takes]
        shown = [i for i, t in enumerate(self.takes.takes) if t.path == self.take_shown]
        p.take_shown = shown[0] if shown else -1
        p.compare_with_take = self.compare_with_take and p.take_shown >= 0
        p.divider = float(self.divider)
        p.region_enabled = self.region_enabled
        mask = self.region_mask()
        p.region_mode = "rectangle" if self.region_rect_mask is not None else "box"
        if self.region_box is not None:
            p.region_box = tuple(self.region_box)
        p.region_selected = int(mask.sum()) if mask is not None else 0
        p.region_total = self.loaded.scene.count if self.loaded is not None else 0
        p.region_in_engine = self.engine_region if self.bridge is not None else ""
        width, height = self._view_size
        p.region_outline = self._region_outline(width, height)
        self._poll_video()
        if self.bridge is None:
            p.running, p.paused = False, False
            return
        st = self.bridge.state
        p.running, p.paused, p.error = st.alive, st.paused, st.error
        p.decisions = st.decisions
        p.loss_history = st.loss_history[-500:]
        if st.params:
            p.params.update(st.params)
        rep = st.last_report
        if rep:
            p.phase = "done" if st.done else str(rep.get("phase", "-"))
            p.step, p.total_steps = int(rep.get("step", 0)), int(rep.get("total_steps", 0))
            p.eta_seconds = (st.step_seconds / max(st.reports_received, 1) * max(p.total_steps - p.step, 0)
                             if st.reports_received and not st.done else None)
        if st.resumed is not None and st.resumed is not self._resume_seen:
            self._resume_seen = st.resumed
            p.status = f"resumed the last session at step {st.resumed.get('step')}"
        exports = (id(st.exported), len(st.exported))  # a restarted worker starts a new list
        if st.exported and exports != self._exports_seen:  # once per export: later messages stay visible
            new = st.exported[self._exports_seen[1]:] if exports[0] == self._exports_seen[0] else st.exported[-1:]
            self._exports_seen = exports
            self._shelve_exports(new)
            p.status = f"exported {st.exported[-1]} (kept as {self.takes.takes[0].name})"

    def viewer_notes(self) -> list[str]:
        """What the viewer evaluates and skips (panel "Decisions"): view-dependent SH, sorts, uploads."""
        renderers = (self.original, self.stylized)
        if SH_LAYER in self.original.layers:
            sh = (f"viewer SH: evaluated for the original scene only, when the camera position changes "
                  f"({self.original.sh_evaluations} evaluations so far); the stylized scene is diffuse")
        else:
            sh = "viewer SH: none evaluated (the scene has no view-dependent SH)"
        sorts = sum(r.sort_count for r in renderers)
        colours = sum(r.uploads["colors"] for r in renderers)
        geometry = sum(r.uploads["geometry"] for r in renderers)
        return [sh, f"viewer work: {sorts} depth sorts (view changes only), {colours} colour and {geometry} "
                    "geometry uploads (changes only)"]

    # ----------------------------------------------------------------- input
    def _handle_input(self, size: tuple[int, int], dt: float) -> None:
        io_ = imgui.get_io()
        width, height = size
        mouse = (io_.mouse_pos.x, io_.mouse_pos.y)
        scale = io_.display_framebuffer_scale
        fb_mouse = (mouse[0] * (scale.x or 1.0), mouse[1] * (scale.y or 1.0))
        if self._dragging == "select" and not imgui.is_mouse_down(0):  # released: select what the rectangle holds
            start, self._rect_start = self._rect_start, None
            self.panel.region_drag = None
            if start is not None and abs(fb_mouse[0] - start[0]) >= 2 and abs(fb_mouse[1] - start[1]) >= 2:
                self.select_rectangle((*start, *fb_mouse), width, height)
        if not io_.want_capture_mouse:
            divider_x = self.divider * width
            if imgui.is_mouse_clicked(0) and io_.key_shift and self.loaded is not None:
                self._dragging, self._rect_start = "select", fb_mouse
                self.region_enabled = True
            elif imgui.is_mouse_clicked(0) and io_.key_alt and self._box_tool_on():
                self._dragging = "box"  # Alt + drag: place the region box in the view
            elif imgui.is_mouse_clicked(0):
                near_divider = self.view_mode == "compare" and abs(mouse[0] - divider_x) <= DIVIDER_GRAB_PIXELS
                self._dragging = "divider" if near_divider else "orbit"
            elif imgui.is_mouse_clicked(1):
                self._dragging = "pan"
            if io_.mouse_wheel and io_.key_alt and self._box_tool_on():  # Alt + wheel: resize the box
                self.scale_region_box(BOX_WHEEL_STEP ** io_.mouse_wheel)
            elif io_.mouse_wheel:
                self.control.zoom(io_.mouse_wheel)
        if not (imgui.is_mouse_down(0) or imgui.is_mouse_down(1)):
            self._dragging = None
        if self._dragging and self._last_mouse is not None:
            dx, dy = mouse[0] - self._last_mouse[0], mouse[1] - self._last_mouse[1]
            if self._dragging == "divider":
                self.divider = float(np.clip(mouse[0] / max(width, 1), 0.0, 1.0))
            elif self._dragging == "orbit" and (dx or dy):
                self.control.orbit(dx, dy)
            elif self._dragging == "pan" and (dx or dy):
                self.control.pan(dx, dy, height)
            elif self._dragging == "box" and (dx or dy):
                self.move_region_box(dx * (scale.x or 1.0), dy * (scale.y or 1.0), width, height)
            elif self._dragging == "select" and self._rect_start is not None:
                sx, sy = scale.x or 1.0, scale.y or 1.0
                self.panel.region_drag = (self._rect_start[0] / sx, self._rect_start[1] / sy, *mouse)
        self._last_mouse = mouse
        if not io_.want_capture_keyboard and not io_.key_ctrl:
            down = imgui.is_key_down
            forward = float(down(imgui.Key.w)) - float(down(imgui.Key.s))
            right = float(down(imgui.Key.d)) - float(down(imgui.Key.a))
            up = float(down(imgui.Key.e)) - float(down(imgui.Key.q))
            self.control.fly(forward, right, up, min(dt, 0.1))

    # ----------------------------------------------------------------- commands
    def execute(self, cmd: Command) -> None:
        """Carry out one panel command."""
        name, args = cmd.name, cmd.args
        bridge = self.bridge
        if name in ("pause", "resume", "step") and bridge is not None:
            {"pause": bridge.pause, "resume": bridge.resume, "step": bridge.step_once}[name]()
        elif name == "restart":
            self.start_engine()
        elif name == "resume_session":
            self.start_engine(resume=True)
        elif name == "set_params":
            self.panel.params.update(args)
            if painting_controls() & args.keys() and self.panel.style2_path:  # a restarted engine keeps the mix
                self._update_style_config()
            if bridge is not None:
                bridge.set_params(**args)
        elif name == "remove_style2":
            self.remove_second_style()
            self.panel.status = "back to one painting"
            if bridge is not None:
                self.start_engine()
        elif name == "view_mode":
            self.view_mode = args["mode"]
        elif name == "fov":
            self.control.set_fov(args["degrees"])
        elif name == "reset_camera":
            self.control.reset()
        elif name == "snap_camera" and args["index"] < len(self.cameras):
            cam = self.cameras[args["index"]]
            self.control.snap_to(cam)
            self.panel.camera_index = args["index"]
            self.panel.status = f"camera {args['index'] + 1}: {cam.name}"
        elif name == "region_enable":
            self.region_enabled = bool(args.get("on", True))
            self._region_version += 1
        elif name == "region_box":
            self.set_region_box(args["box"])
        elif name == "region_fit":
            self.set_region_box(self.scene_box())
        elif name == "toggle_help":
            self.panel.show_help = not self.panel.show_help
        elif name == "screenshot":
            self.screenshot_requests.append(self.output_dir / f"screenshot_{time.strftime('%Y%m%d_%H%M%S')}.png")
        elif name == "export":
            self.export(fmt=args.get("format", "ply"))
        elif name == "turntable":
            self.start_turntable(args.get("frames", self.panel.turntable_frames),
                                 args.get("format", self.panel.turntable_format))
        elif name == "turntable_settings":
            self.panel.turntable_frames = int(args.get("frames", self.panel.turntable_frames))
            self.panel.turntable_format = str(args.get("format", self.panel.turntable_format))
        elif name == "cancel_video" and self.video_job is not None:
            self.video_job.cancel()
        elif name == "show_take":
            self.show_take(int(args["index"]), compare=bool(args.get("compare", True)))
        elif name == "compare_original":
            self.compare_with_original()
        elif name == "rename_take":
            self.takes.rename(int(args["index"]), str(args["name"]))
        elif name == "forget_take":
            self.forget_take(int(args["index"]))
        elif name in ("open_scene", "open_style", "open_style2"):
            self._open_dialog(name)

    def export(self, path: str | Path | None = None, fmt: str = "ply") -> None:
        """Export the stylized scene (``fmt`` "ply", "spz" or "compressed-ply", + .json) through the worker."""
        if self.bridge is None or not self.bridge.alive:
            self.panel.status = "export: no engine is running"
            return
        suffix = EXPORT_SUFFIXES[fmt]
        path = Path(path) if path else self.output_dir / f"stylized_{time.strftime('%Y%m%d_%H%M%S')}{suffix}"
        self.bridge.export(path)
        self.panel.status = f"exporting {path} ..."

    def current_scene(self) -> GaussianScene | None:
        """The stylized scene as the engine last sent it (diffuse colours), else the loaded scene (with its SH)."""
        snap = self.bridge.state.snapshot if self.bridge is not None else {}
        if all(k in snap for k in GEOMETRY_FIELDS) and len(snap.get("colors", ())) == len(snap["means"]):
            from gstyle_core.scene import rgb_to_sh_dc

            arrays = [np.asarray(snap[k], np.float32) for k in GEOMETRY_FIELDS]
            return GaussianScene(*arrays, rgb_to_sh_dc(np.asarray(snap["colors"], np.float32)))
        return self.loaded.scene if self.loaded is not None else None

    def start_turntable(self, frames: int, fmt: str = "mp4", path: str | Path | None = None) -> Path | None:
        """Render a turntable of the current scene into the output folder in the background (``VideoJob``);
        the panel shows its progress. Returns where it will be written (None when it cannot start)."""
        from gstyle_core.render_video import cameras_up, turntable_cameras

        scene = self.current_scene()
        if scene is None or scene.count == 0:
            self.panel.status = "turntable: no scene"
            return None
        if self.video_job is not None and self.video_job.running:
            self.panel.status = "turntable: a video is already rendering"
            return None
        size = (TURNTABLE_WIDTH, TURNTABLE_WIDTH * 3 // 4)
        if self.cameras:  # the scene cameras' aspect and the way they stand
            first = self.cameras[0].resized_to_width(TURNTABLE_WIDTH)
            size = (first.width, first.height)
        up = cameras_up(self.cameras) if self.cameras else "-y"
        try:
            cams = turntable_cameras(scene, int(frames), *size, up=up)
        except GStyleError as exc:
            self.panel.status = f"turntable: {exc}"
            return None
        out = Path(path) if path else turntable_path(self.output_dir, fmt, time.strftime("%Y%m%d_%H%M%S"))
        self.video_job = VideoJob(scene, cams, out, in_thread=self.worker_mode == "thread")
        self.panel.status = f"rendering {out.name} ({len(cams)} frames) ..."
        return out

    def _poll_video(self) -> None:
        p, job = self.panel, self.video_job
        if job is None:
            p.video_running = False
            return
        progress = job.poll()
        p.video_running = job.running
        p.video_fraction = progress.fraction
        p.video_label = f"video {progress.done}/{progress.total}"
        if not job.running:
            p.status = progress.message
            self.video_job = None

    def on_drop(self, paths) -> None:
        """glfw drop callback: open the first dropped file (a scene or a style image); more files are ignored."""
        paths = list(paths)
        if paths:
            self.open_path(paths[0])
            if len(paths) > 1:
                self.panel.status += f" ({len(paths) - 1} more dropped file(s) ignored)"

    def open_path(self, path: str, style_slot: int = 0) -> None:
        """Open a dropped or chosen file: a scene (.ply/.splat/.spz) or a style image (``style_slot`` 1: as the second
        painting of a mix)."""
        suffix = Path(path).suffix.lower()
        try:
            if suffix in SCENE_SUFFIXES and style_slot == 0:
                self.set_scene(load_scene_with_cameras(path, None))
            elif suffix in IMAGE_SUFFIXES:
                self.set_style(path, style_slot)
            else:
                self.panel.status = f"not a scene or image: {Path(path).name}"
                return
        except GStyleError as exc:
            self.panel.status = f"could not open {Path(path).name}: {exc}"
            return
        self.panel.status = f"opened {Path(path).name}"
        if self.bridge is not None:
            self.start_engine()

    def _open_dialog(self, kind: str) -> None:
        try:
            from imgui_bundle import portable_file_dialogs as pfd
        except ImportError:
            self.panel.status = "file dialogs unavailable; drop a file on the window"
            return
        if kind == "open_scene":
            dialog = pfd.open_file("Open scene", "", ["Gaussian scenes", "*.ply *.splat *.spz"])
        else:
            title = "Open second style image" if kind == "open_style2" else "Open style image"
            dialog = pfd.open_file(title, "", ["Images", "*.png *.jpg *.jpeg *.webp *.bmp"])
        self._dialog = (kind, dialog)

    def _poll_dialog(self) -> None:
        if self._dialog is None or not self._dialog[1].ready(0):
            return
        kind, dialog = self._dialog
        self._dialog = None
        for path in dialog.result()[:1]:
            self.open_path(path, style_slot=1 if kind == "open_style2" else 0)

    # ----------------------------------------------------------------- output
    def save_png(self, path: str | Path, rgb: np.ndarray) -> Path:
        """Write uint8 [H, W, 3] as PNG atomically."""
        atomic_write_bytes(path, encode_png(rgb))
        return Path(path)

    def capture(self, fbo: moderngl.Framebuffer) -> np.ndarray:
        """Read ``fbo`` as uint8 RGB (row 0 = top); clears a GL error the default framebuffer read may leave."""
        rgb = read_rgb(fbo)
        _ = self.ctx.error
        return rgb

