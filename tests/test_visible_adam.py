"""``VisibleAdam`` (``engine/visible_adam.py``): Adam on the rows a step's views see, each with its own step count;
its one-pass CPU step against the step written with torch's operators, and both against torch's Adam."""

from __future__ import annotations

import copy

import pytest
import torch

from gstyle_core.engine.visible_adam import VisibleAdam


def random_gradients(rows: int, steps: int, seed: int, seen: float = 0.6, nan_rows: int = 0) -> list[torch.Tensor]:
    """A gradient [rows, 3] a step, a random ``seen`` share of rows non-zero (whole rows); ``nan_rows`` rows of each
    step get a NaN in one channel."""
    g = torch.Generator().manual_seed(seed)
    out = []
    for _ in range(steps):
        grad = torch.randn(rows, 3, generator=g) * (torch.rand(rows, 1, generator=g) < seen)
        grad[torch.randint(rows, (max(rows // 10, 1),), generator=g), 1] = 0.0  # zeros inside seen rows too
        if nan_rows:
            grad[torch.randperm(rows, generator=g)[:nan_rows], 2] = float("nan")
        out.append(grad)
    return out


def run(optimiser, param: torch.Tensor, gradients: list[torch.Tensor], by_operators: bool = False) -> list[int]:
    moved = []
    for grad in gradients:
        param.grad = grad.clone()
        moved.append(optimiser.step_by_operators() if by_operators else optimiser.step())
    return moved


def test_with_every_row_in_view_it_is_torchs_adam():
    start = torch.rand(64, 3, generator=torch.Generator().manual_seed(1))
    gradients = [torch.randn(64, 3, generator=torch.Generator().manual_seed(10 + i)) for i in range(12)]
    reference = start.clone().requires_grad_(True)
    adam = torch.optim.Adam([reference], lr=0.05)
    for grad in gradients:
        reference.grad = grad.clone()
        adam.step()
    for by_operators in (False, True):
        param = start.clone().requires_grad_(True)
        assert run(VisibleAdam(param, lr=0.05), param, gradients, by_operators) == [64] * 12
        torch.testing.assert_close(param.detach(), reference.detach(), rtol=1e-5, atol=1e-6)


def test_rows_out_of_view_keep_their_colour_moments_and_step_count():
    param = torch.rand(4, 3).requires_grad_(True)
    opt = VisibleAdam(param, lr=0.1)
    before = param.detach().clone()
    seen_rows = [[0, 1], [0], [0, 2], [0]]
    for rows in seen_rows:
        grad = torch.zeros(4, 3)
        grad[rows] = 1.0
        param.grad = grad
        assert opt.step() == len(rows)
    assert opt.steps.tolist() == [4.0, 1.0, 1.0, 0.0]
    assert torch.equal(param.detach()[3], before[3]) and opt.exp_avg[3].abs().max() == 0
    # a row's first step is Adam's first step whenever it comes: the same move for rows 1 and 2
    torch.testing.assert_close(param.detach()[1] - before[1], param.detach()[2] - before[2])
    torch.testing.assert_close(param.detach()[1] - before[1], torch.full((3,), -0.1), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("nan_rows", [0, 5])
def test_the_one_pass_step_is_the_operators_step(nan_rows):
    """Random visibility over 15 steps (zeros inside seen rows; with NaN in some rows, which neither moves, as
    ``visible_rows`` reads a NaN as unseen): the same rows move, the same values to float32 rounding."""
    start = torch.rand(500, 3, generator=torch.Generator().manual_seed(2))
    gradients = random_gradients(500, 15, seed=3, nan_rows=nan_rows)
    one_pass, by_operators = start.clone().requires_grad_(True), start.clone().requires_grad_(True)
    a, b = VisibleAdam(one_pass, lr=0.02), VisibleAdam(by_operators, lr=0.02)
    assert run(a, one_pass, gradients) == run(b, by_operators, gradients, by_operators=True)
    assert torch.equal(a.steps, b.steps)
    torch.testing.assert_close(one_pass.detach(), by_operators.detach(), rtol=1e-6, atol=1e-6)
    torch.testing.assert_close(a.exp_avg, b.exp_avg, rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(a.exp_avg_sq, b.exp_avg_sq, rtol=1e-6, atol=1e-9)
    assert bool(torch.isfinite(one_pass).all())


def test_a_parameter_the_one_pass_step_cannot_take_goes_through_the_operators():
    """float64, or a gradient of another shape than the parameter's: the operators' step (the same maths)."""
    start = torch.rand(40, 3, dtype=torch.float64)
    gradients = [g.double() for g in random_gradients(40, 4, seed=5)]
    param = start.clone().requires_grad_(True)
    reference = start.clone().requires_grad_(True)
    opt = VisibleAdam(param, lr=0.1)
    param.grad = gradients[0].clone()
    assert opt._cpu_arrays() is None  # float64: not the one-pass step's
    param.grad = None
    ref = VisibleAdam(reference, lr=0.1)
    assert run(opt, param, gradients) == run(ref, reference, gradients, by_operators=True)
    assert torch.equal(param, reference)


def test_its_state_round_trips_and_steps_on_alike():
    param = torch.rand(30, 3).requires_grad_(True)
    opt = VisibleAdam(param, lr=0.05)
    run(opt, param, random_gradients(30, 3, seed=6))
    copy_param = param.detach().clone().requires_grad_(True)
    restored = VisibleAdam(copy_param, lr=1.0)
    restored.load_state_dict(copy.deepcopy(opt.state_dict()))
    later = random_gradients(30, 3, seed=7)
    run(opt, param, later)
    run(restored, copy_param, later)
    assert torch.equal(param, copy_param)
