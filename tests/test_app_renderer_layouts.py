"""The renderer's compact texture layout (half-float quaternions, scales, colours, SH) against its float32 one and
the rasterizer: images, memory, scenes in any unit."""

from pathlib import Path

import numpy as np
import pytest

moderngl = pytest.importorskip("moderngl")

from synthetic import blob_scene, look_at_camera  # noqa: E402

from app.renderer import SplatRenderer  # noqa: E402
from app.renderer_views import draw_views  # noqa: E402
from app.splat_data import (  # noqa: E402
    geometry_textures,
    scale_exponent,
    scene_arrays,
)

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes"
SH_CAPTURE = DATA / "ply_3dgs" / "kacytran1122_try_iter7000_point_cloud.ply"  # 9,080 Gaussians, SH degree 3
W, H = 160, 120


def images(ctx, arrays, cams, layout, layer):
    """8-bit images (int16) of ``cams`` drawn with ``layout`` on black, stacked."""
    return np.stack(draw_views(ctx, arrays, cams, layout, layer)[0])


def psnr(image, reference):
    return 10 * np.log10(1.0 / np.mean((image / 255.0 - np.clip(reference, 0, 1)) ** 2))


@pytest.mark.skipif(not SH_CAPTURE.is_file(), reason="shared/data ply_3dgs capture with SH absent")
def test_compact_layout_draws_a_real_capture_as_the_float32_one_and_the_rasterizer(ctx):
    pytest.importorskip("torch")
    from gstyle_core.cameras.generate import generate_cameras
    from gstyle_core.io import load_scene
    from gstyle_core.scene_images import render_scene_image

    scene, _ = load_scene(SH_CAPTURE)
    assert scene.sh_degree == 3
    cams = generate_cameras(scene.means, count=3, width=W, height=H).cameras
    arrays = scene_arrays(scene)
    drawn = {(layout, layer): images(ctx, arrays, cams, layout, layer)
             for layout in ("compact", "float32") for layer in ("sh", "diffuse")}
    for layer in ("sh", "diffuse"):
        diff = np.abs(drawn["compact", layer] - drawn["float32", layer])
        # measured at 400x300 on 4 views: mean 0.03-0.04 of a level, 99.9th percentile 2, max 4
        assert diff.mean() < 0.1 and np.percentile(diff, 99.9) <= 3, (layer, diff.mean())
    for i, cam in enumerate(cams):
        reference = render_scene_image(scene, cam)
        compact, full = psnr(drawn["compact", "sh"][i], reference), psnr(drawn["float32", "sh"][i], reference)
        assert compact >= 30.0  # the viewer's agreement with the rasterizer (test_app_renderer's parity test)
        assert abs(compact - full) < 0.1  # measured: equal to 0.01 dB
    # The comparison sees a change of the size of a rounding it would hide: scales 1 % larger in float32.
    diff = np.abs(drawn["compact", "sh"] - drawn["float32", "sh"])
    bigger = dict(arrays, log_scales=arrays["log_scales"] + np.float32(np.log(1.01)))
    moved = np.abs(images(ctx, bigger, cams, "float32", "sh") - drawn["float32", "sh"])
    assert moved.mean() > 2 * diff.mean()


@pytest.mark.parametrize(("unit", "size"), [(0.02, 0.003), (1.0, 0.03), (1e7, 0.03)])
def test_compact_layout_keeps_scenes_in_any_unit(ctx, unit, size):
    """The scales are stored times the scene's power of two: a scene in small or huge units (scales of 6e-5 and
    3e5 here; half floats alone keep 11 bits only from 6.1e-5 to 65504) draws as in float32."""
    scene = blob_scene(800, seed=5, spread=0.5, scale=size)
    arrays = {"means": scene.means * np.float32(unit), "log_scales": scene.log_scales + np.float32(np.log(unit)),
              "quats": scene.quats, "opacity_logits": scene.opacity_logits, "colors": scene.rgb}
    cams = [look_at_camera(np.array(eye) * unit, (0, 0, 0), W, H) for eye in ((0.3, -0.5, -3.0), (2.5, 0.2, 1.0))]
    _, scale_unit = geometry_textures(arrays, "compact")
    assert scale_unit == 2.0 ** -scale_exponent(np.exp(arrays["log_scales"].astype(np.float64)))
    compact = images(ctx, arrays, cams, "compact", "diffuse")
    assert (compact > 0).any(-1).mean() > 0.05  # the splats are drawn (in front of the near plane)
    diff = np.abs(compact - images(ctx, arrays, cams, "float32", "diffuse"))
    assert diff.mean() < 0.05 and diff.max() <= 3


