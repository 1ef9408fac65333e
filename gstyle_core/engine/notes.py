"""The run's decisions in words (``engine.decisions``, printed by the CLI and written to OUT.json).

Each function writes or returns one entry; none of them changes what a run does.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np

from ..style.clip import CLIP_OFF, clip_status, clip_term_name
from ..style.losses import StyleWeights
from .scene_box import SCENE_BOX_MARGIN_PX, box_fraction, scene_box
from .settings import StylizeSettings

Decisions = dict[str, Any]


def sh_note(degree: int, from_photos: bool, used_degree: int, views: int) -> str:
    """What happens to the scene's view-dependent colour (SH bands of ``degree``, ``used_degree`` non-zero)."""
    if degree == 0:
        return "no view-dependent SH in the scene: nothing to evaluate"
    if from_photos:
        return f"SH degree {degree} never evaluated: ground truth from photos, stylization uses diffuse colour"
    kept = f"degree {used_degree}" if used_degree == degree else f"degree {used_degree} (higher bands are all zero)"
    return (f"SH evaluated only for the {views} ground-truth renders at {kept}; stylization and refits use diffuse "
            "colour only")


def note_planned_clip(decisions: Decisions, s: StylizeSettings) -> None:
    """Before the objective is built: what its CLIP term will be (weights found, or the coarse substitute)."""
    decisions["clip"] = clip_status(s.clip_weights) if s.weights.clip > 0 else CLIP_OFF
    if s.weights.clip == 0 and s.scene_kind == "360" and s.defaults == "calibrated" \
            and clip_term_name(s.clip_weights) != "CLIP":
        decisions["clip"] = ("off: no CLIP weights, and the calibrated 360° defaults leave the coarse substitute off "
                             "(it cost style and structure; README); --lambda-clip turns it on")


def note_networks(decisions: Decisions, objective: Any) -> None:
    """The objective's word on its networks: where the VGG weights and the CLIP term (or substitute) came from, and
    the precision they run in (with the reason)."""
    for key, attr in (("clip", "clip_status"), ("vgg", "vgg_status"), ("precision", "precision_status")):
        status = getattr(objective, attr, None)
        if status is not None:
            decisions[key] = status


def factor_words(factors) -> str:
    """Downsampling factors as words: (2, 4, 8) -> '2x, 4x and 8x'."""
    words = [f"{f:g}x" for f in factors]
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def _broad_stroke_factors(objective: Any) -> tuple[float, ...]:
    """The broad-strokes term's factors: the built term's, else the default."""
    term = getattr(getattr(objective, "loss", None), "multiscale_term", None)
    if term is not None:
        return tuple(term.factors)
    from ..style.multiscale import DEFAULT_FACTORS

    return tuple(float(f) for f in DEFAULT_FACTORS)


def note_loss_terms(decisions: Decisions, s: StylizeSettings, objective: Any) -> None:
    """Which loss terms are computed (weight above 0) and which never are; what the broad-strokes term is, when on."""
    weights = getattr(getattr(objective, "loss", None), "weights", s.weights)
    names = [f.name for f in fields(StyleWeights)]
    on = [k for k in names if getattr(weights, k) > 0]
    off = [k for k in names if k not in on]
    decisions["loss_terms"] = (f"computed: {', '.join(on) or 'none'}; never computed (weight 0): "
                               f"{', '.join(off) or 'none'}")
    decisions.pop("broad_strokes", None)
    if s.weights.multiscale > 0:
        decisions["broad_strokes"] = (
            f"lambda {s.weights.multiscale:g} (multiscale): NNFM on the render and the painting both shrunk "
            f"{factor_words(_broad_stroke_factors(objective))}, for the painting's larger strokes and shapes "
            "(docs/notes/texture-scale.md)"
            + ("; in CLIP's place: no CLIP weights" if clip_term_name(s.clip_weights) != "CLIP" else ""))


def note_style(decisions: Decisions, s: StylizeSettings, objective: Any, paintings: int) -> None:
    """How the painting is matched (stroke size), whether the scene's colours are kept, and the mix of several."""
    note = getattr(objective, "style_note", None)
    decisions["style_scale"] = note or f"stroke size {s.style_scale:g} × the working width"
    decisions["colours"] = (
        "kept (keep colours): luminance-only colour match and networks, chroma of c_gt restored after every step"
        if s.keep_colours else "the painting's (full colour match before and after stylization)")
    if paintings > 1:
        shares = " / ".join(f"{w:.2f}" for w in s.style_weights)
        decisions["styles"] = (f"{paintings} paintings mixed {shares}: each style term is the weighted sum of its "
                               f"terms against each painting, the colour matches map onto the weighted palette")


def network_area_note(s: StylizeSettings, from_photos: bool, coverage: list, region_coverage: list) -> str:
    """What the networks look at during stylization (see ``engine/scene_box.py``)."""
    if from_photos and not region_coverage:
        return "whole frames (photos: the scene fills every view)"
    if not s.crop_to_scene:
        return "whole frames (crop_to_scene = False)"
    if region_coverage:
        share = float(np.mean([box_fraction(scene_box(c), *c.shape) for c in region_coverage]))
        return (f"the box of each view that the selected region covers (+{SCENE_BOX_MARGIN_PX} px): "
                f"{100 * share:.0f} % of the frame's pixels on average; losses weighted by the region's coverage")
    share = float(np.mean([box_fraction(scene_box(c), *c.shape) for c in coverage]))
    return (f"the box of each view that the scene covers (+{SCENE_BOX_MARGIN_PX} px): {100 * share:.0f} % of the "
            f"frame's pixels on average")


def note_levels(decisions: Decisions, s: StylizeSettings, asked: tuple[int, ...] | None = None,
                limit: int | None = None) -> None:
    """The widths the run works at, coarse to fine (``phases/refine.py``), and how the colour matches treat each
    Gaussian's own colour difference (``phases/colour_match.py``). ``asked``: the levels asked for, where the photos'
    width (``limit``) capped them to ``s.refine_widths`` (``levels.capped_levels``): ``levels_capped`` says so."""
    from .levels import level_widths

    widths = level_widths(s.working_width, s.refine_widths)
    if asked is not None and tuple(asked) != tuple(s.refine_widths):
        decisions["levels_capped"] = (
            f"levels {', '.join(f'{w} px' for w in asked)} asked for; the photos are {limit} px wide, so the run "
            f"ends at {widths[-1]} px (a wider level would fit enlarged photos)")
    if len(widths) == 1:
        decisions["levels"] = f"{widths[0]} px only (no finer level)"
    else:
        how = ("working-width-sized crops at each finer width, alternating with whole views at the working width"
               if s.refine_mode == "crops" else
               "whole views at each finer width, alternating with whole views at the working width")
        decisions["levels"] = (f"{' → '.join(f'{w} px' for w in widths)}, coarse to fine: {how}, "
                               f"{s.refine_epochs:g} epochs a level")
    decisions["colour_match"] = (
        f"the broad colours (over {s.match_detail_px:g} px) mapped onto the painting's palette, each Gaussian's finer "
        "difference kept as it is" if s.match_detail_px > 0 and not s.keep_colours else
        "whole colours mapped onto the painting's palette (the paper's match)")
