"""The CLIP term: finding CLIP ViT-B/32 weights offline, and the CLIP image-embedding style loss.

The encoder is ``clip_model.ClipVisionEncoder``; without weights the term is the coarse-VGG substitute of
``coarse.py`` (``CoarseStyleLoss``). Both, and their labels, are importable from here too.

``load_clip`` only reads weights that are already on disk (an OpenAI ``ViT-B-32.pt`` — TorchScript archive
or state dict — or an OpenCLIP ``open_clip_pytorch_model.bin`` state dict); it never downloads.

``ClipStyleLoss`` follows the G-Style reference: 16 random square crops of the render, each side drawn
uniformly from [min(short side, 224), short side] (so crops cover half to all of a 448-px render and the
whole short side of small renders), resized to 224x224 (area averaging; crops smaller than 224 are
upsampled), CLIP-normalised, embedded, and compared with the style image's embedding by the squared
great-circle distance ``2·arcsin(‖a−b‖/2)²`` of the unit embeddings; the mean over crops is returned.
"""

from __future__ import annotations

import glob
import os
import zipfile
from collections.abc import Sequence
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from ..errors import WeightsUnavailableError
from .clip_model import ClipVisionEncoder, encoder_from_state_dict, visual_state_dict
from .coarse import COARSE_LABEL, CoarseStyleLoss
from .paintings import as_batch, checked_style_weights, style_list

__all__ = [
    "CLIP_ENV",
    "CLIP_MEAN",
    "CLIP_OFF",
    "CLIP_STD",
    "COARSE_LABEL",
    "COARSE_NAME",
    "ClipStyleLoss",
    "ClipVisionEncoder",
    "CoarseStyleLoss",
    "clip_search_paths",
    "clip_status",
    "clip_term_name",
    "encoder_from_state_dict",
    "find_clip_weights",
    "load_clip",
    "random_square_crops",
    "resize_short_side_center_crop",
    "spherical_distance",
    "visual_state_dict",
]

CLIP_MEAN = (0.48145466, 0.4578275, 0.40821073)
CLIP_STD = (0.26862954, 0.26130258, 0.27577711)
COARSE_NAME = "coarse (CLIP substitute)"  # the term's name on labels (sliders, plots, progress) without CLIP weights
CLIP_OFF = "CLIP term off (λ_CLIP = 0)"
CLIP_ENV = "GSTYLE_CLIP_WEIGHTS"


# ------------------------------------------------------------------------------------------------ loading

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
        styles = style_list(style_image)
        with torch.no_grad():
            embeddings = torch.cat([self.embed(resize_short_side_center_crop(as_batch(s), self.input_size))
                                    for s in styles])
        self.register_buffer("style_embeddings", embeddings, persistent=False)  # [K, 512]
        self.set_style_weights(style_weights)

    def set_style_weights(self, weights: Sequence[float] | None) -> None:
        """Weights of the paintings (None: one painting, weight 1)."""
        self.style_weights = checked_style_weights(weights, self.style_embeddings.shape[0])

    def embed(self, images: torch.Tensor) -> torch.Tensor:
        """Embeddings of [N,3,S,S] RGB [0,1] images."""
        return self.encoder((images - self.mean) / self.std)

    def forward(self, render: torch.Tensor) -> torch.Tensor:  # render: [B,3,H,W] in [0,1]
        render = as_batch(render)
        crops = torch.cat([random_square_crops(render[i:i + 1], self.n_crops, self.input_size, self.generator)
                           for i in range(render.shape[0])])
        embedded = self.embed(crops)
        return torch.stack([w * spherical_distance(embedded, self.style_embeddings[k:k + 1]).mean()
                            for k, w in enumerate(self.style_weights) if w > 0]).sum()
