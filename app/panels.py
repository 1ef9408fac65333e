"""ImGui control panel: reads a ``PanelState``, returns a list of ``Command``s. No GL or rendering code here."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from imgui_bundle import imgui

from gstyle_core.pipeline.controls import control, panel_controls

VIEW_MODES = ("stylized", "original", "compare", "ground truth", "take")
TURNTABLE_FORMATS = ("mp4", "gif", "png frames")
MAX_TURNTABLE_FRAMES = 3600
PANEL_WIDTH = 420.0  # wide enough for a λ row with the substitute's name and its reset button


@dataclass(frozen=True)
class Param:
    """One engine parameter shown as a slider (a row of ``gstyle_core.pipeline.controls``); a loss term's λ also
    gets an on/off checkbox."""

    key: str
    label: str
    default: float
    low: float
    high: float
    tooltip: str
    log: bool = True
    fmt: str = "%.3g"

    @property
    def is_term(self) -> bool:
        """True for a loss term's weight (λ), which can be switched off (weight 0) and on again."""
        return self.key.startswith("lambda_")


def param_rows() -> tuple[Param, ...]:
    """The parameter section's sliders: every live control shown as a slider there (``controls.panel_controls``)."""
    return tuple(Param(c.name, c.label, c.default, c.low, c.high, c.tooltip, c.log, c.fmt)
                 for c in panel_controls("slider"))


COARSE_CLIP_TOOLTIP = (
    "Weight of the coarse (CLIP substitute) term: no CLIP ViT-B/32 weights were found, so the style's large-scale "
    "colour and texture statistics (VGG features of 4x smaller images) are matched instead of CLIP's embedding.")
VIEW_TOOLTIPS = {
    "stylized": "The stylized scene as the engine has it now.",
    "original": "The input scene, with its view-dependent colour (SH) when it has any.",
    "compare": "Stylized left, original right; drag the white divider (C toggles).",
    "ground truth": "The colours the stylization is compared against (available once the engine sent them).",
    "take": "The take chosen under Takes (an earlier export), alone.",
}

HELP_TEXT = """Mouse: left drag orbit, right drag pan, wheel zoom. W/A/S/D/Q/E fly.
B region tool (Alt + drag / wheel: move / resize its box; Shift + drag: select by rectangle)
T compare with the next take (your exports)
Space pause/resume   C compare   1-9 scene cameras (all: the camera list)   R reset view
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
    style2_path: str = ""  # a second painting mixed in (empty: one painting)
    style2_texture: int | None = None
    style2_size: tuple[int, int] = (1, 1)
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
    params: dict[str, float] = field(default_factory=lambda: {p.key: p.default for p in param_rows()})
    view_mode: str = "stylized"
    has_ground_truth: bool = False
    camera_count: int = 0
    fov_deg: float = 50.0
    show_help: bool = False
    resume_available: bool = False  # a saved session of this scene + style exists (cache folder)
    decisions: dict[str, Any] = field(default_factory=dict)  # the engine's, as forwarded by the worker
    defaults: dict[str, float] = field(default_factory=dict)  # "reset" values: the preset the scene resolved to
    switched_off: dict[str, float] = field(default_factory=dict)  # λ of terms turned off, restored when turned on
    clip_name: str = "CLIP"  # what the CLIP term is: "CLIP" or "coarse (CLIP substitute)" without CLIP weights
    camera_names: list[str] = field(default_factory=list)
    camera_index: int = -1  # the scene camera last snapped to (-1: none)
    viewer_notes: list[str] = field(default_factory=list)  # what the viewer skips (SH, sorts, uploads)
    turntable_frames: int = 60
    turntable_format: str = "mp4"  # one of TURNTABLE_FORMATS
    video_running: bool = False  # a turntable video is being rendered in the background
    video_fraction: float = 0.0
    video_label: str = ""
    take_names: list[str] = field(default_factory=list)  # the last exports kept as takes, newest first
    take_labels: list[str] = field(default_factory=list)
    take_shown: int = -1  # the take loaded in the take view (-1: none)
    compare_with_take: bool = False  # the compare view's right side is that take (else the original)
    divider: float = 0.5  # the compare view's split, fraction of the width
    region_enabled: bool = False  # the selection tool is on: its selection is highlighted and used at (re)start
    region_mode: str = "box"  # "box" (the 3D box below) or "rectangle" (the last Shift + drag in the view)
    region_box: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # x0,y0,z0,x1,y1,z1 in scene coordinates
    region_selected: int = 0  # Gaussians of the input scene in the selection
    region_total: int = 0
    region_in_engine: str = ""  # what the running engine was started with ("" : the whole scene)
    region_outline: list[tuple[float, float, float, float]] = field(default_factory=list)  # box edges on screen
    region_drag: tuple[float, float, float, float] | None = None  # the rectangle being dragged (screen pixels)


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


def format_eta(seconds: float | None) -> str:
    """``m:ss`` (or ``h:mm:ss``) for a remaining time; ``-`` when unknown."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "-"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def param_slider(label: str, value: float, p: Param) -> tuple[bool, float]:
    """A parameter's float slider: its range and format, on a logarithmic scale when it has one."""
    flags = imgui.SliderFlags_.logarithmic if p.log else imgui.SliderFlags_.none
    return imgui.slider_float(label, float(value), p.low, p.high, p.fmt, flags)


