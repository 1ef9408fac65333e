"""Writers for the web formats (.spz, PlayCanvas .compressed.ply): round trips through our own readers within the
formats' quantisation steps, SH bands only when used, the CLI, and (when installed) PlayCanvas's splat-transform."""

from __future__ import annotations

import gzip
import struct
import subprocess

import numpy as np
import pytest

from gstyle_core.cli import run
from gstyle_core.errors import SceneFormatError
from gstyle_core.io import load_scene, save_scene
from gstyle_core.io.ply_compressed import CHUNK
from gstyle_core.io.ply_compressed_write import morton_order
from gstyle_core.io.spz_write import encode_spz, fractional_bits
from gstyle_core.scene import GaussianScene, sigmoid, used_sh_degree
from tests.splat_transform_cli import SKIP_REASON, splat_transform

SPZ_SMALL_STEP = np.sqrt(0.5) / 511  # v3: one step of the three smaller quaternion components
CPLY_ROT_STEP = np.sqrt(2.0) / 1023  # compressed PLY: one step of the three smaller components


def random_scene(n: int = 700, degree: int = 3, seed: int = 5, extent: float = 3.0) -> GaussianScene:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    k = (degree + 1) ** 2 - 1
    return GaussianScene(
        rng.uniform(-extent, extent, (n, 3)).astype(np.float32),
        rng.uniform(-6, 0, (n, 3)).astype(np.float32),
        q,
        rng.uniform(-4, 4, n).astype(np.float32),
        rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32),
        rng.uniform(-0.9, 0.9, (n, k, 3)).astype(np.float32),
    )


