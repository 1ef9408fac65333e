"""Mouse and keyboard in the studio's view: orbit, pan, zoom, fly, the compare divider, and the region tool's box
and rectangle. ``StudioInput`` is a part of ``StudioApp``."""

from __future__ import annotations

from collections.abc import Callable

from imgui_bundle import imgui

from .camera_control import CameraControl
from .keys import KeyPresses
from .panels import PanelState
from .region_tool import RegionTool
from .studio_framing import framebuffer_scale
from .studio_views import Views

BOX_WHEEL_STEP = 1.1  # Alt + one wheel notch resizes the region box by this factor
DIVIDER_GRAB_PIXELS = 6


def imgui_input_pending() -> bool:
    """ImGui still holds queued input: it hands on one key or character change a frame, so a typed path (or a fast
    double-click) needs frames after the window's events stopped."""
    ctx = imgui.get_current_context()
    return ctx is not None and len(ctx.input_events_queue) > 0


class StudioInput:
    """The view's mouse and keys: owns the drag under way and the last mouse position. Built with the panel (where
    the view is), the window's key presses, the camera control it moves, the region tool (its box and rectangle),
    the views (the compare divider) and ``has_scene`` (a scene is shown: a rectangle can select in it)."""

    def __init__(self, panel: PanelState, keys: KeyPresses, control: CameraControl, region: RegionTool,
                 views: Views, has_scene: Callable[[], bool]) -> None:
        self.panel, self.keys, self.control, self.region, self.views = panel, keys, control, region, views
        self.has_scene = has_scene
        self._dragging: str | None = None
        self._last_mouse: tuple[float, float] | None = None

    def handle(self, view: tuple[int, int, int, int], dt: float) -> None:
        """``view``: the scene's part of the window (GL viewport, framebuffer pixels); mouse positions are taken
        relative to its top-left corner."""
        io_ = imgui.get_io()
        width, height = view[2], view[3]
        sx, sy = framebuffer_scale()
        origin = self.panel.view_rect[:2]  # window coordinates
        mouse = (io_.mouse_pos.x - origin[0], io_.mouse_pos.y - origin[1])
        fb_mouse = (mouse[0] * sx, mouse[1] * sy)
        region = self.region
        if self._dragging == "select" and not imgui.is_mouse_down(0):  # released: select what the rectangle holds
            region.end_rectangle(fb_mouse, width, height)
        if not io_.want_capture_mouse and mouse[0] >= 0:
            divider_x = self.views.divider * width / sx
            if imgui.is_mouse_clicked(0) and io_.key_shift and self.has_scene():
                self._dragging = "select"
                region.start_rectangle(fb_mouse)
            elif imgui.is_mouse_clicked(0) and io_.key_alt and region.box_tool_on():
                self._dragging = "box"  # Alt + drag: place the region box in the view
            elif imgui.is_mouse_clicked(0):
                near_divider = self.views.mode == "compare" and abs(mouse[0] - divider_x) <= DIVIDER_GRAB_PIXELS
                self._dragging = "divider" if near_divider else "orbit"
            elif imgui.is_mouse_clicked(1):
                self._dragging = "pan"
            if io_.mouse_wheel and io_.key_alt and region.box_tool_on():  # Alt + wheel: resize the box
                region.scale_box(BOX_WHEEL_STEP ** io_.mouse_wheel)
            elif io_.mouse_wheel:
                self.control.zoom(io_.mouse_wheel, cursor=fb_mouse, size=(width, height))  # toward the cursor
        if not (imgui.is_mouse_down(0) or imgui.is_mouse_down(1)):
            self._dragging = None
        if self._dragging and self._last_mouse is not None:
            dx, dy = mouse[0] - self._last_mouse[0], mouse[1] - self._last_mouse[1]
            if self._dragging == "divider":
                self.views.set_divider(fb_mouse[0] / max(width, 1))
            elif self._dragging == "orbit" and (dx or dy):
                self.control.orbit(dx, dy)
            elif self._dragging == "pan" and (dx or dy):
                self.control.pan(dx, dy, height)
            elif self._dragging == "box" and (dx or dy):
                region.move_box(dx * sx, dy * sy, width, height)
            elif self._dragging == "select":
                region.drag_rectangle(mouse, (sx, sy))
        self._last_mouse = mouse
        if not io_.want_capture_keyboard and not io_.key_ctrl:
            chorded = self.keys.chorded  # the S of a Ctrl+S still down after Ctrl was let go: no flying back

            def down(key: imgui.Key) -> bool:
                return imgui.is_key_down(key) and key.name not in chorded

            forward = float(down(imgui.Key.w)) - float(down(imgui.Key.s))
            right = float(down(imgui.Key.d)) - float(down(imgui.Key.a))
            up = float(down(imgui.Key.e)) - float(down(imgui.Key.q))
            self.control.fly(forward, right, up, min(dt, 0.1))
