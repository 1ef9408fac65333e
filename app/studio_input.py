"""Mouse and keyboard in the studio's view: orbit, pan, zoom, fly, the compare divider, and the region tool's box
and rectangle. ``StudioInput`` is a mixin of ``StudioApp``."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from .studio_framing import framebuffer_scale

BOX_WHEEL_STEP = 1.1  # Alt + one wheel notch resizes the region box by this factor
DIVIDER_GRAB_PIXELS = 6


def imgui_input_pending() -> bool:
    """ImGui still holds queued input: it hands on one key or character change a frame, so a typed path (or a fast
    double-click) needs frames after the window's events stopped."""
    ctx = imgui.get_current_context()
    return ctx is not None and len(ctx.input_events_queue) > 0


class StudioInput:
    """``StudioApp``'s input handling; the drag state lives on the app (``_dragging``, ``_last_mouse``,
    ``_rect_start``)."""

    def _handle_input(self, view: tuple[int, int, int, int], dt: float) -> None:
        """``view``: the scene's part of the window (GL viewport, framebuffer pixels); mouse positions are taken
        relative to its top-left corner."""
        io_ = imgui.get_io()
        width, height = view[2], view[3]
        sx, sy = framebuffer_scale()
        origin = self.panel.view_rect[:2]  # window coordinates
        mouse = (io_.mouse_pos.x - origin[0], io_.mouse_pos.y - origin[1])
        fb_mouse = (mouse[0] * sx, mouse[1] * sy)
        if self._dragging == "select" and not imgui.is_mouse_down(0):  # released: select what the rectangle holds
            start, self._rect_start = self._rect_start, None
            self.panel.region_drag = None
            if start is not None and abs(fb_mouse[0] - start[0]) >= 2 and abs(fb_mouse[1] - start[1]) >= 2:
                self.select_rectangle((*start, *fb_mouse), width, height, before=self._region_before_drag)
        if not io_.want_capture_mouse and mouse[0] >= 0:
            divider_x = self.divider * width / sx
            if imgui.is_mouse_clicked(0) and io_.key_shift and self.loaded is not None:
                self._dragging, self._rect_start = "select", fb_mouse
                self._region_before_drag = self.region_state()  # the undo step starts here
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
                self.control.zoom(io_.mouse_wheel, cursor=fb_mouse, size=(width, height))  # toward the cursor
        if not (imgui.is_mouse_down(0) or imgui.is_mouse_down(1)):
            self._dragging = None
        if self._dragging and self._last_mouse is not None:
            dx, dy = mouse[0] - self._last_mouse[0], mouse[1] - self._last_mouse[1]
            if self._dragging == "divider":
                self.divider = float(np.clip(fb_mouse[0] / max(width, 1), 0.0, 1.0))
            elif self._dragging == "orbit" and (dx or dy):
                self.control.orbit(dx, dy)
            elif self._dragging == "pan" and (dx or dy):
                self.control.pan(dx, dy, height)
            elif self._dragging == "box" and (dx or dy):
                self.move_region_box(dx * sx, dy * sy, width, height)
            elif self._dragging == "select" and self._rect_start is not None:
                self.panel.region_drag = (self._rect_start[0] / sx, self._rect_start[1] / sy, *mouse)
        self._last_mouse = mouse
        if not io_.want_capture_keyboard and not io_.key_ctrl:
            chorded = self.keys.chorded  # the S of a Ctrl+S still down after Ctrl was let go: no flying back

            def down(key: imgui.Key) -> bool:
                return imgui.is_key_down(key) and key.name not in chorded

            forward = float(down(imgui.Key.w)) - float(down(imgui.Key.s))
            right = float(down(imgui.Key.d)) - float(down(imgui.Key.a))
            up = float(down(imgui.Key.e)) - float(down(imgui.Key.q))
            self.control.fly(forward, right, up, min(dt, 0.1))
