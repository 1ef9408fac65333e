"""A result opens as a result (issue #35 item 3): a scene the project wrote is recognised by the summary beside it,
opens with its settings and no engine started, and offers the way back to its original; a foreign scene opens as
before."""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from synthetic import blob_scene

from app.export import export_engine
from app.result_files import read_result
from gstyle_core.engine.settings import StylizeSettings, resolve_settings, ui_params
from gstyle_core.io import save_scene


class _Finished:
    """What export_engine reads of an engine: the stylized scene and its settings."""

    def __init__(self, settings: StylizeSettings) -> None:
        self.settings, self.decisions = settings, {}

    def stylized_scene(self):
        return blob_scene(60, seed=4)


def _result(tmp_path: Path, **overrides) -> tuple[Path, Path, Path, StylizeSettings]:
    original, painting = tmp_path / "scenes" / "original.ply", tmp_path / "art" / "painting.png"
    original.parent.mkdir()
    painting.parent.mkdir()
    save_scene(blob_scene(60, seed=4), original)
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(painting)
    settings = resolve_settings("balanced", "360", 8, **overrides)
    out = tmp_path / "out" / "stylized.ply"
    out.parent.mkdir()
    export_engine(_Finished(settings), out, None, ui_params(settings), str(painting), str(original))
    return out, original, painting, settings


def test_settings_come_back_from_their_summary_dict():
    settings = resolve_settings("final", "360", 8, keep_colours=True, style_scale=2.0)
    again = StylizeSettings.from_dict(json.loads(json.dumps(settings.to_dict())))
    assert again == settings
    assert StylizeSettings.from_dict({"preset": "balanced", "a_key_of_a_later_version": 1}).preset == "balanced"
    with pytest.raises(ValueError, match="do not fit"):
        StylizeSettings.from_dict({"weights": {"no_such_term": 1.0}})


def test_a_studio_export_and_a_cli_summary_are_results_and_a_foreign_scene_is_not(tmp_path, monkeypatch):
    out, original, painting, settings = _result(tmp_path, lambda_nnfm=321.0)
    info = read_result(out)
    assert info is not None and info.source == original.resolve() and info.styles == [painting.resolve()]
    assert info.params["lambda_nnfm"] == 321.0 and info.preset == "balanced"
    assert info.line.startswith("stylized.ply: a stylized result (preset balanced, 256 -> 512 px, after painting.png")
    # gstyle stylize's OUT.json names the input as given on its command line (relative to where it ran)
    cli = tmp_path / "out" / "cli.ply"
    save_scene(blob_scene(30), cli)
    (tmp_path / "out" / "cli.json").write_text(json.dumps({"scene": "../scenes/original.ply",
                                                           "settings": settings.to_dict(), "gaussians_after": 30}))
    cli_info = read_result(cli)
    assert cli_info.source == original.resolve() and cli_info.params == ui_params(settings)  # beside the summary
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out" / "cli.json").write_text(json.dumps({"scene": "gone.ply", "settings": {}}))
    gone = read_result(cli)
    assert gone.source is None and gone.source_named == "gone.ply"
    (tmp_path / "out" / "cli.json").write_text(json.dumps({"scene": "bundled demo", "source_scene": str(original),
                                                           "settings": {}}))
    assert read_result(cli).source == original.resolve()  # the absolute source wins over the name as given
    assert read_result(original) is None  # no summary beside it: a foreign scene
    (tmp_path / "scenes" / "original.json").write_text("{broken")
    assert read_result(original) is None


W, H = 160, 120


def test_opening_a_result_starts_nothing_and_restart_from_the_original_does(window, tmp_path, monkeypatch):
    from fakes import ring_studio

    from app.panels import Command

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    out, original, painting, _ = _result(tmp_path, lambda_nnfm=321.0)
    app = ring_studio(window, tmp_path)
    try:
        app.region.enabled = True
        assert app.files.open_path(str(out))
        assert app.engine.bridge is None and app.session.result is not None  # the running engine stopped; none started
        assert not app.region.enabled  # the region tool does not stay on from the scene before
        assert app.panel.result_line.startswith("stylized.ply: a stylized result")
        assert app.panel.params["lambda_nnfm"] == 321.0 and app.panel.result_source_found
        assert "nothing started" in app.panel.status and app.panel.style_path == str(painting.resolve())
        app.execute(Command("restart_from_original"))
        assert app.engine.bridge is not None and app.session.result is None
        assert app.session.loaded.path == str(original.resolve())
        assert app.engine.bridge.wait_until(lambda s: (s.snapshot or {}).get("params", {}).get("lambda_nnfm") == 321.0
                                     or s.error, 30), app.engine.bridge.state.error
    finally:
        app.close(timeout=30)


