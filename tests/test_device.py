"""The device-generic paths on the CPU device: the choice and its reason, clear errors, the parts that move tensors
between devices (renders, refits, checkpoints) behaving on one device exactly as before. The CUDA side is in
``tests/test_raster_gsplat.py`` (it runs where CUDA is)."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.cli import run
from gstyle_core.engine.settings import StylizeSettings, check_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.fit.model import params_from_scene, render_params
from gstyle_core.fit.trainer import FitConfig, Trainer
from gstyle_core.style.precision import choose_precision, cuda_card
from tests.fakes import engine_with_random_vgg
from tests.synthetic import blob_scene, ring_cameras

CUDA = torch.cuda.is_available()


def _engine(monkeypatch, device: str) -> Stylizer:
    return engine_with_random_vgg(monkeypatch, epochs=2, precision="fp32", device=device)


@pytest.mark.skipif(CUDA, reason="auto picks CUDA on this machine")
def test_an_engine_records_its_device_and_why(monkeypatch):
    engine = _engine(monkeypatch, "auto")
    assert engine.decisions["device"] == "cpu (CPU): auto: torch sees no CUDA device"
    assert _engine(monkeypatch, "cpu").decisions["device"] == "cpu (CPU): asked for (--device cpu)"
    while engine.phase != "stylize":
        engine.step()
    engine.step()
    assert engine.objective.device.type == "cpu" and engine.run_state.raster_device.type == "cpu"
    assert engine.render(0).device.type == "cpu"


def test_a_device_setting_outside_the_choices_is_refused():
    with pytest.raises(ValueError, match="device must be one of auto, cpu, cuda, mps"):
        check_settings(StylizeSettings(device="tpu"))
    assert StylizeSettings.from_dict({"preset": "preview"}).device == "auto"  # older summaries: the default


@pytest.mark.skipif(CUDA, reason="this machine has CUDA")
def test_stylize_asking_for_cuda_without_it_is_one_line_and_exit_2(tmp_path, capsys):
    code = run(["stylize", "--out", str(tmp_path / "x.ply"), "--device", "cuda", "--checkpoint-every", "0"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "sees no CUDA device" in err and "\n" not in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def test_rendering_on_a_named_device_gives_the_same_image_and_gradients():
    scene = blob_scene(200, seed=1)
    cam = ring_cameras(1, width=48, height=40)[0]
    results = []
    for device in (None, "cpu"):
        params = params_from_scene(scene)
        out = render_params(params, cam, device=device)
        out.image.sum().backward()
        results.append((out.image.detach(), params["means"].grad.clone()))
    assert torch.equal(results[0][0], results[1][0]) and torch.equal(results[0][1], results[1][1])


def test_a_trainers_saved_moments_are_cpu_copies():
    scene = blob_scene(100, seed=2)
    cams = ring_cameras(2, width=32, height=24)
    params = params_from_scene(scene)
    images = [render_params(params, c).image.detach() for c in cams]
    trainer = Trainer(params_from_scene(scene), cams, images, FitConfig(iterations=3, sh_degree=0, device="cpu"))
    trainer.step()
    saved = trainer.state_dict()["optimizers"]["means"]["state"][0]["exp_avg"]
    live = trainer.optimizers["means"].state[trainer.params["means"]]["exp_avg"]
    assert saved.device.type == "cpu" and torch.equal(saved, live) and saved.data_ptr() != live.data_ptr()


def test_gpu_precision_applies_only_to_cuda_runs():
    size = (48, 64)
    assert choose_precision("fp32", size, gpu=("Card", True))[0] == "fp32"  # an explicit choice stands
    assert choose_precision("auto", size, env={"GSTYLE_PRECISION": "fp32"}, gpu=("Card", True))[0] == "fp32"
    assert choose_precision("auto", size, env={}, gpu=("Card", True))[0] == "bf16"
    assert choose_precision("auto", size, env={}, gpu=("Old card", False))[0] == "fp32"
    assert cuda_card(StylizeSettings(precision="auto", device="cpu")) is None
    if not CUDA:
        assert cuda_card(StylizeSettings(precision="auto", device="auto")) is None


def test_the_gpus_failures_are_told_from_other_errors():
    """What the studio offers to go on on the CPU for: the GPU's own failures, also when raised from one."""
    from gstyle_core.device import DeviceMemoryError, DeviceUnavailable, is_device_failure
    from gstyle_core.raster.gsplat_module import GsplatUnavailable

    for error in (DeviceMemoryError("x"), DeviceUnavailable("x"), GsplatUnavailable("x"),
                  torch.OutOfMemoryError("CUDA out of memory"), torch.AcceleratorError("an illegal memory access")):
        assert is_device_failure(error), error
    try:
        try:
            raise torch.OutOfMemoryError("CUDA out of memory")
        except RuntimeError as inner:
            raise ValueError("while rendering") from inner
    except ValueError as outer:
        assert is_device_failure(outer)
    for error in (RuntimeError("a shape mismatch"), ValueError("x"), MemoryError()):
        assert not is_device_failure(error), error


def test_a_checkpoint_resumes_on_another_device_but_not_with_other_settings():
    """The device is where a run computes, not what: the fingerprint leaves it out, and nothing else."""
    from gstyle_core.engine.checkpoint import engine_fingerprint
    from tests.fakes import make_small_stylizer

    auto, cpu = engine_fingerprint(make_small_stylizer(device="auto")), engine_fingerprint(make_small_stylizer(
        device="cpu"))
    assert auto == cpu and auto["settings"]
    wider = make_small_stylizer(device="cpu")
    wider.settings.working_width = 48
    assert engine_fingerprint(wider)["settings"] != cpu["settings"]
