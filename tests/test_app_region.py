"""The studio's selection tool (issue #15 item 4): the panel turns it on, the box is placed with its numbers, a
Shift + drag rectangle in the view selects the Gaussians whose centres fall in it, the selection is outlined in
the view (no tint on the splats), and the engine starts with it (headless GL window, real small engine in a worker
thread)."""

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import MeanColourPull  # noqa: E402
from imgui_bundle import imgui  # noqa: E402
from imgui_driver import studio_driver  # noqa: E402
from PIL import Image  # noqa: E402
from synthetic import blob_scene, ring_cameras  # noqa: E402

from app.gl_io import read_rgb  # noqa: E402
from app.panels import PANEL_WIDTH, Command  # noqa: E402
from app.studio import LoadedScene, StudioApp  # noqa: E402
from gstyle_core.engine.region import box_mask, rect_mask  # noqa: E402

W, H = 700, 1300
BUILT: list = []
HALF = (-10.0, -10.0, -10.0, 0.0, 10.0, 10.0)


def region_stylizer(region=None, selection=None, **_ignored):
    """The real ``Stylizer`` on the test's scene with the studio's region/selection (kept for the test to inspect)."""
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    style = np.zeros((8, 8, 3), np.float32)
    style[..., 0] = 1.0
    settings = resolve_settings("preview", "forward", 3, max_views=3, epochs=3, min_steps=0, refit_iterations=2,
                                working_width=32, preprocess_rounds=0, split_rate=0.0, region=region)
    BUILT.append(Stylizer(blob_scene(150, seed=5), ring_cameras(3), style, settings,
                          objective_factory=MeanColourPull, selection=selection))
    return BUILT[-1]


def orange_share(rgb: np.ndarray) -> float:
    """How orange the lit pixels of the view right of the panel are (the highlight's tint): mean of R - B over
    pixels that are not background."""
    rgb = rgb[:, int(PANEL_WIDTH) + 20:]
    lit = rgb.astype(np.float32).sum(-1) > 30
    return float((rgb[..., 0].astype(np.float32) - rgb[..., 2])[lit].mean()) if lit.any() else 0.0


