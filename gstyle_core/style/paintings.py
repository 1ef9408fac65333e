"""One painting or several, as the style terms take them: the list, its checked weights, images as [B,3,H,W]."""

from __future__ import annotations

from collections.abc import Sequence

import torch

from .mix import normalise_style_weights


def style_list(style_image: torch.Tensor | Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """One painting or several, as a list (a list of none is an error)."""
    styles = [style_image] if isinstance(style_image, torch.Tensor) else list(style_image)
    if not styles:
        raise ValueError("no style image given")
    return styles


def checked_style_weights(weights: Sequence[float] | None, n_styles: int) -> tuple[float, ...]:
    """Weights of ``n_styles`` paintings, normalised (None for one painting: weight 1; see ``mix``)."""
    return (1.0,) if weights is None and n_styles == 1 else normalise_style_weights(weights, n_styles)


def as_batch(img: torch.Tensor) -> torch.Tensor:
    """Accept [3,H,W], [H,W,3] (numpy layout) or [B,3,H,W]; return float [B,3,H,W]."""
    img = torch.as_tensor(img).float()
    if img.ndim == 3:
        img = img.permute(2, 0, 1) if img.shape[-1] == 3 and img.shape[0] != 3 else img
        img = img.unsqueeze(0)
    if img.ndim != 4 or img.shape[1] != 3:
        raise ValueError(f"expected an RGB image [B,3,H,W], got {tuple(img.shape)}")
    if img.shape[0] == 0 or img.shape[2] == 0 or img.shape[3] == 0:
        raise ValueError(f"expected a non-empty RGB image, got shape {tuple(img.shape)}")
    return img
