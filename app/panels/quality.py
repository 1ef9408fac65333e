"""The panel's quality section: the preset (preview / balanced / final) with what each would take on this scene on
this machine, the width the run is at, Refine (the next finer level from the colours as they are) and the finished
run's result."""

from __future__ import annotations

from imgui_bundle import imgui

from .run_sections import format_eta
from .state import Command, PanelState
from .widgets import button, font_safe, tooltip

QUALITIES = {
    "preview": "Preview: the working width only (256 px); first strokes in seconds.",
    "balanced": "Balanced: the preview, then a finer level at 512 px on crops: fewer specks and sharper edges at a "
                "display's size.",
    "final": "Final: the preview, then 512 px on whole views with twice the steps and every camera: more of the "
             "painting's strokes at a display's size, fewer specks.",
}


DEVICE_WORDS = {"cpu": "the CPU", "cuda": "the GPU", "mps": "the Apple GPU"}


def device_words(device: str) -> str:
    """``device`` ("cpu", "cuda", "mps") as the status line and buttons say it."""
    return DEVICE_WORDS.get(device, device)


def move_target(state: PanelState) -> str | None:
    """The device the panel offers to move the run to: the GPU (CUDA) from elsewhere where there is one, else the
    CPU from a GPU; None without an engine, after the GPU failed (the error offers the CPU) or with nowhere to go.
    MPS is never offered (not measured: ``--device mps`` asks for it)."""
    if not state.device or state.device_failed:
        return None
    if state.device != "cuda" and "cuda" in state.devices:
        return "cuda"
    return "cpu" if state.device != "cpu" else None


def device_line(state: PanelState, out: list[Command]) -> None:
    """What the run computes on, and the button that moves it elsewhere (``move_target``)."""
    if not state.device:
        return
    imgui.text_wrapped(f"Computing on: {state.device_name or device_words(state.device)}")
    tooltip("Where the engine computes. A move goes on from where the run is (its colours, geometry and settings) "
            "on the other device; restarts stay there.")
    target = move_target(state)
    if target and button(f"Move to {device_words(target)}", f"Go on from where the run is, computing on "
                                                            f"{device_words(target)}."):
        out.append(Command("move_to", {"device": target}))


def refine_button(state: PanelState, out: list[Command]) -> None:
    """Refine to the next width; disabled after an engine error (its level would wait for steps that do not come),
    its tooltip saying so."""
    tip = (f"Carry the current colours on at {state.next_width} px without a restart: a finer level, then the final "
           "colour match again. Works during a run and after it. On a 360-degree scene a preview's first level keeps "
           "edges (edges kept 4000, brush strokes 400) unless you moved them; a restart goes back to the values "
           "before.")
    if state.failed:
        tip = "The run stopped at an error: Continue it (or Restart) first, then refine."
    imgui.begin_disabled(state.failed)
    if button(f"Refine -> {state.next_width} px", tip):
        out.append(Command("refine"))
    imgui.end_disabled()


def pending_quality(state: PanelState, out: list[Command]) -> None:
    """A quality chosen that the run (or the result) on show is not at: when it applies, and the restart at it (with
    a result on show and no engine, Restart from the original applies it)."""
    if not state.preset or state.quality == state.preset:
        return
    if state.result_line and not state.device:
        imgui.text_wrapped(f"{state.quality}: applies at Restart from the original (this result is {state.preset})")
        return
    imgui.text_wrapped(f"{state.quality}: applies at Restart (the run is at {state.preset})")
    if button(f"Restart at {state.quality}", f"Start the stylization again from the input scene at the "
                                             f"{state.quality} quality (the run now is {state.preset})."):
        out.append(Command("restart_quality", {"preset": state.quality}))


def quality_section(state: PanelState, out: list[Command]) -> None:
    """Quality radio buttons with their estimates, the run's widths, Refine, and the result once done."""
    imgui.separator()
    imgui.text("Quality")
    for name, tip in QUALITIES.items():
        estimate = state.quality_estimates.get(name)
        now = "  [now]" if name == state.preset else ""
        label = f"{name} ({'~' + format_eta(estimate) if estimate is not None else 'time: measuring'}){now}###q_{name}"
        if imgui.radio_button(label, state.quality == name):
            out.append(Command("set_quality", {"preset": name}))
        tooltip(f"{tip} The time is this scene's on this machine, priced at the median step times measured in "
                "this session's runs of it (a phase's first steps left out). The chosen one is what every start "
                "runs (Restart, Restart from the original, a scene or painting opened); [now]: what is on show.")
    pending_quality(state, out)
    if state.width:  # (nothing to say before a run or a result gives one)
        levels = " -> ".join(f"{w} px" for w in state.levels)  # the panel's font has Latin-1 glyphs only
        imgui.text_wrapped(f"Width: {state.width} px" + (f" (levels {levels})" if len(state.levels) > 1 else ""))
        tooltip("The width of what is on show: the engine's now, or a result's last level. Finer levels go on from "
                "the colours at twice the pixels, so the strokes hold up at a display's size "
                "(docs/notes/tradeoffs.md).")
    if state.next_width:
        refine_button(state, out)
    if state.refine_note:
        imgui.same_line()
        imgui.text_wrapped(state.refine_note)
    device_line(state, out)
    if state.grain:
        imgui.text_wrapped(f"Fine grain at screen size: {state.grain} (1 = the painting's own)")
        tooltip("How fine the colour detail the stylization added is, seen at a display's size: measured on three of "
                "the scene's views rendered at a display's width, the share of the added colour finer than sigma 4 px "
                "against the painting's own share at the size its strokes are matched (1: the painting's grain; well "
                "above 1: single-splat confetti; the speckle ratio of docs/notes/display-size.md). "
                + font_safe(f"The engine's line: {state.summary_line}"))  # sigma spelled out
    elif state.summary_line:  # no figure (its measurement failed): the engine's line as it is
        imgui.text_wrapped(font_safe(f"Result: {state.summary_line}"))
