"""Each line the panel says belongs to the state on screen (issue #48 item 4.3): the red error goes when a step
succeeds after it, a resume's status goes with the run it describes, the width is the one of what is shown (a run's,
or a reopened or undone result's), and Undo / Redo name what they bring back (headless GL window, fake engines in a
worker thread)."""

import json
from pathlib import Path

import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import FakeEngine, make_stylizing_engine, ring_studio  # noqa: E402

from app.panels import Command  # noqa: E402

W, H = 160, 120


class PricelessEngine(FakeEngine):
    """A ``FakeEngine`` whose preset estimates fail: an error line at its start, and then it steps on."""

    def preset_plans(self) -> dict:
        raise RuntimeError("no plans here")


def make_priceless_engine(scene=None, style=None, cameras=None, preset=None, **config) -> PricelessEngine:
    return PricelessEngine(**config)


def make_failing_engine(scene=None, style=None, cameras=None, preset=None, **config) -> FakeEngine:
    return FakeEngine(fail_at=3, **config)


def test_the_red_error_goes_when_a_step_succeeds_after_it_and_stays_while_none_does(window, tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path, make_priceless_engine)
    try:
        assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 3 or s.error and s.reports_received, 30)
        assert app.engine.bridge.state.error is None  # the steps after it made it stale
        app.fill_panel()
        assert app.panel.error is None
        assert app.panel.status == "the run went on after: estimating the presets: RuntimeError: no plans here"
        app.execute(Command("restart"))  # the line was about the run before: it goes with it
        assert app.panel.status == ""
    finally:
        app.close(timeout=30)
    app = ring_studio(window, tmp_path, make_failing_engine)
    try:
        assert app.engine.bridge.wait_until(lambda s: s.error is not None, 30)
        reports = app.engine.bridge.state.reports_received
        app.engine.bridge.wait_until(lambda s: s.reports_received > reports, 1.0)  # nothing steps after the failure
        app.fill_panel()
        assert "fake engine failure" in app.panel.error and app.engine.bridge.state.reports_received == reports
    finally:
        app.close(timeout=30)


def test_a_resumes_status_goes_with_the_run_it_describes(window, tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path, snapshots=3)
    try:
        app.engine.stop()  # the session is saved
        assert app.engine.session_checkpoint().is_file()
        assert app.engine.start(resume=True)
        assert app.engine.bridge.wait_until(lambda s: s.resumed is not None or s.error, 30), \
            app.engine.bridge.state.error
        app.fill_panel()
        assert app.panel.status.startswith("resumed the last session at step ")
        for _ in range(2):
            app.execute(Command("restart"))
            assert (app.panel.phase, app.panel.step) == ("starting", 0)  # not the run before's progress
            assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 1 or s.error, 30)
            app.fill_panel()
            assert "resumed" not in app.panel.status
    finally:
        app.close(timeout=30)


def _result_file(tmp_path: Path, refine_widths: tuple[int, ...]) -> Path:
    """A stylized result with its summary (a 360° run at 256 px and ``refine_widths``)."""
    from synthetic import blob_scene

    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.io import save_scene

    path = tmp_path / "results" / "made.ply"
    path.parent.mkdir(exist_ok=True)
    save_scene(blob_scene(40, seed=2), path)
    settings = resolve_settings("balanced", "360", 4, refine_widths=refine_widths)
    path.with_suffix(".json").write_text(json.dumps({"settings": settings.to_dict()}))
    return path


def test_the_width_shown_is_the_one_of_the_run_or_result_on_show(window, tmp_path, monkeypatch):
    from imgui_driver import studio_driver

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path, lambda **config: make_stylizing_engine(width=512, **config), snapshots=2)
    try:
        driver = studio_driver(window, monkeypatch, app)
        assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 1, 30)
        driver.frame()
        assert app.panel.width == 512 and "Width: 512 px" in driver.recorder.texts
        app.execute(Command("restart"))  # the run at 512 px is saved first: a step back
        app.execute(Command("undo"))  # its result (256 px, no levels) is on show, nothing running
        assert app.engine.bridge is None and app.session.result is not None
        driver.frame()
        assert app.panel.width == 256 and "Width: 256 px" in driver.recorder.texts
        assert app.files.open_path(str(_result_file(tmp_path, (512, 1024))))
        driver.frame()
        assert "Width: 1024 px (levels 256 px -> 512 px -> 1024 px)" in driver.recorder.texts
    finally:
        app.close(timeout=30)


def test_undo_and_redo_name_what_they_bring_back(window, tmp_path, monkeypatch):
    """Two restarts, then two undos and two redos: each button's note names the result it opens, never the one on
    show; the second undo (no engine running) leaves the result on show for redo."""
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path, make_stylizing_engine, snapshots=2)
    try:
        saved = []
        for _ in range(2):
            app.execute(Command("restart"))
            saved.append(app.session.history.done[-1].before)
            assert app.engine.bridge.wait_until(lambda s: s.snapshots_received >= 2 or s.error, 30)
        app.fill_panel()
        assert saved[1].name in app.panel.undo_note and app.panel.redo_note == ""
        app.execute(Command("undo"))
        shown, newest = Path(app.session.loaded.path), app.session.history.undone[-1].after
        assert shown == saved[1] and newest is not None
        app.fill_panel()
        assert saved[0].name in app.panel.undo_note and newest.name in app.panel.redo_note
        assert shown.name not in app.panel.redo_note
        app.execute(Command("undo"))
        app.fill_panel()
        assert Path(app.session.loaded.path) == saved[0] and app.panel.undo_note == ""
        assert saved[1].name in app.panel.redo_note  # the result the first undo opened comes back
        app.execute(Command("redo"))
        assert Path(app.session.loaded.path) == saved[1]
        app.fill_panel()
        assert newest.name in app.panel.redo_note
        app.execute(Command("redo"))
        assert Path(app.session.loaded.path) == newest
    finally:
        app.close(timeout=30)
