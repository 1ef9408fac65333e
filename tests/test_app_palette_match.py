"""The palette match in the studio (issue #48 item 5): on a finished run its slider re-applies at once through the
worker (a new snapshot, a new summary) and Ctrl+Z takes it back (real small engine in a worker thread)."""

import numpy as np
import pytest
from fakes import BUILT, keep_small_stylizer

from app.worker import ThreadWorkerBridge
from gstyle_core.engine.phases.colour_match import ColourMatch, blend_colours

W, H = 700, 1300  # tall enough for the whole panel


def _final(engine) -> ColourMatch:
    return next(p for p in engine.phases if isinstance(p, ColourMatch) and p.final)


def _shows(state, colours) -> bool:
    """The bridge's newest snapshot shows ``colours`` (the engine's c_s as a viewer gets it) exactly."""
    snap = state.snapshot or {}
    return "colors" in snap and np.array_equal(snap["colors"], colours.clamp(0, 1).numpy())


@pytest.mark.slow
def test_a_finished_runs_palette_match_reaches_the_snapshot_the_summary_and_the_session(tmp_path):
    BUILT.clear()
    session = tmp_path / "session.ckpt"
    b = ThreadWorkerBridge(keep_small_stylizer, {"n": 150}, checkpoint_path=session)
    b.start()
    try:
        assert b.wait_until(lambda s: (s.done and s.summary is not None) or s.error, 180), b.state.error
        final = _final(BUILT[-1])
        assert b.wait_until(lambda s: _shows(s, final.matched), 30)  # (a snapshot may wait for a credit)
        b.state.summary = None
        b.set_params(palette_match=0.0)
        assert b.wait_until(lambda s: _shows(s, final.before) or s.error, 30), b.state.error
        assert not np.array_equal(final.before.numpy(), final.matched.numpy())
        assert b.wait_until(lambda s: s.summary is not None, 60)  # measured again on the colours shown
        assert b.state.params["palette_match"] == 0.0 and b.state.done
        b.set_params(palette_match=1.0)
        assert b.wait_until(lambda s: _shows(s, final.matched) or s.error, 30), b.state.error
        b.set_params(palette_match=0.3)
    finally:
        assert b.quit(timeout=30)  # the session is saved at 0.3
    again = ThreadWorkerBridge(keep_small_stylizer, {"n": 150}, resume_from=session)
    again.start()
    try:  # the run reopened where it ended: its colours at 0.3, and the slider re-applies on it
        assert again.wait_until(lambda s: s.resumed is not None or s.error, 120), again.state.error
        assert BUILT[-1].done and again.state.error is None
        assert again.wait_until(lambda s: _shows(s, blend_colours(final.before, final.matched, 0.3)), 30)
        again.set_params(palette_match=0.0)
        assert again.wait_until(lambda s: _shows(s, final.before) or s.error, 30), again.state.error
    finally:
        assert again.quit(timeout=30)


def test_the_slider_changes_a_finished_result_and_ctrl_z_takes_it_back(window, monkeypatch, tmp_path):
    pytest.importorskip("imgui_bundle")
    from fakes import small_studio
    from imgui_driver import studio_driver

    app = small_studio(window, monkeypatch, tmp_path)
    try:
        app.engine.start()
        assert app.engine.bridge.wait_until(lambda s: s.done or s.error, 180), app.engine.bridge.state.error
        final = _final(BUILT[-1])
        assert app.engine.bridge.wait_until(lambda s: _shows(s, final.matched) and s.summary is not None, 60)
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()  # the finished run's lines in the panel before the slider is found
        commands = driver.click("palette_match/palette match", fx=0.1)
        assert "strokes left them" in driver.recorder.find("palette_match/palette match").tooltip
        asked = [c.args["palette_match"] for c in commands if c.name == "set_params"][-1]
        assert 0.0 <= asked < 0.5
        blended = blend_colours(final.before, final.matched, asked)
        assert app.engine.bridge.wait_until(lambda s: _shows(s, blended), 30), app.engine.bridge.state.error
        app.session.history.done[-1].at = float("-inf")  # the drag is over
        app.keys.press("z", ctrl=True)
        driver.frame()
        assert app.panel.params["palette_match"] == 1.0
        assert app.engine.bridge.wait_until(lambda s: _shows(s, final.matched), 30), app.engine.bridge.state.error
    finally:
        assert app.close(timeout=60)