def aligned(loaded: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``loaded`` quaternions with the sign that matches ``reference`` (q and -q are the same rotation)."""
    q = reference / np.linalg.norm(reference, axis=1, keepdims=True)
    return np.where((loaded * q).sum(axis=1, keepdims=True) < 0, -loaded, loaded), q


def f32_slack(values: np.ndarray) -> float:
    """Half a float32 ulp of the largest magnitude (what storing a decoded float64 as float32 adds)."""
    return float(np.spacing(np.float32(np.abs(values).max())))


# ---------------------------------------------------------------------------------------------------- .spz
@pytest.mark.parametrize("version", [2, 3])
def test_spz_round_trip_within_quantisation(tmp_path, version):
    scene = random_scene()
    save_scene(scene, tmp_path / "s.spz") if version == 3 else (tmp_path / "s.spz").write_bytes(
        encode_spz(scene, version=2))
    loaded, report = load_scene(tmp_path / "s.spz")
    assert report.format == f"spz-v{version}" and loaded.count == scene.count and loaded.sh_degree == 3
    frac = fractional_bits(scene.means)
    assert frac == 21  # |x| <= 3 leaves 21 fractional bits of 23
    assert np.abs(loaded.means - scene.means).max() <= 0.5 / (1 << frac) + f32_slack(scene.means)
    assert np.abs(loaded.log_scales - scene.log_scales).max() <= 0.5 / 16 + 1e-6
    assert np.abs(loaded.sh_dc - scene.sh_dc).max() <= 0.5 / (0.15 * 255) + 1e-5
    assert np.abs(loaded.opacities - sigmoid(scene.opacity_logits)).max() <= 0.5 / 255 + 1e-6
    assert np.abs(loaded.sh_rest - scene.sh_rest).max() <= 0.5 / 128 + 1e-6
    q_loaded, q = aligned(loaded.quats, scene.quats)
    if version == 3:  # three components within half a step; the largest, rebuilt, within 3x that (it is >= 1/2)
        assert np.abs(q_loaded - q).max() <= 3 * 0.5 * SPZ_SMALL_STEP + 1e-6
    else:  # x, y, z of the w >= 0 quaternion within half of 1/127.5; w is rebuilt from them (well away from 0)
        q = np.where(q[:, :1] < 0, -q, q)
        q_loaded = np.where(q_loaded[:, :1] < 0, -q_loaded, q_loaded)
        sure = q[:, 0] > 0.2  # near w = 0 the rebuilt w (and the sign) is ill-conditioned
        assert sure.sum() > 400
        assert np.abs(q_loaded[sure, 1:] - q[sure, 1:]).max() <= 0.5 / 127.5 + 1e-6


def test_spz_keeps_small_and_large_scenes_in_range(tmp_path):
    for extent, frac in ((0.01, 23), (5000.0, 10)):
        scene = random_scene(n=50, degree=0, extent=extent)
        save_scene(scene, tmp_path / "s.spz")
        raw = gzip.decompress((tmp_path / "s.spz").read_bytes())
        assert raw[13] == fractional_bits(scene.means) == frac
        loaded, _ = load_scene(tmp_path / "s.spz")
        assert np.abs(loaded.means - scene.means).max() <= 0.5 / (1 << frac) + f32_slack(scene.means)
    huge = random_scene(n=5, degree=0, extent=1e7)
    with pytest.raises(SceneFormatError, match="range"):
        save_scene(huge, tmp_path / "huge.spz")
    assert not (tmp_path / "huge.spz").exists()


def _spz_header(path) -> tuple[int, int, int, int]:
    magic, version, n, degree = struct.unpack_from("<IIIB", gzip.decompress(path.read_bytes()))
    return magic, version, n, degree


@pytest.mark.parametrize("suffix", [".spz", ".compressed.ply"])
def test_sh_bands_written_only_when_used(tmp_path, suffix):
    plain = random_scene(n=300, degree=0)
    zeros = random_scene(n=300, degree=3)
    zeros.sh_rest[:] = 0.0
    band1 = random_scene(n=300, degree=3)
    band1.sh_rest[:, 3:] = 0.0
    for name, scene, degree in (("plain", plain, 0), ("zeros", zeros, 0), ("band1", band1, 1),
                                ("full", random_scene(n=300), 3)):
        path = tmp_path / f"{name}{suffix}"
        save_scene(scene, path)
        loaded, _ = load_scene(path)
        assert loaded.sh_degree == degree, name
        if suffix == ".spz":
            assert _spz_header(path) == (0x5053474E, 3, 300, degree)
        else:
            assert (b"element sh" in path.read_bytes()[:4000]) == (degree > 0)
        if degree:
            order = morton_order(scene.means) if suffix != ".spz" else np.arange(scene.count)
            tol = 0.5 / 128 if suffix == ".spz" else 4 / 255
            assert np.abs(loaded.sh_rest - scene.sh_rest[order, : loaded.sh_rest.shape[1]]).max() <= tol + 1e-6
    assert used_sh_degree(band1.sh_rest) == 1 and used_sh_degree(zeros.sh_rest) == 0


def test_spz_without_sh_when_asked(tmp_path):
    save_scene(random_scene(n=40), tmp_path / "s.spz", keep_sh=False)
    assert _spz_header(tmp_path / "s.spz")[3] == 0


# ------------------------------------------------------------------------------------------ .compressed.ply
def _chunk_steps(values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Per-value quantisation step of a chunked unorm: (chunk max - chunk min) / levels."""
    n = len(values)
    starts = np.arange(0, n, CHUNK)
    span = np.maximum.reduceat(values, starts, axis=0) - np.minimum.reduceat(values, starts, axis=0)
    return np.repeat(span, CHUNK, axis=0)[:n] / levels


def test_compressed_ply_round_trip_within_quantisation(tmp_path):
    scene = random_scene(n=1000)  # 4 chunks, the last one partial
    save_scene(scene, tmp_path / "s.compressed.ply")
    loaded, report = load_scene(tmp_path / "s.compressed.ply")
    assert report.format == "ply-playcanvas-compressed" and loaded.count == scene.count
    ref = scene.subset(morton_order(scene.means))  # the writer stores Gaussians in Morton order
    xyz_levels = np.array([2047.0, 1023.0, 2047.0])
    means = ref.means.astype(np.float64)
    assert np.all(np.abs(loaded.means - means) <= 0.5 * _chunk_steps(means, xyz_levels) + f32_slack(means))
    scales = ref.log_scales.astype(np.float64)
    assert np.all(np.abs(loaded.log_scales - scales) <= 0.5 * _chunk_steps(scales, xyz_levels) + 1e-5)
    rgb = 0.5 + 0.28209479177387814 * ref.sh_dc.astype(np.float64)
    assert np.all(np.abs(loaded.rgb - rgb) <= 0.5 * _chunk_steps(rgb, np.full(3, 255.0)) + 1e-5)
    assert np.abs(loaded.opacities - sigmoid(ref.opacity_logits)).max() <= 0.5 / 255 + 1e-6
    q_loaded, q = aligned(loaded.quats, ref.quats)
    assert np.abs(q_loaded - q).max() <= 3 * 0.5 * CPLY_ROT_STEP + 1e-6
    assert loaded.sh_degree == 3 and np.abs(loaded.sh_rest - ref.sh_rest).max() <= 4 / 255 + 1e-6
    # Morton order makes chunks compact: each chunk's box is far smaller than the scene's
    span = np.ptp(means[:CHUNK], axis=0)
    assert np.prod(span) < 0.5 * np.prod(np.ptp(means, axis=0))


def test_compressed_ply_single_gaussian_and_flat_chunks(tmp_path):
    scene = random_scene(n=1, degree=0)
    save_scene(scene, tmp_path / "one.compressed.ply")
    loaded, _ = load_scene(tmp_path / "one.compressed.ply")
    assert np.allclose(loaded.means, scene.means, atol=1e-6)
    assert np.allclose(loaded.log_scales, scene.log_scales, atol=1e-5)
    assert np.allclose(loaded.rgb, scene.rgb, atol=1e-5)


@pytest.mark.parametrize("name", ["empty.spz", "empty.compressed.ply"])
def test_an_empty_scene_is_written_and_read_back(tmp_path, name):
    save_scene(random_scene(n=0, degree=0), tmp_path / name)
    loaded, _ = load_scene(tmp_path / name)
    assert loaded.count == 0 and loaded.sh_degree == 0


def test_morton_order_is_a_permutation_and_groups_neighbours():
    pts = np.random.default_rng(0).uniform(0, 1, (4096, 3))
    pts[:2] = [[0, 0, 0], [1, 1, 1]]  # the box is [0, 1]^3
    pts[np.abs(pts - 0.5) < 0.005] = 0.25  # nothing on the octant boundary (the cells are 1/1023 wide)
    order = morton_order(pts)
    assert sorted(order.tolist()) == list(range(4096))
    low_octant = np.all(pts < 0.5, axis=1)  # a Z-curve visits one octant entirely before the next
    assert low_octant[order[: low_octant.sum()]].all()


# ---------------------------------------------------------------------------------------------------- CLI
def test_convert_writes_web_formats(tmp_path):
    src = tmp_path / "in.ply"
    scene = random_scene(n=300, degree=1)
    save_scene(scene, src)
    for name in ("out.spz", "out.compressed.ply"):
        assert run(["convert", str(src), str(tmp_path / name)]) == 0
        loaded, _ = load_scene(tmp_path / name)
        assert loaded.count == 300 and loaded.sh_degree == 1
    assert run(["convert", str(src), str(tmp_path / "sh0.spz"), "--sh0"]) == 0
    assert load_scene(tmp_path / "sh0.spz")[0].sh_degree == 0


def test_convert_rejects_unknown_extension(tmp_path, capsys):
    src = tmp_path / "in.ply"
    save_scene(random_scene(n=20, degree=0), src)
    assert run(["convert", str(src), str(tmp_path / "out.ksplat")]) == 2
    assert "unknown output format" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply"]


# ------------------------------------------------------------------------------- PlayCanvas splat-transform
def test_splat_transform_reads_our_files(tmp_path):
    tool = splat_transform()
    if tool is None:
        pytest.skip(f"{SKIP_REASON}; our readers cover the round trip")
    scene = random_scene(n=600, degree=1)
    for name in ("s.spz", "s.compressed.ply"):
        save_scene(scene, tmp_path / name)
        out = tmp_path / f"{name}.plain.ply"
        subprocess.run([*tool, "-w", str(tmp_path / name), str(out)], check=True, capture_output=True, timeout=300)
        theirs, _ = load_scene(out)
        ours, _ = load_scene(tmp_path / name)
        assert theirs.count == ours.count and theirs.sh_degree == ours.sh_degree
        key = np.lexsort(np.round(ours.means, 3).T)
        their_key = np.lexsort(np.round(theirs.means, 3).T)
        assert np.allclose(theirs.means[their_key], ours.means[key], atol=1e-3)
        assert np.allclose(theirs.rgb[their_key], ours.rgb[key], atol=2 / 255)
        assert np.allclose(theirs.log_scales[their_key], ours.log_scales[key], atol=1e-3)
        assert np.allclose(theirs.opacities[their_key], ours.opacities[key], atol=2 / 255)
        dots = np.abs((theirs.quats[their_key] * ours.quats[key]).sum(axis=1))
        assert dots.min() > 0.999
