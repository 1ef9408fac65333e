"""Issue #65 item 3: a slider shows the artist's value while the engine's echo lags (dragged, undone), a Shift drag
is ten times finer, Ctrl+click types a value, and the view shows an artist's change at once."""

import pytest

from app.artist_params import ArtistParams
from app.panels.widgets import fine_value


def test_the_artists_value_wins_until_the_worker_has_taken_it():
    a = ArtistParams()
    a.sending(["style_scale"])  # 1: 200 -> 300
    a.sending(["style_scale"])  # 2: 300 -> 400
    echo = {"style_scale": 300.0, "lr": 0.1}
    a.took(1, snapshots_received=5)  # the worker echoes the first only
    assert a.engine_values(echo) == {"lr": 0.1}  # the panel keeps 400
    a.took(2, snapshots_received=6)
    assert a.engine_values({"style_scale": 400.0}) == {"style_scale": 400.0}
    assert not a.view_owed(6) and a.view_owed(7)  # a snapshot after the change is owed to the view
    a.view_shown()
    assert not a.view_owed(8)


def test_a_fine_drag_moves_a_tenth_as_far_on_the_sliders_scale():
    assert fine_value(0.5, 0.1, 0.0, 1.0, log=False) == pytest.approx(0.51)
    assert fine_value(1.0, 0.5, 0.25, 4.0, log=True) == pytest.approx(1.0 * 16 ** 0.05)  # a tenth of half the range
    assert fine_value(4.0, 1.0, 0.25, 4.0, log=True) == 4.0 and fine_value(0.0, -1.0, 0.0, 1.0, log=False) == 0.0


pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from imgui_bundle import imgui  # noqa: E402
from imgui_driver import panel_alone  # noqa: E402

from app.panels import PanelState  # noqa: E402
from gstyle_core.engine.settings import resolve_settings, ui_params  # noqa: E402

W, H = 700, 1300


@pytest.fixture
def panel(window, monkeypatch):
    params = ui_params(resolve_settings("preview", "360", 4, clip_available=False))
    state = PanelState(params=dict(params), defaults=dict(params))
    return panel_alone(window, monkeypatch, state), state


def drag(driver, path: str, fx0: float, fx1: float, shift: bool) -> list:
    """Press at ``fx0`` of the slider, move to ``fx1`` (Shift held if ``shift``), release."""
    w = driver.recorder.find(path)
    (x0, y), (x1, _) = w.point(fx0), w.point(fx1)
    out = driver.frame(lambda io: io.add_mouse_pos_event(x0, y))
    out += driver.frame(lambda io: io.add_mouse_button_event(0, True))
    if shift:
        out += driver.frame(lambda io: io.add_key_event(imgui.Key.mod_shift, True))
    for i in range(1, 5):
        out += driver.frame(lambda io, i=i: io.add_mouse_pos_event(x0 + (x1 - x0) * i / 4, y))
    out += driver.frame(lambda io: io.add_mouse_button_event(0, False))
    out += driver.frame(lambda io: io.add_key_event(imgui.Key.mod_shift, False))
    return out


def test_a_shift_drag_is_ten_times_finer_than_a_plain_one(panel):
    driver, state = panel
    driver.frame()
    moved = {}
    for shift in (False, True):
        state.params["palette_match"] = 0.5
        drag(driver, "palette_match/palette match", 0.5, 0.9, shift)
        moved[shift] = state.params["palette_match"] - 0.5
    assert moved[False] > 0.3
    assert 0.0 < moved[True] < moved[False] / 5


def test_ctrl_click_types_a_value(panel):
    driver, state = panel
    driver.frame()
    x, y = driver.recorder.find("palette_match/palette match").point(0.5)
    driver.frame(lambda io: io.add_mouse_pos_event(x, y))
    driver.frame(lambda io: io.add_key_event(imgui.Key.mod_ctrl, True))
    driver.frame(lambda io: io.add_mouse_button_event(0, True))
    driver.frame(lambda io: io.add_mouse_button_event(0, False))
    driver.frame(lambda io: io.add_key_event(imgui.Key.mod_ctrl, False))
    driver.frame(lambda io: (io.add_key_event(imgui.Key.a, True), io.add_key_event(imgui.Key.a, False)))
    driver.frame(lambda io: io.add_input_characters_utf8("0.25"))
    out = driver.frame(lambda io: (io.add_key_event(imgui.Key.enter, True), io.add_key_event(imgui.Key.enter, False)))
    out += driver.frame()
    assert state.params["palette_match"] == pytest.approx(0.25)
    assert [c.args for c in out if c.name == "set_params"][-1] == {"palette_match": pytest.approx(0.25)}


def test_a_stale_echo_does_not_move_the_slider_back_and_undo_shows_at_once(studio, window):
    from app.panels import Command

    def frame():
        window.begin_frame()
        studio.frame(window.ctx.screen)
        window.end_frame(swap=False)

    bridge = studio.engine.bridge
    assert bridge.wait_until(lambda s: s.ready, 30)
    start = studio.panel.params["lambda_nnfm"]
    studio.execute(Command("set_params", {"lambda_nnfm": start * 3}))
    bridge.state.params["lambda_nnfm"] = start  # the worker's echo of an older value, as it lags on a big scene
    frame()
    assert studio.panel.params["lambda_nnfm"] == start * 3  # the artist's value, not the echo
    studio.keys.press("z", ctrl=True)
    frame()
    assert studio.panel.params["lambda_nnfm"] == start  # at once after undo
    assert bridge.wait_until(lambda s: not s.artist.waiting, 30)  # the worker took both
    frame()
    assert studio.panel.params["lambda_nnfm"] == start and bridge.state.params["lambda_nnfm"] == start
    assert bridge.state.artist.taken == 2


def test_a_change_that_alters_colours_reaches_the_view_with_its_geometry_at_once():
    import queue
    import threading

    from app.engine_host import EngineHost

    class Engine:
        colour_version, geometry_version = 0, 0

        def set_params(self, **kw):
            self.colour_version += 1
            self.geometry_version += 1

        def snapshot(self):
            return {"colors": [[0.0, 0.0, 0.0]] * 3, "means": [[0.0, 0.0, 0.0]] * 3, "colour_version":
                    self.colour_version, "geometry_version": self.geometry_version}

    events = queue.Queue()
    host = EngineHost(lambda: None, {}, events, threading.Semaphore(0), None)  # no credit free: sent anyway
    host.engine = Engine()
    host.geometry_sends.shape(host.engine.snapshot(), True)  # geometry just sent: a stepping run would hold it
    host.set_params({"keep_colours": 0.0})
    kinds = [(k, p) for k, p in list(events.queue)]
    assert [k for k, _ in kinds] == ["params", "params_taken", "snapshot"]
    assert kinds[1][1] == 1 and "means" in kinds[2][1][1]  # the geometry goes with the colours
