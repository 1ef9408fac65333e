"""Turntable, scene-camera and camera-path videos: nerfstudio camera paths convert to the same camera (and image),
MP4 / GIF / PNG-folder outputs hold the frames, bad input exits 2 and nothing half-written is ever left behind."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PIL import Image

from gstyle_core import render_video as rv
from gstyle_core.cameras import save_cameras_json
from gstyle_core.cameras.camera_path import camera_path_dict, read_camera_path
from gstyle_core.cli import run
from gstyle_core.errors import CameraFormatError, GStyleError
from gstyle_core.io import save_scene
from gstyle_core.scene import GaussianScene, logit, rgb_to_sh_dc
from gstyle_core.scene_images import render_scene_image
from gstyle_core.video import Cancelled, write_frames
from tests.synthetic import blob_scene, look_at_camera, ring_cameras

W, H = 40, 32


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "scene.ply"
    save_scene(blob_scene(150, sh_degree=1), path)
    return path


def listing(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def two_blobs() -> GaussianScene:
    """A red blob at world +x and a blue one at world -x, both at z = 0."""
    means = np.array([[0.8, 0, 0], [-0.8, 0, 0]], np.float32)
    return GaussianScene(means, np.full((2, 3), np.log(0.3), np.float32), np.tile([1, 0, 0, 0], (2, 1)).astype(
        np.float32), logit(np.full(2, 0.95)), rgb_to_sh_dc(np.array([[1, 0, 0], [0, 0, 1]], np.float32)))


# ------------------------------------------------------------------------------------- camera path format
def test_camera_path_in_opengl_convention_becomes_an_opencv_camera(tmp_path):
    # nerfstudio camera 3 units in front of the origin (world -z), looking at it (its -z = world +z), image up =
    # world -y: in OpenGL axes its x is world +x, its y (up) world -y, its z (backwards) world -z.
    c2w_gl = np.array([[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, -3], [0, 0, 0, 1]], float)
    path = tmp_path / "camera_path.json"
    path.write_text(json.dumps({"render_width": W, "render_height": H, "fps": 24, "seconds": 1,
                                "camera_path": [{"camera_to_world": c2w_gl.reshape(-1).tolist(), "fov": 60,
                                                 "aspect": W / H}]}))
    cam_path = read_camera_path(path)
    cam = cam_path.cameras[0]
    assert cam_path.fps == 24 and (cam.width, cam.height) == (W, H)
    assert np.allclose(cam.world_to_cam, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]])
    assert cam.fy == pytest.approx(0.5 * H / math.tan(math.radians(30))) and cam.fx == cam.fy
    assert (cam.cx, cam.cy) == (W / 2, H / 2)
    image = render_scene_image(two_blobs(), cam)
    right, left = image[:, W // 2:], image[:, : W // 2]
    assert right[..., 0].mean() > 3 * right[..., 2].mean() and left[..., 2].mean() > 3 * left[..., 0].mean()


def test_camera_path_of_known_cameras_renders_the_same_images(tmp_path):
    scene = blob_scene(150, sh_degree=1)
    cams = [look_at_camera((0.5, -1.0, -3.0), (0, 0, 0), W, H, fov_deg=47.0),
            look_at_camera((3.0, 0.2, 0.5), (0.1, 0, 0), W, H, fov_deg=47.0)]
    path = tmp_path / "camera_path.json"
    path.write_text(json.dumps(camera_path_dict(cams, fps=12)))
    back = read_camera_path(path).cameras
    for cam, got in zip(cams, back, strict=True):
        assert np.allclose(got.world_to_cam, cam.world_to_cam, atol=1e-9)
        assert (got.fx, got.fy, got.cx, got.cy) == pytest.approx((cam.fy, cam.fy, cam.cx, cam.cy))
        assert np.abs(render_scene_image(scene, got) - render_scene_image(scene, cam)).max() < 1e-5


@pytest.mark.parametrize("content, message", [
    ("{not json", "not a JSON camera path"),
    ("[1, 2]", "JSON object"),
    ('{"render_width": 10, "render_height": 10, "camera_path": []}', "non-empty list"),
    ('{"render_width": 10, "render_height": 10, "camera_path": [{"camera_to_world": [1, 2], "fov": 50}]}',
     "16 finite numbers"),
    ('{"render_width": 10, "render_height": 10, "camera_path": [{"camera_to_world": '
     '[2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "fov": 50}]}', "not a rotation"),
    ('{"render_width": 10, "render_height": 10, "camera_path": [{"camera_to_world": '
     '[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "fov": 190}]}', "fov"),
    ('{"render_width": 0, "render_height": 10, "camera_path": []}', "render_width"),
    ('{"render_width": 10, "render_height": 10, "camera_type": "fisheye", "camera_path": []}', "perspective"),
])
def test_malformed_camera_paths_are_one_line_errors(tmp_path, content, message):
    path = tmp_path / "camera_path.json"
    path.write_text(content)
    with pytest.raises(CameraFormatError, match=message):
        read_camera_path(path)


# ---------------------------------------------------------------------------------------------------- CLI
def test_turntable_gif_orbits_the_scene(tmp_path, scene_file, capsys):
    out = tmp_path / "spin.gif"
    assert run(["render", str(scene_file), "--turntable", "4", "--width", "48", "--out", str(out)]) == 0
    assert "4 frames" in capsys.readouterr().out
    gif = Image.open(out)
    assert gif.n_frames == 4 and gif.size == (48, 36)
    frames = []
    for i in range(4):
        gif.seek(i)
        frames.append(np.asarray(gif.convert("RGB"), np.float32))
    assert frames[0].max() > 0 and np.abs(frames[0] - frames[2]).mean() > 1.0  # the view moves around
    assert listing(tmp_path) == ["scene.ply", "spin.gif"]


def test_turntable_mp4_holds_every_frame(tmp_path, scene_file):
    imageio = pytest.importorskip("imageio.v2")
    pytest.importorskip("imageio_ffmpeg")
    out = tmp_path / "spin.mp4"
    assert run(["render", str(scene_file), "--turntable", "5", "--width", "47", "--fps", "10", "--out",
                str(out)]) == 0
    reader = imageio.get_reader(out, format="FFMPEG")
    frames = [f for f in reader]
    meta = reader.get_meta_data()
    reader.close()
    assert len(frames) == 5 and frames[0].shape == (36, 48, 3)  # 47x35 padded to even sides for H.264
    assert meta["fps"] == pytest.approx(10)
    expected = rv.turntable_cameras(blob_scene(150, sh_degree=1), 5, 640, 480)[1].resized_to_width(47)
    from gstyle_core.io import load_scene

    ref = render_scene_image(load_scene(scene_file)[0], expected)
    assert np.abs(frames[1][:35, :47] / 255.0 - ref).mean() < 0.03  # lossy H.264 of the same view
    assert listing(tmp_path) == ["scene.ply", "spin.mp4"]


def test_video_follows_the_scene_cameras_into_a_folder(tmp_path, scene_file):
    cams = ring_cameras(3, width=W, height=H)
    save_cameras_json(cams, tmp_path / "cameras.json")
    out = tmp_path / "frames"
    assert run(["render", str(scene_file), "--cameras", str(tmp_path / "cameras.json"), "--out", f"{out}/"]) == 0
    assert listing(out) == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]
    from gstyle_core.io import load_scene

    scene = load_scene(scene_file)[0]
    for i, cam in enumerate(cams):
        got = np.asarray(Image.open(out / f"frame_{i:05d}.png"), np.float32) / 255.0
        assert np.abs(got - render_scene_image(scene, cam)).max() <= 0.5 / 255 + 1e-4


def test_video_follows_a_camera_path(tmp_path, scene_file):
    cams = ring_cameras(2, width=W, height=H)
    (tmp_path / "camera_path.json").write_text(json.dumps(camera_path_dict(cams, fps=5)))
    out = tmp_path / "frames"
    assert run(["render", str(scene_file), "--camera-path", str(tmp_path / "camera_path.json"), "--out",
                str(out)]) == 0
    from gstyle_core.io import load_scene

    scene = load_scene(scene_file)[0]
    for i, cam in enumerate(cams):
        got = np.asarray(Image.open(out / f"frame_{i:05d}.png"), np.float32) / 255.0
        assert np.abs(got - render_scene_image(scene, cam)).max() <= 0.5 / 255 + 1e-4


def test_existing_frames_need_force_and_other_folders_are_refused(tmp_path, scene_file, capsys):
    out = tmp_path / "frames"
    args = ["render", str(scene_file), "--width", "24", "--out", str(out)]
    assert run([*args, "--turntable", "3"]) == 0
    assert run([*args, "--turntable", "2"]) == 2 and "--force" in capsys.readouterr().err
    assert listing(out) == [f"frame_{i:05d}.png" for i in range(3)]
    assert run([*args, "--turntable", "2", "--force"]) == 0  # replaced as a whole, not merged
    assert listing(out) == ["frame_00000.png", "frame_00001.png"]
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    assert run([*args[:-1], str(tmp_path / "mine"), "--turntable", "2", "--force"]) == 2
    assert "other files" in capsys.readouterr().err
    assert listing(tmp_path / "mine") == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames", "mine", "scene.ply"]  # no temporary left


@pytest.mark.parametrize("extra, message", [
    (["--turntable", "0", "--out", "v.gif"], "1 to"),
    (["--turntable", "3", "--out", "v.avi"], "unknown video output"),
    (["--turntable", "3", "--out", "v.png"], "unknown video output"),
    (["--camera-path", "missing.json", "--out", "v.gif"], "camera path not found"),
    (["--camera-path", "bad.json", "--out", "v.gif"], "not a JSON camera path"),
    (["--camera-path", "empty.json", "--out", "v.gif"], "non-empty list"),
    (["--turntable", "3", "--camera-path", "empty.json", "--out", "v.gif"], "alternatives"),
    (["--out", "v.gif"], "needs --turntable"),
    (["--turntable", "3", "--camera", "1", "--out", "v.gif"], "--camera picks one image"),
    (["--turntable", "3", "--fps", "0", "--out", "v.gif"], "--fps"),
])
def test_bad_video_requests_exit_2_and_write_nothing(tmp_path, scene_file, capsys, monkeypatch, extra, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.json").write_text("{oops")
    (tmp_path / "empty.json").write_text('{"render_width": 8, "render_height": 8, "fps": 5, "camera_path": []}')
    before = listing(tmp_path)
    assert run(["render", str(scene_file), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gstyle render: error:") and message in err and "\n" not in err
    assert listing(tmp_path) == before


# ------------------------------------------------------------------------------------- atomic frame output
@pytest.mark.parametrize("name", ["v.gif", "v.mp4", "frames"])
def test_a_failing_frame_leaves_no_output(tmp_path, name):
    if name.endswith(".mp4"):
        pytest.importorskip("imageio_ffmpeg")

    def frames():
        yield np.zeros((16, 16, 3), np.float32)
        yield np.ones((16, 16, 3), np.float32)
        raise RuntimeError("renderer crashed")

    with pytest.raises(RuntimeError, match="crashed"):
        write_frames(frames(), tmp_path / name, 10)
    assert listing(tmp_path) == []


@pytest.mark.parametrize("name", ["v.gif", "frames"])
def test_cancel_leaves_the_old_output_untouched(tmp_path, name):
    target = tmp_path / name
    write_frames([np.zeros((8, 8, 3))], target, 5)
    before = target.read_bytes() if target.is_file() else listing(target)
    calls = iter([False, False, True])
    with pytest.raises(Cancelled):
        write_frames([np.ones((8, 8, 3))] * 3, target, 5, cancelled=lambda: next(calls))
    assert (target.read_bytes() if target.is_file() else listing(target)) == before
    assert listing(tmp_path) == [name]


def test_cameras_of_different_sizes_need_a_folder(tmp_path):
    cams = [look_at_camera((0, 0, -3), (0, 0, 0), 20, 16), look_at_camera((0, 0, -3), (0, 0, 0), 24, 16)]
    with pytest.raises(GStyleError, match="different image sizes"):
        rv.render_video(blob_scene(20), cams, tmp_path / "v.gif")
    assert rv.render_video(blob_scene(20), cams, tmp_path / "frames") == 2