def tooltip(text: str) -> None:
    """Tooltip of the last item, shown on hover even when the item is disabled."""
    if imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip | imgui.HoveredFlags_.allow_when_disabled):
        imgui.set_tooltip(text)


def button(label: str, tip: str, small: bool = False) -> bool:
    """A button with its tooltip; True when clicked."""
    clicked = imgui.small_button(label) if small else imgui.button(label)
    tooltip(tip)
    return clicked


def draw_panel(state: PanelState) -> list[Command]:
    """Draw the control panel window and return the commands the user issued this frame."""
    out = shortcut_commands(state)
    imgui.set_next_window_pos(imgui.ImVec2(10, 10), imgui.Cond_.first_use_ever)
    # As tall as its content (sections come and go: a second style, takes, a video's progress) but never taller
    # than the window: beyond that it scrolls.
    viewport = imgui.get_main_viewport()
    imgui.set_next_window_size_constraints(imgui.ImVec2(PANEL_WIDTH, 0),
                                           imgui.ImVec2(PANEL_WIDTH, max(100.0, viewport.size.y - 20)))
    imgui.begin("G-Style Studio", None, imgui.WindowFlags_.always_auto_resize)
    _files_section(state, out)
    _progress_section(state, out)
    _decisions_section(state)
    _view_section(state, out)
    _params_section(state, out)
    _region_section(state, out)
    _output_section(state, out)
    _takes_section(state, out)
    imgui.end()
    if state.view_mode == "compare":
        _compare_labels(state)
    _region_overlay(state)
    if state.show_help:
        _help_overlay()
    return out


def _files_section(state: PanelState, out: list[Command]) -> None:
    imgui.text_wrapped(f"Scene: {state.scene_path or '(none)'}")
    if button("Open scene...", "Open a Gaussian scene (.ply, .splat, .spz); dropping a file on the window works too."):
        out.append(Command("open_scene"))
    imgui.same_line()
    if button("Open style...", "Open a style image (the painting); dropping it on the window works too."):
        out.append(Command("open_style"))
    imgui.text_wrapped(f"Style: {state.style_path or '(none)'}")
    _thumbnail(state.style_texture, state.style_size)
    _second_style(state, out)


def _thumbnail(texture: int | None, size: tuple[int, int], side: float = 120.0) -> None:
    if texture is not None:
        w, h = size
        scale = side / max(w, h, 1)
        imgui.image(imgui.ImTextureRef(texture), imgui.ImVec2(w * scale, h * scale))


