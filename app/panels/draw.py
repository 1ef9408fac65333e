"""The control panel window: its sections in order, the overlays, and the keyboard shortcuts."""

from __future__ import annotations

from imgui_bundle import imgui

from .file_browser import file_browser_window
from .output import output_section, takes_section
from .region import region_overlay, region_section
from .run_sections import decisions_section, files_section, progress_section
from .sliders import params_section
from .state import Command, PanelState
from .view import compare_labels, help_overlay, view_section

PANEL_WIDTH = 420.0  # wide enough for a λ row with the substitute's name and its reset button


def shortcut_commands(state: PanelState) -> list[Command]:
    """Keyboard shortcuts (ignored while a text field has focus)."""
    io = imgui.get_io()
    if io.want_text_input:
        return []
    out: list[Command] = []
    pressed = imgui.is_key_pressed
    if pressed(imgui.Key.space, False):
        out.append(Command("resume" if state.paused else "pause"))
    if pressed(imgui.Key.c, False) and not io.key_ctrl:  # compare with the original (from a take's too), or back
        with_original = state.view_mode == "compare" and not state.compare_with_take
        out.append(Command("view_mode", {"mode": "stylized" if with_original else "compare"}))
    if pressed(imgui.Key.s, False) and io.key_ctrl:
        out.append(Command("export"))
    if pressed(imgui.Key.f12, False):
        out.append(Command("screenshot"))
    if pressed(imgui.Key.h, False):
        out.append(Command("toggle_help"))
    if pressed(imgui.Key.b, False) and not io.key_ctrl:
        out.append(Command("region_enable", {"on": not state.region_enabled}))
    if pressed(imgui.Key.r, False) and not io.key_ctrl:
        out.append(Command("reset_camera"))
    if pressed(imgui.Key.t, False) and state.take_names:  # compare with the next take (newest first)
        following = state.take_shown + 1 if state.compare_with_take else 0
        out.append(Command("show_take", {"index": following % len(state.take_names), "compare": True}))
    for digit in range(1, 10):
        if pressed(getattr(imgui.Key, f"_{digit}"), False) and digit <= state.camera_count:
            out.append(Command("snap_camera", {"index": digit - 1}))
    return out


def draw_panel(state: PanelState) -> list[Command]:
    """Draw the control panel window and return the commands the user issued this frame."""
    out = shortcut_commands(state)
    # Docked to the window's left edge, full height (it scrolls when taller); the scene is laid out beside it
    # (``StudioApp.view_rect``) and takes the whole window while the panel is collapsed (its title bar's arrow).
    viewport = imgui.get_main_viewport()
    imgui.set_next_window_pos(viewport.pos, imgui.Cond_.always)
    imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, viewport.size.y), imgui.Cond_.always)
    opened = imgui.begin("G-Style Studio", None, imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize)[0]
    pos, size = imgui.get_window_pos(), imgui.get_window_size()
    state.panel_rect = None if imgui.is_window_collapsed() else (pos.x, pos.y, pos.x + size.x, pos.y + size.y)
    if opened:
        _sections(state, out)
    imgui.end()
    if state.browser is not None:
        file_browser_window(state.browser, out)
    if state.view_mode == "compare":
        compare_labels(state)
    region_overlay(state)
    if state.show_help:
        help_overlay(state)
    return out


def _sections(state: PanelState, out: list[Command]) -> None:
    """The panel's sections, top to bottom."""
    files_section(state, out)
    progress_section(state, out)
    decisions_section(state)
    view_section(state, out)
    params_section(state, out)
    region_section(state, out)
    output_section(state, out)
    takes_section(state, out)
