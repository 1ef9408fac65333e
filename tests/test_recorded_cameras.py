"""A stylized result renders from its input's generated cameras (issue #50 item 4): ``gstyle stylize`` records the
parameters of a bare scene's generated cameras in OUT.json, and ``gstyle render OUT.ply --camera K`` (and the
studio's framing) use them, so a result whose Gaussians reach further out than its input's is framed as its input
was and before/after pictures of camera K compare pixel to pixel."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image
from synthetic import blob_scene
from test_outputs_stylize import TinyEngine, stylize, tiny  # noqa: F401 - the stand-in engine's fixture

from gstyle_core.cameras import generate_cameras
from gstyle_core.cameras.recorded import RECORD_KEY, camera_record, cameras_from_record, recorded_cameras
from gstyle_core.cli import run
from gstyle_core.cli import stylize as cli
from gstyle_core.engine.build import BuiltEngine
from gstyle_core.errors import GStyleError
from gstyle_core.io import load_scene, save_scene
from gstyle_core.scene import GaussianScene
from gstyle_core.scene_images import load_scene_and_cameras, render_scene_image, save_png


def grown(scene: GaussianScene, count: int = 40, distance: float = 4.0, seed: int = 3) -> GaussianScene:
    """``scene`` with ``count`` more Gaussians on a shell ``distance`` out (a result whose splits reached outward)."""
    shell = blob_scene(count, seed=seed)
    directions = shell.means / np.linalg.norm(shell.means, axis=1, keepdims=True)
    shell.means[:] = (directions * distance).astype(np.float32)
    return GaussianScene.concatenate([scene, shell])


def test_a_record_makes_the_same_cameras_again_through_json():
    means = blob_scene(200, seed=1).means
    for kind, up in (("orbit", "-y"), ("arc", "pca"), ("orbit", np.array([0.3, -1.0, 0.2]))):
        cams = generate_cameras(means, kind=kind, count=7, width=96, height=64, fov_deg=40.0, up=up)
        record = json.loads(json.dumps(camera_record(cams, means)))
        again = cameras_from_record(record)
        assert (again.kind, again.source, len(again)) == (cams.kind, cams.source, 7)
        for a, b in zip(again, cams, strict=True):
            assert (a.width, a.height, a.fx, a.cx, a.cy) == (b.width, b.height, b.fx, b.cx, b.cy)
            np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, rtol=0, atol=1e-12)


def test_cameras_not_generated_record_nothing_and_a_bad_record_is_one_line():
    means = blob_scene(50).means
    assert camera_record(SimpleNamespace(source="cameras.json"), means) is None
    record = camera_record(generate_cameras(means), means)
    for broken in ({k: v for k, v in record.items() if k != "radius"}, {**record, "centre": [0, 0]},
                   {**record, "radius": float("nan")}, {**record, "kind": "spiral"}, {**record, "count": 0}):
        with pytest.raises(GStyleError, match=f"^OUT.json: the recorded cameras \\({RECORD_KEY}\\) are malformed"):
            cameras_from_record(broken, "OUT.json")


def test_a_summary_without_a_record_leaves_the_cameras_generated(tmp_path):
    scene = blob_scene(60)
    save_scene(scene, tmp_path / "s.ply")
    assert recorded_cameras(tmp_path / "s.ply") is None  # no summary beside it
    (tmp_path / "s.json").write_text('{"gaussians": 60}')  # some other summary
    assert recorded_cameras(tmp_path / "s.ply") is None
    (tmp_path / "s.json").write_text("not json")
    _scene, _report, cams = load_scene_and_cameras(str(tmp_path / "s.ply"), None)
    assert cams.source == "generated-orbit"


def test_a_result_of_given_cameras_opens_with_them_while_they_are_there(tmp_path):
    """A run given its cameras (a cameras.json, an LLFF or COLMAP folder) names them in OUT.json (``camera_source``):
    the result renders and opens in the studio from them, not from an orbit around its Gaussians."""
    from gstyle_core.cameras.gs_json import save_cameras_json

    scene = blob_scene(60)
    save_scene(scene, tmp_path / "s.ply")
    given = generate_cameras(scene.means, kind="orbit", count=5)
    save_cameras_json(given, tmp_path / "cameras.json")
    (tmp_path / "s.json").write_text(json.dumps({"camera_source": str(tmp_path / "cameras.json")}))
    cams = recorded_cameras(tmp_path / "s.ply")
    assert cams is not None and len(cams.cameras) == 5 and cams.source.endswith(", the input's, named in s.json")
    assert np.allclose(cams.cameras[3].world_to_cam, given.cameras[3].world_to_cam, atol=1e-5)
    _scene, _report, loaded = load_scene_and_cameras(str(tmp_path / "s.ply"), None)
    assert len(loaded.cameras) == 5 and not loaded.source.startswith("generated")
    (tmp_path / "cameras.json").write_text("[]")  # changed since: unreadable as cameras
    assert recorded_cameras(tmp_path / "s.ply") is None
    (tmp_path / "cameras.json").unlink()  # moved: generated around the result again
    assert recorded_cameras(tmp_path / "s.ply") is None
    assert load_scene_and_cameras(str(tmp_path / "s.ply"), None)[2].source == "generated-orbit"


def test_a_grown_result_renders_camera_k_framed_as_its_input(tiny, tmp_path, monkeypatch, capsys):  # noqa: F811
    source = blob_scene(40, seed=7)
    input_cams = generate_cameras(source.means)

    class GrownEngine(TinyEngine):
        def stylized_scene(self):
            return grown(super().stylized_scene())

    monkeypatch.setattr(cli, "build_stylizer", lambda request: BuiltEngine(
        GrownEngine(), source, None, input_cams, np.zeros((8, 8, 3), np.float32)))
    out = tmp_path / "out.ply"
    assert run(stylize(out)) == 0
    assert json.loads(out.with_suffix(".json").read_text())[RECORD_KEY]["count"] == len(input_cams)
    result = load_scene(out)[0]
    assert result.count == 80
    own = generate_cameras(result.means)  # the cameras generated around the result frame it otherwise
    assert not np.allclose(own[5].world_to_cam, input_cams[5].world_to_cam, atol=1e-3)

    _scene, _report, cams = load_scene_and_cameras(str(out), None)
    assert "recorded in out.json" in cams.source and len(cams) == len(input_cams)
    for a, b in zip(cams, input_cams, strict=True):
        np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, rtol=0, atol=1e-12)
    png = tmp_path / "k5.png"
    assert run(["render", str(out), "--camera", "5", "--out", str(png)]) == 0
    save_png(tmp_path / "expected.png", render_scene_image(result, input_cams[5]))
    np.testing.assert_array_equal(np.asarray(Image.open(png)), np.asarray(Image.open(tmp_path / "expected.png")))
    assert "the input's, recorded in out.json" in capsys.readouterr().out

    out.with_suffix(".json").write_text(json.dumps({RECORD_KEY: {"kind": "orbit"}}))
    assert run(["render", str(out), "--camera", "5", "--out", str(tmp_path / "k5b.png")]) == 2
    assert capsys.readouterr().err.strip() == (f"gstyle render: error: {out.with_suffix('.json')}: the recorded "
                                               f"cameras ({RECORD_KEY}) are malformed: no 'up'")


def test_the_studio_frames_a_result_by_its_inputs_box(tmp_path):
    from gstyle_core.cameras.framing import scene_box

    open_files = pytest.importorskip("app.open_files")
    source = blob_scene(60, seed=2)
    result = grown(source)
    save_scene(result, tmp_path / "r.ply")
    record = camera_record(generate_cameras(source.means), source.means)
    Path(tmp_path / "r.json").write_text(json.dumps({RECORD_KEY: record}))
    loaded = open_files.load_scene_with_cameras(str(tmp_path / "r.ply"), None)
    assert loaded.generated_cameras and loaded.frame_box is not None
    for got, want in zip(loaded.frame_box, scene_box(source.means), strict=True):
        np.testing.assert_allclose(got, want, atol=1e-9)
    assert not np.allclose(scene_box(result.means)[1], scene_box(source.means)[1], atol=0.1)
