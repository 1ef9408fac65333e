"""Where the scene sits in the studio's window: the view beside the docked panel, and the home pose that frames the
scene in it ("frame all", F; R), the camera commands. ``Framing`` is a part of ``StudioApp``."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from imgui_bundle import imgui

from gstyle_core.cameras.camera import Camera

from .camera_control import CameraControl
from .events import Events, Handlers, SceneShown
from .panels import PanelState
from .status_line import StatusLine

if TYPE_CHECKING:
    from .open_files import LoadedScene

MIN_VIEW_WIDTH = 64  # the view keeps at least this many pixels beside the panel


def framebuffer_scale() -> tuple[float, float]:
    """Framebuffer pixels per window coordinate (1, 1 without an ImGui context or for a scale ImGui left at 0)."""
    if imgui.get_current_context() is None:
        return 1.0, 1.0
    scale = imgui.get_io().display_framebuffer_scale
    return (scale.x if scale.x > 0 else 1.0), (scale.y if scale.y > 0 else 1.0)


class Framing:
    """The scene's view rectangle and its framing: owns the scene's robust box, the framed home pose's key and the
    view's size. Built with the panel, the status line, the camera control it frames, ``cameras`` (the scene's: the
    session's) and the events (a new scene is framed and its cameras listed in the panel)."""

    def __init__(self, panel: PanelState, status: StatusLine, control: CameraControl,
                 cameras: Callable[[], list[Camera]], events: Events) -> None:
        self.panel, self.status, self.control, self.cameras = panel, status, control, cameras
        self.view_size: tuple[int, int] = (1, 1)
        self._scene_box: tuple[np.ndarray, np.ndarray] | None = None  # robust box of the centres (None: no scene)
        self._framed: tuple[tuple[int, int] | None, int] | None = None  # (view size, camera version) of the framed
        # home pose (``keep_framed``); None: the home pose is a scene camera's
        events.subscribe(SceneShown, self._scene_shown)

    def _scene_shown(self, event: SceneShown) -> None:
        """A new scene: its cameras in the panel, the view framed on it."""
        cameras = list(event.loaded.cameras)
        p = self.panel
        p.camera_count = len(cameras)
        p.camera_names = [c.name or f"camera {i + 1}" for i, c in enumerate(cameras)]
        p.camera_index = 0 if cameras else -1
        self._frame_scene(event.loaded, cameras)

    def _frame_scene(self, loaded: LoadedScene, cameras: list[Camera]) -> None:
        """Home pose. A scene with cameras of its own: the first one's viewpoint, levelled to the scene's up axis
        (estimated from the cameras), orbiting the scene's centre. A bare scene file (generated cameras, or none):
        the whole scene framed in the view ("frame all", ``frame_all``) from the first generated camera's side, and
        kept framed while the view changes size and the camera has not moved (``keep_framed``); a stylized result
        of one frames its input's box (recorded in its OUT.json), as its input was framed."""
        from gstyle_core.cameras.framing import scene_box
        from gstyle_core.cameras.generate import finite_points, robust_centre_radius
        from gstyle_core.cameras.up import estimate_up

        self._scene_box = getattr(loaded, "frame_box", None) or scene_box(loaded.scene.means)
        centre, radius = robust_centre_radius(finite_points(loaded.scene.means))
        self.control.world_up = estimate_up(cameras)
        if cameras and not loaded.generated_cameras:
            cam = cameras[0]
            self.control.snap_to(cam, float(np.linalg.norm(cam.position - centre)))
            self.control.home = self.control.pose.copy()
            self.control.set_up(self.control.world_up)
            self.control.fly_speed = max(radius, 1e-3)
            self._framed = None
            return
        if cameras:
            self.control.snap_to(cameras[0])  # its side and field of view
        else:
            self.control.frame(centre, radius)  # a side view
        self.frame_all(home=True)
        self._framed = (None, self.control.version)  # framed again for the view's size when it is first drawn

    def frame_all(self, home: bool = False, size: tuple[int, int] | None = None) -> None:
        """Frame the whole scene (its robust box) in the view (``size``: default the last frame's) from the current
        viewing direction, with a margin on every side (F); ``home``: as the home pose (R)."""
        if self._scene_box is None:
            return
        size = size or self.view_size
        self.control.frame_box(*self._scene_box, *size, set_home=home)
        if home:
            self._framed = (size, self.control.version)

    def keep_framed(self, size: tuple[int, int]) -> None:
        """The home pose of a bare scene file follows the view's size (the first frame, a resized window, the panel
        collapsed) as long as the camera stays there; after R it is framed again for the view's size then."""
        if self._framed is not None and self._framed[0] != size and self._framed[1] == self.control.version:
            self.frame_all(home=True, size=size)

    def view_rect(self, full: tuple[int, ...], docked: bool = True) -> tuple[int, int, int, int]:
        """The scene's part of a target whose viewport is ``full`` (GL: x, y from the bottom, width, height):
        right of the docked panel (``docked``: the panel is drawn), or all of it when the panel is collapsed or
        hidden. Also sets ``panel.view_rect`` (window coordinates, y down) for the overlays, and the view's size."""
        x, y, width, height = (int(v) for v in full)
        left = 0
        rect = self.panel.panel_rect if docked else None
        scale = framebuffer_scale()
        if rect is not None:
            left = int(round(min(rect[2] * scale[0], width - MIN_VIEW_WIDTH)))
        left = max(left, 0)
        self.panel.view_rect = (left / scale[0], 0.0, (width - left) / scale[0], height / scale[1])
        self.view_size = (width - left, height)
        return (x + left, y, width - left, height)

    # ----------------------------------------------------------------- camera commands
    def reset_camera(self) -> None:
        """Back to the home pose (R); a framed home is framed again for the view's size now."""
        self.control.reset()
        if self._framed is not None:
            self._framed = (None, self.control.version)

    def snap_camera(self, index: int) -> None:
        """Look through the scene's camera ``index`` (one that exists)."""
        cameras = self.cameras()
        if index < len(cameras):
            cam = cameras[index]
            self.control.snap_to(cam)
            self.panel.camera_index = index
            self.status.say(f"camera {index + 1}: {cam.name}")

    def commands(self) -> Handlers:
        """The panel's commands this part carries out: field of view, reset, frame all, the scene's cameras."""
        return {"fov": lambda args: self.control.set_fov(args["degrees"]),
                "reset_camera": lambda _args: self.reset_camera(),
                "frame_all": lambda _args: self.frame_all(),
                "snap_camera": lambda args: self.snap_camera(args["index"])}
