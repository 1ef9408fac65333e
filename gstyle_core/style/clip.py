"""CLIP image-embedding style loss, and its documented stand-in when no CLIP weights are available.

``ClipVisionEncoder`` is a self-contained ViT image encoder with the layout of OpenAI CLIP ViT-B/32 and
OpenCLIP ``ViT-B-32-quickgelu`` (patch 32, width 768, 12 layers, 12 heads, 512-d output, class token,
``ln_pre``/``ln_post``, ``proj``, QuickGELU). Sizes are configurable so tests can build a tiny one.

``load_clip`` only reads weights that are already on disk (an OpenAI ``ViT-B-32.pt`` — TorchScript archive
or state dict — or an OpenCLIP ``open_clip_pytorch_model.bin`` state dict); it never downloads.

``ClipStyleLoss`` follows the G-Style reference: 16 random square crops of the render, each side drawn
uniformly from [min(short side, 224), short side] (so crops cover half to all of a 448-px render and the
whole short side of small renders), resized to 224x224 (area averaging; crops smaller than 224 are
upsampled), CLIP-normalised, embedded, and compared with the style image's embedding by the squared
great-circle distance ``2·arcsin(‖a−b‖/2)²`` of the unit embeddings; the mean over crops is returned.

Fallback without CLIP weights — ``CoarseStyleLoss``, labelled "coarse-VGG substitute (no CLIP weights)":
CLIP carries the low-frequency part of the style (large patterns, overall palette layout). Without it we
match AdaIN-style statistics (per-channel mean and standard deviation) of VGG relu3_1…relu3_3 features of
the render and of the style image, both downsampled 4x first so the receptive field of relu3 (40 px)
covers about 160 px of the original image; the error is relative (scale-free, about 0…1 like the CLIP
distance) so the same λ_CLIP applies. The render's statistics are taken over the scene only, weighted by its
coverage (rendered alpha) when the caller gives it: an object on an empty background would otherwise be
pushed to make background and object together look like the painting. It is not CLIP, only a substitute for the
coarse scale.
"""

from __future__ import annotations

import glob
import math
import os
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from ..errors import WeightsUnavailableError

CLIP_MEAN = (0.48145466, 0.4578275, 0.40821073)
CLIP_STD = (0.26862954, 0.26130258, 0.27577711)
COARSE_LABEL = "coarse-VGG substitute (no CLIP weights)"
COARSE_NAME = "coarse (CLIP substitute)"  # the term's name on labels (sliders, plots, progress) without CLIP weights
CLIP_OFF = "CLIP term off (λ_CLIP = 0)"
CLIP_ENV = "GSTYLE_CLIP_WEIGHTS"


# ---------------------------------------------------------------------------------------------- the network

