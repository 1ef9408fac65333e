"""Speckle at the display's size: how much of the colour that stylization added is finer than the painting's own.

An artist looks at the result at the display's size (1024 px wide by default), not at the working width the networks
saw. There, excess fine colour reads as confetti: single splats of the painting's hues instead of its strokes. The
figure (issue #34's *speckle ratio*) compares two chroma spectra in the same pixel units:

* the **added chroma**: the opponent channels r − g and (r + g)/2 − b of ``after − before`` (the stylized render
  minus the input render of the same view, both ``display`` px wide), inside the scene (coverage-weighted as
  ``texture_scale.band_energies`` weights), and
* the **painting's chroma**: the same channels of the painting resized (as the engine resizes it) so its long side
  is the stroke size × the display width, i.e. the size at which its strokes are matched, in display pixels
  (``texture_scale.matched_side``); measured unweighted over its whole area.

Each is split into difference-of-Gaussians bands between σ = 0.5, 1.5, 4, 10 and 25 px (``SPECKLE_EDGES``); the
*fine share* is the energy of the bands below σ 4 px over the energy of all four. The **speckle ratio** is the added
chroma's fine share over the painting's: 1 means the added colour is as fine-grained as the painting at that size,
above 1 finer (specks), below 1 smoother. Only colour counts: luminance detail is the scene's own structure. The
figure is about excess fine colour, not fine texture as such: a fine-grained painting has a high fine share itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from .texture_scale import NO_DETAIL, band_energies

SPECKLE_EDGES = (0.5, 1.5, 4.0, 10.0, 25.0)  # σ in display pixels: four DoG bands
FINE_BANDS = 2  # the bands below σ 4 px (0.5–1.5 and 1.5–4)
DEFAULT_DISPLAY_WIDTH = 1024


def opponent_chroma(image: np.ndarray | torch.Tensor) -> np.ndarray:
    """[H, W, 3] RGB → [H, W, 2] opponent chroma: r − g and (r + g)/2 − b (float64)."""
    x = _rgb(image)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    return np.stack([r - g, 0.5 * (r + g) - b], axis=-1)


def luminance(image: np.ndarray | torch.Tensor) -> np.ndarray:
    """[H, W, 3] RGB → [H, W, 1] luminance (Rec. 601 weights, as ``keep_colours`` uses)."""
    return (_rgb(image) @ np.array([0.299, 0.587, 0.114]))[..., None]


def _rgb(image: np.ndarray | torch.Tensor) -> np.ndarray:
    x = np.asarray(image, np.float64)
    if x.ndim != 3 or x.shape[-1] < 3:
        raise ValueError(f"expected an [H, W, 3] image, got shape {x.shape}")
    return x[..., :3]


def chroma_energies(image: np.ndarray | torch.Tensor, weights: np.ndarray | torch.Tensor | None = None,
                    channels: str = "chroma") -> np.ndarray:
    """Energies of ``image``'s opponent chroma (``channels="luminance"``: its luminance) in the four
    ``SPECKLE_EDGES`` bands (``weights`` [H, W] per pixel)."""
    if channels not in CHANNELS:
        raise ValueError(f"channels must be one of {', '.join(CHANNELS)}, got {channels!r}")
    return band_energies(CHANNELS[channels](image), weights, SPECKLE_EDGES, dtype=torch.float32)


CHANNELS = {"chroma": opponent_chroma, "luminance": luminance}


def fine_share(energies: np.ndarray) -> float:
    """The share of ``energies`` (four bands) below σ 4 px; NaN when there is no detail at all."""
    e = np.asarray(energies, np.float64)
    total = float(e.sum())
    return float(e[:FINE_BANDS].sum() / total) if total > NO_DETAIL else float("nan")


def painting_chroma_energies(painting: np.ndarray, side: int, channels: str = "chroma") -> np.ndarray:
    """Chroma (or luminance) band energies of ``painting`` [H, W, 3] resized (as the engine resizes it) to a long side
    of ``side``."""
    from .painting_size import resize_long_side

    return chroma_energies(resize_long_side(np.asarray(painting, np.float32), int(side)), channels=channels)


@dataclass(frozen=True)
class DisplaySpeckle:
    """The figure: fine chroma shares of the added colour (over all views, and per view) and of the painting(s)."""

    width: int  # display width of the renders (px)
    channels: str  # "chroma" (the figure) or "luminance" (keep colours: only the luminance pattern is transferred)
    painting_side: int  # the painting's long side at that width (px)
    added_fine: float  # fine share of the added chroma, energies summed over the views
    painting_fine: float  # the painting's fine share (weighted mean over a mix's paintings)
    per_view_fine: tuple[float, ...]
    fringe: dict | None = None  # the fringe halo of the same renders (``fringe.FringeHalo.to_dict()``), when measured

    @property
    def ratio(self) -> float:
        """The speckle ratio: added fine share over the painting's (NaN where either is undefined)."""
        return self.added_fine / self.painting_fine if self.painting_fine > 0 else float("nan")

    @property
    def per_view_ratios(self) -> tuple[float, ...]:
        """The ratio of each view alone."""
        return tuple(f / self.painting_fine if self.painting_fine > 0 else float("nan") for f in self.per_view_fine)

    def to_dict(self) -> dict:
        """For OUT.json (``quality.display``) and bench tables."""
        bands = [list(SPECKLE_EDGES[k:k + 2]) for k in range(len(SPECKLE_EDGES) - 1)]
        return {"width": self.width, "channels": self.channels, "bands_px": bands,
                "fine_below_px": SPECKLE_EDGES[FINE_BANDS], "painting_side": self.painting_side,
                "added_fine_share": _rounded(self.added_fine), "painting_fine_share": _rounded(self.painting_fine),
                "speckle_ratio": _rounded(self.ratio),
                "speckle_ratio_per_view": [_rounded(r) for r in self.per_view_ratios],
                **({} if self.fringe is None else {"fringe": self.fringe})}

    def line(self) -> str:
        """One line for the end of a run."""
        views = " / ".join(f"{r:.2f}" for r in self.per_view_ratios)
        return (f"speckle at {self.width} px ({self.channels} finer than σ 4 px, added over the painting's at "
                f"{self.painting_side} px): {self.ratio:.2f} (views {views}; 1: the painting's grain, above: specks)")


