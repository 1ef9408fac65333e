"""A capture larger than a run can hold: the plan is said before the run, and the result is the whole capture."""

from __future__ import annotations

import numpy as np
from fakes import short_pull_run

from gstyle_core.engine.capacity import nearest_rows, plan_capacity, with_neighbour_colours
from gstyle_core.scene import importance_order
from tests.synthetic import blob_scene, ring_cameras


def _engine(scene, **overrides):
    return short_pull_run(scene, ring_cameras(4), 2, epochs=3, **overrides)


def test_a_capture_that_fits_is_stylized_whole_and_says_so():
    plan = plan_capacity(blob_scene(50), 80, "a test")
    assert not plan.reduced and plan.max_gaussians == 80
    assert plan.note.startswith("all 50 Gaussians stylized") and "up to 30 more" in plan.note
    assert "cut back to none" in plan_capacity(blob_scene(50), 50, "a test").note


def test_the_most_visible_gaussians_are_held_when_they_do_not_all_fit():
    scene = blob_scene(200, seed=5)
    plan = plan_capacity(scene, 120, "a test")
    assert plan.reduced and len(plan.held) == 120 and np.all(np.diff(plan.held) > 0)
    assert set(plan.held) == set(importance_order(scene.log_scales, scene.opacity_logits)[:120].tolist())
    assert "the other 80 keep their shape" in plan.note and "all 200 are in the result" in plan.note


def test_nearest_rows_matches_a_brute_force_search():
    rng = np.random.default_rng(0)
    points, queries = rng.normal(size=(300, 3)), rng.normal(size=(500, 3))
    queries[0] = np.nan  # non-finite coordinates: searched as the origin, no crash
    brute = np.argmin(((np.nan_to_num(queries)[:, None] - points[None]) ** 2).sum(-1), axis=1)
    assert np.array_equal(nearest_rows(points, queries), brute)


def test_a_reduced_run_stylizes_what_it_holds_and_returns_every_gaussian():
    scene = blob_scene(200, seed=3)
    eng = _engine(scene, max_gaussians=120)
    assert eng.gaussian_count == 120 and "more than the 120 this run can hold" in eng.decisions["capacity"]
    eng.run()
    assert eng.gaussian_count == 120  # no splits past the cap
    out = eng.stylized_scene()
    assert out.count == 200 + eng.gaussian_count - 120  # every input Gaussian, never fewer
    held = eng.capacity.held
    rest = np.setdiff1d(np.arange(200), held)
    tail = out.subset(np.arange(eng.gaussian_count, out.count))
    assert np.array_equal(tail.means, scene.means[rest]) and np.array_equal(tail.quats, scene.quats[rest])
    stylized = out.subset(np.arange(eng.gaussian_count))
    near = nearest_rows(stylized.means, tail.means)
    assert np.allclose(tail.sh_dc, stylized.sh_dc[near])  # the nearest stylized neighbour's colour
    assert np.abs(tail.rgb - scene.rgb[rest]).max() > 0.05  # ... which the style changed
    assert not np.any(tail.sh_rest)


def test_a_resumed_run_holds_the_part_its_checkpoint_was_planned_with(monkeypatch):
    """The cap derived from the free memory changes between a run and its resume: the resumed engine is planned with
    the saved cap (``saved_capacity``), holds the same Gaussians, loads the state and ends as the run would have."""
    from gstyle_core.engine import resources
    from gstyle_core.engine.checkpoint import engine_fingerprint, saved_capacity

    scene = blob_scene(200, seed=6)
    monkeypatch.setattr(resources, "default_max_gaussians", lambda *a, **k: (120, "memory then"))
    first = _engine(scene)
    for _ in range(6):
        first.step()
    state = first.state_dict()
    monkeypatch.setattr(resources, "default_max_gaussians", lambda *a, **k: (150, "memory now"))
    afresh = _engine(scene)  # planned afresh: another part, whose fingerprint refuses the checkpoint
    assert afresh.gaussian_count == 150 and engine_fingerprint(afresh) != engine_fingerprint(first)
    kept = saved_capacity(state)
    assert kept == (120, "memory then, kept from the run resumed") and saved_capacity({"phase": "stylize"}) is None
    again = _engine(scene, capacity=kept)
    again.load_state_dict(state)
    assert engine_fingerprint(again) == engine_fingerprint(first)
    assert again.global_step == first.global_step and np.array_equal(again.capacity.held, first.capacity.held)
    assert again.decisions["capacity"].startswith("200 Gaussians are more than the 120")
    first.run()
    again.run()
    assert np.allclose(again.stylized_scene().sh_dc, first.stylized_scene().sh_dc, atol=1e-6)


def test_a_reduced_region_run_leaves_the_rest_outside_the_region_as_it_was():
    scene = blob_scene(200, seed=4, sh_degree=1)
    box = (-5.0, -5.0, -5.0, 0.0, 5.0, 5.0)  # x <= 0
    eng = _engine(scene, max_gaussians=120, region=box)
    eng.run()
    out = eng.stylized_scene()
    rest = np.setdiff1d(np.arange(200), eng.capacity.held)
    tail = out.subset(np.arange(out.count - len(rest), out.count))
    outside = scene.means[rest, 0] > 0.0
    assert outside.any() and (~outside).any()
    assert np.array_equal(tail.sh_dc[outside], scene.sh_dc[rest][outside])
    assert np.array_equal(tail.sh_rest[outside], scene.sh_rest[rest][outside])  # SH bands kept
    assert not np.any(tail.sh_rest[~outside])


def test_with_neighbour_colours_is_the_scene_itself_when_all_fit():
    scene = blob_scene(20)
    plan = plan_capacity(scene, 100, "a test")
    assert with_neighbour_colours(scene, scene, plan) is scene
