"""The cut: which Gaussians a run at a given width holds as themselves and which it merges into parents.

Every centre gets the world size of one pixel there, the smallest over the training cameras that see it (depth over
focal length at the run's width; ``pixel_footprint``). A Gaussian whose 1σ diameter fits in ``target_px`` such pixels
is *below the cut*: it goes into the cell of a grid whose edge is that size rounded down to a power of two (so cells
of neighbouring depths nest), and each cell with two or more Gaussians becomes one parent (``moments.merge_groups``).
Everything else (larger Gaussians, a Gaussian alone in its cell) is held as it is. The grouping depends only on the
Gaussians' positions and sizes, never on the file's order; a region run never merges selected with unselected ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cameras.camera import Camera
from ..scene import GaussianScene
from .moments import merge_groups

FRAME_MARGIN = 0.1  # a camera sees a centre within its image grown by this fraction on every side
NEAR = 1e-3  # centres nearer than this to a camera's plane (or behind it) are not seen by it


@dataclass(frozen=True)
class LodCut:
    """``parents``: the scene a run holds (the Gaussians kept as they are first, in input order, then one parent per
    merged group); ``child_parent``: each input Gaussian's row in ``parents``; ``merged``: bool over ``parents``, True
    for parents of two or more input Gaussians; ``parent_selection``: a region's mask over ``parents`` (None: no
    region); ``width``/``target_px``: the cut's width and cell size in pixels."""

    parents: GaussianScene
    child_parent: np.ndarray
    merged: np.ndarray
    parent_selection: np.ndarray | None
    width: int
    target_px: float

    @property
    def input_count(self) -> int:
        """Gaussians in the input."""
        return int(len(self.child_parent))

    @property
    def parent_count(self) -> int:
        """Gaussians the run holds."""
        return self.parents.count

    @property
    def note(self) -> str:
        """The cut in words: what the run says before it starts (terminal, panel, OUT.json)."""
        merged_children = int(np.count_nonzero(self.merged[self.child_parent]))
        return (f"{self.input_count:,} Gaussians as {self.parent_count:,} parents at {self.width} px "
                f"({merged_children:,} merged into {int(self.merged.sum()):,} in cells of {self.target_px:g} px; "
                "every input Gaussian is written with its own geometry)")


def pixel_footprint(means: np.ndarray, cameras: Sequence[Camera]) -> np.ndarray:
    """The world size of one pixel at each centre [N, 3] (float64 [N]): the smallest depth / focal length over the
    cameras that see it; a centre no camera frames takes the smallest over the cameras it is in front of, one behind
    every camera ``inf``."""
    pts = np.nan_to_num(np.asarray(means, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    seen = np.full(len(pts), np.inf)
    ahead = np.full(len(pts), np.inf)
    for cam in cameras:
        w2c = np.asarray(cam.world_to_cam, np.float64)
        cam_pts = pts @ w2c[:3, :3].T + w2c[:3, 3]
        z = cam_pts[:, 2]
        front = z > NEAR
        size = np.where(front, z, np.inf) / max(cam.fx, cam.fy)
        safe_z = np.where(front, z, 1.0)
        u = cam.fx * cam_pts[:, 0] / safe_z + cam.cx
        v = cam.fy * cam_pts[:, 1] / safe_z + cam.cy
        mx, my = FRAME_MARGIN * cam.width, FRAME_MARGIN * cam.height
        framed = front & (u > -mx) & (u < cam.width + mx) & (v > -my) & (v < cam.height + my)
        np.minimum(ahead, size, out=ahead)
        np.minimum(seen, np.where(framed, size, np.inf), out=seen)
    return np.where(np.isfinite(seen), seen, ahead)


def _cell_groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Group ids (int64 [M], 0..G-1 in key order) and group sizes of integer key rows [M, K]."""
    if len(keys) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    span = keys.max(axis=0) - keys.min(axis=0) + 1
    bits = np.ceil(np.log2(np.maximum(span, 1) + 1)).astype(int)
    if bits.sum() <= 62:  # packed into one int64: one sort
        packed = np.zeros(len(keys), np.int64)
        for column, b in zip((keys - keys.min(axis=0)).T, bits, strict=True):
            packed = (packed << int(b)) | column
        _, inverse, counts = np.unique(packed, return_inverse=True, return_counts=True)
        return inverse.astype(np.int64), counts
    order = np.lexsort(keys.T[::-1])
    sorted_keys = keys[order]
    starts = np.concatenate([[True], np.any(sorted_keys[1:] != sorted_keys[:-1], axis=1)])
    ids = np.empty(len(keys), np.int64)
    ids[order] = np.cumsum(starts) - 1
    return ids, np.bincount(ids)


def build_cut(scene: GaussianScene, cameras: Sequence[Camera], width: int, target_px: float = 1.0,
              selection: np.ndarray | None = None, size_factor: float = 1.0) -> LodCut:
    """The cut of ``scene`` for training ``cameras`` rendered ``width`` px wide, cells of ``target_px`` pixels;
    ``selection``: a region's bool mask over the scene (selected and unselected Gaussians are never merged)."""
    if target_px <= 0:
        raise ValueError(f"the level of detail's cell size must be above 0 px, got {target_px}")
    cams = [c.resized_to_width(width) for c in cameras]
    cell = target_px * pixel_footprint(scene.means, cams)
    sigma = np.exp(np.nan_to_num(np.asarray(scene.log_scales, np.float64), nan=60.0).max(axis=1))
    below = np.isfinite(cell) & (cell > 0) & (2.0 * sigma <= size_factor * cell) & np.isfinite(scene.means).all(axis=1)
    rows = np.flatnonzero(below)
    level = np.floor(np.log2(cell[rows])).astype(np.int64)
    index = np.floor(scene.means[rows].astype(np.float64) / np.exp2(level)[:, None]).astype(np.int64)
    sel = np.zeros(len(rows), np.int64) if selection is None else np.asarray(selection, bool)[rows].astype(np.int64)
    ids, counts = _cell_groups(np.column_stack([sel, level, index]))
    shared = counts[ids] >= 2  # a Gaussian alone in its cell is held as it is
    kept = np.ones(scene.count, bool)
    kept[rows[shared]] = False
    kept_rows = np.flatnonzero(kept)
    group_of = np.cumsum(counts >= 2) - 1  # renumber the shared cells 0..G-1, in key order
    groups = group_of[ids[shared]]
    n_groups = int((counts >= 2).sum())
    merged_parents, _ = merge_groups(scene.subset(rows[shared]), groups, n_groups)
    child_parent = np.empty(scene.count, np.int64)
    child_parent[kept_rows] = np.arange(len(kept_rows))
    child_parent[rows[shared]] = len(kept_rows) + groups
    parents = GaussianScene.concatenate([scene.subset(kept_rows), merged_parents.with_sh_degree(scene.sh_degree)])
    merged = np.concatenate([np.zeros(len(kept_rows), bool), np.ones(n_groups, bool)])
    parent_selection = None
    if selection is not None:
        parent_selection = np.zeros(parents.count, bool)
        parent_selection[child_parent] = np.asarray(selection, bool)
    return LodCut(parents, child_parent, merged, parent_selection, int(width), float(target_px))
