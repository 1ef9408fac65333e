"""A finer level: the stylization carried on from the current colours at a finer width (coarse to fine).

At the working width only the blend of the Gaussians inside one working pixel is constrained, so at a display's size
each Gaussian's own colour shows as a speck (``style/speckle.py`` measures it). A finer level continues the
optimisation at ``width`` px (Gatys et al.'s coarse-to-fine: the large structure comes from the coarse level, the
fine level adds what its pixels can show), with the painting matched at the stroke size × ``width`` so strokes keep
their size in the scene. Two ways to reach the finer pixels (``settings.refine_mode``; docs/notes/tradeoffs-history.md
measures them):

* ``crops``: every other optimiser step renders, for each of its views, a random window of the view at ``width`` px
  as large as a working-width view (a crop step costs what a working-width step costs) and takes the NNFM, content and
  TV terms on it.
* ``whole``: every other step renders whole views at ``width`` px with every term (4× the pixels per doubling of the
  width), so the large-pattern terms see the finer pixels too.

In both, the steps between are whole views at the working width with every term: the broad strokes (and CLIP) keep
their context, and the style the working width shows is held while the finer level adds its own (the NNFM drop at
the working width; with every step at ``width`` it fell from 31.3 to 27.6 % on the fern after The Great Wave, while
alternating kept 31.4 %, docs/notes/tradeoffs.md).

The level first takes its targets, one view per step (the ground truth at ``width``: the scene's photos resized, or
renders of the input scene with its SH; at most ``MAX_LEVEL_VIEWS`` views), then ``steps`` optimiser steps of c_s
(``colour_steps.py``; its own Adam) at the run's final learning rate. Crops are drawn from the seed and the step, so a
resumed level draws the same ones; a resumed level takes its targets again as it loads (they are renders of the input
or resized photos), so checkpoints do not carry them.
"""

from __future__ import annotations

import math
from functools import partial
from typing import Any

import numpy as np
import torch

from ..colour_steps import ColourSteps
from ..levels import MAX_LEVEL_VIEWS
from ..plan import WHOLE_LEVEL_TAG
from ..step_losses import StepLosses, ViewInput, backward_views
from ..view_choice import choose_views
from .base import Phase, StepReport
from .colour_match import content_target, detail_sigma
from .ground_truth import ground_truth_view

REFINE_MODES = ("crops", "whole")
CROP_TERMS = ("nnfm", "content", "tv", "chroma_tv", "edges")  # a crop's terms: the large-pattern ones need whole views


