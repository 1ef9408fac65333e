"""The studio's artist controls (issue #15): the "stroke size" slider and the "keep colours" and "coherent strokes"
checkboxes reach the engine mid-run, and a closed session resumes with them (headless GL window, real small engine in
a worker thread)."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import BUILT, small_studio  # noqa: E402
from imgui_driver import paused_studio_driver  # noqa: E402
from PIL import Image  # noqa: E402
from synthetic import blob_scene, ring_cameras  # noqa: E402

from app.panels import Command  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from gstyle_core.engine.checkpoint import read_checkpoint  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


def test_stroke_size_and_keep_colours_reach_the_engine_and_the_session(window, monkeypatch, tmp_path):
    def studio():
        return small_studio(window, monkeypatch, tmp_path)

    app = studio()
    try:
        assert app.panel.params["keep_colours"] == 0.0 and app.panel.params["style_scale"] == 1.0
        driver = paused_studio_driver(window, monkeypatch, app)
        commands = driver.click("style_scale/stroke size", fx=0.9)
        assert driver.recorder.find("style_scale/stroke size").tooltip  # every control explains itself
        assert commands and commands[0].name == "set_params" and commands[0].args["style_scale"] > 2
        asked = commands[-1].args["style_scale"]
        commands = driver.click("keep colours")
        assert [c.args for c in commands if c.name == "set_params"] == [{"keep_colours": 1.0}]
        assert driver.recorder.find("keep colours").tooltip
        assert app.engine.bridge.wait_until(lambda s: s.params.get("keep_colours") == 1.0, 30)
        assert app.panel.params["colour_field"] == 0.0  # forward-facing settings: off
        commands = driver.click("coherent strokes")
        assert [c.args for c in commands if c.name == "set_params"] == [{"colour_field": 1.0}]
        assert "neighbouring Gaussians" in driver.recorder.find("coherent strokes").tooltip
        assert app.engine.bridge.wait_until(lambda s: s.params.get("colour_field") == 1.0, 30)
        engine = BUILT[-1]
        assert engine.settings.style_scale == pytest.approx(asked) and engine.settings.keep_colours is True
        assert engine.settings.colour_field is True
        app.engine.bridge.step_once()
        assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 1, 60), app.engine.bridge.state.error
        path = app.engine.session_checkpoint()
    finally:
        assert app.close(timeout=60)
    state, meta = read_checkpoint(path)
    assert meta["params"]["keep_colours"] == 1.0 and meta["params"]["style_scale"] == pytest.approx(asked)
    assert state["settings"]["keep_colours"] is True and state["settings"]["colour_field"] is True

    app = studio()
    try:
        app.execute(Command("resume_session"))
        assert app.engine.bridge.wait_until(lambda s: s.resumed is not None or s.error, 60), \
            app.engine.bridge.state.error
        assert app.engine.bridge.state.error is None
        resumed = BUILT[-1]
        assert resumed.settings.keep_colours is True and resumed.settings.style_scale == pytest.approx(asked)
        assert resumed.settings.colour_field is True
        assert app.engine.bridge.wait_until(lambda s: s.params.get("keep_colours") == 1.0, 30)
    finally:
        app.close(timeout=60)


def mix_stylizer(style=None, style_weights=None, **_ignored):
    """A tiny real engine on the studio's style path(s) and weights (``MeanColourPull``: no networks)."""
    from fakes import MeanColourPull

    from gstyle_core.engine.build import style_paths
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer
    from gstyle_core.images import load_style_image

    styles = [load_style_image(p) for p in style_paths(style)]
    settings = resolve_settings("preview", "forward", 3, max_views=3, epochs=3, min_steps=0, split_rate=0.0,
                                working_width=32, preprocess_rounds=0, style_weights=style_weights)
    BUILT.append(Stylizer(blob_scene(150, seed=5), ring_cameras(3), styles[0] if len(styles) == 1 else styles,
                          settings, objective_factory=MeanColourPull))
    return BUILT[-1]


def test_a_second_style_and_its_mix_slider_reach_the_engine_and_the_export(window, monkeypatch, tmp_path):
    import json

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    first, second = tmp_path / "blue.png", tmp_path / "red.png"
    noise = np.random.default_rng(0).integers(0, 20, (16, 16, 3))
    for path, colour in ((first, (40, 80, 230)), (second, (230, 60, 40))):
        Image.fromarray((np.asarray(colour) + noise).clip(0, 255).astype(np.uint8)).save(path)
    loaded = LoadedScene(str(tmp_path / "ring.ply"), blob_scene(150, seed=5), ring_cameras(3))
    BUILT.clear()
    app = StudioApp(window.ctx, loaded=loaded, style_path=str(first), engine_factory=mix_stylizer,
                    output_dir=tmp_path / "out", worker_mode="thread")
    try:
        driver = paused_studio_driver(window, monkeypatch, app)
        driver.frame()
        assert driver.recorder.find("Mix in a second style...").tooltip
        one_path = app.engine.session_checkpoint()
        app.files.open_path(str(second), style_slot=1)  # what the file dialog of that button does
        assert app.engine.bridge.wait_until(lambda s: len(BUILT) == 2 and s.ready or s.error, 60), \
            app.engine.bridge.state.error
        engine = BUILT[-1]
        assert len(engine.styles) == 2 and engine.settings.style_weights == pytest.approx((0.5, 0.5))
        assert app.engine.session_checkpoint() != one_path  # a mix is its own session
        app.engine.bridge.pause()
        assert app.engine.bridge.wait_until(lambda s: s.paused, 30)
        commands = driver.click("style mix", fx=0.95)
        assert driver.recorder.find("style mix").tooltip
        asked = [c.args["style_mix"] for c in commands if c.name == "set_params"][-1]
        assert asked > 0.8
        assert app.engine.bridge.wait_until(lambda s: s.params.get("style_mix") == pytest.approx(asked), 30)
        assert engine.settings.style_weights == pytest.approx((1 - asked, asked))
        assert app.engine.config["style_weights"] == pytest.approx((1 - asked, asked))  # a restart keeps the mix
        app.engine.bridge.step_once()
        assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 1, 60), app.engine.bridge.state.error
        out = tmp_path / "out" / "mix.ply"
        app.outputs.export(out)
        assert app.engine.bridge.wait_until(lambda s: out.with_suffix(".json").exists() or s.error, 60)
        summary = json.loads(out.with_suffix(".json").read_text())
        assert [s["path"] for s in summary["styles"]] == [str(first), str(second)]
        assert [s["weight"] for s in summary["styles"]] == pytest.approx([1 - asked, asked], abs=1e-5)
        commands = driver.click("remove")
        assert [c.name for c in commands] == ["remove_style2"]
        assert app.engine.bridge.wait_until(lambda s: len(BUILT) == 3 and s.ready or s.error, 60), \
            app.engine.bridge.state.error
        assert len(BUILT[-1].styles) == 1 and app.engine.config["style"] == str(first)
    finally:
        app.close(timeout=60)
