"""Per-phase timing of a stylization run, and the stylize step against its floor (VGG + NNFM).

Prints a per-phase table and ``RESULT step_over_floor=X``: X = mean stylization step time / the time of a VGG-16
(conv1_1…relu3_3) + NNFM forward+backward at the same working resolution, measured in the same run. For an object
scene without photos the step's VGG sees only the box of each view that the scene covers
(``pipeline/scene_box.py``); the floor on those same pixels (mean over the training views) is printed too, as
``per-pixel``. ``--whole-frames`` switches the boxes off (``crop_to_scene = False``) to compare.

    .venv/bin/python bench/stylize.py [SCENE] [--style IMAGE] [--preset preview] [--steps 60]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gstyle_core.pipeline.cli import add_stylize_arguments, build_stylizer  # noqa: E402
from gstyle_core.style.losses import concat_features, nnfm_loss  # noqa: E402


def floor_time(objective, height: int, width: int, repeats: int = 7) -> float:
    """Median time of VGG forward+backward + NNFM on a [1, 3, H, W] image."""
    times = []
    for _ in range(repeats + 2):
        img = torch.rand(1, 3, height, width, requires_grad=True)
        t0 = time.perf_counter()
        loss = nnfm_loss(concat_features(objective.vgg(img)), objective.target)
        loss.backward()
        times.append(time.perf_counter() - t0)
    return statistics.median(times[2:])


def network_sizes(engine) -> list[tuple[int, int]]:
    """(height, width) of what VGG sees in each training view: the view, or its scene box."""
    out = []
    for view, cam in enumerate(engine.cameras):
        box = engine._objective.network_box(view, engine.objective_coverage(view))
        out.append((cam.height, cam.width) if box is None else (box[0].stop - box[0].start, box[1].stop - box[1].start))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--steps", type=int, default=60, help="stylization steps to time (after warm-up)")
    p.add_argument("--whole-frames", action="store_true", help="VGG on whole frames (crop_to_scene = False)")
    args = p.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    engine, scene, _, cams, _ = build_stylizer(args, crop_to_scene=not args.whole_frames)
    phase_times: dict[str, list[float]] = {}
    stylize_times: list[float] = []
    while not engine.done and len(stylize_times) < args.steps + 5:
        rep = engine.step()
        phase_times.setdefault(rep.phase, []).append(rep.seconds)
        if rep.phase == "stylize" and rep.losses:
            stylize_times.append(rep.seconds)
    cam = engine.cameras[0]
    sizes = network_sizes(engine)
    floors = {size: floor_time(engine._objective, *size) for size in sorted(set(sizes))}
    floor = statistics.mean(floors[size] for size in sizes)
    full_floor = floors.get((cam.height, cam.width)) or floor_time(engine._objective, cam.height, cam.width)
    step = statistics.mean(stylize_times[5:]) if len(stylize_times) > 5 else float("nan")
    print(f"scene: {scene.count} Gaussians, {len(engine.cameras)} views, working {cam.width}x{cam.height}, "
          f"torch threads {torch.get_num_threads()}")
    print(f"{'phase':>14} {'steps':>6} {'total s':>9} {'mean s':>8}")
    for phase, ts in phase_times.items():
        print(f"{phase:>14} {len(ts):>6} {sum(ts):>9.2f} {statistics.mean(ts):>8.3f}")
    share = statistics.mean(h * w for h, w in sizes) / (cam.height * cam.width)
    print(f"VGG sees {100 * share:.0f} % of the frame's pixels on average ({engine.decisions.get('network_area')})")
    print(f"{'floor (VGG+NNFM fwd+bwd)':>30}: {full_floor:.3f} s at {cam.width}x{cam.height}, {floor:.3f} s on the "
          f"pixels VGG sees; stylize step mean {step:.3f} s")
    print(f"per-pixel: step / floor on the same pixels = {step / floor:.2f}")
    print(f"RESULT step_over_floor={step / full_floor:.2f}")


if __name__ == "__main__":
    main()
