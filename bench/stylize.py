"""Per-phase timing of a stylization run, and the stylize step against its floor (every network pass it runs).

Prints where it ran (the CPU's model and the flags that decide its speed, torch threads), the run's precision
(``--precision``, default auto, with the reason), the floor on a whole frame at both precisions (fp32 and bf16), a
per-phase table, a table of where the stylize step's time goes, and
``RESULT step_over_floor=X same_pixels=Y``: X = mean stylization step time / (views per step × the floor of a whole
frame at the working resolution), measured in the same run; Y = the step against its floor on the same pixels. The
floor is every network pass the objective runs, forward and backward: VGG-16 (conv1_1…relu3_3) + NNFM on what the
step's networks saw (for an object scene without photos, the box of each view that the scene covers,
``engine/scene_box.py``) and, with the broad-strokes term, VGG + NNFM on each of its levels (×2, ×4, ×8 of the box
grown by the coarsest factor), summed over the step's views. ``--whole-frames`` switches the boxes off
(``crop_to_scene = False``) to compare. Both floors are at the run's precision (the other precision's network is
loaded only for the plain whole-frame VGG + NNFM time). ``--levels`` goes on into the finer levels and adds their
steps against their own floors (``level<W>_crop_over_floor``, ``level<W>_whole_over_floor``).

    .venv/bin/python bench/stylize.py [SCENE] [--style IMAGE] [--preset preview] [--steps 60]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine.build import build_stylizer  # noqa: E402
from gstyle_core.engine.visible_adam import VisibleAdam  # noqa: E402
from gstyle_core.machine import cpu_description, set_torch_threads  # noqa: E402
from gstyle_core.raster import colour_cache  # noqa: E402
from gstyle_core.style import losses, nnfm  # noqa: E402
from gstyle_core.style.features import concat_features  # noqa: E402
from gstyle_core.style.nnfm import StyleTarget, WeightedTargets, style_nnfm  # noqa: E402
from gstyle_core.style.precision import torch_dtype  # noqa: E402
from gstyle_core.style.vgg import load_vgg  # noqa: E402


class PartTimer:
    """Wall time spent inside chosen functions during the stylize steps (bench-only wrappers, removed after)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.active = False
        self._undo: list = []

    def wrap(self, owner, name: str, part: str) -> None:
        original = getattr(owner, name)

        def timed(*args, **kwargs):
            if not self.active:
                return original(*args, **kwargs)
            t0 = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.seconds[part] += time.perf_counter() - t0

        self._undo.append((owner, name, original, name in vars(owner)))  # whether ``owner`` held it itself
        setattr(owner, name, timed)

    def restore(self) -> None:
        for owner, name, original, own in reversed(self._undo):
            if own:
                setattr(owner, name, original)
            else:
                delattr(owner, name)

    @contextmanager
    def on(self):
        self.active = True
        try:
            yield
        finally:
            self.active = False


PARTS = (
    "VGG forward",
    "NNFM forward",
    "backward (all terms)",
    "content term forward",
    "content features (once per view)",
    "TV forward",
    "CLIP / coarse substitute forward",
    "Adam step",
    "colour cache: builds",
    "colour cache: render",
    "colour cache: backward",
)


def instrument(engine) -> PartTimer:
    """Time the parts of the stylize step: the colour cache (builds, render, its backward), the networks' forward
    passes and loss terms, the whole backward pass and the optimiser step."""
    timer = PartTimer()
    objective = engine.build_objective()
    timer.wrap(colour_cache.ColourCache, "__init__", "colour cache: builds")
    timer.wrap(colour_cache.ColourCache, "render", "colour cache: render")
    timer.wrap(colour_cache.SparseProduct, "backward", "colour cache: backward")
    timer.wrap(objective.loss.vgg, "forward", "VGG forward")
    if hasattr(objective.loss.vgg, "stacked"):  # the loss terms' passes give the layers' stack
        timer.wrap(objective.loss.vgg, "stacked", "VGG forward")
    timer.wrap(objective.loss, "content_features", "content features (once per view)")
    timer.wrap(nnfm, "nnfm_loss", "NNFM forward")
    timer.wrap(losses, "stacked_content_loss", "content term forward")
    timer.wrap(losses, "tv_loss", "TV forward")
    if objective.loss.clip_term is not None:
        # the coarse substitute's forward goes through per_image, which takes a step's views in one pass too
        method = "per_image" if hasattr(objective.loss.clip_term, "per_image") else "forward"
        timer.wrap(objective.loss.clip_term, method, "CLIP / coarse substitute forward")
    timer.wrap(torch.Tensor, "backward", "backward (all terms)")
    timer.wrap(VisibleAdam, "step", "Adam step")
    timer.wrap(torch.optim.Adam, "step", "Adam step")
    return timer


