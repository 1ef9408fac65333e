"""The stylization objective as the engine uses it: networks built once, content features cached per view."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict

import numpy as np
import torch

from ..style.clip import CLIP_OFF
from ..style.features import concat_features
from ..style.losses import TERM_NAMES, TOGETHER_TERMS, TermInputs, term_values
from ..style.painting_size import MAX_STYLE_SIDE, MIN_STYLE_SIDE, resize_long_side, style_side
from .scene_box import SCENE_BOX_ALIGN_PX, SCENE_BOX_MARGIN_PX, scene_box
from .settings import StylizeSettings


def to_bchw(img: np.ndarray | torch.Tensor) -> torch.Tensor:
    """[H, W, 3] image -> float32 [1, 3, H, W] tensor."""
    return torch.as_tensor(img, dtype=torch.float32).permute(2, 0, 1)[None].contiguous()


STYLE_TERMS = ("clip", "nnfm", "multiscale")  # the terms the style strength multiplies


class StyleObjective:
    """λ_CLIP·L_CLIP + λ_NNFM·L_NNFM + λ_C·L_content + λ_TV·L_TV (+ λ_MS·L_broad strokes) on a render [H, W, 3] of one
    view.

    The style image is resized so that its longer side is ``style_scale`` × max(64, working width), clamped to
    16-1024 px: the scale at which brush strokes are matched (``style_side``). ``style`` may be a list of paintings
    mixed with the settings' ``style_weights`` (``style/mix.py``: every style term is the weighted sum of its terms
    against each painting; ``set_style_weights`` changes the mix without re-extracting anything). With
    ``keep_colours`` the networks see luminance only (render, content view and painting as grey images;
    ``style/keep_colours.py``).
    CLIP ViT-B/32 is used when its weights are found; otherwise the documented coarse-VGG substitute
    (``clip_status`` says which). The broad-strokes term (``style/multiscale.py``) matches the same resized paintings
    downsampled ×2, ×4 and ×8. ``refresh_style()`` re-extracts the style features after either setting changed.
    """

    luminance_networks = True  # keep colours: networks see luminance (False: colour, chroma restored only; the
    # variant bench/studies/keep_colours.py compares)

    def __init__(self, style: np.ndarray | Sequence[np.ndarray], settings: StylizeSettings, vgg=None,
                 width: int | None = None, terms: Sequence[str] | None = None) -> None:
        """``width``: the render width the painting is matched for (default: the settings' working width; a finer
        level's objective gives its own, ``phases/refine.py``). ``terms``: the only terms this objective computes
        (None: all; a crop of a finer level leaves the large-pattern terms to the whole views)."""
        from ..device import resolve_device
        from ..style.losses import StyleLoss
        from ..style.precision import resolve_precision, torch_dtype
        from ..style.vgg import load_vgg

        # the networks' device: the given network's, else the settings' (device.py); renders are moved there
        self.device = next(vgg.parameters()).device if vgg is not None else resolve_device(settings.device).device
        self.width = width
        self.terms = None if terms is None else frozenset(terms)
        self.precision, self.precision_status = resolve_precision(settings, vgg)  # fp32 | bf16, and why
        dtype = torch_dtype(self.precision)
        if vgg is None:
            vgg = load_vgg(settings.vgg_weights, dtype=dtype, channels_last=dtype == torch.bfloat16).to(self.device)
        self.vgg = vgg
        self.vgg_status = f"VGG-16 weights from {getattr(vgg, 'weights_source', 'the caller')}"
        self._styles = [style] if isinstance(style, np.ndarray) else list(style)
        self._settings = settings
        self._clip_encoder = None
        self._built_for: tuple[bool, float] | None = None
        self._build_style_target()
        self.clip_status = CLIP_OFF
        wanted = self._effective(settings.weights)
        clip_term = self._build_clip_term() if wanted["clip"] > 0 else None
        multiscale_term = self._build_multiscale_term() if wanted["multiscale"] > 0 else None
        self.loss = StyleLoss(self.vgg, self.target, clip_term, weights=wanted, multiscale_term=multiscale_term)
        self.loss.chroma_floor = self._chroma_floor()
        self._content_cache: dict[int, torch.Tensor] = {}  # per view: its relu3 features, stacked
        self._boxes: dict[tuple[int, tuple[int, ...]], tuple[slice, slice] | None] = {}
        # per training view: (content, coverage as given, their copies on the networks' device)
        self._device_inputs: dict[int, tuple[torch.Tensor, torch.Tensor | None, torch.Tensor, torch.Tensor | None]] = {}

    def _style_input(self, style: np.ndarray) -> np.ndarray:
        """A painting as the networks see it: its luminance as grey with keep colours, else as it is."""
        from ..style.keep_colours import grey

        return grey(np.asarray(style, np.float32)) if self._luminance_only() else style

    def _style_weights(self) -> tuple[float, ...] | None:
        """The paintings' weights (None for one painting)."""
        from ..style.mix import normalise_style_weights

        if len(self._styles) == 1:
            return None
        return normalise_style_weights(self._settings.style_weights, len(self._styles))

    def _luminance_only(self) -> bool:
        return bool(self._settings.keep_colours) and self.luminance_networks

    def _build_style_target(self) -> None:
        """Resize the painting for the current stroke size and extract its VGG features (the NNFM candidates)."""
        from ..style.nnfm import StyleTarget, WeightedTargets

        s = self._settings
        side, clamped = style_side(self.width or s.working_width, s.style_scale)
        self._styles_small = [to_bchw(resize_long_side(self._style_input(style), side)).to(self.device)
                              for style in self._styles]
        self._style_small = self._styles_small[0]
        budget = int(s.nnfm_candidates) or None
        targets = [StyleTarget.from_image(self.vgg, small, max_vectors=budget,
                                          generator=torch.Generator().manual_seed(s.seed))
                   for small in self._styles_small]
        weights = self._style_weights()
        self.target = targets[0] if weights is None else WeightedTargets(targets, weights)
        sizes = " and ".join(f"{small.shape[-1]}×{small.shape[-2]}" for small in self._styles_small)
        limits = f" (clamped to {MIN_STYLE_SIDE}-{MAX_STYLE_SIDE} px)" if clamped else ""
        vectors = sum(t.matrix.shape[1] for t in targets)
        subset = (f" (at most {budget:,} of each painting's, drawn at random)" if budget is not None
                  and any(t.matrix.shape[1] == budget for t in targets) else "")
        width = "the working width" if self.width is None else f"{self.width} px"
        self._matched_note = (f"matched at {sizes} px{limits}: stroke size {s.style_scale:g} × {width}; "
                              f"{vectors:,} feature vectors{subset}"
                              + ("; luminance only (keep colours)" if self._luminance_only() else ""))
        self._write_style_note()
        self._built_for = (bool(s.keep_colours), float(s.style_scale))

    def refresh_style(self) -> bool:
        """Re-extract the style features (NNFM target, the coarse CLIP substitute; CLIP's style embedding) when the
        settings' ``style_scale`` or ``keep_colours`` changed since they were built; True when they were. Otherwise
        only the settings' mix weights are applied (``set_style_weights``)."""
        s = self._settings
        if self._built_for == (bool(s.keep_colours), float(s.style_scale)):
            self.set_style_weights()
            return False
        colours_changed = self._built_for is None or self._built_for[0] != bool(s.keep_colours)
        self._build_style_target()
        self.loss.style_target = self.target
        if self.loss.clip_term is not None:
            old_gen = getattr(self.loss.clip_term, "generator", None)
            self.loss.clip_term = self._build_clip_term()
            new_gen = getattr(self.loss.clip_term, "generator", None)
            if isinstance(old_gen, torch.Generator) and isinstance(new_gen, torch.Generator):
                new_gen.set_state(old_gen.get_state())  # CLIP's random crops go on where they were
        if self.loss.multiscale_term is not None:
            self.loss.multiscale_term = self._build_multiscale_term()
        self.loss.chroma_floor = self._chroma_floor()
        if colours_changed:  # content features are of grey or colour views
            self._content_cache.clear()
        return True

    def set_style_weights(self) -> None:
        """Apply the settings' ``style_weights`` to the NNFM targets and the CLIP term (nothing is re-extracted)."""
        from ..style.nnfm import WeightedTargets

        weights = self._style_weights()
        if weights is None:
            return
        if isinstance(self.target, WeightedTargets):
            self.target.weights = weights
        if self.loss.clip_term is not None and hasattr(self.loss.clip_term, "set_style_weights"):
            self.loss.clip_term.set_style_weights(weights)
        if self.loss.multiscale_term is not None:
            self.loss.multiscale_term.set_style_weights(weights)
        self.loss.chroma_floor = self._chroma_floor()
        self._write_style_note()

    def _write_style_note(self) -> None:
        weights = self._style_weights()
        mixed = "painting" if weights is None else (
            f"{len(weights)} paintings mixed {' / '.join(f'{w:.2f}' for w in weights)}, each")
        self.style_note = f"{mixed} {self._matched_note}"

    def _chroma_floor(self) -> float:
        """The colour-smoothness term's floor: the chroma variation per pixel (``chroma_tv_loss``) of the painting(s)
        as matched (weighted over a mix): the render may be as grainy in colour as the painting, not more."""
        from ..style.pixel_terms import chroma_tv_loss

        weights = self._style_weights() or (1.0,)
        with torch.no_grad():
            return float(sum(w * chroma_tv_loss(small) for w, small in zip(weights, self._styles_small, strict=True)))

    def clear_content_cache(self) -> None:
        """Forget the content views' features and device copies (the engine changed its content targets)."""
        self._content_cache.clear()
        self._device_inputs.clear()

    def _build_clip_term(self) -> torch.nn.Module:
        """CLIP ViT-B/32 on the style when its weights are found, else the coarse-VGG substitute (built when λ_CLIP
        first becomes non-zero)."""
        from ..style.clip import ClipStyleLoss, CoarseStyleLoss, load_clip

        if self._clip_encoder is None:
            encoder, self.clip_status = load_clip(self._settings.clip_weights)
            self._clip_encoder = encoder.to(self.device) if encoder is not None else False
        weights = self._style_weights()
        if self._clip_encoder is False:
            return CoarseStyleLoss(self.vgg, self._styles_small, style_weights=weights).to(self.device)
        return ClipStyleLoss(self._clip_encoder, [to_bchw(resize_long_side(self._style_input(style), 448)).to(
                                                  self.device) for style in self._styles],
                             generator=torch.Generator().manual_seed(self._settings.seed),
                             style_weights=weights).to(self.device)

    def _build_multiscale_term(self) -> torch.nn.Module:
        """The broad-strokes term on the NNFM target's own resized paintings (built when its weight is non-zero)."""
        from ..style.multiscale import MultiScaleStyleLoss

        return MultiScaleStyleLoss(self.vgg, self._styles_small, style_weights=self._style_weights()).to(self.device)

    @property
    def calls(self) -> dict[str, int]:
        """Network runs so far (``vgg``, ``clip``)."""
        return self.loss.calls

    def _effective(self, weights) -> dict[str, float]:
        """λ weights as the loss uses them: the style terms (CLIP, NNFM, broad strokes) times the style strength."""
        w = asdict(weights)
        strength = float(self._settings.strength)
        for term in STYLE_TERMS:
            w[term] *= strength
        if self.terms is not None:
            w = {name: value if name in self.terms else 0.0 for name, value in w.items()}
        return w

    def set_weights(self, weights) -> None:
        """Change λ weights (a ``StyleWeights``; the settings' strength applies); the CLIP term (or its substitute)
        and the broad-strokes term are built the first time their weight is non-zero."""
        w = self._effective(weights)
        if w["clip"] > 0 and self.loss.clip_term is None:
            self.loss.clip_term = self._build_clip_term()
        if w["multiscale"] > 0 and self.loss.multiscale_term is None:
            self.loss.multiscale_term = self._build_multiscale_term()
        self.loss.weights = w

    def __call__(self, image: torch.Tensor, content: torch.Tensor, view: int | None,
                 coverage: torch.Tensor | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """The loss and each term's value (``evaluate``'s, read); the arguments are ``evaluate``'s."""
        loss, values = self.evaluate(image, content, view, coverage)
        return loss, term_values(values)

    def takes_views_together(self, count: int) -> bool:
        """Whether ``count`` views gain from going through ``backward_views`` together: a term whose network takes
        several views in one pass is on (the broad strokes, the coarse CLIP substitute: ``StyleLoss.takes_together``)
        and there is more than one view."""
        return count > 1 and any(self.loss.takes_together(name) for name in TOGETHER_TERMS)

    def backward_views(self, images: Sequence[torch.Tensor], contents: Sequence[torch.Tensor],
                       views: Sequence[int | None], coverages: Sequence[torch.Tensor | None], scale: float
                       ) -> tuple[torch.Tensor, torch.Tensor]:
        """Evaluate a step's views (``evaluate``'s arguments, one entry per view) and backpropagate their losses times
        ``scale`` into ``images``: each view's own terms one view at a time, the terms that take views together for
        all of them at once (views of one size through the network in one pass: ``StyleLoss.terms_together``).
        Returns the sum of the views' losses and of their terms' values (``TERM_NAMES`` order), unread."""
        together: TermInputs | None = {} if self.takes_views_together(len(images)) else None
        total = values = None
        for image, content, view, coverage in zip(images, contents, views, coverages, strict=True):
            loss, view_values = self.evaluate(image, content, view, coverage, together=together)
            # the inputs left in ``together`` share their first operators with the view's own terms (keep colours'
            # luminance, a resize): the view's backward keeps those saved for the backward of the terms taken
            # together; the rest of the view's graph goes with ``loss`` below
            if loss.requires_grad:  # False when every term of the view is off or left to ``together``
                (loss * scale).backward(retain_graph=together is not None)
            total = loss.detach() if total is None else total + loss.detach()
            values = view_values if values is None else values + view_values
            del loss
        if together:
            values = values.clone()
            weighted = None
            for name, per_view in self.loss.terms_together(together).items():
                value = per_view.sum()
                term = getattr(self.loss.weights, name) * value
                weighted = term if weighted is None else weighted + term
                values[TERM_NAMES.index(name)] += value.detach()
            (weighted * scale).backward()
            total = total + weighted.detach()
        return total, values

    def evaluate(self, image: torch.Tensor, content: torch.Tensor, view: int | None,
                 coverage: torch.Tensor | None = None, together: TermInputs | None = None
                 ) -> tuple[torch.Tensor, torch.Tensor]:
        """Loss of a render [H,W,3] of training view ``view``, and its terms' values unread (``StyleLoss.evaluate``);
        ``content`` is its colour-matched ground truth and ``coverage`` [H,W] the scene's alpha there (None for
        photos: the whole frame is the scene). With ``crop_to_scene`` VGG sees only the box the scene covers
        (``engine/scene_box.py``); with ``keep_colours`` the networks see the luminance of both. ``view`` None: a
        one-off image (a crop): nothing of it is cached. Inputs on another device than the networks' are moved there
        (the render inside the autograd graph; a view's content and coverage once, while they are the same).
        ``together``: ``StyleLoss.evaluate``'s (the terms that take views together left to the caller)."""
        image = image.to(self.device)
        coverage = None if coverage is None else torch.as_tensor(coverage)
        # the scene's box is found on the CPU's copy of the coverage: on a GPU its reads would wait for the queue
        box_coverage = None if coverage is None else coverage.detach().cpu()
        content, coverage = self._view_inputs(view, content, coverage)
        if self._luminance_only():
            from ..style.keep_colours import grey

            image, content = grey(image), grey(content)
        box = self.network_box(view, box_coverage)
        clip_view = multiscale_view = None
        if box is not None:  # VGG on the box; the CLIP term (or its coarse substitute) keeps the whole frame
            clip_view = (image.permute(2, 0, 1)[None], coverage)
            if self.loss.weights.multiscale > 0:  # its coarsest level: a box grown and aligned by its factor
                grow = int(math.ceil(max(self.loss.multiscale_term.factors)))
                wide = self.network_box(view, box_coverage, grow=grow)
                multiscale_view = clip_view if wide is None else (image[wide].permute(2, 0, 1)[None], coverage[wide])
            image, content, coverage = image[box], content[box], coverage[box]
        render = image.permute(2, 0, 1)[None]
        gt_feats = None
        if self.loss.weights.content > 0:
            gt_feats = self._content_cache.get(view) if view is not None else None
            if gt_feats is None:
                gt_feats = concat_features(self.loss.content_features(content.permute(2, 0, 1)[None],
                                                                      render.shape[-2:]))
                if view is not None:
                    self._content_cache[view] = gt_feats
        gt = content.permute(2, 0, 1)[None] if self.loss.weights.edges > 0 else None  # at the render's size
        return self.loss.evaluate(render, gt=gt, gt_feats=gt_feats, coverage=coverage, clip_view=clip_view,
                                  multiscale_view=multiscale_view, together=together)

    def _view_inputs(self, view: int | None, content: torch.Tensor, coverage: torch.Tensor | None
                     ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """``content`` and ``coverage`` on the networks' device; a training view's copies are kept while the engine
        gives the same tensors (on a GPU each copy from the CPU waits for the queue to drain)."""
        if view is None or self.device.type == "cpu":
            return content.to(self.device), None if coverage is None else coverage.to(self.device)
        kept = self._device_inputs.get(view)
        if kept is None or kept[0] is not content or kept[1] is not coverage:
            kept = (content, coverage, content.to(self.device), None if coverage is None else coverage.to(self.device))
            self._device_inputs[view] = kept
        return kept[2], kept[3]

    def network_box(self, view: int | None, coverage: torch.Tensor | None, grow: int = 1) -> tuple[slice, slice] | None:
        """The view's scene box (fixed per view: the coverage is the ground truth's), None for the whole frame.
        ``grow``: margin and alignment times this (the broad-strokes term's coarsest downsampling factor: at ×4 a
        pixel of its level is 4 of the render's, so the same context and pooling grid need 4× the pixels)."""
        if coverage is None or not self._settings.crop_to_scene or self.loss.working_width is not None:
            return None
        if view is None:
            return scene_box(coverage, SCENE_BOX_MARGIN_PX * grow, SCENE_BOX_ALIGN_PX * grow)
        key = (view, tuple(coverage.shape), grow)
        if key not in self._boxes:
            self._boxes[key] = scene_box(coverage, SCENE_BOX_MARGIN_PX * grow, SCENE_BOX_ALIGN_PX * grow)
        return self._boxes[key]

