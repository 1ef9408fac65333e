"""The numba projection (float32, both backends) against its torch twin: outputs and gradients."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.raster.projection import project_gaussians
from gstyle_core.raster.projection_kernels import project_gaussians_fast
from gstyle_core.raster.synthetic import random_scene
from tests.test_stability_raster import HARD, SIZE, _scene

# Tolerances from float32 rounding (one ulp = eps = 2^-23 relative; each operation rounds by half of it). An output is
# a chain of about 40 float32 operations (quaternion -> rotation -> 3D covariance -> Jacobian -> 2D covariance and
# dilation -> 2x2 inverse); the torch twin rounds in another order (and a float64 twin not at all), so elementwise the
# two differ by at most ~40 half-ulps, less in relative L2. Gradients run the chain backwards and add the three
# outputs' parts: four times that. Measured on an AVX-512 CPU: outputs <= 1.1 ulps (conics, float32 twin), gradients
# <= 2.6 ulps (quats); a 1e-5 relative error in the kernels' outputs fails.
EPS = torch.finfo(torch.float32).eps
OUTPUT_RTOL, GRAD_RTOL = 32 * EPS, 128 * EPS


def _project_and_grads(fn, means, quats, scales, viewmat, K, width, height, dtype):
    leaves = [t.detach().to(dtype).clone().requires_grad_(True) for t in (means, quats, scales)]
    proj = fn(*leaves, viewmat.to(dtype), K.to(dtype), width, height)
    g = torch.Generator().manual_seed(3)
    vis = proj.visible.to(dtype)

    def weights(shape):  # the same numbers for both dtypes
        return torch.randn(shape, generator=g).to(dtype)

    loss = (
        (proj.means2d * weights(proj.means2d.shape) * vis[:, None]).sum()
        + (proj.conics * weights(proj.conics.shape) * vis[:, None]).sum()
        + (proj.depths * weights(proj.depths.shape) * vis).sum()
    )
    loss.backward()
    return proj, [leaf.grad for leaf in leaves]


def _relative(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a.double() - b.double()).norm() / b.double().norm().clamp_min(1e-300))


def _compare(means, quats, scales, viewmat, K, width, height, reference_dtype):
    fast, g_fast = _project_and_grads(project_gaussians_fast, means, quats, scales, viewmat, K, width, height,
                                      torch.float32)
    ref, g_ref = _project_and_grads(project_gaussians, means, quats, scales, viewmat, K, width, height,
                                    reference_dtype)
    assert torch.equal(fast.visible, ref.visible)
    vis = ref.visible
    assert torch.equal(fast.radii, ref.radii)
    assert torch.equal(fast.tile_min[vis], ref.tile_min[vis]) and torch.equal(fast.tile_max[vis], ref.tile_max[vis])
    assert (fast.tiles_x, fast.tiles_y) == (ref.tiles_x, ref.tiles_y)
    assert bool((fast.means2d.detach()[~vis] == 0).all())
    for name in ("means2d", "conics", "depths"):
        a, b = getattr(fast, name).detach()[vis], getattr(ref, name).detach()[vis]
        assert _relative(a, b) <= OUTPUT_RTOL, (name, _relative(a, b))
    for name, a, b in zip(("means", "quats", "scales"), g_fast, g_ref, strict=True):
        assert torch.isfinite(a).all(), name
        assert _relative(a, b) <= GRAD_RTOL, (name, _relative(a, b))


def test_projection_kernels_match_torch_twin_in_float32():
    scene = random_scene(500, width=50, height=37, seed=4, spread=1.5)
    _compare(scene.means, scene.quats, scene.scales, scene.viewmat, scene.K, 50, 37, torch.float32)


@pytest.mark.parametrize("case", list(HARD))
def test_projection_kernels_match_float64_twin_on_hard_inputs(case):
    p = _scene()
    HARD[case](p)
    p = {k: v.to(torch.float32).to(torch.float64) for k, v in p.items()}
    _compare(p["means"], p["quats"], p["scales"], p["viewmat"], p["K"], SIZE, SIZE, torch.float64)
