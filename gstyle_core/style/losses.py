"""The G-Style stylization loss: λ_CLIP·L_CLIP + λ_NNFM·L_NNFM + λ_C·L_content + λ_TV·L_TV.

* NNFM (ARF): every render feature vector (VGG relu3_1|relu3_2|relu3_3, 768 channels) against its nearest painting
  vector by cosine distance, averaged (:mod:`gstyle_core.style.nnfm`).
* Content: mean squared difference of the same VGG features of the render and of the colour-matched
  ground-truth view, computed per layer and summed over the three layers (as the reference code does).
* TV: total variation of the full-resolution render, **summed** squared differences of vertical and
  horizontal neighbours. This follows the G-Style reference code (``calculate_total_variation_loss``: sum
  of squared differences), which its λ_TV = 1e-4 is paired with (:mod:`gstyle_core.style.pixel_terms`).
* CLIP: see :mod:`gstyle_core.style.clip` (or its coarse-VGG substitute).
* Broad strokes (``multiscale``): NNFM with the render and the painting both downsampled ×2, ×4 and ×8
  (:mod:`gstyle_core.style.multiscale`): the painting's larger patterns, for when CLIP cannot run.

A term whose weight is 0 is not computed at all; when λ_NNFM, λ_C and λ_broad strokes are 0 VGG never runs, when
λ_CLIP is 0 the CLIP term never runs. ``StyleLoss.calls`` counts network runs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace

import torch
import torch.nn.functional as F
from torch import nn

from .features import (
    FEATURE_LAYERS,
    concat_features,
    feature_weights,
    resize_to_width,
    stacked_features,
    upsample_for_vgg,
    vgg_input_size,
    weighted_mean,
)
from .nnfm import StyleTarget, WeightedTargets, style_nnfm
from .pixel_terms import chroma_tv_loss, edges_loss, tv_loss


@dataclass(frozen=True)
class StyleWeights:
    """Loss weights; defaults are G-Style's for forward-facing scenes (λ_NNFM 10 for 360° scenes). ``multiscale``
    (the broad-strokes term) is not the paper's: 0 here, the settings turn it on when CLIP cannot run."""

    clip: float = 10.0
    nnfm: float = 100.0
    content: float = 0.05
    tv: float = 1e-4
    multiscale: float = 0.0
    chroma_tv: float = 0.0  # colour smoothness (``chroma_tv_loss``), not the paper's: 0 here, the settings set it
    edges: float = 0.0  # the scene's light-and-dark edges kept (``edges_loss``), not the paper's: 0 here

    @classmethod
    def for_scene_kind(cls, kind: str) -> StyleWeights:
        """``"forward"`` (forward-facing) or ``"360"`` defaults of the reference."""
        if kind not in ("forward", "360"):
            raise ValueError(f"scene kind must be 'forward' or '360', got {kind!r}")
        return cls() if kind == "forward" else cls(nnfm=10.0)


def content_loss(render_feats: Mapping[str, torch.Tensor] | Sequence[torch.Tensor] | torch.Tensor,
                 gt_feats: Mapping[str, torch.Tensor] | Sequence[torch.Tensor] | torch.Tensor,
                 weights: torch.Tensor | None = None) -> torch.Tensor:
    """Mean squared feature difference; for per-layer dicts/lists, the sum over layers of each layer's mean.
    ``weights`` [B,1,h,w] (:func:`feature_weights`) weight each feature position (the scene's coverage)."""
    if isinstance(render_feats, torch.Tensor):
        pairs = [(render_feats, gt_feats)]
    elif isinstance(render_feats, Mapping):
        pairs = [(render_feats[name], gt_feats[name]) for name in FEATURE_LAYERS]
    else:
        pairs = list(zip(render_feats, gt_feats, strict=True))
    return sum(weighted_mean((r - g.detach()) ** 2, weights) for r, g in pairs)


def stacked_content_loss(render_stack: torch.Tensor, gt_stack: torch.Tensor,
                         weights: torch.Tensor | None = None) -> torch.Tensor:
    """:func:`content_loss` over the relu3 layers (the sum of each layer's mean) from their stacks along channels
    ([B, 768, h, w], :func:`concat_features`): the three layers have the same channels and grid, so the sum is three
    times the mean of the stack, one set of operators instead of three."""
    return len(FEATURE_LAYERS) * weighted_mean((render_stack - gt_stack.detach()) ** 2, weights)