def display_speckle(before: Sequence[np.ndarray], after: Sequence[np.ndarray],
                    coverage: Sequence[np.ndarray | None] | None, paintings: Sequence[np.ndarray] | np.ndarray,
                    painting_side: int, painting_weights: Sequence[float] | None = None,
                    channels: str = "chroma") -> DisplaySpeckle:
    """The figure for renders of several views at the display width (lists of [H, W, 3]; ``coverage`` [H, W] per view
    or None) against ``paintings`` at a long side of ``painting_side`` px (several: their fine shares' weighted
    mean). ``channels="luminance"`` measures luminance instead of chroma (keep colours)."""
    if not before or len(before) != len(after) or (coverage is not None and len(coverage) != len(before)):
        raise ValueError(f"{len(before)} before and {len(after)} after image(s), and one coverage each")
    cov = [None] * len(before) if coverage is None else list(coverage)
    per_view = []
    for b, a, c in zip(before, after, cov, strict=True):
        if np.shape(a) != np.shape(b):
            raise ValueError(f"before {np.shape(b)} and after {np.shape(a)} differ in shape")
        per_view.append(chroma_energies(np.asarray(a, np.float64) - np.asarray(b, np.float64), c, channels))
    paint_l = [paintings] if isinstance(paintings, np.ndarray) else list(paintings)
    w = np.ones(len(paint_l)) if painting_weights is None else np.asarray(painting_weights, np.float64)
    if len(w) != len(paint_l) or not w.sum() > 0:
        raise ValueError(f"{len(w)} weight(s) for {len(paint_l)} painting(s)")
    painting = sum(wi * fine_share(painting_chroma_energies(p, painting_side, channels))
                   for wi, p in zip(w / w.sum(), paint_l, strict=True) if wi > 0)
    return DisplaySpeckle(int(np.shape(before[0])[1]), channels, int(painting_side), fine_share(sum(per_view)),
                          float(painting), tuple(fine_share(e) for e in per_view))


def _rounded(value: float) -> float | None:
    """4 decimals; None for NaN (JSON has no NaN)."""
    return round(float(value), 4) if np.isfinite(value) else None