def floor_time(objective, height: int, width: int, repeats: int = 7,
               coarse: tuple[int, int] | None = None, content_forward: bool = False) -> float:
    """Median time of every network pass the objective runs on a [1, 3, H, W] view, forward and backward: VGG +
    NNFM, and with the broad-strokes term (``objective.loss.multiscale_term``, weight > 0) VGG + NNFM on each of its
    levels, taken from a ``coarse`` (h, w) view (the grown box it sees; default the same size); ``content_forward``:
    also VGG forward on the content target (a level's random crop has no cached content features). ``objective``:
    anything with ``vgg`` and ``target`` (and optionally ``loss``), e.g. the run's objective."""
    from gstyle_core.style.features import upsample_for_vgg, vgg_input_size
    from gstyle_core.style.multiscale import downsample

    term = getattr(getattr(objective, "loss", None), "multiscale_term", None)
    if term is not None and not getattr(objective.loss.weights, "multiscale", 0) > 0:
        term = None
    times = []
    for _ in range(repeats + 2):
        img = torch.rand(1, 3, height, width, requires_grad=True)
        t0 = time.perf_counter()
        if content_forward:
            with torch.no_grad():
                objective.vgg(torch.rand(1, 3, height, width))
        loss = style_nnfm(concat_features(objective.vgg(img)), objective.target)
        if term is not None:
            wide = torch.rand(1, 3, *(coarse or (height, width)), requires_grad=True)
            for factor, target in zip(term.factors, term.targets, strict=True):
                small = downsample(wide, factor)
                if tuple(small.shape[-2:]) != vgg_input_size(small.shape[-2:]):
                    small = upsample_for_vgg(small)
                loss = loss + style_nnfm(concat_features(objective.vgg(small)), target)
        loss.backward()
        times.append(time.perf_counter() - t0)
    return statistics.median(times[2:])


class Networks:
    """A VGG and a style target at one precision, for :func:`floor_time`."""

    def __init__(self, vgg, target) -> None:
        self.vgg, self.target = vgg, target


def networks_at(engine, precision: str):
    """The run's own networks at its precision; at the other, the same weights and painting features (the target's
    search in that precision)."""
    objective = engine.objective
    if objective.precision == precision:
        return Networks(objective.vgg, objective.target)
    dtype = torch_dtype(precision)
    vgg = load_vgg(engine.settings.vgg_weights, dtype=dtype, channels_last=precision == "bf16")
    target = objective.target
    parts = target.targets if isinstance(target, WeightedTargets) else [target]
    copies = [StyleTarget(t.matrix, t.scales, search_dtype=dtype) for t in parts]
    return Networks(vgg, WeightedTargets(copies, target.weights) if isinstance(target, WeightedTargets) else copies[0])


def network_sizes(engine) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """(height, width) of what VGG sees in each training view (the view, or its scene box) and of what the
    broad-strokes term's levels are taken from (the box grown by its coarsest factor)."""
    out = []
    objective = engine.objective
    term = objective.loss.multiscale_term
    for view, cam in enumerate(engine.cameras):
        coverage = engine.objective_coverage(view)
        sizes = []
        for grow in (1, int(max(term.factors)) if term is not None else 1):
            box = objective.network_box(view, coverage, grow=grow)
            sizes.append((cam.height, cam.width) if box is None else
                         (box[0].stop - box[0].start, box[1].stop - box[1].start))
        out.append((sizes[0], sizes[1]))
    return out


