"""The rasterizer's one-off setup on CUDA (gsplat's module loaded or built, ``RasterizerSetup``): done once before a
run's first render and outside every step's own time, and said to the studio before a build starts (it takes
minutes on a card's first run) and after it ends. CUDA is not needed: gsplat's side is replaced by doubles that
count their calls; the CUDA run itself is ``tests/test_raster_gsplat.py``'s."""

from __future__ import annotations

import queue
import threading
import time

import pytest
import torch
from fakes import make_small_stylizer

from gstyle_core.raster import gsplat_module
from gstyle_core.raster.gsplat_module import BUILD_NOTE, GsplatUnavailable, RasterizerSetup

BUILD_SECONDS = 1.0


class FakeGsplat:
    """gsplat's module as ``RasterizerSetup`` sees it: kept from before (``kept``) or built by the first
    ``ensure_gsplat`` call (which sleeps ``build_seconds``); counts the calls."""

    def __init__(self, monkeypatch, kept: bool, build_seconds: float = 0.0, fails: bool = False) -> None:
        self.loaded, self.kept, self.build_seconds, self.fails, self.calls = False, kept, build_seconds, fails, 0
        monkeypatch.setattr(gsplat_module, "build_pending", lambda: not (self.loaded or self.kept))
        monkeypatch.setattr(gsplat_module, "ensure_gsplat", self.ensure)

    def ensure(self, log=print) -> object:
        self.calls += 1
        if self.fails:
            raise GsplatUnavailable("gsplat's CUDA build failed: nvcc: not found")
        if not (self.loaded or self.kept):
            time.sleep(self.build_seconds)
        self.loaded = True
        return object()


def test_the_cpu_sets_up_nothing_and_says_nothing(monkeypatch):
    fake = FakeGsplat(monkeypatch, kept=False)
    for device in (torch.device("cpu"), "cpu", torch.device("meta")):
        setup = RasterizerSetup(device)
        assert setup.note == "" and setup.prepare() == 0.0 and setup.note == ""
    assert fake.calls == 0


def test_a_build_is_announced_before_and_timed_after_and_done_once(monkeypatch):
    fake = FakeGsplat(monkeypatch, kept=False, build_seconds=0.05)
    setup = RasterizerSetup(torch.device("cuda"), log=lambda line: None)
    assert setup.note == BUILD_NOTE  # what a UI shows while the build runs
    seconds = setup.prepare()
    assert seconds >= 0.05 and fake.calls == 1
    assert setup.note.startswith("built gsplat's rasterizer for this GPU in ")
    assert setup.note.endswith("s (later runs load it)")
    assert setup.prepare() == 0.0 and fake.calls == 1  # once a run
    assert setup.note == setup.outcome


def test_a_module_kept_from_before_is_loaded_without_a_word(monkeypatch):
    fake = FakeGsplat(monkeypatch, kept=True)
    setup = RasterizerSetup(torch.device("cuda", 0))
    assert setup.note == ""
    assert setup.prepare() == 0.0 and fake.calls == 1 and setup.note == ""


def test_a_failed_build_raises_its_reason_and_is_tried_again(monkeypatch):
    fake = FakeGsplat(monkeypatch, kept=False, fails=True)
    setup = RasterizerSetup(torch.device("cuda"))
    for calls in (1, 2):
        with pytest.raises(GsplatUnavailable, match=r"nvcc: not found; or compute on the CPU \(--device cpu\)$"):
            setup.prepare()
        assert fake.calls == calls and setup.note == BUILD_NOTE


def test_no_cuda_means_no_build_pending():
    if torch.cuda.is_available():
        pytest.skip("this checks a machine without CUDA")
    assert gsplat_module.build_pending() is False


def cuda_setup_engine(monkeypatch):
    """The real engine on a tiny scene whose rasterizer setup is CUDA's, with a gsplat build of BUILD_SECONDS."""
    fake = FakeGsplat(monkeypatch, kept=False, build_seconds=BUILD_SECONDS)
    engine = make_small_stylizer()
    engine.rasterizer_setup = RasterizerSetup(torch.device("cuda"), log=lambda line: None)
    return engine, fake


def test_the_engine_builds_before_its_first_step_outside_the_steps_time(monkeypatch):
    engine, fake = cuda_setup_engine(monkeypatch)
    assert engine.setup_note == BUILD_NOTE
    first = engine.step()
    assert fake.calls == 1 and first.phase == "ground_truth"
    assert engine.timings["gpu_rasterizer_build"] >= BUILD_SECONDS
    assert first.seconds < BUILD_SECONDS  # the build is not a ground-truth step's cost (the ETA prices those)
    assert engine.timings["ground_truth"] == pytest.approx(first.seconds)
    assert engine.decisions["rasterizer"] == engine.setup_note
    assert engine.setup_note.startswith("built gsplat's rasterizer")
    engine.step()
    assert fake.calls == 1


