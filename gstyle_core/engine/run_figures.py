"""The quality figures of a finished run, as ``gstyle stylize`` writes them into OUT.json and the studio's summary
shows them: NNFM drop, content, colour and structure on fixed evaluation views (``evaluate_run``), the same at the
width a run with finer levels ends at (``width_figures``), the texture-scale figure and the speckle figure at a
display's width, with their end-of-run lines."""

from __future__ import annotations

import numpy as np
import torch

from ..style.speckle import DEFAULT_DISPLAY_WIDTH
from .levels import end_width


def evaluation_cameras(engine, n_views: int = 3, width: int = 256) -> list:
    """The fixed views the quality figures are measured on: ``n_views`` training cameras spread over the list
    (``choose_views``), resized to ``width`` px."""
    from .view_choice import choose_views

    return [engine.full_cameras[i].resized_to_width(width) for i in choose_views(engine.full_cameras, n_views)]


def evaluate_run(engine, scene, style: np.ndarray | list[np.ndarray], n_views: int = 3, width: int = 256,
                 display_width: int = 0) -> dict:
    """Quality figures on fixed evaluation views, before (input scene) and after (stylized scene); a list of
    paintings is measured with the engine's mix weights (``Evaluator``). ``display_width`` > 0 adds ``display``, the
    speckle figure of the same views rendered that wide (``run_display_speckle``) and the structure kept there."""
    from ..scene_images import render_scene_image
    from .evaluate import structure_kept

    cams = evaluation_cameras(engine, n_views, width)
    # the run's own network when its objective was built; the figures are measured in fp32 whatever the run's
    # precision and on the CPU whatever the run's device, so that runs at either precision or on any device compare
    vgg = getattr(engine.objective, "vgg", None)
    if (vgg is None or getattr(vgg, "compute_dtype", torch.float32) != torch.float32
            or next(vgg.parameters()).device.type != "cpu"):
        from ..style.vgg import load_vgg

        vgg = load_vgg(engine.settings.vgg_weights)
    ev = figure_evaluator(engine, vgg, style, width, whole_frame=True)
    before, alpha = zip(*(render_scene_image(scene, c, with_alpha=True) for c in cams), strict=True)
    after_scene = engine.stylized_scene()
    after, _ = zip(*(render_scene_image(after_scene, c, with_alpha=True) for c in cams), strict=True)
    before, after, alpha = list(before), list(after), list(alpha)
    initial = ev.measure(before, before, alpha)
    final = ev.measure(after, before, alpha)
    nnfm_drop = 1.0 - final["nnfm"] / max(initial["nnfm"], 1e-12)
    out = {"views": len(cams), "width": width, "initial": initial, "final": final,
           "nnfm_drop": nnfm_drop, "structure": structure_kept(before, after, alpha),
           "texture_scale": run_texture_scale(engine, style, before, after, alpha, width).to_dict()}
    final_width = end_width(engine.settings)
    if final_width > width:  # the run ended at a finer level: its figures there too
        out["at_final_width"] = width_figures(engine, scene, after_scene, style, vgg, n_views, final_width)
    if display_width and display_width > 0:
        renders = display_renders(engine, scene, after_scene, n_views, display_width)
        display = run_display_speckle(engine, scene, after_scene, style, n_views, display_width, renders).to_dict()
        out["display"] = {**display, "structure": structure_kept(*renders[:3])}
    out["images"] = (np.concatenate(before, axis=1), np.concatenate(after, axis=1))
    return out


EVAL_MAX_VECTORS = 16384  # the figures at a finer level's width search at most this many of a painting's vectors


def figure_evaluator(engine, vgg, style, width: int, whole_frame: bool):
    """The ``Evaluator`` of the run's figures at ``width``: the painting(s) with the run's mix weights; at the working
    width (``whole_frame``) every painting vector is searched, at a finer level's width at most ``EVAL_MAX_VECTORS``
    of them (``width_figures``)."""
    from .evaluate import Evaluator

    weights = None if isinstance(style, np.ndarray) else engine.settings.style_weights
    return Evaluator(vgg, style, width, weights=weights, max_vectors=None if whole_frame else EVAL_MAX_VECTORS)


def width_figures(engine, scene, after_scene, style, vgg, n_views: int, width: int) -> dict:
    """NNFM drop and structure of the evaluation views rendered ``width`` px wide (the width a run with finer levels
    ends at), the painting resized to that width; only the covered feature vectors are searched, against at most
    ``EVAL_MAX_VECTORS`` of the painting's (a random subset, the same for before and after)."""
    cams = evaluation_cameras(engine, n_views, width)
    return views_figures(scene, after_scene, cams, figure_evaluator(engine, vgg, style, width, whole_frame=False))


