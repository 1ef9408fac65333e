"""3DGS and PlayCanvas-compressed PLY: encodings, round trips, malformed headers and data, atomic saves."""

from __future__ import annotations

import os

import numpy as np
import pytest

import gstyle_core.io.ply_3dgs as ply_3dgs
from gstyle_core.errors import SceneFormatError
from gstyle_core.io import load_scene, save_scene
from gstyle_core.scene import GaussianScene

BASE = [
    "x",
    "y",
    "z",
    "f_dc_0",
    "f_dc_1",
    "f_dc_2",
    "opacity",
    "scale_0",
    "scale_1",
    "scale_2",
    "rot_0",
    "rot_1",
    "rot_2",
    "rot_3",
]
NP_TO_PLY = {"f4": "float", "f8": "double", "u1": "uchar", "i4": "int", "u4": "uint", "i2": "short"}


def random_scene(n: int = 50, degree: int = 3, seed: int = 0) -> GaussianScene:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    k = (degree + 1) ** 2 - 1
    return GaussianScene(
        rng.normal(size=(n, 3)).astype(np.float32),
        rng.uniform(-6, 0, (n, 3)).astype(np.float32),
        q,
        rng.normal(size=n).astype(np.float32),
        rng.normal(size=(n, 3)).astype(np.float32),
        rng.normal(scale=0.3, size=(n, k, 3)).astype(np.float32),
    )


def ply_bytes(
    columns: dict[str, np.ndarray],
    fmt: str = "binary_little_endian",
    count: int | None = None,
    extra_elements: str = "",
) -> bytes:
    """A PLY file with one vertex element holding ``columns`` (1-D arrays, their dtypes kept)."""
    n = len(next(iter(columns.values())))
    header = ["ply", f"format {fmt} 1.0", f"element vertex {n if count is None else count}"]
    header += [f"property {NP_TO_PLY[a.dtype.str[1:]]} {name}" for name, a in columns.items()]
    header += [extra_elements] if extra_elements else []
    header.append("end_header")
    head = ("\n".join(header) + "\n").encode()
    if fmt == "ascii":
        rows = np.stack([a.astype(np.float64) for a in columns.values()], axis=1)
        return (
            head
            + "".join(
                " ".join(
                    repr(float(v)) if a.dtype.kind == "f" else str(int(v))
                    for v, a in zip(r, columns.values(), strict=True)
                )
                + "\n"
                for r in rows
            ).encode()
        )
    endian = "<" if fmt == "binary_little_endian" else ">"
    table = np.empty(n, [(name, endian + a.dtype.str[1:]) for name, a in columns.items()])
    for name, a in columns.items():
        table[name] = a
    return head + table.tobytes()


def scene_columns(scene: GaussianScene, dtype: str = "f4") -> dict[str, np.ndarray]:
    n, k = scene.count, scene.sh_rest.shape[1]
    cols = {"x": scene.means[:, 0], "y": scene.means[:, 1], "z": scene.means[:, 2]}
    cols |= {"nx": np.zeros(n, np.float32)}  # an extra property to be ignored
    cols |= {f"f_dc_{i}": scene.sh_dc[:, i] for i in range(3)}
    rest = scene.sh_rest.transpose(0, 2, 1).reshape(n, 3 * k)
    cols |= {f"f_rest_{i}": rest[:, i] for i in range(3 * k)}
    cols |= {"opacity": scene.opacity_logits}
    cols |= {f"scale_{i}": scene.log_scales[:, i] for i in range(3)}
    cols |= {f"rot_{i}": scene.quats[:, i] for i in range(4)}
    return {name: np.ascontiguousarray(a).astype(dtype) for name, a in cols.items()}


def assert_same(a: GaussianScene, b: GaussianScene) -> None:
    for field in ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_ply_round_trip_is_bit_exact(tmp_path, degree):
    scene = random_scene(degree=degree)
    save_scene(scene, tmp_path / "s.ply")
    loaded, report = load_scene(tmp_path / "s.ply")
    assert report.repairs == [] and report.sh_degree == degree
    assert_same(scene, loaded)