def run_timed(engine, steps: int, warmup: int = 5) -> tuple[dict[str, list[float]], list[float], PartTimer | None,
                                                             list[int]]:
    """Step the engine to ``steps`` timed stylize steps (after ``warmup`` untimed ones): the seconds of every step per
    phase, of every stylize step with losses (the untimed ones first), the part timer of the timed steps and the
    views of each timed step."""
    phase_times: dict[str, list[float]] = {}
    stylize_times: list[float] = []
    timer: PartTimer | None = None
    step_views: list[int] = []
    while not engine.done and len(stylize_times) < steps + warmup:
        timed = engine.phase == "stylize" and len(stylize_times) >= warmup
        if timed and timer is None:
            timer = instrument(engine)
        if timed and engine.stylize.step_index not in engine.split_steps:
            step_views += engine.stylize.views_of_step()
        with timer.on() if timed else _nothing():
            rep = engine.step()
        phase_times.setdefault(rep.phase, []).append(rep.seconds)
        if rep.phase == "stylize" and rep.losses:
            stylize_times.append(rep.seconds)
    if timer is not None:
        timer.restore()
    return phase_times, stylize_times, timer, step_views


def print_parts(engine, timer: PartTimer, n: int, step: float, same_floor: float) -> None:
    """Where a stylize step goes: the mean seconds inside each part over ``n`` timed steps."""
    print(f"where a stylize step goes (mean over {n} steps; wall time inside each part; the backward pass "
          "includes VGG's, NNFM's and the colour cache's backward):")
    print(f"{'part':>36} {'s / step':>9} {'share':>7}")
    for part in PARTS:
        secs = timer.seconds.get(part, 0.0)
        note = ""
        if part == "CLIP / coarse substitute forward" and engine.objective.loss.clip_term is None:
            note = "  (off: λ_CLIP = 0)"
        elif part == "content features (once per view)" and secs == 0.0:
            note = "  (cached before the timed steps)"
        print(f"{part:>36} {secs / n:>9.4f} {100 * secs / n / step:>6.1f}%{note}")
    other = step - sum(timer.seconds.values()) / n
    print(f"{'rest (step bookkeeping, grad norms)':>36} {other:>9.4f} {100 * other / step:>6.1f}%")
    print(f"{'floor on the same pixels':>36} {same_floor:>9.4f} {100 * same_floor / step:>6.1f}%")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--steps", type=int, default=60, help="stylization steps to time (after warm-up)")
    p.add_argument("--warmup", type=int, default=5, help="stylization steps not timed first")
    p.add_argument("--whole-frames", action="store_true", help="VGG on whole frames (crop_to_scene = False)")
    p.add_argument("--levels", action="store_true",
                   help="go on into the finer levels (--refine-widths or the preset's) and time their steps too")
    args = p.parse_args()
    print(f"cpu: {cpu_description()}")
    if args.threads:
        set_torch_threads(args.threads)
    request = build_request(args)
    request.overrides["crop_to_scene"] = not args.whole_frames
    engine, scene, _, cams, _ = build_stylizer(request)
    phase_times, stylize_times, timer, step_views = run_timed(engine, args.steps, args.warmup)
    cam = engine.cameras[0]
    pairs = network_sizes(engine)
    sizes = [p[0] for p in pairs]
    floors = {pair: floor_time(engine.objective, *pair[0], coarse=pair[1]) for pair in sorted(set(pairs))}
    floor = statistics.mean(floors[pair] for pair in pairs)
    full_floor = floor_time(engine.objective, cam.height, cam.width)
    at = {p: floor_time(networks_at(engine, p), cam.height, cam.width) for p in ("fp32", "bf16")}
    timed_steps = stylize_times[args.warmup:]
    step = statistics.mean(timed_steps) if timed_steps else float("nan")
    views_per_step = engine.settings.views_per_step
    # the floor on the same pixels: each timed step's own views (their boxes), summed
    same_floor = (sum(floors[pairs[v]] for v in step_views) / len(timed_steps)) if timed_steps else float("nan")
    print(f"scene: {scene.count} Gaussians, {len(engine.cameras)} views, working {cam.width}x{cam.height}, "
          f"{views_per_step} view(s) per step, torch threads {torch.get_num_threads()}")
    print(f"{'phase':>14} {'steps':>6} {'total s':>9} {'mean s':>8}")
    for phase, ts in phase_times.items():
        print(f"{phase:>14} {len(ts):>6} {sum(ts):>9.2f} {statistics.mean(ts):>8.3f}")
    share = statistics.mean(h * w for h, w in sizes) / (cam.height * cam.width)
    print(f"VGG sees {100 * share:.0f} % of the frame's pixels on average ({engine.decisions.get('network_area')})")
    print(f"precision: {engine.decisions.get('precision')}")
    print(f"one VGG + NNFM fwd+bwd on a whole frame at {cam.width}x{cam.height}: fp32 {at['fp32']:.3f} s, bf16 "
          f"{at['bf16']:.3f} s (fp32/bf16 {at['fp32'] / at['bf16']:.2f}); the figures below are at "
          f"{engine.objective.precision}")
    print(f"{'floor (every network pass, fwd+bwd)':>36}: {full_floor:.3f} s a view at {cam.width}x{cam.height}, "
          f"{floor:.3f} s a view on the pixels VGG sees; stylize step mean {step:.3f} s ({views_per_step} view(s))")
    if timer is not None and timed_steps:
        print_parts(engine, timer, len(timed_steps), step, same_floor)
    print(f"per-pixel: step / floor on the same pixels = {step / same_floor:.2f}")
    levels = time_levels(engine, args.steps, floor) if args.levels else {}
    print(f"RESULT step_over_floor={step / (views_per_step * full_floor):.2f} same_pixels={step / same_floor:.2f} "
          f"precision={engine.objective.precision} floor_fp32={at['fp32']:.3f} floor_bf16={at['bf16']:.3f}"
          + "".join(f" {k}={v:.2f}" for k, v in levels.items()))


