"""Step-wise 3DGS optimisation: one ``step()`` call = one training iteration on one view.

The same loop serves ``gstyle fit`` (fitting from photos), G-Style's pre-processing refits and the refits after
colour-gradient splits; what differs is the ``Strategy`` and which parameters are trainable.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from ..cameras.camera import Camera
from .model import render_params
from .ssim import psnr, ssim
from .strategy import StepInfo, Strategy


@dataclass
class FitConfig:
    """Learning rates and loss weights of 3DGS (Kerbl et al. 2023) with run-length dependent schedules."""

    iterations: int = 3000
    lr_means: float = 1.6e-4  # times the scene scale; decays exponentially to lr_means_final
    lr_means_final: float = 1.6e-6
    lr_sh_dc: float = 2.5e-3
    lr_sh_rest: float = 2.5e-3 / 20
    lr_opacity: float = 5e-2
    lr_scales: float = 5e-3
    lr_quats: float = 1e-3
    ssim_weight: float = 0.2
    sh_degree: int = 3
    sh_increase_every: int = 1000
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    backend: str = "fast"
    device: str = "cpu"  # where renders and the loss run (the parameters and optimisers stay where they are)
    seed: int = 0
    trainable: tuple[str, ...] = ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest")


@dataclass
class FitReport:
    """Result of one training step."""

    step: int
    loss: float
    l1: float
    gaussians: int
    seconds: float
    changes: dict[str, int] = field(default_factory=dict)


def scene_scale(cameras: Sequence[Camera]) -> float:
    """3DGS's scene extent: 1.1 × the largest distance of a camera centre from their mean (at least 1e-3)."""
    centres = np.stack([c.position for c in cameras])
    return float(max(1.1 * np.linalg.norm(centres - centres.mean(0), axis=1).max(), 1e-3))


def _on_cpu(state):
    """A copy of an optimiser's state with its tensors on the CPU (checkpoints of a GPU run load anywhere;
    ``load_state_dict`` moves them to the parameters' device)."""
    if isinstance(state, torch.Tensor):
        return state.detach().to("cpu", copy=True)
    if isinstance(state, dict):
        return {k: _on_cpu(v) for k, v in state.items()}
    if isinstance(state, (list, tuple)):
        return type(state)(_on_cpu(v) for v in state)
    return copy.deepcopy(state)


