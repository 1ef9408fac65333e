"""Comparing takes (issue #15, item 6): the studio keeps its last exports as named takes that the artist views,
renames, forgets and compares side by side with the current run; the list survives a restart of the studio."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import ring_studio  # noqa: E402
from imgui_driver import studio_driver  # noqa: E402
from synthetic import blob_scene  # noqa: E402

from app.gl_io import read_rgb  # noqa: E402
from app.panels import Command  # noqa: E402
from app.studio import StudioApp  # noqa: E402
from app.takes import TAKES_FILE, TakeShelf  # noqa: E402
from gstyle_core.io import save_scene  # noqa: E402

W, H = 700, 1400  # tall enough for the whole panel


def test_the_shelf_keeps_the_newest_takes_and_remembers_them(tmp_path):
    files = []
    for i in range(4):
        files.append(tmp_path / f"e{i}.ply")
        save_scene(blob_scene(20 + i), files[-1])
    shelf = TakeShelf(tmp_path, limit=3)
    for i, f in enumerate(files):
        shelf.add(f, 20 + i)
    assert [t.name for t in shelf.takes] == ["take 4", "take 3", "take 2"]  # newest first, the oldest forgotten
    assert files[0].exists()  # forgetting never deletes
    shelf.rename(0, "  warm   version ")
    shelf.rename(1, "   ")  # an empty name keeps the old one
    assert [t.name for t in shelf.takes][:2] == ["warm version", "take 3"]
    assert shelf.forget(2).name == "take 2" and files[2].exists()
    assert shelf.load(0).count == 23
    files[2 + 1].rename(tmp_path / "moved.ply")  # the file of "warm version" is gone
    again = TakeShelf(tmp_path, limit=3)
    assert [t.name for t in again.takes] == ["take 3"]
    (tmp_path / TAKES_FILE).write_text("{not json")
    assert TakeShelf(tmp_path).takes == []  # an unreadable list is ignored, never fatal


def _render(app: StudioApp, fbo) -> np.ndarray:
    fbo.use()
    app.render_view(fbo)
    return read_rgb(fbo).astype(np.int16)


def test_exports_become_takes_to_compare_side_by_side(window, monkeypatch, tmp_path):
    app = ring_studio(window, tmp_path, snapshots=2, min_level=0.4)  # the fake's colours cycle; never black here
    try:
        bridge = app.engine.bridge
        driver = studio_driver(window, monkeypatch, app)
        exported = []
        for count, name in enumerate(("early", "late"), start=1):
            bridge.pause()
            assert bridge.wait_until(lambda s: s.paused, 30)
            exported.append(tmp_path / f"{name}.ply")
            app.outputs.export(exported[-1])
            assert bridge.wait_until(lambda s, n=count: len(s.exported) >= n or s.error, 30)
            driver.frame()
            bridge.resume()
            seen = bridge.state.snapshots_received
            assert bridge.wait_until(lambda s, seen=seen: s.snapshots_received >= seen + 30 or s.error, 60)
        bridge.pause()
        assert bridge.wait_until(lambda s: s.paused, 30)
        driver.frame()
        assert app.panel.take_names == ["take 2", "take 1"]
        from PIL import Image

        from app.takes_view import thumbnail_path
        picture = np.asarray(Image.open(thumbnail_path(tmp_path, str(exported[0]))))
        assert picture.shape == (72, 96, 3) and (picture.sum(-1) > 30).sum() > 50  # the scene is in it
        assert all(t is not None for t in app.panel.take_thumbnails)  # each take shows its picture
        assert [t.path for t in app.takes.shelf.takes] == [str(exported[1]), str(exported[0])]
        assert json.loads((tmp_path / TAKES_FILE).read_text())[1]["path"] == str(exported[0])
        assert driver.recorder.find("take1/compare").tooltip
        commands = driver.click("take1/compare")  # the older take, beside the current run
        assert [c.name for c in commands] == ["show_take"]
        assert app.views.mode == "compare" and app.views.compare_with_take and app.views.take_shown == str(exported[0])
        # C after T compares with the original (stylized left, original right, as its tooltip says); C again leaves
        for expected in (("compare", False, "comparing with the original"), ("stylized", False, "")):
            app.keys.press("c")  # as the window's key callback queues it (app/keys.py)
            driver.frame()
            assert (app.views.mode, app.views.compare_with_take, app.panel.status) == expected
        driver.frame()
        assert not app.panel.compare_with_take
        app.execute(Command("show_take", {"index": 1, "compare": True}))
        app.execute(Command("rename_take", {"index": 1, "name": "first try"}))
        assert TakeShelf(tmp_path).takes[1].name == "first try"

        # the compare view: the current run left of the divider, the take right of it. First every snapshot the
        # worker sent before it paused is applied (on a loaded machine the last one can arrive after the pause).
        last = -1
        while bridge.state.snapshots_received != last:
            last = bridge.state.snapshots_received
            time.sleep(0.5)
            driver.frame()
        app.progressive = False
        fbo = window.ctx.simple_framebuffer((160, 120))
        app.views.divider = 0.5
        compare = _render(app, fbo)
        app.views.mode = "take"
        take_alone = _render(app, fbo)
        app.views.mode = "stylized"
        now_alone = _render(app, fbo)
        app.takes.compare_with_original()
        with_original = _render(app, fbo)
        right, left = np.s_[:, 82:], np.s_[:, :78]
        assert np.abs(compare[right] - take_alone[right]).max() <= 1
        assert np.abs(compare[left] - now_alone[left]).max() <= 1
        assert np.abs(take_alone[right] - now_alone[right]).max() > 10  # the take is not the current state
        assert np.abs(with_original[right] - compare[right]).max() > 10
        app.takes.forget_take(1)
        assert app.views.take_shown is None and [t.name for t in app.takes.shelf.takes] == ["take 2"]
    finally:
        app.close()


def test_outputs_and_takes_have_absolute_paths_wherever_the_studio_was_started(window, monkeypatch, tmp_path):
    """Issue #65 item 4: a relative output folder is made absolute when the studio starts (the panel says it), and
    ``takes.json`` keeps absolute paths, so a studio started from elsewhere finds the takes."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    save_scene(blob_scene(40), tmp_path / "out" / "a.ply")
    shelf = TakeShelf("out")
    shelf.add("out/a.ply", 40)
    saved = json.loads((tmp_path / "out" / TAKES_FILE).read_text())
    assert saved[0]["path"] == str(tmp_path / "out" / "a.ply")
    monkeypatch.chdir(tmp_path / "out")
    assert [t.path for t in TakeShelf(tmp_path / "out").takes] == [str(tmp_path / "out" / "a.ply")]
    monkeypatch.chdir(tmp_path)
    app = StudioApp(window.ctx, output_dir="out")
    try:
        assert app.outputs.output_dir == tmp_path / "out" and app.outputs.output_dir.is_absolute()
        app.outputs.save_to("saved")
        app.outputs.fill_panel()
        assert app.panel.output_folder == str(tmp_path / "out") and app.panel.save_folder == str(tmp_path / "saved")
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        assert f"Output folder: {tmp_path / 'out'}" in driver.recorder.texts
    finally:
        app.close()