def test_a_painting_and_a_slider_chosen_on_a_result_are_what_restart_from_the_original_uses(window, tmp_path,
                                                                                             monkeypatch):
    """A result on show (no engine): another painting opened and a slider moved change what *Restart from the
    original* stylizes with, not only the thumbnail; *Stylize it again* uses them too."""
    from fakes import ring_studio

    from app.panels import Command

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    out, original, painting, _ = _result(tmp_path, lambda_nnfm=321.0)
    other = tmp_path / "art" / "other.png"
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (12, 12, 3), dtype=np.uint8)).save(other)
    app = ring_studio(window, tmp_path)
    try:
        assert app.files.open_path(str(out)) and app.panel.style_path == str(painting.resolve())
        assert app.files.open_path(str(other)) and app.engine.bridge is None
        assert app.session.result is not None  # still the result
        app.execute(Command("set_params", {"lambda_nnfm": 123.0}))
        app.execute(Command("restart_from_original"))
        assert app.session.loaded.path == str(original.resolve()) and app.panel.style_path == str(other)
        assert app.engine.bridge.config["style"] == str(other)  # the engine stylizes with the painting opened on it
        assert app.engine.bridge.wait_until(lambda s: (s.snapshot or {}).get("params", {}).get("lambda_nnfm") == 123.0
                                     or s.error, 30), app.engine.bridge.state.error
        app.engine.stop()
        assert app.files.open_path(str(out)) and app.panel.style_path == str(painting.resolve())
        assert app.files.open_path(str(other))
        app.execute(Command("restart"))  # Stylize it again
        assert app.engine.bridge.config["style"] == str(other) and app.engine.bridge.config["scene"] == str(out)
    finally:
        app.close(timeout=30)


def test_the_command_line_opens_a_result_without_starting_an_engine(tmp_path, monkeypatch, capsys):
    from app.main import main

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    out, _, _, _ = _result(tmp_path)
    assert main([str(out), "--headless", "--engine", "--frames", "2", "--size", "160x120", "--output-dir",
                 str(tmp_path / "o")]) == 0
    assert "a stylized result (preset balanced" in capsys.readouterr().out
    assert not (tmp_path / "cache" / "checkpoints").exists()  # no engine ran, so none saved a session


def test_a_result_on_show_without_an_engine_saves_as_it_is(window, tmp_path, monkeypatch):
    """Save As (and Ctrl+S) of a reopened result: no engine runs, the scene as opened and its summary are written in
    the format the name asks for, and it becomes a take."""
    from fakes import ring_studio

    from gstyle_core.io import load_scene

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    out, original, _, settings = _result(tmp_path, lambda_nnfm=321.0)
    app = ring_studio(window, tmp_path)
    try:
        assert app.files.open_path(str(out)) and app.engine.bridge is None
        target = tmp_path / "saved" / "again.spz"
        target.parent.mkdir()
        app.outputs.save_as(target)
        assert target.is_file() and "saved" in app.panel.status and app.takes.shelf.takes[0].path == str(target)
        summary = json.loads(target.with_suffix(".json").read_text())
        assert summary["scene"] == str(target) and summary["settings"]["weights"]["nnfm"] == 321.0
        assert summary["source_scene"] == str(original.resolve()) and summary["gaussians"] == 60
        again, _ = load_scene(target)
        assert again.count == 60 and np.allclose(again.means, app.session.loaded.scene.means, atol=1e-2)
        app.outputs.export(fmt="ply")  # Ctrl+S: into the folder saved to last
        assert len(list(target.parent.glob("stylized_*.ply"))) == 1
    finally:
        app.close(timeout=30)


