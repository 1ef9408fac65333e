"""The studio's quality section (issue #34): each preset's estimate for this scene, the width the run is at, Refine
(the next finer level from the colours as they are, no restart) and the finished run's speckle figure (headless GL
window, real small engine in a worker thread)."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import BUILT, small_studio  # noqa: E402
from imgui_driver import paused_studio_driver  # noqa: E402

from gstyle_core.engine.plan import (  # noqa: E402
    FALLBACK,
    MIN_SAMPLES,
    WARMUP_STEPS,
    MachineRates,
    StepTimes,
    estimate_seconds,
    planned_steps,
    step_kind,
)
from gstyle_core.engine.settings import resolve_settings  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


def test_refine_and_the_quality_choice_in_the_panel(window, monkeypatch, tmp_path):
    app = small_studio(window, monkeypatch, tmp_path)
    try:
        driver = paused_studio_driver(window, monkeypatch, app)
        assert app.engine.bridge.wait_until(lambda s: bool(s.plans), 30)
        driver.frame()
        assert set(app.panel.quality_estimates) == {"preview", "balanced", "final"}
        assert all(v is None for v in app.panel.quality_estimates.values())  # nothing measured yet
        assert "Width: 32 px" in driver.recorder.texts
        app.engine.bridge.resume()
        assert app.engine.bridge.wait_until(lambda s: s.done and s.summary is not None or s.error, 120), \
            app.engine.bridge.state.error
        driver.frame()
        estimates = app.panel.quality_estimates
        assert 0 < estimates["preview"] < estimates["balanced"] < estimates["final"]  # priced at this run's steps
        result = [t for t in driver.recorder.texts if t.startswith("Fine grain at screen size: ")]
        assert result and result[0].endswith("(1 = the painting's own)"), driver.recorder.texts
        ratio = app.engine.bridge.state.summary["display"]["speckle_ratio"]
        assert app.panel.grain == ("-" if ratio is None else f"{ratio:.2f}") and app.panel.grain in result[0]
        colours = BUILT[-1].c_s.clone()
        assert driver.recorder.find("Refine -> 64 px").tooltip
        commands = driver.click("Refine -> 64 px")
        assert [c.name for c in commands] == ["refine"]
        assert app.engine.bridge.wait_until(lambda s: s.done and s.summary is not None
                                            and s.plans.get("levels") == [32, 64] or s.error, 120), \
            app.engine.bridge.state.error
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
        assert [c.name for c in commands] == ["restart_quality"] and app.engine.config["preset"] == "balanced"
        driver.frame()  # the runs before price the presets from the restart on: no "measuring" again
        assert all(v is not None for v in app.panel.quality_estimates.values()), app.panel.quality_estimates
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
        before = dict(app.engine.bridge.state.params)
        assert (before["lambda_nnfm"], before["lambda_edges"]) == (200.0, 0.0)
        app.engine.bridge.resume()
        assert app.engine.bridge.wait_until(lambda s: s.done or s.error, 120), app.engine.bridge.state.error
        app.execute(Command("refine"))
        assert app.engine.bridge.wait_until(lambda s: s.params.get("lambda_edges") == 4000.0 or s.error, 60)
        driver.frame()
        assert (app.panel.params["lambda_nnfm"], app.panel.params["lambda_edges"]) == (400.0, 4000.0)
        assert BUILT[-1].settings.weights.edges == 4000.0  # the level runs at them
        app.execute(Command("set_params", {"lambda_multiscale": 250.0}))  # the artist's own, after the refine
        app.execute(Command("restart"))
        assert app.engine.bridge.wait_until(lambda s: len(BUILT) == 2 and s.params.get("lambda_edges") == 0.0
                                            or s.error, 60), app.engine.bridge.state.error
        driver.frame()
        kept = {**before, "lambda_multiscale": 250.0}
        assert {k: app.panel.params[k] for k in kept} == kept
        w = BUILT[-1].settings.weights
        assert (w.nnfm, w.edges, w.multiscale, w.chroma_tv) == (200.0, 0.0, 250.0, before["lambda_chroma_tv"])
    finally:
        app.close(timeout=60)


def _steps(rates: MachineRates, phase: str, seconds, **report) -> None:
    """Step reports of ``phase`` taking ``seconds`` each (one phase: the first steps are its warm-up)."""
    for value in seconds:
        rates.add({"phase": phase, "seconds": value, **report})


def test_a_plan_prices_each_kind_of_step_and_grows_with_the_preset():
    plans = {name: planned_steps(resolve_settings(name, "360", 24, clip_available=False), 24)
             for name in ("preview", "balanced", "final")}
    assert "refine_512" not in plans["preview"] and plans["balanced"]["refine_targets_512"] == 16  # its 16 views
    assert set(plans["final"]) >= {"refine_whole_512", "refine_targets_512"}  # every camera, whole views at 512 px
    assert plans["final"]["refine_targets_512"] == 24 and "refine_512" not in plans["final"]
    rates = MachineRates()
    assert estimate_seconds(plans["preview"], rates, 256) is None  # nothing measured: no figure
    warm = [9.0] * WARMUP_STEPS  # a phase's first steps (builds, caches, the UI's start): not its rate
    _steps(rates, "stylize", [*warm, *[1.0] * (MIN_SAMPLES - 1)])
    assert estimate_seconds(plans["preview"], rates, 256) is None  # too few steps past the warm-up yet
    _steps(rates, "stylize", [1.0])  # (the same phase goes on)
    _steps(rates, "ground_truth", [*warm, *[0.2] * MIN_SAMPLES])
    _steps(rates, "refine", [*warm, *[2.0] * MIN_SAMPLES], width=512, message="level 512 px: crops at 512 px")
    _steps(rates, "colour_match", [5.0] * 9)  # one step each, priced as nothing
    assert rates.median("refine_512") == 2.0 and rates.median("stylize") == 1.0
    preview, balanced, final = (estimate_seconds(plans[n], rates, 256) for n in ("preview", "balanced", "final"))
    assert 0 < preview < balanced < final
    # a whole-view level's steps are priced apart from a crop level's: every other one renders 4x the pixels
    assert rates.median("refine_whole_512") is None
    _steps(rates, "refine", [*warm, *[5.0] * MIN_SAMPLES], width=512,
           message="level 512 px (whole views): views at 512 px (views 1, 2, 3, 4)")
    assert rates.median("refine_whole_512") == 5.0 and rates.median("refine_512") == 2.0
    assert estimate_seconds(plans["final"], rates, 256) > final
    assert step_kind({"phase": "refine", "width": 512, "message": "level 512 px (whole views): ground truth 1/4"}) \
        == "refine_targets_512"
    p = plans["preview"]
    assert preview == pytest.approx(p["stylize"] * 1.0 + p["ground_truth"] * 0.2 + p["refit"] * 0.15)


def test_the_estimates_settle_a_burst_of_slow_or_fast_steps_moves_them_little():
    """Issue #48 item 4.4: the quality choice's times swung about 3x in one sitting (preview ~1:02 to ~3:13). At
    the session's median step times a burst of ten steps at 3x or 0.3x among a hundred moves each preset's estimate
    by under 5 % (and by less than half as much as the mean step time the estimates used before), and a restart's first
    steps (slower: builds, the UI's start) count for nothing."""
    plans = {name: planned_steps(resolve_settings(name, "360", 24, clip_available=False), 24)
             for name in ("preview", "balanced", "final")}
    rates, times = MachineRates(), StepTimes()
    noise = np.random.default_rng(0).uniform(0.9, 1.1, 100)
    for phase, scale in (("ground_truth", 0.3), ("refit", 0.15), ("stylize", 1.0)):
        for value in scale * noise:
            rates.add({"phase": phase, "seconds": value})
            times.add({"phase": phase, "seconds": value})
    settled = {n: estimate_seconds(p, rates, 256) for n, p in plans.items()}
    for burst in (3.0, 0.3):
        after = MachineRates({k: v.copy() for k, v in rates.samples.items()}, rates.phase)  # the stylize phase goes on
        _steps(after, "stylize", [burst] * 10)
        mean_before = times.mean("stylize")
        moved = StepTimes(dict(times.seconds), dict(times.counts))
        for _ in range(10):
            moved.add({"phase": "stylize", "seconds": burst})
        for name, plan in plans.items():
            change = estimate_seconds(plan, after, 256) / settled[name] - 1
            assert abs(change) < 0.05, (burst, name, change)
        assert abs(moved.mean("stylize") / mean_before - 1) > 2 * abs(change)  # the old figure moved more
    rates.new_run()  # a restart: its first steps of every phase are slow
    for phase in ("ground_truth", "refit", "stylize"):
        _steps(rates, phase, [20.0] * WARMUP_STEPS)
    assert {n: estimate_seconds(p, rates, 256) for n, p in plans.items()} == settled


def test_the_eta_counts_the_steps_of_each_kind_still_to_come_and_a_restart_starts_from_the_runs_before():
    """Early in a run only cheap ground-truth and refit steps are measured: the mean step would promise a fraction of
    the time (issue #35: 0:34-0:41 shown for runs of ~110 s). The ETA prices each kind's remaining steps at the
    session's rates (a restarted run: the runs before's), else at this run's own mean."""
    from gstyle_core.engine.plan import remaining_seconds

    plan = {"ground_truth": 10.0, "refit": 100.0, "stylize": 40.0}
    before = MachineRates()
    for phase, seconds in (("ground_truth", 0.05), ("refit", 0.1), ("stylize", 2.0)):
        _steps(before, phase, [seconds] * (WARMUP_STEPS + MIN_SAMPLES))
    now = StepTimes()
    for _ in range(10):
        now.add({"phase": "ground_truth", "seconds": 0.04})
    guess = 0.04 / FALLBACK["ground_truth"]  # no stylization step known: guessed from the ground truth's (#65)
    assert remaining_seconds(plan, now, 256) == pytest.approx(100 * FALLBACK["refit"] * guess + 40 * guess)
    assert remaining_seconds({"stylize": 4.0}, StepTimes(), 256) is None  # nothing measured: no figure
    left = remaining_seconds(plan, now, 256, before)
    assert left == pytest.approx(100 * 0.1 + 40 * 2.0)  # the ground truth is done; the rest at the session's rates
    now.add({"phase": "stylize", "seconds": 3.0})
    assert remaining_seconds(plan, now, 256, before) == pytest.approx(100 * 0.1 + 39 * 2.0)  # one step moves no rate
    assert remaining_seconds(plan, now, 256) == pytest.approx(100 * 0.15 * 3.0 + 39 * 3.0)  # alone: its own mean


@pytest.mark.slow
def test_a_continued_refined_result_says_the_width_it_is_at_and_refines_to_the_next(window, monkeypatch, tmp_path):
    """Issue #65 item 2: a run refined to 64 px, saved, reopened and continued says the width it is at (64 px), its
    levels and Refine's real next width (not the fresh engine's 64 px before its run was loaded), and Refine goes
    there."""
    from fakes import make_small_stylizer, ring_studio
    from imgui_driver import studio_driver
    from synthetic import blob_scene

    from app.panels import Command
    from gstyle_core.engine.kept_runs import find_result_state
    from gstyle_core.io import save_scene

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    original = tmp_path / "original.ply"
    save_scene(blob_scene(80, seed=5), original)
    app = ring_studio(window, tmp_path, factory=make_small_stylizer)
    try:
        assert app.files.open_path(str(original))
        bridge = app.engine.bridge
        assert bridge.wait_until(lambda s: s.done or s.error, 120) and bridge.state.error is None
        app.execute(Command("refine"))
        assert bridge.wait_until(lambda s: s.done and s.plans.get("levels") == [32, 64] or s.error, 120)
        out = tmp_path / "saved" / "kept.ply"
        out.parent.mkdir()
        app.outputs.save_as(out)
        assert bridge.wait_until(lambda s: s.exported or s.error, 60) and bridge.state.error is None
        assert bridge.wait_until(lambda s: find_result_state(out) is not None, 30), "the run was not kept"
        assert app.files.open_path(str(out)) and app.engine.bridge is None
        app.execute(Command("continue_result"))
        bridge = app.engine.bridge
        assert bridge.wait_until(lambda s: s.resumed and s.plans.get("levels") == [32, 64] or s.error, 120), \
            (bridge.state.error, bridge.state.plans.get("levels"))
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        p = app.panel
        assert p.width == 64 and p.levels == [32, 64] and p.next_width and p.next_width > 64, (p.width, p.next_width)
        assert "Width: 64 px (levels 32 px -> 64 px)" in driver.recorder.texts
        target = p.next_width
        assert bridge.wait_until(lambda s: s.summary is not None or s.error, 60)  # the last news of the run loaded:
        driver.frame()  # the panel as it stays (under load the summary came between finding the button and the click)
        assert [c.name for c in driver.click(f"Refine -> {target} px")] == ["refine"]
        assert bridge.wait_until(lambda s: s.plans.get("levels") == [32, 64, target] or s.error, 60), \
            bridge.state.refine_note
        driver.frame()
        assert p.width == target and p.next_width != target  # the level under way, and the one after it
    finally:
        app.close(timeout=60)


def test_a_quality_chosen_during_a_run_says_it_applies_at_restart_and_any_restart_runs_it(window, monkeypatch,
                                                                                          tmp_path):
    """Issue #65 item 2: the radio marks the tier the run is at ([now]); another chosen says "applies at Restart"
    beside the restart at it, and the plain Restart runs the chosen tier too."""
    from fakes import ring_studio
    from imgui_driver import PanelDriver, install

    from app.panels import Command, PanelState, draw_panel

    state = PanelState(preset="preview", quality="final", device="cpu", width=256, levels=[256], next_width=512)
    driver = PanelDriver(window, install(monkeypatch), lambda: draw_panel(state))
    driver.frame()
    assert "final: applies at Restart (the run is at preview)" in driver.recorder.texts
    assert [w.path for w in driver.recorder.widgets if "[now]" in w.path][0].endswith("###q_preview")
    assert [c.args for c in driver.click("Restart at final") if c.name == "restart_quality"] == [{"preset": "final"}]
    app = ring_studio(window, tmp_path)
    try:
        app.execute(Command("set_quality", {"preset": "balanced"}))
        assert app.engine.bridge.config.get("preset") != "balanced"  # nothing changes until a start
        app.execute(Command("restart"))
        assert app.engine.bridge.config["preset"] == "balanced" == app.panel.quality
    finally:
        app.close(timeout=30)
