"""The panel's selected-region section and its overlay in the view (the selection's outline, the box's edges, the
rectangle being dragged)."""

from __future__ import annotations

from imgui_bundle import imgui

from .state import Command, PanelState
from .widgets import button, tooltip

REGION_TOOLTIP = (
    "Stylize only part of the scene: the Gaussians whose centres are in the box (it is drawn in the view: Alt + drag "
    "moves it, Alt + wheel resizes it, the numbers set it exactly), or, with Shift held, drag a rectangle in the view "
    "to select the Gaussians "
    "whose centres fall in it. The selection is outlined in every view. Only the selected Gaussians are pre-processed, "
    "split and stylized, the losses see only them, and every other Gaussian is exported untouched (SH included). "
    "The feather fades the style out over a band outside the box. "
    "It applies when the run (re)starts (--region x0,y0,z0,x1,y1,z1). Shortcut: B.")


def region_section(state: PanelState, out: list[Command]) -> None:
    """The selection tool: on/off, the box's corners, fit / restart, how many Gaussians it selects."""
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
        if state.region_mode == "box":
            size = max(box[3] - box[0], box[4] - box[1], box[5] - box[2], 1e-3)
            ch_f, feather = imgui.slider_float("feather", state.region_feather, 0.0, 0.5 * size, "%.3f")
            tooltip("The box's soft edge, in scene units: the style fades out over this distance outside the box "
                    "instead of stopping at its faces (0: a hard edge). It applies when the run (re)starts "
                    "(--region-feather).")
            if ch_f:
                out.append(Command("region_feather", {"value": float(feather)}))
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


def region_overlay(state: PanelState) -> None:
    """The region box's edges and the rectangle being dragged, over the scene view."""
    if not state.region_enabled or not (state.region_outline or state.region_drag or state.selection_outline):
        return
    draw = imgui.get_background_draw_list()
    colour = imgui.get_color_u32(imgui.ImVec4(1.0, 0.62, 0.1, 0.9))
    shadow = imgui.get_color_u32(imgui.ImVec4(0.0, 0.0, 0.0, 0.8))
    ox, oy, width, height = state.view_rect
    draw.push_clip_rect(imgui.ImVec2(ox, oy), imgui.ImVec2(ox + width, oy + height))
    for x0, y0, x1, y1 in state.selection_outline:  # what is selected: a gold line on a dark one, any background
        a, b = imgui.ImVec2(ox + x0, oy + y0), imgui.ImVec2(ox + x1, oy + y1)
        draw.add_line(a, b, shadow, 3.0)
        draw.add_line(a, b, colour, 1.5)
    for x0, y0, x1, y1 in state.region_outline:
        draw.add_line(imgui.ImVec2(ox + x0, oy + y0), imgui.ImVec2(ox + x1, oy + y1), colour, 1.5)
    if state.region_drag is not None:
        x0, y0, x1, y1 = state.region_drag
        draw.add_rect(imgui.ImVec2(ox + min(x0, x1), oy + min(y0, y1)),
                      imgui.ImVec2(ox + max(x0, x1), oy + max(y0, y1)), colour, rounding=0.0, thickness=1.5)
    draw.pop_clip_rect()
