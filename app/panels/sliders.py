"""The panel's parameter sliders (one row per ``param_rows()`` entry: on/off for a loss term, slider, reset), the
checkboxes (``switch_rows()``: keep colours, coherent strokes) and "Reset all"."""

from __future__ import annotations

from imgui_bundle import imgui

from .params import COARSE_CLIP_TOOLTIP, Param, param_rows, switch_rows
from .state import Command, PanelState
from .widgets import button, param_slider, tooltip


def default_value(state: PanelState, p: Param) -> float:
    """What "reset" restores: the value of the preset the scene resolved to (else the parameter's own default)."""
    return float(state.defaults.get(p.key, p.default))


def param_tooltip(state: PanelState, p: Param) -> str:
    """The slider's tooltip (the coarse substitute's own when there are no CLIP weights: the label stays "large
    patterns", the tooltip says which term it is)."""
    return COARSE_CLIP_TOOLTIP if p.key == "lambda_clip" and state.clip_name != "CLIP" else p.tooltip


def switch_command(state: PanelState, p: Param, on: bool) -> Command:
    """Turn a term off (weight 0, remembering its λ) or on again (the remembered λ, else the preset's)."""
    if not on:
        state.switched_off[p.key] = float(state.params.get(p.key, default_value(state, p)))
        return Command("set_params", {p.key: 0.0})
    value = state.switched_off.pop(p.key, 0.0) or default_value(state, p) or p.default
    return Command("set_params", {p.key: float(value)})


def params_section(state: PanelState, out: list[Command]) -> None:
    """Undo / Redo, one slider row per parameter, one checkbox per switch and "Reset all"."""
    imgui.separator()
    edit_row(state, out)
    for p in param_rows():
        imgui.push_id(p.key)
        param_row(state, p, out)
        imgui.pop_id()
    for p in switch_rows():
        changed, on = imgui.checkbox(p.label, bool(state.params.get(p.key, default_value(state, p))))
        tooltip(p.tooltip)
        if changed:
            out.append(Command("set_params", {p.key: float(on)}))
    if button("Reset all", "Every parameter back to the preset's value for this scene (the checkboxes too)."):
        values = {p.key: default_value(state, p) for p in (*param_rows(), *switch_rows())}
        out.append(Command("set_params", values))


def edit_row(state: PanelState, out: list[Command]) -> None:
    """Undo and Redo of the parameter changes, each saying which step it takes."""
    for name, label, note in (("undo", "Undo (Ctrl+Z)", state.undo_note),
                              ("redo", "Redo (Ctrl+Shift+Z)", state.redo_note)):
        imgui.begin_disabled(not note)
        if button(f"{label}###{name}", f"{name.capitalize()}: {note}" if note else f"Nothing to {name}.", small=True):
            out.append(Command(name))
        imgui.end_disabled()
        imgui.same_line()
    imgui.new_line()


def param_row(state: PanelState, p: Param, out: list[Command]) -> None:
    """[on/off] slider [reset] of one parameter."""
    value = float(state.params.get(p.key, p.default))
    off = p.is_term and value <= 0
    if p.is_term:
        changed, on = imgui.checkbox("##on", not off)
        tooltip(f"Turn {p.label} on or off (off: weight 0, never computed).")
        if changed:
            out.append(switch_command(state, p, on))
        imgui.same_line()
    imgui.begin_disabled(off)
    imgui.set_next_item_width(96)  # room for the longest label, its reset button and the panel's scrollbar
    shown = state.switched_off.get(p.key, default_value(state, p)) if off else value
    changed, new = param_slider(p.label, shown, p.low, p.high, p.fmt, p.log)
    tooltip(param_tooltip(state, p))
    if changed and not off:
        out.append(Command("set_params", {p.key: float(new)}))
    imgui.end_disabled()
    imgui.same_line()
    if button("reset", f"Back to the preset's value ({default_value(state, p):.3g}).", small=True):
        out.append(Command("set_params", {p.key: default_value(state, p)}))
