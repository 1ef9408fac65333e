"""The panel's top: the scene and painting(s) (files section), the run's progress, controls and losses, and the
engine's decisions."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from imgui_bundle import imgui

from gstyle_core.engine.controls import control, term_label

from .decision_words import artist_lines
from .state import Command, PanelState
from .widgets import button, button_row, font_safe, thumbnail, tooltip


def files_section(state: PanelState, out: list[Command]) -> None:
    """Under the status box (the panel's top: a fixed place, ``status_box``), the scene and the painting(s): their
    paths, thumbnails and open buttons; for a stylized result, what it is and the ways on from it."""
    status_box(state.status)
    imgui.text_wrapped(f"Scene: {state.scene_path or '(none)'}")
    if state.result_line:
        result_block(state, out)
    if button("Open scene...", "Open a Gaussian scene (.ply, .compressed.ply, .splat, .spz, .sog or a SOG folder's "
                               "meta.json); dropping a file (or a SOG folder) on the window works too."):
        out.append(Command("open_scene"))
    imgui.same_line()
    if button("Open style...", "Open a style image (the painting); dropping it on the window works too."):
        out.append(Command("open_style"))
    if state.dialog_note:
        imgui.text_wrapped(state.dialog_note)
        if button("Use the studio's browser", "Choose the file in the studio instead (when the desktop's dialog "
                                               "does not show up)."):
            out.append(Command("use_browser"))
    imgui.text_wrapped(f"Style: {state.style_path or '(none)'}")
    thumbnail(state.style_texture, state.style_size)
    second_style(state, out)


def result_block(state: PanelState, out: list[Command]) -> None:
    """A stylized result was opened: what it is, its original, and the ways on (none starts by itself)."""
    imgui.text_wrapped(font_safe(state.result_line))
    source = state.result_source
    imgui.text_wrapped(f"Original: {source}" + ("" if state.result_source_found or not source else " (not found)"))
    imgui.begin_disabled(not state.result_continuable)
    if button("Continue this run", "Load the run this result was saved from (kept when it was saved) on its "
                                   "original: it is where it ended, so Refine, keep colours and the other controls "
                                   "go on from it. Needs the original scene and the file as it was saved."):
        out.append(Command("continue_result"))
    imgui.end_disabled()
    imgui.begin_disabled(not state.result_source_found)
    if button("Restart from the original", "Open the scene this result was stylized from and stylize it with the "
                                           "settings shown."):
        out.append(Command("restart_from_original"))
    imgui.end_disabled()
    imgui.same_line()
    if button("Stylize it again", "Stylize this result itself as a new scene (pre-processing it again)."):
        out.append(Command("restart"))


def mix_ends(state: PanelState, longest: int = 24) -> str:
    """The line over the mix slider naming the painting at each end (file names cut to ``longest`` characters)."""
    def name(path: str | None) -> str:
        stem = Path(path or "").name or "(none)"
        return stem if len(stem) <= longest else stem[:longest - 3] + "..."

    return f"0: {name(state.style_path)}  <->  1: {name(state.style2_path)}"


def second_style(state: PanelState, out: list[Command]) -> None:
    """The second painting of a mix: open / remove it, its thumbnail and the mix slider."""
    if not state.style2_path:
        if button("Mix in a second style...", "Open a second painting to mix with the first (both their strokes, "
                                              "the weighted palette; the mix slider sets the shares)."):
            out.append(Command("open_style2"))
        return
    imgui.same_line()
    thumbnail(state.style2_texture, state.style2_size, 60.0)
    imgui.text_wrapped(f"Second style: {state.style2_path}")
    imgui.text(mix_ends(state))
    imgui.set_next_item_width(150)
    row = control("style_mix")
    mix = float(state.params.get(row.name, 0.5))
    changed, mix = imgui.slider_float(row.label, mix, row.low, row.high, "%.2f of the 2nd")
    tooltip(row.tooltip)
    if changed:
        out.append(Command("set_params", {row.name: float(min(max(mix, row.low), row.high))}))
    imgui.same_line()
    if button("remove", "Back to the first painting alone (restarts the stylization).", small=True):
        out.append(Command("remove_style2"))


def progress_section(state: PanelState, out: list[Command]) -> None:
    """Phase, step and ETA, pause / step / restart / resume, the error (wrapped) and the loss plot under them."""
    imgui.separator()
    imgui.text(f"Phase: {state.phase}")
    imgui.text(f"Gaussians: {state.gaussians:,}   {state.fps:.1f} fps")
    fraction = state.step / state.total_steps if state.total_steps else 0.0
    imgui.progress_bar(min(max(fraction, 0.0), 1.0), imgui.ImVec2(-1, 0),
                       f"{state.step}/{state.total_steps}  ETA {format_eta(state.eta_seconds)}")
    run_buttons(state, out)
    if state.resume_step is not None:  # the worker died: its last save, not the last closed session
        if button(f"Resume from step {state.resume_step}", "The engine process is gone: go on from the run's last "
                  "save (Space does the same)."):
            out.append(Command("resume_session"))
    elif state.resume_available and button(
            "Resume last session", "Continue the stylization saved when the studio last closed with this scene and "
            "style."):
        out.append(Command("resume_session"))
    if state.error:
        error_block(state, out)
    loss_plot(state)


def run_buttons(state: PanelState, out: list[Command]) -> None:
    """Pause / Resume and Step (disabled, their tooltip saying why, while they cannot work: ``state.stopped``), and
    Restart."""
    pause = (("Resume###pause", "Continue stepping the engine (Space).", Command("resume")) if state.paused else
             ("Pause###pause", "Stop stepping after the current step; the view stays live (Space).", Command("pause")))
    step = ("Step", "Run exactly one engine step (useful while paused).", Command("step"))
    imgui.begin_disabled(bool(state.stopped))
    button_row(out, *((label, state.stopped or tip, command) for label, tip, command in (pause, step)))
    imgui.end_disabled()
    imgui.same_line()
    if button("Restart", "Start the stylization again from the input scene with the current settings."):
        out.append(Command("restart"))


def error_block(state: PanelState, out: list[Command]) -> None:
    """The error in red, and under it the way on: Continue from the last finished step after an engine error, or
    the CPU after the GPU's."""
    imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.35, 0.3, 1.0))
    imgui.text_wrapped(f"Error: {state.error}")
    imgui.pop_style_color()
    if state.device_failed and button(
            "Continue on the CPU", "Go on from where the run stopped, computing on the CPU (slower; the colours, "
            "the geometry and the settings stay). Restart afterwards stays on the CPU too."):
        out.append(Command("move_to", {"device": "cpu"}))
    elif state.failed and state.continue_from is not None and button(
            f"Continue from step {state.continue_from}",
            f"Go on from step {state.continue_from}, the last step that finished: the engine is built again from "
            "the run as that step left it (the failed step kept none of its work). The traceback is in the crash log "
            "named above; if the error comes back, Restart or change a setting first."):
        out.append(Command("continue_run"))


