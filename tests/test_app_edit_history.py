"""Undo and redo of parameter changes (issue #35 item 1, first part): the history itself, the shortcuts, and the
studio applying an undo to the panel and the engine."""

import time

import pytest

from app.edit_history import COALESCE_SECONDS, EditHistory


def test_a_drag_is_one_step_and_undo_redo_walk_it_back_and_forth():
    h = EditHistory()
    h.record({"lambda_nnfm": 100.0}, {"lambda_nnfm": 120.0}, now=0.0)
    h.record({"lambda_nnfm": 120.0}, {"lambda_nnfm": 150.0}, now=0.1)  # the same drag
    h.record({"lambda_nnfm": 150.0}, {"lambda_nnfm": 200.0}, now=0.2)
    h.record({"keep_colours": 0.0}, {"keep_colours": 1.0}, now=0.3)  # another control: a step of its own
    h.record({"keep_colours": 1.0}, {"keep_colours": 1.0}, now=5.0)  # no change: no step
    assert [e.describe() for e in h.done] == ["lambda_nnfm 100 -> 200", "keep_colours 0 -> 1"]
    assert h.undo().before == {"keep_colours": 0.0}
    assert h.undo().before == {"lambda_nnfm": 100.0} and h.undo() is None
    assert h.redo().after == {"lambda_nnfm": 200.0}
    h.record({"lambda_nnfm": 200.0}, {"lambda_nnfm": 210.0}, now=0.25)  # right after a redo: still its own step
    assert len(h.done) == 2 and not h.undone  # a new change forgets what was undone
    h.record({"lambda_nnfm": 210.0}, {"lambda_nnfm": 220.0}, now=0.25 + 2 * COALESCE_SECONDS)
    assert len(h.done) == 3


def test_the_history_keeps_at_most_its_limit():
    h = EditHistory(limit=3)
    for i in range(5):
        h.record({"lr": float(i)}, {"lr": float(i + 1)}, now=10.0 * i)
    assert [e.before["lr"] for e in h.done] == [2.0, 3.0, 4.0]


W, H = 160, 120


def test_ctrl_z_takes_a_slider_back_in_the_panel_and_the_engine(studio, window):
    from app.keys import KeyPress
    from app.panels import Command, PanelState, draw_panel

    def frame():
        window.begin_frame()
        studio.frame(window.ctx.screen)
        window.end_frame(swap=False)

    start = studio.panel.params["lambda_nnfm"]
    studio.execute(Command("set_params", {"lambda_nnfm": start * 3}))
    studio.session.history.done[-1].at = float("-inf")  # a later change, not the same drag
    studio.execute(Command("set_params", {"keep_colours": 1.0}))
    studio.keys.press("z", ctrl=True)
    frame()
    assert studio.panel.params["keep_colours"] == 0.0 and studio.panel.status == "undo: keep_colours 0 -> 1"
    studio.keys.press("z", ctrl=True)
    frame()
    assert studio.panel.params["lambda_nnfm"] == start
    assert studio.engine.bridge.wait_until(
        lambda s: (s.snapshot or {}).get("params", {}).get("lambda_nnfm") == start, 30)  # the engine has it
    frame()  # the panel shows the stacks as they were when the frame began
    assert studio.panel.redo_note.startswith("lambda_nnfm") and studio.panel.undo_note == ""
    studio.keys.press("y", ctrl=True)
    frame()
    assert studio.panel.params["lambda_nnfm"] == start * 3
    for keys, expected in (({"ctrl": True}, "undo"), ({"ctrl": True, "shift": True}, "redo")):
        window.begin_frame()
        cmds = draw_panel(PanelState(), [KeyPress("z", **keys)])
        window.end_frame(swap=False)
        assert cmds == [Command(expected)]


