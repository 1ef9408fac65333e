"""The coarse colour field (``engine/colour_field.py``): its grid, its interpolation, its coherent steps, and how the
stylization phase uses it (switch, stroke size, folding into c_s, defaults)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from synthetic import blob_scene, look_at_camera, ring_cameras

from gstyle_core.engine.arg_types import on_off_arg
from gstyle_core.engine.colour_field import (
    FIELD_CELL_PX,
    FIELD_STEP_SHARE,
    ColourField,
    build_colour_field,
    pixel_footprint,
    unique_points,
)
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer


def test_pixel_footprint_is_distance_over_focal_length():
    cams = [look_at_camera((0.0, 0.0, -d), (0.0, 0.0, 0.0)) for d in (2.0, 4.0, 6.0)]
    points = np.zeros((5, 3))
    assert pixel_footprint(points, cams) == pytest.approx(4.0 / cams[1].fx)
    with pytest.raises(ValueError, match="needs Gaussians and cameras"):
        pixel_footprint(points, [])


def test_the_lattice_holds_only_the_corners_of_occupied_cells():
    """Two clusters far apart: the lattice points are the 8 corners of each occupied cell, nothing in between (an
    unbounded capture's far background costs no more than its foreground, and no cell grows)."""
    near = torch.tensor([[0.01, 0.02, 0.03], [0.05, 0.06, 0.07]])
    far = near + 1000.0
    field = ColourField(torch.cat([near, far]), cell=0.1, lr=0.1, visible=False)
    assert field.cells == 16 and field.cell == 0.1
    assert field.extent == (10002, 10002, 10002)
    assert torch.allclose(field.weights.sum(1), torch.ones(4))
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="cell size"):
            ColourField(near, cell=bad, lr=0.1)
    with pytest.raises(ValueError, match="finite centres"):
        ColourField(torch.tensor([[0.0, float("inf"), 0.0]]), cell=0.1, lr=0.1)


def test_unique_points_matches_torch_unique_of_rows_on_both_paths():
    g = torch.Generator().manual_seed(3)
    for points in (torch.randint(0, 40, (5000, 3), generator=g),  # one int64 key per row
                   torch.tensor([[0, 0, 0], [2**40, 1, 2**30], [0, 0, 0], [5, 2**40, 1]])):  # too wide: rows sorted
        keys, inverse = unique_points(points)
        want_keys, want_inverse = torch.unique(points, dim=0, return_inverse=True)
        assert torch.equal(keys, want_keys) and torch.equal(inverse, want_inverse)


def test_the_field_interpolates_linearly_along_each_axis():
    """A field that is a linear function of the lattice points' positions reads that same function at every point:
    the lattice's axes and the interpolation weights are where they should be."""
    g = torch.Generator().manual_seed(0)
    points = torch.rand(400, 3, generator=g) * torch.tensor([2.0, 1.0, 0.5])
    field = ColourField(points, cell=0.1, lr=0.1, visible=False)
    positions = field.origin.float() + field.lattice.float() * field.cell
    a = torch.tensor([[1.0, -2.0, 0.5], [0.3, 0.0, 1.0], [0.0, 4.0, -1.0]])  # colour = position @ a
    with torch.no_grad():
        field.values.copy_(positions @ a)
    assert torch.allclose(field.sample(), points @ a, atol=1e-4)


