"""Quality figures on fixed evaluation views: NNFM distance to the style, content distance, colour statistics."""

from __future__ import annotations

import numpy as np
import torch

from ..cameras.images import resize_image
from .objective import to_bchw


def colour_stats_distance(pixels: np.ndarray, style_pixels: np.ndarray) -> float:
    """‖μ_a − μ_b‖ + ‖Σ_a − Σ_b‖_F of two RGB pixel sets ([M, 3] in [0, 1])."""
    a = np.asarray(pixels, np.float64).reshape(-1, 3)
    b = np.asarray(style_pixels, np.float64).reshape(-1, 3)
    cov_a = np.cov(a, rowvar=False) if len(a) > 1 else np.zeros((3, 3))
    cov_b = np.cov(b, rowvar=False) if len(b) > 1 else np.zeros((3, 3))
    return float(np.linalg.norm(a.mean(0) - b.mean(0)) + np.linalg.norm(cov_a - cov_b))


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
    """Measures renders against the style image and ground-truth images with one VGG, at one resolution."""

    def __init__(self, vgg, style: np.ndarray, width: int = 256) -> None:
        from ..style.losses import StyleTarget

        self.vgg = vgg
        self.width = width
        self.style = np.asarray(style, np.float32)
        height = max(1, round(self.style.shape[0] * width / self.style.shape[1]))
        self.target = StyleTarget.from_image(vgg, to_bchw(resize_image(self.style, (width, height))))

    @torch.no_grad()
    def measure(self, renders: list[np.ndarray], ground_truth: list[np.ndarray],
                coverage: list[np.ndarray] | None = None) -> dict[str, float]:
        """NNFM distance to the style, content distance (VGG relu3 MSE) to ground truth, colour distance.

        ``nnfm_full`` is the mean over the whole frame. ``nnfm`` weights each feature vector by the scene's coverage
        (rendered alpha, pooled to the feature grid) when ``coverage`` is given: background that no Gaussian covers
        cannot change, so it is left out. ``colour`` uses covered pixels (alpha > 0.5) the same way.
        """
        from ..style.losses import concat_features, content_loss, feature_weights, nnfm_loss, weighted_mean

        nnfm, nnfm_full, content, pixels = [], [], [], []
        for i, (img, gt) in enumerate(zip(renders, ground_truth, strict=True)):
            f = self.vgg(to_bchw(img))
            g = self.vgg(to_bchw(gt))
            d = nnfm_loss(concat_features(f), self.target, reduction="none")[0]
            nnfm_full.append(float(d.mean()))
            if coverage is not None:
                w = feature_weights(torch.as_tensor(np.asarray(coverage[i], np.float32)), d.shape)
                nnfm.append(float(weighted_mean(d[None, None], w)))
                pixels.append(img.reshape(-1, 3)[np.asarray(coverage[i]).reshape(-1) > 0.5])
            else:
                nnfm.append(float(d.mean()))
                pixels.append(img.reshape(-1, 3))
            content.append(float(content_loss(f, g)))
        covered = np.concatenate(pixels) if sum(len(p) for p in pixels) > 1 else np.zeros((2, 3))
        colour = colour_stats_distance(covered, self.style)
        return {"nnfm": float(np.mean(nnfm)), "nnfm_full": float(np.mean(nnfm_full)),
                "content": float(np.mean(content)), "colour": colour}