def views_figures(scene, after_scene, cams: list, ev) -> dict:
    """``width_figures`` on given cameras (``cams``, all ``ev.width`` px wide) with a given ``Evaluator``: the NNFM
    drop of ``after_scene`` against ``scene``'s renders over the covered feature vectors, and the structure kept."""
    from ..scene_images import render_scene_image
    from .evaluate import structure_kept

    before, alpha = zip(*(render_scene_image(scene, c, with_alpha=True) for c in cams), strict=True)
    after = [render_scene_image(after_scene, c) for c in cams]
    initial = ev.measure(list(before), list(before), list(alpha), whole_frame=False)
    final = ev.measure(after, list(before), list(alpha), whole_frame=False)
    return {"width": ev.width, "nnfm_initial": initial["nnfm"], "nnfm_final": final["nnfm"],
            "nnfm_drop": 1.0 - final["nnfm"] / max(initial["nnfm"], 1e-12),
            "structure": structure_kept(list(before), after, list(alpha))}


def texture_scale_line(ts: dict) -> str:
    """The end-of-run line of the texture-scale figure (from ``TextureScale.to_dict()``)."""
    from ..style.texture_scale import TextureScale

    return TextureScale(tuple(ts["added"].values()), tuple(ts["painting"].values()), ts["painting_side"]).line()


def run_texture_scale(engine, style, before, after, alpha, width: int):
    """The texture-scale figure (``style/texture_scale.py``) of evaluation renders ``width`` px wide: band shares of
    what stylization added inside the scene beside the painting's own at the size it is matched (its luminance with
    keep colours: only that pattern is transferred)."""
    from ..style.keep_colours import grey
    from ..style.texture_scale import matched_side, texture_scale

    s = engine.settings
    paintings = [style] if isinstance(style, np.ndarray) else list(style)
    if s.keep_colours:
        paintings = [grey(np.asarray(p, np.float32)) for p in paintings]
    side = matched_side(s.working_width, s.style_scale, width)
    weights = None if len(paintings) == 1 else s.style_weights
    return texture_scale(before, after, [np.asarray(a) for a in alpha], paintings, side, weights)


def display_renders(engine, scene, after_scene, n_views: int, width: int) -> tuple[list, list, list, list]:
    """The evaluation views rendered ``width`` px wide: before and after stylization, each with its coverage
    (alpha): ``(before, after, alpha_before, alpha_after)``."""
    from ..scene_images import render_scene_image

    cams = evaluation_cameras(engine, n_views, width)
    before, alpha = zip(*(render_scene_image(scene, c, with_alpha=True) for c in cams), strict=True)
    after, alpha_after = zip(*(render_scene_image(after_scene, c, with_alpha=True) for c in cams), strict=True)
    return list(before), list(after), [np.asarray(a) for a in alpha], [np.asarray(a) for a in alpha_after]


def run_display_speckle(engine, scene, after_scene, style, n_views: int, width: int,
                        renders: tuple[list, list, list, list] | None = None):
    """The speckle figure (``style/speckle.py``) of the evaluation views rendered ``width`` px wide (``renders``:
    those of ``display_renders`` when already made): the fine share of the chroma stylization added inside the scene
    against the painting's own at its matched size in those pixels (its luminance with keep colours, where only that
    pattern is transferred); with the fringe halo of the same renders (``style/fringe.py``) in its ``fringe``."""
    from dataclasses import replace

    from ..style.fringe import fringe_halo
    from ..style.speckle import display_speckle
    from ..style.texture_scale import matched_side

    s = engine.settings
    before, after, alpha, alpha_after = renders or display_renders(engine, scene, after_scene, n_views, width)
    paintings = [style] if isinstance(style, np.ndarray) else list(style)
    speckle = display_speckle(before, after, alpha, paintings, matched_side(s.working_width, s.style_scale, width),
                              None if len(paintings) == 1 else s.style_weights,
                              channels="luminance" if s.keep_colours else "chroma")
    return replace(speckle, fringe=fringe_halo(before, after, alpha, alpha_after).to_dict())


def result_summary(engine, width: int = DEFAULT_DISPLAY_WIDTH) -> dict:
    """What a finished run's summary shows (the studio's): the speckle figure of the evaluation views at a display's
    ``width`` and the widths the run worked at."""
    before = getattr(engine, "full_input", engine.input_scene)  # the whole capture, as the result is
    display = run_display_speckle(engine, before, engine.stylized_scene(), engine.style_input(), 3, width).to_dict()
    return {"display": display, "levels": list(engine.levels), "line": display_speckle_line(display)}


def display_speckle_line(display: dict) -> str:
    """The end-of-run line of the speckle figure (from ``DisplaySpeckle.to_dict()``)."""
    ratio = display["speckle_ratio"]
    views = " / ".join("-" if r is None else f"{r:.2f}" for r in display["speckle_ratio_per_view"])
    value = "- (no detail to compare)" if ratio is None else f"{ratio:.2f}"
    return (f"speckle at {display['width']} px ({display['channels']} finer than σ 4 px, added over the painting's at "
            f"{display['painting_side']} px): {value} (views {views}; 1: the painting's grain, above: specks)")