def _second_style(state: PanelState, out: list[Command]) -> None:
    """The second painting of a mix: open / remove it, its thumbnail and the mix slider."""
    if not state.style2_path:
        if button("Mix in a second style...", "Open a second painting to mix with the first (both their strokes, "
                                              "the weighted palette; the mix slider sets the shares)."):
            out.append(Command("open_style2"))
        return
    imgui.same_line()
    _thumbnail(state.style2_texture, state.style2_size, 60.0)
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


def _progress_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    imgui.text(f"Phase: {state.phase}")
    imgui.text(f"Gaussians: {state.gaussians:,}   {state.fps:.1f} fps")
    fraction = state.step / state.total_steps if state.total_steps else 0.0
    imgui.progress_bar(min(max(fraction, 0.0), 1.0), imgui.ImVec2(-1, 0),
                       f"{state.step}/{state.total_steps}  ETA {format_eta(state.eta_seconds)}")
    if state.paused:
        if button("Resume###pause", "Continue stepping the engine (Space)."):
            out.append(Command("resume"))
    elif button("Pause###pause", "Stop stepping after the current step; the view stays live (Space)."):
        out.append(Command("pause"))
    imgui.same_line()
    if button("Step", "Run exactly one engine step (useful while paused)."):
        out.append(Command("step"))
    imgui.same_line()
    if button("Restart", "Start the stylization again from the input scene with the current settings."):
        out.append(Command("restart"))
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
    _loss_plot(state.loss_history, state.clip_name)


def term_name(key: str, clip_name: str = "CLIP") -> str:
    """A loss key as labels show it: ``clip`` by what the term is (``clip_name``), the others as they are."""
    return clip_name if key == "clip" else key


def loss_series(history: list[dict[str, float]], clip_name: str = "CLIP") -> list[tuple[str, np.ndarray]]:
    """(legend label, values) per loss key in ``history``; missing or non-positive values are NaN (log axis)."""
    series = []
    for key in sorted({k for h in history for k in h}):
        ys = np.array([h.get(key, np.nan) for h in history], np.float64)
        series.append((term_name(key, clip_name), np.where(ys > 0, ys, np.nan)))
    return series


def _loss_plot(history: list[dict[str, float]], clip_name: str) -> None:
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


def _decisions_section(state: PanelState) -> None:
    """Collapsible list of what the engine and the viewer decided to compute or skip for this scene."""
    if not (state.decisions or state.viewer_notes):
        return
    opened = imgui.collapsing_header("Decisions")
    tooltip("What the engine and the viewer compute or skip for this scene, and why.")
    if opened:
        for line in decision_lines(state.decisions) + state.viewer_notes:
            imgui.bullet()
            imgui.text_wrapped(line)


def _view_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    for mode in VIEW_MODES:
        disabled = (mode == "ground truth" and not state.has_ground_truth) or (mode == "take" and state.take_shown < 0)
        imgui.begin_disabled(disabled)
        if imgui.radio_button(mode, state.view_mode == mode) and state.view_mode != mode and not disabled:
            out.append(Command("view_mode", {"mode": mode}))
        tooltip(VIEW_TOOLTIPS[mode])
        imgui.end_disabled()
        if mode not in (VIEW_MODES[-1], "compare"):  # two rows: the panel is narrower than five radio buttons
            imgui.same_line()
    changed, fov = imgui.slider_float("fov", state.fov_deg, 10.0, 120.0, "%.0f deg")
    tooltip("Vertical field of view of the viewer's camera.")
    if changed:
        out.append(Command("fov", {"degrees": fov}))
    if button("Reset view", "Back to the first scene camera's view (R)."):
        out.append(Command("reset_camera"))
    _camera_list(state, out)


def camera_label(index: int, names: list[str]) -> str:
    """``"3: name"`` (1-based, as the number keys count) for a scene camera."""
    name = names[index] if 0 <= index < len(names) else ""
    return f"{index + 1}: {name}" if name else f"{index + 1}"


def _camera_list(state: PanelState, out: list[Command]) -> None:
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


