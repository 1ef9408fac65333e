"""The step-wise G-Style engine. One ``Stylizer.step()`` = one unit of work of the current phase.

Phases, in order:
1. ``ground_truth``: one view per step: the scene's photos, or renders of the input scene (with its SH) when it
   has none.
2. ``preprocess``: rounds of flat-Gaussian split followed by a refit (one refit iteration per step) with elongation
   clamps; skipped when the Gaussian sizes are already even or when the preset asks for 0 rounds.
3. ``colour_match``: one step: the affine colour transform mapping the ground truth's RGB mean/covariance onto the
   style's, applied to c_gt to start c_s and to the ground-truth images (content targets). Because a render is linear
   in colours (and the transform affine), transforming every Gaussian's colour transforms every opaque pixel the same
   way, which is what the reference achieves by refitting colours to transformed images.
4. ``stylize``: one view per step: render c_s at the working resolution (colour-only cached path), the style loss,
   Adam on c_s with an exponentially decaying learning rate; ‖∂L/∂c_s‖ is accumulated and at the scheduled steps the
   top ``split_rate`` fraction of Gaussians is split (children inherit c_s), followed by ``refit`` steps that refit
   geometry and c_gt to the ground truth with c_s held.
5. ``finish``: one step: colour-match the stylized renders to the style once more (affine transform of c_s).
Then ``done``. There are no threads here: callers (CLI, app worker, tests) decide when to call ``step()``.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import torch

from ..cameras.camera import Camera
from ..cameras.images import resize_image
from ..fit import ops
from ..fit.model import camera_tensors, params_from_scene, render_params, scene_from_params
from ..fit.strategy import Strategy
from ..fit.trainer import FitConfig, Trainer
from ..raster import ColourCache, ColourCacheStore
from ..scene import GaussianScene, rgb_to_sh_dc, sh_dc_to_rgb
from .preprocess import ElongationClampStrategy, flat_split_mask, size_evenness
from .settings import StylizeSettings

GEOMETRY_AND_GT = ("means", "log_scales", "quats", "opacity_logits", "sh_dc")  # refit: all but c_s
PHASES = ("ground_truth", "preprocess", "colour_match", "stylize", "refit", "finish", "done")


@dataclass
class StepReport:
    """What one step did."""

    phase: str
    step: int
    total_steps: int
    losses: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    gaussians: int = 0
    colours_changed: bool = False
    geometry_changed: bool = False
    done: bool = False
    message: str = ""


def choose_views(cameras: list[Camera], max_views: int) -> list[int]:
    """Indices of at most ``max_views`` cameras, evenly spread over the list."""
    n = len(cameras)
    if n <= max_views:
        return list(range(n))
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, max_views)})


class Stylizer:
    """G-Style on one scene: ``step()`` until ``done``; ``snapshot()`` for viewers; ``state_dict()`` for checkpoints."""

    def __init__(
        self,
        scene: GaussianScene,
        cameras: list[Camera],
        style: np.ndarray,
        settings: StylizeSettings,
        *,
        objective_factory=None,
        photos: list[np.ndarray] | None = None,
    ) -> None:
        if scene.count == 0:
            raise ValueError("the scene has no Gaussians")
        if not cameras:
            raise ValueError("stylization needs at least one camera")
        self.settings = settings
        self.input_scene = scene
        torch.manual_seed(settings.seed)
        self._gen = torch.Generator().manual_seed(settings.seed)
        view_ids = choose_views(list(cameras), settings.max_views)
        self.full_cameras = [cameras[i] for i in view_ids]
        self.photos = [photos[i] for i in view_ids] if photos is not None else None
        self.cameras = [c.resized_to_width(settings.working_width) for c in self.full_cameras]
        self.style = np.asarray(style, np.float32)
        # Stylization keeps only the diffuse colour: geometry + c_gt (sh_dc) in params, c_s apart.
        self.params = params_from_scene(scene.with_sh_degree(0))
        self.c_s = torch.zeros((scene.count, 3))
        self.gt_images: list[torch.Tensor] = []
        self.coverage: list[torch.Tensor] = []  # pixels the scene covers (photos: all); colour statistics use these
        self._input_params = None
        self.content_images: list[torch.Tensor] = []
        self.phase = "ground_truth"
        self.phase_step = 0
        self.global_step = 0
        self.geometry_version = 0
        self.colour_version = 0
        self.decisions: dict[str, Any] = {}
        self.history: list[dict[str, float]] = []
        self.timings: dict[str, float] = {}
        self._objective_factory = objective_factory
        self._objective = None
        self._opt: torch.optim.Adam | None = None
        self._grad_acc = torch.zeros(scene.count)
        self._trainer: Trainer | None = None
        self._refit_left = 0
        self._preprocess_round = 0
        self._stylize_step = 0
        self._caches = ColourCacheStore()
        self._pending: dict[str, float] = {}
        self.colour_transform: tuple[np.ndarray, np.ndarray] | None = None
        n = len(self.cameras)
        self.stylize_steps = max(int(round(settings.epochs * n)), settings.min_steps)
        planned = {int(round(e * n)) for e in settings.split_at_epochs}
        self.split_steps = sorted(k for k in planned if 0 < k < self.stylize_steps)
        if settings.split_rate <= 0:
            self.split_steps = []
        self.accumulate_from = int(round(settings.grad_accumulate_from_epoch * n))

    # ----------------------------------------------------------------- public API
    @property
    def done(self) -> bool:
        """True once every phase has run."""
        return self.phase == "done"

    @property
    def gaussian_count(self) -> int:
        """Current number of Gaussians."""
        return int(self.params["means"].shape[0])

    def total_steps(self) -> int:
        """Planned number of steps in all phases (grows if splits are added)."""
        s = self.settings
        n = len(self.cameras)
        pre = self._preprocess_rounds_planned() * (s.refit_iterations + 1)
        return n + pre + 1 + self.stylize_steps + len(self.split_steps) * (s.refit_iterations + 1) + 1

    def set_params(self, **kw: float) -> None:
        """Change λ weights (lambda_clip, lambda_nnfm, lambda_content, lambda_tv), split_rate or lr; next step on."""
        unknown = set(kw) - {"split_rate", "lr"} - {f"lambda_{k}" for k in ("clip", "nnfm", "content", "tv")}
        if unknown:
            raise ValueError(f"unknown parameters: {', '.join(sorted(unknown))}")
        weights = {k[len("lambda_"):]: float(v) for k, v in kw.items() if k.startswith("lambda_") and v is not None}
        if weights:
            self.settings.weights = replace(self.settings.weights, **weights)
            if self._objective is not None:
                self._objective.set_weights(self.settings.weights)
        if kw.get("split_rate") is not None:
            self.settings.split_rate = float(kw["split_rate"])
        if kw.get("lr") is not None:
            ratio = self.settings.lr_end / self.settings.lr_start
            self.settings.lr_start = float(kw["lr"])
            self.settings.lr_end = float(kw["lr"]) * ratio

    def current_params(self) -> dict[str, float]:
        """The values ``set_params`` accepts, as they are now (for UIs to show)."""
        w = self.settings.weights
        return {"lambda_clip": w.clip, "lambda_nnfm": w.nnfm, "lambda_content": w.content, "lambda_tv": w.tv,
                "split_rate": self.settings.split_rate, "lr": self.settings.lr_start}

    def snapshot(self) -> dict[str, Any]:
        """Arrays a viewer needs (numpy copies): geometry, stylized and ground-truth colours, versions."""
        p = self.params
        colors = self.c_s if self.phase in ("stylize", "refit", "finish", "done") else self._gt_rgb()
        return {
            "means": p["means"].detach().numpy().copy(),
            "log_scales": p["log_scales"].detach().numpy().copy(),
            "quats": p["quats"].detach().numpy().copy(),
            "opacity_logits": p["opacity_logits"].detach().numpy().copy(),
            "colors": colors.detach().clamp(0, 1).numpy().copy(),
            "colors_gt": self._gt_rgb().detach().clamp(0, 1).numpy().copy(),
            "geometry_version": self.geometry_version,
            "colour_version": self.colour_version,
            "phase": self.phase,
        }

    def stylized_scene(self) -> GaussianScene:
        """The current scene with c_s as its (SH degree 0) colour."""
        scene = scene_from_params(self.params)
        scene.sh_dc = rgb_to_sh_dc(self.c_s.detach().clamp(0, 1).numpy())
        return scene

    def step(self) -> StepReport:
        """Advance by one step of the current phase."""
        t0 = time.perf_counter()
        phase = self.phase
        handler = getattr(self, f"_step_{phase}", None)
        if handler is None:
            return StepReport("done", self.global_step, self.total_steps(), gaussians=self.gaussian_count, done=True)
        rep = handler()
        rep.seconds = time.perf_counter() - t0
        self.timings[phase] = self.timings.get(phase, 0.0) + rep.seconds
        self.global_step += 1
        rep.step = self.global_step
        rep.total_steps = self.total_steps()
        rep.gaussians = self.gaussian_count
        rep.done = self.done
        if rep.geometry_changed:
            self.geometry_version += 1
            self._caches.invalidate()
        if rep.colours_changed:
            self.colour_version += 1
        if rep.losses:
            self.history.append({"step": self.global_step, **rep.losses})
        return rep

    def run(self, callback=None) -> None:
        """Step until done, calling ``callback(report)`` after each step."""
        while not self.done:
            rep = self.step()
            if callback is not None:
                callback(rep)

    # ----------------------------------------------------------------- phases
    def _gt_rgb(self) -> torch.Tensor:
        return torch.as_tensor(sh_dc_to_rgb(self.params["sh_dc"].detach().numpy()))

    def _enter(self, phase: str) -> None:
        self.phase = phase
        self.phase_step = 0

    def _step_ground_truth(self) -> StepReport:
        i = len(self.gt_images)
        cam = self.cameras[i]
        if self.photos is not None:
            photo = np.clip(np.asarray(self.photos[i], np.float32), 0, 1)
            gt = torch.as_tensor(resize_image(photo, (cam.width, cam.height)))
            covered = torch.ones(gt.shape[:2], dtype=torch.bool)
        else:
            if self._input_params is None:
                self._input_params = params_from_scene(self.input_scene, requires_grad=False)
            with torch.no_grad():
                out = render_params(self._input_params, cam, sh_degree=self.input_scene.sh_degree)
            gt = out.image.clamp(0, 1)
            covered = out.alpha > 0.5
        self.gt_images.append(gt)
        self.coverage.append(covered)
        msg = f"ground truth {i + 1}/{len(self.cameras)} ({'photo' if self.photos is not None else 'render'})"
        if len(self.gt_images) == len(self.cameras):
            self._input_params = None
            self._start_preprocess()
        return StepReport("ground_truth", 0, 0, message=msg)

    def _preprocess_rounds_planned(self) -> int:
        return int(self.decisions.get("preprocess_rounds", self.settings.preprocess_rounds))

    def _start_preprocess(self) -> None:
        s = self.settings
        crit = size_evenness(self.params["log_scales"], s.preprocess_gamma)
        self.decisions["size_evenness"] = {k: round(v, 4) for k, v in crit.items()}
        rounds = s.preprocess_rounds
        # Sizes already even: no flat outliers and few elongated Gaussians (the paper: well-reconstructed scenes may
        # skip pre-processing).
        if rounds > 0 and crit["flat_fraction"] < 0.001 and crit["elongated_fraction"] < 0.01:
            self.decisions["preprocess"] = "skipped: Gaussian sizes already even"
            rounds = 0
        else:
            self.decisions["preprocess"] = f"{rounds} round(s)" if rounds else "off (preset)"
        self.decisions["preprocess_rounds"] = rounds
        self._preprocess_round = 0
        if rounds == 0:
            self._enter("colour_match")
        else:
            self._enter("preprocess")

    def _make_trainer(self, strategy: Strategy, trainable: tuple[str, ...]) -> Trainer:
        cfg = FitConfig(iterations=self.settings.refit_iterations, sh_degree=0, sh_increase_every=10**9,
                        trainable=trainable, seed=self.settings.seed + self.global_step)
        return Trainer(self.params, self.cameras, self.gt_images, cfg, strategy, strategy_state={"extras": {}})

    def _split(self, mask: torch.Tensor, children: int, divisor: float) -> int:
        extras = {"c_s": self.c_s, "grad_acc": self._grad_acc}
        limit = self.settings.max_gaussians - self.gaussian_count
        n_sel = int(mask.sum())
        if n_sel * (children - 1) > limit:
            keep = max(0, limit // max(1, children - 1))
            idx = torch.where(mask)[0][:keep]
            mask = torch.zeros_like(mask)
            mask[idx] = True
            self.decisions.setdefault("reductions", []).append(
                f"split reduced from {n_sel} to {keep} Gaussians by the cap of {self.settings.max_gaussians}")
        ops.split(self.params, {}, extras, mask, n_children=children, scale_divisor=divisor, generator=self._gen)
        self.c_s = extras["c_s"]
        self._grad_acc = extras["grad_acc"]
        return int(mask.sum())

    def _step_preprocess(self) -> StepReport:
        s = self.settings
        changed_geometry = True
        msg = ""
        if self._trainer is None:
            gamma = s.preprocess_gamma * s.preprocess_gamma_growth**self._preprocess_round
            mask = flat_split_mask(self.params["log_scales"], gamma, s.preprocess_cap)
            n = self._split(mask, s.preprocess_children, s.preprocess_scale_divisor)
            it = s.refit_iterations
            clamp_at = tuple(sorted({max(1, it // 4), max(1, it // 2), max(1, 3 * it // 4), it}))
            strategy = ElongationClampStrategy(clamp_at=clamp_at, limit=s.elongation_limit)
            self._trainer = self._make_trainer(strategy, GEOMETRY_AND_GT)
            self._refit_left = it
            msg = f"pre-processing round {self._preprocess_round + 1}: split {n} flat Gaussians (γ={gamma:.3f})"
            losses = {}
        else:
            rep = self._trainer.step()
            self._refit_left -= 1
            losses = {"refit": rep.loss}
        if self._trainer is not None and self._refit_left <= 0:
            self._trainer = None
            self._preprocess_round += 1
            if self._preprocess_round >= self._preprocess_rounds_planned():
                self._enter("colour_match")
        return StepReport("preprocess", 0, 0, losses=losses, geometry_changed=changed_geometry, message=msg)

    def _step_colour_match(self) -> StepReport:
        from ..style.colour_match import apply_colour_transform, colour_transfer_matrix

        gt_pixels = torch.cat([g[m] for g, m in zip(self.gt_images, self.coverage, strict=True)]).numpy()
        if len(gt_pixels) < 2:  # the scene covers no pixel: use whole frames
            gt_pixels = torch.cat([g.reshape(-1, 3) for g in self.gt_images]).numpy()
        style_pixels = self.style.reshape(-1, 3)
        A, b = colour_transfer_matrix(gt_pixels, style_pixels)
        self.colour_transform = (A, b)
        c_gt = self._gt_rgb().numpy()
        self.c_s = torch.as_tensor(apply_colour_transform(c_gt, A, b), dtype=torch.float32)
        self.content_images = [
            torch.as_tensor(apply_colour_transform(g.reshape(-1, 3).numpy(), A, b), dtype=torch.float32).reshape(
                g.shape)
            for g in self.gt_images
        ]
        self._grad_acc = torch.zeros(self.gaussian_count)
        self._enter("stylize")
        return StepReport("colour_match", 0, 0, colours_changed=True, message="colours matched to the style")

    def _objective_fn(self):
        if self._objective is None:
            if self._objective_factory is None:
                from .objective import StyleObjective

                self._objective = StyleObjective(self.style, self.settings)
            else:
                self._objective = self._objective_factory(self.style, self.settings)
            self.decisions["clip"] = getattr(self._objective, "clip_status", "n/a")
        return self._objective

    def _lr(self) -> float:
        s = self.settings
        t = min(1.0, self._stylize_step / max(1, self.stylize_steps))
        return float(math.exp((1 - t) * math.log(s.lr_start) + t * math.log(s.lr_end)))

    def _build_cache(self, view: int) -> ColourCache:
        p, cam = self.params, self.cameras[view]
        viewmat, K = camera_tensors(cam)
        return ColourCache(p["means"].detach(), p["quats"].detach(), torch.exp(p["log_scales"].detach()),
                           torch.sigmoid(p["opacity_logits"].detach()), viewmat, K, cam.width, cam.height,
                           geometry_version=self.geometry_version)

    def _render_cs(self, view: int) -> torch.Tensor:
        cache = self._caches.get_or_build(view, self.geometry_version, lambda: self._build_cache(view))
        return cache.render(self.c_s)

    def _step_stylize(self) -> StepReport:
        s = self.settings
        if self._stylize_step in self.split_steps and s.split_rate > 0:
            return self._do_colour_split()
        if self._opt is None:
            self.c_s = self.c_s.detach().requires_grad_(True)
            self._opt = torch.optim.Adam([self.c_s], lr=self._lr())
        for g in self._opt.param_groups:
            g["lr"] = self._lr()
        view = self._stylize_step % len(self.cameras)
        image = self._render_cs(view)
        total, terms = self._objective_fn()(image, self.content_images[view], view)
        self._opt.zero_grad(set_to_none=True)
        total.backward()
        if self._stylize_step >= self.accumulate_from and self.c_s.grad is not None:
            self._grad_acc += self.c_s.grad.detach().norm(dim=-1)
        self._opt.step()
        with torch.no_grad():
            self.c_s.clamp_(0.0, 1.0)
        self._stylize_step += 1
        self.phase_step += 1
        if self._stylize_step >= self.stylize_steps:
            self._opt = None
            self.c_s = self.c_s.detach()
            self._enter("finish" if s.colour_match_after else "done")
        return StepReport("stylize", 0, 0, losses={"total": float(total.detach()), **terms}, colours_changed=True,
                          message=f"stylize view {view}")

    def _do_colour_split(self) -> StepReport:
        s = self.settings
        self.split_steps.remove(self._stylize_step)
        n = self.gaussian_count
        k = int(math.floor(s.split_rate * n))
        mask = torch.zeros(n, dtype=torch.bool)
        if k > 0:
            mask[torch.topk(self._grad_acc, k).indices] = True
        self.c_s = self.c_s.detach()
        count = self._split(mask, s.split_children, s.split_scale_divisor)
        self._grad_acc = torch.zeros(self.gaussian_count)
        self._opt = None
        self._trainer = self._make_trainer(Strategy(), GEOMETRY_AND_GT)
        self._refit_left = s.refit_iterations
        self._enter("refit" if self._refit_left > 0 else "stylize")
        return StepReport("stylize", 0, 0, geometry_changed=True, colours_changed=True,
                          message=f"split {count} Gaussians with the largest colour gradient")

    def _step_refit(self) -> StepReport:
        rep = self._trainer.step()
        self._refit_left -= 1
        if self._refit_left <= 0:
            self._trainer = None
            self._enter("stylize")
            self.phase_step = 1
        return StepReport("refit", 0, 0, losses={"refit": rep.loss}, geometry_changed=True)

    @torch.no_grad()
    def _step_finish(self) -> StepReport:
        from ..style.colour_match import apply_colour_transform, colour_transfer_matrix

        pixels = []
        for v in range(len(self.cameras)):
            image = self._render_cs(v)
            covered = self._caches.get(v, self.geometry_version).t_final < 0.5
            pixels.append(image[covered])
        covered_pixels = torch.cat(pixels).numpy()
        if len(covered_pixels) < 2:
            covered_pixels = torch.cat([self._render_cs(v).reshape(-1, 3) for v in range(len(self.cameras))]).numpy()
        A, b = colour_transfer_matrix(covered_pixels, self.style.reshape(-1, 3))
        self.c_s = torch.as_tensor(apply_colour_transform(self.c_s.numpy(), A, b), dtype=torch.float32)
        self._enter("done")
        return StepReport("finish", 0, 0, colours_changed=True, message="final colour match to the style")

    # ----------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict[str, Any]:
        """Everything needed to resume (not the optimiser moments of an interrupted refit)."""
        return {
            "params": {k: v.detach().clone() for k, v in self.params.items()},
            "c_s": self.c_s.detach().clone(),
            "grad_acc": self._grad_acc.clone(),
            "gt_images": [g.clone() for g in self.gt_images],
            "coverage": [m.clone() for m in self.coverage],
            "content_images": [g.clone() for g in self.content_images],
            "phase": self.phase,
            "phase_step": self.phase_step,
            "global_step": self.global_step,
            "stylize_step": self._stylize_step,
            "split_steps": list(self.split_steps),
            "preprocess_round": self._preprocess_round,
            "refit_left": self._refit_left,
            "in_refit": self._trainer is not None,
            "decisions": dict(self.decisions),
            "history": list(self.history),
            "timings": dict(self.timings),
            "settings": self.settings.to_dict(),
            "geometry_version": self.geometry_version,
            "colour_version": self.colour_version,
            "colour_transform": self.colour_transform,
            "adam": copy.deepcopy(self._opt.state_dict()) if self._opt is not None else None,
            "generator": self._gen.get_state(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore from ``state_dict()``; an interrupted refit restarts its remaining iterations with fresh Adam."""
        self.params = torch.nn.ParameterDict({k: torch.nn.Parameter(v.clone()) for k, v in state["params"].items()})
        self.c_s = state["c_s"].clone()
        self._grad_acc = state["grad_acc"].clone()
        self.gt_images = [g.clone() for g in state["gt_images"]]
        self.coverage = [m.clone() for m in state["coverage"]]
        self.content_images = [g.clone() for g in state["content_images"]]
        self.phase = state["phase"]
        self.phase_step = state["phase_step"]
        self.global_step = state["global_step"]
        self._stylize_step = state["stylize_step"]
        self.split_steps = list(state["split_steps"])
        self._preprocess_round = state["preprocess_round"]
        self.decisions = dict(state["decisions"])
        self.history = list(state["history"])
        self.timings = dict(state["timings"])
        self.geometry_version = state["geometry_version"] + 1
        self.colour_version = state["colour_version"] + 1
        self.colour_transform = state["colour_transform"]
        self._caches.invalidate()
        self._gen.set_state(state["generator"])
        self._opt = None
        if state.get("adam") is not None:
            self.c_s = self.c_s.detach().requires_grad_(True)
            self._opt = torch.optim.Adam([self.c_s], lr=self._lr())
            self._opt.load_state_dict(state["adam"])
        self._trainer = None
        self._refit_left = state["refit_left"]
        if state["in_refit"] and self._refit_left > 0:
            strategy = Strategy() if self.phase == "refit" else ElongationClampStrategy()
            self._trainer = self._make_trainer(strategy, GEOMETRY_AND_GT)
