"""One test per bug the reader fuzzing (``tests/test_fuzz_readers.py``, ``bench/soak.py``) found, as a fixed example.

Each input below made a reader raise something other than its ``GStyleError`` subclass, allocate what a
header claimed, print a numpy warning, or accept cameras that later crashed (singular poses, 0x0 images).
"""

from __future__ import annotations

import io
import json
import os
import struct
import tracemalloc
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import zstandard

from gstyle_core.cameras import load_cameras, save_cameras_json
from gstyle_core.errors import CameraFormatError, SceneFormatError
from gstyle_core.io import load_scene, save_scene
from tests.fuzzcases import check_camera_source
from tests.fuzzcases.cameras import npy_bytes
from tests.synthetic import blob_scene, ring_cameras


def _json(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "cameras.json"
    path.write_text(text)
    return path


def _one_json_camera(**changes: str) -> str:
    entry = {"id": 0, "img_name": "a", "width": 8, "height": 8, "position": [0, 0, 0],
             "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fx": 5, "fy": 5}
    text = json.dumps([entry])
    for key, value in changes.items():
        text = text.replace(f'"{key}": {json.dumps(entry[key])}', f'"{key}": {value}')
    return text


@pytest.mark.parametrize("text, message", [
    (_one_json_camera(width="1e400"), "malformed field"),  # int(inf): OverflowError
    (_one_json_camera(height="-1e400"), "malformed field"),
    (_one_json_camera(fx="1" * 5000), "cannot read"),  # over Python's 4300-digit limit: plain ValueError
    ("[" * 100_000 + "]" * 100_000, "nested too deeply"),  # RecursionError
    (_one_json_camera(width="10" + "0" * 30), "outside 1..65536"),  # accepted, then any render would explode
])
def test_cameras_json(tmp_path, text, message):
    with pytest.raises(CameraFormatError, match=message):
        load_cameras(_json(tmp_path, text))


def _npz(path: Path, **arrays: np.ndarray) -> Path:
    base = {"viewmats": np.eye(4)[None], "Ks": np.diag([5.0, 5.0, 1.0])[None], "width": np.array(8),
            "height": np.array(8)}
    with zipfile.ZipFile(path, "w") as archive:
        for key, value in (base | arrays).items():
            archive.writestr(f"{key}.npy", npy_bytes(value))
    return path


@pytest.mark.parametrize("arrays, message", [
    ({"width": np.array("abc")}, "must hold real numbers"),  # int("abc")
    ({"width": np.array(1 + 2j)}, "must hold real numbers"),  # int(complex)
    ({"width": np.array(np.nan)}, "finite"),  # int(nan)
    ({"height": np.array(np.inf)}, "finite"),  # int(inf)
    ({"width": np.array(1e300)}, "finite numbers"),
    ({"width": np.array([[2**20]])}, "outside 1..65536"),  # shapes () and (1, 1) together broke isfinite
    ({"Ks": np.array([[["a"] * 3] * 3])}, "must hold real numbers"),
    ({"means3d": np.array([["a"] * 3]), "colors": np.zeros((1, 3))}, "must hold real numbers"),
    ({"viewmats": 2 * np.eye(4)[None]}, "not a rotation plus a translation"),  # scaled: not rigid
    ({"viewmats": np.diag([1.0, 1, 1, 0])[None]}, "not a rotation plus a translation"),  # singular
    ({"viewmats": np.diag([1.0, 1, 1, 1e300])[None]}, "not a rotation plus a translation"),
    ({"viewmats": np.eye(4)[None].astype(object)}, "Python objects"),
])
def test_gsplat_npz(tmp_path, arrays, message):
    with pytest.raises(CameraFormatError, match=message):
        load_cameras(_npz(tmp_path / "c.npz", **arrays))


def test_gsplat_npz_with_a_nameless_member(tmp_path):
    path = _npz(tmp_path / "n.npz")
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr(zipfile.ZipInfo(""), b"x")  # ZipInfo.is_dir() raised IndexError on it
    assert len(load_cameras(path)) == 1


def test_gsplat_npz_points_beyond_float32_and_nan_colours_are_repaired(tmp_path):
    points = np.array([[0.0, 0, 0], [1e300, 0, 0], [1.0, 2, 3]])
    colours = np.array([[np.nan, 0.5, 2.0], [0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warning from the float32 cast
        cs = load_cameras(_npz(tmp_path / "p.npz", means3d=points, colors=colours))
    np.testing.assert_array_equal(cs.points, [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_allclose(cs.point_colors, [[0, 0.5, 1], [0.4, 0.5, 0.6]], atol=1e-7)


def _llff_poses(tmp_path: Path, edit) -> Path:
    """Three identity-rotation LLFF poses (40x30, focal 50) after ``edit(pose [3, 5])`` on each."""
    rows = []
    for i in range(3):
        pose = np.zeros((3, 5))
        pose[:, :3] = np.stack([[0, 1, 0], [1, 0, 0], [0, 0, -1]], axis=1)  # down=+y, right=+x, back=-z
        pose[:, 3] = (0.1 * i, 0, 0)
        pose[:, 4] = (30, 40, 50)
        edit(pose)
        rows.append(np.r_[pose.ravel(), 1.0, 10.0])
    (tmp_path / "poses_bounds.npy").write_bytes(npy_bytes(np.array(rows)))
    return tmp_path


def _scale_rotation(pose):
    pose[:, :3] *= 2.0


def _zero_pose(pose):
    pose[:, :4] = 0.0


def _random_rotation(pose):
    pose[:, :3] = np.random.default_rng(0).normal(size=(3, 3))


def _tiny_image(pose):
    pose[:2, 4] = 0.3


@pytest.mark.parametrize("edit, message", [
    (_scale_rotation, "not a rotation plus a translation"),  # accepted before; singular poses crashed later
    (_zero_pose, "not a rotation plus a translation"),  # LinAlgError (singular matrix) before
    (_random_rotation, "not a rotation plus a translation"),  # LinAlgError (eigvalsh did not converge) before
    (_tiny_image, "image size 0x0"),  # rounds to an empty image
])
def test_llff_poses(tmp_path, edit, message):
    with pytest.raises(CameraFormatError, match=message):
        load_cameras(_llff_poses(tmp_path, edit))


def test_llff_header_that_does_not_parse(tmp_path):
    path = _llff_poses(tmp_path, lambda pose: None) / "poses_bounds.npy"
    path.write_bytes(path.read_bytes().replace(b"'shape': (3, 17), }", b"'shape': (3, 17), "))  # TokenError
    with pytest.raises(CameraFormatError, match="cannot read poses_bounds.npy"):
        load_cameras(tmp_path)


def _colmap(folder: Path, cameras_txt: str, images_bin: bytes, points_bin: bytes | None = None) -> Path:
    folder.mkdir(parents=True)
    (folder / "cameras.txt").write_text(cameras_txt)
    (folder / "images.bin").write_bytes(struct.pack("<Q", 1) + images_bin)
    if points_bin is not None:
        (folder / "points3D.bin").write_bytes(points_bin)
    return folder


def _image(name: bytes, camera_id: int = 1) -> bytes:
    return struct.pack("<i7di", 1, 1, 0, 0, 0, 0, 0, 0, camera_id) + name + b"\0" + struct.pack("<Q", 0)


def test_colmap(tmp_path):
    pinhole = "1 PINHOLE 8 8 5 5 4 4\n"
    with pytest.raises(CameraFormatError, match="outside 1..65536"):
        load_cameras(_colmap(tmp_path / "a", "1 PINHOLE 99999999999999999999 8 5 5 4 4\n", _image(b"a.png")))
    with pytest.raises(CameraFormatError) as info:  # the name went into the message raw, newline included
        load_cameras(_colmap(tmp_path / "b", pinhole, _image(b"evil\nname\x1b[2J.png", camera_id=7)))
    assert str(info.value).isprintable() and "refers to missing camera 7" in str(info.value)
    with pytest.raises(CameraFormatError, match=r"\[5.0, 0.0, 4.0, 4.0\]"):  # was [np.float64(5.0), ...]
        load_cameras(_colmap(tmp_path / "c", "1 PINHOLE 8 8 5 0 4 4\n", _image(b"a.png")))
    point = struct.pack("<Q3d3BdQ", 1, 1e300, 0, 0, 1, 2, 3, 0.5, 0)  # finite in float64, inf in float32
    good = struct.pack("<Q3d3BdQ", 2, 1, 2, 3, 1, 2, 3, 0.5, 0)
    cs = load_cameras(_colmap(tmp_path / "d", pinhole, _image(b"a.png"), struct.pack("<Q", 2) + point + good))
    np.testing.assert_array_equal(cs.points, [[1, 2, 3]])
    assert check_camera_source(tmp_path / "d") == "ok"


def _spz_v4(n: int, alphas_frame: bytes | None = None) -> bytes:
    """SPZ v4, SH degree 0, all streams zero; ``alphas_frame`` replaces the compressed alphas stream."""
    sizes = [9 * n, n, 3 * n, 3 * n, 4 * n]
    frames = [zstandard.ZstdCompressor().compress(bytes(size)) for size in sizes]
    if alphas_frame is not None:
        frames[1] = alphas_frame
    head = struct.pack("<IIIBBBBI", 0x5053474E, 4, n, 0, 12, 0, 5, 32) + bytes(12)
    toc = b"".join(struct.pack("<QQ", len(f), size) for f, size in zip(frames, sizes, strict=True))
    return head + toc + b"".join(frames)


def test_spz_v4_frames_that_lie_about_their_size(tmp_path):
    buffer = io.BytesIO()
    writer = zstandard.ZstdCompressor().stream_writer(buffer, size=2**31, closefd=False)
    writer.write(bytes(8))
    writer.flush(zstandard.FLUSH_BLOCK)  # a frame header declaring 2 GiB of content
    cases = {"frame.spz": (_spz_v4(8, buffer.getvalue()), "declares 2,147,483,648 bytes"),
             "points.spz": (_spz_v4(10**7), "claims 10,000,000 points")}  # a zstd bomb: 200 MB from a few KB
    assert len(cases["points.spz"][0]) < 200e6 / 1100
    for name, (data, message) in cases.items():
        (tmp_path / name).write_bytes(data)
        tracemalloc.start()
        try:
            with pytest.raises(SceneFormatError, match=message):
                load_scene(tmp_path / name)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 8 << 20, f"{name}: {peak:,} bytes"
    (tmp_path / "ok.spz").write_bytes(_spz_v4(8))
    assert load_scene(tmp_path / "ok.spz")[0].count == 8


def _ply(header_lines: list[str], body: bytes = b"") -> bytes:
    return ("\n".join(["ply", "format binary_little_endian 1.0", *header_lines, "end_header"]) + "\n").encode() + body


def test_ply_header_messages_are_printable_and_counts_bounded(tmp_path):
    path = tmp_path / "h.ply"
    path.write_bytes(_ply(["element vertex 1\x1b[2J", "property float x"]))
    with pytest.raises(SceneFormatError) as info:
        load_scene(path)
    assert str(info.value).isprintable() and "\\x1b" in str(info.value)
    path.write_bytes(_ply(["element vertex " + "9" * 5000, "property float x"]))
    with pytest.raises(SceneFormatError, match="malformed PLY element line") as info:  # was int()'s ValueError
        load_scene(path)
    assert len(str(info.value)) < 300


def test_ply_doubles_beyond_float32_are_dropped_without_numpy_warnings(tmp_path):
    names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
             "rot_0", "rot_1", "rot_2", "rot_3"]
    rows = np.zeros((2, len(names)))
    rows[:, names.index("rot_0")] = 1.0
    rows[0, 0] = 1e300
    path = tmp_path / "d.ply"
    path.write_bytes(_ply(["element vertex 2", *(f"property double {n}" for n in names)], rows.astype("<f8").tobytes()))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # "overflow encountered in cast" was printed by gstyle info
        scene, report = load_scene(path)
    assert scene.count == 1 and report.dropped == 1


def test_sog_bundle_needing_an_unknown_zip_version(tmp_path):
    """zipfile raised NotImplementedError ("zip file version 14.6") for a central directory entry whose "version
    needed to extract" a mutation had raised past what it knows."""
    save_scene(blob_scene(5), tmp_path / "ok.sog")
    data = bytearray((tmp_path / "ok.sog").read_bytes())
    at = data.find(b"PK\x01\x02")
    struct.pack_into("<H", data, at + 6, 146)
    (tmp_path / "v146.sog").write_bytes(bytes(data))
    with pytest.raises(SceneFormatError, match="not a readable .sog"):
        load_scene(tmp_path / "v146.sog")
    assert load_scene(tmp_path / "ok.sog")[0].count == 5


def test_scene_path_that_is_a_fifo_does_not_block(tmp_path):
    os.mkfifo(tmp_path / "pipe.ply")
    with pytest.raises(SceneFormatError, match="not a regular file"):
        load_scene(tmp_path / "pipe.ply")


def test_valid_sources_still_load(tmp_path):
    save_cameras_json(ring_cameras(3), tmp_path / "cameras.json")
    assert len(load_cameras(tmp_path / "cameras.json")) == 3
    assert load_cameras(_llff_poses(tmp_path, lambda pose: None) / "poses_bounds.npy")[0].width == 40
    assert len(load_cameras(_npz(tmp_path / "ok.npz"))) == 1