def test_a_saved_result_reopens_and_continues_its_run_on_its_original(window, tmp_path, monkeypatch):
    """Save As from a running engine keeps its run with the file; reopened, the result offers Continue, which opens
    the original and starts the engine from that run (no pre-processing again: it resumes at the step it was at);
    Save As of the reopened result carries the run to the copy."""
    from fakes import make_small_stylizer, ring_studio

    from app.panels import Command
    from gstyle_core.engine.kept_runs import find_result_state

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    original = tmp_path / "original.ply"
    save_scene(blob_scene(80, seed=5), original)
    app = ring_studio(window, tmp_path, factory=make_small_stylizer)
    try:
        assert app.files.open_path(str(original))  # the engine restarts on it
        assert app.engine.bridge.wait_until(lambda s: (s.last_report or {}).get("step", 0) >= 6 or s.error, 120)
        app.engine.bridge.pause()
        out = tmp_path / "saved" / "kept.ply"
        out.parent.mkdir()
        app.outputs.save_as(out)
        assert app.engine.bridge.wait_until(lambda s: s.exported or s.error, 60) \
            and app.engine.bridge.state.error is None
        assert app.engine.bridge.wait_until(lambda s: find_result_state(out) is not None, 30), "the run was not kept"
        step = app.engine.bridge.state.last_report["step"]

        assert app.files.open_path(str(out)) and app.engine.bridge is None
        assert app.panel.result_continuable and app.session.result.state is not None
        app.execute(Command("continue_result"))
        assert app.engine.bridge is not None and app.session.result is None
        assert app.session.loaded.path == str(original.resolve())
        assert app.engine.bridge.wait_until(lambda s: s.resumed or s.error, 120), "did not resume"
        assert app.engine.bridge.state.error is None, app.engine.bridge.state.error
        assert app.engine.bridge.state.resumed["step"] >= step  # where the run was when it was saved

        app.engine.stop()
        assert app.files.open_path(str(out)) and app.session.result.state is not None
        copy = tmp_path / "saved" / "copy.ply"
        app.outputs.save_as(copy)
        assert copy.is_file() and find_result_state(copy) is not None  # the copy can be continued too
    finally:
        app.close(timeout=30)


def test_restart_from_the_original_of_a_refined_preview_goes_back_to_the_presets_weights(window, tmp_path,
                                                                                         monkeypatch):
    """A calibrated 360° preview refined in the studio to 512 px: its level raised brush strokes 200 -> 400 and edges
    kept 0 -> 4000 (``level_weight_changes``). Reopened and restarted from its original at its preset, those go back
    to the preset's; a slider the artist moved on the result keeps the artist's value."""
    from fakes import ring_studio

    from app.panels import Command
    from gstyle_core.engine.settings import level_weight_changes

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    out, original, painting = tmp_path / "out" / "refined.ply", tmp_path / "original.ply", tmp_path / "p.png"
    out.parent.mkdir()
    save_scene(blob_scene(60, seed=4), original)
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(painting)
    settings = resolve_settings("preview", "360", 8, clip_available=False)
    preset = ui_params(settings)
    changes = level_weight_changes(settings)
    settings = resolve_settings("preview", "360", 8, clip_available=False, refine_widths=(512,), **changes)
    export_engine(_Finished(settings), out, None, ui_params(settings), str(painting), str(original))
    info = read_result(out)
    assert info.level_weights["lambda_nnfm"] == (400.0, 200.0) and info.level_weights["lambda_edges"] == (4000.0, 0.0)
    app = ring_studio(window, tmp_path)
    try:
        assert app.files.open_path(str(out)) and app.panel.params["lambda_nnfm"] == 400.0
        app.execute(Command("set_params", {"lambda_edges": 1234.0}))  # the artist's own value
        app.execute(Command("restart_from_original"))
        assert app.panel.params["lambda_nnfm"] == preset["lambda_nnfm"] == 200.0
        assert app.panel.params["lambda_edges"] == 1234.0
    finally:
        app.close(timeout=30)


def test_the_quality_radio_follows_a_result_and_restart_from_the_original_runs_it(window, tmp_path, monkeypatch):
    """Issue #65 item 2: a balanced result opens with the radio on balanced (marked [now]); preview chosen on it says
    when it applies, and Restart from the original runs preview, the tier the radio shows."""
    from fakes import ring_studio
    from imgui_driver import studio_driver

    from app.panels import Command

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    out, original, _, _ = _result(tmp_path)
    app = ring_studio(window, tmp_path)
    try:
        assert app.files.open_path(str(out)) and app.engine.bridge is None
        assert app.panel.quality == app.panel.preset == "balanced"
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        assert [w.path for w in driver.recorder.widgets if "[now]" in w.path] == [
            w.path for w in driver.recorder.widgets if w.path.endswith("###q_balanced")]
        app.execute(Command("set_quality", {"preset": "preview"}))
        driver.frame()
        assert "preview: applies at Restart from the original (this result is balanced)" in driver.recorder.texts
        app.execute(Command("restart_from_original"))
        assert app.session.loaded.path == str(original.resolve())
        assert app.engine.bridge.config["preset"] == "preview" and app.panel.quality == "preview"
    finally:
        app.close(timeout=30)
