"""What the phases of a run share: the scene being stylized, its targets, the active set and the run's records.

Stylization keeps only the diffuse colour: geometry and the ground-truth colour c_gt (``sh_dc``) are ``params``,
the stylized colour c_s is apart. ``geometry_version`` / ``colour_version`` count changes (viewers re-upload on a new
version; the colour caches are per geometry version). The objective is built on first use (``objective_fn``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from ..cameras.camera import Camera
from ..device import describe as describe_device
from ..device import resolve_device
from ..fit import ops
from ..fit.model import camera_tensors, params_from_scene
from ..raster import ColourCache, ColourCacheStore
from ..raster.gsplat_backend import GsplatColourCache
from ..scene import GaussianScene, sh_dc_to_rgb, used_sh_degree
from ..style.colour_match import Palette
from .active import ActiveSet
from .notes import note_loss_terms, note_networks, note_style
from .settings import StylizeSettings

COUNTERS = ("visibility_passes", "cache_builds", "cache_gaussians", "optimised_colours", "refit_gaussians",
            "field_cells")


def objective_generator(objective: Any) -> torch.Generator | None:
    """The random generator of an objective's CLIP term (random crops), if it has one (checkpoints keep its state)."""
    gen = getattr(getattr(getattr(objective, "loss", None), "clip_term", None), "generator", None)
    return gen if isinstance(gen, torch.Generator) else None


