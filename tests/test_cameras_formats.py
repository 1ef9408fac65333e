"""Camera readers: COLMAP text/binary, LLFF, 3DGS cameras.json, gsplat npz, and their error paths."""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gstyle_core.cameras import (
    Camera,
    CameraDistortionWarning,
    CameraSet,
    load_cameras,
    save_cameras_json,
)
from gstyle_core.cameras.colmap import MODELS_BY_NAME, quat_to_rotmat, read_cameras
from gstyle_core.cameras.llff import llff_pose_to_world_to_cam
from gstyle_core.errors import CameraFormatError

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes"
FERN = DATA / "llff_fern"
GARDEN = DATA / "gsplat_garden" / "test_garden.npz"
needs_fern = pytest.mark.skipif(not (FERN / "poses_bounds.npy").is_file(),
                                reason="shared/data llff_fern absent")
needs_garden = pytest.mark.skipif(not GARDEN.is_file(), reason="shared/data gsplat_garden absent")


def project(cam: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates [N,2] and depths [N] of world points in ``cam``."""
    pc = (cam.world_to_cam[:3, :3] @ np.asarray(points, np.float64).T).T + cam.world_to_cam[:3, 3]
    uv = (cam.K @ pc.T).T
    return uv[:, :2] / uv[:, 2:3], pc[:, 2]


def rotmat_to_quat(rot: np.ndarray) -> np.ndarray:
    """w, x, y, z of a rotation matrix (test helper; w >= 0 branch is enough for these rotations)."""
    w = np.sqrt(max(1e-12, 1.0 + np.trace(rot))) / 2
    return np.array([w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w),
                     (rot[1, 0] - rot[0, 1]) / (4 * w)])


def axis_angle(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


# ---- a test-only COLMAP writer -------------------------------------------------------------------

SYNTH_POINTS = np.array([[0.1, -0.2, 4.0], [0.5, 0.3, 5.0], [-0.4, 0.1, 3.5]])
SYNTH_COLORS = np.array([[255, 0, 0], [0, 128, 0], [10, 20, 30]], np.uint8)


def synthetic_model(model: str = "PINHOLE"):
    """Two images of one camera: (camera tuple, list of (name, qvec, tvec)) with known poses."""
    params = {"PINHOLE": [500.0, 520.0, 320.0, 240.0], "SIMPLE_PINHOLE": [500.0, 320.0, 240.0],
              "OPENCV": [500.0, 520.0, 320.0, 240.0, 0.01, -0.02, 0.001, 0.002],
              "SIMPLE_RADIAL": [500.0, 320.0, 240.0, 0.05]}[model]
    poses = []
    motions = [((0, 1, 0), 0.2, (0.1, -0.2, 0.3)), ((1, 1, 0), -0.3, (-0.5, 0.1, 1.0))]
    for i, (axis, angle, t) in enumerate(motions):
        rot = axis_angle(axis, angle)
        poses.append((f"img_{i}.png", rotmat_to_quat(rot), np.array(t, float)))
    return (1, model, 640, 480, params), poses


def write_colmap_text(folder: Path, camera, poses, points=SYNTH_POINTS, colors=SYNTH_COLORS) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    cam_id, model, w, h, params = camera
    (folder / "cameras.txt").write_text("# Camera list\n" + f"{cam_id} {model} {w} {h} "
                                        + " ".join(map(str, params)) + "\n")
    lines = ["# Image list with two lines of data per image:", "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ"]
    for i, (name, q, t) in enumerate(poses):
        lines.append(" ".join(map(str, [i + 1, *q, *t, cam_id, name])))
        lines.append("" if i == 0 else "100.5 200.5 1 10.0 20.0 -1")  # first image: empty POINTS2D line
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    pts = [f"{j + 1} {x} {y} {z} {r} {g} {b} 0.5 1 0 2 1" for j, ((x, y, z), (r, g, b))
           in enumerate(zip(points, colors, strict=True))]
    (folder / "points3D.txt").write_text("# 3D point list\n" + "\n".join(pts) + "\n")


def write_colmap_binary(folder: Path, camera, poses, points=SYNTH_POINTS, colors=SYNTH_COLORS) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    cam_id, model, w, h, params = camera
    model_id = MODELS_BY_NAME[model].model_id
    (folder / "cameras.bin").write_bytes(struct.pack("<Q", 1) + struct.pack("<iiQQ", cam_id, model_id, w, h)
                                         + struct.pack(f"<{len(params)}d", *params))
    data = struct.pack("<Q", len(poses))
    for i, (name, q, t) in enumerate(poses):
        data += struct.pack("<i7di", i + 1, *q, *t, cam_id) + name.encode() + b"\x00"
        data += struct.pack("<Q", 2) + struct.pack("<ddq", 1.0, 2.0, -1) + struct.pack("<ddq", 3.0, 4.0, 1)
    (folder / "images.bin").write_bytes(data)
    data = struct.pack("<Q", len(points))
    for j, (xyz, rgb) in enumerate(zip(points, colors, strict=True)):
        track = [(1, 0), (2, 1)][: 1 + j % 2]
        data += struct.pack("<Q3d3BdQ", j + 1, *xyz, *rgb, 0.5, len(track))
        data += b"".join(struct.pack("<ii", *pair) for pair in track)
    (folder / "points3D.bin").write_bytes(data)


@pytest.mark.parametrize("writer", [write_colmap_text, write_colmap_binary])
def test_colmap_model_projects_known_point_to_known_pixel(tmp_path, writer):
    camera, poses = synthetic_model("PINHOLE")
    writer(tmp_path / "scene" / "sparse" / "0", camera, poses)
    for path in (tmp_path / "scene", tmp_path / "scene" / "sparse", tmp_path / "scene" / "sparse" / "0"):
        cs = load_cameras(path)
        assert len(cs) == 2 and [c.name for c in cs] == ["img_0", "img_1"]
        np.testing.assert_allclose(cs.points, SYNTH_POINTS, atol=1e-6)
        np.testing.assert_allclose(cs.point_colors, SYNTH_COLORS / 255.0, atol=1e-6)
        assert not cs.has_images
    for cam, (_, q, t) in zip(cs, poses, strict=True):
        assert (cam.fx, cam.fy, cam.cx, cam.cy) == (500.0, 520.0, 320.0, 240.0)
        rot = quat_to_rotmat(q)
        world = rot.T @ (np.array([0.2, -0.1, 4.0]) - t)  # the world point that sits at camera (0.2,-0.1,4)
        uv, depth = project(cam, world[None])
        np.testing.assert_allclose(uv[0], [320 + 500 * 0.05, 240 - 520 * 0.025], atol=1e-9)
        np.testing.assert_allclose(depth, [4.0], atol=1e-12)
        np.testing.assert_allclose(cam.position, -rot.T @ t, atol=1e-12)


def test_colmap_pinhole_parts_of_models_and_distortion_warning(tmp_path):
    for model, expected in [("SIMPLE_PINHOLE", (500, 500, 320, 240)), ("SIMPLE_RADIAL", (500, 500, 320, 240)),
                            ("OPENCV", (500, 520, 320, 240))]:
        camera, poses = synthetic_model(model)
        write_colmap_binary(tmp_path / model, camera, poses)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            cs = load_cameras(tmp_path / model)
        distortion = [w for w in caught if issubclass(w.category, CameraDistortionWarning)]
        assert len(distortion) == (0 if model == "SIMPLE_PINHOLE" else 1)
        assert (cs[0].fx, cs[0].fy, cs[0].cx, cs[0].cy) == expected


def test_colmap_images_found_and_intrinsics_fitted_to_downscaled_folder(tmp_path):
    camera, poses = synthetic_model("PINHOLE")
    write_colmap_text(tmp_path / "sparse" / "0", camera, poses)
    for folder, size in (("images", (640, 480)), ("images_2", (320, 240))):
        (tmp_path / folder).mkdir()
        for name, _, _ in poses:
            Image.new("RGB", size, (10, 20, 30)).save(tmp_path / folder / name)
    full = load_cameras(tmp_path)
    assert full.has_images and full[0].image_path == tmp_path / "images" / "img_0.png"
    half = load_cameras(tmp_path, downscale=2)
    assert half[0].image_path.parent.name == "images_2"
    assert (half[0].width, half[0].height, half[0].fx, half[0].cx) == (320, 240, 250.0, 160.0)
    imgs = half.load_images()
    assert imgs[0].shape == (240, 320, 3)
    np.testing.assert_allclose(imgs[1][0, 0], np.array([10, 20, 30]) / 255.0, atol=1e-6)
    quarter = load_cameras(tmp_path, downscale=4)  # no images_4: full-size images, cameras scaled by 1/4
    assert (quarter[0].width, quarter[0].fx) == (160, 125.0)
    assert quarter.load_images()[0].shape == (120, 160, 3)
    explicit = load_cameras(tmp_path, image_dir="images_2")
    assert explicit[0].width == 320
    with pytest.raises(CameraFormatError, match="none of the 2 COLMAP images"):
        (tmp_path / "empty").mkdir()
        load_cameras(tmp_path, image_dir="empty")


# ---- 3DGS cameras.json --------------------------------------------------------------------------

def test_cameras_json_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    cams = []
    for i in range(4):
        w2c = np.eye(4)
        w2c[:3, :3] = axis_angle(rng.normal(size=3), rng.uniform(-2, 2))
        w2c[:3, 3] = rng.normal(size=3) * 5
        cams.append(Camera(800 + i, 600, 700.5 + i, 710.25, 400.0 + i, 290.0, w2c, name=f"view_{i}"))
    save_cameras_json(CameraSet(cams, "360", "test"), tmp_path / "cameras.json")
    entries = json.loads((tmp_path / "cameras.json").read_text())
    assert entries[1]["img_name"] == "view_1" and entries[1]["id"] == 1
    np.testing.assert_allclose(entries[2]["position"], cams[2].position, atol=1e-12)
    np.testing.assert_allclose(entries[2]["rotation"], cams[2].cam_to_world[:3, :3], atol=1e-12)
    back = load_cameras(tmp_path / "cameras.json")
    assert back.source.endswith("cameras.json") and len(back) == 4
    for a, b in zip(cams, back, strict=True):
        fields = ("width", "height", "fx", "fy", "cx", "cy", "name")
        assert [getattr(a, f) for f in fields] == [getattr(b, f) for f in fields]
        np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, atol=1e-12)
    assert load_cameras(tmp_path).source == back.source  # a folder holding cameras.json


def test_cameras_json_reference_layout_without_principal_point(tmp_path):
    rot = axis_angle((0, 1, 0), np.pi / 2)  # camera-to-world: camera z (forward) points along world -x
    entry = {"id": 0, "img_name": "00000", "width": 100, "height": 50, "position": [3.0, 0.0, 0.0],
             "rotation": rot.tolist(), "fx": 80.0, "fy": 80.0}
    (tmp_path / "cameras.json").write_text(json.dumps([entry]))
    cam = load_cameras(tmp_path / "cameras.json")[0]
    assert (cam.cx, cam.cy) == (50.0, 25.0)
    np.testing.assert_allclose(cam.forward, [1.0, 0.0, 0.0], atol=1e-12)
    uv, depth = project(cam, np.array([[5.0, 0.0, 0.0]]))
    np.testing.assert_allclose(uv[0], [50.0, 25.0], atol=1e-9)
    assert depth[0] == pytest.approx(2.0)


def json_entry(**changes) -> str:
    entry = {"width": 10, "height": 10, "position": [0, 0, 0], "rotation": np.eye(3).tolist(),
             "fx": 1, "fy": 1}
    entry.update(changes)
    return json.dumps([entry])


@pytest.mark.parametrize("content, message", [
    ("not json", "cannot read"),
    ("{}", "non-empty JSON list"),
    ("[]", "non-empty JSON list"),
    ("[3]", "camera 0 is not an object"),
    ('[{"width": 10}]', "lacks height"),
    (json_entry(position=[0, 0]), "position must be 3"),
    (json_entry(rotation=[[2, 0, 0], [0, 1, 0], [0, 0, 1]]), "not a rotation"),
    (json_entry(rotation=[[-1, 0, 0], [0, 1, 0], [0, 0, 1]]), "not a rotation"),
    (json_entry(fx=-1), "invalid size"),
    (json_entry(position=[0, float("nan"), 0]), "non-finite"),
    (json_entry(width="x"), "malformed field"),
])
def test_cameras_json_errors(tmp_path, content, message):
    (tmp_path / "cameras.json").write_text(content)
    with pytest.raises(CameraFormatError, match=message) as info:
        load_cameras(tmp_path / "cameras.json")
    assert "\n" not in str(info.value)


# ---- LLFF ---------------------------------------------------------------------------------------

def test_llff_convention_synthetic():
    # a camera at (1,2,3) looking along world +x, image down = world -z, image right = world -y
    down, right, back = np.array([0, 0, -1.0]), np.array([0, -1.0, 0]), np.array([-1.0, 0, 0])
    pose = np.stack([down, right, back, [1, 2, 3], [100, 200, 150]], axis=1)
    w2c = llff_pose_to_world_to_cam(pose)
    cam = Camera(200, 100, 150, 150, 100, 50, w2c)
    np.testing.assert_allclose(cam.forward, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(cam.position, [1, 2, 3], atol=1e-12)
    uv, depth = project(cam, np.array([[11.0, 1.0, 1.0]]))  # 10 ahead, 1 to the right, 2 down
    np.testing.assert_allclose(uv[0], [115.0, 80.0], atol=1e-9)
    assert depth[0] == pytest.approx(10.0)


@needs_fern
def test_llff_fern_cameras_and_points_line_up():
    cs = load_cameras(FERN)
    assert len(cs) == 20 and cs.kind == "forward" and cs.has_images
    assert cs.source == str(FERN)
    for cam in cs:
        assert (cam.width, cam.height) == (504, 378)
        assert cam.fx == pytest.approx(3260.526 / 8, abs=1e-3) and cam.fy == cam.fx
        assert (cam.cx, cam.cy) == (252.0, 189.0)
        assert cam.image_path.parent.name == "images_8"
    assert [c.name for c in cs][:2] == ["image000", "image001"]
    assert cs.points.shape == (10091, 3) and cs.point_colors.shape == (10091, 3)
    bounds = np.load(FERN / "poses_bounds.npy")[:, 15:]
    assert cs.near == pytest.approx(bounds.min()) and cs.far == pytest.approx(bounds.max())
    for cam, (near, far) in zip(cs, bounds, strict=True):
        uv, depth = project(cam, cs.points)
        assert np.all(depth > 0)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
        assert inside.mean() > 0.9
        # LLFF derived its bounds from these very points' depths: they must agree
        lo, hi = np.percentile(depth, [1, 99])
        assert 0.9 * near < lo and hi < 1.1 * far


@needs_fern
def test_fern_colmap_focal_matches_llff_and_paths_into_the_scene():
    with pytest.warns(CameraDistortionWarning, match="SIMPLE_RADIAL"):
        cam = read_cameras(FERN / "sparse" / "0" / "cameras.bin")[1]
    hwf = np.load(FERN / "poses_bounds.npy")[0, :15].reshape(3, 5)[:, 4]
    assert (cam.height, cam.width) == (hwf[0], hwf[1]) and cam.fx == pytest.approx(hwf[2])
    for path in (FERN / "sparse" / "0", FERN / "sparse", FERN / "poses_bounds.npy"):
        assert len(load_cameras(path)) == 20  # no images.bin: poses_bounds.npy is used
    assert load_cameras(FERN, downscale=8)[0].width == 504
    small = load_cameras(FERN, downscale=16)  # no images_16: the images_8 cameras halved, images resized
    assert (small[0].width, small[0].height) == (252, 189)
    assert small[0].fx == pytest.approx(3260.526 / 16, abs=1e-3)
    assert small.has_images and small.load_images()[0].shape == (189, 252, 3)


@needs_fern
def test_fern_images_load_and_scale():
    cs = load_cameras(FERN)
    train, test = cs.split_train_test()
    assert [c.name for c in test] == ["image000", "image008", "image016"] and len(train) == 17
    small, images = test.with_images(max_width=126)
    assert (small[0].width, small[0].height) == (126, round(378 * 126 / 504))
    assert images[0].shape == (small[0].height, small[0].width, 3) and images[0].dtype == np.float32
    assert 0.0 <= images[0].min() and images[0].max() <= 1.0 and images[0].std() > 0.05


def test_llff_synthetic_scene_and_errors(tmp_path):
    poses = np.zeros((3, 3, 5))
    for i in range(3):
        poses[i, :, :3] = np.stack([[0, 1, 0], [1, 0, 0], [0, 0, -1]], axis=1)  # down=+y, right=+x, back=-z
        poses[i, :, 3] = [i * 0.1, 0, 0]
        poses[i, :, 4] = [60, 80, 100]
    arr = np.concatenate([poses.reshape(3, 15), np.tile([[1.0, 10.0]], (3, 1))], axis=1)
    np.save(tmp_path / "poses_bounds.npy", arr)
    cs = load_cameras(tmp_path)
    assert (cs[0].width, cs[0].height, cs[0].fx) == (80, 60, 100.0) and not cs.has_images
    np.testing.assert_allclose(cs[1].world_to_cam[:3, :3], np.eye(3), atol=1e-12)
    (tmp_path / "images_4").mkdir()
    for i in range(2):
        Image.new("RGB", (20, 15)).save(tmp_path / "images_4" / f"{i}.png")
    with pytest.raises(CameraFormatError, match="has 2 images but poses_bounds.npy has 3 poses"):
        load_cameras(tmp_path)
    Image.new("RGB", (20, 15)).save(tmp_path / "images_4" / "2.png")
    assert load_cameras(tmp_path)[0].fx == pytest.approx(25.0)
    Image.new("RGB", (15, 20)).save(tmp_path / "images_4" / "0.png")
    with pytest.raises(CameraFormatError, match="other aspect"):
        load_cameras(tmp_path)
    np.save(tmp_path / "poses_bounds.npy", arr[:, :16])
    with pytest.raises(CameraFormatError, match=r"\[N,17\]"):
        load_cameras(tmp_path)
    arr[0, 4] = np.nan
    np.save(tmp_path / "poses_bounds.npy", arr)
    with pytest.raises(CameraFormatError, match="non-finite"):
        load_cameras(tmp_path)
    (tmp_path / "poses_bounds.npy").write_bytes(b"garbage")
    with pytest.raises(CameraFormatError, match="cannot read poses_bounds.npy"):
        load_cameras(tmp_path)


# ---- gsplat npz ---------------------------------------------------------------------------------

@needs_garden
def test_gsplat_garden_npz():
    cs = load_cameras(GARDEN)
    assert len(cs) == 3 and cs.points.shape == (138766, 3) and cs.point_colors.max() <= 1.0
    with np.load(GARDEN) as data:
        np.testing.assert_allclose(cs[1].world_to_cam, data["viewmats"][1], atol=1e-6)
        assert (cs[0].width, cs[0].height) == (int(data["width"]), int(data["height"]))
        assert cs[2].fx == pytest.approx(float(data["Ks"][2, 0, 0]))
    centre = np.median(cs.points, axis=0)
    for cam in cs:  # OpenCV world-to-camera: the scene centre is in front of every camera and in view
        uv, depth = project(cam, centre[None])
        assert depth[0] > 0 and 0 <= uv[0, 0] < cam.width and 0 <= uv[0, 1] < cam.height
    # 3 cameras of a 360 capture, view directions up to 50° from their mean: "360" (see classify tests)
    assert cs.kind == "360"
    assert load_cameras(GARDEN, downscale=2)[0].width == 324


def test_npz_errors(tmp_path):
    np.savez(tmp_path / "a.npz", viewmats=np.eye(4)[None], width=10, height=10)
    with pytest.raises(CameraFormatError, match="lacks Ks"):
        load_cameras(tmp_path / "a.npz")
    two_ks = np.eye(3)[None].repeat(2, 0)
    np.savez(tmp_path / "b.npz", viewmats=np.eye(4)[None], Ks=two_ks, width=10, height=10)
    with pytest.raises(CameraFormatError, match="viewmats must be"):
        load_cameras(tmp_path / "b.npz")
    k = np.array([[[-5.0, 0, 5], [0, 5, 5], [0, 0, 1]]])
    np.savez(tmp_path / "c.npz", viewmats=np.eye(4)[None], Ks=k, width=10, height=10)
    with pytest.raises(CameraFormatError, match="focal lengths must be positive"):
        load_cameras(tmp_path / "c.npz")
    (tmp_path / "d.npz").write_bytes(b"PK not a zip")
    with pytest.raises(CameraFormatError, match="cannot read d.npz"):
        load_cameras(tmp_path / "d.npz")


# ---- COLMAP and dispatcher errors ---------------------------------------------------------------

def test_colmap_errors(tmp_path):
    camera, poses = synthetic_model("PINHOLE")
    write_colmap_binary(tmp_path / "bin", camera, poses)
    points = (tmp_path / "bin" / "points3D.bin").read_bytes()
    (tmp_path / "bin" / "points3D.bin").write_bytes(points[:-4])
    with pytest.raises(CameraFormatError, match="points3D.bin: file is truncated"):
        load_cameras(tmp_path / "bin")
    (tmp_path / "bin" / "points3D.bin").write_bytes(points)
    data = (tmp_path / "bin" / "images.bin").read_bytes()
    (tmp_path / "bin" / "images.bin").write_bytes(data[:-10])
    with pytest.raises(CameraFormatError, match="images.bin: file is truncated"):
        load_cameras(tmp_path / "bin")
    (tmp_path / "bin" / "cameras.bin").write_bytes(struct.pack("<Q", 1) + struct.pack("<iiQQ", 1, 42, 10, 10))
    with pytest.raises(CameraFormatError, match="unknown camera model id 42"):
        load_cameras(tmp_path / "bin")
    write_colmap_text(tmp_path / "txt", camera, poses)
    (tmp_path / "txt" / "cameras.txt").write_text("1 PINHOLE 640 480 500 500 320\n")
    with pytest.raises(CameraFormatError, match="PINHOLE needs 4 parameters"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "txt" / "cameras.txt").write_text("1 FISHY 640 480 500\n")
    with pytest.raises(CameraFormatError, match="unknown camera model"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "txt" / "cameras.txt").write_text("2 PINHOLE 640 480 500 500 320 240\n")
    with pytest.raises(CameraFormatError, match="refers to missing camera 1"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "txt" / "cameras.txt").write_text("1 PINHOLE 640 480 0 500 320 240\n")
    with pytest.raises(CameraFormatError, match="invalid intrinsics"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "txt" / "cameras.txt").write_text("1 PINHOLE 640 480 500 500 320 240\n")
    (tmp_path / "txt" / "images.txt").write_text("1 0 0 0 0 0 0 0 1 a.png\n\n")
    with pytest.raises(CameraFormatError, match="quaternion"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "txt" / "images.txt").write_text("1 1 0 0 x 0 0 0 1 a.png\n\n")
    with pytest.raises(CameraFormatError, match="malformed COLMAP file"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "txt" / "images.txt").write_text("# nothing registered\n")
    with pytest.raises(CameraFormatError, match="no registered images"):
        load_cameras(tmp_path / "txt")
    (tmp_path / "nomodel" / "sparse" / "0").mkdir(parents=True)
    (tmp_path / "nomodel" / "sparse" / "0" / "cameras.txt").write_text("1 PINHOLE 640 480 500 500 320 240\n")
    with pytest.raises(CameraFormatError, match="no images.bin/images.txt"):
        load_cameras(tmp_path / "nomodel")


def test_dispatch_errors(tmp_path):
    with pytest.raises(CameraFormatError, match="not found"):
        load_cameras(tmp_path / "missing")
    with pytest.raises(CameraFormatError, match="no cameras in"):
        load_cameras(tmp_path)
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(CameraFormatError, match="unknown camera file x.txt"):
        load_cameras(tmp_path / "x.txt")
    camera, poses = synthetic_model("PINHOLE")
    write_colmap_text(tmp_path / "m", camera, poses)
    with pytest.raises(CameraFormatError, match="image folder not found"):
        load_cameras(tmp_path / "m", image_dir="nope")
    with pytest.raises(CameraFormatError, match="downscale must be a positive integer"):
        load_cameras(tmp_path / "m", downscale=0)
    assert len(load_cameras(tmp_path / "m" / "images.txt")) == 2