TERM_NAMES = ("clip", "nnfm", "content", "tv", "multiscale", "chroma_tv", "edges")  # StyleLoss's terms, in order
TOGETHER_TERMS = ("clip", "multiscale")  # the terms whose network may take several views in one pass
TermInputs = dict[str, list[tuple[torch.Tensor, "torch.Tensor | None"]]]  # term → the views' (render, coverage)


def per_view_values(term: nn.Module, inputs: Sequence[tuple[torch.Tensor, torch.Tensor | None]]
                    ) -> tuple[torch.Tensor, int]:
    """``term`` (a module with ``per_image`` and ``passes``) of each (render [1,3,H,W], coverage) of ``inputs``:
    [len(inputs)] in their order, the renders of one size (and coverage) taken in one batch; and the network passes
    that took (``passes`` per batch)."""
    groups: dict[tuple, list[int]] = {}
    for i, (render, coverage) in enumerate(inputs):
        groups.setdefault((tuple(render.shape), None if coverage is None else tuple(coverage.shape[-2:])),
                          []).append(i)
    values: list[torch.Tensor | None] = [None] * len(inputs)
    for members in groups.values():
        renders = torch.cat([inputs[i][0] for i in members])
        coverage = None if inputs[members[0]][1] is None else torch.stack(
            [torch.as_tensor(inputs[i][1], dtype=torch.float32).reshape(inputs[i][1].shape[-2:]) for i in members])
        per_image = term.per_image(renders, coverage)
        for k, i in enumerate(members):
            values[i] = per_image[k]
    return torch.stack(values), len(groups) * term.passes


def term_values(values: torch.Tensor) -> dict[str, float]:
    """The terms' values of ``StyleLoss.evaluate`` ([len(TERM_NAMES)], any device) read in one transfer, by name."""
    return dict(zip(TERM_NAMES, values.detach().cpu().tolist(), strict=True))


