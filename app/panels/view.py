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

HELP_ROWS = (  # (keys, what they do): the help overlay (H); the README lists the same keys
    ("left drag", "orbit (turns about the scene's up)"),
    ("right drag, wheel", "pan, zoom toward the cursor"),
    ("W A S D, Q E", "fly; down, up"),
    ("F", "frame the whole scene from this side"),
    ("R", "reset the view"),
    ("1-9", "scene cameras (all of them: the camera list)"),
    ("Space", "pause / resume the engine"),
    ("C", "compare: stylized left, original right"),
    ("T", "compare with the next take (your exports)"),
    ("B", "region tool on / off"),
    ("Alt + drag, wheel", "move, resize the region box"),
    ("Shift + drag", "select by rectangle"),
    ("Ctrl+S, Ctrl+Shift+S", "export .ply, Save As"),
    ("Ctrl+Q", "quit (the session is saved)"),
    ("Ctrl+Z, Ctrl+Shift+Z", "undo, redo (parameters, replaced results)"),
    ("F12", "screenshot of the window"),
    ("Shift+F12", "screenshot of the scene view alone"),
)
HELP_TITLE = "H, Esc or a click here closes this help"
HELP_PAD = 10.0  # pixels between the help and the view's edges
MIN_HELP_WIDTH = 160.0  # narrower views: the help covers the panel's edge (it says how to close it)



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


def help_overlay(state: PanelState, out: list[Command]) -> None:
    """The keys and mouse actions over the scene's view, beside the panel, centred: a table where the view is wide
    enough for it, else one wrapped line per key. A view narrower than ``MIN_HELP_WIDTH`` (a window under ~600
    pixels wide) gets it at the window's right edge, over the panel's edge; its title says that H, Esc or a click on
    it closes it."""
    ox, oy, width, height = state.view_rect
    style = imgui.get_style()
    keys_width = max(imgui.calc_text_size(keys).x for keys, _ in HELP_ROWS)
    table_width = (keys_width + max(imgui.calc_text_size(what).x for _, what in HELP_ROWS)
                   + 4 * style.cell_padding.x + 2 * style.window_padding.x + 2 * style.item_spacing.x)
    room = width - 2 * HELP_PAD
    as_table = table_width <= room
    help_width = table_width if as_table else max(room, MIN_HELP_WIDTH)
    centre_x = ox + width / 2 if help_width <= room else ox + width - help_width / 2
    imgui.set_next_window_pos(imgui.ImVec2(max(centre_x, help_width / 2), oy + height / 2), imgui.Cond_.always,
                              imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_size_constraints(imgui.ImVec2(help_width, 0.0),
                                           imgui.ImVec2(help_width, max(height - 2 * HELP_PAD, 60.0)))
    imgui.set_next_window_bg_alpha(0.85)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
             | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav
             | imgui.WindowFlags_.no_saved_settings)
    imgui.begin("help", None, flags)
    imgui.text_wrapped(HELP_TITLE)
    imgui.separator()
    if as_table and imgui.begin_table("keys", 2, imgui.TableFlags_.row_bg):
        imgui.table_setup_column("keys", imgui.TableColumnFlags_.width_fixed, keys_width)
        imgui.table_setup_column("what", imgui.TableColumnFlags_.width_stretch)
        for keys, what in HELP_ROWS:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.text(keys)
            imgui.table_next_column()
            imgui.text(what)
        imgui.end_table()
    elif not as_table:
        for keys, what in HELP_ROWS:
            imgui.text_wrapped(f"{keys}: {what}")
    if imgui.is_window_hovered() and imgui.is_mouse_clicked(0):
        out.append(Command("toggle_help"))
    imgui.end()
