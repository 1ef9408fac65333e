"""The before/after picture (studio without a display, gallery): views around the orbit, cropped to the scene."""

import numpy as np
import pytest
from synthetic import blob_scene, ring_cameras

from gstyle_core.errors import GStyleError
from gstyle_core.scene import rgb_to_sh_dc
from gstyle_core.scene_images import before_after_picture


def test_picture_has_input_above_stylized_cropped_to_the_scene():
    before = blob_scene(400, seed=3, spread=0.3)
    after = blob_scene(400, seed=3, spread=0.3)
    after.sh_dc[:] = rgb_to_sh_dc(np.array([1.0, 0.0, 0.0]))  # the "stylized" scene: same geometry, red
    cams = ring_cameras(8, radius=4.0, width=64, height=48)
    pic = before_after_picture(before, after, cams, n_views=3, width=128)
    h = pic.shape[0] // 2
    assert pic.shape[0] % 2 == 0 and pic.shape[1] < 3 * 128 and h < 96  # the empty margins are cropped
    top, bottom = pic[:h], pic[h:]
    lit = top.sum(axis=2) > 0.05
    assert lit.mean() > 0.2  # the crop keeps mostly the scene
    assert bottom[lit][:, 0].mean() > 3 * bottom[lit][:, 1:].mean()  # the bottom row is the red scene
    assert not np.allclose(top, bottom)


def test_views_are_spread_over_the_orbit_and_no_cameras_is_an_error():
    scene = blob_scene(200, seed=1)
    cams = ring_cameras(8, radius=3.0, width=32, height=24)
    pic = before_after_picture(scene, scene, cams, n_views=2, width=64)
    assert np.allclose(pic[: pic.shape[0] // 2], pic[pic.shape[0] // 2:])  # same scene: same halves
    with pytest.raises(GStyleError):
        before_after_picture(scene, scene, [], n_views=2)
