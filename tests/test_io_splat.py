"""antimatter15 .splat round trips within the documented quantisation, and format-neutral input errors."""

from __future__ import annotations

import os

import numpy as np
import pytest

from gstyle_core.errors import OutputWriteError, SceneFormatError
from gstyle_core.io import load_scene, save_scene, validate_and_repair
from gstyle_core.io.splat import RECORD
from gstyle_core.scene import GaussianScene, sigmoid


def random_scene(n: int = 200, seed: int = 1) -> GaussianScene:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return GaussianScene(
        rng.normal(size=(n, 3)).astype(np.float32),
        rng.uniform(-6, 1, (n, 3)).astype(np.float32),
        q,
        rng.normal(scale=2, size=n).astype(np.float32),
        rng.uniform(-1.7, 1.7, (n, 3)).astype(np.float32),
        np.zeros((n, 3, 3), np.float32),
    )


def test_splat_round_trip_within_quantisation(tmp_path):
    scene = random_scene()
    save_scene(scene, tmp_path / "s.splat")
    assert (tmp_path / "s.splat").stat().st_size == 32 * scene.count
    loaded, report = load_scene(tmp_path / "s.splat")
    assert report.format == "splat" and loaded.sh_degree == 0 and report.repairs == []
    assert np.array_equal(loaded.means, scene.means)
    assert np.allclose(loaded.log_scales, scene.log_scales, atol=1e-5)
    assert np.abs(loaded.rgb - np.clip(scene.rgb, 0, 1)).max() <= 0.5 / 255 + 1e-6
    assert np.abs(loaded.opacities - sigmoid(scene.opacity_logits)).max() <= 0.5 / 255 + 1e-6
    dots = np.abs((loaded.quats * scene.quats).sum(axis=1))
    assert np.degrees(2 * np.arccos(np.clip(dots, -1, 1))).max() < 2.0  # rotation error under 2 degrees


def test_splat_requantising_is_stable(tmp_path):
    save_scene(random_scene(), tmp_path / "a.splat")
    once, _ = load_scene(tmp_path / "a.splat")
    save_scene(once, tmp_path / "b.splat")
    a, b = (np.frombuffer((tmp_path / f).read_bytes(), RECORD) for f in ("a.splat", "b.splat"))
    assert np.array_equal(a["position"], b["position"]) and np.array_equal(a["rgba"], b["rgba"])
    assert np.allclose(a["scale"], b["scale"], rtol=1e-6, atol=0)  # exp/log in float32
    assert np.abs(a["rot"].astype(int) - b["rot"]).max() <= 1  # renormalising moves a byte by at most 1


def test_splat_zero_and_negative_scales_are_clamped(tmp_path):
    rec = np.zeros(4, RECORD)
    rec["scale"] = [[0.01, 0.02, 0.03], [0.0, 0.01, 0.01], [-1.0, 0.01, 0.01], [1e6, 0.01, 0.01]]
    rec["rot"] = [128, 128, 128, 128]  # the zero quaternion in all four
    rec["rot"][0] = [255, 128, 128, 128]
    (tmp_path / "s.splat").write_bytes(rec.tobytes())
    scene, report = load_scene(tmp_path / "s.splat")
    text = "\n".join(report.repairs)
    assert "clamped 2 zero/negative scales" in text
    assert "clamped scales of 1 Gaussians" in text  # the huge one (tiny ones are already at 1e-7)
    assert "replaced 3 zero quaternions" in text
    assert np.allclose(scene.quats[1:], [1, 0, 0, 0])
    assert scene.scales.min() >= 1e-7 * 0.999 and scene.scales.max() <= 1e4 * 1.001


def test_splat_size_not_multiple_of_32(tmp_path):
    (tmp_path / "s.splat").write_bytes(bytes(32 * 3 + 5))
    with pytest.raises(SceneFormatError, match="not a multiple of 32"):
        load_scene(tmp_path / "s.splat")


def test_empty_missing_directory_and_unknown_inputs(tmp_path):
    (tmp_path / "empty.ply").write_bytes(b"")
    with pytest.raises(SceneFormatError, match="empty.ply: empty file"):
        load_scene(tmp_path / "empty.ply")
    with pytest.raises(SceneFormatError, match="no such file"):
        load_scene(tmp_path / "missing.ply")
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(SceneFormatError, match="is a directory"):
        load_scene(tmp_path / "dir.ply")
    (tmp_path / "notes.txt").write_bytes(b"hello, this is not a splat scene at all\n" * 3)
    with pytest.raises(SceneFormatError, match="unknown scene format"):
        load_scene(tmp_path / "notes.txt")
    (tmp_path / "x.zst").write_bytes(b"\x28\xb5\x2f\xfd" + bytes(60))
    with pytest.raises(SceneFormatError, match="zstd"):
        load_scene(tmp_path / "x.zst")


def test_save_to_a_directory_path_fails_cleanly(tmp_path):
    (tmp_path / "out.splat").mkdir()
    with pytest.raises(OutputWriteError, match=r"cannot write .*out\.splat: it is a directory"):
        save_scene(random_scene(), tmp_path / "out.splat")
    assert os.listdir(tmp_path) == ["out.splat"]


def test_validate_leaves_valid_scenes_bit_identical_and_inputs_untouched():
    scene = random_scene()
    before = scene.quats.copy()
    repaired, repairs, dropped = validate_and_repair(scene)
    assert repairs == [] and dropped == 0
    assert np.array_equal(repaired.quats, scene.quats) and repaired.quats is not scene.quats
    scene.quats[0] *= 2
    scene.means[1, 0] = np.nan
    validate_and_repair(scene)
    assert np.array_equal(scene.quats[0], before[0] * 2)  # the caller's arrays are not modified
