"""The studio's artist controls (issue #15): the "stroke size" slider and the "keep colours" checkbox reach the
engine mid-run, and a closed session resumes with them (headless GL window, real small engine in a worker thread)."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import make_small_stylizer  # noqa: E402
from imgui_driver import paused_studio_driver  # noqa: E402
from PIL import Image  # noqa: E402
from synthetic import blob_scene, ring_cameras  # noqa: E402

from app.panels import Command  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from gstyle_core.pipeline.checkpoint import read_checkpoint  # noqa: E402

W, H = 700, 1100  # tall enough for the whole panel
BUILT: list = []


def keep_small_stylizer(**config):
    """``make_small_stylizer``, kept for the test to look at (thread mode: the same process)."""
    BUILT.append(make_small_stylizer(**config))
    return BUILT[-1]


def test_stroke_size_and_keep_colours_reach_the_engine_and_the_session(window, monkeypatch, tmp_path):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    style = tmp_path / "style.png"
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(style)
    loaded = LoadedScene(str(tmp_path / "ring.ply"), blob_scene(150, seed=5), ring_cameras(3))
    BUILT.clear()

    def studio():
        return StudioApp(window.ctx, loaded=loaded, style_path=str(style), engine_factory=keep_small_stylizer,
                         output_dir=tmp_path / "out", worker_mode="thread")

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
        assert app.bridge.wait_until(lambda s: s.params.get("keep_colours") == 1.0, 30)
        engine = BUILT[-1]
        assert engine.settings.style_scale == pytest.approx(asked) and engine.settings.keep_colours is True
        app.bridge.step_once()
        assert app.bridge.wait_until(lambda s: s.reports_received >= 1, 60), app.bridge.state.error
        path = app.session_checkpoint()
    finally:
        assert app.close(timeout=60)
    state, meta = read_checkpoint(path)
    assert meta["params"]["keep_colours"] == 1.0 and meta["params"]["style_scale"] == pytest.approx(asked)
    assert state["settings"]["keep_colours"] is True

    app = studio()
    try:
        app.execute(Command("resume_session"))
        assert app.bridge.wait_until(lambda s: s.resumed is not None or s.error, 60), app.bridge.state.error
        assert app.bridge.state.error is None
        resumed = BUILT[-1]
        assert resumed.settings.keep_colours is True and resumed.settings.style_scale == pytest.approx(asked)
        assert app.bridge.wait_until(lambda s: s.params.get("keep_colours") == 1.0, 30)
    finally:
        app.close(timeout=60)
