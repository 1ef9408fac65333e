"""Small ImGui helpers the panel's sections share: tooltips, buttons, a log-scale slider, a thumbnail."""

from __future__ import annotations

import math
from typing import Any

from imgui_bundle import imgui

FINE_DRAG = 0.1  # a slider dragged with Shift held moves this much as fast (a tenth: fine tuning)


def param_slider(label: str, value: float, low: float, high: float, fmt: str = "%.3g",
                 log: bool = True) -> tuple[bool, float]:
    """A float slider with a control's range and format, on a logarithmic scale when it has one. Dragged with Shift
    held it moves ten times slower (``fine_value``: by the mouse's motion, not to where the mouse is); Ctrl+click
    (or double-click) types a value (ImGui's own, clamped to the range)."""
    flags = imgui.SliderFlags_.logarithmic if log else imgui.SliderFlags_.none
    changed, new = imgui.slider_float(label, float(value), low, high, fmt, flags | imgui.SliderFlags_.always_clamp)
    io = imgui.get_io()
    if imgui.is_item_active() and io.key_shift and imgui.is_mouse_down(0) and not imgui.is_item_deactivated():
        moved = io.mouse_delta.x / max(imgui.get_item_rect_size().x, 1.0)
        new = fine_value(float(value), moved, low, high, log)
        changed = new != float(value)
    return changed, new


def fine_value(value: float, moved: float, low: float, high: float, log: bool) -> float:
    """``value`` moved by ``moved`` of a slider's width at ``FINE_DRAG`` of the speed, on its scale (logarithmic
    when ``log`` and the range is positive), within the range."""
    step = moved * FINE_DRAG
    if log and low > 0:
        t = math.log(max(value, low) / low) / math.log(high / low) + step
        return float(min(max(low * (high / low) ** t, low), high))
    return float(min(max(value + step * (high - low), low), high))


# The panel's font (ImGui's default) has Latin-1 glyphs only: the engine's words outside it, spelled out.
FONT_SPELLINGS = str.maketrans({"λ": "lambda", "σ": "sigma", "γ": "gamma", "≥": ">=", "≤": "<=", "→": "->",
                                "–": "-", "—": "-", "…": "...", "≈": "~", "′": "'", "∂": "d", "‖": "|"})


def font_safe(text: str) -> str:
    """``text`` with the characters the panel's font lacks spelled out (``FONT_SPELLINGS``; others outside Latin-1
    become "?" as the font would show them, so a test can see them)."""
    text = text.translate(FONT_SPELLINGS)
    return "".join(c if ord(c) < 256 else "?" for c in text)


TOOLTIP_WIDTH = 420.0  # pixels of text per tooltip line at most


def tooltip(text: str) -> None:
    """Tooltip of the last item, shown on hover even when the item is disabled; wrapped to fit the window (a long
    one is not cut at the window's edge)."""
    if imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip | imgui.HoveredFlags_.allow_when_disabled):
        width = imgui.get_main_viewport().size.x
        imgui.begin_tooltip()
        imgui.push_text_wrap_pos(max(min(TOOLTIP_WIDTH, width - 40.0), 120.0))
        imgui.text_wrapped(font_safe(text))
        imgui.pop_text_wrap_pos()
        imgui.end_tooltip()


def button(label: str, tip: str, small: bool = False) -> bool:
    """A button with its tooltip; True when clicked."""
    clicked = imgui.small_button(label) if small else imgui.button(label)
    tooltip(tip)
    return clicked


def button_row(out: list, *buttons: tuple[str, str, Any]) -> None:
    """Buttons side by side, each (label, tooltip, command): a clicked one's command is appended to ``out``."""
    for i, (label, tip, command) in enumerate(buttons):
        if i:
            imgui.same_line()
        if button(label, tip):
            out.append(command)


def thumbnail(texture: int | None, size: tuple[int, int], side: float = 120.0) -> None:
    """A GL texture drawn with its longer side ``side`` pixels long (nothing when None)."""
    if texture is not None:
        w, h = size
        scale = side / max(w, h, 1)
        imgui.image(imgui.ImTextureRef(texture), imgui.ImVec2(w * scale, h * scale))
