"""Adam that updates only the rows the current view sees (as 3DGS trainers' visibility-selective Adam does).

With one training view per step, a Gaussian outside the view gets a zero gradient. Plain Adam still moves it on
its momentum and decays its moments, so colours keep drifting while nobody looks at them and each Gaussian's
effective step depends on how often it is in view. Here the rows with a zero gradient keep their colour, their
moments and their own step count; the others take an ordinary Adam step with bias correction by their own count.
"""

from __future__ import annotations

import torch


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
        """One Adam step on the visible rows; returns how many rows moved."""
        rows = self.visible_rows()
        if rows.numel() == 0:
            return 0
        b1, b2 = self.betas
        g, m, t = self.first_moment(rows)
        v = self.exp_avg_sq[rows].mul_(b2).addcmul_(g, g, value=1 - b2)
        self.exp_avg_sq[rows] = v
        shape = (-1,) + (1,) * (g.ndim - 1)
        m_hat = m / (1 - b1 ** t).reshape(shape)
        v_hat = v / (1 - b2 ** t).reshape(shape)
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