def default_value(state: PanelState, p: Param) -> float:
    """What "reset" restores: the value of the preset the scene resolved to (else the parameter's own default)."""
    return float(state.defaults.get(p.key, p.default))


def param_label(state: PanelState, p: Param) -> str:
    """The slider's label (the CLIP term by what it is)."""
    return f"lambda {state.clip_name}" if p.key == "lambda_clip" else p.label


def param_tooltip(state: PanelState, p: Param) -> str:
    """The slider's tooltip (the coarse substitute's own when there are no CLIP weights)."""
    return COARSE_CLIP_TOOLTIP if p.key == "lambda_clip" and state.clip_name != "CLIP" else p.tooltip


def switch_command(state: PanelState, p: Param, on: bool) -> Command:
    """Turn a term off (weight 0, remembering its λ) or on again (the remembered λ, else the preset's)."""
    if not on:
        state.switched_off[p.key] = float(state.params.get(p.key, default_value(state, p)))
        return Command("set_params", {p.key: 0.0})
    value = state.switched_off.pop(p.key, 0.0) or default_value(state, p) or p.default
    return Command("set_params", {p.key: float(value)})


def _params_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    for p in param_rows():
        imgui.push_id(p.key)
        _param_row(state, p, out)
        imgui.pop_id()
    for c in panel_controls("checkbox"):  # keep colours
        changed, on = imgui.checkbox(c.label, bool(state.params.get(c.name, c.default)))
        tooltip(c.tooltip)
        if changed:
            out.append(Command("set_params", {c.name: float(on)}))
    if button("Reset all", "Every parameter back to the preset's value for this scene (keep colours too)."):
        values = {p.key: default_value(state, p) for p in param_rows()}
        values.update({c.name: float(state.defaults.get(c.name, c.default)) for c in panel_controls("checkbox")})
        out.append(Command("set_params", values))


def _param_row(state: PanelState, p: Param, out: list[Command]) -> None:
    """[on/off] slider [reset] of one parameter."""
    value = float(state.params.get(p.key, p.default))
    off = p.is_term and value <= 0
    if p.is_term:
        changed, on = imgui.checkbox("##on", not off)
        tooltip(f"Turn the {param_label(state, p)[len('lambda '):]} term on or off (off: weight 0, never computed).")
        if changed:
            out.append(switch_command(state, p, on))
        imgui.same_line()
    imgui.begin_disabled(off)
    imgui.set_next_item_width(96)  # room for the longest label, its reset button and the panel's scrollbar
    shown = state.switched_off.get(p.key, default_value(state, p)) if off else value
    changed, new = param_slider(param_label(state, p), shown, p)
    tooltip(param_tooltip(state, p))
    if changed and not off:
        out.append(Command("set_params", {p.key: float(new)}))
    imgui.end_disabled()
    imgui.same_line()
    if button("reset", f"Back to the preset's value ({default_value(state, p):.3g}).", small=True):
        out.append(Command("set_params", {p.key: default_value(state, p)}))


REGION_TOOLTIP = (
    "Stylize only part of the scene: the Gaussians whose centres are in the box (it is drawn in the view: Alt + drag "
    "moves it, Alt + wheel resizes it, the numbers set it exactly), or, with Shift held, drag a rectangle in the view "
    "to select the Gaussians "
    "whose centres fall in it. The selection is drawn highlighted. Only the selected Gaussians are pre-processed, "
    "split and stylized, the losses see only them, and every other Gaussian is exported untouched (SH included). "
    "It applies when the run (re)starts (--region x0,y0,z0,x1,y1,z1). Shortcut: B.")


