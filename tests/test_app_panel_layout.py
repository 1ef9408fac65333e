"""The panel at the studio's default window size (issue #48 item 4.5): the mouse wheel scrolls it wherever the pointer
is (over the loss plot and its legend too), every widget with its label fits its width, and it speaks an artist's
words (the result's grain, the sliders) with the engine's terms in the tooltips (headless GL window)."""

import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from imgui_bundle import imgui  # noqa: E402
from imgui_driver import PanelDriver, install  # noqa: E402

from app.panels import PanelState, draw_panel, loss_series, run_sections  # noqa: E402
from app.window_size import DEFAULT_SIZE  # noqa: E402
from gstyle_core.engine.controls import CONTROLS, term_label  # noqa: E402
from gstyle_core.engine.settings import resolve_settings, ui_params  # noqa: E402

W, H = DEFAULT_SIZE
TERMS = ("clip", "nnfm", "multiscale", "content", "tv", "chroma_tv", "edges", "refit")


def full_state() -> PanelState:
    """A panel with every section filled: a finished run with its losses, estimates, levels, its grain figure, two
    paintings, the region tool on, decisions."""
    params = ui_params(resolve_settings("preview", "360", 4, clip_available=False))
    state = PanelState(params=dict(params), defaults=dict(params), phase="done", step=233, total_steps=233)
    state.loss_history = [{"step": float(i), **{k: 1.0 + j + i for j, k in enumerate(TERMS)}} for i in range(60)]
    state.quality_estimates = {"preview": 3723.0, "balanced": 13_000.0, "final": 40_000.0}  # h:mm:ss, the longest
    state.preset, state.levels, state.width, state.next_width = "preview", [256, 512, 1024], 1024, None
    state.summary_line, state.grain = "speckle at 1024 px (chroma finer than sigma 4 px ...): 0.61", "0.61"
    state.style_path, state.style2_path = "/data/styles/starry_night_vangogh.jpg", "/data/styles/great_wave.jpg"
    state.params["style_mix"] = 0.5
    state.region_enabled, state.region_box, state.region_total = True, (-1.5, -2.0, -1.0, 1.5, 2.0, 1.0), 40_000
    state.decisions = {"clip": "coarse substitute", "levels": "256 px -> 512 px -> 1024 px"}
    state.undo_note, state.redo_note = "brush strokes back to 200", "the result after restart (result_1.ply)"
    state.camera_count, state.camera_names = 3, ["orbit_000", "orbit_001", "orbit_002"]
    return state


@pytest.fixture
def panel(window, monkeypatch):
    """(driver, state, rects): the full panel alone; ``rects`` gets the loss plot's and the status box's
    rectangles (x0, y0, x1, y1) as drawn in the last frame."""
    state, rects = full_state(), {}
    for name in ("loss_plot", "status_box"):
        drawn = getattr(run_sections, name)

        def recording(*args, _drawn=drawn, _name=name):
            _drawn(*args)
            lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
            rects[_name] = (lo.x, lo.y, hi.x, hi.y)

        monkeypatch.setattr(run_sections, name, recording)
    driver = PanelDriver(window, install(monkeypatch), lambda: draw_panel(state))
    return driver, state, rects


def panel_scroll() -> float:
    """How far the panel's window is scrolled down now (pixels)."""
    return imgui.internal.find_window_by_name("G-Style Studio").scroll.y


def test_the_wheel_scrolls_the_panel_wherever_the_pointer_is_on_it(panel):
    """One notch scrolls the panel one step (ImGui's: five lines) over the loss plot, its legend below it and the
    status box; never two steps. With every term on (eight lines in the plot) the legend, laid out in one row, did
    not fit, scrolled itself and kept the wheel: it is a term a line now, in room made for it."""
    driver, state, rects = panel
    state.params.update(lambda_clip=10.0, lambda_edges=4000.0)
    driver.frame()
    step = 5 * imgui.get_font_size()
    for name, fy in (("loss_plot", 0.3), ("loss_plot", 0.8), ("loss_plot", 0.95), ("status_box", 0.5)):
        driver.frame(lambda io: io.add_mouse_pos_event(200, 40))  # over the scene's path: back to the top
        driver.frame(lambda io: io.add_mouse_wheel_event(0, 50))
        driver.frame()
        x0, y0, x1, y1 = rects[name]
        x, y = (x0 + x1) / 2, y0 + fy * (y1 - y0)
        driver.frame(lambda io, x=x, y=y: io.add_mouse_pos_event(x, y))
        driver.frame()  # the pointer rests there (what it hovers is known from the frame after it came)
        assert panel_scroll() == 0.0
        driver.frame(lambda io: io.add_mouse_wheel_event(0, -1))
        driver.frame()
        driver.frame()
        assert panel_scroll() == pytest.approx(step), (name, fy)