def test_a_restart_leaves_its_result_a_step_back_and_redo_brings_the_new_one(window, tmp_path, monkeypatch):
    """Restart throws nothing away: the result it replaced is saved (no take), Ctrl+Z opens it as a result with
    the engine stopped, Ctrl+Shift+Z opens the result the undo left."""
    import numpy as np
    from fakes import make_stylizing_engine, ring_studio

    from app.panels import Command
    from app.result_undo import history_folder
    from gstyle_core.scene import sh_dc_to_rgb

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path, make_stylizing_engine, snapshots=3)
    try:
        bridge = app.engine.bridge
        bridge.pause()
        assert bridge.wait_until(lambda s: s.paused, 30)
        time.sleep(0.3)
        bridge.poll()
        shown = float(bridge.state.snapshot["colors"][0, 0])
        app.execute(Command("restart"))
        assert [e.action for e in app.session.history.done] == ["restart"] and app.engine.bridge is bridge
        assert bridge.wait_until(lambda s: s.snapshots_received >= 2 or s.error, 60)
        app.execute(Command("undo"))
        before = app.session.history.undone[-1].before
        assert app.engine.bridge is None and app.session.result is not None and app.session.loaded.path == str(before)
        assert before.parent == history_folder() and app.takes.shelf.takes == []  # saved for undo: no take
        rgb = sh_dc_to_rgb(app.session.loaded.scene.sh_dc)
        assert np.allclose(rgb, shown, atol=2e-3)  # the colours the paused run showed
        assert app.panel.status.startswith("undo: the result before restart")
        assert app.panel.phase == "result (nothing running)" and app.panel.loss_history == []  # the run's gone
        app.execute(Command("redo"))
        after = app.session.history.done[-1].after
        assert after is not None and app.session.loaded.path == str(after) and after != before
    finally:
        app.close(timeout=30)
    assert not history_folder().exists()  # the undo stack ends with the session


def test_region_changes_are_undone_a_drag_at_a_time(studio):
    """The region tool's selection is an undo step: turned on with a box, the box dragged (many moves: one step), a
    rectangle selected; Ctrl+Z walks back through them to the tool off, Ctrl+Shift+Z forward again."""
    from app.panels import Command

    box = studio.region.scene_box()
    half = tuple(v * 0.5 for v in box)
    studio.execute(Command("region_box", {"box": half}))
    first = studio.region.state()
    studio.session.history.done[-1].at = float("-inf")  # a later change is a step of its own
    for k in range(5):  # a drag: moves within the coalescing time
        studio.region.set_box(tuple(v + 0.01 * (k + 1) for v in half))
    dragged = studio.region.state()
    studio.session.history.done[-1].at = float("-inf")
    assert studio.region.select_rectangle((0, 0, W, H), W, H) > 0
    assert studio.region.rect_mask is not None
    studio.undo.undo_or_redo("undo")
    assert studio.region.state()[:2] == dragged[:2] and studio.region.rect_mask is None
    studio.undo.undo_or_redo("undo")
    assert studio.region.state()[:2] == first[:2]
    studio.undo.undo_or_redo("undo")
    assert not studio.region.enabled and "region selection" in studio.panel.status
    studio.undo.undo_or_redo("redo")
    studio.undo.undo_or_redo("redo")
    studio.undo.undo_or_redo("redo")
    assert studio.region.enabled and studio.region.rect_mask is not None


def test_an_unchanged_region_is_no_step():
    h = EditHistory()
    state = (True, (0.0, 0.0, 0.0, 1.0, 1.0, 1.0), None)
    h.record_region(state, state)
    assert not h.done
    h.record_region((False, None, None), state, now=0.0)
    h.record_region(state, (True, (0.0, 0.0, 0.0, 2.0, 2.0, 2.0), None), now=0.5)  # within the coalescing time
    assert len(h.done) == 1 and h.done[0].before == (False, None, None)


def _paintings(tmp_path):
    import numpy as np
    from PIL import Image

    paths = []
    for name, rgb in (("first.png", (200, 40, 40)), ("second.png", (40, 40, 200)), ("third.png", (40, 200, 40))):
        path = tmp_path / name
        Image.fromarray(np.full((12, 12, 3), rgb, np.uint8)).save(path)
        paths.append(str(path))
    return paths


