"""Windows of the ground truth at the width a run ends at, for the pre-processing refits.

A refit fits the geometry to the ground truth at the working width (256 px): what only a finer pixel shows is not
held, and each pre-processing round and each longer refit took structure away at a display's size
(docs/notes/tradeoffs.md, "Where the structure at 1024 px goes"). A run with finer levels therefore gives every other
refit iteration a window of one of its views at the width it ends at, as large as a working-width view, so an iteration
costs what it cost before. A view's ground truth at that width (its photo resized, or a render of the input scene) is
taken when a window of it is first drawn, at most one a step, and kept for the run's later refits (``MAX_LEVEL_VIEWS``
views at most, as a finer level keeps). Windows are drawn from the seed and the refit's iteration, so a resumed refit
draws the same.
"""

from __future__ import annotations

import numpy as np
import torch

from ...cameras.camera import Camera
from ...fit.model import params_from_scene
from ..levels import MAX_LEVEL_VIEWS
from ..view_choice import choose_views
from .ground_truth import ground_truth_view


class EndWidthCrops:
    """The end-width ground truth of a run's views (``run.end_targets``, shared by its refits) and the windows drawn
    from it."""

    def __init__(self, run, width: int) -> None:
        self.run, self.width = run, int(width)
        self.views = choose_views(run.cameras, MAX_LEVEL_VIEWS)  # run view indices
        self.cameras = [run.full_cameras[v].resized_to_width(self.width) for v in self.views]
        store = getattr(run, "end_targets", None)
        if store is None or store.get("width") != self.width:
            store = run.end_targets = {"width": self.width, "images": {}, "input": None}
        self.store = store
        self.images: dict[int, torch.Tensor] = store["images"]  # position in ``views`` -> [H, W, 3]

    def window(self, seed: int, iteration: int, size: tuple[int, int]) -> tuple[Camera, torch.Tensor]:
        """The camera and ground truth of a ``size`` (width, height) window of one view at the end width, both drawn
        from ``seed`` and ``iteration``; the view's ground truth is taken first when it has none yet."""
        rng = np.random.default_rng([int(seed), int(iteration)])
        k = int(rng.integers(len(self.views)))
        cam = self.cameras[k]
        if k not in self.images:
            run = self.run
            if run.photos is None and self.store["input"] is None:  # the input scene with its SH, to render
                self.store["input"] = params_from_scene(run.truth_scene, requires_grad=False)
            self.images[k] = ground_truth_view(run, cam, self.views[k], self.store["input"])[0]
            if len(self.images) == len(self.views):
                self.store["input"] = None
        w, h = min(size[0], cam.width), min(size[1], cam.height)
        x0 = int(rng.integers(cam.width - w + 1))
        y0 = int(rng.integers(cam.height - h + 1))
        return cam.cropped(x0, y0, w, h), self.images[k][y0:y0 + h, x0:x0 + w]
