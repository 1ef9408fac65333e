"""The colour-gradient split: the ``split_rate`` fraction of the active Gaussians with the largest accumulated
‖∂L/∂c_s‖ is split (children inherit c_s); one step, scheduled by the stylization, followed by a refit."""

from __future__ import annotations

import math

import torch

from .base import Phase, StepReport


class ColourSplit(Phase):
    """One split of the Gaussians whose stylized colour pulled hardest (reported as a stylization step)."""

    name = "stylize"

    def __init__(self, run) -> None:
        super().__init__(run)
        self.count: int | None = None  # Gaussians split, once done

    @property
    def finished(self) -> bool:
        return self.count is not None

    def remaining_steps(self) -> int:
        return 0 if self.finished else 1

    def step(self) -> StepReport:
        run, s = self.run, self.run.settings
        pool = run.active.gather(run.grad_acc)  # a fraction of the active Gaussians; no others are split
        k = int(math.floor(s.split_rate * len(pool)))
        chosen = torch.zeros(len(pool), dtype=torch.bool)
        if k > 0:
            chosen[torch.topk(pool, k).indices] = True
        mask = run.active.expand(chosen, fill=False)
        run.c_s = run.c_s.detach()
        self.count = run.split(mask, s.split_children, s.split_scale_divisor, priority=run.grad_acc)
        run.grad_acc = torch.zeros(run.gaussian_count)
        return self.report(geometry_changed=True, colours_changed=True,
                           message=f"split {self.count} Gaussians with the largest colour gradient")