def test_sh0_and_keep_sh_false_write_45_zero_f_rest(tmp_path):
    for scene, keep in ((random_scene(degree=0), True), (random_scene(degree=3), False)):
        save_scene(scene, tmp_path / "s.ply", keep_sh=keep)
        data = (tmp_path / "s.ply").read_bytes()
        header = data[: data.index(b"end_header")].decode()
        assert header.count("property float f_rest_") == 45 and "f_rest_44" in header
        loaded, _ = load_scene(tmp_path / "s.ply")
        assert loaded.sh_degree == 0  # all-zero f_rest loads as degree 0
        _, report = load_scene(tmp_path / "s.ply")
        assert any("all 45 f_rest values are zero" in w for w in report.warnings)
        assert np.array_equal(loaded.sh_dc, scene.sh_dc)


def test_f_rest_is_channel_major_in_the_file(tmp_path):
    scene = random_scene(n=4, degree=1)
    save_scene(scene, tmp_path / "s.ply")
    data = (tmp_path / "s.ply").read_bytes()
    body = np.frombuffer(data[data.index(b"end_header\n") + 11 :], "<f4").reshape(4, -1)
    assert np.array_equal(body[:, 9:12], scene.sh_rest[:, :, 0])  # f_rest_0..2 = red coefficients


@pytest.mark.parametrize("fmt", ["ascii", "binary_big_endian", "binary_little_endian"])
@pytest.mark.parametrize("dtype", ["f4", "f8"])
def test_other_encodings_and_double_properties(tmp_path, fmt, dtype):
    scene = random_scene(n=20, degree=2)
    (tmp_path / "s.ply").write_bytes(ply_bytes(scene_columns(scene, dtype), fmt))
    loaded, report = load_scene(tmp_path / "s.ply")
    assert fmt in report.format and loaded.count == 20 and loaded.sh_degree == 2
    assert np.allclose(loaded.sh_rest, scene.sh_rest, atol=1e-6)
    assert np.allclose(loaded.means, scene.means, atol=1e-6)


