"""Every studio control does what it says (issue #17): clicked headless through the real ImGui panel."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import BUILT, keep_small_stylizer  # noqa: E402
from imgui_driver import panel_alone, paused_studio_driver, studio_driver  # noqa: E402
from synthetic import blob_scene, ring_cameras  # noqa: E402

from app.panels import PanelState, loss_series, param_rows  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from gstyle_core.engine.controls import control  # noqa: E402
from gstyle_core.engine.settings import resolve_settings, ui_params  # noqa: E402
from gstyle_core.style.clip import COARSE_NAME  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


def panel_state(**kw) -> PanelState:
    params = ui_params(resolve_settings("preview", "360", 4, clip_available=False))  # a 360° scene on a machine
    # without CLIP weights: the CLIP term off, the broad-strokes term on
    return PanelState(params=dict(params), defaults=dict(params), **kw)


@pytest.fixture
def panel(window, monkeypatch):
    """(driver, state): the panel alone, its set_params commands applied to the state as the studio does."""
    state = panel_state(camera_count=12, camera_names=[f"cam{i + 1}" for i in range(12)])
    return panel_alone(window, monkeypatch, state), state


def test_every_control_button_and_view_mode_has_a_tooltip(panel):
    driver, state = panel
    state.decisions, state.resume_available, state.paused = {"sh": "none"}, True, True
    driver.frame()
    drawn = driver.recorder.widgets
    kinds = {w.kind for w in drawn}
    assert {"button", "small_button", "checkbox", "radio_button", "slider_float", "begin_combo"} <= kinds
    radios = {w.path for w in drawn if w.kind == "radio_button"}
    assert {r for r in radios if "###q_" not in r} == {"stylized", "original", "compare", "ground truth", "take"}
    assert {r.split("###q_")[1] for r in radios if "###q_" in r} == {"preview", "balanced", "final"}  # the quality
    assert [w.path for w in drawn if not w.tooltip] == []


def test_camera_list_reaches_every_camera(panel):
    driver, _state = panel
    driver.click("##cameras")  # opens the list
    commands = driver.click("12: cam12")
    assert [(c.name, c.args) for c in commands] == [("snap_camera", {"index": 11})]


@pytest.mark.parametrize("key", ["lambda_nnfm", "lambda_multiscale"])
def test_each_term_switches_off_and_back_on(panel, key):
    driver, state = panel
    value = state.params[key]
    assert value > 0
    commands = driver.click(f"{key}/##on")
    assert [c.args for c in commands] == [{key: 0.0}]
    assert driver.click(f"{key}/{control(key).label}") == []  # its slider is disabled while off
    commands = driver.click(f"{key}/##on")
    assert [c.args for c in commands] == [{key: value}]


def test_the_clip_term_off_without_weights_turns_on_at_the_papers_weight(panel):
    driver, state = panel
    assert state.params["lambda_clip"] == 0.0
    commands = driver.click("lambda_clip/##on")
    assert [c.args for c in commands] == [{"lambda_clip": 10.0}]


def test_a_term_that_starts_at_zero_can_be_turned_on(panel):
    driver, state = panel
    state.params["lambda_content"] = 0.0
    commands = driver.click("lambda_content/##on")
    assert [c.args for c in commands] == [{"lambda_content": state.defaults["lambda_content"]}]


def test_coarse_substitute_is_named_so_in_the_sliders_tooltip(panel):
    """The slider and the plot say "large patterns" whatever the term is; the tooltip says it is the substitute."""
    driver, state = panel
    state.clip_name = COARSE_NAME
    driver.frame()
    slider = driver.recorder.find("lambda_clip/large patterns")
    assert "coarse (CLIP substitute)" in slider.tooltip and "no CLIP ViT-B/32 weights" in slider.tooltip
    state.clip_name = "CLIP"
    driver.frame()
    assert "CLIP ViT-B/32 embeddings" in driver.recorder.find("lambda_clip/large patterns").tooltip
    history = [{"clip": 1.0, "nnfm": 2.0, "multiscale": 3.0, "content": 0.0}]
    assert [label for label, *_ in loss_series(history)] == ["large patterns", "broad strokes", "brush strokes"]
    # (content: weight 0, never computed, no line in the plot)


def test_loss_plot_lines_are_named_at_their_steps_and_joined_across_other_steps():
    """Issue #27 item 6: terms recorded only on some steps (content, NNFM on stylize steps; refit on the refit
    steps between them) are continuous lines at the steps they were recorded at; a term switched off is left out."""
    history = [{"step": 10.0 + i, **({"refit": 0.5} if i % 3 else {"nnfm": 2.0 + i, "content": 1.0, "clip": 0.3})}
               for i in range(12)]
    series = {label: (xs, ys) for label, xs, ys in loss_series(history)}
    assert sorted(series) == sorted(["large patterns", "brush strokes", "keep the scene", "refit"])
    xs, ys = series["brush strokes"]
    assert np.array_equal(xs, [10, 13, 16, 19]) and np.array_equal(ys, [2, 5, 8, 11])
    assert len(series["refit"][0]) == 8
    assert "large patterns" not in [label for label, *_ in loss_series(history, frozenset({"clip"}))]
    relative = {label: ys for label, _, ys in loss_series(history, relative=True)}
    assert np.allclose(relative["brush strokes"], [1, 2.5, 4, 5.5]) and np.allclose(relative["keep the scene"], 1)


def test_studio_names_the_clip_term_by_the_weights_found(window, no_clip_weights, tmp_path):
    app = StudioApp(window.ctx, loaded=LoadedScene("s", blob_scene(50), ring_cameras(4)), output_dir=tmp_path)
    try:
        assert app.panel.clip_name == COARSE_NAME
    finally:
        app.close()


def test_reset_goes_to_the_presets_values_of_a_360_scene(window, monkeypatch, tmp_path):
    cams = ring_cameras(8, width=64, height=48)
    app = StudioApp(window.ctx, loaded=LoadedScene("ring", blob_scene(200), cams), output_dir=tmp_path)
    try:
        preset = ui_params(resolve_settings("preview", "360", len(cams)))
        assert (preset["lambda_nnfm"], preset["split_rate"], preset["lr"]) == (200.0, 0.02, 0.05)  # calibrated
        driver = studio_driver(window, monkeypatch, app)
        app.panel.params.update(lambda_nnfm=100.0, split_rate=0.05, lr=0.1, strength=3.0)
        driver.click("lambda_nnfm/reset")
        assert app.panel.params["lambda_nnfm"] == 200.0 and app.panel.params["lr"] == 0.1
        driver.click("Reset all")
        assert {p.key: app.panel.params[p.key] for p in param_rows()} == {p.key: preset[p.key] for p in param_rows()}
    finally:
        app.close()




def test_strength_slider_reaches_the_engine(window, monkeypatch, tmp_path):
    BUILT.clear()
    app = StudioApp(window.ctx, loaded=LoadedScene("ring", blob_scene(150, seed=5), ring_cameras(3)),
                    engine_factory=keep_small_stylizer, output_dir=tmp_path, worker_mode="thread")
    try:
        driver = paused_studio_driver(window, monkeypatch, app)
        commands = driver.click("strength/style strength", fx=0.9)
        assert commands and commands[0].name == "set_params" and commands[0].args["strength"] > 10
        asked = commands[-1].args["strength"]
        assert app.engine.bridge.wait_until(lambda s: s.params.get("strength") == asked, 30)
        assert BUILT[-1].settings.strength == pytest.approx(asked)
    finally:
        app.close()


def test_a_long_status_does_not_move_the_controls_below(panel):
    """Issue #27 item 9: after an export the status wraps to two lines; the buttons below stay where they were."""
    driver, state = panel
    where = []
    for status in ("", "exported /a/rather/long/output/folder/stylized_20261126_020001.ply (kept as take 3)",
                   "x " * 400):
        state.status = status
        driver.frame()
        where.append(driver.recorder.find("Reset view").rect)
    assert where[0] == where[1] == where[2]
