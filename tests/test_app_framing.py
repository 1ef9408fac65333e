"""Frame all (issue #27): a scene file without cameras opens with its robust box inside the view beside the panel,
with a margin on every side, and stays framed when the view changes size; F frames it from any side; R comes back
to the framed home; turntable videos frame it in every frame. ``gstyle_core/cameras/framing.py`` does the maths."""

from __future__ import annotations

import numpy as np
import pytest

from gstyle_core.cameras import framing
from gstyle_core.cameras.framing import box_corners, fit_distance, focal_for, projected_bounds, scene_box
from gstyle_core.cameras.generate import generate_cameras, look_at

W, H = 640, 480
MARGIN_LO = 0.045  # every side keeps at least this share of the view free (FRAME_MARGIN, rounding)


def margins(camera, corners: np.ndarray) -> np.ndarray:
    """(left, top, right, bottom) free share of ``camera``'s image beside the projected ``corners``."""
    rotation = np.linalg.inv(camera.world_to_cam)[:3, :3]
    x0, y0, x1, y1 = projected_bounds(corners, camera.position, rotation, camera.fx, camera.width, camera.height)
    return np.array([x0 / camera.width, y0 / camera.height, 1 - x1 / camera.width, 1 - y1 / camera.height])


def tall_scene_means(seed: int = 0) -> np.ndarray:
    """A tall column (up = -y) standing on a wide base, plus a few far floaters (0.05 %)."""
    rng = np.random.default_rng(seed)
    column = rng.uniform([-0.3, -4.0, -0.3], [0.3, 0.0, 0.3], (3000, 3))
    base = rng.uniform([-1.5, -0.2, -1.5], [1.5, 0.4, 1.5], (3000, 3))
    floaters = rng.uniform(-40, 40, (3, 3))
    return np.concatenate([column, base, floaters])


def test_scene_box_ignores_a_few_floaters_and_grows_a_flat_box():
    lo, hi = scene_box(tall_scene_means())
    assert np.all(lo > [-1.6, -4.1, -1.6]) and np.all(hi < [1.6, 0.5, 1.6])
    assert np.all(lo < [-1.4, -3.9, -1.4]) and np.all(hi > [1.4, 0.3, 1.4])
    flat_lo, flat_hi = scene_box(np.column_stack([np.random.default_rng(1).normal(size=(100, 2)), np.zeros(100)]))
    assert flat_hi[2] - flat_lo[2] > 0
    empty_lo, empty_hi = scene_box(np.full((4, 3), np.nan))
    assert np.all(empty_hi > empty_lo)


@pytest.mark.parametrize("size", [(220, 480), (640, 480), (480, 640)])
def test_fit_distance_puts_every_corner_on_or_inside_the_margin(size):
    """The fitted camera sees all eight corners at least framing.FRAME_MARGIN inside each edge, and one touches it."""
    width, height = size
    lo, hi = scene_box(tall_scene_means())
    corners, centre = box_corners(lo, hi), (lo + hi) / 2
    forward = np.array([0.3, 0.35, 1.0]) / np.linalg.norm([0.3, 0.35, 1.0])  # looking slightly down (-y is up)
    rotation = look_at(centre - forward, centre, np.array([0.0, -1.0, 0.0]))[:3, :3].T
    focal = focal_for(width, height, 50.0)
    distance = fit_distance(corners, centre, rotation, focal, width, height)
    x0, y0, x1, y1 = projected_bounds(corners, centre - distance * forward, rotation, focal, width, height)
    free = np.array([x0 / width, y0 / height, 1 - x1 / width, 1 - y1 / height])
    assert free.min() == pytest.approx(framing.FRAME_MARGIN, abs=1e-6)  # tight: no farther than needed
    assert np.all(free >= framing.FRAME_MARGIN - 1e-6)


