"""The fringe halo at the display's size: how much brighter stylization made the capture's fading edge than its body.

A capture fades out at its fringe: pixels there are covered by a few faint Gaussians only (the input's accumulated
alpha is low). If stylization drives those Gaussians' colours to bright extremes, the result shows a halo of bright
strokes around the scene (issue #50 item 4). The figure compares renders of the same views before and after
stylization (black background, so a render is premultiplied: colour = Σ w_i c_i, alpha = Σ w_i):

* the **fringe**: pixels whose *input* alpha lies in ``FRINGE_ALPHA`` (0.02 < α < 0.5); the **body**: α ≥ 0.5;
* the colour the Gaussians carry there, un-premultiplied over a region: Σ colour / Σ alpha (an alpha-weighted mean,
  so nearly empty pixels count little and a division by a tiny alpha never dominates);
* the **lift** of a region: the luminance of that colour after minus before; the **halo** = fringe lift − body lift
  (0: stylization brightened the fringe as much as the body; above 0: a brighter rim);
* the **near-saturated share**: the alpha-weighted share of fringe pixels whose un-premultiplied colour has its largest
  channel ≥ ``BRIGHT`` (0.95), before and after, beside the same share of the stylized body's pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from .speckle import _rounded as _r
from .speckle import luminance

FRINGE_ALPHA = (0.02, 0.5)  # the input's alpha of a fringe pixel: above the first, below the second
BRIGHT = 0.95  # a fringe pixel's un-premultiplied largest channel at least this: near saturation


@dataclass(frozen=True)
class FringeHalo:
    """The halo figure over several views (module docstring)."""

    fringe_share: float  # fringe pixels over all covered ones (input alpha > 0.02)
    lift_fringe: float  # luminance after − before of the fringe's un-premultiplied colour
    lift_body: float  # the same in the body (input alpha ≥ 0.5)
    bright_before: float  # alpha-weighted share of fringe pixels near saturation, input
    bright_after: float  # the same, stylized
    bright_body: float  # the alpha-weighted share of the stylized body's pixels near saturation

    @property
    def halo(self) -> float:
        """How much more stylization brightened the fringe than the body (luminance in [0, 1] units)."""
        return self.lift_fringe - self.lift_body

    def to_dict(self) -> dict:
        """For OUT.json (``quality.display.fringe``) and bench tables."""
        return {"fringe_alpha": list(FRINGE_ALPHA), "bright_channel": BRIGHT, "fringe_share": _r(self.fringe_share),
                "lift_fringe": _r(self.lift_fringe), "lift_body": _r(self.lift_body), "halo": _r(self.halo),
                "bright_before": _r(self.bright_before), "bright_after": _r(self.bright_after),
                "bright_body": _r(self.bright_body)}

    def line(self) -> str:
        """One line for the end of a run."""
        return fringe_halo_line(self.to_dict())


def fringe_halo_line(d: dict) -> str:
    """The end-of-run line of the figure (from ``FringeHalo.to_dict()``, as OUT.json keeps it)."""
    def num(key: str, fmt: str) -> str:
        return "-" if d.get(key) is None else format(d[key], fmt)

    low, high = d["fringe_alpha"]
    return (f"fringe halo (input alpha {low}–{high}, {num('fringe_share', '.0%')} of the scene's pixels): "
            f"{num('halo', '+.3f')} luminance over the body's lift ({num('lift_fringe', '+.3f')} vs "
            f"{num('lift_body', '+.3f')}; 0: no brighter rim); near-saturated {num('bright_before', '.1%')} → "
            f"{num('bright_after', '.1%')} (the body's {num('bright_body', '.1%')})")


def fringe_halo(before: Sequence[np.ndarray], after: Sequence[np.ndarray], alpha_before: Sequence[np.ndarray],
                alpha_after: Sequence[np.ndarray] | None = None) -> FringeHalo:
    """The figure for renders of several views (lists of [H, W, 3] on black, and their [H, W] alphas; the stylized
    alphas default to the input's: stylization keeps the geometry's coverage)."""
    a_after = alpha_before if alpha_after is None else alpha_after
    if not before or not len(before) == len(after) == len(alpha_before) == len(a_after):
        raise ValueError(f"{len(before)} before and {len(after)} after image(s), and one alpha each")
    sums = np.zeros((2, 2, 2))  # [before/after, fringe/body, (Σ luminance, Σ alpha)]
    bright, weight, fringe_px, covered_px = np.zeros(3), np.zeros(3), 0, 0  # fringe before, after; body after
    for b, a, ab, aa in zip(before, after, alpha_before, a_after, strict=True):
        if np.shape(a) != np.shape(b):
            raise ValueError(f"before {np.shape(b)} and after {np.shape(a)} differ in shape")
        alpha_in = _plane(ab)
        fringe = (alpha_in > FRINGE_ALPHA[0]) & (alpha_in < FRINGE_ALPHA[1])
        body = alpha_in >= FRINGE_ALPHA[1]
        fringe_px, covered_px = fringe_px + int(fringe.sum()), covered_px + int((alpha_in > FRINGE_ALPHA[0]).sum())
        for k, (image, alpha) in enumerate(((b, alpha_in), (a, _plane(aa)))):
            lum = luminance(image)[..., 0]
            for r, mask in enumerate((fringe, body)):
                sums[k, r] += (lum[mask].sum(), alpha[mask].sum())
            bright[k] += _near_saturated(image, alpha, alpha_in, fringe)
            weight[k] += float(alpha_in[fringe].sum())
        bright[2] += _near_saturated(a, _plane(aa), alpha_in, body)
        weight[2] += float(alpha_in[body].sum())
    mean = sums[..., 0] / np.maximum(sums[..., 1], 1e-12)  # [before/after, fringe/body]
    lift = mean[1] - mean[0]
    shares = np.where(weight > 0, bright / np.maximum(weight, 1e-12), np.nan)
    return FringeHalo(fringe_px / covered_px if covered_px else float("nan"), float(lift[0]), float(lift[1]),
                      *(float(v) for v in shares))


def _plane(alpha: np.ndarray | torch.Tensor) -> np.ndarray:
    """An [H, W] (or [H, W, 1]) alpha as a float64 [H, W] array."""
    a = np.asarray(alpha, np.float64)
    return a.reshape(a.shape[:2])


def _near_saturated(image: np.ndarray, alpha: np.ndarray, weight: np.ndarray, mask: np.ndarray) -> float:
    """Σ ``weight`` over the ``mask`` pixels whose un-premultiplied colour (image / alpha) reaches ``BRIGHT``."""
    colour = np.asarray(image, np.float64)[..., :3][mask] / np.maximum(alpha[mask], 1e-6)[:, None]
    return float(weight[mask][colour.max(axis=1) >= BRIGHT].sum())
