"""A multi-scale style term for when CLIP cannot run: the painting's patterns matched at coarser scales.

The NNFM term compares VGG relu3_x features of the render with the painting's (``nnfm.py``). A relu3 feature sees
about 40 px, so at the working width it matches brush marks a few pixels wide, and its gradient reaches the pixels
through the full-resolution convolutions: the colour updates it asks for are fine-grained. This term runs the same
network on the render and on the painting both **downsampled** by each factor of ``factors`` (default ×2, ×4 and
×8, antialiased bilinear): at ×4 a relu3 feature sees ~160 px of the render and of the painting at its matched size,
at ×8 ~320 px (the whole painting at stroke size 1), so broad strokes and large shapes are compared, and the gradient
comes back through the downsampling's adjoint (a smooth upsampling), i.e. as a coarse colour change. Both sides are
resized by the same factor, so the stroke size (the painting's matched size) means the same at every level.

Why ×8 as well (docs/notes/texture-scale.md, 9 scene × painting pairs, preview): against ×2 and ×4 alone it kept more of
the scene (structure higher on all nine, +0.00 to +0.07) with the coarse share as high or higher on seven, for ≤ 1.1
points of NNFM drop: each level weighs a third instead of a half, so the ×2 level pulls less on mid-size detail.

Loss: the mean over levels of the NNFM distance (mean over the render's feature vectors of 1 − cos to the nearest
painting vector, coverage-weighted like the NNFM term), so its λ is on the NNFM term's scale. Several paintings:
Σ w_i · NNFM_i at each level (``nnfm.WeightedTargets``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
import torch.nn.functional as F
from torch import nn

from .features import feature_weights, stacked_features, upsample_for_vgg, vgg_input_size
from .nnfm import StyleTarget, WeightedTargets, style_nnfm, style_nnfm_per_image

DEFAULT_FACTORS = (2, 4, 8)  # read when a term is built without factors (benches may set it)


def downsample(img: torch.Tensor, factor: float) -> torch.Tensor:
    """``img`` [B, C, H, W] shrunk by ``factor`` (antialiased bilinear; each side at least 1 px)."""
    if factor == 1:
        return img
    size = (max(1, round(img.shape[-2] / factor)), max(1, round(img.shape[-1] / factor)))
    return F.interpolate(img, size=size, mode="bilinear", align_corners=False, antialias=True)


class MultiScaleStyleLoss(nn.Module):
    """NNFM between the render and the painting(s), both downsampled by each of ``factors``.

    ``paintings``: [1, 3, H, W] RGB in [0, 1], each already at its matched size (stroke size × working width, as the
    NNFM target is built); ``style_weights``: one per painting (None: one painting, or equal shares).
    ``forward(render [1, 3, H, W], coverage [H, W] | None)`` returns the scalar loss; ``last_levels`` holds each
    level's distance of the last call (for logs)."""

    network = "vgg"
    takes_coverage = True

    def __init__(self, vgg: nn.Module, paintings: Sequence[torch.Tensor] | torch.Tensor,
                 factors: Sequence[float] | None = None, style_weights: Sequence[float] | None = None,
                 chunk: int = 4096) -> None:
        super().__init__()
        paintings = [paintings] if isinstance(paintings, torch.Tensor) else list(paintings)
        factors = DEFAULT_FACTORS if factors is None else factors
        if not paintings:
            raise ValueError("the multi-scale term needs at least one painting")
        factors = tuple(float(f) for f in factors)
        if not factors or any(not f >= 1 for f in factors):
            raise ValueError(f"downsampling factors must be 1 or more, got {factors}")
        if style_weights is None:
            style_weights = [1.0 / len(paintings)] * len(paintings)
        if len(style_weights) != len(paintings):
            raise ValueError(f"{len(style_weights)} weight(s) for {len(paintings)} painting(s)")
        self.vgg = vgg
        self.factors = factors
        self._paintings = paintings
        self._style_weights = tuple(float(w) for w in style_weights)
        self.chunk = chunk
        self.targets: list[StyleTarget | WeightedTargets] = []
        for f in factors:
            per_painting = [StyleTarget.from_image(vgg, upsample_for_vgg(downsample(p, f))) for p in paintings]
            self.targets.append(per_painting[0] if len(per_painting) == 1
                                else WeightedTargets(per_painting, style_weights))
        self.last_levels: dict[float, torch.Tensor] = {}

    @property
    def passes(self) -> int:
        """Network passes a call takes (one a level)."""
        return len(self.factors)

    def with_factors(self, factors: Sequence[float]) -> MultiScaleStyleLoss:
        """The same term (network, paintings, mix weights) at other downsampling ``factors``."""
        return MultiScaleStyleLoss(self.vgg, self._paintings, factors=factors, style_weights=self._style_weights,
                                   chunk=self.chunk)

    def set_style_weights(self, weights: Sequence[float]) -> None:
        """Re-weight the paintings of a mix (nothing is re-extracted)."""
        self._style_weights = tuple(float(w) for w in weights)
        for target in self.targets:
            if isinstance(target, WeightedTargets):
                target.weights = self._style_weights

    def _level_features(self, renders: torch.Tensor, factor: float) -> torch.Tensor:
        """The stacked relu3 features of ``renders`` downsampled by ``factor`` (stretched to VGG's minimum size)."""
        small = downsample(renders, factor)
        if tuple(small.shape[-2:]) != vgg_input_size(small.shape[-2:]):
            small = upsample_for_vgg(small)
        return stacked_features(self.vgg, small)

    def _levels(self, renders: torch.Tensor, coverage: torch.Tensor | None, distance: Callable) -> torch.Tensor:
        """Each level's ``distance`` (``style_nnfm`` or ``style_nnfm_per_image``) of ``renders`` to its target,
        stacked; ``last_levels`` keeps each one's value (over the batch)."""
        if renders.ndim != 4 or renders.shape[1] != 3:
            raise ValueError(f"renders must be [B, 3, H, W], got {tuple(renders.shape)}")
        levels = []
        for factor, target in zip(self.factors, self.targets, strict=True):
            feats = self._level_features(renders, factor)
            d = distance(feats, target, self.chunk, weights=feature_weights(coverage, feats.shape[-2:]))
            # a tensor: reading it here would wait for the GPU
            self.last_levels[factor] = d.detach() if d.ndim == 0 else d.detach().mean()
            levels.append(d)
        return torch.stack(levels)

    def forward(self, render: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
        return self._levels(render, coverage, style_nnfm).mean()

    def per_image(self, renders: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
        """The term of each of a batch of renders of one size, [B] (what ``forward`` gives for each alone), every
        level through the network once for the whole batch (on a GPU: a quarter of the kernel launches for four
        views). ``coverage``: [B, H, W] or [B, 1, H, W], or None."""
        if coverage is not None and coverage.ndim == 3:
            coverage = coverage[:, None]
        return self._levels(renders, coverage, style_nnfm_per_image).mean(0)
