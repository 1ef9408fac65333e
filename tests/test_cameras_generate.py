"""Generated cameras for bare scenes and the forward / 360 classification."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gstyle_core.cameras import Camera, classify_scene_kind, generate_cameras, load_cameras, look_at
from gstyle_core.cameras.generate import resolve_up

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes"


def project(cam: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pc = (cam.world_to_cam[:3, :3] @ np.asarray(points, np.float64).T).T + cam.world_to_cam[:3, 3]
    uv = (cam.K @ pc.T).T
    return uv[:, :2] / uv[:, 2:3], pc[:, 2]


def assert_valid(cam: Camera) -> None:
    assert np.all(np.isfinite(cam.world_to_cam)) and np.all(np.isfinite(cam.K))
    rot = cam.world_to_cam[:3, :3]
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    assert cam.fx > 0 and cam.fy > 0 and cam.width > 0 and cam.height > 0


def blob(n=5000, seed=0, centre=(1.0, 2.0, 3.0), scale=(2.0, 0.5, 1.0)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.asarray(centre) + rng.normal(size=(n, 3)) * np.asarray(scale)


def test_look_at_identity_and_up():
    w2c = look_at(np.zeros(3), np.array([0, 0, 5.0]), np.array([0, -1.0, 0]))
    np.testing.assert_allclose(w2c, np.eye(4), atol=1e-12)
    w2c = look_at(np.array([0, 0, -5.0]), np.zeros(3), np.array([0, -1.0, 0]))
    cam = Camera(100, 100, 50, 50, 50, 50, w2c)
    uv, _ = project(cam, np.array([[0, -1.0, 0]]))  # a point above the target is above the image centre
    assert uv[0, 1] < 50 and uv[0, 0] == pytest.approx(50)


@pytest.mark.parametrize("kind, expected_kind", [("orbit", "360"), ("arc", "forward"), ("auto", "360")])
def test_generated_cameras_frame_the_central_mass(kind, expected_kind):
    pts = blob()
    floaters = np.random.default_rng(1).uniform(-1000, 1000, size=(100, 3))  # 2 % floaters must not matter
    cs = generate_cameras(np.concatenate([pts, floaters]), kind=kind, count=12, width=320, height=240)
    assert len(cs) == 12 and cs.kind == expected_kind and cs.source.startswith("generated-")
    centre = np.median(pts, axis=0)
    for cam in cs:
        assert_valid(cam)
        assert (cam.width, cam.height) == (320, 240)
        uv, depth = project(cam, pts)
        assert np.all(depth > 0)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < 320) & (uv[:, 1] >= 0) & (uv[:, 1] < 240)
        assert inside.mean() > 0.9
        c_uv, _ = project(cam, centre[None])
        np.testing.assert_allclose(c_uv[0], [160, 120], atol=1.0)
        assert (cam.position - centre) @ np.array([0, -1.0, 0]) > 0  # above the centre (default up = -y)
    assert classify_scene_kind(cs) == expected_kind


@pytest.mark.parametrize("means", [
    np.array([[1.0, 2.0, 3.0]]),
    np.full((50, 3), 7.5),
    np.zeros((0, 3)),
    np.array([[np.nan, 0, 0], [np.inf, 1, 1]]),
    np.array([[1e30, -1e30, 3e29], [1e30, -1e30, 3e29]], np.float32),
    blob(100, centre=(1e7, -3e7, 5e6), scale=(1e-3, 1e-3, 1e-3)),
    np.array([[3.0e38, 3.0e38, -3.0e38], [-3.0e38, 1.0, 0.0]], np.float32),
])
@pytest.mark.parametrize("kind", ["orbit", "arc"])
def test_generated_cameras_never_degenerate(means, kind):
    cs = generate_cameras(means, kind=kind, count=5)
    for cam in cs:
        assert_valid(cam)
    finite = means[np.all(np.isfinite(means), axis=1)].astype(np.float64)
    target = np.median(finite, axis=0) if len(finite) else np.zeros(3)
    for cam in cs:
        _, depth = project(cam, target[None])
        assert depth[0] > 0


def test_up_axis_options():
    flat = blob(scale=(3.0, 3.0, 0.2))  # a "ground" in the x-y plane: up is ±z
    up_pca = generate_cameras(flat, kind="orbit", count=4, up="pca")
    centre = np.median(flat, axis=0)
    for cam in up_pca:
        offset = cam.position - centre
        assert abs(offset[2]) > 0.3 * np.linalg.norm(offset)  # elevated along z
    z_up = generate_cameras(flat, count=4, up="+z")
    assert all((c.position - centre)[2] > 0 for c in z_up)
    explicit = generate_cameras(flat, count=4, up=np.array([0, 0, 2.0]))
    np.testing.assert_allclose(explicit[0].world_to_cam, z_up[0].world_to_cam, atol=1e-12)
    ground = flat.copy()
    ground[:500, 2] += np.random.default_rng(2).uniform(0.5, 3.0, 500)  # things standing on it, along +z
    assert resolve_up("pca", ground, np.median(ground, axis=0)) @ np.array([0, 0, 1.0]) > 0.99
    ground[:, 2] *= -1  # the same scene upside down
    assert resolve_up("pca", ground, np.median(ground, axis=0)) @ np.array([0, 0, -1.0]) > 0.99
    sphere = blob(scale=(1.0, 1.0, 1.0))  # no flat direction: pca falls back to -y
    np.testing.assert_allclose(generate_cameras(sphere, count=3, up="pca")[1].world_to_cam,
                               generate_cameras(sphere, count=3)[1].world_to_cam, atol=1e-12)


@pytest.mark.parametrize("kwargs, message", [
    ({"kind": "spiral"}, "kind must be"),
    ({"count": 0}, "must be >= 1"),
    ({"fov_deg": 0.0}, "fov_deg"),
    ({"up": "north"}, "up must be one of"),
    ({"up": np.zeros(3)}, "non-zero 3-vector"),
])
def test_generate_argument_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        generate_cameras(blob(10), **kwargs)
    with pytest.raises(ValueError, match=r"means must be \[N,3\]"):
        generate_cameras(np.zeros((4, 2)))


def test_classify_rules():
    one = generate_cameras(blob(), kind="orbit", count=1)
    assert classify_scene_kind(one) == "forward"  # a single view cannot be 360
    assert classify_scene_kind([]) == "forward"
    # a quarter orbit looking inward: view directions spread ±45°, the edge of "forward"
    half_span = generate_cameras(blob(), kind="orbit", count=16).cameras
    assert classify_scene_kind(half_span[:3]) == "forward"  # 3 of 16 = 45° of arc
    assert classify_scene_kind(half_span[:6]) == "360"  # 112° of arc
    # parallel cameras translated sideways (LLFF-like rig) are forward
    rig = [Camera(64, 48, 50, 50, 32, 24, look_at(np.array([x, 0, 0.0]), np.array([x, 0, 10.0]),
                                                    np.array([0, -1.0, 0]))) for x in np.linspace(-1, 1, 5)]
    assert classify_scene_kind(rig) == "forward"
    # cameras at one spot looking outward in all directions (a panorama) are 360
    pano = [Camera(64, 48, 50, 50, 32, 24, look_at(np.zeros(3), np.array([np.cos(a), 0, np.sin(a)]),
                                                     np.array([0, -1.0, 0]))) for a in np.linspace(0, 6, 8)]
    assert classify_scene_kind(pano) == "360"
    # same directions but cameras placed on both sides of the points' centre: not one-sided
    sides = [Camera(64, 48, 50, 50, 32, 24, look_at(np.array([0, 0, z]), np.array([0, 0, z + 1.0]),
                                                      np.array([0, -1.0, 0]))) for z in (-5.0, 5.0)]
    assert classify_scene_kind(sides, points=np.zeros((1, 3))) == "360"
    assert classify_scene_kind(sides) == "forward"


@pytest.mark.skipif(not (DATA / "llff_fern" / "poses_bounds.npy").is_file(),
                    reason="shared/data llff_fern absent")
def test_classify_fern_forward():
    cs = load_cameras(DATA / "llff_fern")
    assert classify_scene_kind(cs) == "forward"
    assert classify_scene_kind(cs.cameras) == "forward"  # without the sparse points as well


@pytest.mark.skipif(not (DATA / "gsplat_garden" / "test_garden.npz").is_file(),
                    reason="shared/data gsplat_garden absent")
def test_classify_garden_three_cameras():
    # Only 3 cameras of the Mip-NeRF 360 garden orbit, about 85° of azimuth apart end to end: their view
    # directions lie up to 50° from the mean, beyond the 45° forward limit, so "360", which is right for
    # this scene, though with 3 views it is close to the boundary.
    cs = load_cameras(DATA / "gsplat_garden" / "test_garden.npz")
    forwards = np.stack([c.forward for c in cs])
    mean = forwards.mean(axis=0) / np.linalg.norm(forwards.mean(axis=0))
    spread = np.degrees(np.arccos(forwards @ mean)).max()
    assert 45 < spread < 60
    assert classify_scene_kind(cs) == "360"
    # the garden's ground is the least-variance axis; "pca" must find the cameras' up (minus image y)
    cameras_up = -np.mean([c.world_to_cam[1, :3] for c in cs], axis=0)
    cameras_up /= np.linalg.norm(cameras_up)
    assert resolve_up("pca", cs.points.astype(np.float64), np.median(cs.points, axis=0)) @ cameras_up > 0.9
