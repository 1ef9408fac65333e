"""A saved result keeps its run (issue #35 item 3, ``gstyle_core/engine/kept_runs.py``): the studio's worker and
``gstyle stylize`` keep the engine's state with every result they write, a reopened result whose file is unchanged
finds it, and the engine rebuilt on the original from the inputs kept with it loads that run where it ended (however
the sliders stood when it was built)."""

import json

import numpy as np
from fakes import make_small_stylizer

from app.worker import WorkerBridge
from gstyle_core.engine.kept_runs import (
    file_digest,
    find_result_state,
    note_path,
    prune,
    result_state_path,
    save_result_state,
)


def test_a_kept_run_is_found_for_its_file_and_lost_when_the_file_changes(tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    result = tmp_path / "out" / "stylized.ply"
    result.parent.mkdir()
    result.write_bytes(b"ply\n" + bytes(range(200)))
    config = {"scene": "/scenes/a.ply", "style": ["x.jpg", "y.jpg"], "style_weights": (0.25, 0.75),
              "selection": np.ones(5, bool), "preset": "balanced"}
    path = save_result_state(result, {"global_step": 7}, {"config": config, "fingerprint": {}})
    assert path.parent == tmp_path / "cache" / "results"
    found, note = find_result_state(result)
    assert found == path and note["digest"] == file_digest(result)
    assert note["config"] == {"scene": "/scenes/a.ply", "style": ["x.jpg", "y.jpg"], "style_weights": [0.25, 0.75],
                              "preset": "balanced"} and note["selection"]  # the mask stays in the state's meta
    result.write_bytes(b"ply\n" + bytes(range(201)))  # written over by another tool: its run no longer fits
    assert find_result_state(result) is None
    note_path(path).write_text("{broken")
    assert find_result_state(result) is None
    # undo's results keep their runs beside them, in the session's history folder (removed with it)
    history = tmp_path / "cache" / "history" / "session_1" / "result_1.ply"
    history.parent.mkdir(parents=True)
    history.write_bytes(b"ply\n")
    assert result_state_path(history) == history.parent / "result_1.ply.state.ckpt"


def test_only_the_newest_kept_runs_stay(tmp_path):
    import os

    for i in range(5):
        state = tmp_path / f"r{i}.ckpt"
        state.write_bytes(b"x")
        note_path(state).write_text("{}")
        os.utime(state, (1000 + i, 1000 + i))
    prune(tmp_path, keep=4)
    assert sorted(p.name for p in tmp_path.glob("*.ckpt")) == ["r1.ckpt", "r2.ckpt", "r3.ckpt", "r4.ckpt"]
    prune(tmp_path, keep=4, budget=2)  # one byte each: the two newest fit the budget
    assert sorted(p.name for p in tmp_path.glob("*.ckpt")) == ["r3.ckpt", "r4.ckpt"]
    assert sorted(p.name for p in tmp_path.glob("*.json")) == ["r3.ckpt.json", "r4.ckpt.json"]
    prune(tmp_path, keep=4, budget=0)  # the newest stays whatever its size
    assert [p.name for p in tmp_path.glob("*.ckpt")] == ["r4.ckpt"]


def test_a_result_reopened_continues_its_run_where_it_ended(tmp_path, monkeypatch):
    """The run is built with a slider moved (its settings differ from the config's defaults) and saved as a result;
    a new worker given another config rebuilds it from the inputs kept with the result and resumes at its step."""
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    b = WorkerBridge(make_small_stylizer, {"n": 80})
    b.start()
    try:
        b.set_params(lambda_content=0.2)
        b.restart()  # built again with the slider where it is: the engine's fingerprint has λ_content 0.2
        assert b.wait_until(lambda s: (s.last_report or {}).get("step", 0) >= 6 or s.error, 120), "no progress"
        b.pause()
        result = tmp_path / "out" / "kept.ply"
        result.parent.mkdir()
        b.export(result)
        assert b.wait_until(lambda s: s.exported or s.export_failures or s.error, 60), "no export"
        assert b.state.error is None and not b.state.export_failures, (b.state.error, b.state.export_failures)
    finally:
        b.quit()
    kept = find_result_state(result)
    assert kept is not None, "the run was not kept with the result"
    state_path, note = kept
    assert note["config"]["n"] == 80
    from gstyle_core.engine.checkpoint import read_checkpoint

    state, meta = read_checkpoint(state_path)
    assert meta["build_params"]["lambda_content"] == 0.2 and meta["kind"] == "result"

    again = WorkerBridge(make_small_stylizer, {"n": 12}, resume_from=state_path, start_paused=True)
    again.start()
    try:
        assert again.wait_until(lambda s: s.resumed or s.error, 120), "did not resume"
        assert again.state.error is None, again.state.error
        assert again.state.resumed["step"] == state["global_step"]
        assert again.wait_until(lambda s: len((s.snapshot or {}).get("means", ())) > 0, 30)
        assert len(again.state.snapshot["means"]) == state["run"]["params"]["means"].shape[0]  # its geometry
    finally:
        again.quit()
    assert json.loads(note_path(state_path).read_text())["result"] == str(result.resolve())


def test_the_config_kept_for_a_command_line_run_builds_the_same_engine(tmp_path, monkeypatch):
    """``gstyle stylize``'s request, kept as the studio's engine config (paths made absolute), builds an engine with
    the same fingerprint from another folder: the kept run loads into it."""
    from PIL import Image
    from synthetic import blob_scene

    from app.engine_factory import make_stylizer
    from gstyle_core.engine.build import BuildRequest, build_stylizer, request_config
    from gstyle_core.engine.checkpoint import engine_fingerprint
    from gstyle_core.io import save_scene

    (tmp_path / "work").mkdir()
    save_scene(blob_scene(50, seed=3), tmp_path / "work" / "scene.ply")
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(
        tmp_path / "work" / "art.png")
    monkeypatch.chdir(tmp_path / "work")
    request = BuildRequest(scene="scene.ply", style=["art.png"], preset="balanced",
                           overrides={"lambda_content": 0.2, "working_width": 64, "region": None})
    built = build_stylizer(request)
    config = request_config(request)
    assert config["scene"] == str(tmp_path / "work" / "scene.ply") and "region" not in config
    monkeypatch.chdir(tmp_path)
    again = make_stylizer(**config)
    assert engine_fingerprint(again) == engine_fingerprint(built.engine)
    again.load_state_dict(built.engine.state_dict())
