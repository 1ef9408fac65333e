"""Densification strategies: objects with step hooks that decide what to grow, split and prune.

The optimiser loop (``Trainer``) stays the same; a strategy sees each step before and after the backward pass.
``DefaultStrategy`` is 3DGS's adaptive density control (Kerbl et al. 2023): Gaussians whose accumulated 2D positional
gradient is large are cloned (small ones) or split (large ones); transparent ones are pruned; opacities are reset now
and then. G-Style's own splits (flat-Gaussian and colour-gradient) live in ``gstyle_core.engine`` as strategies of
the same shape.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch

from . import ops
from .model import PARAM_NAMES  # noqa: F401  (re-exported for strategies)


@dataclass
class StepInfo:
    """What a strategy may look at for one training step."""

    step: int
    width: int
    height: int
    means2d: torch.Tensor | None = None  # with .grad after backward
    radii: torch.Tensor | None = None
    visible: torch.Tensor | None = None


class Strategy:
    """Base class: no densification at all."""

    def initialize_state(self, params: torch.nn.ParameterDict) -> dict[str, Any]:
        """Per-run state (accumulators); also holds ``extras`` that must follow every split/prune."""
        return {"extras": {}}

    def step_pre_backward(self, params, optimizers, state, info: StepInfo) -> None:
        """Called after the render, before ``loss.backward()`` (retains the 2D means' gradient)."""
        if info.means2d is not None and info.means2d.requires_grad:
            info.means2d.retain_grad()

    def step_post_backward(self, params, optimizers, state, info: StepInfo) -> dict[str, int]:
        """Called after backward and the optimiser step; returns counts of what changed (for reports)."""
        return {}


@dataclass
class DefaultStrategy(Strategy):
    """3DGS adaptive density control with counts scaled to the run length.

    ``grad_threshold`` applies to the mean norm of the 2D positional gradient in normalised device
    coordinates, as in the 3DGS code (pixel gradients times half the image size).
    """

    refine_start: int = 500
    refine_stop: int = 15_000
    refine_every: int = 100
    reset_every: int = 3_000
    grad_threshold: float = 2e-4
    prune_opacity: float = 0.005
    split_scale_fraction: float = 0.01  # of the scene extent: larger Gaussians split, smaller clone
    max_gaussians: int = 1_000_000
    scene_scale: float = 1.0
    generator: torch.Generator = field(default_factory=lambda: torch.Generator().manual_seed(0))

    def initialize_state(self, params: torch.nn.ParameterDict) -> dict[str, Any]:
        n = params["means"].shape[0]
        return {"extras": {}, "grad2d": torch.zeros(n), "count": torch.zeros(n)}

    def step_post_backward(self, params, optimizers, state, info: StepInfo) -> dict[str, int]:
        out: dict[str, int] = {}
        if info.step >= self.refine_stop:
            return out
        if info.means2d is not None and info.means2d.grad is not None and info.visible is not None:
            g = info.means2d.grad.detach().to(state["grad2d"].device, copy=True)  # renders may run on a GPU
            g[:, 0] *= info.width / 2.0
            g[:, 1] *= info.height / 2.0
            vis = info.visible.to(g.device)
            state["grad2d"][vis] += g[vis].norm(dim=-1)
            state["count"][vis] += 1
        if info.step > self.refine_start and info.step % self.refine_every == 0:
            out = self._refine(params, optimizers, state)
        if self.reset_every and info.step > 0 and info.step % self.reset_every == 0:
            with torch.no_grad():
                cap = torch.logit(torch.tensor(self.prune_opacity * 2.0))
                params["opacity_logits"].clamp_(max=cap)
            opt = optimizers.get("opacity_logits")
            for st in opt.state.values() if opt is not None else ():
                for key in ("exp_avg", "exp_avg_sq"):
                    if key in st:
                        st[key].zero_()
            out["opacity_reset"] = 1
        return out

    def _refine(self, params, optimizers, state) -> dict[str, int]:
        avg = state["grad2d"] / state["count"].clamp_min(1)
        big_grad = avg > self.grad_threshold
        max_scale = torch.exp(params["log_scales"].detach()).max(dim=-1).values
        is_small = max_scale <= self.split_scale_fraction * self.scene_scale
        clone_mask = big_grad & is_small
        split_mask = big_grad & ~is_small
        room = self.max_gaussians - params["means"].shape[0]
        clone_mask = _cap_mask(clone_mask, avg, max(room, 0))
        room -= int(clone_mask.sum())
        split_mask = _cap_mask(split_mask, avg, max(room, 0))  # each split adds one net Gaussian
        extras = state["extras"]
        extras_with_acc = dict(extras, grad2d=state["grad2d"], count=state["count"])
        n_clone = int(clone_mask.sum())
        ops.duplicate(params, optimizers, extras_with_acc, clone_mask)
        split_mask = torch.cat([split_mask, torch.zeros(n_clone, dtype=torch.bool)])
        n_split = int(split_mask.sum())
        ops.split(params, optimizers, extras_with_acc, split_mask, n_children=2, scale_divisor=1.6,
                  generator=self.generator)
        opacity = torch.sigmoid(params["opacity_logits"].detach())
        prune_mask = opacity < self.prune_opacity
        n_prune = int(prune_mask.sum())
        if n_prune:
            ops.remove(params, optimizers, extras_with_acc, prune_mask)
        for k in extras:
            extras[k] = extras_with_acc[k]
        n = params["means"].shape[0]
        state["grad2d"] = torch.zeros(n)
        state["count"] = torch.zeros(n)
        return {"cloned": n_clone, "split": n_split, "pruned": n_prune}


def _cap_mask(mask: torch.Tensor, priority: torch.Tensor, limit: int) -> torch.Tensor:
    """Keep at most ``limit`` True entries of ``mask``, those with the highest ``priority``."""
    n = int(mask.sum())
    if n <= limit:
        return mask
    out = torch.zeros_like(mask)
    if limit > 0:
        idx = torch.where(mask)[0]
        top = torch.topk(priority[idx], limit).indices
        out[idx[top]] = True
    return out
