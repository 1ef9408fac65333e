"""The VGG-16 relu3 features as the loss terms take them: the layers' stack, unit vectors, the scene's coverage per
feature position and a mean weighted by it, and the input sizes the network needs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
import torch.nn.functional as F

from .vgg import FEATURE_LAYERS

NORM_EPS = 1e-8
MIN_VGG_SIDE = 4  # relu3_x follow two 2x poolings: a smaller input has no feature vector (VGG raises)


def concat_features(feats: Mapping[str, torch.Tensor] | Sequence[torch.Tensor] | torch.Tensor) -> torch.Tensor:
    """relu3_1|relu3_2|relu3_3 concatenated along channels → [B, 768, h, w]. A tensor is returned as is."""
    if isinstance(feats, torch.Tensor):
        return feats
    if isinstance(feats, Mapping):
        feats = [feats[name] for name in FEATURE_LAYERS]
    return torch.cat(list(feats), dim=1)


def stacked_features(vgg, img: torch.Tensor) -> torch.Tensor:
    """``vgg``'s relu3 features of ``img`` stacked along channels ([B, 768, h, w], :func:`concat_features`): the
    network's own ``stacked`` where it has one (one cast for the stack), else the stack of its features."""
    stacked = getattr(vgg, "stacked", None)
    return stacked(img) if stacked is not None else concat_features(vgg(img))


def normalise_vectors(x: torch.Tensor, dim: int) -> torch.Tensor:
    """Unit vectors along ``dim``; zero vectors stay (finite) zero vectors."""
    return x / ((x * x).sum(dim, keepdim=True) + NORM_EPS).sqrt()


def vector_norms(x: torch.Tensor) -> torch.Tensor:
    """The lengths of the rows of ``x`` [N, C] as :func:`normalise_vectors` divides by them (its ε included): [N]."""
    return ((x * x).sum(1) + NORM_EPS).sqrt()


def feature_weights(coverage: torch.Tensor | None, size: tuple[int, int] | torch.Size) -> torch.Tensor | None:
    """The scene's coverage (rendered alpha, [H,W], [1,H,W] or [B,1,H,W] in [0, 1]) averaged over each cell of a
    feature grid of ``size`` (h, w) → [B,1,h,w] weights; None stays None (every feature vector counts fully)."""
    if coverage is None:
        return None
    c = torch.as_tensor(coverage, dtype=torch.float32)
    c = c.reshape((1, 1) + tuple(c.shape[-2:])) if c.ndim < 4 else c
    return F.adaptive_avg_pool2d(c, tuple(size)).clamp(0.0, 1.0)


def weighted_mean(values: torch.Tensor, weights: torch.Tensor | None) -> torch.Tensor:
    """Mean of ``values`` [B,...,h,w] weighted per feature position by ``weights`` [B,1,h,w] (None: plain mean).
    All-zero weights give 0 (nothing of the scene in view: nothing to match)."""
    if weights is None:
        return values.mean()
    w = weights.reshape(weights.shape[0], *([1] * (values.ndim - 3)), *weights.shape[-2:]).expand_as(values)
    return (values * w).sum() / w.sum().clamp_min(NORM_EPS)


def vgg_input_size(size: tuple[int, int] | torch.Size) -> tuple[int, int]:
    """``size`` (h, w) with each side raised to at least ``MIN_VGG_SIDE``."""
    return max(int(size[0]), MIN_VGG_SIDE), max(int(size[1]), MIN_VGG_SIDE)


def upsample_for_vgg(img: torch.Tensor) -> torch.Tensor:
    """A render with a side below ``MIN_VGG_SIDE`` px stretched (bilinear) to that size; others as they are."""
    size = vgg_input_size(img.shape[-2:])
    if size == tuple(img.shape[-2:]):
        return img
    return F.interpolate(img, size=size, mode="bilinear", align_corners=False)


def resize_to_width(img: torch.Tensor, width: int | None) -> torch.Tensor:
    """Bilinear (antialiased) resize so the width is ``width`` px, keeping the aspect ratio (None: as is)."""
    if width is None or img.shape[-1] == width:
        return img
    height = max(1, round(img.shape[-2] * width / img.shape[-1]))
    return F.interpolate(img, size=(height, width), mode="bilinear", align_corners=False,
                         antialias=width < img.shape[-1])