class Trainer:
    """Fit Gaussians (``params``) to posed images, one iteration per ``step()``."""

    def __init__(
        self,
        params: torch.nn.ParameterDict,
        cameras: Sequence[Camera],
        images: Sequence[np.ndarray | torch.Tensor],
        config: FitConfig | None = None,
        strategy: Strategy | None = None,
        strategy_state: dict | None = None,
        extent: float | None = None,
    ) -> None:
        if len(cameras) == 0 or len(cameras) != len(images):
            raise ValueError("fitting needs at least one camera and exactly one image per camera")
        self.params = params
        self.cameras = list(cameras)
        self.config = config or FitConfig()
        self.device = torch.device(self.config.device)
        self.images = [torch.as_tensor(np.asarray(im, np.float32)).to(self.device) for im in images]
        for cam, im in zip(self.cameras, self.images, strict=True):
            if tuple(im.shape[:2]) != (cam.height, cam.width):
                raise ValueError(f"image {tuple(im.shape)} does not match camera {cam.width}x{cam.height}")
        self.strategy = strategy or Strategy()
        self.extent = extent if extent is not None else scene_scale(self.cameras)
        self.state = strategy_state if strategy_state is not None else self.strategy.initialize_state(params)
        self.background = torch.tensor(self.config.background, dtype=torch.float32, device=self.device)
        self.step_index = 0
        self._rng = np.random.default_rng(self.config.seed)
        self._order: list[int] = []
        self.optimizers = self._make_optimizers()

    def _make_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        c = self.config
        lrs = {
            "means": c.lr_means * self.extent,
            "log_scales": c.lr_scales,
            "quats": c.lr_quats,
            "opacity_logits": c.lr_opacity,
            "sh_dc": c.lr_sh_dc,
            "sh_rest": c.lr_sh_rest,
        }
        opts = {}
        for name, p in self.params.items():
            train = name in c.trainable and p.numel() > 0
            p.requires_grad_(train)
            if train:
                # fused: one kernel per step instead of a pass per moment (2.2x faster on the CPU at 1.4 M rows)
                fused = p.dtype == torch.float32 and p.device.type in ("cpu", "cuda")
                opts[name] = torch.optim.Adam([p], lr=lrs[name], eps=1e-15, fused=fused or None)
        return opts

    @property
    def active_sh_degree(self) -> int:
        """SH degree in use now: raised by one every ``sh_increase_every`` steps (3DGS warm-up)."""
        available = int(round(math.sqrt(self.params["sh_rest"].shape[1] + 1))) - 1
        every = max(1, self.config.sh_increase_every)
        return min(self.config.sh_degree, available, self.step_index // every)

    def _means_lr(self) -> float:
        c = self.config
        t = min(1.0, self.step_index / max(1, c.iterations))
        start, end = c.lr_means * self.extent, c.lr_means_final * self.extent
        return float(math.exp((1 - t) * math.log(start) + t * math.log(end)))

    def _next_view(self) -> int:
        if not self._order:
            self._order = list(self._rng.permutation(len(self.cameras)))
        return int(self._order.pop())

    def step(self, view: tuple[Camera, torch.Tensor] | None = None) -> FitReport:
        """Run one optimisation iteration on the next view of a shuffled epoch, or on ``view`` (a camera and its
        target image [H, W, 3], e.g. a window of a finer view; the epoch's order is left as it is)."""
        t0 = time.perf_counter()
        if "means" in self.optimizers:
            for g in self.optimizers["means"].param_groups:
                g["lr"] = self._means_lr()
        if view is None:
            idx = self._next_view()
            cam, gt = self.cameras[idx], self.images[idx]
        else:
            cam, gt = view[0], torch.as_tensor(view[1], dtype=torch.float32).to(self.device)
        out = render_params(self.params, cam, sh_degree=self.active_sh_degree, background=self.background,
                            backend=self.config.backend, device=self.device)
        info = StepInfo(self.step_index, cam.width, cam.height, out.means2d, out.radii, out.visible)
        self.strategy.step_pre_backward(self.params, self.optimizers, self.state, info)
        l1 = torch.abs(out.image - gt).mean()
        loss = (1 - self.config.ssim_weight) * l1
        if self.config.ssim_weight > 0:
            loss = loss + self.config.ssim_weight * (1 - ssim(out.image, gt))
        loss.backward()
        for opt in self.optimizers.values():
            opt.step()
            opt.zero_grad(set_to_none=True)
        changes = self.strategy.step_post_backward(self.params, self.optimizers, self.state, info)
        self.step_index += 1
        return FitReport(self.step_index, float(loss.detach()), float(l1.detach()), self.params["means"].shape[0],
                         time.perf_counter() - t0, changes)

    def state_dict(self) -> dict:
        """What a resumed fit needs besides the parameters: the step count, the view order (the shuffle's random
        state and what is left of the current epoch) and every optimiser's moments (copies)."""
        return {"step_index": self.step_index, "rng": self._rng.bit_generator.state,
                "order": [int(i) for i in self._order],
                "optimizers": {k: _on_cpu(o.state_dict()) for k, o in self.optimizers.items()}}

    def load_state_dict(self, state: dict) -> None:
        """Restore ``state_dict()`` into a trainer built over parameters of the same shapes."""
        if set(state["optimizers"]) != set(self.optimizers):
            raise ValueError(f"the saved fit trained {sorted(state['optimizers'])}, this one {sorted(self.optimizers)}")
        self.step_index = int(state["step_index"])
        self._rng.bit_generator.state = state["rng"]
        self._order = [int(i) for i in state["order"]]
        for name, opt in self.optimizers.items():
            opt.load_state_dict(state["optimizers"][name])

    @torch.no_grad()
    def evaluate(self, cameras: Sequence[Camera], images: Sequence[np.ndarray | torch.Tensor]) -> float:
        """Mean PSNR (dB) of renders at the full SH degree against ``images``."""
        values = []
        for cam, im in zip(cameras, images, strict=True):
            out = render_params(self.params, cam, sh_degree=self.config.sh_degree, background=self.background,
                                backend=self.config.backend, device=self.device)
            values.append(psnr(out.image, torch.as_tensor(np.asarray(im, np.float32)).to(self.device)))
        return float(np.mean(values)) if values else float("nan")
