"""The stylization objective as the engine uses it: networks built once, content features cached per view."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import torch

from ..cameras.images import resize_image
from ..style.clip import CLIP_OFF
from .scene_box import scene_box
from .settings import StylizeSettings


def to_bchw(img: np.ndarray | torch.Tensor) -> torch.Tensor:
    """[H, W, 3] image -> float32 [1, 3, H, W] tensor."""
    return torch.as_tensor(img, dtype=torch.float32).permute(2, 0, 1)[None].contiguous()


def resize_long_side(img: np.ndarray, long_side: int) -> np.ndarray:
    """Resize an [H, W, 3] float image so its longer side is ``long_side`` pixels (aspect kept)."""
    h, w = img.shape[:2]
    s = long_side / max(h, w)
    return resize_image(img, (max(1, int(round(w * s))), max(1, int(round(h * s)))))


class StyleObjective:
    """λ_CLIP·L_CLIP + λ_NNFM·L_NNFM + λ_C·L_content + λ_TV·L_TV on a render [H, W, 3] of one view.

    The style image is resized so that its longer side matches the working resolution's longer side (the scale at
    which brush strokes are matched). CLIP ViT-B/32 is used when its weights are found; otherwise the documented
    coarse-VGG substitute (``clip_status`` says which).
    """

    def __init__(self, style: np.ndarray, settings: StylizeSettings, vgg=None) -> None:
        from ..style.losses import StyleLoss, StyleTarget
        from ..style.vgg import load_vgg

        dtype = torch.bfloat16 if settings.vgg_dtype == "bfloat16" else torch.float32
        if vgg is None:
            vgg = load_vgg(settings.vgg_weights, dtype=dtype, channels_last=dtype == torch.bfloat16)
        self.vgg = vgg
        self.vgg_status = f"VGG-16 weights from {getattr(vgg, 'weights_source', 'the caller')}"
        self._style = style
        long_side = max(64, int(settings.working_width * settings.style_scale))
        self._style_small = to_bchw(resize_long_side(style, long_side))
        self.target = StyleTarget.from_image(self.vgg, self._style_small)
        self._settings = settings
        self.clip_status = CLIP_OFF
        clip_term = self._build_clip_term() if settings.weights.clip > 0 else None
        self.loss = StyleLoss(self.vgg, self.target, clip_term, weights=self._effective(settings.weights))
        self._content_cache: dict[int, dict[str, torch.Tensor]] = {}
        self._boxes: dict[tuple[int, tuple[int, ...]], tuple[slice, slice] | None] = {}

    def _build_clip_term(self) -> torch.nn.Module:
        """CLIP ViT-B/32 on the style when its weights are found, else the coarse-VGG substitute (built when λ_CLIP
        first becomes non-zero)."""
        from ..style.clip import ClipStyleLoss, CoarseStyleLoss, load_clip

        encoder, self.clip_status = load_clip(self._settings.clip_weights)
        if encoder is None:
            return CoarseStyleLoss(self.vgg, self._style_small)
        return ClipStyleLoss(encoder, to_bchw(resize_long_side(self._style, 448)),
                             generator=torch.Generator().manual_seed(self._settings.seed))

    @property
    def calls(self) -> dict[str, int]:
        """Network runs so far (``vgg``, ``clip``)."""
        return self.loss.calls

    def _effective(self, weights) -> dict[str, float]:
        """λ weights as the loss uses them: the style terms (CLIP, NNFM) times the settings' style strength."""
        w = asdict(weights)
        strength = float(self._settings.strength)
        w["clip"] *= strength
        w["nnfm"] *= strength
        return w

    def set_weights(self, weights) -> None:
        """Change λ weights (a ``StyleWeights``; the settings' strength applies); the CLIP term (or its substitute)
        is built the first time its weight is non-zero."""
        w = self._effective(weights)
        if w["clip"] > 0 and self.loss.clip_term is None:
            self.loss.clip_term = self._build_clip_term()
        self.loss.weights = w

    def __call__(self, image: torch.Tensor, content: torch.Tensor, view: int,
                 coverage: torch.Tensor | None = None) -> tuple[torch.Tensor, dict]:
        """Loss of a render [H,W,3] of training view ``view``; ``content`` is its colour-matched ground truth and
        ``coverage`` [H,W] the scene's alpha there (None for photos: the whole frame is the scene). With
        ``crop_to_scene`` VGG sees only the box the scene covers (``pipeline/scene_box.py``)."""
        box = self.network_box(view, coverage)
        clip_view = None
        if box is not None:  # VGG on the box; the CLIP term (or its coarse substitute) keeps the whole frame
            clip_view = (image.permute(2, 0, 1)[None], coverage)
            image, content, coverage = image[box], content[box], coverage[box]
        render = image.permute(2, 0, 1)[None]
        gt_feats = None
        if self.loss.weights.content > 0:
            gt_feats = self._content_cache.get(view)
            if gt_feats is None:
                gt_feats = self.loss.content_features(content.permute(2, 0, 1)[None], render.shape[-2:])
                self._content_cache[view] = gt_feats
        return self.loss(render, gt_feats=gt_feats, coverage=coverage, clip_view=clip_view)

    def network_box(self, view: int, coverage: torch.Tensor | None) -> tuple[slice, slice] | None:
        """The view's scene box (fixed per view: the coverage is the ground truth's), None for the whole frame."""
        if coverage is None or not self._settings.crop_to_scene or self.loss.working_width is not None:
            return None
        key = (view, tuple(coverage.shape))
        if key not in self._boxes:
            self._boxes[key] = scene_box(coverage)
        return self._boxes[key]

