"""The panel's quality section: the preset (preview / balanced / final) with what each would take on this scene on
this machine, the width the run is at, Refine (the next finer level from the colours as they are) and the finished
run's result."""

from __future__ import annotations

from imgui_bundle import imgui

from .run_sections import font_safe, format_eta
from .state import Command, PanelState
from .widgets import button, tooltip

QUALITIES = {
    "preview": "Preview: the working width only (256 px on 360° scenes); first strokes in seconds.",
    "balanced": "Balanced: more steps, then a finer level at 512 px, so strokes hold up at a display's size.",
    "final": "Final: more pre-processing and steps, then levels at 512 and 1024 px: painted at a display's size.",
}


def quality_section(state: PanelState, out: list[Command]) -> None:
    """Quality radio buttons with their estimates, the run's widths, Refine, and the result once done."""
    imgui.separator()
    imgui.text("Quality")
    for name, tip in QUALITIES.items():
        estimate = state.quality_estimates.get(name)
        label = f"{name} ({'~' + format_eta(estimate) if estimate is not None else 'time: measuring'})###q_{name}"
        if imgui.radio_button(label, state.quality == name):
            out.append(Command("set_quality", {"preset": name}))
        tooltip(f"{tip} The time is this scene's on this machine, priced at the step times of the run so far.")
        if name != "final":
            imgui.same_line()
    if state.quality != state.preset and state.preset:
        if button(f"Restart at {state.quality}", f"Start the stylization again from the input scene at the "
                                                 f"{state.quality} quality (the run now is {state.preset})."):
            out.append(Command("restart_quality", {"preset": state.quality}))
    levels = " -> ".join(f"{w} px" for w in state.levels)  # the panel's font has Latin-1 glyphs only
    imgui.text_wrapped(f"Width: {state.width} px" + (f" (levels {levels})" if len(state.levels) > 1 else ""))
    tooltip("The width the engine renders at now. Finer levels go on from the colours at twice the pixels, so the "
            "strokes hold up at a display's size (docs/tradeoffs.md).")
    if state.next_width:
        if button(f"Refine -> {state.next_width} px", f"Carry the current colours on at {state.next_width} px "
                                                         "without a restart: a finer level, then the final colour "
                                                         "match again. Works during a run and after it. On a "
                                                         "360-degree scene a preview's first level keeps edges "
                                                         "(lambda edges 4000, NNFM 400) unless you moved them."):
            out.append(Command("refine"))
    if state.refine_note:
        imgui.same_line()
        imgui.text_wrapped(state.refine_note)
    if state.summary_line:
        imgui.text_wrapped(font_safe(f"Result: {state.summary_line}"))  # sigma spelled out
        tooltip("Measured on three of the scene's views rendered at a display's size: how much of the colour the "
                "stylization added is finer than sigma 4 px, against the painting's own share at the size its strokes "
                "are matched (1: the painting's grain; well above 1: single-splat confetti).")