def test_region_tool_box_rectangle_highlight_and_engine(window, monkeypatch, tmp_path):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    style = tmp_path / "style.png"
    Image.fromarray(np.full((16, 16, 3), 128, np.uint8)).save(style)
    scene = blob_scene(150, seed=5)
    loaded = LoadedScene(str(tmp_path / "blob.ply"), scene, ring_cameras(3))
    BUILT.clear()
    app = StudioApp(window.ctx, loaded=loaded, style_path=str(style), engine_factory=region_stylizer,
                    output_dir=tmp_path / "out", worker_mode="thread")
    app.progressive = False
    try:
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        plain = read_rgb(window.ctx.screen)
        assert not app.views.stylized.highlight and app.region.mask() is None
        driver.click("Selected region")  # open the section
        commands = driver.click("select a region")
        assert [c.args for c in commands if c.name == "region_enable"] == [{"on": True}]
        assert driver.recorder.find("select a region").tooltip  # the control explains itself
        driver.frame()
        # on: the box starts as the scene's bounds, every Gaussian selected (none dimmed), outlined with its box
        assert app.region.mask().all() and app.views.stylized.highlight and app.views.original.highlight
        assert app.panel.selection_outline
        assert any("150 of 150 Gaussians selected by the box" in t for t in driver.recorder.texts)
        assert len(app.panel.region_outline) == 12
        assert orange_share(read_rgb(window.ctx.screen)) > orange_share(plain) + 10
        read_rgb_sum_all_selected = read_rgb(window.ctx.screen)[:, int(PANEL_WIDTH) + 20:].astype(np.float32).sum()
        # the box's numbers (the panel's drag fields send this command) place and resize it
        app.execute(Command("region_box", {"box": HALF}))
        driver.frame()
        inside = box_mask(scene.means, HALF)
        assert np.array_equal(app.region.mask(), inside) and 20 < inside.sum() < 130
        lit = read_rgb(window.ctx.screen)[:, int(PANEL_WIDTH) + 20:].astype(np.float32).sum()
        assert lit < 0.9 * read_rgb_sum_all_selected  # the Gaussians outside the box are dimmed
        assert any(f"{int(inside.sum())} of 150 Gaussians" in t for t in driver.recorder.texts)
        # Alt + drag moves the box in the view (its centre follows the mouse), Alt + wheel resizes it
        def centre_pixel():
            box = np.asarray(app.region.box)
            cam = app.control.camera(*app.framing.view_size)
            p = np.asarray(cam.world_to_cam)[:3, :3] @ ((box[:3] + box[3:]) / 2) + np.asarray(cam.world_to_cam)[:3, 3]
            return np.array([cam.fx * p[0] / p[2] + cam.cx, cam.fy * p[1] / p[2] + cam.cy])

        before, extent = centre_pixel(), np.subtract(HALF[3:], HALF[:3])
        x0 = PANEL_WIDTH + 80.0
        driver.frame(lambda io: io.add_mouse_pos_event(x0, 500))
        driver.frame(lambda io: io.add_key_event(imgui.Key.mod_alt, True))
        driver.frame(lambda io: io.add_mouse_button_event(0, True))
        driver.frame(lambda io: io.add_mouse_pos_event(x0 + 40, 500))
        driver.frame(lambda io: io.add_mouse_button_event(0, False))
        assert np.allclose(centre_pixel() - before, (40, 0), atol=0.5)
        driver.frame(lambda io: io.add_mouse_wheel_event(0, 1))
        driver.frame(lambda io: io.add_key_event(imgui.Key.mod_alt, False))
        box = np.asarray(app.region.box)
        assert np.allclose(box[3:] - box[:3], 1.1 * extent) and np.allclose(centre_pixel() - before, (40, 0), atol=0.5)
        app.execute(Command("region_box", {"box": HALF}))
        # Shift + drag a rectangle over the right part of the view (clear of the panel)
        rect = (PANEL_WIDTH + 40.0, 200.0, 690.0, 900.0)
        driver.frame(lambda io: io.add_key_event(imgui.Key.mod_shift, True),
                     lambda io: io.add_mouse_pos_event(rect[0], rect[1]))
        driver.frame(lambda io: io.add_mouse_button_event(0, True))
        driver.frame(lambda io: io.add_mouse_pos_event(rect[2], rect[3]))
        assert app.panel.region_drag is not None  # the rectangle is drawn while dragging
        driver.frame(lambda io: io.add_mouse_button_event(0, False))
        driver.frame(lambda io: io.add_key_event(imgui.Key.mod_shift, False))
        left = app.panel.view_rect[0]  # the view starts right of the docked panel
        expected = rect_mask(scene.means, app.control.camera(*app.framing.view_size),
                             (rect[0] - left, rect[1], rect[2] - left, rect[3]))
        assert 0 < expected.sum() < 150
        assert np.array_equal(app.region.mask(), expected) and app.panel.region_mode == "rectangle"
        # the engine starts with the selection; its snapshot's selection keeps the highlight after the start
        app.engine.start()
        assert app.engine.bridge.wait_until(lambda s: s.ready or s.error, 60) and app.engine.bridge.state.error is None
        engine = BUILT[-1]
        assert np.array_equal(engine.input_selection, expected)
        assert "selected and stylized" in engine.decisions["region"]
        driver.frame()
        assert any("running with a rectangle selection" in t for t in driver.recorder.texts)
        # the box again, then B turns the tool off: no highlight, and a restart runs on the whole scene
        app.execute(Command("region_box", {"box": HALF}))
        app.execute(Command("restart"))
        assert app.engine.bridge.wait_until(lambda s: s.ready or s.error, 60)
        assert app.engine.bridge.wait_until(lambda s: len(BUILT) >= 2, 30)
        assert BUILT[-1].settings.region == HALF and np.array_equal(BUILT[-1].input_selection, inside)
        app.keys.press("b")  # as the window's key callback queues it (app/keys.py)
        driver.frame()
        driver.frame()  # the key is read as the panel is drawn, after the scene: the next frame draws undimmed
        assert not app.region.enabled and not app.views.stylized.highlight
    finally:
        assert app.close(timeout=60)


def test_the_feather_slider_goes_to_the_engine_with_the_box(window, monkeypatch, tmp_path):
    """The region section's feather (box mode) is handed to the engine with the box when the run (re)starts, and the
    panel says the engine runs with it; a rectangle selection has no feather."""
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = StudioApp(window.ctx, loaded=LoadedScene("blob", blob_scene(150, seed=5), ring_cameras(3)),
                    output_dir=tmp_path)
    try:
        app.execute(Command("region_box", {"box": HALF}))
        app.execute(Command("region_feather", {"value": 0.25}))
        app.engine.take_region()
        assert app.engine.config["region"] == HALF and app.engine.config["region_feather"] == 0.25
        assert "feathered over 0.25" in app.region.engine_region
        app.region.select_rectangle((0, 0, 200, 200), 400, 300)
        app.engine.take_region()
        assert "region_feather" not in app.engine.config and "selection" in app.engine.config
    finally:
        app.close(timeout=30)
