"""What a step reads back from the networks' device: the views' loss values once a step (``StepLosses``), a view's
content and coverage sent once (``StyleObjective._view_inputs``), the coarse term's weights decided without a read."""

from __future__ import annotations

import pytest
import torch
from fakes import engine_with_random_vgg

from gstyle_core.engine.step_losses import StepLosses, backward_views
from gstyle_core.style.coarse import position_weights
from gstyle_core.style.losses import TERM_NAMES, term_values
from gstyle_core.style.multiscale import DEFAULT_FACTORS


@pytest.fixture()
def engine(monkeypatch):
    engine = engine_with_random_vgg(monkeypatch, views_per_step=3)
    while engine.phase != "stylize":
        engine.step()
    return engine


def _view_args(engine, view: int):
    run = engine.run_state
    image = run.render_seen(view, run.active.gather_seen(run.c_s).clone().requires_grad_(True))
    return image, run.content_images[view], view, run.objective_coverage(view)


def test_evaluate_gives_the_calls_values_unread(engine):
    objective = engine.run_state.objective_fn()
    image, content, view, coverage = _view_args(engine, 0)
    loss, values = objective.evaluate(image, content, view, coverage)
    called_loss, called = objective(image, content, view, coverage)
    assert isinstance(values, torch.Tensor) and values.shape == (len(TERM_NAMES),)
    assert term_values(values) == called and float(loss.detach()) == float(called_loss.detach())
    assert called["nnfm"] > 0 and called["content"] > 0  # real terms, not zeros


def test_a_steps_losses_are_the_mean_of_its_views(engine):
    objective = engine.run_state.objective_fn()
    per_view = [objective(*_view_args(engine, v)) for v in range(3)]
    losses = StepLosses(3)
    shares = [losses.evaluate(objective, *_view_args(engine, v)) for v in range(3)]
    read = losses.read()
    assert list(read) == ["total", *TERM_NAMES]
    assert read["total"] == pytest.approx(sum(float(loss.detach()) for loss, _ in per_view) / 3, rel=1e-6)
    for name in TERM_NAMES:
        assert read[name] == pytest.approx(sum(terms[name] for _, terms in per_view) / 3, rel=1e-6, abs=1e-12)
    for share, (loss, _) in zip(shares, per_view, strict=True):  # what each view backpropagates: its share
        assert share.requires_grad and float(share.detach()) == pytest.approx(float(loss.detach()) / 3, rel=1e-6)


def test_objectives_that_give_floats_are_added_up_as_floats():
    def objective(value):
        return torch.tensor(value), {"pull": value / 2}

    losses = StepLosses(2)
    for value in (1.0, 3.0):
        losses.evaluate(objective, value)
    assert losses.read() == {"total": 2.0, "pull": 1.0}


def test_a_views_content_and_coverage_are_sent_once_while_they_are_the_same(engine):
    objective = engine.run_state.objective_fn()
    _, content, view, coverage = _view_args(engine, 1)
    assert objective._view_inputs(view, content, coverage)[0] is content  # on the CPU: nothing to send or keep
    objective.device = torch.device("meta")  # another device than the tensors': copies are made
    sent = objective._view_inputs(view, content, coverage)
    assert sent[0].device.type == "meta" and sent[1].device.type == "meta"
    assert objective._view_inputs(view, content, coverage)[0] is sent[0]  # kept
    assert objective._view_inputs(view, content.clone(), coverage)[0] is not sent[0]  # a new content target
    assert objective._view_inputs(None, content, coverage)[0] is not sent[0]  # a one-off crop: never kept
    objective.clear_content_cache()
    assert objective._device_inputs == {}


def test_the_coarse_terms_weights_sum_to_one_or_weigh_all_alike():
    grid = torch.zeros(2, 1, 3, 4)
    grid[0, 0, 1, 2], grid[0, 0, 0, 0] = 3.0, 1.0
    w = position_weights(grid)
    assert w.shape == (2, 1, 12)
    torch.testing.assert_close(w.sum(-1), torch.ones(2, 1))
    assert float(w[0, 0, 6]) == 0.75 and float(w[0, 0, 0]) == 0.25
    torch.testing.assert_close(w[1], torch.full((1, 12), 1 / 12))  # no coverage: the whole frame


@pytest.mark.parametrize("terms", [("multiscale",), ("clip",), ("clip", "multiscale")],
                         ids=["broad strokes", "coarse substitute", "both"])
def test_a_steps_views_backpropagate_as_each_alone_with_terms_taken_together(engine, terms):
    from dataclasses import replace

    run = engine.run_state
    objective = run.objective_fn()
    objective.set_weights(replace(run.settings.weights, clip=10.0 if "clip" in terms else 0.0,
                                  multiscale=50.0 if "multiscale" in terms else 0.0))
    assert objective.takes_views_together(3) and objective.loss.clip_term.label.startswith("coarse")
    seen = run.active.gather_seen(run.c_s).clone()

    def inputs(leaf):
        return [(run.render_seen(v, leaf), run.content_images[v], v, run.objective_coverage(v)) for v in range(3)]

    with torch.no_grad():  # the views' content features cached first: both paths below run the same networks
        for render, content, view, coverage in inputs(seen):
            objective.evaluate(render, content, view, coverage)
    alone = seen.clone().requires_grad_(True)
    expected = StepLosses(3)
    calls = objective.calls["vgg"]
    for render, content, view, coverage in inputs(alone):
        expected.evaluate(objective, render, content, view, coverage=coverage).backward()
    calls_alone, calls = objective.calls["vgg"] - calls, objective.calls["vgg"]
    together = seen.clone().requires_grad_(True)
    losses = StepLosses(3)
    backward_views(objective, [lambda view=view: view for view in inputs(together)], losses)
    passes = {"clip": 1, "multiscale": len(DEFAULT_FACTORS)}  # the coarse substitute: one; broad strokes: a level
    assert objective.calls["vgg"] - calls == calls_alone - 2 * sum(passes[t] for t in terms)  # 3 views in 1 pass
    torch.testing.assert_close(together.grad, alone.grad, rtol=1e-4, atol=1e-7)
    read, want = losses.read(), expected.read()
    assert all(read[t] > 0 for t in terms) and list(read) == list(want)
    for name in want:
        assert read[name] == pytest.approx(want[name], rel=1e-5, abs=1e-9)


def test_without_a_term_to_take_together_the_views_go_one_after_another(engine):
    from dataclasses import replace

    objective = engine.run_state.objective_fn()
    objective.set_weights(replace(engine.run_state.settings.weights, clip=0.0, multiscale=0.0))
    assert not objective.takes_views_together(3)
    made, run = [], engine.run_state
    leaf = run.active.gather_seen(run.c_s).clone().requires_grad_(True)

    def view_input(view):
        assert (leaf.grad is not None) == (view > 0)  # the view before was backpropagated before this one is made
        made.append(view)
        return run.render_seen(view, leaf), run.content_images[view], view, run.objective_coverage(view)

    losses = StepLosses(3)
    backward_views(objective, [lambda view=view: view_input(view) for view in range(3)], losses)
    assert made == [0, 1, 2] and leaf.grad is not None and losses.read()["total"] > 0
