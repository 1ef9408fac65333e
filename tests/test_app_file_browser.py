"""The studio's Open buttons (issue #26), clicked headless through the real ImGui panel: without a dialog program
the studio's own file browser opens and says why, and a file chosen in it (clicks, double-click or a typed path)
opens; with one, the native dialog is used, its answer opened, and the panel offers the studio's browser instead."""

import json

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from imgui_bundle import imgui  # noqa: E402, I001 - before glfw (gl-stack.md)
from imgui_driver import studio_driver  # noqa: E402
from PIL import Image  # noqa: E402
from synthetic import blob_scene, look_at_camera  # noqa: E402

import app.open_files as open_files  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from gstyle_core.io import save_scene  # noqa: E402

W, H = 900, 700


@pytest.fixture
def files(tmp_path):
    """data/sub/scene.splat (120 Gaussians), data/sub/painting.png, data/notes.txt."""
    sub = tmp_path / "data" / "sub"
    sub.mkdir(parents=True)
    save_scene(blob_scene(120, seed=3), sub / "scene.splat")
    noise = np.random.default_rng(0).integers(0, 60, (32, 32, 3))
    Image.fromarray((noise + [20, 60, 180]).clip(0, 255).astype(np.uint8)).save(sub / "painting.png")
    (tmp_path / "data" / "notes.txt").write_text("not a scene")
    return tmp_path / "data"


@pytest.fixture
def studio(window, tmp_path, monkeypatch):
    """A studio with a 50-Gaussian scene, no engine, no dialog program, its recent folders in ``tmp_path``."""
    monkeypatch.delenv(open_files.DIALOG_ENV, raising=False)
    monkeypatch.setattr(open_files.shutil, "which", lambda _name: None)
    loaded = LoadedScene(str(tmp_path / "first.ply"), blob_scene(50), [look_at_camera((0, 0, -3), (0, 0, 0), W, H)])
    app = StudioApp(window.ctx, loaded=loaded, engine_factory=None, engine_config={}, output_dir=tmp_path / "out")
    app.files.recent_file = tmp_path / "recent.json"
    yield app
    app.close()


def type_into(driver, path: str, text: str, enter: bool = True) -> list:
    """Click the text field at ``path``, type ``text`` and (``enter``) press Enter; the commands drawn meanwhile."""
    commands = driver.click(path)
    commands += driver.frame(lambda io: io.add_input_characters_utf8(text))
    if enter:
        commands += driver.frame(lambda io: io.add_key_event(imgui.Key.enter, True))
        commands += driver.frame(lambda io: io.add_key_event(imgui.Key.enter, False))
    return commands


def test_without_a_dialog_program_the_studio_browser_opens_and_clicks_through_it_open_the_scene(
        window, monkeypatch, studio, files):
    driver = studio_driver(window, monkeypatch, studio)
    driver.click("Open scene...")
    browser = studio.panel.browser
    assert browser is not None and browser.title == "Open scene"
    assert open_files.NO_PROGRAM in browser.note and open_files.NO_PROGRAM in studio.panel.status
    type_into(driver, "##path", str(files))  # a folder's path: the browser goes there
    assert browser.folder == files.resolve() and "notes.txt" not in [e.name for e in browser.entries()]
    driver.click("sub/")
    assert [e.name for e in browser.entries()] == ["scene.splat"]
    driver.click("scene.splat")
    assert browser.selected == "scene.splat" and studio.views.stylized.count == 50
    driver.click("Open")
    assert studio.views.stylized.count == 120 and studio.panel.browser is None
    assert studio.panel.status == "opened scene.splat (120 Gaussians)" and studio.panel.gaussians == 120
    assert json.loads(studio.files.recent_file.read_text()) == [str((files / "sub").resolve())]


def test_a_typed_path_or_a_double_click_opens_a_painting_and_the_second_one_goes_to_the_mix(
        window, monkeypatch, studio, files):
    driver = studio_driver(window, monkeypatch, studio)
    driver.click("Open style...")
    type_into(driver, "##path", str(files / "sub" / "painting.png"))
    assert studio.panel.style_path == str((files / "sub" / "painting.png").resolve())
    assert studio.panel.browser is None and "opened painting.png as the style" in studio.panel.status
    driver.click("Mix in a second style...")
    browser = studio.panel.browser
    assert browser.title == "Open second style image" and browser.folder == (files / "sub").resolve()  # recent
    driver.click("painting.png")
    x, y = driver.recorder.find("painting.png").point()
    driver.frame(lambda io: io.add_mouse_pos_event(x, y))
    for down in (True, False, True, False):  # a double click
        driver.frame(lambda io, d=down: io.add_mouse_button_event(0, d))
    assert studio.panel.style2_path.endswith("painting.png") and studio.panel.browser is None


