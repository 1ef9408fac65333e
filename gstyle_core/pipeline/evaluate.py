"""Quality figures on fixed evaluation views: NNFM distance to the style, content distance, colour statistics."""

from __future__ import annotations

import numpy as np
import torch


def colour_stats_distance(pixels: np.ndarray, style_pixels: np.ndarray) -> float:
    """‖μ_a − μ_b‖ + ‖Σ_a − Σ_b‖_F of two RGB pixel sets ([M, 3] in [0, 1])."""
    a = np.asarray(pixels, np.float64).reshape(-1, 3)
    b = np.asarray(style_pixels, np.float64).reshape(-1, 3)
    cov_a = np.cov(a, rowvar=False) if len(a) > 1 else np.zeros((3, 3))
    cov_b = np.cov(b, rowvar=False) if len(b) > 1 else np.zeros((3, 3))
    return float(np.linalg.norm(a.mean(0) - b.mean(0)) + np.linalg.norm(cov_a - cov_b))


class Evaluator:
    """Measures renders against the style image and ground-truth images with one VGG, at one resolution."""

    def __init__(self, vgg, style: np.ndarray, width: int = 256) -> None:
        from ..style.losses import StyleTarget

        self.vgg = vgg
        self.width = width
        self.style = np.asarray(style, np.float32)
        self.target = StyleTarget(vgg, _to_bchw(_resize_to_width(self.style, width)))

    @torch.no_grad()
    def measure(self, renders: list[np.ndarray], ground_truth: list[np.ndarray]) -> dict[str, float]:
        """Mean NNFM distance to the style, content distance (VGG relu3 MSE) to ground truth, colour distance."""
        from ..style.losses import content_loss, nnfm_loss

        nnfm, content = [], []
        for img, gt in zip(renders, ground_truth, strict=True):
            f = self.vgg(_to_bchw(img))
            g = self.vgg(_to_bchw(gt))
            nnfm.append(float(nnfm_loss(f, self.target)))
            content.append(float(content_loss(f, g)))
        colour = colour_stats_distance(np.concatenate([r.reshape(-1, 3) for r in renders]), self.style)
        return {"nnfm": float(np.mean(nnfm)), "content": float(np.mean(content)), "colour": colour}


def _resize_to_width(img: np.ndarray, width: int) -> np.ndarray:
    from PIL import Image

    h, w = img.shape[:2]
    height = max(1, int(round(h * width / w)))
    pil = Image.fromarray((np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8))
    return np.asarray(pil.resize((width, height), Image.LANCZOS), np.float32) / 255.0


def _to_bchw(img: np.ndarray | torch.Tensor) -> torch.Tensor:
    t = torch.as_tensor(np.asarray(img, np.float32))
    return t.permute(2, 0, 1)[None].contiguous()