def _region_section(state: PanelState, out: list[Command]) -> None:
    flags = imgui.TreeNodeFlags_.default_open if state.region_enabled else 0
    opened = imgui.collapsing_header("Selected region", flags)
    tooltip(REGION_TOOLTIP)
    if not opened:
        return
    changed, on = imgui.checkbox("select a region", state.region_enabled)
    tooltip(REGION_TOOLTIP)
    if changed:
        out.append(Command("region_enable", {"on": bool(on)}))
    if state.region_enabled:
        box = list(state.region_box)
        step = max(1e-3, 0.005 * max(abs(box[3] - box[0]), abs(box[4] - box[1]), abs(box[5] - box[2]), 1e-3))
        ch_lo, lo = imgui.drag_float3("box min", box[:3], step, 0.0, 0.0, "%.3f")
        tooltip("The box's low corner (x0, y0, z0) in scene coordinates: drag to move that face, or type a value.")
        ch_hi, hi = imgui.drag_float3("box max", box[3:], step, 0.0, 0.0, "%.3f")
        tooltip("The box's high corner (x1, y1, z1) in scene coordinates.")
        if ch_lo or ch_hi:
            lo, hi = list(lo), list(hi)
            for k in range(3):  # a face dragged past the other pushes it along
                if ch_lo and lo[k] > hi[k]:
                    hi[k] = lo[k]
                if ch_hi and hi[k] < lo[k]:
                    lo[k] = hi[k]
            out.append(Command("region_box", {"box": tuple(float(v) for v in (*lo, *hi))}))
        if button("fit to scene", "Reset the box to the scene's bounds (every Gaussian selected).", small=True):
            out.append(Command("region_fit"))
        imgui.same_line()
        if button("restart with it", "Restart the stylization with this selection.", small=True):
            out.append(Command("restart"))
        how = "box" if state.region_mode == "box" else "rectangle (Shift + drag; move the box to go back to it)"
        imgui.text_wrapped(f"{state.region_selected:,} of {state.region_total:,} Gaussians selected by the {how}")
        imgui.text_wrapped("In the view: Alt + drag moves the box, Alt + wheel resizes it; Shift + drag selects the "
                           "Gaussians whose centres fall in a rectangle.")
    if state.region_in_engine:
        imgui.text_wrapped(f"running with {state.region_in_engine}")


def _region_overlay(state: PanelState) -> None:
    """The region box's edges and the rectangle being dragged, over the scene view."""
    if not state.region_enabled or not (state.region_outline or state.region_drag):
        return
    draw = imgui.get_background_draw_list()
    colour = imgui.get_color_u32(imgui.ImVec4(1.0, 0.62, 0.1, 0.9))
    for x0, y0, x1, y1 in state.region_outline:
        draw.add_line(imgui.ImVec2(x0, y0), imgui.ImVec2(x1, y1), colour, 1.5)
    if state.region_drag is not None:
        x0, y0, x1, y1 = state.region_drag
        draw.add_rect(imgui.ImVec2(min(x0, x1), min(y0, y1)), imgui.ImVec2(max(x0, x1), max(y0, y1)), colour,
                      rounding=0.0, thickness=1.5)


def _output_section(state: PanelState, out: list[Command]) -> None:
    imgui.separator()
    if button("Export .ply (Ctrl+S)", "Save the stylized scene as .ply with a .json summary in the output folder."):
        out.append(Command("export"))
    imgui.same_line()
    if button("Screenshot (F12)", "Save the current view as PNG in the output folder."):
        out.append(Command("screenshot"))
    if button("Export .spz", "Save the stylized scene for web viewers as Niantic .spz (about 10x smaller than .ply) "
                             "with a .json summary in the output folder."):
        out.append(Command("export", {"format": "spz"}))
    imgui.same_line()
    if button("Export .compressed.ply", "Save the stylized scene for web viewers as PlayCanvas / SuperSplat "
                                        "compressed PLY with a .json summary in the output folder."):
        out.append(Command("export", {"format": "compressed-ply"}))
    _video_row(state, out)