def test_the_sparse_interpolation_and_its_adjoint_match_their_definitions():
    """``sample`` (one sparse product) is Σ over a point's 8 corners of weight × value, ``adjoint`` (the transpose's
    product) the weighted sum of the points' values onto each lattice point, and autograd through ``sample`` gives
    ``adjoint``: written out here with gathers and ``index_add`` (float64)."""
    g = torch.Generator().manual_seed(3)
    points = torch.rand(700, 3, generator=g) * torch.tensor([3.0, 1.0, 2.0])
    field = ColourField(points, cell=0.15, lr=0.1)
    grid, n, m = field.grid, len(points), field.cells
    values, colour_grad = torch.randn(m, 3, generator=g), torch.randn(n, 3, generator=g)
    index, weights = grid.index, grid.weights.double()
    by_definition = (values.double()[index] * weights[..., None]).sum(1)
    onto_lattice = torch.zeros(m, 3, dtype=torch.float64).index_add_(
        0, index.reshape(-1), (weights[..., None] * colour_grad.double()[:, None, :]).reshape(-1, 3))
    assert torch.allclose(grid.sample(values).double(), by_definition, atol=1e-5)
    assert torch.allclose(grid.adjoint(colour_grad).double(), onto_lattice, atol=1e-5)
    leaf = values.clone().requires_grad_(True)
    grid.sample(leaf).backward(colour_grad)
    assert torch.equal(leaf.grad, grid.adjoint(colour_grad))
    field.take_gradient(colour_grad)  # the step's shortcut: the colours' gradient through the field, no forward
    assert torch.equal(field.values.grad, grid.adjoint(colour_grad))


def test_a_field_stepped_and_not_yet_folded_is_folded_before_the_next_step():
    """Between a field's step and its fold the colours lack the field's values; a step's ``begin`` folds them first
    (the views must render the whole colour), and a fold leaves nothing unfolded."""
    from types import SimpleNamespace

    from gstyle_core.engine.colour_steps import ColourSteps

    points = torch.rand(50, 3, generator=torch.Generator().manual_seed(4))
    field = ColourField(points, cell=0.3, lr=0.1)
    assert not field.unfolded
    field.take_gradient(torch.ones(50, 3))
    field.step()
    assert field.unfolded and field.values.abs().max() > 0
    steps = ColourSteps(SimpleNamespace(settings=SimpleNamespace(colour_field=True, style_scale=1.0)))
    steps.c_opt = torch.full((50, 3), 0.5, requires_grad=True)
    steps.optimiser, steps.field, steps._field_for = torch.optim.Adam([steps.c_opt], lr=0.1), field, (True, 1.0)
    expected = 0.5 + field.sample().detach()
    colours = steps.begin(0.1)
    assert colours is steps.c_opt and torch.equal(colours.detach(), expected)
    assert not field.unfolded and field.values.abs().max() == 0


def test_one_step_moves_a_neighbourhood_together_and_leaves_far_points():
    points = torch.tensor([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.0, 0.03, 0.0], [3.0, 3.0, 3.0]])
    field = ColourField(points, cell=0.5, lr=0.1, visible=True)
    colours = torch.full((4, 3), 0.5)
    (field.sample()[0] * torch.tensor([1.0, 0.0, 0.0])).sum().backward()  # a gradient on point 0's red only
    field.step()
    field.fold_into(colours)
    moved = colours - 0.5
    assert moved[0, 0] < -0.05 and moved[1, 0] < -0.05 and moved[2, 0] < -0.05  # its neighbours move with it
    assert torch.allclose(moved[:3, 0], moved[0, 0].expand(3), rtol=0.2)
    assert moved[3].abs().max() == 0 and moved[:, 1:].abs().max() == 0  # far points and other channels stay
    assert field.values.abs().max() == 0  # folded: the colours hold all of it


def small_engine(**overrides) -> Stylizer:
    settings = resolve_settings("preview", "360", 6, max_views=6, epochs=4, min_steps=0, working_width=32,
                                refit_iterations=2, preprocess_rounds=0, split_rate=0.0, max_gaussians=10_000,
                                clip_available=False, **overrides)
    style = np.zeros((16, 16, 3), np.float32)
    style[:, :8, 0] = 1.0
    style[:, 8:, 2] = 1.0
    return Stylizer(blob_scene(300, seed=4), ring_cameras(6), style, settings, objective_factory=ColourPull)


