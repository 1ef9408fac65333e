"""The mean loss and terms over an optimiser step's views, added up where the losses are and read once a step, and
the backward pass of a step's views (``backward_views``).

On a GPU every read of a value on the CPU waits for the GPU's queue to drain: read after each view, the CPU could not
queue the next view's work while the GPU computes this one's. ``StepLosses`` keeps the views' values on the device
and reads them in one transfer when the step reports them. Objectives with an ``evaluate`` method
(``StyleObjective``) give their terms unread; others (test stand-ins) give a dict of floats, added up as such.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import torch

from ..style.losses import TERM_NAMES


class StepLosses:
    """The losses of a step's ``views`` views: ``add`` each view's, ``read`` the means once the step is done."""

    def __init__(self, views: int) -> None:
        self.views = max(1, int(views))
        self._sum: torch.Tensor | None = None  # [1 + len(TERM_NAMES)]: the total, then the terms (unread)
        self._floats: dict[str, float] = {}  # objectives that give floats

    def evaluate(self, objective: Any, *args: Any, **kwargs: Any) -> torch.Tensor:
        """Evaluate ``objective`` on a view (its ``evaluate`` when it has one, else its call), keep its values, and
        return the view's share of the step's loss (the loss over ``views``) to backpropagate."""
        evaluate = getattr(objective, "evaluate", None)
        loss, values = evaluate(*args, **kwargs) if evaluate is not None else objective(*args, **kwargs)
        self.add(loss, values)
        return loss / self.views

    def add(self, loss: torch.Tensor, values: torch.Tensor | dict[str, float]) -> None:
        """Add a view's loss and its terms (a ``TERM_NAMES`` tensor, unread, or a dict of floats)."""
        if isinstance(values, torch.Tensor):
            row = torch.cat([loss.detach().float().reshape(1), values.detach().float().to(loss.device)])
            self._sum = row if self._sum is None else self._sum + row
            return
        self._floats["total"] = self._floats.get("total", 0.0) + float(loss.detach())
        for name, value in values.items():
            self._floats[name] = self._floats.get(name, 0.0) + float(value)

    def read(self) -> dict[str, float]:
        """The step's mean total and terms (``total`` first), read in one transfer."""
        out = dict(self._floats)
        if self._sum is not None:
            read = dict(zip(("total", *TERM_NAMES), self._sum.cpu().tolist(), strict=True))
            for name, value in read.items():
                out[name] = out.get(name, 0.0) + value
        total = out.pop("total", 0.0)
        return {"total": total / self.views, **{name: value / self.views for name, value in out.items()}}


ViewInput = tuple[torch.Tensor, torch.Tensor, "int | None", "torch.Tensor | None"]  # (render, content, view, coverage)


def backward_views(objective: Any, views: Sequence[Callable[[], ViewInput]], losses: StepLosses) -> None:
    """Backpropagate the mean loss of a step's views into their renders, keeping the values in ``losses``. ``views``
    make each view's input when called: its render, content target, training view (None for a crop) and coverage.
    Where the objective takes views together (``StyleObjective.takes_views_together``: terms it computes for all
    of them in one pass, the broad strokes and the coarse CLIP substitute) all views are rendered first and go to
    its ``backward_views`` as copies of the renders that stop the gradient; each render then passes its gradient on
    once, in view order. Otherwise one view is rendered, evaluated and backpropagated after the other (one view's
    graph held at a time)."""
    together = getattr(objective, "takes_views_together", None)
    if together is None or not together(len(views)):
        for make in views:
            render, content, view, coverage = make()
            loss = losses.evaluate(objective, render, content, view, coverage=coverage)
            if loss.requires_grad:  # every term off (the artist's λ all 0): a constant, nothing to backpropagate
                loss.backward()
        return
    inputs = [make() for make in views]
    renders = [render for render, _, _, _ in inputs]
    leaves = [render.detach().requires_grad_(True) for render in renders]
    total, values = objective.backward_views(leaves, [c for _, c, _, _ in inputs], [v for _, _, v, _ in inputs],
                                             [cov for _, _, _, cov in inputs], scale=1.0 / losses.views)
    losses.add(total, values)
    for render, leaf in zip(renders, leaves, strict=True):
        if leaf.grad is not None:
            render.backward(leaf.grad)
