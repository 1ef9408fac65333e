"""One stylization step dissected (docs/texture-scale.md): the texture scale of what each term asks for, and the
multi-scale term's cost.

``spectrum``: the engine runs to the start of stylization; then for a few training views and each term (NNFM,
content, TV at the settings' stroke size; NNFM and the multi-scale term at every ``--scales`` stroke size) the band
shares (``style/texture_scale.py``, over the view's coverage, at the working width) of

* ``dL_dimage``: the loss's gradient with respect to the rendered image,
* ``render_grad``: the colour gradient of every Gaussian rendered back into the view (what the footprints keep),
* ``adam_step``: Adam's first update rendered (lr·sign(g): every colour moves by the same amount),
* ``shared_step``: the same step under one shared normalisation (g / RMS(g)).

``time``: one view's render + objective + backward with and without the multi-scale term, alternated in one process
(a shared machine's load drifts over both alike); medians.

    python bench/scale_step.py spectrum --style ../shared/data/styles/starry_night_vangogh.jpg
    python bench/scale_step.py time ../shared/data/scenes/playcanvas/biker.spz --style ...
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scale_causes import WithMultiScale  # noqa: E402

from gstyle_core.pipeline.cli import add_stylize_arguments, build_stylizer  # noqa: E402
from gstyle_core.style.multiscale import MultiScaleStyleLoss  # noqa: E402
from gstyle_core.style.texture_scale import band_energies, shares  # noqa: E402

KINDS = ("dL_dimage", "render_grad", "adam_step", "shared_step")


def engine_at_stylize(args: argparse.Namespace):
    """The engine built as ``gstyle stylize`` builds it, stepped to its first stylization step."""
    engine, *_ = build_stylizer(args)
    while engine.phase != "stylize":
        engine.step()
    return engine


def term_loss(engine, objective, term: str, multiscale, image: torch.Tensor, view: int) -> torch.Tensor:
    """One term's loss of a render of ``view`` (the others' weights 0)."""
    coverage = engine.objective_coverage(view)
    if term == "multiscale":
        box = objective.network_box(view, coverage)
        img, cov = (image, coverage) if box is None else (image[box], coverage[box])
        return multiscale(img.permute(2, 0, 1)[None], cov)
    loss, _ = objective(image, engine.content_images[view], view, coverage=coverage)
    return loss


def spectrum(args: argparse.Namespace, views: list[int], scales: list[float]) -> list[dict]:
    """Band shares of each term's gradient and first steps (see the module docstring)."""
    engine = engine_at_stylize(args)
    objective = engine._objective_fn()
    ids = engine._seen()
    weights = dict(objective.loss.weights.__dict__)
    default_scale = engine.settings.style_scale
    rows = []
    for scale in scales:
        engine.settings.style_scale = scale
        objective.refresh_style()
        multiscale = MultiScaleStyleLoss(objective.vgg, objective._styles_small)
        terms = ("nnfm", "content", "tv", "multiscale") if scale == default_scale else ("nnfm", "multiscale")
        for term in terms:
            if term != "multiscale":
                objective.loss.weights = {k: (v if k == term else 0.0) for k, v in weights.items()}
            energy = {k: np.zeros(3) for k in KINDS}
            for view in views:
                colours = (engine.c_s if ids is None else engine.c_s[ids]).clone().requires_grad_(True)
                image = engine._render_cs(view, colours)
                image.retain_grad()
                term_loss(engine, objective, term, multiscale, image, view).backward()
                g = colours.grad.detach()
                mask = engine.objective_coverage(view)
                mask = None if mask is None else mask.numpy()
                visible = g.abs().amax(1) > 0
                with torch.no_grad():
                    energy["dL_dimage"] += band_energies(image.grad.numpy(), mask)
                    energy["render_grad"] += band_energies(engine._render_cs(view, g).numpy(), mask)
                    energy["adam_step"] += band_energies(engine._render_cs(view, torch.sign(g)).numpy(), mask)
                    rms = g[visible].pow(2).mean().sqrt().clamp_min(1e-30)
                    energy["shared_step"] += band_energies(engine._render_cs(view, g / rms).numpy(), mask)
            objective.loss.weights = weights
            row = {"S": scale, "term": term, **{k: [round(float(v), 3) for v in shares(e)] for k, e in energy.items()}}
            print(json.dumps(row), flush=True)
            rows.append(row)
    return rows


def step_time(args: argparse.Namespace, rounds: int, weight: float) -> dict:
    """Median seconds of one view's render + objective + backward, without and with the multi-scale term."""
    engine = engine_at_stylize(args)
    objective = engine._objective_fn()
    wrapped = WithMultiScale(objective, weight, (2.0, 4.0))
    ids = engine._seen()

    def one(fn, view: int) -> float:
        colours = (engine.c_s if ids is None else engine.c_s[ids]).clone().requires_grad_(True)
        t0 = time.perf_counter()
        image = engine._render_cs(view, colours)
        loss, _ = fn(image, engine.content_images[view], view, coverage=engine.objective_coverage(view))
        loss.backward()
        return time.perf_counter() - t0

    times: dict[str, list[float]] = {"nnfm": [], "nnfm+multiscale": []}
    n = len(engine.cameras)
    for view in {(r * 5) % n for r in range(rounds)}:  # warm-up: content features are cached per view
        one(objective, view)
    one(wrapped, 0)
    for r in range(rounds):
        view = (r * 5) % n
        pair = [("nnfm", objective), ("nnfm+multiscale", wrapped)]
        for name, fn in pair if r % 2 == 0 else pair[::-1]:  # alternate which goes first
            times[name].append(one(fn, view))
    out = {k: round(float(np.median(v)), 4) for k, v in times.items()}
    out["ratio"] = round(out["nnfm+multiscale"] / out["nnfm"], 3)
    out["gaussians"] = engine.gaussian_count
    print(json.dumps(out), flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mode", choices=("spectrum", "time"))
    add_stylize_arguments(p)
    p.add_argument("--views", default="0,5,10", help="spectrum: training views to sum over")
    p.add_argument("--scales", default="0.5,1,2", help="spectrum: stroke sizes")
    p.add_argument("--rounds", type=int, default=12, help="time: alternations")
    p.add_argument("--multiscale", type=float, default=200.0, help="time: the term's λ")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.mode == "spectrum":
        spectrum(args, [int(v) for v in args.views.split(",")], [float(s) for s in args.scales.split(",")])
    else:
        step_time(args, args.rounds, args.multiscale)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
