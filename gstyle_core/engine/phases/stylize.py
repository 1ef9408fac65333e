"""Stylization: one optimiser step of c_s per step, with colour-gradient splits and their refits in between.

A step renders c_s at the working resolution for ``views_per_step`` training views (the colour-only cached path),
takes the objective's mean loss and one Adam step on c_s with an exponentially decaying learning rate. From
``grad_accumulate_from`` on, ‖∂L/∂c_s‖ is accumulated; at the scheduled steps (``split_at``, fractions of the
stylization counted in optimiser steps, so every preset performs them) a ``ColourSplit`` runs, then a ``Refit``.
Only the active Gaussians are optimised (``active.py``): the unseen ones get no gradient and keep their colour. With
``optimizer="visible_adam"`` only the Gaussians in the step's views move (``visible_adam.py``). With
``colour_field`` a coarse colour field steps beside the colours and is folded into them after every step
(``colour_field.py``; rebuilt when the stroke size or the switch changes). Keep colours: after every optimiser step
c_s takes the chroma of c_gt back.
"""

from __future__ import annotations

import math
from functools import partial
from typing import Any

import torch

from ..colour_steps import ColourSteps
from ..notes import network_area_note
from ..step_losses import StepLosses, ViewInput, backward_views
from .base import Phase, StepReport
from .colour_split import ColourSplit
from .refit import Refit

STEP_MESSAGE = "stylize view"  # how an optimiser step's report message starts (the views follow)


def is_optimiser_step(phase: str | None, message: str | None) -> bool:
    """True for the report of a stylization optimiser step (not a split, a refit or a finer level's step)."""
    return phase == "stylize" and str(message or "").startswith(STEP_MESSAGE)


class Stylize(Phase):
    """The stylization's optimiser steps, splits and refits."""

    name = "stylize"

    def __init__(self, run) -> None:
        super().__init__(run)
        s, n = run.settings, len(run.cameras)
        # epochs and min_steps count views; a step takes views_per_step of them
        views_total = max(int(round(s.epochs * n)), s.min_steps)
        self.steps = max(1, int(math.ceil(views_total / max(1, s.views_per_step))))
        planned = {int(round(f * self.steps)) for f in s.split_at}
        self.split_steps = sorted(k for k in planned if 0 < k < self.steps)  # a split leaves the list once done
        self.accumulate_from = int(round(s.grad_accumulate_from * self.steps))
        self.step_index = 0  # optimiser steps taken
        self.splits_done = 0
        self.colour_steps = ColourSteps(run)  # Adam on the active rows of c_s, with the colour field
        self.refit: Refit | None = None

    optimiser = property(lambda self: self.colour_steps.optimiser, doc="The colours' optimiser (None between runs).")
    c_opt = property(lambda self: self.colour_steps.c_opt, doc="The optimised copy of the active rows of c_s.")
    field = property(lambda self: self.colour_steps.field, doc="The coarse colour field (None when off).")

    @property
    def current(self) -> str:
        return "refit" if self.refit is not None else "stylize"

    def start(self) -> None:
        super().start()
        run = self.run
        run.grad_acc = torch.zeros(run.gaussian_count)
        run.decisions["network_area"] = network_area_note(run.settings, run.photos is not None, run.coverage,
                                                          run.region_coverage)

    @property
    def finished(self) -> bool:
        return self.step_index >= self.steps and self.refit is None

    def remaining_steps(self) -> int:
        s = self.run.settings
        pending = len(self.split_steps) if s.split_rate > 0 else 0
        left = self.steps - self.step_index + pending * (1 + s.refit_iterations)
        return left + (self.refit.remaining_steps() if self.refit is not None else 0)

    def lr(self) -> float:
        """The learning rate of the next optimiser step (exponential decay from lr_start to lr_end)."""
        s = self.run.settings
        t = min(1.0, self.step_index / max(1, self.steps))
        return float(math.exp((1 - t) * math.log(s.lr_start) + t * math.log(s.lr_end)))

    def view_of(self, k: int) -> int:
        """The training view of stylization view ``k``: camera order (``orbit``) or, as the reference does, a new
        random permutation of the views every epoch (``random``; drawn from the seed and the epoch, so a resumed
        run sees the same order)."""
        n, s = len(self.run.cameras), self.run.settings
        if s.view_order == "orbit":
            return k % n
        epoch = torch.Generator().manual_seed(s.seed * 1_000_003 + k // n)
        return int(torch.randperm(n, generator=epoch)[k % n])

    def views_of_step(self, index: int | None = None) -> list[int]:
        """The training views of optimiser step ``index`` (default: the next one)."""
        index = self.step_index if index is None else index
        per = self.run.settings.views_per_step
        return [self.view_of(index * per + j) for j in range(per)]

    def step(self) -> StepReport:
        if self.refit is not None:
            rep = self.refit.step()
            if self.refit.finished:
                self.refit = None
            return rep
        if self.step_index in self.split_steps and self.run.settings.split_rate > 0:
            return self._split()
        return self._optimise()

    def _split(self) -> StepReport:
        self.split_steps.remove(self.step_index)
        self.splits_done += 1
        self.colour_steps.stop()  # new rows: a new optimiser after the refit
        rep = ColourSplit(self.run).step()
        if self.run.settings.refit_iterations > 0:
            self.refit = Refit.after_split(self.run)
            self.refit.start()
        return rep

    def _optimise(self) -> StepReport:
        run, steps = self.run, self.colour_steps
        views = self.views_of_step()
        steps.begin(self.lr())
        losses = StepLosses(len(views))
        # the mean loss over this step's views: gradients add up before one optimiser step
        backward_views(run.objective_fn(), [partial(self._view_input, view) for view in views], losses)
        steps.finish(accumulate=self.step_index >= self.accumulate_from)
        self.step_index += 1
        if self.step_index >= self.steps:
            steps.stop()
        return self.report(losses=losses.read(), colours_changed=True,
                           message=f"{STEP_MESSAGE}{'s' if len(views) > 1 else ''} {', '.join(map(str, views))}")

    def _view_input(self, view: int) -> ViewInput:
        """A training view's render of the step's colours, its content target and coverage."""
        run = self.run
        return (run.render_seen(view, self.colour_steps.seen_colours()), run.content_images[view], view,
                run.objective_coverage(view))

    def restore_chroma(self) -> None:
        """Keep colours: c_s (and the optimised copy) take the chroma of c_gt back."""
        self.colour_steps.restore_chroma()

    def state_dict(self) -> dict[str, Any]:
        return {**super().state_dict(), "step_index": self.step_index, "split_steps": list(self.split_steps),
                "splits_done": self.splits_done, **self.colour_steps.state_dict(),
                "refit": None if self.refit is None else self.refit.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        super().load_state_dict(state)
        self.step_index, self.splits_done = int(state["step_index"]), int(state["splits_done"])
        self.split_steps = [int(k) for k in state["split_steps"]]
        self.refit = None
        self.colour_steps.load_state_dict(state, self.lr())
        if state["refit"] is not None:  # built as a fresh one is, then its saved state
            self.refit = Refit.after_split(self.run)
            self.refit.load_state_dict(state["refit"])