STATUS_LINES = 3


def status_box(text: str) -> None:
    """The status, wrapped, in a box of a fixed ``STATUS_LINES`` lines at the panel's top (empty, new or long, the
    controls below never move under the mouse); a longer one scrolls in the box (its scroll bar; the wheel stays the
    panel's) and shows whole in its tooltip."""
    height = STATUS_LINES * imgui.get_text_line_height_with_spacing()
    imgui.begin_child("##status", imgui.ImVec2(-1, height), 0, imgui.WindowFlags_.no_scroll_with_mouse)
    imgui.text_wrapped(font_safe(text))
    imgui.end_child()
    if text:
        tooltip(text)


def format_eta(seconds: float | None) -> str:
    """``m:ss`` (or ``h:mm:ss``) for a remaining time; ``-`` when unknown."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "-"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def loss_series(history: list[dict[str, float]], off: frozenset[str] = frozenset(),
                relative: bool = False) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(legend label: the term's slider label, ``term_label``; steps, values) per loss term in ``history``, only the
    points where the term was recorded (positive: a log axis), at their steps (an entry's ``"step"``, else its
    index). Terms never computed or in
    ``off`` (switched off now) have no series. ``relative``: each term over its first recorded value, so terms
    thousands of times apart share one axis and each one's fall shows."""
    steps = np.array([h.get("step", i) for i, h in enumerate(history)], np.float64)
    series = []
    for key in sorted({k for h in history for k in h} - {"step"} - set(off)):
        ys = np.array([h.get(key, np.nan) for h in history], np.float64)
        recorded = np.isfinite(ys) & (ys > 0)
        if recorded.any():
            values = ys[recorded] / ys[recorded][0] if relative else ys[recorded]
            series.append((term_label(key), steps[recorded], values))
    return series


def switched_off_terms(state: PanelState) -> frozenset[str]:
    """Loss terms whose λ is 0 now (switched off, or set so): left out of the plot."""
    return frozenset(name.removeprefix("lambda_") for name, value in state.params.items()
                     if name.startswith("lambda_") and value == 0)


def loss_plot(state: PanelState) -> None:
    """The losses so far against the step, each over its first value on a log axis (one named line per term, its
    fall visible whatever its size), the legend below the plot, a term a line (nothing without implot or history)."""
    series = loss_series(state.loss_history, switched_off_terms(state), relative=True)
    if not series:
        return
    try:
        from imgui_bundle import implot
    except ImportError:
        return
    # One term a line, in room made for them: in one row they did not fit, and the legend then scrolled itself,
    # keeping the mouse wheel from the panel.
    legend = len(series) * imgui.get_text_line_height_with_spacing()
    if implot.begin_plot("Losses", imgui.ImVec2(-1, 150 + legend)):
        implot.setup_axes("step", "loss / first", implot.AxisFlags_.auto_fit, implot.AxisFlags_.auto_fit)
        implot.setup_axis_scale(implot.ImAxis_.y1, implot.Scale_.log10)
        implot.setup_legend(implot.Location_.south, implot.LegendFlags_.outside)
        for label, xs, ys in series:
            implot.plot_line(label, xs, ys)
        implot.end_plot()


def decision_lines(decisions: dict[str, Any]) -> list[str]:
    """One ``name: value`` line per engine decision (dicts as ``k=v`` lists, lists joined with ``;``), in characters
    the panel's font has (``font_safe``)."""
    lines = []
    for key, value in decisions.items():
        if isinstance(value, dict):
            text = ", ".join(f"{k}={v}" for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            text = "; ".join(str(v) for v in value)
        else:
            text = str(value)
        lines.append(font_safe(f"{key.replace('_', ' ')}: {text}"))
    return lines


def decisions_section(state: PanelState) -> None:
    """Collapsible list (folded at first) of what the engine and the viewer decided to compute or skip for this
    scene: a few plain lines first (``decision_words.artist_lines``), then the engine's own under *Engine details*."""
    if not (state.decisions or state.viewer_notes):
        return
    opened = imgui.collapsing_header("Decisions")
    tooltip("What the engine and the viewer compute or skip for this scene, and why.")
    if not opened:
        return
    for line in artist_lines(state.decisions):
        imgui.bullet()
        imgui.text_wrapped(font_safe(line))
    details = decision_lines(state.decisions) + state.viewer_notes
    if details:
        imgui.text_disabled("Engine details")
    for line in details:
        imgui.bullet()
        imgui.text_wrapped(line)
