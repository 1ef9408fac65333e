"""The studio opens a ``gstyle batch`` folder as takes (issue #50 item 1): each finished job a take named SCENE after
PAINTING with its settings line, to compare with; from ``gstyle-studio --batch DIR``, or the folder or its
batch.csv dropped on the window or chosen in the file browser. The batch runs the stand-in engine
(``batch_worker.py``) with one job failed (a broken painting), which is no take."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from batch_worker import use_tiny_engine  # noqa: E402
from fakes import still_studio  # noqa: E402
from synthetic import blob_scene  # noqa: E402
from test_batch import make_inputs  # noqa: E402

from app.takes import TakeShelf  # noqa: E402
from gstyle_core.cli import run  # noqa: E402
from gstyle_core.errors import GStyleError  # noqa: E402
from gstyle_core.io import save_scene  # noqa: E402

W, H = 160, 120
FINISHED = ["scene1 after red", "scene2 after red"]


@pytest.fixture
def batch_dir(tmp_path, monkeypatch) -> Path:
    """A finished batch: two scenes after red (done) and after blue (failed: the painting is broken)."""
    inputs = make_inputs(tmp_path, monkeypatch)
    Path(inputs["paintings"][1]).write_bytes(b"not a painting")
    use_tiny_engine(monkeypatch.setattr)
    argv = ["batch", "--scenes", *inputs["scenes"], "--styles", *inputs["paintings"], "--out", str(inputs["out"]),
            "--checkpoint-every", "0", "--jobs", "1"]
    assert run(argv) == 1  # two jobs failed
    return inputs["out"]


def test_a_batch_s_finished_jobs_are_takes_that_exports_do_not_push_off(batch_dir, tmp_path):
    shelf = TakeShelf(tmp_path / "studio", limit=2)
    shelf.add(save_export(tmp_path / "studio" / "early.ply"), 30)
    new = shelf.add_batch(batch_dir)
    assert [t.name for t in new] == FINISHED and [t.name for t in shelf.takes] == [*FINISHED, "take 1"]
    assert {(t.path, t.gaussians, t.settings, t.batch, Path(t.scene).name) for t in new} == {
        (str(batch_dir / f"scene{k}__red.ply"), 40, "preview, 32 px", str(batch_dir), f"scene{k}.ply") for k in (1, 2)}
    for k in (2, 3):  # more exports than the limit: the oldest export goes, the batch's takes stay
        shelf.add(save_export(tmp_path / "studio" / f"e{k}.ply"), 30)
    assert [t.name for t in shelf.takes] == ["take 3", "take 2", *FINISHED]
    assert [t.name for t in TakeShelf(tmp_path / "studio", limit=2).takes] == ["take 3", "take 2", *FINISHED]
    assert shelf.load(2).count == 40
    with pytest.raises(GStyleError, match=r"^cannot read .*batch.csv: No such file or directory$"):
        shelf.add_batch(tmp_path)


def save_export(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    save_scene(blob_scene(30), path)
    return path


@pytest.fixture
def studio(window, tmp_path):
    app = still_studio(window, tmp_path, (W, H))
    yield app
    app.close()


def test_a_batch_folder_or_its_table_dropped_opens_its_jobs_as_takes_to_compare(studio, batch_dir, tmp_path):
    studio.files.on_drop([str(batch_dir)])
    assert [t.name for t in studio.takes.shelf.takes] == FINISHED
    assert studio.panel.status == "opened the batch batch: 2 takes to compare (scene1 after red, ...)"
    # the studio showed another scene: the first take opens as the scene, compared with its original
    assert studio.session.loaded.path == str(batch_dir / "scene1__red.ply") and studio.session.result is not None
    assert studio.views.mode == "compare" and not studio.views.compare_with_take and studio.views.take_shown is None
    texture = studio.takes.texture(studio.takes.shelf.takes[1])  # its after picture, fitted in the thumbnail
    assert texture is not None and texture[1] == (96, 32)
    assert studio.takes.show_take(1, compare=False) and studio.session.loaded.path == str(batch_dir / "scene2__red.ply")
    assert studio.views.mode == "stylized" and studio.panel.status == (
        "opened scene2 after red (scene2__red.ply), a take of another scene, as the scene")
    # a take of the scene on show (scene2's input) is drawn beside it from the same camera
    same = replace(studio.takes.shelf.takes[0], name="scene2 again", path=str(batch_dir / "scene1__red.ply"),
                   scene=studio.takes.shelf.takes[1].scene)
    studio.takes.shelf.takes.append(same)
    assert studio.takes.show_take(2, compare=True) and studio.session.loaded.path == str(batch_dir / "scene2__red.ply")
    views = studio.views
    assert views.take_shown == same.path and views.compare_with_take and views.take_view.count == 40

    assert studio.files.open_path(str(batch_dir / "batch.csv")) and len(studio.takes.shelf.takes) == 2  # the same takes
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "batch.csv").write_text("scene,painting,status,out\n")
    assert not studio.files.open_path(str(empty / "batch.csv"))
    assert studio.panel.status == f"no finished jobs in {empty / 'batch.csv'}"
    (empty / "batch.csv").write_text("a,b\n1,2\n")
    assert not studio.files.open_path(str(empty))
    assert studio.panel.status == (f"could not open the batch: {empty / 'batch.csv'} is not a gstyle batch table "
                                   "(no scene, painting, status and out columns)")
    assert len(studio.takes.shelf.takes) == 2


def test_gstyle_studio_batch_shows_the_first_result_with_the_batch_as_takes(batch_dir, tmp_path, capsys):
    from app.main import main

    shot = tmp_path / "shot.png"
    assert main(["--batch", str(batch_dir), "--headless", "--frames", "2", "--size", "320x240",
                 "--output-dir", str(tmp_path / "studio"), "--screenshot", str(shot)]) == 0
    out = capsys.readouterr().out
    assert "opened the batch batch: 2 takes to compare" in out and shot.is_file(), out
    assert "gstyle-studio: scene1__red.ply: a stylized result (preset preview, 32 px, after red.png" in out, out
    assert [t.name for t in TakeShelf(tmp_path / "studio").takes] == FINISHED  # remembered with the studio's takes
    assert main(["--batch", str(tmp_path / "nowhere"), "--headless", "--frames", "1"]) == 2
    assert capsys.readouterr().err.strip() == (f"gstyle-studio: cannot read {tmp_path / 'nowhere' / 'batch.csv'}: "
                                               "No such file or directory")
