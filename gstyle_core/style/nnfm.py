"""NNFM (ARF): every render feature vector (relu3_1|relu3_2|relu3_3, 768 channels) against its nearest painting
vector by cosine distance. The nearest-neighbour search runs without gradients, in chunks, in the precision of the
network the painting's target was taken with; the gradient flows through the render side only (the painting's side
is a constant), in closed form (``CosineDistance``). Several paintings: Σ w_i · NNFM_i (``WeightedTargets``)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import torch
import torch.nn.functional as F
from torch import nn

from .features import NORM_EPS, normalise_vectors, stacked_features, vector_norms, weighted_mean


class CosineDistance(torch.autograd.Function):
    """1 − cos between the rows of ``vectors`` [N, C] and unit rows ``matched`` [N, C] (constant), given the rows'
    ``norms`` [N] (:func:`vector_norms`): d = 1 − v·m / s. Its gradient in closed form,
    ∂d/∂v = (v·m / s² · v − m) / s, is a handful of operators where autograd through the normalisation takes
    seventeen (each one a kernel launch on a GPU) and as many temporaries the size of the features."""

    @staticmethod
    def forward(ctx, vectors: torch.Tensor, matched: torch.Tensor, norms: torch.Tensor) -> torch.Tensor:
        dots = (vectors * matched).sum(1)
        ctx.save_for_backward(vectors, matched, norms, dots)
        return 1.0 - dots / norms

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> tuple[torch.Tensor, None, None]:
        vectors, matched, norms = ctx.saved_tensors[:3]
        dots = ctx.saved_tensors[3]
        scale = grad / norms  # [N]
        along = dots / (norms * norms)  # [N]
        return (vectors * along[:, None] - matched) * scale[:, None], None, None


class StyleTarget:
    """Style image → unit-normalised VGG feature matrix [C, M] (computed once), optionally at several
    scales of the style image (features of all scales are pooled into one set of candidates)."""

    def __init__(self, matrix: torch.Tensor, scales: tuple[float, ...] = (1.0,),
                 search_dtype: torch.dtype = torch.float32) -> None:
        if matrix.ndim != 2:
            raise ValueError(f"style feature matrix must be [C, M], got {tuple(matrix.shape)}")
        self.matrix = matrix.detach()
        self.scales = scales
        self.search_matrix = self.matrix.to(search_dtype)  # what the NNFM search multiplies (style/precision.py)

    @classmethod
    def from_image(cls, vgg: nn.Module, style_image: torch.Tensor, scales: Iterable[float] = (1.0,),
                   max_vectors: int | None = None, generator: torch.Generator | None = None) -> StyleTarget:
        """Run ``vgg`` on ``style_image`` [1,3,H,W] (RGB [0,1]) at each scale; ``max_vectors`` keeps a random
        subset of the candidates to bound memory (None keeps all)."""
        scales = tuple(scales)
        columns = []
        with torch.no_grad():
            for scale in scales:
                img = style_image
                if scale != 1.0:
                    size = (max(8, round(img.shape[-2] * scale)), max(8, round(img.shape[-1] * scale)))
                    img = F.interpolate(img, size=size, mode="bilinear", align_corners=False, antialias=scale < 1)
                feats = stacked_features(vgg, img)
                columns.append(feats.permute(1, 0, 2, 3).flatten(1))  # [C, B*h*w]
        matrix = torch.cat(columns, dim=1)
        if max_vectors is not None and matrix.shape[1] > max_vectors:
            keep = torch.randperm(matrix.shape[1], generator=generator)[:max_vectors]
            matrix = matrix[:, keep]
        return cls(normalise_vectors(matrix.float(), dim=0), scales,
                   search_dtype=getattr(vgg, "compute_dtype", torch.float32))  # a bf16 network: a bf16 search

    @classmethod
    def from_features(cls, style_feats: torch.Tensor) -> StyleTarget:
        """From raw features [C, hs, ws] or [1, C, hs, ws]."""
        if style_feats.ndim == 4:
            style_feats = style_feats.permute(1, 0, 2, 3)
        return cls(normalise_vectors(style_feats.detach().flatten(1).float(), dim=0))


class WeightedTargets:
    """The style targets of several paintings with weights that sum to 1 (``style/mix.py``): NNFM against them is
    Σ w_i · NNFM_i over one set of render features; a painting of weight 0 is skipped."""

    def __init__(self, targets: Sequence[StyleTarget], weights: Sequence[float]) -> None:
        if len(targets) != len(weights) or not targets:
            raise ValueError(f"{len(weights)} weight(s) for {len(targets)} style target(s)")
        self.targets = list(targets)
        self.weights = tuple(float(w) for w in weights)

    @property
    def vector_count(self) -> int:
        """Candidate feature vectors over all paintings."""
        return sum(t.matrix.shape[1] for t in self.targets)


def style_nnfm(render_feats: torch.Tensor, style: StyleTarget | WeightedTargets | torch.Tensor, chunk: int = 4096,
               weights: torch.Tensor | None = None) -> torch.Tensor:
    """NNFM against one painting (:func:`nnfm_loss`) or a mix of them (Σ w_i · NNFM_i, weight-0 paintings
    skipped); ``weights`` are the feature positions' weights, as for :func:`nnfm_loss`."""
    if not isinstance(style, WeightedTargets):
        return nnfm_loss(render_feats, style, chunk, weights=weights)
    terms = [w * nnfm_loss(render_feats, t, chunk, weights=weights)
             for t, w in zip(style.targets, style.weights, strict=True) if w > 0]
    return torch.stack(terms).sum() if terms else render_feats.new_zeros(())


