"""The studio's quality section (issue #34): each preset's estimate for this scene, the width the run is at, Refine
(the next finer level from the colours as they are, no restart) and the finished run's speckle figure (headless GL
window, real small engine in a worker thread)."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import BUILT, small_studio  # noqa: E402
from imgui_driver import paused_studio_driver  # noqa: E402

from gstyle_core.pipeline.plan import StepTimes, estimate_seconds, planned_steps  # noqa: E402
from gstyle_core.pipeline.settings import resolve_settings  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


def test_refine_and_the_quality_choice_in_the_panel(window, monkeypatch, tmp_path):
    app = small_studio(window, monkeypatch, tmp_path)
    try:
        driver = paused_studio_driver(window, monkeypatch, app)
        assert app.bridge.wait_until(lambda s: bool(s.plans), 30)
        driver.frame()
        assert set(app.panel.quality_estimates) == {"preview", "balanced", "final"}
        assert all(v is None for v in app.panel.quality_estimates.values())  # nothing measured yet
        assert "Width: 32 px" in driver.recorder.texts
        app.bridge.resume()
        assert app.bridge.wait_until(lambda s: s.done and s.summary is not None or s.error, 120), \
            app.bridge.state.error
        driver.frame()
        estimates = app.panel.quality_estimates
        assert 0 < estimates["preview"] < estimates["balanced"] < estimates["final"]  # priced at this run's steps
        result = [t for t in driver.recorder.texts if t.startswith("Fine grain at screen size: ")]
        assert result and result[0].endswith("(1 = the painting's own)"), driver.recorder.texts
        ratio = app.bridge.state.summary["display"]["speckle_ratio"]
        assert app.panel.grain == ("-" if ratio is None else f"{ratio:.2f}") and app.panel.grain in result[0]
        colours = BUILT[-1].c_s.clone()
        assert driver.recorder.find("Refine -> 64 px").tooltip
        commands = driver.click("Refine -> 64 px")
        assert [c.name for c in commands] == ["refine"]
        assert app.bridge.wait_until(lambda s: s.done and s.summary is not None and s.plans.get("levels") == [32, 64]
                                     or s.error, 120), app.bridge.state.error
        engine = BUILT[-1]
        assert len(BUILT) == 1 and engine.levels == (32, 64)  # the same engine went on: no restart
        assert not np.array_equal(engine.c_s.numpy(), colours.numpy())
        driver.frame()
        assert "Width: 64 px (levels 32 px -> 64 px)" in driver.recorder.texts
        assert app.panel.refine_note == "" and not [t for t in driver.recorder.texts if "refining" in t]  # it ended
        assert all(ord(c) < 256 for text in driver.recorder.texts for c in text)  # the font has Latin-1 only
        commands = driver.click("balanced (~" + [w.path for w in driver.recorder.widgets
                                                 if w.path.endswith("###q_balanced")][0].split("(~", 1)[1])
        assert [c.args for c in commands if c.name == "set_quality"] == [{"preset": "balanced"}]
        driver.frame()
        commands = driver.click("Restart at balanced")
        assert [c.name for c in commands] == ["restart_quality"] and app.engine_config["preset"] == "balanced"
    finally:
        app.close(timeout=60)


def test_refine_moves_the_weights_for_its_level_only_and_a_restart_returns_the_panels(window, monkeypatch, tmp_path):
    """A calibrated 360° preview refined: its first level runs at the weights of runs with levels (the sliders show
    them meanwhile); Restart goes back to the values before the refine, except one the artist moved since."""
    from fakes import keep_small_360_stylizer

    from app.panels import Command

    app = small_studio(window, monkeypatch, tmp_path, factory=keep_small_360_stylizer)
    try:
        driver = paused_studio_driver(window, monkeypatch, app)
        before = dict(app.bridge.state.params)
        assert (before["lambda_nnfm"], before["lambda_edges"]) == (200.0, 0.0)
        app.bridge.resume()
        assert app.bridge.wait_until(lambda s: s.done or s.error, 120), app.bridge.state.error
        app.execute(Command("refine"))
        assert app.bridge.wait_until(lambda s: s.params.get("lambda_edges") == 4000.0 or s.error, 60)
        driver.frame()
        assert (app.panel.params["lambda_nnfm"], app.panel.params["lambda_edges"]) == (400.0, 4000.0)
        assert BUILT[-1].settings.weights.edges == 4000.0  # the level runs at them
        app.execute(Command("set_params", {"lambda_multiscale": 250.0}))  # the artist's own, after the refine
        app.execute(Command("restart"))
        assert app.bridge.wait_until(lambda s: len(BUILT) == 2 and s.params.get("lambda_edges") == 0.0 or s.error,
                                     60), app.bridge.state.error
        driver.frame()
        kept = {**before, "lambda_multiscale": 250.0}
        assert {k: app.panel.params[k] for k in kept} == kept
        w = BUILT[-1].settings.weights
        assert (w.nnfm, w.edges, w.multiscale, w.chroma_tv) == (200.0, 0.0, 250.0, before["lambda_chroma_tv"])
    finally:
        app.close(timeout=60)


def test_a_plan_prices_each_kind_of_step_and_grows_with_the_preset():
    plans = {name: planned_steps(resolve_settings(name, "360", 24, clip_available=False), 24)
             for name in ("preview", "balanced", "final")}
    assert "refine_512" not in plans["preview"] and plans["balanced"]["refine_targets_512"] == 24
    assert set(plans["final"]) >= {"refine_512", "refine_1024", "refine_targets_1024"}
    times = StepTimes()
    assert estimate_seconds(plans["preview"], times, 256) is None  # nothing measured: no figure
    times.add({"phase": "stylize", "seconds": 1.0})
    times.add({"phase": "ground_truth", "seconds": 0.2})
    times.add({"phase": "refine", "width": 512, "message": "level 512 px: crops at 512 px", "seconds": 2.0})
    times.add({"phase": "colour_match", "seconds": 5.0})  # one step, priced as nothing
    assert times.mean("refine_512") == 2.0 and times.mean("stylize") == 1.0
    preview, balanced, final = (estimate_seconds(plans[n], times, 256) for n in ("preview", "balanced", "final"))
    assert 0 < preview < balanced < final
    p = plans["preview"]
    assert preview == pytest.approx(p["stylize"] * 1.0 + p["ground_truth"] * 0.2 + p["refit"] * 0.15)


def test_the_eta_counts_the_steps_of_each_kind_still_to_come_and_a_restart_starts_from_the_run_before():
    """Early in a run only cheap ground-truth and refit steps are measured: the mean step would promise a fraction of
    the time (issue #35: 0:34-0:41 shown for runs of ~110 s). The ETA prices each kind's remaining steps, and a
    restarted run uses the run before's costs until its own are measured."""
    from gstyle_core.pipeline.plan import remaining_seconds

    plan = {"ground_truth": 10.0, "refit": 100.0, "stylize": 40.0}
    before = StepTimes()
    for phase, seconds in (("ground_truth", 0.05), ("refit", 0.1), ("stylize", 2.0)):
        before.add({"phase": phase, "seconds": seconds})
    now = StepTimes()
    for _ in range(10):
        now.add({"phase": "ground_truth", "seconds": 0.04})
    assert remaining_seconds(plan, now, 256) is None  # no stylization step known: no figure rather than a wrong one
    left = remaining_seconds(plan, now, 256, prior=before)
    assert left == pytest.approx(100 * 0.1 + 40 * 2.0)  # the ground truth is done; the rest at the run before's costs
    now.add({"phase": "stylize", "seconds": 3.0})
    assert remaining_seconds(plan, now, 256, prior=before) == pytest.approx(100 * 0.1 + 39 * 3.0)  # its own, once seen