def test_a_painting_choice_is_a_step_of_its_own(window, tmp_path, monkeypatch):
    """With no result replaced, opening a painting, mixing in a second one and removing it are undo steps: undo puts
    the painting(s) and the mix before it back and the engine restarts with them; redo chooses again."""
    from fakes import ring_studio

    from app.edit_history import ChoiceEdit
    from app.panels import Command

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    first, second, third = _paintings(tmp_path)
    app = ring_studio(window, tmp_path)
    try:
        assert app.files.open_path(first, record=False) and app.session.history.done == []
        assert app.files.open_path(second)
        assert isinstance(app.session.history.last(), ChoiceEdit) and app.engine.config["style"] == second
        assert app.files.open_path(third, style_slot=1)
        app.execute(Command("set_params", {"style_mix": 0.8}))
        app.session.history.done[-1].at = float("-inf")
        app.execute(Command("remove_style2"))
        assert app.panel.style2_path == "" and app.engine.config["style"] == second
        app.execute(Command("undo"))  # the second painting back, at its mix
        assert app.panel.style2_path == third and app.engine.config["style"] == [second, third]
        assert app.engine.config["style_weights"] == pytest.approx((0.2, 0.8))
        assert app.panel.status == "undo: the painting (second.png + third.png -> second.png)"
        app.execute(Command("undo"))  # the mix
        app.execute(Command("undo"))  # the second painting mixed in
        assert app.panel.style2_path == "" and app.engine.config["style"] == second
        app.execute(Command("undo"))  # the first painting
        assert app.panel.style_path == first and app.engine.config["style"] == first
        assert app.engine.bridge.wait_until(lambda s: s.ready and not s.error, 30)
        assert app.engine.bridge.config["style"] == first  # the engine restarted with it
        app.execute(Command("redo"))
        assert app.panel.style_path == second and app.engine.bridge.config["style"] == second
    finally:
        app.close(timeout=30)


def test_a_painting_that_replaces_a_result_is_one_step_with_it(window, tmp_path, monkeypatch):
    """A painting chosen while a result is shown: the replaced result is the step (undo brings it back with its
    painting), not a second one."""
    from fakes import make_stylizing_engine, ring_studio

    from app.edit_history import ResultEdit

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    first, second, _ = _paintings(tmp_path)
    app = ring_studio(window, tmp_path, make_stylizing_engine, snapshots=2)
    try:
        assert app.files.open_path(first, record=False)
        assert app.engine.bridge.wait_until(lambda s: s.snapshots_received >= 2 or s.error, 60)
        steps = len(app.session.history.done)
        assert app.files.open_path(second)
        assert len(app.session.history.done) == steps + 1 and isinstance(app.session.history.last(), ResultEdit)
    finally:
        app.close(timeout=30)


def test_redo_of_a_painting_brings_back_the_result_made_after_it(window, tmp_path, monkeypatch):
    """Undo of a painting saves the result made with it first (``save_result``); redo opens that result instead of
    starting over."""
    import json

    from fakes import ring_studio
    from synthetic import blob_scene

    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.io import save_scene

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    first, second, _ = _paintings(tmp_path)
    made = tmp_path / "made_with_second.ply"
    save_scene(blob_scene(40, seed=2), made)
    made.with_suffix(".json").write_text(json.dumps({"settings": resolve_settings("preview", "360", 4).to_dict()}))
    app = ring_studio(window, tmp_path)
    try:
        app.files.open_path(first, record=False)
        app.files.open_path(second)
        monkeypatch.setattr(app.undo, "save_result", lambda: made)  # the run with the second painting made a result
        app.undo.undo_or_redo("undo")
        assert app.panel.style_path == first and app.session.history.undone[-1].result_after == made
        app.undo.undo_or_redo("redo")
        assert app.session.result is not None and app.session.loaded.path == str(made) and app.engine.bridge is None
        assert app.panel.status == f"redo: {made.name} is back"
    finally:
        app.close(timeout=30)


def test_another_quality_is_a_step_of_its_own(window, tmp_path, monkeypatch):
    """With no result replaced, choosing another quality (which restarts the engine) is an undo step: undo puts the
    quality before it back and restarts with it; redo chooses again."""
    from fakes import ring_studio

    from app.edit_history import ChoiceEdit
    from app.panels import Command

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path)
    try:
        assert app.undo.choice_state("quality") == "preview"
        app.execute(Command("restart_quality", {"preset": "balanced"}))
        assert isinstance(app.session.history.last(), ChoiceEdit) and app.engine.bridge.config["preset"] == "balanced"
        app.execute(Command("undo"))
        assert app.panel.quality == "preview" and app.engine.bridge.config["preset"] == "preview"
        assert app.panel.status == "undo: the quality (preview -> balanced)"
        app.execute(Command("redo"))
        assert app.panel.quality == "balanced" and app.engine.bridge.config["preset"] == "balanced"
        app.execute(Command("restart_quality", {"preset": "balanced"}))  # the same quality again: no step
        assert len(app.session.history.done) == 1
    finally:
        app.close(timeout=30)
