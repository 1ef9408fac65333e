"""Two (or more) paintings mixed: their weights, checked and normalised in one place.

A mix is a list of style images with weights that sum to 1. Every style term is the weighted sum of the same term
against each painting (NNFM: Σ w_i·NNFM_i on the render's one set of VGG features; the CLIP term and its coarse
substitute likewise on one embedding or one set of statistics of the render), and the colour matches map onto the
weighted palette (``colour_match.Palette.mixture``). A painting whose weight is 0 costs nothing (its terms are
skipped).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

MAX_STYLES = 8  # each painting adds a nearest-neighbour search per step


def normalise_style_weights(weights: Sequence[float] | None, n_styles: int) -> tuple[float, ...]:
    """Weights for ``n_styles`` paintings, normalised to sum 1 (None or empty: equal shares); ``ValueError`` saying
    why for a wrong count, a negative or non-finite weight or all zeros."""
    if n_styles < 1:
        raise ValueError("at least one style image is needed")
    if n_styles > MAX_STYLES:
        raise ValueError(f"at most {MAX_STYLES} style images can be mixed, got {n_styles}")
    if not weights:
        return tuple([1.0 / n_styles] * n_styles)
    try:
        values = [float(w) for w in weights]
    except (TypeError, ValueError):
        raise ValueError(f"style weights must be numbers, got {list(weights)}") from None
    if len(values) != n_styles:
        raise ValueError(f"{len(values)} style weight(s) for {n_styles} style image(s): give one weight per style")
    if not all(math.isfinite(w) and w >= 0 for w in values):
        raise ValueError(f"style weights must be finite and 0 or more, got {values}")
    total = sum(values)
    if total <= 0:
        raise ValueError(f"style weights must not all be 0, got {values}")
    return tuple(w / total for w in values)


def parse_style_weights(text: str) -> list[float]:
    """``"0.7,0.3"`` -> [0.7, 0.3] (``ValueError`` naming the bad entry)."""
    out = []
    for part in text.split(","):
        try:
            out.append(float(part))
        except ValueError:
            raise ValueError(f"style weights are numbers separated by commas (e.g. 0.7,0.3), got {text!r}") from None
    return out


def weights_with_mix(weights: Sequence[float], mix: float) -> tuple[float, ...]:
    """The studio's mix slider: the last painting gets ``mix`` (0-1), the others share the rest in their current
    proportions (equally when they had none)."""
    if not (math.isfinite(mix) and 0.0 <= mix <= 1.0):
        raise ValueError(f"style mix must be between 0 and 1, got {mix}")
    n = len(weights)
    if n < 2:
        raise ValueError("the style mix needs two style images")
    rest = [max(float(w), 0.0) for w in weights[:-1]]
    total = sum(rest)
    shares = [w / total for w in rest] if total > 0 else [1.0 / (n - 1)] * (n - 1)
    return tuple([s * (1.0 - mix) for s in shares] + [float(mix)])