class ColourPull:
    """Stand-in objective: pulls every pixel towards a random colour drawn per pixel and view (fixed per view), so
    neighbouring Gaussians get unrelated gradients."""

    def __init__(self, style, settings) -> None:
        self.weights = settings.weights

    def set_weights(self, weights) -> None:
        self.weights = weights

    def __call__(self, image, content, view, coverage=None):
        target = torch.rand(image.shape, generator=torch.Generator().manual_seed(view))
        loss = ((image - target) ** 2).mean()
        return loss, {"nnfm": float(loss.detach())}


def lr_at(engine: Stylizer, index: int) -> float:
    """The schedule's learning rate at optimiser step ``index`` (exponential from lr_start to lr_end)."""
    s, t = engine.settings, min(1.0, index / engine.stylize.steps)
    return float(np.exp((1 - t) * np.log(s.lr_start) + t * np.log(s.lr_end)))


def neighbour_agreement(engine: Stylizer, before: torch.Tensor) -> float:
    """Correlation of each Gaussian's colour change with its nearest neighbour's (1: moves alike; 0: unrelated)."""
    from scipy.spatial import cKDTree

    means = engine.params["means"].detach().numpy()
    _, j = cKDTree(means).query(means, k=2)
    change = (engine.c_s - before).numpy()
    return float(np.corrcoef(change.ravel(), change[j[:, 1]].ravel())[0, 1])


def test_360_defaults_without_clip_turn_the_field_on_and_an_option_turns_it_off():
    assert resolve_settings("preview", "360", clip_available=False).colour_field
    assert not resolve_settings("preview", "360", clip_available=False, colour_field=False).colour_field
    assert not resolve_settings("preview", "360", clip_available=True).colour_field  # CLIP keeps its place
    assert not resolve_settings("preview", "forward").colour_field  # the paper's values
    assert on_off_arg("1") is True and on_off_arg("off") is False
    with pytest.raises(Exception, match="expected 1 or 0"):
        on_off_arg("maybe")


def test_the_stylization_steps_the_field_and_folds_it_into_the_colours():
    engine = small_engine()
    while engine.phase != "stylize":
        engine.step()
    engine.step()  # the first optimiser step builds the field
    field = engine.stylize.field
    assert field is not None and engine.counters["field_cells"] == field.cells
    assert field.values.abs().max() == 0  # folded after the step
    groups = engine.stylize.optimiser.param_groups
    assert groups[0]["lr"] == pytest.approx(FIELD_STEP_SHARE * lr_at(engine, 0))
    assert engine.decisions["colour_field"].startswith("on: ")
    footprint = pixel_footprint(engine.params["means"].detach().numpy(), engine.run_state.cameras)
    assert field.cell == pytest.approx(FIELD_CELL_PX * footprint)
    engine.set_params(style_scale=2.0)  # a stroke size twice as large: cells twice as large, from the next step
    engine.step()
    assert engine.stylize.field.cell == pytest.approx(2 * FIELD_CELL_PX * footprint)
    engine.set_params(colour_field=0.0)
    engine.step()
    assert engine.stylize.field is None and engine.decisions["colour_field"] == "off"
    assert engine.stylize.optimiser.param_groups[0]["lr"] == pytest.approx(lr_at(engine, 2))


def test_with_the_field_neighbouring_colours_change_more_alike():
    changes = {}
    for on in (False, True):
        engine = small_engine(colour_field=on)
        while engine.phase != "stylize":
            engine.step()
        before = engine.c_s.clone()
        while engine.phase == "stylize":
            engine.step()
        changes[on] = neighbour_agreement(engine, before)
    assert changes[True] > changes[False] + 0.03, changes


def test_build_colour_field_scales_its_cells_with_the_stroke_size():
    points = torch.as_tensor(blob_scene(200, seed=1).means)
    cams = ring_cameras(4)
    one = build_colour_field(points, cams, 1.0, 0.1, visible=True)
    two = build_colour_field(points, cams, 2.0, 0.1, visible=True)
    assert two.cell == pytest.approx(2 * one.cell)
    assert two.cells < one.cells
