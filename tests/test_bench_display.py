"""bench/studies/display_table.py (issue #34's targets from OUT.json summaries) and bench/pictures/display_gallery.py
(pictures at a display's size with full-size crops) on tiny inputs."""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench" / "studies"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench" / "pictures"))

import display_gallery  # noqa: E402
import display_table  # noqa: E402


def _summary(path: Path, *, speckle, drop_end, structure_end, coarse=1.1) -> Path:
    path.write_text(json.dumps({
        "scene": "/x/biker.spz", "style": "/y/starry.jpg", "seconds_total": 180.0, "gaussians_after": 1000,
        "settings": {"preset": "balanced", "working_width": 256, "refine_widths": [512], "refine_mode": "crops"},
        "quality": {"width": 256, "nnfm_drop": 0.33, "structure": 0.52, "texture_scale": {"coarse_ratio": coarse},
                    "at_final_width": {"width": 512, "nnfm_drop": drop_end, "structure": structure_end},
                    "display": {"speckle_ratio": speckle}}}))
    return path


def test_the_table_names_the_targets_each_run_misses(tmp_path, capsys):
    good = _summary(tmp_path / "a.json", speckle=0.8, drop_end=0.31, structure_end=0.55)
    bad = _summary(tmp_path / "b.json", speckle=None, drop_end=0.26, structure_end=0.45, coarse=0.8)
    assert display_table.misses(display_table.row(good)) == []
    assert display_table.misses(display_table.row(bad)) == ["speckle", "drop", "structure", "coarse"]
    assert display_table.main([str(good), str(bad), "--markdown"]) == 0
    out = capsys.readouterr().out
    assert "| biker.spz | starry.jpg | balanced | 256→512 (crops) |" in out
    assert "RESULT rows=2 all_targets_met=1 speckle_met=1" in out


def test_the_gallery_shows_each_file_at_the_width_with_a_full_size_crop(tmp_path):
    from PIL import Image
    from synthetic import blob_scene

    from gstyle_core.io import save_scene

    before, after = blob_scene(150, seed=2), blob_scene(150, seed=2)
    after.sh_dc = after.sh_dc + np.float32(0.5)
    save_scene(before, tmp_path / "in.ply")
    save_scene(after, tmp_path / "out.ply")
    sheet = tmp_path / "sheet.png"
    assert display_gallery.main([str(tmp_path / "in.ply"), str(tmp_path / "out.ply"), "--labels", "input,after",
                                 "--width", "128", "--crop", "40", "--view", "0", "--out", str(sheet)]) == 0
    picture = np.asarray(Image.open(sheet).convert("RGB")).astype(int)
    assert picture.shape[0] > 2 * 40 and picture.shape[1] >= 40
    half = picture.shape[0] // 2
    assert np.abs(picture[:half].mean(axis=(0, 1)) - picture[half:].mean(axis=(0, 1))).max() > 3  # rows differ
