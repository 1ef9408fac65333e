"""The step-wise G-Style engine: a short runner over the phases of ``engine/phases``.

``Stylizer.step()`` = one unit of work of the current phase (ground truth, pre-processing, colour match,
stylization with its splits and refits, final colour match; ``phases/__init__.py`` lists them). Its progress total is
the steps done plus the sum of the phases' remaining steps; its checkpoint is the run state's and each phase's
``state_dict`` under the phase's name. There are no threads here: callers (CLI, app worker, tests) decide when to
call ``step()``.

Live controls (``set_params``): λ weights and strength reach the objective from the next step; split rate and lr
the stylization. Keep colours (``settings.keep_colours``, ``style/keep_colours.py``): the colour matches map only the
luminance mean/std onto the painting's, the networks see luminance only, and after every optimiser step each
Gaussian's c_s takes the chroma of its c_gt back: the scene keeps its hues and takes the painting's luminance
pattern. Turned on mid-run, c_s takes c_gt's chroma at once and the content targets are matched again; turned off,
c_s keeps its colours and from then on the painting's colours are matched again (the finish colour-matches them
fully). Stroke size (``settings.style_scale``): the painting is matched at that × the working width; changed mid-run,
its features are extracted again before the next step (``objective.py``). Several paintings (``style`` a list,
``settings.style_weights``, ``style/mix.py``): every style term is the weighted sum of its terms against each
painting and the colour matches map onto the weighted palette; a mix changed mid-run (``set_params(style_mix=...)``)
re-matches the content targets and re-weights the terms from the next step. Palette match
(``settings.palette_match``, t): the final colour match leaves (1 − t)·before + t·matched; both are kept, so a
finished run takes a new t at once (``phases/colour_match.ColourMatch.reapply``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from ..cameras.camera import Camera
from ..device import DeviceChoice, out_of_memory
from ..fit.model import scene_from_params
from ..raster.gsplat_module import RasterizerSetup
from ..scene import GaussianScene, rgb_to_sh_dc
from ..style.clip import clip_term_name
from ..style.mix import normalise_style_weights
from .capacity import held_part, with_neighbour_colours
from .controls import Effect, apply_controls
from .feather import feathered_colours, merge_unselected
from .levels import capped_levels
from .live_controls import LiveControls
from .lod_run import LiveChildren, plan_cut, whole_capture
from .notes import note_levels, note_loss_terms, note_planned_clip, note_style, sh_note
from .phases import ColourMatch, GroundTruth, Phase, Preprocess, Refine, StepReport, Stylize
from .plan import STYLIZED_PHASES
from .region import region_note, selected_box, selection_mask
from .run_state import RunState
from .settings import StylizeSettings, ui_params
from .stylizer_levels import LevelsMixin
from .view_choice import choose_views

__all__ = ["Stylizer", "StepReport", "choose_views", "ENGINE_STATE"]

ENGINE_STATE = 2  # the layout of ``Stylizer.state_dict()`` (checkpoint.FORMAT names it too)


def _shared(owner: str, name: str, doc: str) -> property:
    """A read-only property of the runner that shows ``self.<owner>.<name>``."""
    return property(lambda self: getattr(getattr(self, owner), name), doc=doc)


class Stylizer(LevelsMixin):
    """G-Style on one scene: ``step()`` until ``done``; ``snapshot()`` for viewers; ``state_dict()`` for checkpoints."""

    def __init__(self, scene: GaussianScene, cameras: list[Camera], style: np.ndarray | Sequence[np.ndarray],
                 settings: StylizeSettings, *, objective_factory=None, photos: list[np.ndarray] | None = None,
                 selection: np.ndarray | None = None, capacity: tuple[int, str] | None = None) -> None:
        """``capacity``: the cap on Gaussians and where it came from, as a saved run had it (``state_dict``'s
        "capacity"), so that a run resumed with other free memory holds the same part; None: worked out now."""
        if scene.count == 0:
            raise ValueError("the scene has no Gaussians")
        if not cameras:
            raise ValueError("stylization needs at least one camera")
        torch.manual_seed(settings.seed)
        self.camera_count = len(cameras)  # all the scene's cameras (the run trains on at most max_views of them)
        view_ids = choose_views(list(cameras), settings.max_views)
        # one painting, or several mixed with settings.style_weights (style/mix.py)
        styles = [np.asarray(s, np.float32) for s in ([style] if isinstance(style, np.ndarray) else style)]
        settings.style_weights = normalise_style_weights(settings.style_weights, len(styles))
        # a selected region (settings.region and/or a ``selection`` mask, region.py): only these Gaussians are
        # pre-processed, split, refitted and stylized
        mask = selection_mask(scene.means, selected_box(settings), selection)
        # a capture larger than the run can hold: its most visible part is stylized, the rest takes its colours
        # from neighbours when the result is made (capacity.py); decided before anything large is built
        self.full_input, self.full_selection = scene, mask
        # Gaussians far below a pixel at the run's width are held as merged parents (lod_run.py); every input
        # Gaussian is written back from them when the result is made
        self.lod, lod_note = plan_cut(scene, mask, [cameras[i] for i in view_ids], settings)
        if self.lod is not None:
            scene, mask = self.lod.parents, self.lod.parent_selection
        self.cut_input, self.cut_selection = scene, mask
        self.capacity, scene, mask = held_part(scene, mask, settings, capacity)
        self.input_selection = mask  # over the held input Gaussians (None: all); in the checkpoint fingerprint
        self.run_state = run = RunState(
            scene, [cameras[i] for i in view_ids], [photos[i] for i in view_ids] if photos is not None else None,
            styles, settings, objective_factory=objective_factory, selection=mask)
        run.decisions["lod"] = lod_note
        self.live_children = None if self.lod is None else LiveChildren(self.lod, self.capacity, self.full_input,
                                                                        self.full_selection)
        if self.lod is not None:
            run.lineage = torch.arange(scene.count)
            held = self.capacity.held
            run.lod_merged = torch.as_tensor(self.lod.merged if held is None else self.lod.merged[held])
            if not self.capacity.reduced:  # the ground truth: what every Gaussian of the capture shows
                run.truth_scene = self.full_input
        if mask is not None:
            run.decisions["region"] = region_note(settings.region, int(self.full_selection.sum()),
                                                  self.full_input.count, settings.region_feather)
        run.decisions["sh"] = sh_note(scene.sh_degree, photos is not None, run.gt_sh_degree, len(run.cameras))
        self.clip_name = clip_term_name(settings.clip_weights)  # "CLIP", or the coarse substitute's name
        note_planned_clip(run.decisions, settings)
        note_loss_terms(run.decisions, settings, None)
        note_style(run.decisions, settings, None, len(styles))
        # a run on photos ends at most at their width: a level's ground truth is the photos resized, and photos
        # enlarged hold no finer detail to fit (the run's decisions say so)
        self.level_limit = min(c.width for c in run.full_cameras) if photos is not None else None
        asked = tuple(settings.refine_widths)
        settings.refine_widths = capped_levels(asked, settings.working_width, self.level_limit)
        note_levels(run.decisions, settings, asked=asked, limit=self.level_limit)
        self.ground_truth, self.preprocess, self.colour_match = GroundTruth(run), Preprocess(run), ColourMatch(run)
        self.stylize = Stylize(run)
        levels = [Refine(run, width, i) for i, width in enumerate(settings.refine_widths)]
        finish = [ColourMatch(run, final=True)] if settings.colour_match_after else []
        self.phases: list[Phase] = [self.ground_truth, self.preprocess, self.colour_match, self.stylize, *levels,
                                    *finish]
        run.max_gaussians = self.capacity.max_gaussians
        run.decisions["max_gaussians"] = f"at most {run.max_gaussians:,} Gaussians ({self.capacity.how})"
        run.decisions["capacity"] = self.capacity.note
        self.phase_step = 0  # steps since the run entered the current phase
        self.rasterizer_setup = RasterizerSetup(run.raster_device)  # gsplat's module on CUDA, before the first step
        self.live = LiveControls(self)
        self._settle()

    # ----------------------------------------------------------------- what callers read
    settings = _shared("run_state", "settings", "The run's settings (``set_params`` changes the live ones).")
    input_scene = _shared("run_state", "input_scene", "The scene as it came in.")
    full_cameras = _shared("run_state", "full_cameras", "The training cameras at full resolution.")
    cameras = _shared("run_state", "cameras", "The training cameras at the working width.")
    photos = _shared("run_state", "photos", "The training photos (None: ground truth rendered from the scene).")
    styles = _shared("run_state", "styles", "The painting(s), float32 [H, W, 3] each.")
    params = _shared("run_state", "params", "Geometry and c_gt (sh_dc) of the current Gaussians.")
    c_s = _shared("run_state", "c_s", "The stylized colour of every current Gaussian, RGB [N, 3].")
    gt_images = _shared("run_state", "gt_images", "Ground-truth image of each training view.")
    coverage = _shared("run_state", "coverage", "Alpha of each ground-truth view (photos: 1).")
    region_coverage = _shared("run_state", "region_coverage", "The selected Gaussians' weight per view (regions).")
    content_images = _shared("run_state", "content_images", "The colour-matched ground truth (content targets).")
    colour_transform = _shared("run_state", "colour_transform", "(A, b) of the first colour match, once made.")
    decisions = _shared("run_state", "decisions", "What the run decided and why, in words (OUT.json).")
    history = _shared("run_state", "history", "The losses of every step that had any.")
    timings = _shared("run_state", "timings", "Seconds spent per phase.")
    counters = _shared("run_state", "counters", "Work done (visibility passes, cache builds, ...).")
    global_step = _shared("run_state", "global_step", "Steps done.")
    geometry_version = _shared("run_state", "geometry_version", "Counts geometry changes.")
    colour_version = _shared("run_state", "colour_version", "Counts colour changes.")
    gaussian_count = _shared("run_state", "gaussian_count", "Current number of Gaussians.")
    max_gaussians = _shared("run_state", "max_gaussians", "The cap on the Gaussian count after splits.")
    active = _shared("run_state", "active", "The active set: seen (and selected) Gaussians.")
    objective = _shared("run_state", "objective", "The objective once built (the first stylization step), else None.")
    stylize_steps = _shared("stylize", "steps", "Optimiser steps of the stylization.")
    split_steps = _shared("stylize", "split_steps", "Stylization steps at which a colour-gradient split is still due.")
    splits_done = _shared("stylize", "splits_done", "Colour-gradient splits performed.")

    @property
    def style(self) -> np.ndarray:
        """The (first) painting."""
        return self.run_state.styles[0]

    @property
    def selection(self) -> np.ndarray | None:
        """Bool [N] over the current Gaussians: the selected ones of a region run (children inherit); None: all."""
        sel = self.run_state.active.selected
        return None if sel is None else sel.numpy().copy()

    @property
    def origin(self) -> np.ndarray | None:
        """Each current Gaussian's row in the input scene (region runs; None otherwise)."""
        origin = self.run_state.active.origin
        return None if origin is None else origin.numpy().copy()

    def build_objective(self) -> Any:
        """The objective, built now if no stylization step has built it yet."""
        return self.run_state.objective_fn()

    def gt_colours(self) -> torch.Tensor:
        """c_gt, the current Gaussians' ground-truth diffuse colour, RGB [N, 3]."""
        return self.run_state.gt_rgb()

    def render(self, view: int, colours: torch.Tensor | None = None) -> torch.Tensor:
        """Training view ``view`` rendered with c_s (or ``colours`` [N, 3]) through its colour cache, [H, W, 3]."""
        return self.run_state.render(view, colours)

    def objective_coverage(self, view: int) -> torch.Tensor | None:
        """The scene's (or the region's) coverage of a training view as the objective gets it (None: photos)."""
        return self.run_state.objective_coverage(view)

    def style_input(self) -> np.ndarray | list[np.ndarray]:
        """What objectives are built from: the painting, or the list of paintings of a mix."""
        return self.run_state.style_input()

    def current_params(self) -> dict[str, float]:
        """The values ``set_params`` accepts, as they are now (for UIs to show)."""
        return ui_params(self.settings)

    # ----------------------------------------------------------------- progress
    def current_phase(self) -> Phase | None:
        """The phase the next step belongs to (None: the run is done)."""
        return next((p for p in self.phases if not p.finished), None)

    def _settle(self) -> None:
        """Start the phases the run has reached: each unstarted one up to the first that is not finished."""
        for phase in self.phases:
            if not phase.started:
                phase.start()
            if not phase.finished:
                return

    @property
    def phase(self) -> str:
        """The current phase's name ("ground_truth" ... "finish", "refit" inside the stylization), or "done"."""
        current = self.current_phase()
        return "done" if current is None else current.current

    @property
    def device_choice(self) -> DeviceChoice:
        """The device the run computes on, its name in words and why it was chosen."""
        return self.run_state.device_choice

    @property
    def setup_note(self) -> str:
        """A line for a UI to show about the rasterizer's one-off setup (``RasterizerSetup.note``): before the step
        that builds gsplat's CUDA module (the first run on a card: minutes), that it will; after it, how long it
        took; "" otherwise (the CPU, or a module kept from an earlier run)."""
        return self.rasterizer_setup.note

    @property
    def done(self) -> bool:
        """True once every phase has run."""
        return self.current_phase() is None

    def total_steps(self) -> int:
        """Steps done plus every phase's remaining steps as planned now (splits add theirs when performed)."""
        return self.run_state.global_step + sum(p.remaining_steps() for p in self.phases if not p.finished)

    def step(self) -> StepReport:
        """Advance by one step of the current phase."""
        run, current = self.run_state, self.current_phase()
        if current is None:
            return StepReport("done", run.global_step, self.total_steps(), gaussians=self.gaussian_count, done=True,
                              width=self.current_width)
        phase, width = current.current, self.current_width
        try:
            built = self.rasterizer_setup.prepare()  # once, before the first render: not part of any step's time
            if built:
                run.timings["gpu_rasterizer_build"] = built
                run.decisions["rasterizer"] = self.rasterizer_setup.outcome
            t0 = time.perf_counter()
            rep = current.step()
        except torch.OutOfMemoryError as error:  # a GPU's: one line that says what to lower, not torch's page
            raise out_of_memory(run.device_choice, f"{phase} with {self.gaussian_count:,} Gaussians at {width} px"
                                ) from error
        rep.width = width
        rep.seconds = time.perf_counter() - t0
        run.timings[phase] = run.timings.get(phase, 0.0) + rep.seconds
        run.global_step += 1
        if rep.geometry_changed:
            run.geometry_version += 1
            run.caches.invalidate()
        if rep.colours_changed:
            run.colour_version += 1
        self._settle()
        self.phase_step = self.phase_step + 1 if self.phase == phase else 0
        rep.step, rep.total_steps, rep.gaussians, rep.done = run.global_step, self.total_steps(), \
            self.gaussian_count, self.done
        if run.reduction_note:  # a split was cut back by max_gaussians
            rep.message = f"{rep.message}; {run.reduction_note}" if rep.message else run.reduction_note
            run.reduction_note = ""
        if rep.losses:
            run.history.append({"step": run.global_step, **rep.losses})
        return rep

    def run(self, callback=None) -> None:
        """Step until done, calling ``callback(report)`` after each step."""
        while not self.done:
            rep = self.step()
            if callback is not None:
                callback(rep)

    def preset_plans(self) -> dict[str, dict[str, float]]:
        """Every preset's steps of each kind on this scene (``plan.planned_steps``), for the studio's estimates."""
        from .plan import planned_steps
        from .settings import PRESETS, resolve_settings

        s = self.settings
        clip = self.clip_name == "CLIP"
        return {name: planned_steps(resolve_settings(name, s.scene_kind, self.camera_count, defaults=s.defaults,
                                                     clip_available=clip), self.camera_count) for name in PRESETS}

    def run_plan(self) -> dict[str, float]:
        """This run's own steps of each kind (its settings, the levels it was given included): the studio's ETA."""
        from .plan import planned_steps

        return planned_steps(self.settings, self.camera_count)

    # ----------------------------------------------------------------- live controls
    def set_params(self, **kw: float) -> None:
        """Change live controls (``controls.CONTROLS``: λ weights, strength, stroke size, palette match, keep colours,
        split rate, lr, style mix: the last painting's weight when several are mixed, the others share the rest) from
        the next step on (the palette match of a finished run at once); a term whose weight turns non-zero is built
        then. ``ValueError`` (nothing changed) for an unknown name or a refused value."""
        self.live.carry_out(apply_controls(self.settings, kw))

    # ----------------------------------------------------------------- outputs
    def snapshot(self) -> dict[str, Any]:
        """Arrays a viewer needs (numpy copies): geometry, stylized and ground-truth colours, versions."""
        p, run = self.params, self.run_state
        colors = feathered_colours(run, run.c_s) if self.phase in STYLIZED_PHASES else run.gt_rgb()
        if self.live_children is not None:  # a run on a cut: its kept rows and every child, as the result has them
            arrays = {k: p[k].detach().numpy() for k in ("means", "log_scales", "quats", "opacity_logits")}
            return {**self.live_children.snapshot(
                run.geometry_key(), arrays, colors.detach().clamp(0, 1).numpy().astype(np.float32),
                run.gt_rgb().detach().numpy().astype(np.float32), run.lineage.numpy(), self.selection,
                bool(self.settings.keep_colours)),
                "geometry_version": run.geometry_version, "colour_version": run.colour_version, "phase": self.phase}
        return {
            "means": p["means"].detach().numpy().copy(),
            "log_scales": p["log_scales"].detach().numpy().copy(),
            "quats": p["quats"].detach().numpy().copy(),
            "opacity_logits": p["opacity_logits"].detach().numpy().copy(),
            "colors": colors.detach().clamp(0, 1).numpy().copy(),
            "colors_gt": run.gt_rgb().detach().clamp(0, 1).numpy().copy(),
            "selected": self.selection,
            "geometry_version": run.geometry_version,
            "colour_version": run.colour_version,
            "phase": self.phase,
        }

    def stylized_scene(self) -> GaussianScene:
        """The current scene with c_s as its (SH degree 0) colour. A region run: the Gaussians outside the selection
        are the input's rows exactly (every attribute, their SH bands included; stylized ones get zero bands)."""
        scene = scene_from_params(self.params)
        scene.sh_dc = rgb_to_sh_dc(feathered_colours(self.run_state, self.c_s.detach()).clamp(0, 1).numpy())
        scene = merge_unselected(scene, self.input_scene, self.run_state.active)
        selected = self.run_state.active.selected  # a capture larger than the run held: the rest joins it
        whole = with_neighbour_colours(scene, self.cut_input, self.capacity,
                                       None if selected is None else selected.numpy(), self.cut_selection)
        if self.lod is None:
            return whole
        return whole_capture(whole, self.run_state.gt_rgb().numpy().astype(np.float64),
                             self.run_state.lineage.numpy(), self.capacity, self.lod, self.full_input,
                             self.full_selection, bool(self.settings.keep_colours))

    # ----------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict[str, Any]:
        """Everything needed to resume: the run state and each phase's state under its name (copies)."""
        return {"engine_state": ENGINE_STATE, "phase": self.phase, "global_step": self.global_step,
                "phase_step": self.phase_step, "settings": self.settings.to_dict(),
                "capacity": (self.capacity.max_gaussians, self.capacity.how),
                "run": self.run_state.state_dict(), "phases": {p.name: p.state_dict() for p in self.phases}}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore ``state_dict()`` into an engine built for the same inputs; ``ValueError`` when it does not fit
        (its layout, its phases and a region's presence are checked before anything changes)."""
        if state.get("engine_state") != ENGINE_STATE:
            raise ValueError(f"engine state layout {state.get('engine_state')!r}, this engine reads {ENGINE_STATE}")
        saved_widths = tuple((state.get("settings") or {}).get("refine_widths") or ())
        for width in saved_widths[len(self.settings.refine_widths):]:  # levels added to the saved run (refine())
            if saved_widths[:len(self.settings.refine_widths)] != self.settings.refine_widths:
                break
            self.refine(width)
        names = {p.name for p in self.phases}
        if set(state["phases"]) != names:
            raise ValueError(f"the checkpoint's phases {sorted(state['phases'])} differ from this run's "
                             f"{sorted(names)} (another colour_match_after setting?)")
        self.run_state.load_state_dict(state["run"])
        for p in self.phases:
            p.load_state_dict(state["phases"][p.name])
        self.phase_step = int(state["phase_step"])
        saved = state.get("settings") or {}
        if len(saved.get("style_weights") or ()) == len(self.styles) > 1:  # the mix as it was (content targets too)
            self.settings.style_weights = normalise_style_weights(saved["style_weights"], len(self.styles))
        # a resumed run keeps its stroke size and keep colours; the painting's features follow them and the mix
        kept = {"style_scale": saved.get("style_scale"), "keep_colours": saved.get("keep_colours")}
        # ... and a finished run's palette match is this engine's (not in the fingerprint: it can be re-applied)
        self.live.carry_out(apply_controls(self.settings, kept) | Effect.STYLE_FEATURES | Effect.PALETTE_MATCH)
        self._settle()

