"""The coarse-scale stand-in for the CLIP term when no CLIP weights are available.

``CoarseStyleLoss``, labelled "coarse-VGG substitute (no CLIP weights)": CLIP carries the low-frequency part of the
style (large patterns, overall palette layout). Without it we match AdaIN-style statistics (per-channel mean and
standard deviation) of VGG relu3_1…relu3_3 features of the render and of the style image, both downsampled 4x
first so the receptive field of relu3 (40 px) covers about 160 px of the original image; the error is relative
(scale-free, about 0…1 like the CLIP distance) so the same λ_CLIP applies. The render's statistics are taken over
the scene only, weighted by its coverage (rendered alpha) when the caller gives it: an object on an empty background
would otherwise be pushed to make background and object together look like the painting. It is not CLIP, only a
substitute for the coarse scale.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
import torch.nn.functional as F
from torch import nn

from .paintings import as_batch, checked_style_weights, style_list

COARSE_LABEL = "coarse-VGG substitute (no CLIP weights)"


def position_weights(grid: torch.Tensor) -> torch.Tensor:
    """A feature grid's coverage weights [B, 1, h, w] as [B, 1, h*w] summing to 1 per image; an image without any
    coverage weighs every position alike. Decided on the device: reading the sum would wait for a GPU's queue."""
    flat = grid.flatten(2)
    total = flat.sum(-1, keepdim=True)
    return torch.where(total > 0, flat / total.clamp_min(torch.finfo(flat.dtype).tiny), 1.0 / flat.shape[-1])


class CoarseStyleLoss(nn.Module):
    """Stand-in for the CLIP term: mean/std statistics of VGG relu3_x features at a coarse scale.

    Per layer: (‖μ_r − μ_s‖² + ‖σ_r − σ_s‖²) / (‖μ_s‖² + ‖σ_s‖²), the relative error of the per-channel
    statistics, averaged over the three layers. Being relative, it does not depend on the feature scale of
    the VGG weights and lies in the same range as the CLIP distance (0 for a perfect match, ~1 for unrelated
    statistics), so λ_CLIP can be kept."""

    network = "vgg"
    passes = 1  # network passes a call takes
    takes_coverage = True
    label = COARSE_LABEL

    def __init__(self, vgg: Callable[[torch.Tensor], dict[str, torch.Tensor]],
                 style_image: torch.Tensor | Sequence[torch.Tensor], downsample: int = 4,
                 style_weights: Sequence[float] | None = None) -> None:
        super().__init__()
        self.vgg = vgg
        self.downsample = downsample
        self.styles_stats = []  # per painting: {layer: (mean, std)}
        with torch.no_grad():
            for style in style_list(style_image):
                stats = self._statistics(as_batch(style))
                self.styles_stats.append({name: (m.detach(), s.detach()) for name, (m, s) in stats.items()})
        self.set_style_weights(style_weights)

    def set_style_weights(self, weights: Sequence[float] | None) -> None:
        """Weights of the paintings (None: one painting, weight 1)."""
        self.style_weights = checked_style_weights(weights, len(self.styles_stats))

    def _statistics(self, img: torch.Tensor, coverage: torch.Tensor | None = None
                    ) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        from .features import feature_weights

        height, width = img.shape[-2:]
        size = (max(16, height // self.downsample), max(16, width // self.downsample))
        small = F.interpolate(img, size=size, mode="bilinear", align_corners=False, antialias=True)
        feats = self.vgg(small)
        out = {}
        grids: dict[tuple[int, ...], torch.Tensor] = {}  # the relu3 layers share one grid: its weights made once
        for name, f in feats.items():
            flat = f.flatten(2)  # [B, C, h*w]
            if coverage is None:
                out[name] = (flat.mean(-1), (flat.var(-1, unbiased=False) + 1e-8).sqrt())
                continue
            if tuple(f.shape[-2:]) not in grids:
                grids[tuple(f.shape[-2:])] = position_weights(feature_weights(coverage, f.shape[-2:]))
            w = grids[tuple(f.shape[-2:])]
            mean = (flat * w).sum(-1)
            var = (((flat - mean[..., None]) ** 2) * w).sum(-1)
            out[name] = (mean, (var + 1e-8).sqrt())
        return out

    def forward(self, render: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
        """Relative error of the render's feature statistics (over the scene: ``coverage`` [H,W] or [B,1,H,W]
        weights each position; None: the whole frame) against the style image's (several: weighted sum); a batch:
        the mean of its renders' errors."""
        return self.per_image(as_batch(render), coverage).mean()

    def per_image(self, renders: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
        """The error of each of a batch of renders [B, 3, H, W], [B] (what ``forward`` gives for each alone), the
        batch through the network in one pass. ``coverage``: [H, W] (all alike), [B, H, W] or [B, 1, H, W], or None."""
        if coverage is not None and coverage.ndim == 3:
            coverage = coverage[:, None]
        render_stats = self._statistics(renders, coverage)
        per_style = []
        for weight, style_stats in zip(self.style_weights, self.styles_stats, strict=True):
            if weight <= 0:
                continue
            terms = []
            for name, (mean, std) in render_stats.items():
                style_mean, style_std = style_stats[name]
                error = ((mean - style_mean) ** 2).sum(-1) + ((std - style_std) ** 2).sum(-1)  # [B]
                scale = (style_mean**2).sum(-1) + (style_std**2).sum(-1) + 1e-8
                terms.append(error / scale)
            per_style.append(weight * torch.stack(terms).mean(0))
        return torch.stack(per_style).sum(0)
