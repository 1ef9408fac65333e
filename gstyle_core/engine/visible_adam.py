"""Adam that updates only the rows the current view sees (as 3DGS trainers' visibility-selective Adam does).

With one training view per step, a Gaussian outside the view gets a zero gradient. Plain Adam still moves it on
its momentum and decays its moments, so colours keep drifting while nobody looks at them and each Gaussian's
effective step depends on how often it is in view. Here the rows with a zero gradient keep their colour, their
moments and their own step count; the others take an ordinary Adam step with bias correction by their own count.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numba import njit


class VisibleAdam:
    """Adam over one [N, C] tensor, updating only rows whose gradient is non-zero (the rows in view)."""

    def __init__(self, param: torch.Tensor, lr: float, betas: tuple[float, float] = (0.9, 0.999),
                 eps: float = 1e-8) -> None:
        self.param = param
        self.param_groups = [{"lr": float(lr)}]  # same shape as torch.optim's, so callers set the lr alike
        self.betas = betas
        self.eps = eps
        self.exp_avg = torch.zeros_like(param)
        self.exp_avg_sq = torch.zeros_like(param)
        self.steps = torch.zeros(param.shape[0], dtype=torch.float32)

    def zero_grad(self, set_to_none: bool = True) -> None:
        """Forget the gradient of the last step."""
        self.param.grad = None if set_to_none else torch.zeros_like(self.param)

    @torch.no_grad()
    def visible_rows(self) -> torch.Tensor:
        """Indices of the rows with a non-zero gradient."""
        g = self.param.grad
        if g is None:
            return torch.zeros(0, dtype=torch.long)
        return torch.nonzero(g.reshape(g.shape[0], -1).abs().amax(dim=1) > 0).flatten()

    @torch.no_grad()
    def first_moment(self, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The visible ``rows``' gradient, their first moment and step count advanced by one step (stored)."""
        b1 = self.betas[0]
        g = self.param.grad[rows]
        m = self.exp_avg[rows].mul_(b1).add_(g, alpha=1 - b1)
        t = self.steps[rows] + 1
        self.exp_avg[rows], self.steps[rows] = m, t
        return g, m, t

    @torch.no_grad()
    def step(self) -> int:
        """One Adam step on the visible rows; returns how many rows moved: one pass over the rows
        (``_visible_adam_rows``) for contiguous float32 tensors, else torch's operators (``step_by_operators``), the
        same step."""
        arrays = self._cpu_arrays()
        if arrays is None:
            return self.step_by_operators()
        return int(_visible_adam_rows(*arrays, *self._corrections(), float(self.param_groups[0]["lr"]), self.betas[0],
                                      self.betas[1], self.eps))

    def _corrections(self) -> tuple[np.ndarray, np.ndarray]:
        """Adam's bias corrections 1 − β^t for every step count t a row can reach in this step (float64 powers,
        rounded to float32, as ``step_by_operators`` takes them)."""
        counts = np.arange(int(self.steps.max()) + 2, dtype=np.float64) if self.steps.numel() else np.arange(2.0)
        b1, b2 = self.betas
        return (1.0 - b1 ** counts).astype(np.float32), (1.0 - b2 ** counts).astype(np.float32)

    def _cpu_arrays(self) -> tuple[np.ndarray, ...] | None:
        """The parameter, its gradient, the moments and step counts as numpy views [N, C] / [N] for the one-pass
        step: None unless all are contiguous float32 tensors on the CPU (a gradient of another layout is copied)."""
        p, g = self.param, self.param.grad
        if g is None:
            return None
        tensors = (p, self.exp_avg, self.exp_avg_sq, self.steps)
        if any(t.device.type != "cpu" or t.dtype != torch.float32 or not t.is_contiguous() for t in tensors) \
                or g.device.type != "cpu" or g.shape != p.shape:
            return None
        rows = p.shape[0]
        g = g.detach().to(torch.float32).contiguous()
        return (p.detach().numpy().reshape(rows, -1), g.numpy().reshape(rows, -1),
                self.exp_avg.numpy().reshape(rows, -1), self.exp_avg_sq.numpy().reshape(rows, -1), self.steps.numpy())

    @torch.no_grad()
    def step_by_operators(self) -> int:
        """``step`` written with torch's operators: gathers and scatters of the visible rows (about a third as fast
        on the CPU; ``tests/test_visible_adam.py`` holds the two together)."""
        rows = self.visible_rows()
        if rows.numel() == 0:
            return 0
        b1, b2 = self.betas
        g, m, t = self.first_moment(rows)
        v = self.exp_avg_sq[rows].mul_(b2).addcmul_(g, g, value=1 - b2)
        self.exp_avg_sq[rows] = v
        shape = (-1,) + (1,) * (g.ndim - 1)
        t64 = t.to(torch.float64)  # the corrections in double, as torch's Adam takes them (1 - 0.999 in float32 is
        # off by 1.3e-5)
        m_hat = m / (1 - b1 ** t64).to(m.dtype).reshape(shape)
        v_hat = v / (1 - b2 ** t64).to(v.dtype).reshape(shape)
        self.param[rows] -= self.param_groups[0]["lr"] * m_hat / (v_hat.sqrt() + self.eps)
        return int(rows.numel())

    def state_dict(self) -> dict:
        """Moments, per-row step counts and the lr (for checkpoints)."""
        return {"exp_avg": self.exp_avg.clone(), "exp_avg_sq": self.exp_avg_sq.clone(), "steps": self.steps.clone(),
                "lr": self.param_groups[0]["lr"], "kind": "visible_adam"}

    def load_state_dict(self, state: dict) -> None:
        """Restore from ``state_dict()``; shapes must match the parameter."""
        if state.get("kind") != "visible_adam" or tuple(state["exp_avg"].shape) != tuple(self.param.shape):
            raise ValueError("optimiser state does not fit this parameter")
        self.exp_avg = state["exp_avg"].clone()
        self.exp_avg_sq = state["exp_avg_sq"].clone()
        self.steps = state["steps"].clone()
        self.param_groups[0]["lr"] = float(state["lr"])


@njit(cache=True)
def _visible_adam_rows(param, grad, exp_avg, exp_avg_sq, steps, corrections1, corrections2, lr, b1, b2,
                       eps):  # pragma: no cover - numba
    """``VisibleAdam.step`` in one pass over the rows of float32 arrays [N, C] (``steps`` [N]), in place: a row whose
    gradient has a non-zero entry and no NaN (as ``visible_rows``: its largest |g| above 0) counts a step and takes
    Adam's update with its own bias correction (``corrections1/2[t]``: 1 − β^t); the others are left alone. Returns
    the rows moved."""
    moved = 0
    channels = param.shape[1]
    for i in range(param.shape[0]):
        largest = 0.0
        for c in range(channels):
            a = abs(grad[i, c])
            if a != a:  # NaN: torch's amax gives NaN, which is not above 0
                largest = a
                break
            largest = max(largest, a)
        if not largest > 0.0:
            continue
        t = steps[i] + np.float32(1.0)
        steps[i] = t
        correction1, correction2 = corrections1[int(t)], corrections2[int(t)]
        for c in range(channels):
            g = grad[i, c]
            m = exp_avg[i, c] * np.float32(b1) + g * np.float32(1.0 - b1)
            v = exp_avg_sq[i, c] * np.float32(b2) + np.float32(1.0 - b2) * g * g
            exp_avg[i, c] = m
            exp_avg_sq[i, c] = v
            denominator = np.float32(math.sqrt(v / correction2)) + np.float32(eps)
            param[i, c] -= np.float32(lr) * (m / correction1) / denominator
        moved += 1
    return moved
