"""The loss terms computed on the render's pixels, beside the network terms of ``losses.py``: total variation (the
paper's), colour smoothness and edges kept (this project's). Each takes a render [B, 3, H, W] at its own size."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch.autograd.function import once_differentiable


def tv_loss(img: torch.Tensor, kind: str = "squared") -> torch.Tensor:
    """Total variation of ``img`` [B,3,H,W], **summed** over pixels, channels and the batch:
    Σ (Δ_x)² + Σ (Δ_y)² (``kind="squared"``, the G-Style reference; its gradient in closed form,
    ``SquaredVariation``) or Σ|Δ_x| + Σ|Δ_y| (``kind="abs"``)."""
    if kind == "squared":
        return SquaredVariation.apply(img)
    if kind == "abs":
        dx, dy = neighbour_differences(img)
        return dx.abs().sum() + dy.abs().sum()
    raise ValueError(f"tv kind must be 'squared' or 'abs', got {kind!r}")


def adjoint_differences(gx: torch.Tensor, gy: torch.Tensor) -> torch.Tensor:
    """Dₓᵀ·gx + Dᵧᵀ·gy: the gradient, with respect to the planes [..., H, W] that ``neighbour_differences`` took
    dx [..., H, W-1] and dy [..., H-1, W] of, of Σ gx·dx + Σ gy·dy. Four operators, in place on one buffer."""
    out = F.pad(gx, (1, 0))  # out[..., w] = gx[..., w-1]: +gx at the right pixel of each horizontal pair
    out[..., :, :-1].sub_(gx)  # in place on views (``-=`` on an index would add a copy back)
    out[..., 1:, :].add_(gy)
    out[..., :-1, :].sub_(gy)
    return out


class SquaredVariation(torch.autograd.Function):
    """Σ (Δ_x)² + Σ (Δ_y)² of ``img`` with its gradient in closed form, 2·(Dₓᵀ·Δ_x + Dᵧᵀ·Δ_y): twelve operators,
    forward and backward, where autograd through the slices takes twenty-three (on a GPU each is a kernel launch,
    for each view of a step)."""

    @staticmethod
    def forward(ctx, img: torch.Tensor) -> torch.Tensor:
        dx, dy = neighbour_differences(img)
        ctx.save_for_backward(dx, dy)
        return _dot(dx, dx) + _dot(dy, dy)

    @staticmethod
    @once_differentiable
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:
        dx, dy = ctx.saved_tensors
        return adjoint_differences(dx, dy).mul_(2.0 * grad)


def opponent_chroma(img: torch.Tensor) -> torch.Tensor:
    """[B, 3, H, W] RGB → [B, 2, H, W] opponent chroma r − g and (r + g)/2 − b (``style/speckle.py``'s channels)."""
    r, g, b = img[:, 0], img[:, 1], img[:, 2]
    return torch.stack([r - g, 0.5 * (r + g) - b], dim=1)


def luminance(img: torch.Tensor) -> torch.Tensor:
    """[B, 3, H, W] RGB → [B, H, W] luminance (Rec. 601 weights)."""
    return 0.299 * img[:, 0] + 0.587 * img[:, 1] + 0.114 * img[:, 2]


def neighbour_differences(planes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Differences of horizontally and vertically neighbouring pixels of ``planes`` [..., H, W]."""
    return planes[..., :, 1:] - planes[..., :, :-1], planes[..., 1:, :] - planes[..., :-1, :]


class LinearPairsMean(torch.autograd.Function):
    """The mean squared difference of neighbouring pixels of ``matrix`` [K, 3] applied to each pixel of ``img`` −
    ``target`` (both [B, 3, H, W]; ``target`` None: 0): horizontal and vertical pairs, the two means summed. With
    ``coverage`` ([H, W] in [0, 1]) each pair, its K channels summed, weighs the product of its two pixels' coverage
    (the mean is over the weight times the batch); without it the mean is over every pair, channel and image. The
    gradient is in closed form, ``matrix``ᵀ · (Dₓᵀ·2wΔ_x/nₓ + Dᵧᵀ·2wΔ_y/nᵧ): about half the operators autograd takes
    through the slices and channel stacks (each a kernel launch on a GPU, for each view of a step)."""

    @staticmethod
    def forward(ctx, img: torch.Tensor, matrix: torch.Tensor, target: torch.Tensor | None,
                coverage: torch.Tensor | None) -> torch.Tensor:
        weights = _on_device(matrix, img)[:, :, None, None]
        planes = F.conv2d(img if target is None else img - target.to(img.dtype), weights)  # [B, K, H, W]
        dx, dy = neighbour_differences(planes)
        if coverage is None:
            wdx, wdy, nx, ny = dx, dy, float(max(dx.numel(), 1)), float(max(dy.numel(), 1))
        else:
            w = torch.as_tensor(coverage, dtype=dx.dtype, device=dx.device).reshape(dx.shape[-2], dy.shape[-1])
            wx, wy = w[:, 1:] * w[:, :-1], w[1:, :] * w[:-1, :]
            eps, batch = 1e-8, dx.shape[0]
            nx, ny = (wx.sum(), wy.sum()) if batch == 1 else (wx.sum() * batch, wy.sum() * batch)
            wdx, wdy, nx, ny = dx * wx, dy * wy, nx + eps, ny + eps
        ctx.save_for_backward(weights, wdx, wdy)
        ctx.norms = (nx, ny)  # intermediates, not inputs or outputs: kept as they are
        return _dot(wdx, dx) / nx + _dot(wdy, dy) / ny

    @staticmethod
    @once_differentiable
    def backward(ctx, grad: torch.Tensor) -> tuple[torch.Tensor, None, None, None]:
        weights, wdx, wdy = ctx.saved_tensors
        nx, ny = ctx.norms
        twice = 2.0 * grad
        planes = adjoint_differences(wdx * (twice / nx), wdy * (twice / ny))
        return F.conv2d(planes, weights.transpose(0, 1)), None, None, None


def _dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Σ a·b over every element of two tensors of one shape, as one operator: both are read in ``a``'s memory order
    (a render [H, W, 3] seen as [1, 3, H, W] is channels-last; flattening it in the logical order would copy it)."""
    if a.dim() == 4 and not a.is_contiguous() and a.is_contiguous(memory_format=torch.channels_last):
        a, b = a.permute(0, 2, 3, 1), b.permute(0, 2, 3, 1)
    return torch.dot(a.reshape(-1), b.reshape(-1))


_DEVICE_COPIES: dict[tuple[int, torch.device, torch.dtype], torch.Tensor] = {}


def _on_device(matrix: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """``matrix`` (a module constant) on ``like``'s device and dtype, copied there once: on a GPU a copy from the
    CPU's memory would wait for the queue to drain on every call."""
    if matrix.device == like.device and matrix.dtype == like.dtype:
        return matrix
    key = (id(matrix), like.device, like.dtype)
    if key not in _DEVICE_COPIES:
        _DEVICE_COPIES[key] = matrix.to(device=like.device, dtype=like.dtype)
    return _DEVICE_COPIES[key]


_BASIS = torch.eye(3)[:, :, None, None]  # the three unit colours as a batch of 1-pixel images
_OPPONENT = opponent_chroma(_BASIS)[:, :, 0, 0].t().contiguous()  # [2, 3]: opponent_chroma as a matrix
_LUMINANCE = luminance(_BASIS)[:, 0, 0][None]  # [1, 3]: luminance's weights


def chroma_tv_loss(img: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
    """Colour smoothness: the mean squared difference of the opponent chroma of neighbouring pixels of ``img``
    [B, 3, H, W] (``LinearPairsMean``, weighted by ``coverage``). Luminance is left free: edges and shading carry the
    scene's structure."""
    return LinearPairsMean.apply(img, _OPPONENT, None, coverage)


def edges_loss(img: torch.Tensor, gt: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
    """Edges kept: the mean squared difference between the luminance gradients (differences of neighbouring pixels,
    horizontal and vertical) of ``img`` and of ``gt`` (its content target), both [B, 3, H, W] (``LinearPairsMean``
    on their difference, weighted by ``coverage``). The painting's colours and the texture NNFM adds may change
    everything but where the scene's light and dark edges lie and how strong they are (a gradient-domain content
    term, after Li et al.'s Laplacian-steered style transfer, 2017)."""
    return LinearPairsMean.apply(img, _LUMINANCE, gt.detach(), coverage)