class QuickGELU(nn.Module):
    """x·sigmoid(1.702x), the activation of the OpenAI CLIP weights."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x * torch.sigmoid(1.702 * x)


class _Mlp(nn.Module):
    def __init__(self, width: int) -> None:
        super().__init__()
        self.c_fc = nn.Linear(width, 4 * width)
        self.gelu = QuickGELU()
        self.c_proj = nn.Linear(4 * width, width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.c_proj(self.gelu(self.c_fc(x)))


class _ResidualBlock(nn.Module):
    def __init__(self, width: int, heads: int) -> None:
        super().__init__()
        self.ln_1 = nn.LayerNorm(width)
        self.attn = nn.MultiheadAttention(width, heads, batch_first=True)
        self.ln_2 = nn.LayerNorm(width)
        self.mlp = _Mlp(width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # x: [B, T, width]
        h = self.ln_1(x)
        x = x + self.attn(h, h, h, need_weights=False)[0]
        return x + self.mlp(self.ln_2(x))


class _Transformer(nn.Module):
    def __init__(self, width: int, layers: int, heads: int) -> None:
        super().__init__()
        self.resblocks = nn.Sequential(*[_ResidualBlock(width, heads) for _ in range(layers)])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.resblocks(x)


class ClipVisionEncoder(nn.Module):
    """CLIP ViT image tower. ``forward(x [B,3,S,S], CLIP-normalised) -> [B, output_dim]`` embeddings.
    Parameter names equal the ``visual.*`` keys of OpenAI CLIP and OpenCLIP checkpoints (prefix removed)."""

    def __init__(self, image_size: int = 224, patch_size: int = 32, width: int = 768, layers: int = 12,
                 heads: int = 12, output_dim: int = 512) -> None:
        super().__init__()
        if image_size % patch_size:
            raise ValueError(f"image_size {image_size} is not a multiple of patch_size {patch_size}")
        self.image_size = image_size
        self.conv1 = nn.Conv2d(3, width, kernel_size=patch_size, stride=patch_size, bias=False)
        scale = width ** -0.5
        grid = image_size // patch_size
        self.class_embedding = nn.Parameter(scale * torch.randn(width))
        self.positional_embedding = nn.Parameter(scale * torch.randn(grid * grid + 1, width))
        self.ln_pre = nn.LayerNorm(width)
        self.transformer = _Transformer(width, layers, heads)
        self.ln_post = nn.LayerNorm(width)
        self.proj = nn.Parameter(scale * torch.randn(width, output_dim))
        self.calls = 0

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        self.calls += 1
        x = self.conv1(x)  # [B, width, g, g]
        x = x.flatten(2).transpose(1, 2)  # [B, g*g, width]
        cls = self.class_embedding.to(x.dtype).expand(x.shape[0], 1, -1)
        x = torch.cat([cls, x], dim=1) + self.positional_embedding.to(x.dtype)
        x = self.transformer(self.ln_pre(x))
        return self.ln_post(x[:, 0, :]) @ self.proj


# -------------------------------------------------------------------------------------------------- loading

def visual_state_dict(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The image-tower weights of an OpenAI or OpenCLIP checkpoint, keys without the ``visual.`` prefix.
    Accepts optional ``module.`` prefixes and a ``{"state_dict": ...}`` wrapper."""
    if "state_dict" in state and isinstance(state["state_dict"], dict):
        state = state["state_dict"]
    out = {}
    for key, value in state.items():
        name = key[len("module."):] if key.startswith("module.") else key
        if name.startswith("visual."):
            out[name[len("visual."):]] = value
    if not out and "conv1.weight" in state:  # already a bare image-tower dict
        out = dict(state)
    return out


