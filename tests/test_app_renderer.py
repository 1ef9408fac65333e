"""GL splat renderer: pixel asserts on known Gaussians, blending, sorting, and parity with the torch rasterizer."""

from pathlib import Path

import numpy as np
import pytest

moderngl = pytest.importorskip("moderngl")

from synthetic import blob_scene, look_at_camera  # noqa: E402

from app.gl_io import read_rgb_float  # noqa: E402
from app.renderer import SplatRenderer  # noqa: E402
from app.splat_data import back_to_front_order, rotation_matrices  # noqa: E402
from gstyle_core.cameras.camera import Camera  # noqa: E402

W, H = 64, 48


def float_fbo(ctx, w=W, h=H):
    return ctx.framebuffer([ctx.texture((w, h), 4, dtype="f4")])


def gaussians(means, scale, opacity_logit, colors):
    n = len(means)
    return {"means": np.asarray(means, np.float32),
            "log_scales": np.full((n, 3), np.log(scale), np.float32),
            "quats": np.tile(np.array([1, 0, 0, 0], np.float32), (n, 1)),
            "opacity_logits": np.full(n, opacity_logit, np.float32),
            "colors": np.asarray(colors, np.float32)}


def blob_setup(ctx, seed):
    """500 random Gaussians loaded into a renderer, a float FBO and a camera looking at them."""
    scene = blob_scene(500, seed=seed)
    r = SplatRenderer(ctx)
    r.set_scene({"means": scene.means, "log_scales": scene.log_scales, "quats": scene.quats,
                 "opacity_logits": scene.opacity_logits, "sh_dc": scene.sh_dc})
    return scene, r, float_fbo(ctx), look_at_camera((0, 0, -3), (0, 0, 0), W, H)


def test_single_gaussian_lands_where_projected(ctx):
    # Off-centre principal point and a mean off the axis: centre at pixel (fx*X/Z+cx, fy*Y/Z+cy) = (40.5, 12.5)
    cam = Camera(W, H, 50.0, 50.0, 30.0, 20.0, np.eye(4))
    r = SplatRenderer(ctx)
    r.set_scene(gaussians([[0.42, -0.3, 2.0]], 0.05, 12.0, [[1.0, 0.5, 0.25]]))
    fbo = float_fbo(ctx)
    r.render(cam, fbo, (0.0, 0.0, 0.0))
    img = read_rgb_float(fbo)
    peak = np.unravel_index(np.argmax(img[..., 0]), img.shape[:2])
    assert peak == (12, 40)  # row 12, col 40: the pixel whose centre (40.5, 12.5) is the mean
    assert np.allclose(img[12, 40], [0.99, 0.495, 0.2475], atol=2e-3)  # alpha capped at 0.99
    # EWA: cov2d = J (s^2 I) J^T + 0.3 I with J the projection's Jacobian at the mean
    x, y, z = 0.42, -0.3, 2.0
    jac = np.array([[50 / z, 0, -50 * x / z**2], [0, 50 / z, -50 * y / z**2]])
    conic = np.linalg.inv(jac @ jac.T * 0.05**2 + 0.3 * np.eye(2))
    for d in ([1.0, 0.0], [0.0, 2.0], [-2.0, 1.0]):
        expected = min(0.99, np.exp(-0.5 * np.array(d) @ conic @ np.array(d)))
        assert np.isclose(img[12 + int(d[1]), 40 + int(d[0]), 0], expected, atol=2e-3)
    assert img[0, 0].max() == 0.0 and img[-1, -1].max() == 0.0
    r.release()