def test_scale_exponent_centres_the_scales_and_never_overflows_half_floats():
    rng = np.random.default_rng(0)
    scales = np.exp(rng.normal(np.log(3e-3), 1.0, (1000, 3)))
    k = scale_exponent(scales)
    assert 0.5 <= np.median(scales) * 2.0**k <= 2.0
    outlier = scales.copy()
    outlier[0, 0] = 1e3 * 2.0**k * 60.0  # stored as is, it would exceed 65504
    assert outlier.max() * 2.0 ** scale_exponent(outlier) <= 2.0**15
    assert scale_exponent(np.array([[np.nan, 0.0, -1.0]])) == 0  # nothing usable: unit 1


def test_gl_memory_of_the_layouts(ctx):
    """Bytes a Gaussian by part: compact geometry 32 (mean, opacity float32; quaternion, scales half), a colour
    layer 8, SH of degree 3 96; float32 64, 16 and 192. The projection's output: 40, 52 with the SH colour. 4096
    Gaussians fill one texture row exactly."""
    scene = blob_scene(4096, seed=2, sh_degree=3)
    cam = look_at_camera((0, 0, -4.0), (0, 0, 0), W, H)  # every Gaussian in front of it
    expected = {"compact": (32, 8, 96), "float32": (64, 16, 192)}
    for layout, (geometry, colours, sh) in expected.items():
        for with_sh in (True, False):
            r = SplatRenderer(ctx, layout=layout)
            arrays = scene_arrays(scene)
            if not with_sh:
                arrays.pop("sh_rest")
            r.set_scene(arrays)
            r.render(cam, ctx.framebuffer([ctx.texture((W, H), 4)]), layer="sh" if with_sh else "diffuse")
            memory = r.gl_memory()
            assert memory == {"geometry": 4096 * geometry, "colours": 4096 * colours, "sh": 4096 * sh * with_sh,
                              "projected": 4096 * (52 if with_sh else 40), "order": 4096 * 4}
            r.release()


def test_unknown_layout_is_a_clear_error(ctx):
    with pytest.raises(ValueError, match="unknown texture layout 'half'; have compact, float32"):
        SplatRenderer(ctx, layout="half")


def test_a_draw_in_chunks_is_the_same_image_as_one_draw(ctx):
    """On a software GL the splats are drawn in chunks (each waiting for the one before it, which bounds
    llvmpipe's binned scenes in flight); the chunks blend in the same order, so the image is the same."""
    from app.gl_io import is_software_gl, read_rgb_float
    from app.renderer import SOFTWARE_DRAW_CHUNK

    scene = blob_scene(3000, seed=8, spread=0.5, scale=0.04)
    r = SplatRenderer(ctx)
    assert r.draw_chunk == (SOFTWARE_DRAW_CHUNK if is_software_gl(ctx) else 0)
    r.set_scene(scene_arrays(scene))
    cam = look_at_camera((0.3, -0.8, -3.0), (0, 0, 0), W, H)
    pictures = {}
    for chunk in (0, 1000, 2999, 7):
        r.draw_chunk = chunk
        fbo = ctx.framebuffer([ctx.texture((W, H), 4, dtype="f4")])
        r.render(cam, fbo, (0.1, 0.2, 0.3))
        pictures[chunk] = read_rgb_float(fbo)
        fbo.release()
    for chunk in (1000, 2999, 7):
        np.testing.assert_array_equal(pictures[chunk], pictures[0])
    r.release()
