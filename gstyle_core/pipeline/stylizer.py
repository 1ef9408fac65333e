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
   geometry and c_gt to the ground truth with c_s held. Gaussians that no training camera sees (``cull_unseen``)
   take no part: they are left out of the colour caches, the optimiser, the split ranking and the refits. Without
   photos the objective gets each view's coverage: the losses count the scene, not the empty background, and VGG
   sees only the scene's box (``crop_to_scene``, ``scene_box.py``).
5. ``finish``: one step: colour-match the stylized renders to the style once more (affine transform of c_s).
Then ``done``. There are no threads here: callers (CLI, app worker, tests) decide when to call ``step()``.

Keep colours (``settings.keep_colours``, ``style/keep_colours.py``): the colour matches (3 and 5) map only the
luminance mean/std onto the painting's, the networks see luminance only, and after every optimiser step each
Gaussian's c_s takes the chroma of its c_gt back (its luminance stays): the scene keeps its hues and takes the
painting's luminance pattern. Turned on mid-run, c_s takes c_gt's chroma at once and the content targets are
matched again; turned off, c_s keeps its colours and from then on the painting's colours are matched again (the
finish colour-matches them fully). Stroke size (``settings.style_scale``): the painting is matched at that × the
working width; changed mid-run, its features are extracted again before the next step (``objective.py``).
Several paintings (``style`` a list, ``settings.style_weights``, ``style/mix.py``): every style term is the weighted
sum of its terms against each painting and the colour matches map onto the weighted palette; a mix changed mid-run
(``set_params(style_mix=...)``) re-matches the content targets and re-weights the terms from the next step.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
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
from ..scene import GaussianScene, rgb_to_sh_dc, sh_dc_to_rgb, used_sh_degree
from ..style.clip import CLIP_OFF, clip_status, clip_term_name
from ..style.colour_match import Palette
from ..style.mix import normalise_style_weights, weights_with_mix
from .preprocess import ElongationClampStrategy, evenness_verdict, flat_split_mask, size_evenness
from .region import region_note, selection_mask
from .scene_box import SCENE_BOX_MARGIN_PX, box_fraction, scene_box
from .settings import StylizeSettings, ui_params
from .visibility import culling_note, seen_mask

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


def objective_generator(objective) -> torch.Generator | None:
    """The random generator of an objective's CLIP term (random crops), if it has one (checkpoints keep its state)."""
    gen = getattr(getattr(getattr(objective, "loss", None), "clip_term", None), "generator", None)
    return gen if isinstance(gen, torch.Generator) else None