def test_two_half_opaque_layers_blend_to_three_quarters(ctx):
    cam = Camera(W, H, 40.0, 40.0, W / 2, H / 2, np.eye(4))
    logit_half = 0.0  # sigmoid(0) = 0.5
    big = 5.0  # huge scale: alpha ~ 0.5 across the centre pixels
    r = SplatRenderer(ctx)
    r.set_scene(gaussians([[0, 0, 3.0], [0, 0, 2.0]], big, logit_half, [[1, 0, 0], [1, 0, 0]]))
    fbo = ctx.framebuffer([ctx.texture((W, H), 4)])  # 8-bit, as the notes' check
    r.render(cam, fbo, (0.0, 0.0, 0.0))
    rgb = np.frombuffer(fbo.read(components=3), np.uint8).reshape(H, W, 3)
    assert abs(int(rgb[H // 2, W // 2, 0]) - 191) <= 2  # 0.5 + 0.5 * 0.5 = 0.75
    assert rgb[H // 2, W // 2, 1] == 0


def test_front_to_back_order_and_background(ctx):
    cam = Camera(W, H, 40.0, 40.0, W / 2, H / 2, np.eye(4))
    r = SplatRenderer(ctx)
    # red at z=2 (front), green at z=4 (behind), both alpha 0.5; grey background
    r.set_scene(gaussians([[0, 0, 4.0], [0, 0, 2.0]], 5.0, 0.0, [[0, 1, 0], [1, 0, 0]]))
    fbo = float_fbo(ctx)
    bg = (0.2, 0.2, 0.2)
    r.render(cam, fbo, bg)
    px = read_rgb_float(fbo)[H // 2, W // 2]
    # image = c_front a + c_back a (1 - a) + bg (1 - a)^2
    expect = np.array([0.5, 0.25, 0.0]) + 0.25 * np.array(bg)
    assert np.allclose(px, expect, atol=3e-3)


def test_behind_camera_and_non_finite_gaussians_are_not_drawn(ctx):
    cam = Camera(W, H, 40.0, 40.0, W / 2, H / 2, np.eye(4))
    r = SplatRenderer(ctx)
    data = gaussians([[0, 0, -2.0], [np.nan, 0, 2.0]], 5.0, 5.0, [[1, 1, 1], [1, 1, 1]])
    r.set_scene(data)
    fbo = float_fbo(ctx)
    r.render(cam, fbo, (0.0, 0.0, 0.0))
    assert read_rgb_float(fbo).max() == 0.0


def test_sort_happens_only_when_the_view_changes(ctx):
    scene, r, fbo, cam = blob_setup(ctx, seed=3)
    r.render(cam, fbo)
    r.render(cam, fbo)
    r.update_colors(np.zeros((500, 3), np.float32))  # colour upload: no re-sort
    r.render(cam, fbo)
    assert r.sort_count == 1
    r.render(look_at_camera((0.1, 0, -3), (0, 0, 0), W, H), fbo)
    assert r.sort_count == 2


def test_projection_runs_once_per_camera_and_is_shared_by_colours_layers_and_slices(ctx):
    scene, r, fbo, cam = blob_setup(ctx, seed=4)
    whole = r.render(cam, fbo)
    full = read_rgb_float(fbo)
    r.update_colors(np.full((500, 3), 0.5, np.float32), "other")
    r.render(cam, fbo, layer="other")
    r.update_colors(np.random.default_rng(0).uniform(0, 1, (500, 3)).astype(np.float32), "streamed")
    r.render(cam, fbo, layer="streamed")
    r.render(cam, fbo, instances=(0, whole // 2))
    r.render(cam, fbo, clear=False, instances=(whole // 2, whole))
    assert r.projection_count == 1
    np.testing.assert_array_equal(read_rgb_float(fbo), full)  # slices of one projection add up to the whole
    r.render(look_at_camera((0, 0.1, -3), (0, 0, 0), W, H), fbo)  # new camera: projected again
    assert r.projection_count == 2
    r.render(look_at_camera((0, 0.1, -3), (0, 0, 0), W, H, fov_deg=70.0), fbo)  # same pose, new intrinsics
    assert r.projection_count == 3
    geometry = {"means": scene.means + 0.01, "log_scales": scene.log_scales, "quats": scene.quats,
                "opacity_logits": scene.opacity_logits}
    r.update_geometry(geometry)
    r.update_colors(np.full((500, 3), 0.5, np.float32))
    r.render(cam, fbo)
    assert r.projection_count == 4


def test_bad_colour_shape_is_a_clear_error(ctx):
    r = SplatRenderer(ctx)
    r.set_scene(gaussians([[0, 0, 2.0]], 0.1, 0.0, [[1, 0, 0]]))
    with pytest.raises(ValueError, match=r"colours must have shape \[1, 3\]"):
        r.update_colors(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="unknown colour layer"):
        r.render(Camera(W, H, 40.0, 40.0, 32, 24, np.eye(4)), float_fbo(ctx), layer="nope")


def test_back_to_front_order_and_rotations():
    order = back_to_front_order(np.array([[0, 0, 1.0], [0, 0, 5.0], [0, 0, -1.0], [0, 0, 3.0]]), np.eye(4), 0.01)
    assert order.tolist() == [1, 3, 0]
    q = np.array([[np.cos(0.4), 0, 0, np.sin(0.4)], [0, 0, 0, 0]])
    r = rotation_matrices(q)
    assert np.allclose(r[0] @ [1, 0, 0], [np.cos(0.8), np.sin(0.8), 0]) and np.allclose(r[1], np.eye(3))


def psnr(a, b):
    return 10 * np.log10(1.0 / np.mean((np.clip(a, 0, 1) - np.clip(b, 0, 1)) ** 2))


@pytest.mark.parametrize("sh_degree", [0, 3])
def test_matches_torch_rasterizer(ctx, sh_degree):
    torch = pytest.importorskip("torch")
    try:
        from gstyle_core.raster import rasterize
    except ImportError as exc:
        pytest.skip(f"gstyle_core.raster.rasterize not available: {exc}")
    from app.studio import scene_arrays

    w, h = 320, 240
    scene = blob_scene(3000, seed=1, sh_degree=sh_degree, spread=0.5, scale=0.04)
    cam = look_at_camera((0.3, -0.8, -3.0), (0, 0, 0), w, h)
    r = SplatRenderer(ctx)
    r.set_scene(scene_arrays(scene))
    fbo = float_fbo(ctx, w, h)
    bg = (0.1, 0.2, 0.3)
    r.render(cam, fbo, bg, layer="sh" if sh_degree else "diffuse")
    gl = read_rgb_float(fbo)

    def t(a):
        return torch.from_numpy(np.ascontiguousarray(a, np.float32))

    colors = t(np.concatenate([scene.sh_dc[:, None], scene.sh_rest], 1)) if sh_degree else t(scene.rgb)
    ref = rasterize(t(scene.means), t(scene.quats), t(scene.scales), t(scene.opacities), colors,
                    t(cam.world_to_cam), t(cam.K), w, h, t(bg), sh_degree=sh_degree or None).image.numpy()
    assert psnr(gl, ref) >= 30.0
    r.release()


# ====================================================================== the order from the sorter thread
def test_renderer_draws_with_the_newest_finished_order_and_waits_only_when_asked(ctx):
    from fakes import GatedSort

    from app.depth_sort import DepthSorter, depth_order

    sort = GatedSort()
    sort.gate.set()
    scene = blob_scene(500, seed=6)
    r = SplatRenderer(ctx, DepthSorter(sort))
    r.set_scene({"means": scene.means, "log_scales": scene.log_scales, "quats": scene.quats,
                 "opacity_logits": scene.opacity_logits, "sh_dc": scene.sh_dc})
    fbo = float_fbo(ctx)
    cam_a, cam_b = look_at_camera((0, 0, -3), (0, 0, 0), W, H), look_at_camera((2.5, 0, -2), (0, 0, 0), W, H)
    r.render(cam_a, fbo)  # waits for its own order
    order_a = r.order()
    assert np.array_equal(order_a, depth_order(scene.means, cam_a.world_to_cam, 0.01))
    sort.gate.clear()
    sort.started.clear()
    assert r.render(cam_b, fbo, wait=False) == order_a.size  # the sort of view b is held: drawn with a's order
    assert sort.started.wait(30) and r.sort_count == 1 and np.array_equal(r.order(), order_a)
    assert not r.prepare(cam_b, wait=False)  # not b's own order yet
    sort.gate.set()
    assert r.sorter.idle(30)
    r.render(cam_b, fbo, wait=False)  # b's order has finished: the next frame uses it
    assert r.sort_count == 2 and np.array_equal(r.order(), depth_order(scene.means, cam_b.world_to_cam, 0.01))
    assert r.prepare(cam_b, wait=False)
    r.release()
    assert not r.sorter.running


def test_a_still_camera_submits_no_sort_and_uploads_no_order(ctx):
    scene, r, fbo, cam = blob_setup(ctx, seed=7)
    r.render(cam, fbo, detail=0.5)
    r.render(cam, fbo)
    submitted, sorted_, orders = r.sorter.stats.submitted, r.sorter.stats.sorted, r.sort_count
    assert (submitted, orders) == (2, 2)
    for _ in range(5):
        assert r.prepare(cam, wait=False)
        r.render(cam, fbo, wait=False)
    r.update_colors(np.full((500, 3), 0.2, np.float32))
    r.render(cam, fbo)
    assert (r.sorter.stats.submitted, r.sorter.stats.sorted, r.sort_count) == (submitted, sorted_, orders)
    view = np.array(cam.world_to_cam, np.float64)
    view[0, 3] += 0.2  # a pan across the view: the same depths, no new sort
    r.render(Camera(W, H, cam.fx, cam.fy, cam.cx, cam.cy, view), fbo)
    assert r.sorter.stats.submitted == submitted
    r.release()


BIKER = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes" / "playcanvas" / "biker.spz"


@pytest.mark.skipif(not BIKER.is_file(), reason="shared/data playcanvas/biker.spz absent")
def test_quantised_order_draws_the_exact_orders_image_on_a_real_capture(ctx):
    from app.depth_sort import DepthSorter, exact_sort_request, key_bits
    from app.gl_io import read_rgb
    from app.splat_data import scene_arrays
    from gstyle_core.cameras.generate import finite_points, robust_centre_radius
    from gstyle_core.io import load_scene

    scene, _ = load_scene(BIKER)
    centre, radius = robust_centre_radius(finite_points(scene.means))
    w, h = 320, 240
    cam = look_at_camera(centre + radius * np.array([1.2, -0.4, 0.9]), centre, w, h)
    images = {}
    for name, sorter, bits in (("exact", DepthSorter(exact_sort_request), 16), ("16 bits", DepthSorter(), 16),
                               ("count bits", DepthSorter(), key_bits(scene.count)), ("10 bits", DepthSorter(), 10)):
        r = SplatRenderer(ctx, sorter)
        r.sort_bits = bits
        r.set_scene(scene_arrays(scene))
        fbo = ctx.framebuffer([ctx.texture((w, h), 4)])
        r.render(cam, fbo, (0.0, 0.0, 0.0))
        images[name] = read_rgb(fbo).astype(np.int16)
        r.release()
    diffs = {name: np.abs(img - images["exact"]) for name, img in images.items()}
    for name in ("16 bits", "count bits"):
        assert diffs[name].mean() < 0.05 and np.percentile(diffs[name], 99.9) <= 3  # measured 0.006 / 1 (16 bits)
    assert diffs["10 bits"].mean() > diffs["16 bits"].mean()  # coarser keys do show (the comparison can fail)


HALF_ROUNDOFF = 2.0**-11  # half floats keep 11 significant bits: a normal value rounds within 2^-11 of itself
HALF_SUBNORMAL_ERROR = 2.0**-25  # half the spacing of half floats below 2^-14
FLOAT32_EVAL = (2e-5, 1e-5)  # the shader's own float32 evaluation (absolute, relative; float32 layout measured)


@pytest.mark.parametrize("layout", ["compact", "float32"])
@pytest.mark.parametrize("degree", [1, 2, 3])
def test_projection_pass_evaluates_sh_as_the_rasterizer_on_random_directions(ctx, degree, layout):
    """The shader's SH colours (read back from the projection pass) against sh.py in float64. Coefficients stored
    as half floats are each off by at most 2^-11 of themselves (or 2^-25 below 2^-14), so a colour is off by at
    most sum_k |basis_k(dir)| (2^-11 |c_k| + 2^-25) more than the float32 evaluation's own error."""
    torch = pytest.importorskip("torch")
    from app.splat_data import scene_arrays
    from gstyle_core.raster.sh import eval_sh_colors, sh_basis

    rng = np.random.default_rng(degree)
    scene = blob_scene(2000, seed=degree, sh_degree=degree, spread=2.0)
    scene.sh_rest = rng.normal(0, 0.4, scene.sh_rest.shape).astype(np.float32)
    r = SplatRenderer(ctx, layout=layout)
    r.set_scene(scene_arrays(scene))
    coeffs = torch.from_numpy(np.concatenate([scene.sh_dc[:, None], scene.sh_rest], 1)).double()
    means = torch.from_numpy(scene.means).double()
    seen, worst = np.zeros(scene.count, bool), 0.0
    for _ in range(6):  # cameras at random places looking in random directions: directions over the whole sphere
        eye = rng.normal(0, 0.5, 3)
        cam = look_at_camera(eye, eye + rng.normal(0, 1, 3), W, H)
        r.render(cam, float_fbo(ctx), layer="sh")
        order, rgb = r.order(), r.projected()["rgb"].astype(np.float64)
        drawn = r.projected()["axes"].any(1)  # culled ones (degenerate, faint) carry no colour
        position = torch.tensor(cam.position, dtype=torch.float64)
        ref = eval_sh_colors(coeffs, means, position, degree).numpy()[order]
        offset = means - position
        basis = sh_basis(offset / offset.norm(dim=1, keepdim=True), degree).abs().numpy()[order]  # [M, K]
        tolerance = FLOAT32_EVAL[0] + FLOAT32_EVAL[1] * np.abs(ref)
        if layout == "compact":
            magnitude = np.abs(coeffs.numpy()[order])  # [M, K, 3]
            tolerance += np.einsum("mk,mkc->mc", basis, HALF_ROUNDOFF * magnitude + HALF_SUBNORMAL_ERROR)
        error = np.abs(rgb - ref)[drawn]
        assert (error <= tolerance[drawn]).all(), f"worst error / tolerance {np.max(error / tolerance[drawn]):.2f}"
        worst = max(worst, float(error.max()))
        seen[order[drawn]] = True
    assert seen.mean() > 0.9
    if layout == "compact":  # the coefficients really are half floats: errors beyond float32's own
        assert worst > FLOAT32_EVAL[0]
    r.release()