def encoder_from_state_dict(state: dict[str, torch.Tensor]) -> ClipVisionEncoder:
    """Build a :class:`ClipVisionEncoder` whose sizes are read off the weights, and load them.
    The head count is not stored in the weights; CLIP ViTs use 64-wide heads (ViT-B/32: 768 / 64 = 12)."""
    visual = visual_state_dict(state)
    needed = ("conv1.weight", "positional_embedding", "proj", "class_embedding")
    missing = [k for k in needed if k not in visual]
    if missing:
        raise WeightsUnavailableError(f"not a CLIP ViT checkpoint (missing visual.{missing[0]})")
    width, _, patch, _ = visual["conv1.weight"].shape
    tokens = visual["positional_embedding"].shape[0]
    grid = math.isqrt(tokens - 1)
    layers = len({k.split(".")[2] for k in visual if k.startswith("transformer.resblocks.")})
    encoder = ClipVisionEncoder(image_size=grid * patch, patch_size=patch, width=width, layers=layers,
                                heads=max(1, width // 64), output_dim=visual["proj"].shape[1])
    wanted = encoder.state_dict().keys()
    try:
        encoder.load_state_dict({k: visual[k].float() for k in wanted if k in visual}, strict=True)
    except RuntimeError as exc:
        first = str(exc).splitlines()[1].strip() if "\n" in str(exc) else str(exc)
        raise WeightsUnavailableError(f"CLIP weights do not fit a ViT image encoder: {first}") from exc
    return encoder.eval().requires_grad_(False)


def _is_torchscript_archive(path: Path) -> bool:
    """TorchScript zips hold a ``<name>/constants.pkl`` (or ``code/``) member; plain state dicts do not."""
    if not zipfile.is_zipfile(path):
        return False
    with zipfile.ZipFile(path) as archive:
        return any(name.endswith("/constants.pkl") or "/code/" in name for name in archive.namelist())


def _read_checkpoint(path: Path) -> dict[str, torch.Tensor]:
    try:
        if _is_torchscript_archive(path):  # the OpenAI release files are TorchScript archives
            obj = torch.jit.load(str(path), map_location="cpu").state_dict()
        else:
            obj = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise WeightsUnavailableError(f"cannot read CLIP weights from {path} ({type(exc).__name__})") from exc
    if not isinstance(obj, dict):
        raise WeightsUnavailableError(f"{path} does not hold a CLIP state dict")
    return obj


def clip_search_paths() -> list[Path]:
    """Usual places of ViT-B/32 weights: the OpenAI clip cache and Hugging Face hub snapshots."""
    home = Path.home()
    hf_home = Path(os.environ.get("HF_HOME", home / ".cache" / "huggingface"))
    hub = Path(os.environ.get("HF_HUB_CACHE", hf_home / "hub"))
    paths = [home / ".cache" / "clip" / "ViT-B-32.pt"]
    for pattern in ("models--*ViT-B-32*", "models--*vit_base_patch32_clip*"):
        snapshots = hub / pattern / "snapshots" / "*" / "open_clip_pytorch_model.bin"
        paths += sorted(Path(p) for p in glob.glob(str(snapshots)))
    return paths


def find_clip_weights(path: str | Path | None = None) -> Path | None:
    """The CLIP weights file :func:`load_clip` would read (``path``, ``$GSTYLE_CLIP_WEIGHTS``, then the usual
    places); an explicit file is returned whether or not it exists. None: nothing found."""
    explicit = path if path is not None else os.environ.get(CLIP_ENV) or None
    if explicit is not None:
        return Path(explicit).expanduser()
    return next((file for file in clip_search_paths() if file.is_file()), None)


def clip_term_name(path: str | Path | None = None) -> str:
    """What the CLIP term is on this machine, for labels: "CLIP" with weights, else :data:`COARSE_NAME`."""
    found = find_clip_weights(path)
    return "CLIP" if found is not None and found.is_file() else COARSE_NAME


def clip_status(path: str | Path | None = None) -> str:
    """One line on the CLIP term without loading it: where its weights are, or where we looked in vain."""
    found = find_clip_weights(path)
    if found is not None:
        return f"CLIP weights from {found}"
    looked = ", ".join(str(p) for p in clip_search_paths()[:1]) + ", ~/.cache/huggingface/hub/models--*ViT-B-32*"
    return f"CLIP ViT-B/32 weights not found (looked in {looked}, ${CLIP_ENV}); using the {COARSE_LABEL}"


def load_clip(path: str | Path | None = None) -> tuple[ClipVisionEncoder | None, str]:
    """Find and load CLIP ViT-B/32 image weights offline → (encoder or None, one-line description).

    Search order: ``path`` (e.g. ``--clip-weights``), ``$GSTYLE_CLIP_WEIGHTS``, ~/.cache/clip/ViT-B-32.pt,
    Hugging Face hub snapshots of ViT-B-32 OpenCLIP models. An explicitly given file that cannot be used
    raises :class:`WeightsUnavailableError`; when nothing is found the encoder is None and the text says
    where we looked and that the coarse-VGG substitute is used.
    """
    file = find_clip_weights(path)
    if file is None:
        return None, clip_status(path)
    if not file.is_file():
        raise WeightsUnavailableError(f"CLIP weights file {file} does not exist")
    return encoder_from_state_dict(_read_checkpoint(file)), f"CLIP weights from {file}"


# --------------------------------------------------------------------------------------------------- losses

def random_square_crops(img: torch.Tensor, n_crops: int, out_size: int,
                        generator: torch.Generator | None = None) -> torch.Tensor:
    """``n_crops`` random square crops of ``img [1,3,H,W]`` → [n_crops, 3, out_size, out_size].
    Side uniform in [min(short, out_size), short] (at least 1 px); area-resized to ``out_size``."""
    if img.ndim != 4 or img.shape[0] != 1:
        raise ValueError(f"crops need one image [1,3,H,W], got {tuple(img.shape)}")
    height, width = img.shape[-2:]
    short = min(height, width)
    if short < 1:
        raise ValueError(f"cannot crop an empty image of size {height}x{width}")
    low = max(1, min(short, out_size))
    crops = []
    for _ in range(n_crops):
        side = int(low + torch.rand((), generator=generator).item() * (short - low + 1))
        side = min(max(side, 1), short)
        top = int(torch.randint(0, height - side + 1, (), generator=generator))
        left = int(torch.randint(0, width - side + 1, (), generator=generator))
        crop = img[:, :, top:top + side, left:left + side]
        crops.append(F.adaptive_avg_pool2d(crop, out_size))
    return torch.cat(crops, dim=0)


def resize_short_side_center_crop(img: torch.Tensor, size: int) -> torch.Tensor:
    """CLIP's preprocessing geometry: short side to ``size`` (bicubic, antialiased), central square crop."""
    height, width = img.shape[-2:]
    scale = size / min(height, width)
    new_h, new_w = max(size, round(height * scale)), max(size, round(width * scale))
    resized = F.interpolate(img, size=(new_h, new_w), mode="bicubic", align_corners=False,
                            antialias=scale < 1).clamp(0, 1)
    top, left = (new_h - size) // 2, (new_w - size) // 2
    return resized[:, :, top:top + size, left:left + size]


def spherical_distance(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """2·arcsin(‖â−b̂‖/2)² for unit-normalised rows of ``a`` [N,D] against ``b`` [1,D] → [N].

    Computed as 2·atan2(‖â−b̂‖, ‖â+b̂‖)² (the same half-angle): arcsin's derivative is infinite at opposite
    embeddings and gave NaN gradients there; atan2 is finite everywhere."""
    a = F.normalize(a, dim=-1, eps=1e-8)
    b = F.normalize(b, dim=-1, eps=1e-8)
    return 2 * torch.atan2((a - b).norm(dim=-1), (a + b).norm(dim=-1)) ** 2


class ClipStyleLoss(nn.Module):
    """Mean spherical distance between CLIP embeddings of random render crops and of the style image; for several
    paintings (``style_image`` a list, ``style_weights`` summing to 1) the weighted sum of the distances to each
    painting's embedding (the render is embedded once)."""

    network = "clip"
    label = "CLIP ViT-B/32"

    def __init__(self, encoder: ClipVisionEncoder, style_image: torch.Tensor | Sequence[torch.Tensor],
                 n_crops: int = 16, generator: torch.Generator | None = None,
                 style_weights: Sequence[float] | None = None) -> None:
        super().__init__()
        self.encoder = encoder.eval().requires_grad_(False)
        self.n_crops = n_crops
        self.generator = generator
        self.input_size = encoder.image_size
        self.register_buffer("mean", torch.tensor(CLIP_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(CLIP_STD).view(1, 3, 1, 1), persistent=False)
        styles = _style_list(style_image)
        with torch.no_grad():
            embeddings = torch.cat([self.embed(resize_short_side_center_crop(_as_batch(s), self.input_size))
                                    for s in styles])
        self.register_buffer("style_embeddings", embeddings, persistent=False)  # [K, 512]
        self.set_style_weights(style_weights)

    def set_style_weights(self, weights: Sequence[float] | None) -> None:
        """Weights of the paintings (None: one painting, weight 1)."""
        self.style_weights = _checked_weights(weights, self.style_embeddings.shape[0])

    def embed(self, images: torch.Tensor) -> torch.Tensor:
        """Embeddings of [N,3,S,S] RGB [0,1] images."""
        return self.encoder((images - self.mean) / self.std)

    def forward(self, render: torch.Tensor) -> torch.Tensor:  # render: [B,3,H,W] in [0,1]
        render = _as_batch(render)
        crops = torch.cat([random_square_crops(render[i:i + 1], self.n_crops, self.input_size, self.generator)
                           for i in range(render.shape[0])])
        embedded = self.embed(crops)
        return torch.stack([w * spherical_distance(embedded, self.style_embeddings[k:k + 1]).mean()
                            for k, w in enumerate(self.style_weights) if w > 0]).sum()


class CoarseStyleLoss(nn.Module):
    """Stand-in for the CLIP term: mean/std statistics of VGG relu3_x features at a coarse scale.

    Per layer: (‖μ_r − μ_s‖² + ‖σ_r − σ_s‖²) / (‖μ_s‖² + ‖σ_s‖²), the relative error of the per-channel
    statistics, averaged over the three layers. Being relative, it does not depend on the feature scale of
    the VGG weights and lies in the same range as the CLIP distance (0 for a perfect match, ~1 for unrelated
    statistics), so λ_CLIP can be kept."""

    network = "vgg"
    takes_coverage = True
    label = COARSE_LABEL

    def __init__(self, vgg: Callable[[torch.Tensor], dict[str, torch.Tensor]],
                 style_image: torch.Tensor | Sequence[torch.Tensor], downsample: int = 4,
                 style_weights: Sequence[float] | None = None) -> None:
        super().__init__()
        self.vgg = vgg
        self.downsample = downsample
        self.styles_stats = []  # per painting: {layer: (mean, std)}
        with torch.no_grad():
            for style in _style_list(style_image):
                stats = self._statistics(_as_batch(style))
                self.styles_stats.append({name: (m.detach(), s.detach()) for name, (m, s) in stats.items()})
        self.set_style_weights(style_weights)

    def set_style_weights(self, weights: Sequence[float] | None) -> None:
        """Weights of the paintings (None: one painting, weight 1)."""
        self.style_weights = _checked_weights(weights, len(self.styles_stats))

    def _statistics(self, img: torch.Tensor, coverage: torch.Tensor | None = None
                    ) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        from .losses import feature_weights

        height, width = img.shape[-2:]
        size = (max(16, height // self.downsample), max(16, width // self.downsample))
        small = F.interpolate(img, size=size, mode="bilinear", align_corners=False, antialias=True)
        feats = self.vgg(small)
        out = {}
        for name, f in feats.items():
            flat = f.flatten(2)  # [B, C, h*w]
            w = feature_weights(coverage, f.shape[-2:])
            if w is None or float(w.sum()) <= 0.0:
                out[name] = (flat.mean(-1), (flat.var(-1, unbiased=False) + 1e-8).sqrt())
                continue
            w = w.flatten(2) / w.flatten(2).sum(-1, keepdim=True)  # [B, 1, h*w], sums to 1
            mean = (flat * w).sum(-1)
            var = (((flat - mean[..., None]) ** 2) * w).sum(-1)
            out[name] = (mean, (var + 1e-8).sqrt())
        return out

    def forward(self, render: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
        """Relative error of the render's feature statistics (over the scene: ``coverage`` [H,W] or [B,1,H,W]
        weights each position; None: the whole frame) against the style image's (several: weighted sum)."""
        render_stats = self._statistics(_as_batch(render), coverage)
        per_style = []
        for weight, style_stats in zip(self.style_weights, self.styles_stats, strict=True):
            if weight <= 0:
                continue
            terms = []
            for name, (mean, std) in render_stats.items():
                style_mean, style_std = style_stats[name]
                error = ((mean - style_mean) ** 2).sum(-1) + ((std - style_std) ** 2).sum(-1)  # [B]
                scale = (style_mean**2).sum(-1) + (style_std**2).sum(-1) + 1e-8
                terms.append((error / scale).mean())
            per_style.append(weight * torch.stack(terms).mean())
        return torch.stack(per_style).sum()


def _style_list(style_image: torch.Tensor | Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """One painting or several, as a list (a list of none is an error)."""
    styles = [style_image] if isinstance(style_image, torch.Tensor) else list(style_image)
    if not styles:
        raise ValueError("no style image given")
    return styles


def _checked_weights(weights: Sequence[float] | None, n_styles: int) -> tuple[float, ...]:
    from .mix import normalise_style_weights

    return (1.0,) if weights is None and n_styles == 1 else normalise_style_weights(weights, n_styles)


def _as_batch(img: torch.Tensor) -> torch.Tensor:
    """Accept [3,H,W], [H,W,3] (numpy layout) or [B,3,H,W]; return float [B,3,H,W]."""
    img = torch.as_tensor(img).float()
    if img.ndim == 3:
        img = img.permute(2, 0, 1) if img.shape[-1] == 3 and img.shape[0] != 3 else img
        img = img.unsqueeze(0)
    if img.ndim != 4 or img.shape[1] != 3:
        raise ValueError(f"expected an RGB image [B,3,H,W], got {tuple(img.shape)}")
    if img.shape[0] == 0 or img.shape[2] == 0 or img.shape[3] == 0:
        raise ValueError(f"expected a non-empty RGB image, got shape {tuple(img.shape)}")
    return img
