"""Hostile inputs, fuzzed: every scene reader, every camera reader and the style-image loader.

Property (see ``tests/fuzzcases``): a mutated file either loads into a valid result (finite arrays of
consistent shapes, usable cameras, an RGB image in [0, 1]) or raises the reader's ``GStyleError`` subclass
with one printable line; never another exception, never a hang (hypothesis deadline), and allocations stay
under ``MEMORY_LIMIT`` (tracemalloc peak). Example counts come from the hypothesis profile selected by
``GSTYLE_FUZZ_PROFILE`` (``tests/conftest.py``).
"""

from __future__ import annotations

import gzip
import io
import os
import random
import re
import shutil
import struct
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gstyle_core.cameras import load_cameras
from gstyle_core.cli import run
from gstyle_core.errors import CameraFormatError, SceneFormatError
from gstyle_core.io import load_scene
from tests.fuzzcases import (
    CAMERA_FORMATS,
    IMAGE_FORMATS,
    SCENE_FORMATS,
    RandomDraw,
    check_camera_source,
    check_scene_file,
    check_style_image,
    run_bounded,
    scene_case,
    valid_image,
    valid_scene_file,
    write_camera_case,
    write_image_case,
    write_valid_cameras,
)
from tests.fuzzcases.cameras import npy_bytes, npy_with_shape
from tests.fuzzcases.sog import write_sog_folder_case

FUZZ = settings.get_profile(os.environ.get("GSTYLE_FUZZ_PROFILE", "ci"))
LYING_LIMIT = 8 << 20  # a lying header must fail before allocating what it claims


class HypothesisDraw:
    """The fuzz cases' ``Draw`` on top of hypothesis, so failing cases shrink."""

    def __init__(self, data: st.DataObject) -> None:
        self.data = data

    def integer(self, lo: int, hi: int) -> int:
        return self.data.draw(st.integers(lo, hi))

    def choice(self, options):
        return self.data.draw(st.sampled_from(options))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


# --- the generators start from valid files -----------------------------------------------------------


@pytest.mark.parametrize("fmt", SCENE_FORMATS)
def test_unmutated_scene_files_load(tmp_path, fmt):
    sample = valid_scene_file(fmt, RandomDraw(random.Random(fmt)))
    path = tmp_path / f"valid{sample.suffix}"
    path.write_bytes(sample.pack(sample.payload))
    scene, report = load_scene(path)
    assert scene.count == sample.count and report.dropped == 0 and check_scene_file(path) == "ok"


@pytest.mark.parametrize("fmt", CAMERA_FORMATS)
def test_unmutated_camera_sources_load(tmp_path, fmt):
    target = write_valid_cameras(fmt, RandomDraw(random.Random(fmt)), tmp_path)
    assert check_camera_source(target) == "ok"


@pytest.mark.parametrize("fmt", IMAGE_FORMATS)
def test_unmutated_images_load(tmp_path, fmt):
    path = tmp_path / f"valid.{fmt}"
    path.write_bytes(valid_image(fmt, RandomDraw(random.Random(fmt))))
    assert check_style_image(path) == "ok"


# --- the properties ----------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", SCENE_FORMATS)
@FUZZ
@given(data=st.data())
def test_scene_readers_survive_mutations(workdir, fmt, data):
    raw, suffix = scene_case(fmt, HypothesisDraw(data))
    path = workdir / f"{fmt}{suffix}"
    path.write_bytes(raw)
    try:
        run_bounded(check_scene_file, path)
    finally:
        path.unlink()


@FUZZ
@given(data=st.data())
def test_sog_folder_survives_meta_json_mutations(workdir, data):
    folder = Path(tempfile.mkdtemp(dir=workdir))
    try:
        run_bounded(check_scene_file, write_sog_folder_case(HypothesisDraw(data), folder))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("fmt", CAMERA_FORMATS)
@FUZZ
@given(data=st.data())
def test_camera_readers_survive_mutations(workdir, fmt, data):
    folder = Path(tempfile.mkdtemp(dir=workdir))
    try:
        run_bounded(check_camera_source, write_camera_case(fmt, HypothesisDraw(data), folder))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("fmt", IMAGE_FORMATS)
