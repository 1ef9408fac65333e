"""The panel's view section (view modes, field of view, scene cameras) and what it draws over the view: the compare
view's labels and the help overlay."""

from __future__ import annotations

from imgui_bundle import imgui

from .state import VIEW_MODES, Command, PanelState
from .widgets import button, tooltip

VIEW_TOOLTIPS = {
    "stylized": "The stylized scene as the engine has it now.",
    "original": "The input scene, with its view-dependent colour (SH) when it has any.",
    "compare": "Stylized left, original right; drag the white divider (C toggles; T compares with the takes).",
    "ground truth": "The colours the stylization is compared against (available once the engine sent them).",
    "take": "The take chosen under Takes (an earlier export; the newest when none is chosen), alone.",
}

HELP_TEXT = """Mouse: left drag orbit (turntable about the scene's up), right drag pan, wheel dolly. W/A/S/D/Q/E fly.
B region tool (Alt + drag / wheel: move / resize its box; Shift + drag: select by rectangle)
T compare with the next take (your exports)
Space pause/resume   C compare   1-9 scene cameras (all: the camera list)   R reset view   F frame all
Ctrl+S export .ply   F12 screenshot of the window   Shift+F12 of the scene view alone
H this help"""


def view_section(state: PanelState, out: list[Command]) -> None:
    """View modes, field of view, reset view and the scene cameras."""
    imgui.separator()
    for mode in VIEW_MODES:
        disabled = (mode == "ground truth" and not state.has_ground_truth) or (mode == "take" and not state.take_names)
        imgui.begin_disabled(disabled)
        again = mode == "compare" and state.compare_with_take  # from a take back to the original
        if imgui.radio_button(mode, state.view_mode == mode) and (state.view_mode != mode or again) and not disabled:
            out.append(Command("view_mode", {"mode": mode}))
        tooltip(VIEW_TOOLTIPS[mode])
        imgui.end_disabled()
        if mode not in (VIEW_MODES[-1], "compare"):  # two rows: the panel is narrower than five radio buttons
            imgui.same_line()
    changed, fov = imgui.slider_float("fov", state.fov_deg, 10.0, 120.0, "%.0f deg")
    tooltip("Field of view of the viewer's camera, across the view's smaller side.")
    if changed:
        out.append(Command("fov", {"degrees": fov}))
    if button("Reset view", "Back to the home view (R): the first scene camera's, or for a scene file without "
                            "cameras the whole scene framed."):
        out.append(Command("reset_camera"))
    imgui.same_line()
    if button("Frame all", "Look at the whole scene from this side, with a margin on every side of the view (F)."):
        out.append(Command("frame_all"))
    camera_list(state, out)


def camera_label(index: int, names: list[str]) -> str:
    """``"3: name"`` (1-based, as the number keys count) for a scene camera."""
    name = names[index] if 0 <= index < len(names) else ""
    return f"{index + 1}: {name}" if name else f"{index + 1}"


def camera_list(state: PanelState, out: list[Command]) -> None:
    """A combo of every scene camera (the number keys reach only the first nine)."""
    names = state.camera_names or [""] * state.camera_count
    if not names:
        return
    imgui.same_line()
    imgui.set_next_item_width(150)
    current = camera_label(state.camera_index, names) if 0 <= state.camera_index < len(names) else "scene cameras"
    if not imgui.begin_combo("##cameras", current, imgui.ComboFlags_.height_large):
        tooltip(f"Jump to one of the scene's {len(names)} cameras (keys 1-9: the first nine).")
        return
    for i in range(len(names)):
        if imgui.selectable(camera_label(i, names), i == state.camera_index)[0]:
            out.append(Command("snap_camera", {"index": i}))
    imgui.end_combo()


def compare_labels(state: PanelState) -> None:
    """Names of the two sides of the compare view, at the top beside the divider."""
    ox, oy, width, height = state.view_rect
    x = ox + width * min(max(state.divider, 0.0), 1.0)
    right = (state.take_names[state.take_shown] if state.compare_with_take and 0 <= state.take_shown
             < len(state.take_names) else "original")
    draw = imgui.get_foreground_draw_list()
    colour = imgui.get_color_u32(imgui.ImVec4(1.0, 1.0, 1.0, 0.9))
    left = "now"
    y = oy + height - 28
    draw.add_text(imgui.ImVec2(x - 10 - imgui.calc_text_size(left).x, y), colour, left)
    draw.add_text(imgui.ImVec2(x + 10, y), colour, right)


def help_overlay(state: PanelState) -> None:
    """The keys and mouse actions, centred over the scene's view (beside the panel, not over its controls)."""
    ox, oy, width, height = state.view_rect
    imgui.set_next_window_pos(imgui.ImVec2(ox + width * 0.5, oy + height * 0.5), imgui.Cond_.always,
                              imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_bg_alpha(0.85)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
             | imgui.WindowFlags_.no_inputs)
    imgui.begin("help", None, flags)
    imgui.push_text_wrap_pos(max(width - 40.0, 160.0))
    imgui.text_wrapped(HELP_TEXT)
    imgui.pop_text_wrap_pos()
    imgui.end()
