"""The selection's outline (``app.selection_outline``): the footprint of the selected centres, as segments."""

import numpy as np
from synthetic import look_at_camera

from app.selection_outline import footprint, outline_segments, project_points, selection_outline


def test_one_block_gives_its_four_sides():
    grid = np.zeros((5, 6), bool)
    grid[1:3, 2:5] = True
    segs = outline_segments(grid, cell=10.0)
    assert sorted(segs) == sorted([(20.0, 10.0, 50.0, 10.0), (20.0, 30.0, 50.0, 30.0),
                                   (20.0, 10.0, 20.0, 30.0), (50.0, 10.0, 50.0, 30.0)])


def test_footprint_grows_by_one_cell_and_clips_to_the_view():
    grid = footprint(np.array([[25.0, 25.0], [500.0, 500.0]]), 60, 40, cell=10.0)
    assert grid.shape == (4, 6)
    assert grid[1:4, 1:4].all() and grid.sum() == 9  # the far point is outside


def test_outline_follows_the_projected_selection():
    cam = look_at_camera((0, 0, -3), (0, 0, 0), 200, 100)
    pts = np.random.default_rng(0).uniform(-0.2, 0.2, (300, 3))
    px = project_points(pts, cam)
    segs = selection_outline(pts, cam, cell=4.0)
    xs = [x for s in segs for x in (s[0], s[2])]
    ys = [y for s in segs for y in (s[1], s[3])]
    assert min(xs) <= px[:, 0].min() and max(xs) >= px[:, 0].max()
    assert min(ys) <= px[:, 1].min() and max(ys) >= px[:, 1].max()
    assert 0 < min(xs) and max(xs) < 200  # around the middle, inside the view
    assert selection_outline(pts + [0, 0, -10.0], cam) == []  # behind the camera: nothing
