"""A refit: geometry and c_gt of the seen Gaussians fitted to the ground truth again, c_s held; one iteration a step.

Used after each pre-processing split (with elongation clamps; in a run with finer levels every other iteration on a
window of the ground truth at the width the run ends at, ``end_width_crops.py``) and after each colour-gradient split
(no strategy).
When some Gaussians are unseen (or a region is selected), the refit trains a copy of the seen rows and writes it
back after every iteration; in a region run the unselected rows render as they are but never move. A checkpoint
holds the rows it works on, the trainer's Adam moments, its view order and step count, so a resumed refit goes on
exactly where it stopped.

The trainer (on CUDA a copy of the rows on the GPU) is built by the refit's first step, not by ``start``: the step
that starts a refit (a split) then touches no GPU memory, and a first step that fails (the GPU out of memory) leaves
the refit as it was, to be built again by the next step, on this device or, handed over, on another.
"""

from __future__ import annotations

from typing import Any

import torch

from ...fit.strategy import Strategy
from ...fit.trainer import FitConfig, Trainer
from ..flat_split import ElongationClampStrategy
from ..levels import end_width
from .base import Phase, StepReport
from .end_width_crops import EndWidthCrops

GEOMETRY_AND_GT = ("means", "log_scales", "quats", "opacity_logits", "sh_dc")  # refit: all but c_s


def row_mask_hook(free: torch.Tensor):
    """A gradient hook that zeroes the rows not in ``free`` (bool [N]): Adam never moves them."""
    def hook(grad: torch.Tensor) -> torch.Tensor:
        return grad * free.reshape((-1,) + (1,) * (grad.ndim - 1)).to(grad.device, grad.dtype)
    return hook


class Refit(Phase):
    """``settings.refit_iterations`` refit iterations, one per step, with ``strategy``'s hooks."""

    name = "refit"

    def __init__(self, run, strategy: Strategy, name: str = "refit") -> None:
        super().__init__(run)
        self.name = name
        self.strategy = strategy
        self.iterations = int(run.settings.refit_iterations)
        self.steps_done = 0
        self.trainer: Trainer | None = None
        self._ids: torch.Tensor | None = None  # rows of run.params the trainer's copy holds (None: every row)
        self._frozen: tuple[torch.Tensor, dict[str, torch.Tensor]] | None = None  # region: rows that stay put
        self._seed = 0  # the trainer's view order, drawn at start
        self.crops: EndWidthCrops | None = None  # windows at the end width for every other iteration

    @classmethod
    def after_split(cls, run) -> Refit:
        """The refit after a colour-gradient split (reported as "refit")."""
        return cls(run, Strategy(), "refit")

    @classmethod
    def preprocessing(cls, run) -> Refit:
        """The refit of a pre-processing round: elongation clamped at points derived from its length; in a run with
        finer levels every other iteration fits a window of the ground truth at the width the run ends at
        (``end_width_crops.py``)."""
        s = run.settings
        refit = cls(run, ElongationClampStrategy(s.refit_iterations, s.elongation_limit), "preprocess")
        width = end_width(s)
        if width > s.working_width:
            refit.crops = EndWidthCrops(run, width)
        return refit

    @property
    def finished(self) -> bool:
        return self.started and self.steps_done >= self.iterations

    def remaining_steps(self) -> int:
        return self.iterations - self.steps_done

    def start(self) -> None:
        super().start()
        self._seed = self.run.settings.seed + self.run.global_step

    def _build(self, ids: torch.Tensor | None, seed: int) -> None:
        """The trainer over ``ids``' rows (a copy) or over the run's parameters themselves (None). On CUDA the
        trainer's copy (of every row when ``ids`` is None) lives on the GPU with its Adam moments; each step writes it
        back into the run's parameters."""
        run = self.run
        device = run.raster_device
        cfg = FitConfig(iterations=self.iterations, sh_degree=0, sh_increase_every=10**9, trainable=GEOMETRY_AND_GT,
                        seed=seed, backend=run.settings.raster_backend, device=str(device))
        copied = ids is not None or device.type != "cpu"  # then written back into run.params after each step
        params = run.params if not copied else torch.nn.ParameterDict(
            {k: torch.nn.Parameter((v.detach() if ids is None else v.detach()[ids]).to(device, copy=True))
             for k, v in run.params.items()})
        self._ids, self._frozen = ids, None
        selected = run.active.selected
        if selected is not None:  # region: the unselected Gaussians render as they are but never move
            free = selected[ids].to(device)
            self._frozen = (torch.nonzero(~free).flatten(), {k: v.detach()[~free].clone() for k, v in params.items()})
            for p in params.values():
                if p.requires_grad and p.ndim >= 1:
                    p.register_hook(row_mask_hook(free))
            run.counters["refit_gaussians"] = int(free.sum())
        else:
            run.counters["refit_gaussians"] = int(params["means"].shape[0])
        self.trainer = Trainer(params, run.cameras, run.gt_images, cfg, self.strategy, strategy_state={"extras": {}})

    def step(self) -> StepReport:
        if self.trainer is None:  # the first step, or a first step that failed
            self._build(self.run.active.refit_ids(), seed=self._seed)
        view = None
        if self.crops is not None and self.steps_done % 2 == 1:
            whole = self.run.cameras[0]
            view = self.crops.window(self._seed, self.steps_done, (whole.width, whole.height))
        rep = self.trainer.step(view=view)
        with torch.no_grad():
            if self._frozen is not None:  # undo whatever the strategy (elongation clamps) did to unselected rows
                rows, values = self._frozen
                for k, v in self.trainer.params.items():
                    v[rows] = values[k]
            if self.trainer.params is not self.run.params:  # a copy (of ``_ids``' rows, or on the GPU)
                for k, v in self.trainer.params.items():
                    target = self.run.params[k]
                    if self._ids is None:
                        target.copy_(v.detach())
                    else:
                        target[self._ids] = v.detach().to(target.device)
        self.steps_done += 1
        if self.finished:
            self.trainer = self._frozen = None
        return self.report(losses={"refit": rep.loss}, geometry_changed=True)

    def state_dict(self) -> dict[str, Any]:
        running = self.trainer is not None
        return {**super().state_dict(), "steps_done": self.steps_done, "iterations": self.iterations,
                "seed": self._seed,
                "ids": None if self._ids is None else self._ids.clone(),
                "trainer": self.trainer.state_dict() if running else None}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        super().load_state_dict(state)
        if int(state["iterations"]) != self.iterations:
            raise ValueError(f"the saved refit runs {state['iterations']} iterations, this run's {self.iterations}")
        self.steps_done, self._seed = int(state["steps_done"]), int(state.get("seed", 0))
        self.trainer = self._frozen = None
        if state["trainer"] is not None:  # interrupted: the same rows, moments, view order and step count
            self._build(state["ids"], seed=0)
            self.trainer.load_state_dict(state["trainer"])