def style_nnfm_per_image(render_feats: torch.Tensor, style: StyleTarget | WeightedTargets, chunk: int = 4096,
                         weights: torch.Tensor | None = None) -> torch.Tensor:
    """:func:`style_nnfm` of each image of a batch of features [B, C, h, w] on its own: [B], each image's mean over
    its own feature positions (weighted by its ``weights`` [B, 1, h, w]), as :func:`style_nnfm` gives for that image
    alone. The searches of the batch run together."""
    pairs = ([(style, 1.0)] if not isinstance(style, WeightedTargets)
             else [(t, w) for t, w in zip(style.targets, style.weights, strict=True) if w > 0])
    if not pairs:
        return render_feats.new_zeros(render_feats.shape[0])
    maps = [w * nnfm_loss(render_feats, t, chunk, reduction="none") for t, w in pairs]  # [B, h, w] each
    distances = maps[0] if len(maps) == 1 else torch.stack(maps).sum(0)
    if weights is None:
        return distances.flatten(1).mean(1)
    w = weights.flatten(1)
    return (distances.flatten(1) * w).sum(1) / w.sum(1).clamp_min(NORM_EPS)


def _style_matrix(style: StyleTarget | torch.Tensor) -> torch.Tensor:
    if isinstance(style, StyleTarget):
        return style.matrix
    if style.ndim == 2:  # already a normalised [C, M] matrix
        return style.detach()
    return StyleTarget.from_features(style).matrix


def nearest_indices(scores: torch.Tensor) -> torch.Tensor:
    """Each row's index of its largest score (the first of equal ones); bf16 through ``max``, as fast as fp32's
    ``argmax`` where bf16's ``argmax`` is ~5× slower on CPUs."""
    return scores.argmax(dim=1) if scores.dtype == torch.float32 else scores.max(dim=1).indices


def nnfm_loss(render_feats: torch.Tensor, style: StyleTarget | torch.Tensor, chunk: int = 4096,
              reduction: str = "mean", weights: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over render vectors of min over style vectors of (1 − cos). ``render_feats`` [B,C,h,w];
    ``style`` a :class:`StyleTarget`, raw features [C,hs,ws] or a normalised matrix [C,M]. The
    nearest-neighbour search runs in chunks of ``chunk`` render vectors, without gradients.
    ``weights`` [B,1,h,w] (:func:`feature_weights`) make it a weighted mean over the scene's feature vectors.
    ``reduction="none"`` returns the distance of every render vector, [B, h, w]. The search runs in the dtype of
    a :class:`StyleTarget`'s ``search_matrix`` (bf16 for a target taken with a bf16 network); distances are fp32."""
    style_matrix = _style_matrix(style).to(render_feats.device)
    search_matrix = style.search_matrix.to(render_feats.device) if isinstance(style, StyleTarget) else style_matrix
    if render_feats.ndim != 4 or render_feats.shape[1] != style_matrix.shape[0]:
        raise ValueError(f"render features {tuple(render_feats.shape)} do not match style channels "
                         f"{style_matrix.shape[0]}")
    if style_matrix.shape[1] == 0:
        raise ValueError("the style target has no feature vectors")
    if render_feats.numel() == 0:
        raise ValueError(f"the render has no feature vectors (features {tuple(render_feats.shape)})")
    vectors = render_feats.float().permute(0, 2, 3, 1).flatten(0, 2)  # [N, C]
    with torch.no_grad():
        norms = vector_norms(vectors)
        queries = (vectors / norms[:, None]).to(search_matrix.dtype)
        blocks = queries.split(max(1, chunk))
        nearest = (nearest_indices(blocks[0] @ search_matrix) if len(blocks) == 1
                   else torch.cat([nearest_indices(block @ search_matrix) for block in blocks]))
        matched = style_matrix.index_select(1, nearest).t().contiguous()  # [N, C], constant (a gather of whole
        # columns: ~6× faster than indexing the transposed view's rows, the same values)
    distances = CosineDistance.apply(vectors, matched, norms)
    if reduction == "none":
        b, _, h, w = render_feats.shape
        return distances.reshape(b, h, w)
    if weights is not None:
        b, _, h, w = render_feats.shape
        return weighted_mean(distances.reshape(b, 1, h, w), weights)
    return distances.mean()
