"""The GPU rasterizer (gsplat's kernels behind our projection) against the CPU one: the twin test.

The CUDA tests run where torch sees a CUDA device and gsplat is installed (``bench/gpu_check.sh`` runs them on a GPU
machine); elsewhere they skip saying so. On the CPU, gsplat's own pure-torch projection (``gsplat/cuda/
_torch_impl.py``) checks that ours follows gsplat's conventions (pixel centres, field-of-view clamp, dilation), so
that the GPU path, which blends our projection with gsplat's kernels, is consistent with both.

Tolerances: images within 1e-3 (the blends are float32 on both, in another order) except where a Gaussian's alpha
sits at the 1/255 cut-off, which one side keeps and the other skips (measured on an H200: 3 of 23,040 values of
one scene, at most 0.003; mean difference below 1e-6): at most 0.05 % of the values may differ by more, never by
more than two such Gaussians (2/255); colour gradients cosine
>= 0.999; geometry gradients (means, quats, scales, opacities) cosine >= 0.99 and relative L2 error <= 5e-2 (they
run through float32 kernels summing per-pixel contributions in another order, and the CPU's square radius and the
GPU's fast-math exponentials differ in the last bits). The scenes keep opacities below 0.99, where the two alpha
clamps (0.99 on the CPU, gsplat's 0.999) do not differ (``gsplat_backend.py``).
"""

from __future__ import annotations

import importlib.util

import pytest
import torch

from gstyle_core.device import DEVICES, DeviceUnavailable, resolve_device
from gstyle_core.raster import ColourCache, rasterize
from gstyle_core.raster.projection import covariance_3d, project_gaussians
from gstyle_core.raster.synthetic import random_scene

HAS_GSPLAT = importlib.util.find_spec("gsplat") is not None
CUDA = torch.cuda.is_available()
needs_cuda = pytest.mark.skipif(not (CUDA and HAS_GSPLAT), reason="needs a CUDA device and gsplat (GPU machine: "
                                                                  "bench/gpu_check.sh runs these)")
needs_gsplat = pytest.mark.skipif(not HAS_GSPLAT, reason="gsplat is not installed (pip install gsplat==1.5.3)")


def _cosine(a: torch.Tensor, b: torch.Tensor) -> float:
    a, b = a.double().flatten(), b.double().flatten()
    return float(a @ b / (a.norm() * b.norm()).clamp_min(1e-30))


def _relative(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a.double() - b.double()).norm() / b.double().norm().clamp_min(1e-30))


def _render_with_grads(scene, device: str, weights: torch.Tensor):
    leaves = [p.detach().to(device).requires_grad_(True) for p in scene.params()]
    out = rasterize(*leaves, scene.viewmat.to(device), scene.K.to(device), scene.width, scene.height)
    (out.image * weights.to(device)).sum().backward()
    return out, [p.grad.cpu() for p in leaves]


@needs_cuda
@pytest.mark.parametrize("seed,n,size", [(0, 400, (96, 80)), (1, 3000, (160, 120)), (2, 50, (33, 47))])
def test_gsplat_and_numba_rasterizers_agree(seed, n, size):
    scene = random_scene(n, *size, seed=seed)
    weights = torch.rand(size[1], size[0], 3, generator=torch.Generator().manual_seed(seed))
    cpu, cpu_grads = _render_with_grads(scene, "cpu", weights)
    gpu, gpu_grads = _render_with_grads(scene, "cuda", weights)
    assert gpu.image.is_cuda and gpu.stats["backend"] == "gsplat"
    assert torch.equal(cpu.visible, gpu.visible.cpu())
    for ours, theirs in ((gpu.image, cpu.image), (gpu.alpha, cpu.alpha)):
        diff = (ours.detach().cpu() - theirs.detach()).abs()
        assert diff.mean() <= 1e-5
        assert int((diff > 1e-3).sum()) <= 5e-4 * diff.numel()
        assert diff.max() <= 2 / 255
    names = ["means", "quats", "scales", "opacities", "colors"]
    for name, g_cpu, g_gpu in zip(names, cpu_grads, gpu_grads, strict=True):
        if name == "colors":
            assert _cosine(g_gpu, g_cpu) >= 0.999, name
        else:
            assert _cosine(g_gpu, g_cpu) >= 0.99, name
            assert _relative(g_gpu, g_cpu) <= 5e-2, name