class Refine(Phase):
    """One finer level at ``width`` px (``index``: its place among the run's levels, for its checkpoint key)."""

    def __init__(self, run, width: int, index: int) -> None:
        super().__init__(run)
        s = run.settings
        if s.refine_mode not in REFINE_MODES:
            raise ValueError(f"refine mode must be one of {', '.join(REFINE_MODES)}, got {s.refine_mode!r}")
        self.name = f"refine_{index}"
        self.width, self.mode = int(width), s.refine_mode
        self.views = choose_views(run.cameras, MAX_LEVEL_VIEWS)  # run view indices this level takes targets of
        self.cameras = [run.full_cameras[v].resized_to_width(self.width) for v in self.views]
        self.gt: list[torch.Tensor] = []
        self.alpha: list[torch.Tensor] = []
        self.boxes: list[tuple[int, int, int, int]] = []  # the covered box of each view at ``width`` (x0, y0, x1, y1)
        views_total = max(1, int(round(s.refine_epochs * len(run.cameras))))
        self.steps = max(1, int(math.ceil(views_total / max(1, s.views_per_step))))
        self.step_index = 0
        self.colour_steps = ColourSteps(run)
        self._input_params = None

    @property
    def current(self) -> str:
        return "refine"

    @property
    def targets_done(self) -> bool:
        return len(self.gt) >= len(self.cameras)

    @property
    def finished(self) -> bool:
        return self.targets_done and self.step_index >= self.steps

    def remaining_steps(self) -> int:
        return len(self.cameras) - len(self.gt) + self.steps - self.step_index

    def step(self) -> StepReport:
        if not self.targets_done:
            return self._take_target()
        return self._optimise()

    # ------------------------------------------------------------------------------------------------ targets
    def _take_target(self) -> StepReport:
        run, i = self.run, len(self.gt)
        if self._input_params is None and run.photos is None:
            from ...fit.model import params_from_scene

            self._input_params = params_from_scene(run.truth_scene, requires_grad=False)
        gt, alpha = ground_truth_view(run, self.cameras[i], self.views[i], self._input_params)
        self.gt.append(gt)
        self.alpha.append(alpha)
        self.boxes.append(covered_box(alpha))
        if self.targets_done:
            self._input_params = None
        return self.report(message=f"level {self.width} px: ground truth {i + 1}/{len(self.cameras)}")

    # ------------------------------------------------------------------------------------------------ steps
    def lr(self) -> float:
        """The learning rate of the level's steps (``settings.refine_lr``; by default the run's final one)."""
        s = self.run.settings
        return float(s.lr_end if s.refine_lr is None else s.refine_lr)

    def crop_step(self, index: int | None = None) -> bool:
        """Whether optimiser step ``index`` (default: the next) renders at the level's width (crops or whole views,
        by the mode: every other step, the first included) rather than whole views at the working width."""
        index = self.step_index if index is None else index
        return index % 2 == 0

    def _generator(self) -> torch.Generator:
        return torch.Generator().manual_seed(self.run.settings.seed * 1_000_003 + 7919 * self.width + self.step_index)

    def _optimise(self) -> StepReport:
        run = self.run
        per = max(1, run.settings.views_per_step)
        gen = self._generator()
        fine = self.crop_step()
        pool = len(self.cameras) if fine else len(run.cameras)
        picks = torch.randperm(pool, generator=gen)[:per].tolist()
        self.colour_steps.begin(self.lr())
        colours = self.colour_steps.seen_colours()
        losses = StepLosses(len(picks))
        if fine:
            terms = CROP_TERMS if self.mode == "crops" else None
            backward_views(run.level_objective(self.width, terms),
                           [partial(self._fine_view, k, colours, gen) for k in picks], losses)
        else:
            backward_views(run.objective_fn(), [partial(self._coarse_view, k, colours) for k in picks], losses)
        self.colour_steps.finish()
        self.step_index += 1
        if self.step_index >= self.steps:
            self.colour_steps.stop()
        what = (f"{'crops' if self.mode == 'crops' else 'views'} at {self.width} px" if fine
                else f"whole views at {run.settings.working_width} px")
        level = f"level {self.width} px" + (f" {WHOLE_LEVEL_TAG}" if self.mode == "whole" else "")
        return self.report(losses=losses.read(), colours_changed=True,
                           message=f"{level}: {what} (views {', '.join(map(str, picks))})")

    def _coarse_view(self, view: int, colours: torch.Tensor) -> ViewInput:
        """A whole training view at the working width, for every term (the stylization's own step): its render of
        ``colours`` (the step's seen colours, ``ColourSteps.seen_colours``), content target and coverage."""
        run = self.run
        return run.render_seen(view, colours), run.content_images[view], view, run.objective_coverage(view)

    def _fine_view(self, k: int, colours: torch.Tensor, gen: torch.Generator) -> ViewInput:
        """Level view ``k`` at the level's width: a random crop the size of a working-width view (``crops``), or the
        whole view (``whole``), as ``_coarse_view`` gives it (no training view: nothing of it is cached)."""
        run = self.run
        full = self.cameras[k]
        if self.mode == "crops":
            small = run.cameras[self.views[k]]
            w, h = min(small.width, full.width), min(small.height, full.height)
            x0, y0 = random_window(self.boxes[k], (full.width, full.height), (w, h), gen)
        else:
            x0, y0, w, h = 0, 0, full.width, full.height
        cache = run.build_cache(full.cropped(x0, y0, w, h))
        image = cache.render(colours)
        alpha = self.alpha[k][y0:y0 + h, x0:x0 + w]
        region = None
        if run.active.region:
            indicator = run.active.selected.to(torch.float32)[:, None].expand(-1, 3)
            region = cache.render(run.active.gather_seen(indicator).contiguous())[..., 0].clamp(0.0, 1.0)
        content = self._content(k, (x0, y0, w, h), region)
        coverage = region if region is not None else (None if run.photos is not None else alpha)
        return image, content, None, coverage

    def _content(self, k: int, window: tuple[int, int, int, int], region: torch.Tensor | None) -> torch.Tensor:
        """The content target of ``window`` (x0, y0, w, h) of level view ``k``: taken on the window grown by the
        detail match's blur (3σ) and cut back, so the window's border sees the same neighbours as the whole view."""
        run, (x0, y0, w, h) = self.run, window
        scale = self.width / run.settings.working_width
        pad = int(math.ceil(3 * detail_sigma(run, scale)))
        full_h, full_w = self.gt[k].shape[:2]
        gx0, gy0, gx1, gy1 = max(0, x0 - pad), max(0, y0 - pad), min(full_w, x0 + w + pad), min(full_h, y0 + h + pad)
        gt, alpha = self.gt[k][gy0:gy1, gx0:gx1], self.alpha[k][gy0:gy1, gx0:gx1]
        grown = None
        if region is not None:  # the region's weight is known on the window only: 0 around it
            grown = torch.zeros(gy1 - gy0, gx1 - gx0)
            grown[y0 - gy0:y0 - gy0 + h, x0 - gx0:x0 - gx0 + w] = region
        target = content_target(run, gt, alpha, grown, scale)
        return target[y0 - gy0:y0 - gy0 + h, x0 - gx0:x0 - gx0 + w]

    # ------------------------------------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, Any]:
        return {**super().state_dict(), "width": self.width, "mode": self.mode, "step_index": self.step_index,
                "targets": len(self.gt), **self.colour_steps.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore ``state_dict()``; the targets it had are taken again now (renders of the input scene or resized
        photos: the same images), so a checkpoint does not carry them."""
        super().load_state_dict(state)
        if int(state["width"]) != self.width or state["mode"] != self.mode:
            raise ValueError(f"checkpoint of a {state['mode']} level at {state['width']} px, this run's "
                             f"{self.name} is {self.mode} at {self.width} px")
        self.step_index = int(state["step_index"])
        self.gt, self.alpha, self.boxes = [], [], []
        for _ in range(int(state["targets"])):
            self._take_target()
        self.colour_steps.load_state_dict(state, self.lr())


def covered_box(alpha: torch.Tensor) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) of the pixels ``alpha`` [H, W] covers (> 1/255); the whole frame when none is."""
    covered = alpha > 1.0 / 255.0
    rows, cols = torch.nonzero(covered.any(1)).flatten(), torch.nonzero(covered.any(0)).flatten()
    if len(rows) == 0:
        return 0, 0, int(alpha.shape[1]), int(alpha.shape[0])
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def random_window(box: tuple[int, int, int, int], frame: tuple[int, int], size: tuple[int, int],
                  generator: torch.Generator) -> tuple[int, int]:
    """The corner (x0, y0) of a random ``size`` (w, h) window inside ``frame`` (W, H), over ``box`` (x0, y0, x1, y1):
    uniform along an axis where the box is larger than the window, centred on the box where it is smaller."""
    corner = []
    for lo, hi, extent, n in ((box[0], box[2], frame[0], size[0]), (box[1], box[3], frame[1], size[1])):
        if hi - lo > n:
            start = lo + int(torch.randint(0, hi - lo - n + 1, (1,), generator=generator))
        else:
            start = (lo + hi - n) // 2
        corner.append(int(np.clip(start, 0, max(0, extent - n))))
    return corner[0], corner[1]
