"""A step's colours are sent to the rasterizer once (``ColourSteps.seen_colours``): the gradients are those of
placing and rendering them for every view, to the bit, with and without a region and the colour field."""

from __future__ import annotations

import pytest
import torch
from fakes import engine_with_random_vgg

HALF = (-10.0, -10.0, -10.0, 0.0, 10.0, 10.0)  # the x <= 0 half of the blob


def _at_stylize(monkeypatch, **overrides):
    engine = engine_with_random_vgg(monkeypatch, views_per_step=3, **overrides)
    while engine.phase != "stylize":
        engine.step()
    engine.step()  # one optimiser step: Adam's moments are not zero
    return engine


def _per_view_gradient(engine, colours: torch.Tensor) -> torch.Tensor:
    """The gradient of the step's colours the way each view once made it: placed and rendered per view."""
    run, stylize = engine.run_state, engine.stylize
    for view in stylize.views_of_step():
        image = run.render_seen(view, run.active.place_in_seen(run.c_s, colours))
        loss, _ = run.objective_fn()(image, run.content_images[view], view, coverage=run.objective_coverage(view))
        (loss / run.settings.views_per_step).backward()
    return colours.grad.clone()


@pytest.mark.parametrize("overrides", [{}, {"region": HALF}, {"region": HALF, "colour_field": True}],
                         ids=["whole scene", "region", "region and colour field"])
def test_the_steps_colours_sent_once_give_the_per_view_gradient(monkeypatch, overrides):
    engine = _at_stylize(monkeypatch, **overrides)
    steps = engine.stylize.colour_steps
    colours = steps.begin(engine.stylize.lr())
    expected = _per_view_gradient(engine, colours)
    if overrides.get("region"):
        assert steps.seen_colours().shape[0] > colours.shape[0]  # the seen rows hold more than the active ones
    colours.grad = None
    seen = steps.seen_colours()
    assert steps.seen_colours() is seen  # made once a step
    run = engine.run_state
    for view in engine.stylize.views_of_step():
        image = run.render_seen(view, seen)
        loss, _ = run.objective_fn()(image, run.content_images[view], view, coverage=run.objective_coverage(view))
        (loss / run.settings.views_per_step).backward()
    assert colours.grad is None  # nothing reaches the optimised colours before the step ends
    steps._carry_back()
    assert torch.equal(colours.grad, expected)


def test_seen_colours_needs_a_started_step(monkeypatch):
    engine = _at_stylize(monkeypatch)
    steps = engine.stylize.colour_steps
    steps.stop()
    with pytest.raises(RuntimeError, match="before begin"):
        steps.seen_colours()
