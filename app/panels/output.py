"""The panel's output sections: exports, screenshot, turntable video, and the takes (the last exports)."""

from __future__ import annotations

from imgui_bundle import imgui

from .state import MAX_TURNTABLE_FRAMES, TURNTABLE_FORMATS, Command, PanelState
from .widgets import button, button_row, thumbnail, tooltip


def output_section(state: PanelState, out: list[Command]) -> None:
    """Export buttons (.ply, .spz, .compressed.ply, .sog), screenshots (window, scene view) and the turntable video
    row."""
    imgui.separator()
    imgui.text_wrapped(f"Saves into: {state.save_folder}")
    tooltip("Where Ctrl+S and the export buttons write: the folder saved to last (Save As), else beside the scene "
            "you opened, else the output folder.")
    imgui.text_wrapped(f"Output folder: {state.output_folder}")
    tooltip("The studio's output folder (--output-dir, else out/ where the studio was started, made absolute when it "
            "started): screenshots, turntable videos, the takes' list (takes.json) and exports when no other folder "
            "applies.")
    button_row(out, ("Save As... (Ctrl+Shift+S)", "Save the stylized scene under a name and folder you choose (.ply, "
                                                  ".spz, .compressed.ply or .sog, with a .json summary); Ctrl+S "
                                                  "writes there from then on.", Command("save_as")))
    button_row(out, ("Export .ply (Ctrl+S)", "Save the stylized scene as .ply with a .json summary in the folder "
                                             "shown above.", Command("export")),
               ("Export .spz", "Save the stylized scene for web viewers as Niantic .spz (about 10x smaller than .ply) "
                               "with a .json summary in the folder shown above.", Command("export", {"format": "spz"})))
    button_row(out, ("Export .compressed.ply", "Save the stylized scene for web viewers as PlayCanvas / SuperSplat "
                                               "compressed PLY with a .json summary in the folder shown above.",
                     Command("export", {"format": "compressed-ply"})),
               ("Export .sog", "Save the stylized scene as PlayCanvas SOG (one .sog file of lossless WebP images, "
                               "what SuperSplat publishes; about 15x smaller than .ply) with a .json summary in the "
                               "folder shown above.", Command("export", {"format": "sog"})))
    button_row(out, ("Screenshot (F12)", "Save the whole window (panel and overlays included) as PNG in the output "
                                         "folder.", Command("screenshot", {"scene_only": False})),
               ("Scene only (Shift+F12)", "Save the scene view alone (its size, no panel or overlays) as PNG in the "
                                          "output folder.", Command("screenshot", {"scene_only": True})))
    video_row(state, out)


def video_row(state: PanelState, out: list[Command]) -> None:
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


def takes_section(state: PanelState, out: list[Command]) -> None:
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
        shown = state.take_thumbnails[i] if i < len(state.take_thumbnails) else None
        if shown is not None:
            thumbnail(shown[0], shown[1], 48.0)
            tooltip(state.take_labels[i] if i < len(state.take_labels) else name)
            imgui.same_line()
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
        if i < len(state.take_settings) and state.take_settings[i]:
            imgui.text_disabled(f"  {state.take_settings[i]}")
        imgui.pop_id()
