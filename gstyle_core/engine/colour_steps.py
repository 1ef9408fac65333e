"""What every optimiser step of a stylization does around its loss: Adam on the active rows of c_s.

The stylization phase (``phases/stylize.py``) and the finer levels (``phases/refine.py``) share it. A step is
``colours = steps.begin(lr)`` (the optimised colours the views render: the coarse colour field, when it is on, is
folded into them at every step's end, so it adds zeros here), the loss of each view, rendered from
``steps.seen_colours()``, backpropagated, then ``steps.finish()``: the colours' gradient gives the field's (the
interpolation's adjoint, one sparse product), Adam steps the colours and the field, the field is folded into the
colours (another sparse product), the colours are clamped to [0, 1] and written into ``run.c_s``, and with keep
colours c_s takes c_gt's chroma back. Only the active Gaussians are optimised (``active.py``): the unseen ones get
no gradient and keep their colour; ``visible_adam`` moves only the Gaussians the step's views see. The field is
rebuilt when the stroke size or its switch changes (``colour_field.py``).

The colours the views render are made once a step (``seen_colours``): the seen rows, with the active ones the
optimised colours, sent to the rasterizer's device once, as a leaf there whose gradient the views add up; ``finish``
carries that sum back into the optimised colours in one pass. On a GPU a step thus sends the colours there once and
their gradient back once, instead of once per view (each such copy waits for the GPU's queue to drain); on the CPU
the views' gradients add up in the same order as before, so the result is the same to the bit.
"""

from __future__ import annotations

import copy
from typing import Any

import torch

from .colour_field import ColourField, build_colour_field