class RunState:
    """The state the phases read and write; ``state_dict()`` holds all of it that later steps read."""

    def __init__(self, scene: GaussianScene, full_cameras: list[Camera], photos: list[np.ndarray] | None,
                 styles: Sequence[np.ndarray], settings: StylizeSettings, *,
                 objective_factory: Callable | None = None, selection: np.ndarray | None = None) -> None:
        self.settings = settings
        self.device_choice = resolve_device(settings.device)  # the style networks' device (device.py)
        self.raster_device = self.device_choice.raster_device
        self.input_scene = scene
        self.truth_scene = scene  # what the ground truth renders: the whole capture where the run holds a cut of it
        self.lineage: torch.Tensor | None = None  # a run on a level-of-detail cut: each row's parent (lod_run.py)
        self.lod_merged: torch.Tensor | None = None  # ... and which of its parents merge several input Gaussians
        self.full_cameras = full_cameras
        self.photos = photos
        self.cameras = [c.resized_to_width(settings.working_width) for c in full_cameras]
        self.styles = list(styles)
        self.palettes = [Palette.of(s) for s in self.styles]
        self.params = params_from_scene(scene.with_sh_degree(0))
        self.c_s = torch.zeros((scene.count, 3))
        self.grad_acc = torch.zeros(scene.count)  # ‖∂L/∂c_s‖ accumulated for the colour-gradient split
        self.gt_images: list[torch.Tensor] = []
        self.coverage: list[torch.Tensor] = []  # alpha of each ground-truth view (photos: 1)
        self.region_coverage: list[torch.Tensor] = []  # the selected Gaussians' weight in each view (region runs)
        self.content_images: list[torch.Tensor] = []  # colour-matched ground truth (content targets)
        self.colour_transform: tuple[np.ndarray, np.ndarray] | None = None
        self.gt_sh_degree = used_sh_degree(scene.sh_rest)
        self.geometry_version = 0
        self.colour_version = 0
        self.global_step = 0
        self.decisions: dict[str, Any] = {"device": describe_device(self.device_choice)}
        # Work done, for tests and the trade-off bench: visibility passes, colour caches built and the Gaussians in
        # them, colours given gradients (per optimiser), Gaussians in refits (per refit), cells of the colour field
        # (per field).
        self.counters = dict.fromkeys(COUNTERS, 0)
        self.history: list[dict[str, float]] = []
        self.timings: dict[str, float] = {}
        self.generator = torch.Generator().manual_seed(settings.seed)  # split positions
        self.caches = ColourCacheStore()
        self.active = ActiveSet(self, selection)
        self.max_gaussians = 0
        self.reduction_note = ""  # a split cut back by max_gaussians (reported with the step)
        self._objective_factory = objective_factory
        self._objective: Any = None
        self.level_objectives: dict[tuple[int, tuple[str, ...] | None], Any] = {}  # finer levels' (level_objective)
        self._objective_rng: torch.Tensor | None = None  # a resumed run's CLIP crops, for an objective built later
        self._level_rngs: dict[tuple, torch.Tensor] = {}  # the same for the finer levels' objectives

    # ------------------------------------------------------------------------------------------------ basics
    @property
    def gaussian_count(self) -> int:
        """Current number of Gaussians."""
        return int(self.params["means"].shape[0])

    def geometry_key(self) -> tuple[int, int]:
        """(geometry version, Gaussian count): what the active set and colour caches are valid for."""
        return self.geometry_version, self.gaussian_count

    def aggregate_rows(self) -> torch.Tensor | None:
        """Bool over the rows: descendants of a level-of-detail parent that merges several input Gaussians (None:
        no cut). The pre-processing does not split them: their input Gaussians are the finer detail."""
        return None if self.lineage is None or self.lod_merged is None else self.lod_merged[self.lineage]

    def gt_rgb(self) -> torch.Tensor:
        """c_gt, the ground-truth diffuse colour of every Gaussian, as RGB [N, 3]."""
        return torch.as_tensor(sh_dc_to_rgb(self.params["sh_dc"].detach().numpy()))

    def style_input(self) -> np.ndarray | list[np.ndarray]:
        """What objectives are built from: the painting, or the list of paintings of a mix."""
        return self.styles[0] if len(self.styles) == 1 else list(self.styles)

    # ------------------------------------------------------------------------------------------------ objective
    @property
    def objective(self) -> Any:
        """The objective if it was built (the first stylization step builds it), else None."""
        return self._objective

    def objective_fn(self) -> Any:
        """The objective, built now if it was not yet (networks loaded, the style's features extracted)."""
        if self._objective is None:
            if self._objective_factory is None:
                from .objective import StyleObjective

                self._objective = StyleObjective(self.style_input(), self.settings)
            else:
                self._objective = self._objective_factory(self.style_input(), self.settings)
            note_networks(self.decisions, self._objective)
            note_style(self.decisions, self.settings, self._objective, len(self.styles))
            gen = objective_generator(self._objective)
            if gen is not None and self._objective_rng is not None:  # resumed: CLIP crops go on where they were
                gen.set_state(self._objective_rng)
            note_loss_terms(self.decisions, self.settings, self._objective)
        return self._objective

    def level_objective(self, width: int, terms: tuple[str, ...] | None) -> Any:
        """The objective of a finer level (``phases/refine.py``): the painting matched for renders ``width`` px wide,
        computing only ``terms`` (None: all), on the run objective's network; built once per (width, terms)."""
        key = (int(width), terms)
        if key not in self.level_objectives:
            base = self.objective_fn()
            if self._objective_factory is None:
                from .objective import StyleObjective

                self.level_objectives[key] = StyleObjective(self.style_input(), self.settings, vgg=base.vgg,
                                                            width=width, terms=terms)
            else:  # test objectives know no widths
                self.level_objectives[key] = self._objective_factory(self.style_input(), self.settings)
            gen = objective_generator(self.level_objectives[key])
            if gen is not None and key in self._level_rngs:  # resumed: its random crops go on where they were
                gen.set_state(self._level_rngs.pop(key))
        return self.level_objectives[key]

    def objectives(self) -> list[Any]:
        """Every objective built so far: the run's, then the finer levels' (live controls reach all of them)."""
        return ([] if self._objective is None else [self._objective]) + list(self.level_objectives.values())

    def objective_coverage(self, view: int) -> torch.Tensor | None:
        """The scene's coverage of a training view as the objective gets it: None for photos (they are all scene).
        A region run: the selected Gaussians' weight (photos too), so the losses see only the selected part."""
        if self.region_coverage:
            return self.region_coverage[view]
        return None if self.photos is not None else self.coverage[view]

    def match_coverage(self) -> list[torch.Tensor]:
        """What the colour matches count as the scene in each view: its coverage, or the region's."""
        return self.region_coverage if self.region_coverage else self.coverage

    # ------------------------------------------------------------------------------------------------ renders
    def cache(self, view: int) -> ColourCache | GsplatColourCache:
        """The colour cache of a training view over the seen Gaussians (columns in ``active.seen_ids()`` order)."""
        return self.caches.get_or_build(view, self.geometry_version, lambda: self._build_cache(view))

    def _build_cache(self, view: int) -> ColourCache:
        return self.build_cache(self.cameras[view])

    def build_cache(self, cam: Camera) -> ColourCache | GsplatColourCache:
        """A colour cache of any camera (a finer level's view or crop) over the seen Gaussians, not stored (on CUDA
        gsplat's: its renders are on the GPU)."""
        p = {k: self.active.gather_seen(self.params[k].detach())
             for k in ("means", "quats", "log_scales", "opacity_logits")}
        viewmat, K = camera_tensors(cam)
        self.counters["cache_builds"] += 1
        self.counters["cache_gaussians"] += int(p["means"].shape[0])
        kind = GsplatColourCache if self.raster_device.type == "cuda" else ColourCache
        extra = {"device": self.raster_device} if kind is GsplatColourCache else {}
        return kind(p["means"], p["quats"], torch.exp(p["log_scales"]), torch.sigmoid(p["opacity_logits"]),
                    viewmat, K, cam.width, cam.height, geometry_version=self.geometry_version, **extra)

    def render_seen(self, view: int, colours: torch.Tensor) -> torch.Tensor:
        """Render ``colours`` of the seen Gaussians (one row per cache column) from a training view (on the
        rasterizer's device: the objective takes it there)."""
        return self.cache(view).render(colours)

    def render(self, view: int, colours: torch.Tensor | None = None) -> torch.Tensor:
        """Render c_s (or ``colours`` [N, 3] of every Gaussian) from a training view through its colour cache; the
        image is on the CPU (differentiable all the same)."""
        return self.render_seen(view, self.active.gather_seen(self.c_s if colours is None else colours)).cpu()

    @torch.no_grad()
    def selected_weight(self, view: int) -> torch.Tensor:
        """[H, W]: how much of each pixel of a training view the selected Gaussians make (their rendered weight, in
        front of or behind the others as they are): the region's coverage."""
        indicator = self.active.selected.to(torch.float32)[:, None].expand(-1, 3).contiguous()
        return self.render(view, indicator)[..., 0].clamp(0.0, 1.0)

    # ------------------------------------------------------------------------------------------------ edits
    def split(self, mask: torch.Tensor, children: int, divisor: float, priority: torch.Tensor | None = None) -> int:
        """Split the ``mask`` Gaussians (c_s, the gradient and a region's rows follow), each child drawn inside its
        parent's footprint (``ops.child_offset_limit``); past ``max_gaussians`` the lowest-``priority`` candidates are
        dropped. Returns how many were split."""
        extras = {"c_s": self.c_s, "grad_acc": self.grad_acc, **self.active.split_extras()}
        if self.lineage is not None:
            extras["lineage"] = self.lineage
        limit = max(0, self.max_gaussians - self.gaussian_count)
        n_sel = int(mask.sum())
        if n_sel * (children - 1) > limit:
            keep = min(n_sel, limit // max(1, children - 1))
            idx = torch.where(mask)[0]
            if priority is not None and keep > 0:
                idx = idx[torch.topk(priority.detach()[idx].double(), keep).indices]
            mask = torch.zeros_like(mask)
            mask[idx[:keep]] = True
            self.reduction_note = (f"split reduced from {n_sel:,} to {keep:,} Gaussians by the cap of "
                                   f"{self.max_gaussians:,}")
            self.decisions.setdefault("reductions", []).append(f"step {self.global_step + 1}: {self.reduction_note}")
        ops.split(self.params, {}, extras, mask, n_children=children, scale_divisor=divisor, generator=self.generator,
                  max_offset=ops.child_offset_limit(divisor))  # children inside their parent: the scene never grows
        self.c_s, self.grad_acc = extras["c_s"], extras["grad_acc"]
        self.lineage = extras.get("lineage")
        self.active.take_split_extras(extras)
        return int(mask.sum())

    @torch.no_grad()
    def restore_chroma(self) -> None:
        """Keep colours: every (selected) Gaussian's c_s takes the chroma of its c_gt back (its luminance stays)."""
        from ..style.keep_colours import with_chroma_of

        c_gt = self.gt_rgb().to(self.c_s.dtype)
        self.c_s = self.active.keep_unselected(with_chroma_of(self.c_s.detach(), c_gt), self.c_s)

    # ------------------------------------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, Any]:
        """Tensors, targets, records and random states (copies)."""
        gen = objective_generator(self._objective)
        return {
            "params": {k: v.detach().clone() for k, v in self.params.items()},
            "c_s": self.c_s.detach().clone(),
            "grad_acc": self.grad_acc.clone(),
            "gt_images": [g.clone() for g in self.gt_images],
            "coverage": [m.clone() for m in self.coverage],
            "region_coverage": [m.clone() for m in self.region_coverage],
            "content_images": [g.clone() for g in self.content_images],
            "colour_transform": self.colour_transform,
            "geometry_version": self.geometry_version,
            "colour_version": self.colour_version,
            "global_step": self.global_step,
            "decisions": dict(self.decisions),
            "history": list(self.history),
            "timings": dict(self.timings),
            "generator": self.generator.get_state(),
            "objective_rng": gen.get_state() if gen is not None else self._objective_rng,
            "level_rngs": {**self._level_rngs, **{key: objective_generator(o).get_state()
                                                  for key, o in self.level_objectives.items()
                                                  if objective_generator(o) is not None}},
            "active": self.active.state_dict(),
            "lineage": None if self.lineage is None else self.lineage.clone(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore ``state_dict()``. Versions count on past the saved ones (viewers upload everything again)."""
        self.active.load_state_dict(state["active"])
        if (state.get("lineage") is None) != (self.lineage is None):
            raise ValueError("the checkpoint and this run differ in the level of detail (--lod on / off)")
        if self.lineage is not None:
            self.lineage = torch.as_tensor(state["lineage"]).to(torch.long).clone()
        self.params = torch.nn.ParameterDict({k: torch.nn.Parameter(v.clone()) for k, v in state["params"].items()})
        self.c_s = state["c_s"].clone()
        self.grad_acc = state["grad_acc"].clone()
        self.gt_images = [g.clone() for g in state["gt_images"]]
        self.coverage = [m.clone() for m in state["coverage"]]
        self.region_coverage = [m.clone() for m in state["region_coverage"]]
        self.content_images = [g.clone() for g in state["content_images"]]
        self.colour_transform = state["colour_transform"]
        self.geometry_version = state["geometry_version"] + 1
        self.colour_version = state["colour_version"] + 1
        self.global_step = state["global_step"]
        self.decisions = dict(state["decisions"])
        self.history = list(state["history"])
        self.timings = dict(state["timings"])
        self.generator.set_state(state["generator"])
        self._objective_rng = state["objective_rng"]
        self._level_rngs = dict(state.get("level_rngs") or {})
        for key, objective in self.level_objectives.items():
            gen = objective_generator(objective)
            if gen is not None and key in self._level_rngs:
                gen.set_state(self._level_rngs.pop(key))
        gen = objective_generator(self._objective)
        if gen is not None and self._objective_rng is not None:
            gen.set_state(self._objective_rng)
        self.caches.invalidate()
