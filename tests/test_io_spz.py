"""SPZ v1-v4 readers, tested with a small test-only encoder (RDF scene -> RUB SPZ) beyond the one sample."""

from __future__ import annotations

import gzip
import struct

import numpy as np
import pytest
import zstandard

from gstyle_core.errors import SceneFormatError
from gstyle_core.io import load_scene
from gstyle_core.scene import GaussianScene, sigmoid

SQRT_HALF = np.sqrt(0.5)
SH_FLIP = np.array([-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1], np.float32)


def random_scene(n: int = 300, degree: int = 2, seed: int = 3) -> GaussianScene:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    k = (degree + 1) ** 2 - 1
    return GaussianScene(
        rng.uniform(-3, 3, (n, 3)).astype(np.float32),
        rng.uniform(-6, 0, (n, 3)).astype(np.float32),
        q,
        rng.uniform(-3, 3, n).astype(np.float32),
        rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32),
        rng.uniform(-0.9, 0.9, (n, k, 3)).astype(np.float32),
    )


def _u8(x: np.ndarray) -> np.ndarray:
    return np.clip(np.round(x), 0, 255).astype(np.uint8)


def encode_streams(scene: GaussianScene, version: int, frac: int = 12) -> list[bytes]:
    """Pack a scene (RDF axes) into the SPZ attribute streams (RUB axes), following the reference packer."""
    flip = np.array([1, -1, -1], np.float32)
    fixed = np.round(scene.means * flip * (1 << frac)).astype(np.int64).reshape(-1)
    positions = np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, (fixed >> 16) & 0xFF], axis=1).astype(np.uint8)
    if version == 1:
        positions = (scene.means * flip).astype("<f2")
    alphas = _u8(sigmoid(scene.opacity_logits) * 255.0)
    colours = _u8(scene.sh_dc * (0.15 * 255.0) + 127.5)
    scales = _u8((scene.log_scales + 10.0) * 16.0)
    w, x, y, z = scene.quats.T
    xyzw = np.stack([x, -y, -z, w], axis=1).astype(np.float64)
    if version < 3:
        xyzw *= np.where(xyzw[:, 3:] < 0, -1.0, 1.0)
        rotations = _u8(xyzw[:, :3] * 127.5 + 127.5)
    else:
        largest = np.abs(xyzw).argmax(axis=1)
        xyzw *= np.where(xyzw[np.arange(len(xyzw)), largest] < 0, -1.0, 1.0)[:, None]
        comp = largest.astype(np.uint64)
        for i in range(4):
            mag = (511 * np.abs(xyzw[:, i]) / SQRT_HALF + 0.5).astype(np.uint64)
            field = ((xyzw[:, i] < 0).astype(np.uint64) << np.uint64(9)) | mag
            comp = np.where(largest == i, comp, (comp << np.uint64(10)) | field)
        rotations = comp.astype("<u4")
    k = scene.sh_rest.shape[1]
    sh = _u8(scene.sh_rest * SH_FLIP[:k, None] * 128.0 + 128.0)
    return [a.tobytes() for a in (positions, alphas, colours, scales, rotations, sh)]


def header(version: int, n: int, degree: int, frac: int = 12, flags: int = 0, last: int = 0) -> bytes:
    return struct.pack("<IIIBBBB", 0x5053474E, version, n, degree, frac, flags, last)


def spz_legacy(scene: GaussianScene, version: int, extension: bytes = b"") -> bytes:
    flags = 2 if extension else 0
    body = header(version, scene.count, scene.sh_degree, flags=flags) + extension
    return gzip.compress(body + b"".join(encode_streams(scene, version)))


def spz_v4(scene: GaussianScene, extension: bytes = b"") -> bytes:
    streams = encode_streams(scene, 4)
    frames = [zstandard.ZstdCompressor().compress(s) for s in streams]
    if not streams[5]:
        frames, streams = frames[:5], streams[:5]
    toc_offset = 32 + len(extension)
    head = header(4, scene.count, scene.sh_degree, flags=2 if extension else 0, last=len(frames))
    head += struct.pack("<I", toc_offset) + bytes(12) + extension
    toc = b"".join(struct.pack("<QQ", len(f), len(s)) for f, s in zip(frames, streams, strict=True))
    return head + toc + b"".join(frames)


def check_close(
    loaded: GaussianScene, scene: GaussianScene, rotation_deg: float, pos_tol: float = 0.5 / 4096
) -> None:
    assert np.abs(loaded.means - scene.means).max() <= pos_tol + 1e-6
    assert np.abs(loaded.log_scales - scene.log_scales).max() <= 0.5 / 16 + 1e-6
    assert np.abs(loaded.sh_dc - scene.sh_dc).max() <= 0.5 / (0.15 * 255) + 1e-5
    assert np.abs(loaded.opacities - sigmoid(scene.opacity_logits)).max() <= 0.5 / 255 + 1e-5
    if scene.sh_rest.size:
        assert np.abs(loaded.sh_rest - scene.sh_rest).max() <= 0.5 / 128 + 1e-6
    dots = np.clip(np.abs((loaded.quats * scene.quats).sum(axis=1)).astype(np.float64), 0, 1)
    angles = np.degrees(2 * np.arccos(dots))
    assert angles.max() < rotation_deg and np.median(angles) < 1.0


