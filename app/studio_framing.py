"""Where the scene sits in the studio's window: the view beside the docked panel, and the home pose that frames the
scene in it ("frame all", F; R). ``StudioFraming`` is a mixin of ``StudioApp``."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

MIN_VIEW_WIDTH = 64  # the view keeps at least this many pixels beside the panel


def framebuffer_scale() -> tuple[float, float]:
    """Framebuffer pixels per window coordinate (1, 1 without an ImGui context or for a scale ImGui left at 0)."""
    if imgui.get_current_context() is None:
        return 1.0, 1.0
    scale = imgui.get_io().display_framebuffer_scale
    return (scale.x if scale.x > 0 else 1.0), (scale.y if scale.y > 0 else 1.0)


class StudioFraming:
    """The scene's view rectangle and its framing (state set up by ``StudioApp.__init__``: ``_scene_box``,
    ``_framed``, ``_view_size``)."""

    def _frame_scene(self) -> None:
        """Home pose. A scene with cameras of its own: the first one's viewpoint, levelled to the scene's up axis
        (estimated from the cameras), orbiting the scene's centre. A bare scene file (generated cameras, or none):
        the whole scene framed in the view ("frame all", ``frame_all``) from the first generated camera's side, and
        kept framed while the view changes size and the camera has not moved (``_keep_framed``); a stylized result
        of one frames its input's box (recorded in its OUT.json), as its input was framed."""
        from gstyle_core.cameras.framing import scene_box
        from gstyle_core.cameras.generate import finite_points, robust_centre_radius
        from gstyle_core.cameras.up import estimate_up

        self._scene_box = getattr(self.loaded, "frame_box", None) or scene_box(self.loaded.scene.means)
        centre, radius = robust_centre_radius(finite_points(self.loaded.scene.means))
        self.control.world_up = estimate_up(self.cameras)
        if self.cameras and not self.loaded.generated_cameras:
            cam = self.cameras[0]
            self.control.snap_to(cam, float(np.linalg.norm(cam.position - centre)))
            self.control.home = self.control.pose.copy()
            self.control.set_up(self.control.world_up)
            self.control.fly_speed = max(radius, 1e-3)
            self._framed = None
            return
        if self.cameras:
            self.control.snap_to(self.cameras[0])  # its side and field of view
        else:
            self.control.frame(centre, radius)  # a side view
        self.frame_all(home=True)
        self._framed = (None, self.control.version)  # framed again for the view's size when it is first drawn

    def frame_all(self, home: bool = False, size: tuple[int, int] | None = None) -> None:
        """Frame the whole scene (its robust box) in the view (``size``: default the last frame's) from the current
        viewing direction, with a margin on every side (F); ``home``: as the home pose (R)."""
        if self.loaded is None:
            return
        size = size or self._view_size
        self.control.frame_box(*self._scene_box, *size, set_home=home)
        if home:
            self._framed = (size, self.control.version)

    def _keep_framed(self, size: tuple[int, int]) -> None:
        """The home pose of a bare scene file follows the view's size (the first frame, a resized window, the panel
        collapsed) as long as the camera stays there; after R it is framed again for the view's size then."""
        if self._framed is not None and self._framed[0] != size and self._framed[1] == self.control.version:
            self.frame_all(home=True, size=size)

    def view_rect(self, full: tuple[int, ...], with_ui: bool = True) -> tuple[int, int, int, int]:
        """The scene's part of a target whose viewport is ``full`` (GL: x, y from the bottom, width, height):
        right of the docked panel, or all of it when the panel is collapsed or hidden. Also sets
        ``panel.view_rect`` (window coordinates, y down) for the overlays."""
        x, y, width, height = (int(v) for v in full)
        left = 0
        rect = self.panel.panel_rect if with_ui and self.show_ui else None
        scale = framebuffer_scale()
        if rect is not None:
            left = int(round(min(rect[2] * scale[0], width - MIN_VIEW_WIDTH)))
        left = max(left, 0)
        self.panel.view_rect = (left / scale[0], 0.0, (width - left) / scale[0], height / scale[1])
        return (x + left, y, width - left, height)