class ColourSteps:
    """The optimiser of c_s's active rows (and of the colour field), built on the first ``begin``."""

    def __init__(self, run) -> None:
        self.run = run
        self.optimiser: Any = None
        self.c_opt: torch.Tensor | None = None  # the optimised copy of the active rows of c_s
        self.field: ColourField | None = None  # the coarse colour field over c_opt's Gaussians (colour_field on)
        self._field_for: tuple[bool, float] | None = None  # (switch, stroke size) the field was built for
        self._in_step = False  # between ``begin`` and ``finish``
        self._placed: tuple[torch.Tensor, torch.Tensor] | None = None  # (seen colours, their leaf on the device)

    @property
    def started(self) -> bool:
        """True once the optimiser exists (after the first ``begin`` or a restored state)."""
        return self.optimiser is not None

    def begin(self, lr: float) -> torch.Tensor:
        """Start a step at learning rate ``lr``: the colours [A, 3] (active rows) the step's views render; their
        gradients are what ``finish`` steps on."""
        s = self.run.settings
        if self.optimiser is None:
            self.start(lr)
        elif self._field_for != (bool(s.colour_field), float(s.style_scale)):
            self.sync_field(lr)
        field = self.field
        for g in self.optimiser.param_groups:
            g["lr"] = lr * (field.colour_share if field is not None else 1.0)
        self.optimiser.zero_grad(set_to_none=True)
        if field is not None:  # folded at every step's end, so the views render c_opt (+ a field of zeros)
            field.set_lr(lr * field.field_share)
            field.zero_grad()
            if field.unfolded:
                field.fold_into(self.c_opt)
        self._in_step = True
        self._placed = None
        return self.c_opt

    def seen_colours(self) -> torch.Tensor:
        """The step's colours of the seen Gaussians (the colour caches' columns) on the rasterizer's device, made on
        the step's first call: a leaf there, whose gradient the views' backward passes add up (``finish`` carries it
        back into ``begin``'s colours)."""
        if not self._in_step:
            raise RuntimeError("seen_colours() before begin()")
        if self._placed is None:
            run = self.run
            placed = run.active.place_in_seen(run.c_s, self.c_opt)
            leaf = placed.detach().to(run.raster_device).requires_grad_(True)
            self._placed = (placed, leaf)
        return self._placed[1]

    def _carry_back(self) -> None:
        """The seen colours' summed gradient, sent back once, through the placing into ``begin``'s colours."""
        if self._placed is not None:
            placed, leaf = self._placed
            if leaf.grad is not None:
                placed.backward(leaf.grad.to(placed.device))
            self._placed = None

    def finish(self, accumulate: bool = False) -> None:
        """End the step: the optimiser steps on the gradients the views left in ``begin``'s colours; ``accumulate``
        adds each colour's gradient norm to ``run.grad_acc`` (the colour-gradient split's ranking)."""
        run = self.run
        self._carry_back()
        if self.field is not None and self.c_opt.grad is not None:  # the field's gradient: the colours' through it
            self.field.take_gradient(self.c_opt.grad)
        self._in_step = False
        if accumulate and self.c_opt.grad is not None:
            run.active.scatter_add(run.grad_acc, self.c_opt.grad.detach().norm(dim=-1))
        self.optimiser.step()
        if self.field is not None:
            self.field.step()
            self.field.fold_into(self.c_opt)
        with torch.no_grad():
            self.c_opt.clamp_(0.0, 1.0)
            run.active.scatter(run.c_s, self.c_opt)
        if run.settings.keep_colours:
            self.restore_chroma()

    def start(self, lr: float) -> None:
        """Adam on a copy of the active rows of c_s (the others get no gradient and keep their colour)."""
        from .visible_adam import VisibleAdam

        run = self.run
        run.c_s = run.c_s.detach()
        self.c_opt = run.active.gather(run.c_s).clone().requires_grad_(True)
        run.counters["optimised_colours"] = int(self.c_opt.shape[0])
        if run.settings.optimizer == "visible_adam":
            self.optimiser = VisibleAdam(self.c_opt, lr=lr)
        else:
            self.optimiser = torch.optim.Adam([self.c_opt], lr=lr)
        self.sync_field(lr)

    def stop(self) -> None:
        """Drop the optimiser (new rows after a split, or the phase ended); the next ``begin`` builds a new one."""
        self.optimiser, self.c_opt, self.field = None, None, None
        self._in_step, self._placed = False, None

    def sync_field(self, lr: float) -> None:
        """Build the colour field over the optimised Gaussians when the settings ask for it (for their stroke size),
        drop it when they do not."""
        run, s = self.run, self.run.settings
        self.field = None
        if s.colour_field:
            points = run.active.gather(run.params["means"].detach())
            self.field = build_colour_field(points, run.cameras, s.style_scale, lr,
                                            visible=s.optimizer == "visible_adam")
            run.counters["field_cells"] = self.field.cells
            run.decisions["colour_field"] = self.field.describe(s.style_scale)
        else:
            run.decisions["colour_field"] = "off"
        self._field_for = (bool(s.colour_field), float(s.style_scale))

    @torch.no_grad()
    def restore_chroma(self) -> None:
        """Keep colours: c_s (and the optimised copy) take the chroma of c_gt back."""
        self.run.restore_chroma()
        if self.c_opt is not None:
            self.c_opt.copy_(self.run.active.gather(self.run.c_s))

    @torch.no_grad()
    def put_back(self, colours: torch.Tensor) -> None:
        """c_s (and the optimised copy) become ``colours``, an earlier copy of c_s of the same shape."""
        self.run.c_s = colours.clone()
        if self.c_opt is not None:
            self.c_opt.copy_(self.run.active.gather(self.run.c_s))

    def state_dict(self) -> dict[str, Any]:
        """Adam's state and the field's (None before the first step and after ``stop``)."""
        return {"adam": None if self.optimiser is None else copy.deepcopy(self.optimiser.state_dict()),
                "field": None if self.field is None else copy.deepcopy(self.field.state_dict())}

    def load_state_dict(self, state: dict[str, Any], lr: float) -> None:
        """Restore ``state_dict()`` (the colours are the run's c_s)."""
        self.stop()
        if state.get("adam") is not None:
            self.start(lr)
            self.optimiser.load_state_dict(state["adam"])
            if self.field is not None and state.get("field") is not None:
                self.field.load_state_dict(state["field"])
