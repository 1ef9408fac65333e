"""On a CUDA device: a real out-of-memory error on the card mid-stylization and the run handed over to the CPU from
its last finished step, through the studio's worker ("Continue on the CPU"), and a run moved the other way ("Move
to the GPU"). These run where torch sees a CUDA device and gsplat is installed (``bench/gpu_check.sh`` runs them on a
GPU machine) and skip elsewhere; ``tests/test_app_worker.py`` and ``tests/test_app_device_moves.py`` check the same
paths on the CPU with stand-ins for the GPU."""

from __future__ import annotations

import importlib.util

import pytest
import torch

from app.worker import ThreadWorkerBridge

needs_cuda = pytest.mark.skipif(not (torch.cuda.is_available() and importlib.util.find_spec("gsplat") is not None),
                                reason="needs a CUDA device and gsplat (GPU machine: bench/gpu_check.sh runs it)")


def hold_the_card() -> list:
    """Leave a step no GPU memory: the allocator held to a sliver of the card (no new segment), then every free
    block in torch's cache taken, largest first, down to 512 bytes (held to the card's limit alone, a small step was
    served from the cache's free blocks and never ran out: seen on an H100). Returns the blocks taken."""
    torch.cuda.empty_cache()
    torch.cuda.set_per_process_memory_fraction(1e-6)
    held, size = [], 1 << 26
    while size >= 512:
        try:
            held.append(torch.empty(size, dtype=torch.uint8, device="cuda"))
        except torch.OutOfMemoryError:
            size = (1 << 20) + 512 if size == 1 << 21 else size // 2  # just over 1 MiB: the large pool's smallest
    return held


def let_go_of_the_card(held: list) -> None:
    """Undo :func:`hold_the_card`."""
    held.clear()
    torch.cuda.set_per_process_memory_fraction(1.0)
    torch.cuda.empty_cache()


@needs_cuda
def test_a_real_out_of_memory_on_the_card_goes_on_on_the_cpu(monkeypatch):
    from fakes import BUILT, keep_small_stylizer

    from gstyle_core.engine.stylizer import Stylizer

    step, load = Stylizer.step, Stylizer.load_state_dict
    loaded = []

    def step_on_a_full_card(engine):
        """The third optimiser step of the stylization with no memory left on the card: a real OOM from torch's
        allocator (a split step, which touches only the CPU's copy, would go through)."""
        stylize = engine.stylize
        if (engine.settings.device == "cuda" and engine.phase == "stylize" and stylize.step_index == 2
                and 2 not in stylize.split_steps):
            held = hold_the_card()
            try:
                return step(engine)
            finally:
                let_go_of_the_card(held)
        return step(engine)

    def recording_load(engine, state):
        load(engine, state)
        loaded.append((engine, engine.c_s.clone(), engine.run_state.params["means"].detach().cpu().clone()))

    monkeypatch.setattr(Stylizer, "step", step_on_a_full_card)
    monkeypatch.setattr(Stylizer, "load_state_dict", recording_load)
    BUILT.clear()
    b = ThreadWorkerBridge(keep_small_stylizer, {"n": 2000, "device": "cuda"})
    b.start()
    try:
        assert b.wait_until(lambda s: s.error is not None or s.done, 300)
        assert b.state.device_failed and "ran out of memory in stylize" in b.state.error, b.state.error
        failed = BUILT[-1]
        colours, means = failed.c_s.detach().cpu().clone(), failed.run_state.params["means"].detach().cpu().clone()
        b.move_to(dict(b.config), "cpu")
        assert b.wait_until(lambda s: s.done or s.error, 300), "the run did not end on the CPU"
        assert b.state.error is None, b.state.error
        engine, at_load, means_at_load = loaded[-1]
        assert engine.settings.device == "cpu" and engine.run_state.raster_device.type == "cpu"
        assert torch.equal(at_load, colours) and torch.equal(means_at_load, means)
    finally:
        assert b.quit(timeout=60)


@needs_cuda
def test_a_run_moved_from_the_cpu_to_the_card_goes_on_there():
    """The other way (the studio's Move to the GPU): a run on the CPU, moved mid-stylization, ends on the card."""
    from fakes import BUILT, keep_small_stylizer

    BUILT.clear()
    b = ThreadWorkerBridge(keep_small_stylizer, {"n": 2000, "device": "cpu"})
    b.start()
    try:
        # (a stylize step reported: the last report alone may be past the phase, its steps drained in one poll)
        assert b.wait_until(lambda s: s.step_times.counts.get("stylize") or s.error, 300)
        assert b.state.error is None, b.state.error
        b.move_to(dict(b.config), "cuda")
        assert b.wait_until(lambda s: s.done or s.error, 300), "the run did not end on the card"
        assert b.state.error is None and b.state.resumed is not None, b.state.error
        assert BUILT[-1].device_choice.kind == "cuda" and b.state.device == "cuda"
    finally:
        assert b.quit(timeout=60)
