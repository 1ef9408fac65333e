"""Saving like a desktop tool (issue #35 item 4): Save As (Ctrl+Shift+S) through the studio's browser, then Ctrl+S
writes to the place saved last; before that, beside the scene the artist opened, else the output folder."""

import pytest

from app.file_browser import FileBrowser

W, H = 160, 120


def test_the_browser_in_save_mode_takes_a_new_name_and_adds_the_format(tmp_path):
    (tmp_path / "sub").mkdir()
    browser = FileBrowser("Save", (".ply", ".spz", ".compressed.ply"), folder=tmp_path, saving=True)
    assert browser.submit("my take") == (tmp_path / "my take.ply").resolve()
    assert browser.submit("web.spz") == (tmp_path / "web.spz").resolve()
    assert browser.submit("sub") is None and browser.folder == (tmp_path / "sub").resolve()  # a folder: go there
    assert browser.submit(str(tmp_path / "no" / "x.ply")) is None and "no such folder" in browser.error
    assert FileBrowser("Open", (".ply",), folder=tmp_path).submit("my take.ply") is None  # opening needs the file


def test_save_as_writes_where_chosen_and_ctrl_s_follows(window, tmp_path, monkeypatch):
    from fakes import ring_studio

    from app.panels import Command

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("GSTYLE_FILE_DIALOG", "studio")
    app = ring_studio(window, tmp_path / "out")
    try:
        assert app.outputs.export_folder() == tmp_path / "out"  # "ring" is no file: the output folder
        chosen = tmp_path / "mine"
        chosen.mkdir()
        app.execute(Command("save_as"))
        browser = app.panel.browser
        assert browser is not None and browser.saving
        app.execute(Command("browser_open", {"path": str(browser.submit(str(chosen / "first")))}))
        assert app.panel.browser is None and app.outputs.save_folder == chosen.resolve()
        assert app.engine.bridge.wait_until(lambda s: len(s.exported) >= 1 or s.error, 30), \
            app.engine.bridge.state.error
        assert (chosen / "first.ply").is_file() and (chosen / "first.json").is_file()
        app.execute(Command("export"))  # Ctrl+S: into the folder saved to last
        assert app.engine.bridge.wait_until(lambda s: len(s.exported) >= 2 or s.error, 30)
        assert len(list(chosen.glob("stylized_*.ply"))) == 1
    finally:
        app.close(timeout=30)


def test_exports_go_beside_an_opened_scene_unless_it_is_the_demo(window, tmp_path, monkeypatch):
    from fakes import ring_studio
    from synthetic import blob_scene

    from gstyle_core.io import save_scene

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path / "out")
    try:
        scene = tmp_path / "captures" / "garden.ply"
        scene.parent.mkdir()
        save_scene(blob_scene(40), scene)
        assert app.files.open_path(str(scene))
        assert app.outputs.export_folder() == scene.parent
        assert app.files.open_path(str(pytest.importorskip("gstyle_core.assets").DEMO_SCENE))
        assert app.outputs.export_folder() == tmp_path / "out"
    finally:
        app.close(timeout=30)
