"""Multi-view consistency measure: reprojection through rendered depth lines up the same surface points."""

import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))  # the measure: bench/consistency.py
from consistency import render_with_depth, reprojection_error, view_consistency  # noqa: E402
from synthetic import blob_scene, look_at_camera  # noqa: E402

from gstyle_core.scene import rgb_to_sh_dc, sh_dc_to_rgb

W, H = 64, 48


def dense_scene():
    return blob_scene(3000, seed=3, spread=0.4, scale=0.08)


def cam(angle):
    return look_at_camera((3 * np.sin(angle), -0.3, -3 * np.cos(angle)), (0, 0, 0), W, H, fov_deg=40)


def test_same_view_has_zero_error():
    scene, c = dense_scene(), cam(0.0)
    r = render_with_depth(scene, c)
    err, used = reprojection_error(r, c, r, c)
    assert used > 500 and err < 1e-5


def test_nearby_views_of_one_scene_agree_and_a_colour_change_shows():
    scene, a, b = dense_scene(), cam(0.0), cam(0.06)
    ra, rb = render_with_depth(scene, a), render_with_depth(scene, b)
    same, used = reprojection_error(ra, a, rb, b)
    assert used > 500 and same < 0.05
    shifted = dataclasses.replace(scene, sh_dc=rgb_to_sh_dc(np.clip(sh_dc_to_rgb(scene.sh_dc), 0, 1) * 0.5 + 0.3))
    # Same geometry, different colours in view B: the error is about the colour difference, not the warp.
    other, _ = reprojection_error(ra, a, render_with_depth(shifted, b), b)
    rgb = np.clip(sh_dc_to_rgb(scene.sh_dc), 0, 1)
    expected = np.abs(rgb - (rgb * 0.5 + 0.3)).mean()
    assert abs(other - expected) < 0.05 + same


def test_view_consistency_averages_pairs_and_handles_disjoint_views():
    scene = dense_scene()
    value = view_consistency(scene, [(cam(0.0), cam(0.05)), (cam(1.0), cam(1.05))])
    assert 0 <= value < 0.05
    away = look_at_camera((0, 0, -3), (0, 0, -10), W, H)  # looks away from the scene: nothing shared
    assert np.isnan(view_consistency(scene, [(away, cam(0.0))]))
