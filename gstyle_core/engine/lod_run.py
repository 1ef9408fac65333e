"""A run on the level of detail's cut (``gstyle_core/lod``): decided before anything large is built, undone when the
result is made.

``plan_cut`` merges the Gaussians far below a pixel at the run's finest width (the working width, or the last of
its finer levels) into parents; the run then holds the parents (and the capacity plan is made over them). The ground
truth is still rendered from the whole capture, so pre-processing and refits fit the parents to what every Gaussian
shows. ``whole_capture`` turns the run's result back into every input Gaussian: rows of parents that were input
Gaussians as the run left them, the children of merged parents with their own geometry and their own colour plus
their parent's change (``lod.carry``). The decision is one line (``LodCut.note``), printed before the run starts and
kept in OUT.json under ``decisions.lod``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cameras.camera import Camera
from ..lod import LodCut, build_cut, expand_to_children
from ..lod.carry import carried_colours, descendant_rows
from ..scene import GaussianScene
from .capacity import CapacityPlan

# "auto" cuts captures denser than this at the run's width. Measured (docs/notes/captures.md, "The level of detail"): at
# 3.1 Gaussians a pixel (biker's first 150k at 256 px) a cut (of an earlier rule) saved 7 % of the time and cost 3
# points of the NNFM drop; at 27 (1.2 M) it took the run from 237 to 58 s.
AUTO_GAUSSIANS_PER_PIXEL = 4.0


def cut_width(settings) -> int:
    """The width the cut is made for: the finest the run renders at (its working width or its last finer level)."""
    return int(max([settings.working_width, *settings.refine_widths]))


def gaussians_per_pixel(count: int, cameras: Sequence[Camera], width: int) -> float:
    """Gaussians per pixel of a training view ``width`` px wide (the views' mean pixel count)."""
    pixels = np.mean([c.width * c.height for c in (cam.resized_to_width(width) for cam in cameras)])
    return count / max(float(pixels), 1.0)


def plan_cut(scene: GaussianScene, selection: np.ndarray | None, cameras: Sequence[Camera],
             settings) -> tuple[LodCut | None, str]:
    """The cut a run with ``settings`` makes of ``scene`` for its training ``cameras`` (None: off, or nothing to
    merge) and the decision in words."""
    if settings.lod == "off":
        return None, "off (--lod off): every Gaussian is stylized on its own"
    width = cut_width(settings)
    density = gaussians_per_pixel(scene.count, cameras, width)
    if settings.lod == "auto" and density <= AUTO_GAUSSIANS_PER_PIXEL:
        return None, (f"off (auto): {density:.1f} Gaussians a pixel at {width} px, at most "
                      f"{AUTO_GAUSSIANS_PER_PIXEL:g}: every Gaussian is stylized on its own")
    cut = build_cut(scene, cameras, width, float(settings.lod_pixels), selection, float(settings.lod_merge_size))
    if not cut.merged.any():
        return None, (f"no Gaussian below {settings.lod_pixels:g} px at {cut.width} px: all {scene.count:,} held "
                      "as they are")
    return cut, cut.note


def whole_capture(result: GaussianScene, run_base_rgb: np.ndarray, run_lineage: np.ndarray,
                  capacity: CapacityPlan, cut: LodCut, full_input: GaussianScene,
                  full_selection: np.ndarray | None, keep_colours: bool = False) -> GaussianScene:
    """Every input Gaussian from a run on ``cut``. ``result``: the run's rows (their colour before stylization
    ``run_base_rgb`` and parent among the held parents ``run_lineage``) followed by the parents
    the capacity plan did not hold (``capacity.with_neighbour_colours``); each row's change is its colour now
    minus its colour before."""
    parents = cut.parents
    if capacity.reduced:
        rest = np.ones(parents.count, bool)
        rest[capacity.held] = False
        lineage = np.concatenate([capacity.held[run_lineage], np.flatnonzero(rest)])
        base = np.concatenate([run_base_rgb, parents.rgb[rest]])
    else:
        lineage, base = np.asarray(run_lineage, np.int64), run_base_rgb
    if len(lineage) != result.count:
        raise ValueError(f"whole_capture: {result.count:,} rows but {len(lineage):,} parents for them")
    deltas = result.rgb.astype(np.float64) - base
    return expand_to_children(result, deltas, lineage, cut, full_input, full_selection, keep_colours)


class LiveChildren:
    """What a viewer is sent of a run on a cut: the rows of parents held as they were, then every child of a merged
    parent (that the run holds) with its own geometry and its parent's change, as the result will have it. The
    children, the rows that carry their change and the geometry are worked out once a geometry version
    (``_layout``); a step's snapshot then costs the children's colours only."""

    def __init__(self, cut: LodCut, capacity: CapacityPlan, full_input: GaussianScene,
                 full_selection: np.ndarray | None) -> None:
        self.cut, self.full_input, self.full_selection = cut, full_input, full_selection
        held = np.arange(cut.parent_count) if capacity.held is None else capacity.held
        self.run_parent = np.full(cut.parent_count, -1, np.int64)  # each parent's row among the held parents
        self.run_parent[held] = np.arange(len(held))
        children = np.flatnonzero(cut.merged[cut.child_parent])
        self.children = children[self.run_parent[cut.child_parent[children]] >= 0]
        self._key: tuple | None = None
        self._layout_cache: tuple | None = None

    def _layout(self, key: tuple, params: dict, gt: np.ndarray, lineage: np.ndarray,
                selected: np.ndarray | None) -> dict:
        """What changes only with the geometry, worked out once a geometry version: the rows shown as they are
        (``keep``), each child's row that carries its change (``source``), the geometry, c_gt and the selection."""
        if key != self._key or self._layout_cache is None:
            merged_held = self.cut.merged[self.run_parent >= 0]  # over the held parents, in their order
            keep = ~merged_held[lineage]
            parents = self.run_parent[self.cut.child_parent[self.children]]
            kids = self.full_input
            source = descendant_rows(lineage, params["means"], parents, kids.means[self.children])
            own = kids.rgb[self.children].astype(np.float32)
            layout = {name: np.concatenate([params[name][keep], getattr(kids, name)[self.children]]).astype(np.float32)
                      for name in ("means", "log_scales", "quats", "opacity_logits")}
            layout["colors_gt"] = np.concatenate([np.clip(gt[keep], 0, 1), np.clip(own, 0, 1)]).astype(np.float32)
            outside = None if self.full_selection is None else ~np.asarray(self.full_selection, bool)[self.children]
            layout["selected"] = None if selected is None else np.concatenate([selected[keep], ~outside])
            self._key, self._layout_cache = key, (keep, source, own, outside, layout)
        return self._layout_cache

    def snapshot(self, key: tuple, params: dict, colours: np.ndarray, gt: np.ndarray, lineage: np.ndarray,
                 selected: np.ndarray | None, keep_colours: bool = False) -> dict:
        """The viewer's arrays (``Stylizer.snapshot``'s geometry and colour fields) from the run's rows; the
        geometry and c_gt arrays are the same objects until the geometry changes (a viewer never writes to them)."""
        keep, source, own, outside, layout = self._layout(key, params, gt, lineage, selected)
        change = (colours - gt)[source]
        if outside is not None:  # a region's outside keeps its colours
            change[outside] = 0.0
        colors = np.concatenate([colours[keep], carried_colours(own, change, keep_colours)], dtype=np.float32)
        return {**layout, "colors": colors}
