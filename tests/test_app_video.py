"""The studio's turntable video (a background job with a progress bar and Cancel) and its web-format exports."""

from __future__ import annotations

import time

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import make_fake_engine  # noqa: E402
from imgui_driver import studio_driver  # noqa: E402
from synthetic import blob_scene, ring_cameras  # noqa: E402

from app.panels import Command  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from app.video_job import VideoJob  # noqa: E402
from gstyle_core.io import load_scene  # noqa: E402
from gstyle_core.render_video import turntable_cameras  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


def wait_job(job: VideoJob, timeout: float = 300.0):
    deadline = time.monotonic() + timeout
    while job.poll().state == "running" and time.monotonic() < deadline:
        time.sleep(0.02)
    return job.progress


def test_video_job_in_a_thread_writes_and_reports_progress(tmp_path):
    scene = blob_scene(100)
    cams = turntable_cameras(scene, 3, 32, 24)
    job = VideoJob(scene, cams, tmp_path / "t.gif", fps=10, in_thread=True)
    progress = wait_job(job)
    assert (progress.state, progress.done, progress.total) == ("done", 3, 3), progress.message
    assert Image.open(tmp_path / "t.gif").n_frames == 3


def test_cancelled_job_writes_nothing(tmp_path):
    scene = blob_scene(100)
    job = VideoJob(scene, turntable_cameras(scene, 400, 32, 24), tmp_path / "t.gif", in_thread=True)
    job.cancel()
    progress = wait_job(job)
    assert progress.state == "cancelled" and list(tmp_path.iterdir()) == []


def test_turntable_button_renders_in_the_background_while_the_ui_keeps_drawing(window, monkeypatch, tmp_path):
    app = StudioApp(window.ctx, loaded=LoadedScene("ring", blob_scene(150), ring_cameras(4, width=64, height=48)),
                    output_dir=tmp_path)  # the default: the video renders in a spawned process
    try:
        driver = studio_driver(window, monkeypatch, app)
        driver.click("##turntable_format")  # opens the format list
        commands = driver.click("gif")
        assert [(c.name, c.args) for c in commands] == [("turntable_settings", {"format": "gif"})]
        app.execute(Command("turntable_settings", {"frames": 6}))  # the frame count's input field does the same
        commands = driver.click("Turntable video...")
        assert [(c.name, c.args) for c in commands] == [("turntable", {"frames": 6, "format": "gif"})]
        assert app.outputs.video_job is not None and app.panel.video_running
        frames_while_rendering = 0
        deadline = time.monotonic() + 600  # seconds here, minutes on a loaded machine (spawn, torch import)
        while app.outputs.video_job is not None and time.monotonic() < deadline:
            driver.frame()
            frames_while_rendering += 1
            time.sleep(0.02)  # paced like a vsync'd UI (a busy loop would starve the niced renderer)
        assert app.outputs.video_job is None and app.panel.status.startswith("wrote "), app.panel.status
        assert frames_while_rendering >= 5  # the studio kept drawing (and showing progress) meanwhile
        written = list(tmp_path.glob("turntable_*.gif"))
        assert len(written) == 1 and Image.open(written[0]).n_frames == 6
        assert Image.open(written[0]).size == (640, 480)  # the scene cameras' aspect at 640 wide
    finally:
        app.close()


def test_cancel_button_stops_the_video(window, monkeypatch, tmp_path):
    app = StudioApp(window.ctx, loaded=LoadedScene("ring", blob_scene(150), ring_cameras(4)), output_dir=tmp_path,
                    worker_mode="thread")
    try:
        driver = studio_driver(window, monkeypatch, app)
        assert app.outputs.start_turntable(3000, "png frames") is not None
        driver.frame()
        assert driver.recorder.find("Cancel###video").tooltip
        driver.click("Cancel###video")
        deadline = time.monotonic() + 300
        while app.outputs.video_job is not None and time.monotonic() < deadline:
            driver.frame()
        assert app.panel.status == "video cancelled; nothing written" and list(tmp_path.iterdir()) == []
    finally:
        app.close()


def test_turntable_of_the_stylized_scene_and_web_exports(window, monkeypatch, tmp_path):
    app = StudioApp(window.ctx, loaded=LoadedScene("ring", blob_scene(150), ring_cameras(4)), output_dir=tmp_path,
                    engine_factory=make_fake_engine, engine_config={"n": 150}, worker_mode="thread")
    try:
        app.engine.start()
        assert app.engine.bridge.wait_until(lambda s: s.snapshots_received >= 2 or s.error, 60), \
            app.engine.bridge.state.error
        app.engine.bridge.pause()
        assert app.engine.bridge.wait_until(lambda s: s.paused, 30)
        app.engine.bridge.poll()
        snap = app.engine.bridge.state.snapshot
        scene = app.outputs.current_scene()
        assert np.allclose(scene.rgb, snap["colors"], atol=1e-6) and np.allclose(scene.means, snap["means"])
        driver = studio_driver(window, monkeypatch, app)
        for label, fmt in (("Export .spz", "spz-v3"), ("Export .compressed.ply", "ply-playcanvas-compressed"),
                           ("Export .sog", "sog-v2 (bundle)")):
            driver.frame()  # shows the last export's status line, which is then cleared: the panel keeps its first
            app.panel.status = ""  # height, and a long status line would push these buttons below its bottom
            commands = driver.click(label)
            assert [c.name for c in commands] == ["export"]
            assert app.engine.bridge.wait_until(lambda s, fmt=fmt: s.exported and fmt[:3] in s.exported[-1], 30)
            loaded, report = load_scene(app.engine.bridge.state.exported[-1])
            assert report.format == fmt and loaded.count == 150
    finally:
        app.close()
