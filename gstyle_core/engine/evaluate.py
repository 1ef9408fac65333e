"""Quality figures on fixed evaluation views: NNFM distance to the style, content distance, colour statistics."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ..cameras.images import resize_image
from ..style.colour_match import Palette
from .objective import to_bchw


def colour_stats_distance(pixels: np.ndarray, style_pixels: np.ndarray | Palette) -> float:
    """‖μ_a − μ_b‖ + ‖Σ_a − Σ_b‖_F of two RGB pixel sets ([M, 3] in [0, 1]); the style may be given as its
    ``Palette`` (e.g. the weighted palette of a mix)."""
    a = np.asarray(pixels, np.float64).reshape(-1, 3)
    cov_a = np.cov(a, rowvar=False) if len(a) > 1 else np.zeros((3, 3))
    if isinstance(style_pixels, Palette):
        mean_b, cov_b = style_pixels.mean, style_pixels.cov
    else:
        b = np.asarray(style_pixels, np.float64).reshape(-1, 3)
        mean_b, cov_b = b.mean(0), (np.cov(b, rowvar=False) if len(b) > 1 else np.zeros((3, 3)))
    return float(np.linalg.norm(a.mean(0) - mean_b) + np.linalg.norm(cov_a - cov_b))


def luminance_edges(img: np.ndarray) -> np.ndarray:
    """Sobel gradient magnitude of the luminance of an [H, W, 3] image in [0, 1] → [H, W] (borders replicated)."""
    lum = np.asarray(img, np.float64)[..., :3] @ np.array([0.299, 0.587, 0.114])
    p = np.pad(lum, 1, mode="edge")
    gx = (p[:-2, 2:] + 2 * p[1:-1, 2:] + p[2:, 2:]) - (p[:-2, :-2] + 2 * p[1:-1, :-2] + p[2:, :-2])
    gy = (p[2:, :-2] + 2 * p[2:, 1:-1] + p[2:, 2:]) - (p[:-2, :-2] + 2 * p[:-2, 1:-1] + p[:-2, 2:])
    return np.hypot(gx, gy)


def interior_mask(alpha: np.ndarray, radius: int = 2) -> np.ndarray:
    """Pixels whose whole (2·radius+1)² neighbourhood is covered (alpha > 0.5): the scene without its silhouette."""
    covered = np.asarray(alpha, np.float64).reshape(np.shape(alpha)[:2]) > 0.5
    p = np.pad(covered, radius, mode="constant", constant_values=False)
    h, w = covered.shape
    out = np.ones_like(covered)
    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            out &= p[dy:dy + h, dx:dx + w]
    return out


def structure_kept(before: list[np.ndarray], after: list[np.ndarray], alpha: list[np.ndarray] | None) -> float:
    """How much of the scene's structure survived stylization: the Pearson correlation of the luminance edge maps of
    the before/after renders over the pixels the scene covers (its silhouette left out, since every render of it
    keeps that edge; whole frames when ``alpha`` is None). 1: the same edges; 0: unrelated edges."""
    xs, ys = [], []
    for i, (b, a) in enumerate(zip(before, after, strict=True)):
        mask = np.ones(b.shape[:2], bool) if alpha is None else interior_mask(alpha[i])
        xs.append(luminance_edges(b)[mask])
        ys.append(luminance_edges(a)[mask])
    x, y = np.concatenate(xs), np.concatenate(ys)
    if len(x) < 2 or x.std() == 0 or y.std() == 0:
        return float("nan")
    return float(np.corrcoef(x, y)[0, 1])


class Evaluator:
    """Measures renders against the style image and ground-truth images with one VGG, at one resolution.

    Several paintings (``style`` a list, ``weights`` one per painting, summing to 1): ``nnfm`` is the weighted sum of
    the distances to each painting (``nnfm_styles`` lists them) and ``colour`` compares with the weighted palette."""

    def __init__(self, vgg, style: np.ndarray | Sequence[np.ndarray], width: int = 256,
                 weights: Sequence[float] | None = None, max_vectors: int | None = None) -> None:
        """``max_vectors``: at most this many of each painting's feature vectors (a random subset drawn from seed 0;
        None: all), to bound the search at large widths."""
        from ..style.mix import normalise_style_weights
        from ..style.nnfm import StyleTarget

        self.vgg = vgg
        self.width = width
        self.styles = [np.asarray(s, np.float32) for s in ([style] if isinstance(style, np.ndarray) else style)]
        self.weights = normalise_style_weights(weights, len(self.styles))
        self.targets = []
        for image in self.styles:
            height = max(1, round(image.shape[0] * width / image.shape[1]))
            self.targets.append(StyleTarget.from_image(vgg, to_bchw(resize_image(image, (width, height))),
                                                       max_vectors=max_vectors,
                                                       generator=torch.Generator().manual_seed(0)))
        self.palette = Palette.mixture([Palette.of(s) for s in self.styles], self.weights)

    @torch.no_grad()
    def measure(self, renders: list[np.ndarray], ground_truth: list[np.ndarray],
                coverage: list[np.ndarray] | None = None, whole_frame: bool = True) -> dict[str, float]:
        """NNFM distance to the style, content distance (VGG relu3 MSE) to ground truth, colour distance.

        ``nnfm_full`` is the mean over the whole frame. ``nnfm`` weights each feature vector by the scene's coverage
        (rendered alpha, pooled to the feature grid) when ``coverage`` is given: background that no Gaussian covers
        cannot change, so it is left out. ``colour`` uses covered pixels (alpha > 0.5) the same way.
        ``whole_frame=False`` (with ``coverage``): only the covered feature vectors are searched (the same ``nnfm``;
        no ``nnfm_full``), for large widths.
        """
        from ..style.features import concat_features, feature_weights, weighted_mean
        from ..style.losses import content_loss
        from ..style.nnfm import nnfm_loss

        per_style = np.zeros((len(self.targets), len(renders)))  # coverage-weighted NNFM per painting and view
        per_style_full = np.zeros_like(per_style)
        content, pixels = [], []
        for i, (img, gt) in enumerate(zip(renders, ground_truth, strict=True)):
            f = self.vgg(to_bchw(img))
            g = self.vgg(to_bchw(gt))
            stacked = concat_features(f)
            w = None if coverage is None else feature_weights(
                torch.as_tensor(np.asarray(coverage[i], np.float32)), stacked.shape[-2:])
            for k, target in enumerate(self.targets):
                if whole_frame or w is None:
                    d = nnfm_loss(stacked, target, reduction="none")[0]
                    per_style_full[k, i] = float(d.mean())
                    per_style[k, i] = float(weighted_mean(d[None, None], w))
                else:  # the covered vectors only: those the weighted mean counts
                    keep = w.flatten() > 0
                    vectors = stacked.flatten(2)[..., keep][..., None]  # [1, C, n, 1]
                    d = nnfm_loss(vectors, target, reduction="none").flatten() if keep.any() else torch.zeros(1)
                    kept = w.flatten()[keep] if keep.any() else torch.zeros(1)
                    per_style[k, i] = float((d * kept).sum() / kept.sum().clamp_min(1e-8))
                    per_style_full[k, i] = float("nan")
            if coverage is not None:
                pixels.append(img.reshape(-1, 3)[np.asarray(coverage[i]).reshape(-1) > 0.5])
            else:
                pixels.append(img.reshape(-1, 3))
            content.append(float(content_loss(f, g)))
        covered = np.concatenate(pixels) if sum(len(p) for p in pixels) > 1 else np.zeros((2, 3))
        colour = colour_stats_distance(covered, self.styles[0] if len(self.styles) == 1 else self.palette)
        shares = np.asarray(self.weights)[:, None]
        out = {"nnfm": float((shares * per_style).sum(0).mean()),
               "nnfm_full": float((shares * per_style_full).sum(0).mean()),
               "content": float(np.mean(content)), "colour": colour}
        if len(self.styles) > 1:
            out["nnfm_styles"] = [float(v) for v in per_style.mean(1)]
        return out