def time_levels(engine, steps: int, view_floor: float) -> dict[str, float]:
    """Step on into the finer levels and time ``steps`` of each (after 2 untimed ones): their crop steps against the
    floor of the level's networks on a crop (VGG + NNFM at the level's painting size, and VGG forward on the crop's
    content target), their whole-view steps at the
    working width against the stylization's floor (``view_floor`` a view). Prints a row per level; returns the
    ratios for the RESULT line."""
    from gstyle_core.engine.phases.refine import CROP_TERMS, Refine

    out: dict[str, float] = {}
    while not engine.done:
        level = next((p for p in engine.phases if isinstance(p, Refine) and not p.finished), None)
        if level is None:
            break
        kinds: dict[bool, list[float]] = {True: [], False: []}
        while not level.finished:
            crop = level.targets_done and level.crop_step()
            rep = engine.step()
            if level.targets_done and rep.losses and level.step_index > 2:
                kinds[crop].append(rep.seconds)
            if len(kinds[True]) + len(kinds[False]) >= steps:
                break
        cam = engine.cameras[0]
        terms = CROP_TERMS if level.mode == "crops" else None
        crop_floor = floor_time(engine.run_state.level_objective(level.width, terms), cam.height, cam.width,
                                content_forward=True)
        per = engine.settings.views_per_step
        rows = [("crop" if level.mode == "crops" else "whole view", kinds[True], per * crop_floor),
                ("whole view at the working width", kinds[False], per * view_floor)]
        for name, times, floor in rows:
            if times:
                ratio = statistics.mean(times) / floor
                print(f"level {level.width} px, {name} steps: {statistics.mean(times):.3f} s, floor {floor:.3f} s, "
                      f"step / floor {ratio:.2f} ({len(times)} steps)")
                out[f"level{level.width}_{name.split()[0]}_over_floor"] = ratio
        while not level.finished:  # the rest of the level untimed
            engine.step()
    return out


@contextmanager
def _nothing():
    yield


if __name__ == "__main__":
    main()
