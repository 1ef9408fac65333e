"""G-Style pre-processing: split "flat" (large-area) Gaussians and clamp elongated ones, then refit.

- Area of a Gaussian: product of its two largest scales. A Gaussian is flat when its area exceeds
  mean(area) + γ·std(area); at most ``cap`` (a fraction) of the Gaussians, the largest, are split per round.
- Elongation: largest scale / second largest. Above the limit (1.5) the largest becomes the mean of the two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..fit.strategy import StepInfo, Strategy


def gaussian_areas(log_scales: torch.Tensor) -> torch.Tensor:
    """Product of the two largest scales of each Gaussian, [N]."""
    top2 = torch.topk(log_scales.detach(), 2, dim=-1).values
    return torch.exp(top2.sum(dim=-1))


def flat_split_mask(log_scales: torch.Tensor, gamma: float, cap: float) -> torch.Tensor:
    """Gaussians whose area exceeds mean + γ·std, capped to the largest ``cap`` fraction."""
    n = log_scales.shape[0]
    if n < 2:
        return torch.zeros(n, dtype=torch.bool)
    area = gaussian_areas(log_scales).double()
    mask = area > area.mean() + gamma * area.std()
    limit = int(math.floor(cap * n))
    if int(mask.sum()) > limit:
        keep = torch.zeros_like(mask)
        if limit > 0:
            keep[torch.topk(area, limit).indices] = True
        mask = mask & keep
    return mask


@torch.no_grad()
def projected_size_px(means: torch.Tensor, log_scales: torch.Tensor, cameras) -> torch.Tensor:
    """Each Gaussian's largest σ in pixels of ``cameras`` where it shows largest: its largest scale × the cameras'
    median focal length / its distance to the nearest camera centre, [N]."""
    import numpy as np

    centres = torch.as_tensor(np.stack([c.position for c in cameras]), dtype=torch.float32)  # [V, 3]
    fx = float(np.median([c.fx for c in cameras]))
    nearest = torch.cdist(means.detach().to(torch.float32), centres).min(dim=1).values.clamp_min(1e-9)
    return torch.exp(log_scales.detach().max(dim=-1).values) * fx / nearest


def shown_split_mask(mask: torch.Tensor, size_px: torch.Tensor, divisor: float, min_child_px: float) -> torch.Tensor:
    """``mask`` without the Gaussians too small to show their split: children (σ / ``divisor``) below
    ``min_child_px`` at the final width add Gaussians and refit time and nothing a render at that width can show."""
    return mask & (size_px / float(divisor) >= min_child_px)


def size_evenness(log_scales: torch.Tensor, gamma: float) -> dict[str, float]:
    """The criterion for skipping pre-processing: how uneven Gaussian areas are.

    Returns the coefficient of variation of the area, the fraction of Gaussians above mean + γ·std and the fraction of
    elongated ones (largest / second scale > 1.5).
    """
    n = log_scales.shape[0]
    if n < 2:
        return {"area_cv": 0.0, "flat_fraction": 0.0, "elongated_fraction": 0.0}
    area = gaussian_areas(log_scales).double()
    mean, std = float(area.mean()), float(area.std())
    flat = float((area > mean + gamma * std).double().mean())
    top2 = torch.topk(log_scales.detach(), 2, dim=-1).values
    elong = float(((top2[:, 0] - top2[:, 1]) > math.log(1.5)).double().mean())
    return {"area_cv": std / max(mean, 1e-30), "flat_fraction": flat, "elongated_fraction": elong}


EVEN_FLAT_FRACTION = 0.001  # sizes count as even below this fraction of flat Gaussians ...
EVEN_ELONGATED_FRACTION = 0.01  # ... and below this fraction of elongated ones


def evenness_verdict(crit: dict[str, float]) -> tuple[bool, str]:
    """Whether ``size_evenness`` figures say the sizes are already even, and the figures against their thresholds.

    Even sizes: no flat outliers and few elongated Gaussians, so pre-processing has nothing to split or clamp
    (the paper notes that well-reconstructed scenes may not need it).
    """
    even = crit["flat_fraction"] < EVEN_FLAT_FRACTION and crit["elongated_fraction"] < EVEN_ELONGATED_FRACTION
    text = (f"flat fraction {crit['flat_fraction']:.4f} (even below {EVEN_FLAT_FRACTION}), elongated fraction "
            f"{crit['elongated_fraction']:.4f} (even below {EVEN_ELONGATED_FRACTION}), area CV {crit['area_cv']:.3f}")
    return even, text


@torch.no_grad()
def clamp_elongation(log_scales: torch.Tensor, limit: float = 1.5) -> int:
    """In place: where largest/second > ``limit``, set the largest scale to the mean of the two. Returns the count."""
    if log_scales.shape[0] == 0:
        return 0
    vals, idx = torch.sort(log_scales, dim=-1, descending=True)
    s1, s2 = torch.exp(vals[:, 0]), torch.exp(vals[:, 1])
    mask = s1 > limit * s2
    if not bool(mask.any()):
        return 0
    new_log = torch.log((s1 + s2) / 2)
    rows = torch.where(mask)[0]
    log_scales[rows, idx[rows, 0]] = new_log[rows].to(log_scales.dtype)
    return int(mask.sum())


def clamp_points(iterations: int) -> tuple[int, ...]:
    """The refit iterations after which elongation is clamped: at 1/4, 1/2, 3/4 and the end of the refit."""
    it = int(iterations)
    return tuple(sorted({max(1, it // 4), max(1, it // 2), max(1, 3 * it // 4), it}))


@dataclass
class ElongationClampStrategy(Strategy):
    """Refit strategy of the pre-processing: clamp elongation at a few fixed iterations of each refit round.

    The clamp points follow from the refit's length (``clamp_points``), so a resumed refit clamps where a fresh one
    does."""

    iterations: int
    limit: float = 1.5

    @property
    def clamp_at(self) -> tuple[int, ...]:
        """Iterations (counted from 1) after which the clamp runs."""
        return clamp_points(self.iterations)

    def step_post_backward(self, params, optimizers, state, info: StepInfo) -> dict[str, int]:
        if info.step + 1 in self.clamp_at:
            return {"clamped": clamp_elongation(params["log_scales"].data, self.limit)}
        return {}
