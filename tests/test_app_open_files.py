"""Opening files in the studio: dropped files and the file dialogs' answers reach ``StudioApp.open_path``; scenes and
style images load, anything else or a broken file leaves the studio as it was with a one-line status."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from imgui_bundle import imgui  # noqa: E402, F401, I001 - before glfw (gl-stack.md)
from PIL import Image  # noqa: E402

from app.studio import LoadedScene, StudioApp  # noqa: E402
from fakes import still_studio  # noqa: E402
from gstyle_core.io import save_scene  # noqa: E402
from synthetic import blob_scene, look_at_camera  # noqa: E402

W, H = 160, 120


@pytest.fixture()
def studio(window, tmp_path):
    app = still_studio(window, tmp_path, (W, H))
    yield app
    app.close()


def _style_png(path, colour):
    noise = np.random.default_rng(0).integers(-20, 20, (12, 12, 3))
    Image.fromarray(np.clip(np.array(colour) + noise, 0, 255).astype(np.uint8)).save(path)
    return path


def test_dropped_scene_and_style_are_opened(studio, tmp_path):
    scene_path = tmp_path / "dropped.ply"
    save_scene(blob_scene(120, seed=2), scene_path)
    studio.files.on_drop([str(scene_path), str(tmp_path / "ignored.ply")])
    assert studio.views.stylized.count == 120
    assert "opened dropped.ply" in studio.panel.status and "1 more dropped file(s) ignored" in studio.panel.status
    style = _style_png(tmp_path / "style.png", (200, 40, 40))
    studio.files.on_drop([str(style)])
    assert studio.panel.style_path == str(style)
    studio.files.on_drop([])  # an empty drop changes nothing
    assert studio.views.stylized.count == 120


def test_sog_bundles_folders_and_their_meta_json_open(studio, tmp_path):
    save_scene(blob_scene(130, seed=3, sh_degree=1), tmp_path / "scene.sog")
    save_scene(blob_scene(140, seed=4), tmp_path / "web" / "meta.json")
    for path, count in ((tmp_path / "scene.sog", 130), (tmp_path / "web", 140), (tmp_path / "web" / "meta.json", 140)):
        studio.files.on_drop([str(path)])
        assert studio.views.stylized.count == count and f"opened {path.name}" in studio.panel.status
    (tmp_path / "web" / "quats.webp").unlink()
    studio.files.open_path(str(tmp_path / "web"))
    assert studio.views.stylized.count == 140 and studio.panel.status.startswith("could not open web: ")
    assert "quats (quats.webp) is missing" in studio.panel.status and "\n" not in studio.panel.status


def test_unknown_or_broken_files_leave_the_studio_as_it_was(studio, tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    studio.files.on_drop([str(tmp_path / "notes.txt")])
    assert studio.views.stylized.count == 50 and studio.panel.status == "not a scene or image: notes.txt"
    broken = tmp_path / "broken.ply"
    broken.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nend_header\n")
    studio.files.open_path(str(broken))
    assert studio.views.stylized.count == 50
    assert studio.panel.status.startswith("could not open broken.ply: ") and "\n" not in studio.panel.status
    fake_image = tmp_path / "fake.png"
    fake_image.write_bytes(b"not a png")
    studio.files.open_path(str(fake_image))
    assert studio.panel.status.startswith("could not open fake.png: ")


class _FakeDialog:
    def __init__(self, answer):
        self.answer = answer
        self.polls = 0

    def ready(self, _timeout):
        self.polls += 1
        return self.polls >= 2  # the user takes a frame to choose

    def result(self):
        return self.answer

    def kill(self):
        pass


def test_a_dialog_answer_is_opened_when_ready_and_a_cancel_changes_nothing(studio, tmp_path):
    style = _style_png(tmp_path / "chosen.jpg", (30, 90, 200))
    studio.files.dialog = ("open_style", _FakeDialog([str(style)]), "zenity", 0.0)
    studio.files.poll_dialog()
    assert studio.panel.style_path != str(style)  # not ready yet
    studio.files.poll_dialog()
    assert studio.panel.style_path == str(style) and studio.files.dialog is None
    studio.files.dialog = ("open_scene", _FakeDialog([]), "zenity", 0.0)  # cancelled (long after it opened)
    studio.files.poll_dialog()
    studio.files.poll_dialog()
    assert studio.files.dialog is None and studio.views.stylized.count == 50


def test_sliders_show_the_preset_of_the_scene_kind_before_any_engine_runs(window, tmp_path):
    from synthetic import ring_cameras

    forward = [look_at_camera((x, 0, -3), (x, 0, 0), W, H) for x in (-0.2, 0.0, 0.2)]
    app = StudioApp(window.ctx, loaded=LoadedScene("f.ply", blob_scene(30), forward), engine_factory=None,
                    engine_config={}, output_dir=tmp_path / "out")
    try:
        assert app.panel.params["lambda_nnfm"] == 100.0 and app.panel.params["lr"] == 0.1
        app.session.set_scene(LoadedScene("o.ply", blob_scene(30), ring_cameras(8)))  # cameras all around: 360°
        assert app.panel.params["lambda_nnfm"] == 200.0 and app.panel.params["lr"] == 0.05  # calibrated 360°
        assert app.panel.params["split_rate"] == 0.02
    finally:
        app.close()


def test_the_files_given_on_the_command_line_are_each_a_line_in_the_terminal(tmp_path, monkeypatch, capsys):
    """Issue #65 item 4: the scene and the paintings given on the command line are logged as an open in the studio
    is (``opened NAME (N Gaussians)``, ``opened NAME as the style``)."""
    from app.main import main

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    scene = tmp_path / "given.ply"
    save_scene(blob_scene(60, seed=2), scene)
    first, second = _style_png(tmp_path / "one.png", (200, 40, 40)), _style_png(tmp_path / "two.png", (40, 40, 200))
    assert main([str(scene), "--style", str(first), "--style", str(second), "--headless", "--frames", "1",
                 "--size", "160x120", "--output-dir", str(tmp_path / "o")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "gstyle-studio: opened given.ply (60 Gaussians)" in lines
    assert "gstyle-studio: opened one.png as the style" in lines
    assert "gstyle-studio: opened two.png as the second style" in lines