def write(tmp_path, data: bytes, name: str = "bad.ply"):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def expect_error(path, *fragments: str) -> str:
    with pytest.raises(SceneFormatError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and path.name in message
    for fragment in fragments:
        assert fragment in message, message
    return message


def test_truncated_body(tmp_path):
    data = ply_bytes(scene_columns(random_scene(n=10)))
    expect_error(write(tmp_path, data[:-7]), "truncated")


@pytest.mark.parametrize("count", [11, 10**6, 10**12])
def test_header_lying_about_count_fails_fast(tmp_path, count):
    data = ply_bytes(scene_columns(random_scene(n=10)), count=count)
    expect_error(write(tmp_path, data), "truncated", f"{count * 60 * 4:,}")


def test_ascii_lying_count(tmp_path):
    expect_error(
        write(tmp_path, ply_bytes(scene_columns(random_scene(n=5)), "ascii", count=10**12)), "truncated"
    )
    expect_error(write(tmp_path, ply_bytes(scene_columns(random_scene(n=5)), "ascii", count=6)), "truncated")


@pytest.mark.parametrize(
    "mutate, fragment",
    [
        (lambda d: d.replace(b"end_header", b"end_headr"), "end_header"),
        (lambda d: d.replace(b"binary_little_endian", b"binary_middle_endian"), "format"),
        (lambda d: d.replace(b"element vertex 10", b"element vertex ten"), "element"),
        (lambda d: d.replace(b"property float x", b"property quad x"), "property"),
        (lambda d: d.replace(b"ply\n", b"ply\nbogus line\n", 1), "unexpected"),
        (lambda d: b"ply\n" + bytes([0xFF]) * 40 + b"\nend_header\n", "ASCII"),
    ],
)
def test_malformed_headers(tmp_path, mutate, fragment):
    data = ply_bytes(scene_columns(random_scene(n=10)))
    expect_error(write(tmp_path, mutate(data)), fragment)


def test_flipped_endianness_header_gives_repairs_not_crashes(tmp_path):
    data = ply_bytes(scene_columns(random_scene(n=10)))
    flipped = data.replace(b"binary_little_endian", b"binary_big_endian")
    try:
        scene, report = load_scene(write(tmp_path, flipped))
    except SceneFormatError as exc:
        assert "\n" not in str(exc)
    else:  # byte-swapped floats are garbage: validation must have kept the result finite and bounded
        assert np.isfinite(scene.means).all() and report.count_in_file == 10


def test_missing_properties_and_wrong_types(tmp_path):
    cols = scene_columns(random_scene(n=5))
    del cols["opacity"], cols["rot_3"]
    expect_error(write(tmp_path, ply_bytes(cols)), "missing", "opacity", "rot_3")
    cols = scene_columns(random_scene(n=5))
    cols["x"] = cols["x"].astype(np.int32)
    expect_error(write(tmp_path, ply_bytes(cols)), "float or double", "x (i4)")
    cols = scene_columns(random_scene(n=5, degree=1))
    del cols["f_rest_8"]
    expect_error(write(tmp_path, ply_bytes(cols)), "8 f_rest")
    point_cloud = {"x": np.zeros(3, np.float32), "red": np.zeros(3, np.uint8)}
    expect_error(write(tmp_path, ply_bytes(point_cloud)), "missing")


def test_list_properties_before_vertices_are_rejected(tmp_path):
    data = b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int idx\nend_header\n3 0 1 2\n"
    expect_error(write(tmp_path, data), "no 'vertex' element")
    cols = scene_columns(random_scene(n=3))
    data = ply_bytes(cols).replace(
        b"element vertex", b"element face 1\nproperty list uchar int idx\nelement vertex"
    )
    expect_error(write(tmp_path, data), "list properties")


def test_nan_inf_and_bad_values_are_repaired_and_reported(tmp_path):
    scene = random_scene(n=10, degree=1)
    scene.means[0, 1] = np.nan
    scene.quats[1, 2] = np.inf
    scene.log_scales[2, 0] = -np.inf
    scene.sh_dc[3, 0] = np.nan
    scene.sh_rest[4, 1, 2] = np.inf
    scene.opacity_logits[5] = np.nan
    scene.opacity_logits[6] = np.inf
    scene.log_scales[7] = (-30.0, 0.0, 20.0)
    scene.quats[8] = 0.0
    scene.quats[9] *= 3.0
    loaded, report = load_scene(write(tmp_path, ply_bytes(scene_columns(scene))))
    text = "\n".join(report.repairs)
    assert report.dropped == 3 and loaded.count == 7 and report.count_in_file == 10
    assert "dropped 3 Gaussians" in text
    assert "NaN/inf colour/SH coefficients to 0 in 2 Gaussians" in text
    assert "1 NaN opacities" in text and "clamped 1 opacity logits" in text
    assert "clamped scales of 1 Gaussians" in text
    assert "1 zero quaternions" in text and "renormalised 1 quaternions" in text
    for field in ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest"):
        assert np.isfinite(getattr(loaded, field)).all()
    assert np.allclose(np.linalg.norm(loaded.quats, axis=1), 1.0, atol=1e-6)
    assert loaded.log_scales.min() >= np.log(1e-7) - 1e-5 and loaded.log_scales.max() <= np.log(1e4) + 1e-5
    assert np.abs(loaded.opacity_logits).max() <= 40.0
    assert "repair:" in report.summary()


def test_failing_save_leaves_no_file_and_no_temp_file(tmp_path, monkeypatch):
    def explode(scene, keep_sh):
        raise OSError("disk full")

    monkeypatch.setattr(ply_3dgs, "encode_3dgs_body", explode)
    with pytest.raises(OSError):
        save_scene(random_scene(), tmp_path / "out.ply")
    assert os.listdir(tmp_path) == []
    (tmp_path / "keep.ply").write_bytes(b"old")
    with pytest.raises(OSError):
        save_scene(random_scene(), tmp_path / "keep.ply")
    assert os.listdir(tmp_path) == ["keep.ply"] and (tmp_path / "keep.ply").read_bytes() == b"old"


def test_save_rejects_unknown_format_and_bad_shapes(tmp_path):
    with pytest.raises(SceneFormatError, match="unknown output format"):
        save_scene(random_scene(), tmp_path / "s.obj")
    bad = random_scene()
    bad.quats = bad.quats[:, :3]
    with pytest.raises(SceneFormatError, match="quats"):
        save_scene(bad, tmp_path / "s.ply")
    assert os.listdir(tmp_path) == []
    save_scene(random_scene(), tmp_path / "s.anything", fmt="ply")
    assert load_scene(tmp_path / "s.anything")[0].count == 50


# --- PlayCanvas compressed PLY ---


def compressed_ply(
    n: int, chunks: int | None = None, colour: bool = True, vertex_type: str = "uint"
) -> bytes:
    """A compressed PLY whose packed values are known: every vertex at the middle of its chunk's box."""
    chunk_props = [
        "min_x",
        "min_y",
        "min_z",
        "max_x",
        "max_y",
        "max_z",
        "min_scale_x",
        "min_scale_y",
        "min_scale_z",
        "max_scale_x",
        "max_scale_y",
        "max_scale_z",
    ]
    chunk_props += ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"] if colour else []
    n_chunks = -(-n // 256) if chunks is None else chunks
    lines = ["ply", "format binary_little_endian 1.0", f"element chunk {n_chunks}"]
    lines += [f"property float {p}" for p in chunk_props]
    lines += [f"element vertex {n}"]
    lines += [
        f"property {vertex_type} {p}"
        for p in ("packed_position", "packed_rotation", "packed_scale", "packed_color")
    ]
    lines.append("end_header")
    chunk_row = [0, 0, 0, 2, 4, 6, -4, -4, -4, -2, -2, -2] + ([0, 0, 0, 1, 1, 1] if colour else [])
    chunk_data = np.tile(np.array(chunk_row, "<f4"), n_chunks)
    position = (2047 << 21) | (0 << 11) | 1023  # x at max, y at min, z ~ middle
    rotation = (0 << 30) | (512 << 20) | (512 << 10) | 512  # largest = w, others ~ 0
    scale = (0 << 21) | (1023 << 11) | 0
    colour_word = (255 << 24) | (0 << 16) | (128 << 8) | 255
    vertex = np.tile(np.array([position, rotation, scale, colour_word], "<u4"), n)
    return ("\n".join(lines) + "\n").encode() + chunk_data.tobytes() + vertex.tobytes()


def test_compressed_ply_decoding_rules(tmp_path):
    scene, report = load_scene(write(tmp_path, compressed_ply(300)))
    assert report.format == "ply-playcanvas-compressed" and scene.count == 300
    assert np.allclose(scene.means[0], (2.0, 0.0, 6.0 * 1023 / 2047), atol=1e-6)
    assert np.allclose(scene.log_scales[0], (-4.0, -2.0, -4.0), atol=1e-6)
    assert np.allclose(scene.quats[0], (1.0, 0.0, 0.0, 0.0), atol=2e-3)
    assert np.allclose(scene.rgb[0], (1.0, 0.0, 128 / 255), atol=1e-5)
    assert scene.opacity_logits[0] == pytest.approx(40.0)


def test_compressed_ply_errors(tmp_path):
    expect_error(write(tmp_path, compressed_ply(300, chunks=1)), "1 chunks for 300 vertices")
    expect_error(write(tmp_path, compressed_ply(300, vertex_type="float")), "wrong property types")
    expect_error(write(tmp_path, compressed_ply(300)[:-5]), "truncated")
    scene, _ = load_scene(write(tmp_path, compressed_ply(10, colour=False)))
    assert np.allclose(scene.rgb[0], (1.0, 0.0, 128 / 255), atol=1e-5)