def test_the_recent_folders_list_goes_back_to_an_earlier_folder(window, monkeypatch, studio, files):
    studio.files.recent_file.write_text(json.dumps([str(files / "sub"), str(files)]))
    driver = studio_driver(window, monkeypatch, studio)
    driver.click("Open scene...")
    assert studio.panel.browser.folder == files / "sub"
    driver.click("##recent")
    driver.click(str(files))
    assert studio.panel.browser.folder == files.resolve()


def test_a_file_that_does_not_open_keeps_the_browser_with_the_reason_cancel_and_escape_close_it(
        window, monkeypatch, studio, files):
    driver = studio_driver(window, monkeypatch, studio)
    driver.click("Open scene...")
    browser = studio.panel.browser
    browser.go(files)
    driver.click("all files")
    driver.click("notes.txt")
    driver.click("Open")
    assert studio.panel.browser is browser and browser.error == "not a scene or image: notes.txt"
    driver.click("Cancel")
    assert studio.panel.browser is None and studio.panel.status == "no file chosen"
    driver.click("Open scene...")
    driver.frame(lambda io: io.add_key_event(imgui.Key.escape, True))
    driver.frame(lambda io: io.add_key_event(imgui.Key.escape, False))
    assert studio.panel.browser is None and studio.views.stylized.count == 50


class FakeNativeDialog:
    """Stands in for ``portable_file_dialogs.open_file``: records its arguments; answers when told to."""

    opened: list = []

    def __init__(self, title, start, filters):
        self.args, self.answer, self.killed = (title, start, filters), None, False
        FakeNativeDialog.opened.append(self)

    def ready(self, _timeout=0):
        return self.answer is not None

    def result(self):
        return self.answer

    def kill(self):
        self.killed = True


@pytest.fixture
def native(monkeypatch):
    """A desktop with zenity, its dialog faked."""
    from imgui_bundle import portable_file_dialogs

    FakeNativeDialog.opened = []
    monkeypatch.setattr(open_files.shutil, "which", lambda name: f"/usr/bin/{name}" if name == "zenity" else None)
    monkeypatch.setattr(portable_file_dialogs, "open_file", FakeNativeDialog)
    return FakeNativeDialog.opened


def test_a_native_dialog_is_used_where_there_is_one_and_its_answer_opened(window, monkeypatch, studio, files,
                                                                           native):
    studio.files.recent_file.write_text(json.dumps([str(files)]))
    driver = studio_driver(window, monkeypatch, studio)
    driver.click("Open scene...")
    assert studio.panel.browser is None and len(native) == 1
    scenes = "*.ply *.compressed.ply *.splat *.spz *.sog *meta.json *batch.csv"  # a batch's table: its jobs as takes
    assert native[0].args == ("Open scene", f"{files}/", ["Gaussian scenes", scenes])
    assert "zenity file dialog" in studio.panel.status and "zenity" in studio.panel.dialog_note
    native[0].answer = [str(files / "sub" / "scene.splat")]
    driver.frame()
    assert studio.views.stylized.count == 120 and studio.panel.dialog_note == "" and studio.files.dialog is None


def test_the_panel_offers_the_studio_browser_while_a_native_dialog_is_open(window, monkeypatch, studio, native):
    driver = studio_driver(window, monkeypatch, studio)
    driver.click("Open style...")
    driver.click("Use the studio's browser")
    assert native[0].killed and studio.files.dialog is None and studio.panel.dialog_note == ""
    assert studio.panel.browser is not None and studio.panel.browser.title == "Open style image"


def test_a_native_dialog_that_ends_at_once_without_an_answer_hands_over_to_the_studio_browser(studio, native):
    studio.files._open_dialog("open_scene")
    native[0].answer = []  # zenity could not show its window and exited
    studio.files.poll_dialog()
    assert studio.panel.browser is not None and "the zenity file dialog did not open" in studio.panel.browser.note
    studio.panel.browser = None
    studio.files._open_dialog("open_style")
    kind, dialog, program, started = studio.files.dialog
    studio.files.dialog = (kind, dialog, program, started - 10)  # the person looked for ten seconds, then cancelled
    dialog.answer = []
    studio.files.poll_dialog()
    assert studio.panel.browser is None and studio.panel.status == "no file chosen"


def test_typed_characters_imgui_has_not_handed_on_keep_the_studio_drawing(window, monkeypatch, studio):
    """ImGui takes one key or character change a frame: a path typed faster than that must not wait for the next
    window event when the studio renders on demand (app/on_demand.py)."""
    from app.studio_input import imgui_input_pending

    studio.progressive = False  # full frames at once: the view is not still building
    driver = studio_driver(window, monkeypatch, studio)
    for _ in range(20):
        driver.frame()
    assert not imgui_input_pending() and not studio.busy()
    for ch in "/tmp":
        imgui.get_io().add_key_event(imgui.Key.a, True)  # as glfw queues them: key down, character, key up
        imgui.get_io().add_input_character(ord(ch))
        imgui.get_io().add_key_event(imgui.Key.a, False)
    assert imgui_input_pending() and studio.busy()
    for _ in range(20):
        driver.frame()
    assert not imgui_input_pending() and not studio.busy()