@needs_cuda
def test_gsplat_colour_cache_matches_the_sparse_one():
    from gstyle_core.raster.gsplat_backend import GsplatColourCache

    scene = random_scene(2000, 128, 96, seed=3)
    geometry = (scene.means, scene.quats, scene.scales, scene.opacities, scene.viewmat, scene.K, 128, 96)
    cpu_cache = ColourCache(*geometry, geometry_version=0)
    gpu_cache = GsplatColourCache(*geometry, geometry_version=0, device="cuda")
    colours = scene.colors.clone().requires_grad_(True)
    weights = torch.rand(96, 128, 3, generator=torch.Generator().manual_seed(4))
    (cpu_cache.render(colours) * weights).sum().backward()
    cpu_grad, colours.grad = colours.grad.clone(), None
    gpu_image = gpu_cache.render(colours)  # CPU colours in, gradients back to them
    (gpu_image * weights.cuda()).sum().backward()
    assert gpu_image.is_cuda
    for ours, theirs in ((gpu_image.detach().cpu(), cpu_cache.render(scene.colors)),
                         (gpu_cache.t_final, cpu_cache.t_final)):
        diff = (ours - theirs.detach()).abs()
        assert diff.mean() <= 1e-5 and int((diff > 1e-3).sum()) <= 5e-4 * diff.numel() and diff.max() <= 2 / 255
    assert _cosine(colours.grad, cpu_grad) >= 0.999


@needs_cuda
def test_a_cuda_run_stylizes_on_the_gpu(tmp_path):
    from gstyle_core.engine.build import SETTING_OPTIONS, BuildRequest, build_stylizer

    overrides = dict.fromkeys(SETTING_OPTIONS)
    overrides.update(device="cuda", working_width=64)
    engine = build_stylizer(BuildRequest(preset="preview", overrides=overrides)).engine
    assert engine.run_state.raster_device.type == "cuda"
    assert engine.decisions["device"].startswith("cuda")
    for _ in range(400):
        if engine.done:
            break
        engine.step()
    assert torch.isfinite(engine.run_state.c_s).all()


@needs_gsplat
def test_our_projection_follows_gsplats_torch_reference():
    """Our torch projection against gsplat's pure-torch one (float64): the same means2d, depths and conics."""
    from gsplat.cuda._torch_impl import _fully_fused_projection

    scene = random_scene(500, 120, 90, seed=5, dtype=torch.float64)
    scene.K[0, 2] += 7.5  # an off-centre principal point: the clamp's asymmetric limits
    ours = project_gaussians(scene.means, scene.quats, scene.scales, scene.viewmat, scene.K, 120, 90)
    covars = covariance_3d(scene.quats, scene.scales)
    radii, means2d, depths, conics, _ = _fully_fused_projection(
        scene.means, covars, scene.viewmat[None], scene.K[None], 120, 90, eps2d=0.3)
    both = ours.visible & (radii[0] > 0).all(-1)
    assert int(both.sum()) > 400
    torch.testing.assert_close(ours.means2d[both], means2d[0][both], rtol=1e-9, atol=1e-9)
    torch.testing.assert_close(ours.depths[both], depths[0][both], rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(ours.conics[both], conics[0][both], rtol=1e-7, atol=1e-9)


def test_auto_resolves_to_cuda_only_where_torch_sees_it():
    choice = resolve_device("auto")
    assert choice.kind == ("cuda" if CUDA else "cpu")
    assert "auto" in choice.reason
    assert resolve_device("cpu").kind == "cpu"
    assert set(DEVICES) == {"auto", "cpu", "cuda", "mps"}


@pytest.mark.skipif(CUDA, reason="this machine has CUDA")
def test_asking_for_cuda_without_it_says_so():
    with pytest.raises(DeviceUnavailable, match="sees no CUDA device"):
        resolve_device("cuda")


def test_an_unknown_device_is_refused():
    with pytest.raises(ValueError, match="device must be one of"):
        resolve_device("tpu")


def test_the_gsplat_backend_refuses_cpu_tensors():
    scene = random_scene(10)
    with pytest.raises(ValueError, match="float32 tensors on a CUDA device"):
        rasterize(*scene.params(), scene.viewmat, scene.K, 64, 64, backend="gsplat")


@pytest.mark.skipif(CUDA, reason="this machine has CUDA")
def test_gsplat_module_needs_cuda():
    from gstyle_core.raster.gsplat_module import GsplatUnavailable, ensure_gsplat

    with pytest.raises(GsplatUnavailable, match="no CUDA device"):
        ensure_gsplat(log=lambda line: None)


@needs_gsplat
def test_the_built_module_is_kept_per_torch_cuda_gsplat_and_card(monkeypatch, tmp_path):
    from gstyle_core.raster.gsplat_module import built_module_path

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path))
    monkeypatch.delenv("GSTYLE_GSPLAT_MODULE", raising=False)
    path = built_module_path(arch="9.0")
    assert path.parent.parent == tmp_path / "gsplat" and path.name == "gsplat_cuda.so"
    assert "sm90" in path.parent.name and "+" not in path.parent.name
    monkeypatch.setenv("GSTYLE_GSPLAT_MODULE", str(tmp_path / "mine.so"))
    assert built_module_path(arch="9.0") == tmp_path / "mine.so"
