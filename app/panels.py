"""ImGui control panel: reads a ``PanelState``, returns a list of ``Command``s. No GL or rendering code here."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from imgui_bundle import imgui

VIEW_MODES = ("stylized", "original", "compare", "ground truth")


@dataclass(frozen=True)
class Param:
    """One engine parameter shown as a log-scale slider."""

    key: str
    label: str
    default: float
    low: float
    high: float
    tooltip: str


PARAMS = (
    Param("lambda_clip", "lambda CLIP", 10.0, 1e-2, 1e3,
          "Weight of the CLIP term: matches the style's large-scale patterns and layout of colour."),
    Param("lambda_nnfm", "lambda NNFM", 100.0, 1e-1, 1e4,
          "Weight of the nearest-neighbour feature matching term: brush strokes and local texture (VGG)."),
    Param("lambda_content", "lambda content", 0.05, 1e-4, 10.0,
          "Weight of content preservation: keeps the scene recognisable (VGG features of the photo)."),
    Param("lambda_tv", "lambda TV", 1e-4, 1e-7, 1e-1, "Weight of total variation: smooths noisy pixels."),
    Param("split_rate", "split rate", 0.05, 1e-3, 0.5,
          "Fraction of Gaussians split where the style gradient is largest (finer detail, more Gaussians)."),
    Param("lr", "learning rate", 0.1, 1e-3, 1.0, "Starting learning rate of the colour optimisation."),
)

HELP_TEXT = """Mouse: left drag orbit, right drag pan, wheel zoom. W/A/S/D/Q/E fly.
Space pause/resume   C compare   1-9 scene cameras   R reset view
Ctrl+S export .ply   F12 screenshot   H this help"""


@dataclass
class Command:
    """Something the user asked for; the app (not the panel) carries it out."""

    name: str
    args: dict[str, Any] = field(default_factory=dict)


@dataclass
class PanelState:
    """Everything the panel displays; the app fills it each frame."""

    scene_path: str = ""
    style_path: str = ""
    style_texture: int | None = None  # GL texture id of the style thumbnail
    style_size: tuple[int, int] = (1, 1)
    phase: str = "-"
    step: int = 0
    total_steps: int = 0
    eta_seconds: float | None = None
    gaussians: int = 0
    fps: float = 0.0
    paused: bool = False
    running: bool = False
    error: str | None = None
    status: str = ""
    loss_history: list[dict[str, float]] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=lambda: {p.key: p.default for p in PARAMS})
    view_mode: str = "stylized"
    has_ground_truth: bool = False
    camera_count: int = 0
    fov_deg: float = 50.0
    show_help: bool = False
    resume_available: bool = False  # a saved session of this scene + style exists (cache folder)
    decisions: dict[str, Any] = field(default_factory=dict)  # the engine's, as forwarded by the worker
    viewer_notes: list[str] = field(default_factory=list)  # what the viewer skips (SH, sorts, uploads)


def shortcut_commands(state: PanelState) -> list[Command]:
    """Keyboard shortcuts (ignored while a text field has focus)."""
    io = imgui.get_io()
    if io.want_text_input:
        return []
    out: list[Command] = []
    pressed = imgui.is_key_pressed
    if pressed(imgui.Key.space, False):
        out.append(Command("resume" if state.paused else "pause"))
    if pressed(imgui.Key.c, False) and not io.key_ctrl:
        out.append(Command("view_mode", {"mode": "stylized" if state.view_mode == "compare" else "compare"}))
    if pressed(imgui.Key.s, False) and io.key_ctrl:
        out.append(Command("export"))
    if pressed(imgui.Key.f12, False):
        out.append(Command("screenshot"))
    if pressed(imgui.Key.h, False):
        out.append(Command("toggle_help"))
    if pressed(imgui.Key.r, False) and not io.key_ctrl:
        out.append(Command("reset_camera"))
    for digit in range(1, 10):
        if pressed(getattr(imgui.Key, f"_{digit}"), False) and digit <= state.camera_count:
            out.append(Command("snap_camera", {"index": digit - 1}))
    return out


def format_eta(seconds: float | None) -> str:
    """``m:ss`` (or ``h:mm:ss``) for a remaining time; ``-`` when unknown."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "-"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def log_slider(label: str, value: float, low: float, high: float) -> tuple[bool, float]:
    """A float slider on a logarithmic scale (ImGui's logarithmic flag)."""
    return imgui.slider_float(label, float(value), low, high, "%.3g", imgui.SliderFlags_.logarithmic)


def draw_panel(state: PanelState) -> list[Command]:
    """Draw the control panel window and return the commands the user issued this frame."""
    out = shortcut_commands(state)
    imgui.set_next_window_pos(imgui.ImVec2(10, 10), imgui.Cond_.first_use_ever)
    imgui.set_next_window_size(imgui.ImVec2(330, 0), imgui.Cond_.first_use_ever)
    imgui.begin("G-Style Studio")
    _files_section(state, out)
    _progress_section(state, out)
    _decisions_section(state)
    _view_section(state, out)
    _params_section(state, out)
    _output_section(out)
    imgui.end()
    if state.show_help:
        _help_overlay()
    return out