def test_every_widget_and_its_label_fit_the_panel_at_the_default_size(panel):
    """Nothing is cut at the right edge (the quality choices were, side by side): each drawn widget, a slider with
    its label, ends left of the panel's scrollbar; the Decisions and the region sections open."""
    driver, state, _ = panel
    driver.click("Decisions")
    driver.frame()
    right = state.panel_rect[2] - imgui.get_style().scrollbar_size
    spacing = imgui.get_style().item_inner_spacing.x
    drawn = driver.recorder.widgets
    assert {w.path.split("###")[1] for w in drawn if "###q_" in w.path} == {"q_preview", "q_balanced", "q_final"}
    assert any(w.path.endswith("box min") for w in drawn)  # the region section is open
    cut = []
    for w in drawn:
        end = w.rect[2]
        if w.kind in ("slider_float", "drag_float3"):
            label = w.path.split("/")[-1].split("##")[0]
            end += (imgui.calc_text_size(label).x + spacing) if label else 0.0
        if end > right + 0.5:
            cut.append((w.path, round(end)))
    assert cut == [], f"past {right:.0f} px: {cut}"


def test_the_panel_says_the_grain_and_the_sliders_in_an_artists_words(panel):
    driver, state, _ = panel
    driver.frame()
    assert "Fine grain at screen size: 0.61 (1 = the painting's own)" in driver.recorder.texts
    assert not [t for t in driver.recorder.texts if "speckle" in t]  # the engine's line is in the tooltip only
    for row in CONTROLS:
        assert "lambda" not in row.label and "_" not in row.label, row.label
        if row.name.startswith("lambda_"):  # the engine's term names stay in the tooltip
            assert row.name in row.tooltip, row.name
    words = {row.name: row.label for row in CONTROLS if row.name.startswith("lambda_")}
    assert words == {"lambda_clip": "large patterns", "lambda_nnfm": "brush strokes",
                     "lambda_multiscale": "broad strokes", "lambda_content": "keep the scene",
                     "lambda_tv": "smoothness", "lambda_chroma_tv": "colour smoothness", "lambda_edges": "edges kept"}
    assert driver.recorder.find("lambda_nnfm/brush strokes").tooltip.startswith("Brush strokes")
    assert driver.recorder.find("lambda_nnfm/##on").tooltip.startswith("Turn brush strokes on or off")
    assert [term_label(t) for t in ("nnfm", "content", "refit")] == ["brush strokes", "keep the scene", "refit"]
    legend = [label for label, *_ in loss_series(state.loss_history)]
    assert "brush strokes" in legend and "large patterns" in legend and "NNFM" not in legend


def test_a_status_line_never_moves_the_controls_and_the_error_stays_above_the_plot(panel, monkeypatch):
    """Issue #65 item 4: the status box is at the panel's top at a fixed height: no status, a short one or one longer
    than the box (it scrolls in it) leave every control where it was; a long error is wrapped above the loss plot."""
    driver, state, rects = panel
    drawn = {}
    for status in ("", "opened scene.ply (59,000 Gaussians)", "could not open broken.ply: truncated " * 12):
        state.status = status
        driver.frame()
        driver.frame()
        drawn[status] = ({w.path: w.rect for w in driver.recorder.widgets}, rects["status_box"])
    (first, box), *others = drawn.values()
    for widgets, other_box in others:
        assert other_box == box and widgets == first
    assert box[3] <= first["Open scene..."][1]  # above the controls
    error_end = {}

    def error_block(*args, _drawn=run_sections.error_block):
        _drawn(*args)
        error_end["y"] = imgui.get_item_rect_max().y

    monkeypatch.setattr(run_sections, "error_block", error_block)
    state.error = "cannot read /data/scenes/a_very_long_folder_name/truncated_capture.ply: " + "it ends early " * 8
    driver.frame()
    assert any(t.startswith("Error: cannot read") for t in driver.recorder.texts)
    assert error_end["y"] <= rects["loss_plot"][1]
    assert all(w.rect[2] <= W for w in driver.recorder.widgets)
