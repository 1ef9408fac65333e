"""The panel's top: the scene and painting(s) (files section), the run's progress, controls and losses, and the
engine's decisions."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from imgui_bundle import imgui

from gstyle_core.pipeline.controls import control, term_label

from .state import Command, PanelState
from .widgets import button, button_row, thumbnail, tooltip


def files_section(state: PanelState, out: list[Command]) -> None:
    """The scene and the painting(s): their paths, thumbnails and open buttons."""
    imgui.text_wrapped(f"Scene: {state.scene_path or '(none)'}")
    if button("Open scene...", "Open a Gaussian scene (.ply, .splat, .spz); dropping a file on the window works too."):
        out.append(Command("open_scene"))
    imgui.same_line()
    if button("Open style...", "Open a style image (the painting); dropping it on the window works too."):
        out.append(Command("open_style"))
    imgui.text_wrapped(f"Style: {state.style_path or '(none)'}")
    thumbnail(state.style_texture, state.style_size)
    second_style(state, out)


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
    imgui.set_next_item_width(150)
    row = control("style_mix")
    mix = float(state.params.get(row.name, 0.5))
    changed, mix = imgui.slider_float(row.label, mix, row.low, row.high, row.fmt)
    tooltip(row.tooltip)
    if changed:
        out.append(Command("set_params", {row.name: float(min(max(mix, row.low), row.high))}))
    imgui.same_line()
    if button("remove", "Back to the first painting alone (restarts the stylization).", small=True):
        out.append(Command("remove_style2"))


def progress_section(state: PanelState, out: list[Command]) -> None:
    """Phase, step and ETA, pause / step / restart / resume, errors, status and the loss plot."""
    imgui.separator()
    imgui.text(f"Phase: {state.phase}")
    imgui.text(f"Gaussians: {state.gaussians:,}   {state.fps:.1f} fps")
    fraction = state.step / state.total_steps if state.total_steps else 0.0
    imgui.progress_bar(min(max(fraction, 0.0), 1.0), imgui.ImVec2(-1, 0),
                       f"{state.step}/{state.total_steps}  ETA {format_eta(state.eta_seconds)}")
    pause = (("Resume###pause", "Continue stepping the engine (Space).", Command("resume")) if state.paused else
             ("Pause###pause", "Stop stepping after the current step; the view stays live (Space).", Command("pause")))
    button_row(out, pause, ("Step", "Run exactly one engine step (useful while paused).", Command("step")),
               ("Restart", "Start the stylization again from the input scene with the current settings.",
                Command("restart")))
    if state.resume_available and button(
            "Resume last session", "Continue the stylization saved when the studio last closed with this scene and "
            "style."):
        out.append(Command("resume_session"))
    if state.error:
        imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.35, 0.3, 1.0))
        imgui.text_wrapped(f"Error: {state.error}")
        imgui.pop_style_color()
    if state.status:
        imgui.text_wrapped(state.status)
    loss_plot(state.loss_history, state.clip_name)


def format_eta(seconds: float | None) -> str:
    """``m:ss`` (or ``h:mm:ss``) for a remaining time; ``-`` when unknown."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "-"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def term_name(key: str, clip_name: str = "CLIP") -> str:
    """A loss key as labels show it: ``clip`` by what the term is (``clip_name``), the others by their λ row's label
    (``multiscale``: "broad strokes")."""
    return clip_name if key == "clip" else term_label(key)


def loss_series(history: list[dict[str, float]], clip_name: str = "CLIP") -> list[tuple[str, np.ndarray]]:
    """(legend label, values) per loss key in ``history``; missing or non-positive values are NaN (log axis); a
    term never computed (no positive value: switched off) has no series."""
    series = []
    for key in sorted({k for h in history for k in h}):
        ys = np.array([h.get(key, np.nan) for h in history], np.float64)
        if not np.any(ys > 0):
            continue
        series.append((term_name(key, clip_name), np.where(ys > 0, ys, np.nan)))
    return series


def loss_plot(history: list[dict[str, float]], clip_name: str) -> None:
    """The losses so far on a log axis (nothing without implot or history)."""
    series = loss_series(history, clip_name)
    if not series:
        return
    try:
        from imgui_bundle import implot
    except ImportError:
        return
    if implot.begin_plot("Losses", imgui.ImVec2(-1, 140)):
        implot.setup_axes("step", "loss", implot.AxisFlags_.auto_fit, implot.AxisFlags_.auto_fit)
        implot.setup_axis_scale(implot.ImAxis_.y1, implot.Scale_.log10)
        for label, ys in series:
            implot.plot_line(label, np.arange(len(ys), dtype=np.float64), ys)
        implot.end_plot()


def decision_lines(decisions: dict[str, Any]) -> list[str]:
    """One ``name: value`` line per engine decision (dicts as ``k=v`` lists, lists joined with ``;``)."""
    lines = []
    for key, value in decisions.items():
        if isinstance(value, dict):
            text = ", ".join(f"{k}={v}" for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            text = "; ".join(str(v) for v in value)
        else:
            text = str(value)
        lines.append(f"{key.replace('_', ' ')}: {text}")
    return lines


def decisions_section(state: PanelState) -> None:
    """Collapsible list of what the engine and the viewer decided to compute or skip for this scene."""
    if not (state.decisions or state.viewer_notes):
        return
    opened = imgui.collapsing_header("Decisions")
    tooltip("What the engine and the viewer compute or skip for this scene, and why.")
    if opened:
        for line in decision_lines(state.decisions) + state.viewer_notes:
            imgui.bullet()
            imgui.text_wrapped(line)
