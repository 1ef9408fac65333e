"""Every shared sample scene loads with the expected count and sane content; real-data round trips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gstyle_core.io import load_scene, save_scene

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes"
SAMPLES = {
    "ply_3dgs/kacytran1122_try_iter7000_point_cloud.ply": (9_080, "ply-3dgs", 3),
    "ply_3dgs/cvlab_epfl_pc_short.ply": (100, "ply-3dgs", 3),
    "ply_3dgs/swiftgraphics_test-splat.3-points-from-train.ply": (3, "ply-3dgs", 3),
    "splat/winter_fountain.cropped.splat": (93_713, "splat", 0),
    "splat/lastchance.splat": (14_831, "splat", 0),
    "playcanvas/guitar.compressed.ply": (90_854, "ply-playcanvas-compressed", 0),
    "playcanvas/biker.spz": (152_746, "spz-v4", 0),
}


def sample(rel: str) -> Path:
    path = DATA / rel
    if not path.exists():
        pytest.skip(f"shared test data not present ({path})")
    return path


@pytest.mark.parametrize("rel", sorted(SAMPLES))
def test_sample_loads_with_expected_count(rel):
    count, fmt, degree = SAMPLES[rel]
    scene, report = load_scene(sample(rel))
    assert report.count_in_file == count
    assert scene.count == count and report.count_loaded == count and report.dropped == 0
    assert report.format.startswith(fmt)
    assert scene.sh_degree == degree == report.sh_degree
    for field in ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest"):
        arr = getattr(scene, field)
        assert arr.dtype == np.float32 and np.isfinite(arr).all(), field
    assert np.allclose(np.linalg.norm(scene.quats, axis=1), 1.0, atol=1e-5)
    rgb = scene.rgb
    assert ((rgb > -0.25) & (rgb < 1.25)).all(axis=1).mean() > 0.9  # colours mostly in range
    assert str(sample(rel)) in report.summary()


def test_trailing_bytes_are_tolerated_with_a_warning():
    _, report = load_scene(sample("ply_3dgs/cvlab_epfl_pc_short.ply"))
    assert any("14,029 trailing bytes" in w for w in report.warnings)
    _, report = load_scene(sample("ply_3dgs/swiftgraphics_test-splat.3-points-from-train.ply"))
    assert any("1 trailing bytes" in w for w in report.warnings)


def test_detection_is_by_content_not_extension(tmp_path):
    for rel in (
        "playcanvas/biker.spz",
        "playcanvas/guitar.compressed.ply",
        "ply_3dgs/cvlab_epfl_pc_short.ply",
    ):
        renamed = tmp_path / (Path(rel).stem + ".bin")
        renamed.write_bytes(sample(rel).read_bytes())
        assert load_scene(renamed)[0].count == SAMPLES[rel][0]
    splat = tmp_path / "fountain.data"
    splat.write_bytes(sample("splat/lastchance.splat").read_bytes())
    scene, report = load_scene(splat)
    assert scene.count == 14_831 and report.format == "splat"


def test_real_ply_round_trip_is_bit_exact(tmp_path):
    scene, _ = load_scene(sample("ply_3dgs/kacytran1122_try_iter7000_point_cloud.ply"))
    out = tmp_path / "copy.ply"
    save_scene(scene, out)
    again, report = load_scene(out)
    assert report.repairs == [] and again.sh_degree == 3
    for field in ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest"):
        assert np.array_equal(getattr(scene, field), getattr(again, field)), field
    out2 = tmp_path / "copy2.ply"
    save_scene(again, out2)
    assert out.read_bytes() == out2.read_bytes()


def test_compressed_guitar_decodes_to_a_compact_upright_object():
    scene, _ = load_scene(sample("playcanvas/guitar.compressed.ply"))
    lo, hi = scene.bounds()
    extent = hi - lo
    assert extent[1] == extent.max()  # a standing guitar: tallest along the (down) y axis
    assert 0.5 < extent.max() < 20
