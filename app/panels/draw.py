"""The control panel window: its sections in order, the overlays, and the keyboard shortcuts."""

from __future__ import annotations

from collections.abc import Sequence

from imgui_bundle import imgui

from ..keys import KeyPress
from .file_browser import file_browser_window
from .output import output_section, takes_section
from .quality import quality_section
from .region import region_overlay, region_section
from .run_sections import decisions_section, files_section, progress_section
from .sliders import params_section
from .state import Command, PanelState
from .view import compare_labels, help_overlay, view_section

PANEL_WIDTH = 420.0  # wide enough for a λ row with the substitute's name and its reset button


def shortcut_commands(state: PanelState, presses: Sequence[KeyPress]) -> list[Command]:
    """The commands of the keyboard shortcuts among ``presses`` (the key presses since the last frame, each with the
    modifiers held at that moment: ``app/keys.py``); none while a text field has focus."""
    if imgui.get_io().want_text_input:
        return []
    out: list[Command] = []
    for press in presses:
        out += _shortcut(state, press)
    return out


def _shortcut(state: PanelState, press: KeyPress) -> list[Command]:
    """The commands of one key press (most keys act only without Ctrl, Alt and Super)."""
    name = press.name
    if name == "s" and press.ctrl and not press.alt:  # Ctrl+Shift+S: Save As; Ctrl+S: save where it saved last
        return [Command("save_as" if press.shift else "export")]
    if name == "q" and press.ctrl and not (press.alt or press.shift):  # quit as the close button does
        return [Command("quit")]
    if press.ctrl and not press.alt and (name == "y" or (name == "z" and press.shift)):
        return [Command("redo")]
    if name == "z" and press.ctrl and not press.alt:
        return [Command("undo")]
    if name == "f12" and press.plain:  # Shift+F12: the scene view alone, F12: the whole window
        return [Command("screenshot", {"scene_only": press.shift})]
    if not press.plain:
        return []
    if name == "space" and state.resume_step is not None:  # the worker died: go on from its last save
        return [Command("resume_session")]
    if name == "space":  # as the Pause / Resume button: nothing while it cannot work (``state.stopped``)
        return [] if state.stopped else [Command("resume" if state.paused else "pause")]
    if name == "c":  # compare with the original (from a take's too), or back
        with_original = state.view_mode == "compare" and not state.compare_with_take
        return [Command("view_mode", {"mode": "stylized" if with_original else "compare"})]
    if name == "h" or (name == "escape" and state.show_help):
        return [Command("toggle_help")]
    if name == "b":
        return [Command("region_enable", {"on": not state.region_enabled})]
    if name == "r":
        return [Command("reset_camera")]
    if name == "f":
        return [Command("frame_all")]
    if name == "t" and state.take_names:  # compare with the next take (newest first; first one unlike the view)
        unlike = [i for i, differs in enumerate(state.take_differs) if differs]
        following = state.take_shown + 1 if state.compare_with_take else (unlike[0] if unlike else 0)
        return [Command("show_take", {"index": following % len(state.take_names), "compare": True})]
    if name.isdigit() and 1 <= int(name) <= state.camera_count:
        return [Command("snap_camera", {"index": int(name) - 1})]
    return []


def draw_panel(state: PanelState, presses: Sequence[KeyPress] = ()) -> list[Command]:
    """Draw the control panel window and return the commands the user issued this frame (``presses``: the key
    presses since the last frame, for the shortcuts)."""
    out = shortcut_commands(state, presses)
    # Docked to the window's left edge, full height (it scrolls when taller); the scene is laid out beside it
    # (``StudioApp.view_rect``) and takes the whole window while the panel is collapsed (its title bar's arrow).
    viewport = imgui.get_main_viewport()
    imgui.set_next_window_pos(viewport.pos, imgui.Cond_.always)
    imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, viewport.size.y), imgui.Cond_.always)
    # It stays behind the windows over it (the help, the file browser) when clicked, as a docked panel does.
    flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_bring_to_front_on_focus
    opened = imgui.begin("G-Style Studio", None, flags)[0]
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
        help_overlay(state, out)
    return out


def _sections(state: PanelState, out: list[Command]) -> None:
    """The panel's sections, top to bottom."""
    files_section(state, out)
    progress_section(state, out)
    quality_section(state, out)
    decisions_section(state)
    view_section(state, out)
    params_section(state, out)
    region_section(state, out)
    output_section(state, out)
    takes_section(state, out)