def test_the_worker_tells_the_studio_before_the_build_and_after_it(monkeypatch):
    from app.engine_host import EngineHost
    from app.worker import WorkerBridge

    engine, _ = cuda_setup_engine(monkeypatch)
    events: queue.Queue = queue.Queue()
    host = EngineHost(lambda: None, {}, events, threading.Semaphore(2), None)
    host.engine = engine
    for _ in range(3):
        host.step()
    sent = [(kind, payload) for kind, payload in list(events.queue) if kind in ("setup_note", "report")]
    assert [kind for kind, _ in sent] == ["setup_note", "report", "setup_note", "report", "report"]
    assert sent[0][1] == BUILD_NOTE and sent[2][1].startswith("built gsplat's rasterizer")

    bridge = WorkerBridge(lambda: None)
    for kind, payload in sent[:1]:
        bridge._apply(kind, payload)
    assert bridge.state.setup_note == BUILD_NOTE
    for kind, payload in sent[1:]:
        bridge._apply(kind, payload)
    assert bridge.state.setup_note == sent[2][1]


def test_the_studio_shows_a_new_setup_note_and_leaves_later_news_alone():
    from app.events import Events
    from app.panels import PanelState
    from app.status_line import StatusLine
    from app.studio_sync import EngineSync
    from app.worker import WorkerState

    panel = PanelState()  # the engine sync alone: no engine, no renderer (the setup note needs neither)
    studio = EngineSync(panel, StatusLine(panel), Events(), engine=None, stylized=None,
                        showing_result=lambda: False, shelve=lambda new: "")
    state = WorkerState()
    studio._sync_setup_note(state)
    assert studio.panel.status == "" and studio.panel.phase == "-"
    state.setup_note = BUILD_NOTE
    studio._sync_setup_note(state)
    assert studio.panel.status == BUILD_NOTE and studio.panel.phase == "GPU setup"  # before any step's report
    studio.panel.status = "exported take.ply"  # news after the note is not overwritten by the same note
    studio._sync_setup_note(state)
    assert studio.panel.status == "exported take.ply"
    state.setup_note = "built gsplat's rasterizer for this GPU in 184 s (later runs load it)"
    studio._sync_setup_note(state)
    assert studio.panel.status == state.setup_note


CARDS = {"cuda": ("NVIDIA GeForce RTX 3060 (12 GiB, CUDA 13.0)", "; 0.4 of 12.0 GiB free now"),
         "mps": ("Apple GPU (MPS)", "")}


@pytest.mark.parametrize("kind", sorted(CARDS))
def test_a_gpu_out_of_memory_in_a_step_is_one_line_that_says_what_to_lower(monkeypatch, kind):
    """torch's out-of-memory error in a step becomes a ``DeviceMemoryError`` (shown as one line by the CLI and the
    studio) naming the card (on CUDA with what it holds, its cache released first), the phase, the Gaussians and
    the width, and what to lower. The card's calls are doubles here: no GPU is needed."""
    from gstyle_core.device import DeviceChoice, DeviceMemoryError
    from gstyle_core.errors import GStyleError

    name, held = CARDS[kind]
    released = []
    engine = make_small_stylizer()
    monkeypatch.setattr(engine.run_state, "device_choice", DeviceChoice(torch.device(kind), name, "asked for"))
    monkeypatch.setattr(torch.mps, "empty_cache", lambda: released.append("mps"))
    monkeypatch.setattr(torch.cuda, "empty_cache", lambda: released.append("cuda"))
    monkeypatch.setattr(torch.cuda, "mem_get_info", lambda device: (0.4 * 2**30, 12 * 2**30))
    engine.step()  # a ground-truth step goes through

    def too_big():
        raise torch.OutOfMemoryError("MPS backend out of memory (MPS allocated: 7.9 GB ...)\nlong advice")

    monkeypatch.setattr(engine.current_phase(), "step", too_big)
    with pytest.raises(DeviceMemoryError) as caught:
        engine.step()
    error = caught.value
    assert isinstance(error, GStyleError) and isinstance(error.__cause__, torch.OutOfMemoryError)
    line = str(error)
    assert "\n" not in line and line.startswith(f"{name} ran out of memory in ground_truth")
    assert f"with {engine.gaussian_count:,} Gaussians at {engine.current_width} px{held}: " in line
    assert released == [kind]
    assert "--working-width, --max-gaussians" in line and line.endswith("or compute on the CPU (--device cpu)")