class StyleLoss(nn.Module):
    """The combined loss. ``forward(render [1,3,H,W], gt [1,3,H,W] | None) -> (total, {term: value})``.

    ``vgg`` and ``style_target`` (one painting's or a :class:`WeightedTargets` mix) serve NNFM and content;
    ``clip_term`` is a :class:`ClipStyleLoss` or a
    :class:`CoarseStyleLoss` (or None: the CLIP weight must then be 0); ``multiscale_term`` a
    :class:`~gstyle_core.style.multiscale.MultiScaleStyleLoss` (or None: its weight must then be 0), given the same
    (resized, cropped) render and coverage as NNFM. ``working_width`` resizes the render
    (and gt) before the networks, like the reference's 1024-px stylization size; TV uses the full render.
    A render (or gt) with a side below ``MIN_VGG_SIDE`` px is stretched to it for VGG (no relu3 features otherwise).
    Terms with weight 0 are skipped entirely and reported as 0.
    """

    def __init__(self, vgg: nn.Module | None, style_target: StyleTarget | WeightedTargets | None,
                 clip_term: nn.Module | None = None, weights: StyleWeights | Mapping[str, float] | None = None,
                 working_width: int | None = None, nnfm_chunk: int = 4096,
                 multiscale_term: nn.Module | None = None) -> None:
        super().__init__()
        self.vgg = vgg
        self.style_target = style_target
        self.clip_term = clip_term
        self.multiscale_term = multiscale_term
        self.working_width = working_width
        self.nnfm_chunk = nnfm_chunk
        self.chroma_floor = 0.0  # the colour-smoothness term counts only chroma variation above this (the painting's)
        self.calls = {"vgg": 0, "clip": 0}
        self._weight_vectors: dict[tuple, torch.Tensor] = {}  # ``_weight_vector``'s
        self._weights = StyleWeights()
        self.weights = weights if weights is not None else StyleWeights()

    @property
    def weights(self) -> StyleWeights:
        return self._weights

    @weights.setter
    def weights(self, value: StyleWeights | Mapping[str, float]) -> None:
        if isinstance(value, Mapping):
            unknown = set(value) - set(asdict(self._weights))
            if unknown:
                raise ValueError(f"unknown loss weight(s): {sorted(unknown)}")
            value = replace(self._weights, **{k: float(v) for k, v in value.items()})
        for name, weight in asdict(value).items():
            if not weight >= 0.0:
                raise ValueError(f"loss weight {name} must be >= 0, got {weight}")
        if (value.nnfm > 0 or value.content > 0) and self.vgg is None:
            raise ValueError("NNFM/content weights need a VGG network")
        if value.nnfm > 0 and self.style_target is None:
            raise ValueError("the NNFM weight needs a style target")
        if value.clip > 0 and self.clip_term is None:
            raise ValueError("the CLIP weight needs a CLIP term (or its coarse-VGG substitute)")
        if value.multiscale > 0 and self.multiscale_term is None:
            raise ValueError("the broad-strokes weight needs its multi-scale term")
        self._weights = value

    def forward(self, render: torch.Tensor, gt: torch.Tensor | None = None,
                gt_feats: Mapping[str, torch.Tensor] | torch.Tensor | None = None,
                coverage: torch.Tensor | None = None,
                clip_view: tuple[torch.Tensor, torch.Tensor | None] | None = None,
                multiscale_view: tuple[torch.Tensor, torch.Tensor | None] | None = None,
                ) -> tuple[torch.Tensor, dict[str, float]]:
        """The total and each term's value (``evaluate``'s, read); the arguments are ``evaluate``'s."""
        total, values = self.evaluate(render, gt, gt_feats, coverage, clip_view, multiscale_view)
        return total, term_values(values)

    def evaluate(self, render: torch.Tensor, gt: torch.Tensor | None = None,
                 gt_feats: Mapping[str, torch.Tensor] | torch.Tensor | None = None,
                 coverage: torch.Tensor | None = None,
                 clip_view: tuple[torch.Tensor, torch.Tensor | None] | None = None,
                 multiscale_view: tuple[torch.Tensor, torch.Tensor | None] | None = None,
                 together: TermInputs | None = None,
                 ) -> tuple[torch.Tensor, torch.Tensor]:
        """The total and the terms' values as one tensor on the render's device, in ``TERM_NAMES`` order, unread
        (on a GPU a read waits for the queue to drain: a step reads its views' values once, ``term_values``).
        ``gt_feats``: the ground truth's relu3 features (``content_features``, or their stack; None: taken from
        ``gt``). ``coverage``: the scene's rendered alpha ([H,W] or [1,1,H,W], render resolution) for scenes on an empty
        background; NNFM, content and the coarse substitute then average over the scene's feature positions
        (None: over the whole frame, as for photos). ``clip_view`` = (render, coverage) gives the CLIP term (or its
        substitute, whose context is a large part of the frame) another view of the same render than ``render``,
        e.g. the whole frame when ``render`` is a crop of it; ``multiscale_view`` likewise for the broad-strokes term
        (a wider crop: its coarse levels need more context and a coarser pixel grid than NNFM's). With ``together``
        (a dict) the terms that can take several views in one pass (``takes_together``: the broad strokes, the coarse
        CLIP substitute) are not computed: their inputs (render, coverage) are appended to ``together[term]``, for
        ``terms_together`` to take with other views', and the total and the terms' values leave them out."""
        w = self._weights
        terms = dict.fromkeys(TERM_NAMES, render.new_zeros(()))
        small = resize_to_width(render, self.working_width) if (w.nnfm or w.content or w.clip or w.multiscale) \
            else render
        self._vgg_terms(terms, small, gt, gt_feats, coverage)
        for name, view in (("clip", clip_view), ("multiscale", multiscale_view)):
            if getattr(w, name) > 0:
                self._large_pattern_term(terms, name, (small, coverage) if view is None else (
                    resize_to_width(view[0], self.working_width), view[1]), together)
        self._pixel_terms(terms, render, gt, coverage)
        # the total as one dot product of the terms with their weights (0 for the terms left to the caller): two
        # operators, and one in the backward pass, where a sum of weighted terms takes two a term and one a term
        values = torch.stack([terms[name].float().reshape(()) for name in TERM_NAMES])
        return values @ self._weight_vector(frozenset(together or ()), values.device), values.detach()

    def _vgg_terms(self, terms: dict[str, torch.Tensor], small: torch.Tensor, gt: torch.Tensor | None,
                   gt_feats: Mapping[str, torch.Tensor] | torch.Tensor | None, coverage: torch.Tensor | None) -> None:
        """NNFM and content into ``terms``, from one VGG pass over the (resized) render ``small``."""
        w = self._weights
        if not (w.nnfm > 0 or w.content > 0):
            return
        stacked = stacked_features(self.vgg, upsample_for_vgg(small))
        self.calls["vgg"] += 1
        grid = feature_weights(coverage, stacked.shape[-2:])
        if w.nnfm > 0:
            terms["nnfm"] = style_nnfm(stacked, self.style_target, self.nnfm_chunk, weights=grid)
        if w.content > 0:
            if gt_feats is None:
                gt_feats = self.content_features(gt, small.shape[-2:])
            terms["content"] = stacked_content_loss(stacked, concat_features(gt_feats), grid)

    def _large_pattern_term(self, terms: dict[str, torch.Tensor], name: str,
                            view: tuple[torch.Tensor, torch.Tensor | None], together: TermInputs | None) -> None:
        """The CLIP term (or its substitute) or the broad strokes (``name``) on ``view`` = (render, coverage) into
        ``terms``, or its input into ``together`` when the term takes several views in one pass."""
        if together is not None and self.takes_together(name):  # the caller's, with other views' inputs
            together.setdefault(name, []).append(view)
            return
        module = self._together_term(name)
        if name == "multiscale":
            terms[name] = module(*view)
            self.calls["vgg"] += module.passes
            return
        terms[name] = module(*view) if getattr(module, "takes_coverage", False) else module(view[0])
        self.calls[getattr(module, "network", "clip")] += 1

    def _pixel_terms(self, terms: dict[str, torch.Tensor], render: torch.Tensor, gt: torch.Tensor | None,
                     coverage: torch.Tensor | None) -> None:
        """TV, colour smoothness and edges kept into ``terms``, on the full-resolution render."""
        w = self._weights
        if w.tv > 0:
            terms["tv"] = tv_loss(render)
        if w.chroma_tv > 0:  # only the colour variation beyond the painting's own
            terms["chroma_tv"] = (chroma_tv_loss(render, coverage) - self.chroma_floor).clamp_min(0.0)
        if w.edges > 0:
            if gt is None:
                raise ValueError("the edges term needs the content target (gt) at the render's size")
            terms["edges"] = edges_loss(render, gt, coverage)

    def _weight_vector(self, left: frozenset[str], device: torch.device) -> torch.Tensor:
        """The weights in ``TERM_NAMES`` order as a float32 vector on ``device``, 0 for the terms in ``left``;
        made once for each weights, terms left out and device (on a GPU a copy from the CPU's memory would wait for
        the queue to drain on every view)."""
        key = (self._weights, left, device)
        vector = self._weight_vectors.get(key)
        if vector is None:
            if len(self._weight_vectors) > 64:  # sliders make new weights: keep the recent ones only
                self._weight_vectors.clear()
            vector = torch.tensor([0.0 if name in left else float(getattr(self._weights, name))
                                   for name in TERM_NAMES], dtype=torch.float32, device=device)
            self._weight_vectors[key] = vector
        return vector

    def _together_term(self, name: str) -> nn.Module | None:
        """The module of ``name``, one of ``TOGETHER_TERMS``."""
        return {"clip": self.clip_term, "multiscale": self.multiscale_term}[name]

    def takes_together(self, name: str) -> bool:
        """Whether the term ``name`` (one of ``TOGETHER_TERMS``) is on and can take several views in one pass (its
        module has ``per_image``: the broad strokes, the coarse CLIP substitute; CLIP itself cannot)."""
        return getattr(self._weights, name) > 0 and hasattr(self._together_term(name), "per_image")

    def terms_together(self, together: TermInputs) -> dict[str, torch.Tensor]:
        """The terms ``evaluate`` left in ``together``, each view's value: {term: [views]}, in the order the views
        were evaluated; the views of one size go through the network together (``per_image``)."""
        out = {}
        for name, inputs in together.items():
            term = self._together_term(name)
            out[name], passes = per_view_values(term, inputs)
            self.calls[term.network] += passes
        return out

    @torch.no_grad()
    def content_features(self, gt: torch.Tensor | None, size: tuple[int, int] | torch.Size) -> dict[str, torch.Tensor]:
        """VGG features of the ground-truth view [1,3,H,W] at ``size`` (raised to at least ``MIN_VGG_SIDE`` per
        side, as renders are; cache them per view: they never change)."""
        if gt is None:
            raise ValueError("the content term needs the ground-truth view (gt)")
        size = vgg_input_size(size)
        gt_small = gt if gt.shape[-2:] == tuple(size) else F.interpolate(
            gt, size=tuple(size), mode="bilinear", align_corners=False, antialias=True)
        self.calls["vgg"] += 1
        return self.vgg(gt_small)
