"""Studio sessions: closing saves the running engine in the cache folder (keyed by scene + style), and the panel's
"Resume last session" continues it (headless GL window, fake engine in a spawned worker)."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from imgui_bundle import imgui  # noqa: E402, F401, I001 - before glfw (gl-stack.md)
from PIL import Image  # noqa: E402

from app.panels import Command  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from fakes import make_fake_engine  # noqa: E402
from gstyle_core.engine.checkpoint import read_checkpoint  # noqa: E402
from synthetic import blob_scene, look_at_camera  # noqa: E402

W, H = 160, 120


def _frame(win, app):
    win.begin_frame()
    screen = win.ctx.screen
    screen.use()
    app.frame(screen)
    win.end_frame(swap=False)


def test_close_saves_the_session_and_resume_continues_it(window, tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    style = tmp_path / "style.png"
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(style)
    loaded = LoadedScene(str(tmp_path / "scene.ply"), blob_scene(50), [look_at_camera((0, 0, -3), (0, 0, 0), W, H)])

    def studio():
        return StudioApp(window.ctx, loaded=loaded, style_path=str(style), engine_factory=make_fake_engine,
                         engine_config={"n": 50}, output_dir=tmp_path / "out")

    app = studio()
    assert not app.engine.resume_available()
    app.engine.start()
    assert app.engine.bridge.wait_until(lambda s: s.snapshots_received >= 4, 60), app.engine.bridge.state.error
    path = app.engine.session_checkpoint()
    assert path.parent == tmp_path / "cache" / "checkpoints"
    assert app.close(timeout=60)  # what closing the window does
    state, meta = read_checkpoint(path)
    assert state["steps"] >= 4 and meta["kind"] == "studio" and meta["style"] == str(style)
    assert not (tmp_path / "out").exists()  # nothing written beside the outputs

    app = studio()
    try:
        _frame(window, app)
        assert app.panel.resume_available  # the panel shows "Resume last session"
        app.execute(Command("resume_session"))
        assert app.engine.bridge.wait_until(lambda s: s.resumed is not None, 60), app.engine.bridge.state.error
        assert app.engine.bridge.state.resumed["step"] == state["steps"]
        assert app.engine.bridge.wait_until(lambda s: s.snapshots_received >= 1, 30)
        assert app.engine.bridge.state.snapshot["colour_version"] >= state["steps"]  # counting on, not from 0
        _frame(window, app)
        assert not app.panel.resume_available and "resumed the last session" in app.panel.status
        # another style is another session: nothing to resume for it
        app.engine.config["style"] = str(tmp_path / "other.png")
        assert not app.engine.resume_available()
    finally:
        app.close(timeout=60)


def test_ctrl_q_ends_the_frame_loop_as_the_close_button_does(window, tmp_path, monkeypatch):
    """Ctrl+Q (the ``quit`` command) ends ``_run_frames`` before its frame budget; main then closes the studio,
    which saves the session as for the close button (the test above)."""
    import argparse

    from app.main import _run_frames

    loaded = LoadedScene(str(tmp_path / "scene.ply"), blob_scene(50), [look_at_camera((0, 0, -3), (0, 0, 0), W, H)])
    app = StudioApp(window.ctx, loaded=loaded, engine_factory=make_fake_engine, engine_config={"n": 50},
                    output_dir=tmp_path / "out")
    drawn = []
    frame = app.frame

    def frame_then_quit(screen):
        frame(screen)
        drawn.append(1)
        if len(drawn) == 2:
            app.keys.press("q", ctrl=True)

    app.frame = frame_then_quit
    args = argparse.Namespace(frames=50, fps=0, on_demand=False, pacing=False, screenshot=None)
    _run_frames(window, app, args, {"stop": False})
    assert app.quit_requested and len(drawn) == 3  # the press is read in the frame after it
