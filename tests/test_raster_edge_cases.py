"""Edge cases and hostile inputs: culling, empty scenes, tiny images, extreme scales and quaternions."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.raster import rasterize
from gstyle_core.raster.synthetic import random_scene

BACKENDS = ("fast", "reference")


def _single(z: float, scale: float = 0.1, opacity: float = 0.8):
    """One Gaussian on the optical axis shifted so that it projects onto the centre of pixel (16, 16)."""
    means = torch.tensor([[0.5 * z / 40.0, 0.5 * z / 40.0, z]])
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]])
    scales = torch.full((1, 3), scale)
    return [means, quats, scales, torch.tensor([opacity]), torch.tensor([[0.9, 0.4, 0.1]])]


CAMERA = (torch.eye(4), torch.tensor([[40.0, 0, 16], [0, 40.0, 16], [0, 0, 1]]))


def _render(params, backend, size=32, **kw):
    return rasterize(*params, *CAMERA, size, size, backend=backend, **kw)


def _finite_backward(out, params):
    for p in params:
        p.grad = None
    (out.image.sum() + out.alpha.sum() + out.depth.sum()).backward()
    for p in params:
        assert p.grad is not None and torch.isfinite(p.grad).all()


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("z", [-1.0, 0.0, 0.01])  # behind, on the camera plane, on the near plane
def test_gaussians_behind_or_on_near_plane_are_culled(backend, z):
    params = [p.requires_grad_(True) for p in _single(z)]
    out = _render(params, backend, background=torch.tensor([0.1, 0.2, 0.3]))
    assert not out.visible.any() and int(out.radii[0]) == 0
    assert torch.allclose(out.image, torch.tensor([0.1, 0.2, 0.3]).expand(32, 32, 3))
    assert (out.alpha == 0).all() and (out.depth == 0).all()
    _finite_backward(out, params)


@pytest.mark.parametrize("backend", BACKENDS)
def test_gaussian_covering_the_whole_screen(backend):
    params = [p.requires_grad_(True) for p in _single(4.0, scale=20.0, opacity=0.7)]
    out = _render(params, backend)
    assert out.visible.all() and out.stats["tile_pairs"] == out.stats["tiles"]
    assert torch.allclose(out.alpha, torch.full((32, 32), 0.7), atol=0.01)  # sigma = 200 px
    assert torch.allclose(out.depth, torch.full((32, 32), 4.0), atol=1e-4)
    _finite_backward(out, params)


@pytest.mark.parametrize("backend", BACKENDS)
def test_opacity_zero_and_one(backend):
    zero = [p.requires_grad_(True) for p in _single(4.0, opacity=0.0)]
    out = _render(zero, backend)
    assert (out.image == 0).all() and (out.alpha == 0).all()
    _finite_backward(out, zero)
    one = [p.requires_grad_(True) for p in _single(4.0, opacity=1.0)]
    out = _render(one, backend)
    assert abs(float(out.alpha.detach().max()) - 0.99) < 1e-6  # the 3DGS clamp
    _finite_backward(out, one)


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_gaussians(backend):
    params = [torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, 3)]
    params = [p.requires_grad_(True) for p in params]
    bg = torch.tensor([0.5, 0.25, 1.0], requires_grad=True)
    out = _render(params, backend, background=bg)
    assert out.image.shape == (32, 32, 3) and out.means2d.shape == (0, 2) and out.radii.shape == (0,)
    assert torch.allclose(out.image, bg.detach().expand(32, 32, 3)) and (out.alpha == 0).all()
    out.image.sum().backward()
    assert torch.allclose(bg.grad, torch.full((3,), 32.0 * 32.0))


def test_one_by_one_image_matches_reference():
    scene = random_scene(50, width=1, height=1, seed=4, spread=0.05)
    outs = [rasterize(*scene.params(), scene.viewmat, scene.K, 1, 1, backend=b) for b in BACKENDS]
    assert outs[0].image.shape == (1, 1, 3) and float(outs[0].alpha.detach()) > 0
    assert torch.allclose(outs[0].image, outs[1].image, atol=1e-5)


@pytest.mark.parametrize("backend", BACKENDS)
def test_hostile_inputs_stay_finite(backend):
    scene = random_scene(40, width=24, height=24, seed=9)
    scene.scales[:10] = 1e-8
    scene.scales[10:20] = 1e4
    scene.scales[20, 0] = 1e-8  # needle: one tiny axis, one huge
    scene.scales[20, 1] = 1e4
    scene.quats[20:30] = 1e-30
    scene.quats[30] = 0.0
    scene.means[35] = torch.tensor([0.0, 0.0, 0.0100001])  # just past the near plane
    scene.requires_grad_()
    out = rasterize(*scene.params(), scene.viewmat, scene.K, 24, 24, backend=backend)
    for t in (out.image, out.alpha, out.depth, out.means2d):
        assert torch.isfinite(t).all()
    _finite_backward(out, scene.params())


@pytest.mark.parametrize("backend", BACKENDS)
def test_thousands_stacked_on_one_pixel(backend):
    n = 2000
    g = torch.Generator().manual_seed(0)
    params = [
        torch.tensor([0.0, 0.0, 4.0]) + 1e-4 * torch.randn(n, 3, generator=g),
        torch.randn(n, 4, generator=g),
        torch.full((n, 3), 0.002),
        torch.rand(n, generator=g),
        torch.rand(n, 3, generator=g),
    ]
    params = [p.requires_grad_(True) for p in params]
    out = _render(params, backend)
    assert torch.isfinite(out.image).all() and float(out.alpha.detach().max()) > 0.99
    _finite_backward(out, params)


def test_fast_backend_accepts_float64():
    scene = random_scene(30, width=16, height=16, seed=1, dtype=torch.float64).requires_grad_()
    out = rasterize(*scene.params(), scene.viewmat, scene.K, 16, 16, backend="fast")
    assert out.image.dtype == torch.float64
    out.image.sum().backward()
    assert scene.means.grad.dtype == torch.float64 and torch.isfinite(scene.means.grad).all()


def test_bad_arguments_give_clear_errors():
    scene = random_scene(5)
    args = scene.params()
    with pytest.raises(ValueError, match="quats"):
        rasterize(args[0], args[1][:, :3], *args[2:], scene.viewmat, scene.K, 8, 8)
    with pytest.raises(ValueError, match="backend"):
        rasterize(*args, scene.viewmat, scene.K, 8, 8, backend="cuda")
    with pytest.raises(ValueError, match="image size"):
        rasterize(*args, scene.viewmat, scene.K, 0, 8)
    with pytest.raises(ValueError, match="sh_degree"):
        rasterize(*args, scene.viewmat, scene.K, 8, 8, sh_degree=2)