def _video_row(state: PanelState, out: list[Command]) -> None:
    """"Turntable video..." with its frame count and format, or, while one renders, its progress and Cancel."""
    if state.video_running:
        imgui.progress_bar(min(max(state.video_fraction, 0.0), 1.0), imgui.ImVec2(-80, 0), state.video_label)
        imgui.same_line()
        if button("Cancel###video", "Stop the turntable video; nothing is written."):
            out.append(Command("cancel_video"))
        return
    if button("Turntable video...", "Render frames orbiting the scene (the stylized one while an engine runs, else "
                                    "the input) into the output folder, in the background; the studio stays live."):
        out.append(Command("turntable", {"frames": state.turntable_frames, "format": state.turntable_format}))
    imgui.same_line()
    imgui.set_next_item_width(70)
    changed, frames = imgui.input_int("##turntable_frames", state.turntable_frames, 0, 0)
    tooltip("How many frames the turntable has (one full turn).")
    if changed:
        out.append(Command("turntable_settings", {"frames": int(min(max(frames, 1), MAX_TURNTABLE_FRAMES))}))
    imgui.same_line()
    imgui.set_next_item_width(100)
    if imgui.begin_combo("##turntable_format", state.turntable_format):
        for fmt in TURNTABLE_FORMATS:
            if imgui.selectable(fmt, fmt == state.turntable_format)[0]:
                out.append(Command("turntable_settings", {"format": fmt}))
            tooltip(f"Write the turntable as {fmt}.")
        imgui.end_combo()
    tooltip("MP4 (H.264), an animated GIF, or a folder of numbered PNG frames.")


def _takes_section(state: PanelState, out: list[Command]) -> None:
    """The last exports as named takes: compare one with the current run (or the original), view it, rename it."""
    if not state.take_names:
        return
    opened = imgui.collapsing_header("Takes", imgui.TreeNodeFlags_.default_open)
    tooltip("Your last exports, kept to switch between and compare side by side with the current run.")
    if not opened:
        return
    current = (state.take_names[state.take_shown] if state.compare_with_take and state.take_shown >= 0
               else "the original")
    imgui.set_next_item_width(180)
    if imgui.begin_combo("compare with", current):
        if imgui.selectable("the original", not state.compare_with_take)[0]:
            out.append(Command("compare_original"))
        for i, name in enumerate(state.take_names):
            if imgui.selectable(f"{name}##take{i}", state.compare_with_take and i == state.take_shown)[0]:
                out.append(Command("show_take", {"index": i, "compare": True}))
        imgui.end_combo()
    tooltip("What the compare view shows right of the divider: the input scene, or one of your takes (the current "
            "run stays on the left; C toggles the compare view).")
    for i, name in enumerate(state.take_names):
        imgui.push_id(f"take{i}")
        imgui.set_next_item_width(120)
        changed, text = imgui.input_text("##name", name)
        tooltip(state.take_labels[i] if i < len(state.take_labels) else name)
        if changed and text.strip():
            out.append(Command("rename_take", {"index": i, "name": text}))
        imgui.same_line()
        if button("compare", "Stylized now on the left, this take on the right (drag the divider).", small=True):
            out.append(Command("show_take", {"index": i, "compare": True}))
        imgui.same_line()
        if button("view", "Show this take alone.", small=True):
            out.append(Command("show_take", {"index": i, "compare": False}))
        imgui.same_line()
        if button("forget", "Take it off this list (its file stays in the output folder).", small=True):
            out.append(Command("forget_take", {"index": i}))
        imgui.pop_id()


def _compare_labels(state: PanelState) -> None:
    """Names of the two sides of the compare view, at the top beside the divider."""
    viewport = imgui.get_main_viewport()
    x = viewport.pos.x + viewport.size.x * min(max(state.divider, 0.0), 1.0)
    right = (state.take_names[state.take_shown] if state.compare_with_take and 0 <= state.take_shown
             < len(state.take_names) else "original")
    draw = imgui.get_foreground_draw_list()
    colour = imgui.get_color_u32(imgui.ImVec4(1.0, 1.0, 1.0, 0.9))
    left = "now"
    y = viewport.pos.y + viewport.size.y - 28
    draw.add_text(imgui.ImVec2(x - 10 - imgui.calc_text_size(left).x, y), colour, left)
    draw.add_text(imgui.ImVec2(x + 10, y), colour, right)


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