@FUZZ
@given(data=st.data())
def test_style_image_loader_survives_mutations(workdir, fmt, data):
    path = write_image_case(fmt, HypothesisDraw(data), workdir / f"style-{fmt}")
    try:
        run_bounded(check_style_image, path)
    finally:
        path.unlink()


# --- headers that lie about sizes fail before allocating ---------------------------------------------


def _ply_claiming(count: int, fmt: str = "binary_little_endian") -> bytes:
    props = "".join(f"property float {p}\n" for p in ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                                                     "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2",
                                                     "rot_3"))
    return f"ply\nformat {fmt} 1.0\nelement vertex {count}\n{props}end_header\n".encode() + bytes(560)


def _spz_claiming(count: int) -> bytes:
    return gzip.compress(struct.pack("<IIIBBBB", 0x5053474E, 3, count, 0, 12, 0, 0) + bytes(200))


def _spz_v4_claiming(size: int) -> bytes:
    head = struct.pack("<IIIBBBBI", 0x5053474E, 4, 10, 0, 12, 0, 5, 32) + bytes(12)
    return head + struct.pack("<10Q", size, 90, *([size, 10] * 4)) + bytes(64)


def _compressed_claiming(vertices: int) -> bytes:
    """A valid PlayCanvas compressed PLY whose vertex, chunk and sh counts all claim ``vertices``."""
    sample = valid_scene_file("ply-compressed", RandomDraw(random.Random(2)))
    data = re.sub(rb"element (vertex|sh) \d+", rb"element \1 %d" % vertices, sample.payload)
    return re.sub(rb"element chunk \d+", b"element chunk %d" % -(-vertices // 256), data)


def _sog_claiming(count: int | None = None, member_size: int | None = None) -> bytes:
    """A valid small .sog whose meta.json claims ``count`` Gaussians, or whose last ZIP member claims to unpack to
    ``member_size`` bytes (central directory only: what a reader sees first)."""
    sample = valid_scene_file("sog-bundle", RandomDraw(random.Random(3)))
    with zipfile.ZipFile(io.BytesIO(sample.payload)) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    if count is not None:
        members["meta.json"] = re.sub(rb'"count":\d+', b'"count":%d' % count, members["meta.json"])
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    data = bytearray(buffer.getvalue())
    if member_size is not None:
        at = data.rfind(b"PK\x01\x02")
        data[at + 24 : at + 28] = struct.pack("<I", member_size)
    return bytes(data)


LYING_SCENES = {
    "ply-10^12-vertices": _ply_claiming(10**12),
    "ply-10^7-vertices": _ply_claiming(10**7),
    "ply-ascii-10^9-vertices": _ply_claiming(10**9, "ascii"),
    "compressed-ply-2^40-vertices": _compressed_claiming(2**40),
    "compressed-ply-10^6-vertices": _compressed_claiming(10**6),
    "spz-10^7-points": _spz_claiming(10**7),
    "spz-2^32-1-points": _spz_claiming(2**32 - 1),
    "spz-v4-2^63-byte-stream": _spz_v4_claiming(2**63),
    "sog-2^40-gaussians": _sog_claiming(count=2**40),
    "sog-10^7-gaussians": _sog_claiming(count=10**7),
    "sog-member-of-4-GiB": _sog_claiming(member_size=2**32 - 1),
}


@pytest.mark.parametrize("name", sorted(LYING_SCENES))
def test_lying_scene_headers_fail_fast(tmp_path, name):
    path = tmp_path / "lie.bin"
    path.write_bytes(LYING_SCENES[name])
    assert run_bounded(check_scene_file, path, LYING_LIMIT)[0] == "error"


def _npy(array: np.ndarray, shape: str | None = None) -> bytes:
    return npy_with_shape(npy_bytes(array), shape) if shape else npy_bytes(array)


def _colmap_with(folder: Path, images_bin: bytes, points_bin: bytes | None = None) -> Path:
    folder.mkdir(parents=True)
    cameras = struct.pack("<Q", 1) + struct.pack("<iiQQ", 1, 1, 8, 8) + struct.pack("<4d", 5, 5, 4, 4)
    (folder / "cameras.bin").write_bytes(cameras)
    (folder / "images.bin").write_bytes(images_bin)
    if points_bin is not None:
        (folder / "points3D.bin").write_bytes(points_bin)
    return folder


def _image_record(name: bytes, camera_id: int = 1, points2d: int = 0) -> bytes:
    return struct.pack("<i7di", 1, 1, 0, 0, 0, 0, 0, 0, camera_id) + name + b"\0" + struct.pack("<Q", points2d)


def test_lying_camera_headers_fail_fast(tmp_path):
    rows = np.tile(np.r_[0, 1, 0, 0, 1, 0, 0, 0, -1, 0, 0, 0, 8, 8, 5, 1, 10.0], (2, 1))
    (tmp_path / "llff").mkdir()
    (tmp_path / "llff" / "poses_bounds.npy").write_bytes(_npy(rows, "(10000000, 17)"))
    npz = tmp_path / "lie.npz"
    with zipfile.ZipFile(npz, "w") as archive:
        archive.writestr("viewmats.npy", _npy(np.eye(4)[None], "(100000000, 4, 4)"))
        for key, value in (("Ks", np.diag([5.0, 5, 1])[None]), ("width", np.array(8)), ("height", np.array(8))):
            archive.writestr(f"{key}.npy", _npy(value))
    points = struct.pack("<Q", 2**40) + bytes(43)
    sources = [tmp_path / "llff", npz,
               _colmap_with(tmp_path / "n2d", struct.pack("<Q", 1) + _image_record(b"a.png", points2d=10**8)),
               _colmap_with(tmp_path / "pts", struct.pack("<Q", 1) + _image_record(b"a.png"), points)]
    for source in sources:
        assert run_bounded(check_camera_source, source, LYING_LIMIT)[0] == "error", source


# --- paths that are not files ------------------------------------------------------------------------


def test_empty_missing_directory_and_device_paths(tmp_path):
    (tmp_path / "empty.ply").write_bytes(b"")
    (tmp_path / "folder.ply").mkdir()
    fifo = tmp_path / "pipe.ply"
    os.mkfifo(fifo)  # reading it would block forever
    for name in ("empty.ply", "folder.ply", "missing.ply", "pipe.ply"):
        assert check_scene_file(tmp_path / name) == "error", name
    (tmp_path / "cams").mkdir()
    (tmp_path / "cams" / "cameras.json").write_bytes(b"")
    (tmp_path / "cams" / "poses_bounds.npy").mkdir()
    for target in ("cams", "cams/cameras.json", "missing.json", "pipe.ply"):
        assert check_camera_source(tmp_path / target) == "error", target


# --- the command line --------------------------------------------------------------------------------

CLI_CASES = {
    "lying.ply": _ply_claiming(10**12),
    "truncated.ply": _ply_claiming(10)[:-100],
    "control-chars.ply": b"ply\nformat binary_little_endian 1.0\nelement vertex 1\x1b[2J\nend_header\n",
    "bad.splat": bytes(33),
    "corrupt.spz": _spz_claiming(5)[:12] + b"\xff" * 40,
    "empty.ply": b"",
    "random.bin": random.Random(1).randbytes(500),
    "corrupt.sog": b"PK\x03\x04" + random.Random(2).randbytes(300),
    "meta.json": b'{"version": 2, "count": 5}',
}


@pytest.mark.parametrize("name", sorted(CLI_CASES) + ["a-directory"])
def test_gstyle_info_on_corrupt_files_prints_one_line_and_exits_2(tmp_path, capsys, name):
    path = tmp_path / name
    if name == "a-directory":
        path.mkdir()
    else:
        path.write_bytes(CLI_CASES[name])
    assert run(["info", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.endswith("\n") and err.count("\n") == 1, err
    assert err.startswith("gstyle info: error:") and err[:-1].isprintable(), err


def test_errors_are_the_reader_specific_subclass(tmp_path):
    (tmp_path / "x.ply").write_bytes(_ply_claiming(10**12))
    with pytest.raises(SceneFormatError):
        load_scene(tmp_path / "x.ply")
    (tmp_path / "cameras.json").write_text("[" * 100_000)
    with pytest.raises(CameraFormatError, match="nested too deeply"):
        load_cameras(tmp_path / "cameras.json")
