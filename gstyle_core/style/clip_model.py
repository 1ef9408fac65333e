"""The CLIP ViT image encoder and its weights' layout.

``ClipVisionEncoder`` is a self-contained ViT image encoder with the layout of OpenAI CLIP ViT-B/32 and
OpenCLIP ``ViT-B-32-quickgelu`` (patch 32, width 768, 12 layers, 12 heads, 512-d output, class token,
``ln_pre``/``ln_post``, ``proj``, QuickGELU). Sizes are configurable so tests can build a tiny one;
``encoder_from_state_dict`` reads them off a checkpoint's weights.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from ..errors import WeightsUnavailableError


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