@pytest.mark.parametrize(
    "version, degree, rotation_deg", [(2, 1, 15.0), (3, 2, 0.5), (3, 3, 0.5), (2, 0, 15.0)]
)
def test_gzip_spz_decodes_within_quantisation(tmp_path, version, degree, rotation_deg):
    scene = random_scene(degree=degree)
    (tmp_path / "s.spz").write_bytes(spz_legacy(scene, version))
    loaded, report = load_scene(tmp_path / "s.spz")
    assert report.format == f"spz-v{version}" and loaded.count == scene.count and loaded.sh_degree == degree
    check_close(loaded, scene, rotation_deg)


def test_v1_float16_positions(tmp_path):
    scene = random_scene(degree=1)
    (tmp_path / "s.spz").write_bytes(spz_legacy(scene, 1))
    loaded, report = load_scene(tmp_path / "s.spz")
    assert report.format == "spz-v1"
    check_close(loaded, scene, 15.0, pos_tol=2e-3)  # float16 keeps 11 significant bits


@pytest.mark.parametrize("degree", [0, 3])
def test_v4_zstd_streams_decode_within_quantisation(tmp_path, degree):
    scene = random_scene(degree=degree)
    (tmp_path / "s.spz").write_bytes(spz_v4(scene))
    loaded, report = load_scene(tmp_path / "s.spz")
    assert report.format == "spz-v4" and report.warnings == []
    check_close(loaded, scene, 0.5)


def test_rub_to_rdf_conversion_of_a_known_gaussian(tmp_path):
    # Stored (RUB): position (1, 2, 3), rotation 90 degrees about +y: xyzw = (0, s, 0, s).
    s = 0.70710678
    scene = GaussianScene(
        np.array([[1, -2, -3]], np.float32),
        np.zeros((1, 3), np.float32),
        np.array([[s, 0, -s, 0]], np.float32),
        np.zeros(1, np.float32),
        np.zeros((1, 3), np.float32),
        np.zeros((1, 3, 3), np.float32),
    )
    (tmp_path / "s.spz").write_bytes(spz_legacy(scene, 3))
    raw = gzip.decompress((tmp_path / "s.spz").read_bytes())
    fixed = np.frombuffer(raw[16:25], np.uint8).astype(int)
    assert fixed[3] | (fixed[4] << 8) == 2 * 4096  # y stored as +2 (up), i.e. flipped from RDF's -2
    loaded, _ = load_scene(tmp_path / "s.spz")
    assert np.allclose(loaded.means, [[1, -2, -3]], atol=1e-3)
    assert np.allclose(np.abs(loaded.quats), [[s, 0, s, 0]], atol=2e-3)


def test_extensions_are_skipped_with_a_warning(tmp_path):
    scene = random_scene(n=20, degree=1)
    ext = struct.pack("<IIfff", 2, 0, -0.5, 1.2, 0.3)
    (tmp_path / "a.spz").write_bytes(spz_legacy(scene, 3, extension=ext))
    (tmp_path / "b.spz").write_bytes(spz_v4(scene, extension=ext))
    for name in ("a.spz", "b.spz"):
        loaded, report = load_scene(tmp_path / name)
        assert any("20 bytes of SPZ extensions" in w for w in report.warnings)
        check_close(loaded, scene, 0.5)


def expect_error(tmp_path, data: bytes, *fragments: str) -> None:
    (tmp_path / "bad.spz").write_bytes(data)
    with pytest.raises(SceneFormatError) as info:
        load_scene(tmp_path / "bad.spz")
    assert "\n" not in str(info.value) and "bad.spz" in str(info.value)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


def test_spz_errors(tmp_path):
    scene = random_scene(n=50)
    good = spz_legacy(scene, 3)
    expect_error(tmp_path, good[: len(good) // 2], "gzip")  # cut in the middle of the deflate stream
    corrupt = bytearray(good)
    corrupt[40:60] = bytes(20)
    expect_error(tmp_path, bytes(corrupt), "gzip")
    raw = gzip.decompress(good)
    expect_error(tmp_path, gzip.compress(raw[:-30]), "truncated")
    expect_error(tmp_path, gzip.compress(b"NOPE" + raw[4:]), "gzip data is not an SPZ")
    expect_error(tmp_path, gzip.compress(raw[:4] + struct.pack("<I", 9) + raw[8:]), "version 9")
    expect_error(
        tmp_path, gzip.compress(raw[:8] + struct.pack("<I", 10**9) + raw[12:]), "1,000,000,000 points"
    )
    expect_error(tmp_path, gzip.compress(raw[:8] + struct.pack("<I", 10**7) + raw[12:]), "10,000,000 points")
    expect_error(tmp_path, gzip.compress(raw[:8] + struct.pack("<I", 51) + raw[12:]), "truncated")
    expect_error(tmp_path, gzip.compress(raw[:12] + bytes([7]) + raw[13:]), "SH degree 7")


def test_spz_v4_errors(tmp_path):
    scene = random_scene(n=50, degree=0)
    good = spz_v4(scene)
    expect_error(tmp_path, good[:-10], "truncated")
    expect_error(tmp_path, good[:20], "truncated")
    toc_entry = struct.unpack_from("<QQ", good, 32)
    lying = good[:32] + struct.pack("<QQ", toc_entry[0], toc_entry[1] + 3) + good[48:]
    expect_error(tmp_path, lying, "positions stream")
    broken = bytearray(good)
    broken[32 + 16 * 5 + 4 : 32 + 16 * 5 + 12] = b"\xff" * 8
    expect_error(tmp_path, bytes(broken), "zstd")
    wrong_count = good[:15] + bytes([3]) + good[16:]
    expect_error(tmp_path, wrong_count, "3 streams")