def test_turntable_frames_all_show_the_whole_box_at_one_distance():
    from gstyle_core.render_video import turntable_cameras
    from gstyle_core.scene import GaussianScene, logit

    means = tall_scene_means().astype(np.float32)
    n = len(means)
    scene = GaussianScene(means, np.full((n, 3), -4.0, np.float32), np.tile(np.float32([1, 0, 0, 0]), (n, 1)),
                          logit(np.full(n, 0.5)), np.zeros((n, 3), np.float32))
    cams = turntable_cameras(scene, 12, 640, 480)
    corners = box_corners(*scene_box(means))
    centre = corners.mean(0)
    for cam in cams:
        assert margins(cam, corners).min() >= MARGIN_LO
    distances = [np.linalg.norm(cam.position - centre) for cam in cams]
    assert np.ptp(distances) < 1e-6 * distances[0]  # the video does not zoom
    orbit = generate_cameras(means, kind="orbit", count=12, width=640, height=480).cameras
    for cam, generated in zip(cams, orbit, strict=True):  # the same orbit's directions (20 degrees down)
        horizontal = np.array([1.0, 0.0, 1.0])
        a, b = cam.forward * horizontal, generated.forward * horizontal
        assert np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b) > 0.99
    assert framing.frame_cameras([], *scene_box(means), np.array([0.0, -1.0, 0.0])) == []


@pytest.fixture
def demo_studio(window, tmp_path):
    """The studio on the bundled demo (a .splat: generated cameras) in a 640x480 headless window, no engine."""
    from app.open_files import load_scene_with_cameras
    from app.studio import StudioApp

    loaded = load_scene_with_cameras(None, None)
    assert loaded.generated_cameras
    app = StudioApp(window.ctx, loaded=loaded, output_dir=tmp_path)
    app.progressive = False
    yield app
    app.close()


def view_margins(app) -> np.ndarray:
    """Free shares of the view (left, top, right, bottom) beside the demo's projected robust box."""
    return margins(app.control.camera(*app.framing.view_size), box_corners(*scene_box(app.session.loaded.scene.means)))


def test_the_demo_opens_framed_beside_the_panel_and_stays_framed(window, demo_studio):
    from app.panels import PANEL_WIDTH

    app = demo_studio
    screen = window.draw(app.frame)
    assert app.framing.view_size == (W - PANEL_WIDTH, H)
    free = view_margins(app)
    assert free.min() >= MARGIN_LO and free.min() < 0.06  # inside with a margin, and not lost in the distance
    rgb = app.outputs.capture(screen)
    lit = rgb[:, int(PANEL_WIDTH):].astype(int).sum(-1) > 60
    ys, xs = np.nonzero(lit)
    assert lit.sum() > 1000 and ys.min() > 0.03 * H and ys.max() < 0.97 * H  # the fountain's top clear of the edge
    # the panel hidden: the view is the whole window, framed again
    app.show_ui = False
    window.draw(app.frame)
    assert app.framing.view_size == (W, H) and view_margins(app).min() >= MARGIN_LO
    # the camera moved: a new view size no longer re-frames it; R does, for the view's size then
    app.control.orbit(120, 0)
    app.control.zoom(-12)
    app.show_ui = True
    window.draw(app.frame)
    assert view_margins(app).min() > 0.3  # zoomed out: small, not re-framed
    app.keys.press("r")
    window.draw(app.frame)
    window.draw(app.frame)
    assert app.framing.view_size == (W - PANEL_WIDTH, H)
    free = view_margins(app)
    assert free.min() >= MARGIN_LO and free.min() < 0.06


def test_f_frames_the_whole_scene_from_the_side_the_view_looks(window, demo_studio):
    app = demo_studio
    window.draw(app.frame)
    app.control.orbit(300, -80)  # another side, from higher up
    app.control.zoom(6)  # close in: the scene overflows the view
    window.draw(app.frame)
    assert view_margins(app).min() < 0
    forward = app.control.pose.rotation[:, 2].copy()
    app.keys.press("f")
    window.draw(app.frame)
    free = view_margins(app)
    assert free.min() >= MARGIN_LO and free.min() < 0.06
    assert np.allclose(app.control.pose.rotation[:, 2], forward)  # the same side
    home = app.control.home.eye.copy()
    app.keys.press("r")  # F does not move the home
    window.draw(app.frame)
    assert np.allclose(app.control.pose.eye, home)