def _files_section(state: PanelState, out: list[Command]) -> None:
    imgui.text_wrapped(f"Scene: {state.scene_path or '(none)'}")
    if imgui.button("Open scene..."):
        out.append(Command("open_scene"))
    imgui.same_line()
    if imgui.button("Open style..."):
        out.append(Command("open_style"))
    imgui.text_wrapped(f"Style: {state.style_path or '(none)'}")
    if state.style_texture is not None:
        w, h = state.style_size
        scale = 120.0 / max(w, h, 1)
        imgui.image(imgui.ImTextureRef(state.style_texture), imgui.ImVec2(w * scale, h * scale))


def _progress_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    imgui.text(f"Phase: {state.phase}")
    imgui.text(f"Gaussians: {state.gaussians:,}   {state.fps:.1f} fps")
    fraction = state.step / state.total_steps if state.total_steps else 0.0
    imgui.progress_bar(min(max(fraction, 0.0), 1.0), imgui.ImVec2(-1, 0),
                       f"{state.step}/{state.total_steps}  ETA {format_eta(state.eta_seconds)}")
    if imgui.button("Resume" if state.paused else "Pause"):
        out.append(Command("resume" if state.paused else "pause"))
    imgui.same_line()
    if imgui.button("Step"):
        out.append(Command("step"))
    imgui.same_line()
    if imgui.button("Restart"):
        out.append(Command("restart"))
    if state.resume_available:
        if imgui.button("Resume last session"):
            out.append(Command("resume_session"))
        imgui.set_item_tooltip("Continue the stylization saved when the studio last closed with this scene and style.")
    if state.error:
        imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.35, 0.3, 1.0))
        imgui.text_wrapped(f"Error: {state.error}")
        imgui.pop_style_color()
    if state.status:
        imgui.text_wrapped(state.status)
    _loss_plot(state.loss_history)


def _loss_plot(history: list[dict[str, float]]) -> None:
    if not history:
        return
    try:
        from imgui_bundle import implot
    except ImportError:
        return
    keys = sorted({k for h in history for k in h})
    if not keys:
        return
    if implot.begin_plot("Losses", imgui.ImVec2(-1, 140)):
        implot.setup_axes("step", "loss", implot.AxisFlags_.auto_fit, implot.AxisFlags_.auto_fit)
        implot.setup_axis_scale(implot.ImAxis_.y1, implot.Scale_.log10)
        for key in keys:
            ys = np.array([h.get(key, np.nan) for h in history], np.float64)
            ys = np.where(ys > 0, ys, np.nan)
            implot.plot_line(key, np.arange(len(ys), dtype=np.float64), ys)
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


def _decisions_section(state: PanelState) -> None:
    """Collapsible list of what the engine and the viewer decided to compute or skip for this scene."""
    if not (state.decisions or state.viewer_notes):
        return
    if imgui.collapsing_header("Decisions"):
        for line in decision_lines(state.decisions) + state.viewer_notes:
            imgui.bullet()
            imgui.text_wrapped(line)


def _view_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    for mode in VIEW_MODES:
        if mode == "ground truth" and not state.has_ground_truth:
            imgui.begin_disabled()
            imgui.radio_button(mode, False)
            imgui.end_disabled()
        elif imgui.radio_button(mode, state.view_mode == mode) and state.view_mode != mode:
            out.append(Command("view_mode", {"mode": mode}))
        if mode != VIEW_MODES[-1]:
            imgui.same_line()
    changed, fov = imgui.slider_float("fov", state.fov_deg, 10.0, 120.0, "%.0f deg")
    if changed:
        out.append(Command("fov", {"degrees": fov}))
    if imgui.button("Reset view"):
        out.append(Command("reset_camera"))
    if state.camera_count:
        imgui.same_line()
        imgui.text(f"scene cameras: 1-{min(state.camera_count, 9)}")


def _params_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    for p in PARAMS:
        imgui.push_id(p.key)
        value = state.params.get(p.key, p.default)
        imgui.set_next_item_width(170)
        changed, new = log_slider(p.label, value, p.low, p.high)
        imgui.set_item_tooltip(p.tooltip)
        if changed:
            out.append(Command("set_params", {p.key: float(new)}))
        imgui.same_line()
        if imgui.small_button("reset"):
            out.append(Command("set_params", {p.key: p.default}))
        imgui.pop_id()


def _output_section(out: list[Command]) -> None:
    imgui.separator()
    if imgui.button("Export .ply (Ctrl+S)"):
        out.append(Command("export"))
    imgui.same_line()
    if imgui.button("Screenshot (F12)"):
        out.append(Command("screenshot"))


def _help_overlay() -> None:
    viewport = imgui.get_main_viewport()
    imgui.set_next_window_pos(imgui.ImVec2(viewport.size.x * 0.5, viewport.size.y * 0.5), imgui.Cond_.always,
                              imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_bg_alpha(0.85)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
             | imgui.WindowFlags_.no_inputs)
    imgui.begin("help", None, flags)
    imgui.text(HELP_TEXT)
    imgui.end()