def _row_mask_hook(free: torch.Tensor):
    """A gradient hook that zeroes the rows not in ``free`` (bool [N]): Adam never moves them."""
    def hook(grad: torch.Tensor) -> torch.Tensor:
        return grad * free.reshape((-1,) + (1,) * (grad.ndim - 1)).to(grad.dtype)
    return hook


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
        style: np.ndarray | Sequence[np.ndarray],
        settings: StylizeSettings,
        *,
        objective_factory=None,
        photos: list[np.ndarray] | None = None,
        selection: np.ndarray | None = None,
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
        # one painting, or several mixed with settings.style_weights (style/mix.py)
        self.styles = [np.asarray(s, np.float32) for s in ([style] if isinstance(style, np.ndarray) else style)]
        settings.style_weights = normalise_style_weights(settings.style_weights, len(self.styles))
        self.style = self.styles[0]
        self._palettes = [Palette.of(s) for s in self.styles]
        # Stylization keeps only the diffuse colour: geometry + c_gt (sh_dc) in params, c_s apart.
        self.params = params_from_scene(scene.with_sh_degree(0))
        self.c_s = torch.zeros((scene.count, 3))
        self.gt_images: list[torch.Tensor] = []
        self.coverage: list[torch.Tensor] = []  # alpha of each ground-truth view (photos: 1); see _step_colour_match
        self._input_params = None
        self.content_images: list[torch.Tensor] = []
        self.phase = "ground_truth"
        self.phase_step = 0
        self.global_step = 0
        self.geometry_version = 0
        self.colour_version = 0
        self.decisions: dict[str, Any] = {}
        # Work done, for tests and the trade-off bench: visibility passes, colour caches built and the Gaussians in
        # them, colours given gradients (per optimiser), Gaussians in refits (per refit).
        self.counters = dict.fromkeys(("visibility_passes", "cache_builds", "cache_gaussians", "optimised_colours",
                                       "refit_gaussians"), 0)
        self._seen_key: tuple[int, int] | None = None
        self._seen_ids: torch.Tensor | None = None  # Gaussians some training camera sees (None: all)
        self._c_opt: torch.Tensor | None = None  # the optimised c_s rows (the seen ones) during stylization
        self._trainer_ids: torch.Tensor | None = None  # the Gaussians the running refit works on (None: all)
        self._frozen = None  # region runs: (rows of the refit's copy that must not move, their values)
        self._gt_sh_degree = used_sh_degree(scene.sh_rest)
        # A selected region (settings.region and/or a ``selection`` mask, region.py): only these Gaussians are
        # pre-processed, split, refitted and stylized; ``_origin`` maps each current Gaussian to its input row.
        mask = selection_mask(scene.means, settings.region, selection)
        self.input_selection = mask  # over the input's Gaussians (None: all); in the checkpoint fingerprint
        self._selected = None if mask is None else torch.as_tensor(mask, dtype=torch.bool)
        self._origin = None if mask is None else torch.arange(scene.count)
        self.region_coverage: list[torch.Tensor] = []  # the selected Gaussians' weight in each view (region runs)
        self._active_key: tuple[int, int] | None = None
        self._active_cache: tuple[torch.Tensor, torch.Tensor] | None = None  # region runs: see _refresh_active
        if mask is not None:
            self.decisions["region"] = region_note(settings.region, int(mask.sum()), scene.count)
        self.decisions["sh"] = self._sh_note(scene.sh_degree)
        self.clip_name = clip_term_name(settings.clip_weights)  # "CLIP", or the coarse substitute's name
        self._note_planned_clip()
        self.history: list[dict[str, float]] = []
        self.timings: dict[str, float] = {}
        self._objective_factory = objective_factory
        self._objective = None
        self._note_loss_terms()
        self._note_style()
        self._opt: torch.optim.Adam | None = None
        self._grad_acc = torch.zeros(scene.count)
        self._trainer: Trainer | None = None
        self._refit_left = 0
        self._preprocess_round = 0
        self._stylize_step = 0
        self.splits_done = 0  # colour-gradient splits performed (they leave split_steps once done)
        self._caches = ColourCacheStore()
        self._pending: dict[str, float] = {}
        self.colour_transform: tuple[np.ndarray, np.ndarray] | None = None
        n = len(self.cameras)
        # epochs and min_steps count views; a step takes views_per_step of them
        views_total = max(int(round(settings.epochs * n)), settings.min_steps)
        self.stylize_steps = max(1, int(math.ceil(views_total / max(1, settings.views_per_step))))
        # splits at fixed fractions of the stylization, in optimiser steps, so that every preset performs them
        planned = {int(round(f * self.stylize_steps)) for f in settings.split_at}
        self.split_steps = sorted(k for k in planned if 0 < k < self.stylize_steps)
        self.accumulate_from = int(round(settings.grad_accumulate_from * self.stylize_steps))
        self.max_gaussians, how = settings.max_gaussians, "max_gaussians setting"
        if self.max_gaussians <= 0:  # 0: derived from the memory available now (pipeline/resources.py)
            from .resources import default_max_gaussians

            self.max_gaussians, how = default_max_gaussians(settings.working_width)
        self.decisions["max_gaussians"] = f"at most {self.max_gaussians:,} Gaussians ({how})"
        self._reduction_note = ""

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
        splits = self.splits_done + (len(self.split_steps) if s.split_rate > 0 else 0)
        return n + pre + 1 + self.stylize_steps + splits * (s.refit_iterations + 1) + 1

    def set_params(self, **kw: float) -> None:
        """Change live controls (``controls.CONTROLS``: λ weights, strength, stroke size, keep colours, split rate,
        lr, style mix: the last painting's weight when several are mixed, the others share the rest) from the next
        step on; a term whose weight turns non-zero is built then. ``ValueError`` (nothing changed) for an unknown
        name or a refused value."""
        from .controls import Effect, apply_controls

        effects = apply_controls(self.settings, kw)
        if effects & Effect.REWEIGHT:
            if self._objective is not None:
                self._objective.set_weights(self.settings.weights)
                self._note_networks()
            else:
                self._note_planned_clip()
            self._note_loss_terms()
        if effects & Effect.CONTENT_TARGETS and self.content_images:  # past the colour match: new content targets
            self._match_content_targets()
            if effects & Effect.RESTORE_CHROMA and self.settings.keep_colours:  # c_s takes c_gt's chroma
                self._restore_chroma()
                self.colour_version += 1
        if effects & Effect.CONTENT_TARGETS and hasattr(self._objective, "clear_content_cache"):
            self._objective.clear_content_cache()
        if effects & Effect.STYLE_FEATURES:
            self._set_style_controls(None, None)  # the painting's features for the new settings, and their note

    def _set_style_controls(self, scale: float | None, keep: float | bool | None, mix: float | None = None) -> None:
        """Stroke size, keep colours and the style mix, mid-run too (the module docstring says what each does
        then)."""
        from .settings import check_style_scale

        s = self.settings
        if scale is not None:
            s.style_scale = check_style_scale(scale)
        mix_changed = False
        if mix is not None and len(self.styles) > 1:
            weights = weights_with_mix(s.style_weights, float(mix))
            mix_changed = not np.allclose(weights, s.style_weights, rtol=0, atol=1e-9)
            s.style_weights = weights
        elif mix is not None and float(mix) != 0.0:
            raise ValueError("the style mix needs a second style image")
        keep_changed = keep is not None and bool(keep) != s.keep_colours
        if keep_changed:
            s.keep_colours = bool(keep)
        if (keep_changed or mix_changed) and self.content_images:  # past the colour match: new content targets
            self._match_content_targets()
            if keep_changed and s.keep_colours:  # c_s takes c_gt's chroma
                self._restore_chroma()
                self.colour_version += 1
        if hasattr(self._objective, "refresh_style"):  # test objectives may have no style features
            self._objective.refresh_style()
        if (keep_changed or mix_changed) and hasattr(self._objective, "clear_content_cache"):
            self._objective.clear_content_cache()
        self._note_style()

    def _note_style(self) -> None:
        """Decisions: how the painting is matched (stroke size) and whether the scene's colours are kept."""
        note = getattr(self._objective, "style_note", None)
        self.decisions["style_scale"] = note or f"stroke size {self.settings.style_scale:g} × the working width"
        self.decisions["colours"] = (
            "kept (keep colours): luminance-only colour match and networks, chroma of c_gt restored after every step"
            if self.settings.keep_colours else "the painting's (full colour match before and after stylization)")
        if len(self.styles) > 1:
            shares = " / ".join(f"{w:.2f}" for w in self.settings.style_weights)
            self.decisions["styles"] = (f"{len(self.styles)} paintings mixed {shares}: each style term is the weighted "
                                        f"sum of its terms against each painting, the colour matches map onto the "
                                        f"weighted palette")

    def style_input(self) -> np.ndarray | list[np.ndarray]:
        """What objectives are built from: the painting, or the list of paintings of a mix."""
        return self.style if len(self.styles) == 1 else list(self.styles)

    def current_params(self) -> dict[str, float]:
        """The values ``set_params`` accepts, as they are now (for UIs to show)."""
        return ui_params(self.settings)

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
            "selected": None if self._selected is None else self._selected.numpy().copy(),
            "geometry_version": self.geometry_version,
            "colour_version": self.colour_version,
            "phase": self.phase,
        }

    def stylized_scene(self) -> GaussianScene:
        """The current scene with c_s as its (SH degree 0) colour. A region run: the Gaussians outside the selection
        are the input's rows exactly (every attribute, their SH bands included; stylized ones get zero bands)."""
        scene = scene_from_params(self.params)
        scene.sh_dc = rgb_to_sh_dc(self.c_s.detach().clamp(0, 1).numpy())
        if self._selected is None:
            return scene
        inp = self.input_scene
        keep = (~self._selected).numpy()
        rows = self._origin.numpy()[keep]
        fields = {}
        for name in ("means", "log_scales", "quats", "opacity_logits", "sh_dc"):
            src = np.asarray(getattr(inp, name))
            arr = np.asarray(getattr(scene, name)).astype(src.dtype, copy=True)
            arr[keep] = src[rows]
            fields[name] = arr
        rest = np.asarray(inp.sh_rest)
        sh_rest = np.zeros((scene.count,) + rest.shape[1:], rest.dtype)
        sh_rest[keep] = rest[rows]
        return GaussianScene(**fields, sh_rest=sh_rest)

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
        if self._reduction_note:  # a split was cut back by max_gaussians
            rep.message = f"{rep.message}; {self._reduction_note}" if rep.message else self._reduction_note
            self._reduction_note = ""
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

    # ----------------------------------------------------------------- what the scene needs
    def _sh_note(self, degree: int) -> str:
        if degree == 0:
            return "no view-dependent SH in the scene: nothing to evaluate"
        if self.photos is not None:
            return f"SH degree {degree} never evaluated: ground truth from photos, stylization uses diffuse colour"
        used = self._gt_sh_degree
        kept = f"degree {used}" if used == degree else f"degree {used} (higher bands are all zero)"
        return (f"SH evaluated only for the {len(self.cameras)} ground-truth renders at {kept}; stylization and "
                "refits use diffuse colour only")

    def _note_loss_terms(self) -> None:
        loss = getattr(self._objective, "loss", None)
        weights = getattr(loss, "weights", self.settings.weights)
        on = [k for k in ("clip", "nnfm", "content", "tv") if getattr(weights, k) > 0]
        off = [k for k in ("clip", "nnfm", "content", "tv") if k not in on]
        self.decisions["loss_terms"] = (f"computed: {', '.join(on) or 'none'}; never computed (weight 0): "
                                        f"{', '.join(off) or 'none'}")

    def _seen(self) -> torch.Tensor | None:
        """Indices of the Gaussians some training camera sees, None when that is all of them (or culling is off).

        Recomputed whenever the geometry changed (a new version or count): after every split and refit.
        """
        key = (self.geometry_version, self.gaussian_count)
        if key == self._seen_key:
            return self._seen_ids
        n = self.gaussian_count
        if not self.settings.cull_unseen:
            self.decisions["culled"] = "off (cull_unseen = False): every Gaussian is rendered, optimised, split"
            ids = None
        else:
            p = self.params
            mask = seen_mask(p["means"], p["quats"], torch.exp(p["log_scales"].detach()),
                             torch.sigmoid(p["opacity_logits"].detach()), self.cameras)
            self.counters["visibility_passes"] += 1
            unseen = n - int(mask.sum())
            self.decisions["culled"] = culling_note(unseen, n, len(self.cameras))
            ids = torch.nonzero(mask).flatten() if unseen else None
        self._seen_key, self._seen_ids = key, ids
        return ids

    def _active(self) -> torch.Tensor | None:
        """Indices of the Gaussians the run works on: the seen ones, and of those only the selected ones in a region
        run; None when that is all of them. These are pre-processed, split, refitted and optimised."""
        if self._selected is None:
            return self._seen()
        return self._refresh_active()[0]

    def _active_in_seen(self) -> torch.Tensor | None:
        """Positions of ``_active()`` in the colour caches' columns (``_seen()`` order); None: the same set."""
        return None if self._selected is None else self._refresh_active()[1]

    def _refresh_active(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Region runs: (``_active()``, ``_active_in_seen()``), computed again only when the geometry changed."""
        key = (self.geometry_version, self.gaussian_count)
        if key != self._active_key:
            ids = self._seen()
            mask = self._selected.clone()
            pos = torch.arange(self.gaussian_count)
            if ids is not None:
                seen = torch.zeros_like(mask)
                seen[ids] = True
                mask &= seen
                pos = torch.full((self.gaussian_count,), -1, dtype=torch.long)
                pos[ids] = torch.arange(len(ids))
            active = torch.nonzero(mask).flatten()
            self._active_key, self._active_cache = key, (active, pos[active])
        return self._active_cache

    def _in_seen(self, values: torch.Tensor) -> torch.Tensor:
        ids = self._seen()
        return values if ids is None else values[ids]

    def _render_colours(self) -> torch.Tensor:
        """The colours of the caches' Gaussians for a stylization render: the optimised rows (``_c_opt``) in place,
        in a region run the others' colours held (no gradient)."""
        pos = self._active_in_seen()
        if pos is None:
            return self._c_opt
        base = self._in_seen(self.c_s).detach()
        return base.index_put((pos,), self._c_opt)

    @torch.no_grad()
    def _selected_weight(self, view: int) -> torch.Tensor:
        """[H, W]: how much of each pixel of a training view the selected Gaussians make (their rendered weight, in
        front of or behind the others as they are): the region's coverage."""
        indicator = self._in_seen(self._selected.to(torch.float32))[:, None].expand(-1, 3).contiguous()
        return self._render_cs(view, indicator)[..., 0].clamp(0.0, 1.0)

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
            covered = torch.ones(gt.shape[:2])
        else:
            if self._input_params is None:
                self._input_params = params_from_scene(self.input_scene, requires_grad=False)
            with torch.no_grad():
                out = render_params(self._input_params, cam, sh_degree=self._gt_sh_degree,
                                    backend=self.settings.raster_backend)
            gt = out.image.clamp(0, 1)
            covered = out.alpha.clamp(0, 1)
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
        ids = self._active()
        log_scales = self.params["log_scales"] if ids is None else self.params["log_scales"][ids]
        crit = size_evenness(log_scales, s.preprocess_gamma)  # of the Gaussians the cameras see (and selected)
        self.decisions["size_evenness"] = {k: round(v, 4) for k, v in crit.items()}
        even, figures = evenness_verdict(crit)
        rounds = s.preprocess_rounds
        if rounds <= 0:
            self.decisions["preprocess"] = f"off (0 rounds in the settings); {figures}"
        elif even and not s.force_preprocess:
            self.decisions["preprocess"] = f"skipped: Gaussian sizes already even ({figures})"
            rounds = 0
        else:
            why = "forced although the sizes are even" if even else "sizes uneven"
            self.decisions["preprocess"] = f"{rounds} round(s), {why} ({figures})"
        self.decisions["preprocess_rounds"] = rounds
        self._preprocess_round = 0
        if rounds == 0:
            self._enter("colour_match")
        else:
            self._enter("preprocess")

    def _make_trainer(self, strategy: Strategy, trainable: tuple[str, ...]) -> Trainer:
        """A refit of the seen Gaussians (a copy when some are unseen; ``_trainer_step`` writes it back)."""
        cfg = FitConfig(iterations=self.settings.refit_iterations, sh_degree=0, sh_increase_every=10**9,
                        trainable=trainable, seed=self.settings.seed + self.global_step,
                        backend=self.settings.raster_backend)
        ids = self._seen()
        if self._selected is not None and ids is None:
            ids = torch.arange(self.gaussian_count)
        params = self.params if ids is None else torch.nn.ParameterDict(
            {k: torch.nn.Parameter(v.detach()[ids].clone()) for k, v in self.params.items()})
        self._trainer_ids = ids
        self._frozen = None
        if self._selected is not None:  # region: the unselected Gaussians render as they are but never move
            free = self._selected[ids]
            self._frozen = (torch.nonzero(~free).flatten(), {k: v.detach()[~free].clone() for k, v in params.items()})
            for p in params.values():
                if p.requires_grad and p.ndim >= 1:
                    p.register_hook(_row_mask_hook(free))
            self.counters["refit_gaussians"] = int(free.sum())
        else:
            self.counters["refit_gaussians"] = int(params["means"].shape[0])
        return Trainer(params, self.cameras, self.gt_images, cfg, strategy, strategy_state={"extras": {}})

    def _trainer_step(self):
        rep = self._trainer.step()
        ids = self._trainer_ids
        frozen = self._frozen
        with torch.no_grad():
            if frozen is not None:  # undo whatever the strategy (elongation clamps) did to the unselected rows
                rows, values = frozen
                for k, v in self._trainer.params.items():
                    v[rows] = values[k]
            if ids is not None:
                for k, v in self._trainer.params.items():
                    self.params[k][ids] = v.detach()
        return rep

    def _split(self, mask: torch.Tensor, children: int, divisor: float, priority: torch.Tensor | None = None) -> int:
        """Split the ``mask`` Gaussians; past ``max_gaussians`` the lowest-``priority`` candidates are dropped."""
        extras = {"c_s": self.c_s, "grad_acc": self._grad_acc}
        if self._selected is not None:  # children inherit the selection (and their parent's input row)
            extras.update(selected=self._selected, origin=self._origin)
        limit = max(0, self.max_gaussians - self.gaussian_count)
        n_sel = int(mask.sum())
        if n_sel * (children - 1) > limit:
            keep = min(n_sel, limit // max(1, children - 1))
            idx = torch.where(mask)[0]
            if priority is not None and keep > 0:
                idx = idx[torch.topk(priority.detach()[idx].double(), keep).indices]
            mask = torch.zeros_like(mask)
            mask[idx[:keep]] = True
            self._reduction_note = (f"split reduced from {n_sel:,} to {keep:,} Gaussians by the cap of "
                                    f"{self.max_gaussians:,}")
            self.decisions.setdefault("reductions", []).append(f"step {self.global_step + 1}: {self._reduction_note}")
        ops.split(self.params, {}, extras, mask, n_children=children, scale_divisor=divisor, generator=self._gen)
        self.c_s = extras["c_s"]
        self._grad_acc = extras["grad_acc"]
        if self._selected is not None:
            self._selected, self._origin = extras["selected"], extras["origin"]
        return int(mask.sum())

    def _step_preprocess(self) -> StepReport:
        s = self.settings
        changed_geometry = True
        msg = ""
        if self._trainer is None:
            gamma = s.preprocess_gamma * s.preprocess_gamma_growth**self._preprocess_round
            ids = self._active()
            if ids is None:
                mask = flat_split_mask(self.params["log_scales"], gamma, s.preprocess_cap)
            else:  # unseen (and unselected) Gaussians are never split
                mask = torch.zeros(self.gaussian_count, dtype=torch.bool)
                mask[ids] = flat_split_mask(self.params["log_scales"][ids], gamma, s.preprocess_cap)
            from .preprocess import gaussian_areas

            n = self._split(mask, s.preprocess_children, s.preprocess_scale_divisor,
                            priority=gaussian_areas(self.params["log_scales"]))
            it = s.refit_iterations
            clamp_at = tuple(sorted({max(1, it // 4), max(1, it // 2), max(1, 3 * it // 4), it}))
            strategy = ElongationClampStrategy(clamp_at=clamp_at, limit=s.elongation_limit)
            self._trainer = self._make_trainer(strategy, GEOMETRY_AND_GT)
            self._refit_left = it
            msg = f"pre-processing round {self._preprocess_round + 1}: split {n} flat Gaussians (γ={gamma:.3f})"
            losses = {}
        else:
            rep = self._trainer_step()
            self._refit_left -= 1
            losses = {"refit": rep.loss}
        if self._trainer is not None and self._refit_left <= 0:
            self._trainer = None
            self._preprocess_round += 1
            if self._preprocess_round >= self._preprocess_rounds_planned():
                self._enter("colour_match")
        return StepReport("preprocess", 0, 0, losses=losses, geometry_changed=changed_geometry, message=msg)

    def _step_colour_match(self) -> StepReport:
        from ..style.colour_match import apply_colour_transform

        if self._selected is not None:
            self.region_coverage = [self._selected_weight(v) for v in range(len(self.cameras))]
        A, b = self._match_content_targets()
        c_gt = self._gt_rgb().numpy()
        keep = self.settings.keep_colours  # luminance map unclipped, then the chroma of c_gt as far as it fits
        self.c_s = torch.as_tensor(apply_colour_transform(c_gt, A, b, clip=not keep), dtype=torch.float32)
        if self._selected is not None:  # outside the region the Gaussians keep their own colour
            self.c_s = torch.where(self._selected[:, None], self.c_s, torch.as_tensor(c_gt, dtype=torch.float32))
        if keep:
            self._restore_chroma()
        self._grad_acc = torch.zeros(self.gaussian_count)
        self.decisions["network_area"] = self._network_area_note()
        self._enter("stylize")
        return StepReport("colour_match", 0, 0, colours_changed=True, message="colours matched to the style")

    def _surface(self, image: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
        """The pixels [M, 3] the scene covers (alpha > 0.5) whose statistics the colour match maps. With keep
        colours they are divided by alpha (the surface's colour, not its blend with the black background): the
        luminance map Y -> aY + β of the Gaussians turns a pixel into aY + alpha·β, so matched on these the
        render's covered pixels get the painting's luminance mean and std, not a darker scene's."""
        covered = alpha > 0.5
        if not self.settings.keep_colours:
            return image[covered]
        return image[covered] / alpha[covered].unsqueeze(-1)

    def _transfer_matrix(self, content_pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The affine colour map onto the painting: full colour, or luminance only with keep colours."""
        from ..style.colour_match import colour_transfer_matrix
        from ..style.keep_colours import luminance_transfer_matrix

        match = luminance_transfer_matrix if self.settings.keep_colours else colour_transfer_matrix
        return match(content_pixels, Palette.mixture(self._palettes, self.settings.style_weights))

    def _match_content_targets(self) -> tuple[np.ndarray, np.ndarray]:
        """Colour-match the ground truth to the style: sets ``colour_transform`` and the content targets."""
        from ..style.colour_match import apply_colour_transform

        gt_pixels = torch.cat([self._surface(g, m) for g, m in zip(self.gt_images, self._match_coverage(),
                                                                   strict=True)]).numpy()
        if len(gt_pixels) < 2:  # the scene covers no pixel: use whole frames
            gt_pixels = torch.cat([g.reshape(-1, 3) for g in self.gt_images]).numpy()
        A, b = self._transfer_matrix(gt_pixels)
        self.colour_transform = (A, b)
        # The content targets are what the colour-matched Gaussians render: a render is Σ w_i c_i with Σ w_i = alpha
        # over a black background, so c -> A c + b turns a pixel p into A p + alpha b. The background stays black
        # (transforming it too would ask c_s for a change no Gaussian can make, and pull at every silhouette).
        self.content_images = []
        for i, (g, a) in enumerate(zip(self.gt_images, self.coverage, strict=True)):
            p = apply_colour_transform(g.reshape(-1, 3).numpy(), A, np.zeros(3), clip=False)
            p = torch.as_tensor(p + a.reshape(-1, 1).numpy() * b, dtype=torch.float32)
            if self.settings.keep_colours:  # the view's own hues at the new luminance (as c_s gets them)
                from ..style.keep_colours import with_chroma_of

                p = with_chroma_of(p, g.reshape(-1, 3))
            if self.region_coverage:  # region: the selected share of each pixel matched, the rest as it was
                share = (self.region_coverage[i] / a.clamp_min(1e-6)).clamp(0.0, 1.0).reshape(-1, 1)
                p = g.reshape(-1, 3) + share * (p - g.reshape(-1, 3))
            self.content_images.append(p.clamp(0.0, 1.0).reshape(g.shape))
        return A, b

    @torch.no_grad()
    def _restore_chroma(self) -> None:
        """Keep colours: every (selected) Gaussian's c_s (and the optimised copy) takes the chroma of its c_gt back."""
        from ..style.keep_colours import with_chroma_of

        c_gt = self._gt_rgb().to(self.c_s.dtype)
        restored = with_chroma_of(self.c_s.detach(), c_gt)
        self.c_s = restored if self._selected is None else torch.where(self._selected[:, None], restored, self.c_s)
        if self._c_opt is not None:
            ids = self._active()
            self._c_opt.copy_(self.c_s if ids is None else self.c_s[ids])

    def _match_coverage(self) -> list[torch.Tensor]:
        """What the colour matches count as the scene in each view: its coverage, or the region's."""
        return self.region_coverage if self.region_coverage else self.coverage

    def objective_coverage(self, view: int) -> torch.Tensor | None:
        """The scene's coverage of a training view as the objective gets it: None for photos (they are all scene).
        A region run: the selected Gaussians' weight (photos too), so the losses see only the selected part."""
        if self.region_coverage:
            return self.region_coverage[view]
        return None if self.photos is not None else self.coverage[view]

    def _network_area_note(self) -> str:
        """What the networks look at during stylization (see ``pipeline/scene_box.py``)."""
        if self.photos is not None and not self.region_coverage:
            return "whole frames (photos: the scene fills every view)"
        if not self.settings.crop_to_scene:
            return "whole frames (crop_to_scene = False)"
        if self.region_coverage:
            share = float(np.mean([box_fraction(scene_box(c), *c.shape) for c in self.region_coverage]))
            return (f"the box of each view that the selected region covers (+{SCENE_BOX_MARGIN_PX} px): "
                    f"{100 * share:.0f} % of the frame's pixels on average; losses weighted by the region's coverage")
        share = float(np.mean([box_fraction(scene_box(c), *c.shape) for c in self.coverage]))
        return (f"the box of each view that the scene covers (+{SCENE_BOX_MARGIN_PX} px): {100 * share:.0f} % of the "
                f"frame's pixels on average")

    def _objective_fn(self):
        if self._objective is None:
            if self._objective_factory is None:
                from .objective import StyleObjective

                self._objective = StyleObjective(self.style_input(), self.settings)
            else:
                self._objective = self._objective_factory(self.style_input(), self.settings)
            self._note_networks()
            self._note_style()
            gen, saved = objective_generator(self._objective), getattr(self, "_objective_rng", None)
            if gen is not None and saved is not None:  # resumed: the CLIP crops continue where they were
                gen.set_state(saved)
            self._note_loss_terms()
        return self._objective

    def _note_planned_clip(self) -> None:
        """Before the objective is built: what its CLIP term will be (weights found, or the coarse substitute)."""
        s = self.settings
        self.decisions["clip"] = clip_status(s.clip_weights) if s.weights.clip > 0 else CLIP_OFF
        if s.weights.clip == 0 and s.scene_kind == "360" and s.defaults == "calibrated" \
                and clip_term_name(s.clip_weights) != "CLIP":
            self.decisions["clip"] = ("off: no CLIP weights, and the calibrated 360° defaults leave the coarse "
                                      "substitute off (it cost style and structure; README); --lambda-clip turns it on")

    def _note_networks(self) -> None:
        """The objective's word on its networks: where the VGG weights and the CLIP term (or substitute) came from."""
        for key, attr in (("clip", "clip_status"), ("vgg", "vgg_status")):
            status = getattr(self._objective, attr, None)
            if status is not None:
                self.decisions[key] = status

    def _lr(self) -> float:
        s = self.settings
        t = min(1.0, self._stylize_step / max(1, self.stylize_steps))
        return float(math.exp((1 - t) * math.log(s.lr_start) + t * math.log(s.lr_end)))

    def _build_cache(self, view: int) -> ColourCache:
        """The colour cache of one view over the seen Gaussians only (columns in ``_seen()`` order)."""
        cam, ids = self.cameras[view], self._seen()
        p = {k: self.params[k].detach() for k in ("means", "quats", "log_scales", "opacity_logits")}
        if ids is not None:
            p = {k: v[ids] for k, v in p.items()}
        viewmat, K = camera_tensors(cam)
        self.counters["cache_builds"] += 1
        self.counters["cache_gaussians"] += int(p["means"].shape[0])
        return ColourCache(p["means"], p["quats"], torch.exp(p["log_scales"]), torch.sigmoid(p["opacity_logits"]),
                           viewmat, K, cam.width, cam.height, geometry_version=self.geometry_version)

    def _render_cs(self, view: int, colours: torch.Tensor | None = None) -> torch.Tensor:
        """Render c_s (or ``colours`` of the seen Gaussians) from a training view through its colour cache."""
        cache = self._caches.get_or_build(view, self.geometry_version, lambda: self._build_cache(view))
        if colours is None:
            ids = self._seen()
            colours = self.c_s if ids is None else self.c_s[ids]
        return cache.render(colours)

    def _step_stylize(self) -> StepReport:
        s = self.settings
        if self._stylize_step in self.split_steps and s.split_rate > 0:
            return self._do_colour_split()
        ids = self._active()
        if self._opt is None:
            self._start_colour_optimiser(ids)
        for g in self._opt.param_groups:
            g["lr"] = self._lr()
        views = [self._stylize_view(self._stylize_step * s.views_per_step + j) for j in range(s.views_per_step)]
        self._opt.zero_grad(set_to_none=True)
        total, terms = 0.0, {}
        for view in views:  # the mean loss over this step's views: gradients add up before one optimiser step
            image = self._render_cs(view, self._render_colours())
            loss, view_terms = self._objective_fn()(image, self.content_images[view], view,
                                                    coverage=self.objective_coverage(view))
            (loss / len(views)).backward()
            total += float(loss.detach()) / len(views)
            for k, v in view_terms.items():
                terms[k] = terms.get(k, 0.0) + v / len(views)
        grad = self._c_opt.grad
        if self._stylize_step >= self.accumulate_from and grad is not None:
            norms = grad.detach().norm(dim=-1)
            if ids is None:
                self._grad_acc += norms
            else:
                self._grad_acc.index_add_(0, ids, norms)
        self._opt.step()
        with torch.no_grad():
            self._c_opt.clamp_(0.0, 1.0)
            if ids is None:
                self.c_s.copy_(self._c_opt)
            else:
                self.c_s[ids] = self._c_opt
        if s.keep_colours:
            self._restore_chroma()
        self._stylize_step += 1
        self.phase_step += 1
        if self._stylize_step >= self.stylize_steps:
            self._opt, self._c_opt = None, None
            self._enter("finish" if s.colour_match_after else "done")
        return StepReport("stylize", 0, 0, losses={"total": total, **terms}, colours_changed=True,
                          message=f"stylize view{'s' if len(views) > 1 else ''} {', '.join(map(str, views))}")

    def _stylize_view(self, k: int) -> int:
        """The training view of stylization step ``k``: camera order (``orbit``) or, as the reference does, a new
        random permutation of the views every epoch (``random``; drawn from the seed and the epoch, so a resumed run
        sees the same order)."""
        n = len(self.cameras)
        if self.settings.view_order == "orbit":
            return k % n
        epoch = torch.Generator().manual_seed(self.settings.seed * 1_000_003 + k // n)
        return int(torch.randperm(n, generator=epoch)[k % n])

    def _start_colour_optimiser(self, ids: torch.Tensor | None) -> None:
        """Adam on a copy of the seen Gaussians' c_s (unseen ones get no gradient and keep their colour); with
        ``optimizer="visible_adam"`` only the Gaussians in the current view move (``visible_adam.py``)."""
        from .visible_adam import VisibleAdam

        self.c_s = self.c_s.detach()
        self._c_opt = (self.c_s if ids is None else self.c_s[ids]).clone().requires_grad_(True)
        self.counters["optimised_colours"] = int(self._c_opt.shape[0])
        if self.settings.optimizer == "visible_adam":
            self._opt = VisibleAdam(self._c_opt, lr=self._lr())
        else:
            self._opt = torch.optim.Adam([self._c_opt], lr=self._lr())

    def _do_colour_split(self) -> StepReport:
        s = self.settings
        self.split_steps.remove(self._stylize_step)
        self.splits_done += 1
        n = self.gaussian_count
        ids = self._active()  # the split rate is a fraction of the seen (selected) Gaussians; no others are split
        k = int(math.floor(s.split_rate * (n if ids is None else len(ids))))
        mask = torch.zeros(n, dtype=torch.bool)
        if k > 0:
            top = torch.topk(self._grad_acc if ids is None else self._grad_acc[ids], k).indices
            mask[top if ids is None else ids[top]] = True
        self.c_s = self.c_s.detach()
        self._c_opt = None
        count = self._split(mask, s.split_children, s.split_scale_divisor, priority=self._grad_acc)
        self._grad_acc = torch.zeros(self.gaussian_count)
        self._opt = None
        self._trainer = self._make_trainer(Strategy(), GEOMETRY_AND_GT)
        self._refit_left = s.refit_iterations
        self._enter("refit" if self._refit_left > 0 else "stylize")
        return StepReport("stylize", 0, 0, geometry_changed=True, colours_changed=True,
                          message=f"split {count} Gaussians with the largest colour gradient")

    def _step_refit(self) -> StepReport:
        rep = self._trainer_step()
        self._refit_left -= 1
        if self._refit_left <= 0:
            self._trainer = None
            self._enter("stylize")
            self.phase_step = 1
        return StepReport("refit", 0, 0, losses={"refit": rep.loss}, geometry_changed=True)

    @torch.no_grad()
    def _step_finish(self) -> StepReport:
        from ..style.colour_match import apply_colour_transform

        pixels = []
        for v in range(len(self.cameras)):
            image = self._render_cs(v)
            alpha = 1.0 - self._caches.get(v, self.geometry_version).t_final
            pixels.append(self._surface(image, alpha if self._selected is None else self._selected_weight(v)))
        covered_pixels = torch.cat(pixels).numpy()
        if len(covered_pixels) < 2:
            covered_pixels = torch.cat([self._render_cs(v).reshape(-1, 3) for v in range(len(self.cameras))]).numpy()
        A, b = self._transfer_matrix(covered_pixels)
        keep = self.settings.keep_colours
        matched = torch.as_tensor(apply_colour_transform(self.c_s.numpy(), A, b, clip=not keep), dtype=torch.float32)
        self.c_s = matched if self._selected is None else torch.where(self._selected[:, None], matched, self.c_s)
        if keep:
            self._restore_chroma()
        self._enter("done")
        what = "luminance (colours kept)" if self.settings.keep_colours else "style"
        return StepReport("finish", 0, 0, colours_changed=True, message=f"final colour match to the {what}")

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
            "splits_done": self.splits_done,
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
            "objective_rng": g.get_state() if (g := objective_generator(self._objective)) is not None else None,
            "selected": None if self._selected is None else self._selected.clone(),
            "origin": None if self._origin is None else self._origin.clone(),
            "region_coverage": [m.clone() for m in self.region_coverage],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore from ``state_dict()``; an interrupted refit restarts its remaining iterations with fresh Adam."""
        self.params = torch.nn.ParameterDict({k: torch.nn.Parameter(v.clone()) for k, v in state["params"].items()})
        self.c_s = state["c_s"].clone()
        self._grad_acc = state["grad_acc"].clone()
        self.gt_images = [g.clone() for g in state["gt_images"]]
        self.coverage = [m.clone() for m in state["coverage"]]
        self.content_images = [g.clone() for g in state["content_images"]]
        if (state.get("selected") is None) != (self._selected is None):
            raise ValueError("the checkpoint was made " + ("with" if self._selected is None else "without")
                             + " a selected region, this run is " + ("without" if self._selected is None else "with")
                             + " one")
        if self._selected is not None:
            self._selected = torch.as_tensor(state["selected"]).to(torch.bool).clone()
            self._origin = torch.as_tensor(state["origin"]).to(torch.long).clone()
            self._active_key = None
        self.region_coverage = [m.clone() for m in state.get("region_coverage") or []]
        self.phase = state["phase"]
        self.phase_step = state["phase_step"]
        self.global_step = state["global_step"]
        self._stylize_step = state["stylize_step"]
        self.split_steps = list(state["split_steps"])
        self.splits_done = int(state.get("splits_done", 0))  # checkpoints written before it was recorded: 0
        self._preprocess_round = state["preprocess_round"]
        self.decisions = dict(state["decisions"])
        self.history = list(state["history"])
        self.timings = dict(state["timings"])
        self.geometry_version = state["geometry_version"] + 1
        self.colour_version = state["colour_version"] + 1
        self.colour_transform = state["colour_transform"]
        self._caches.invalidate()
        self._gen.set_state(state["generator"])
        self._objective_rng = state.get("objective_rng")
        if self._objective is not None and self._objective_rng is not None and objective_generator(self._objective):
            objective_generator(self._objective).set_state(self._objective_rng)
        self._opt, self._c_opt = None, None
        if state.get("adam") is not None:
            self._start_colour_optimiser(self._active())
            self._opt.load_state_dict(state["adam"])
        saved = state.get("settings") or {}
        if len(saved.get("style_weights") or ()) == len(self.styles) > 1:  # the mix as it was (content targets too)
            self.settings.style_weights = normalise_style_weights(saved["style_weights"], len(self.styles))
        self._set_style_controls(saved.get("style_scale"), saved.get("keep_colours"))  # a resumed run keeps them
        self._trainer = None
        self._refit_left = state["refit_left"]
        if state["in_refit"] and self._refit_left > 0:
            strategy = Strategy() if self.phase == "refit" else ElongationClampStrategy()
            self._trainer = self._make_trainer(strategy, GEOMETRY_AND_GT)
