"""One stylization step dissected (docs/notes/texture-scale.md): the texture scale of what each term asks for, and the
multi-scale term's cost.

``spectrum``: the engine runs to the start of stylization; then for a few training views and each term (NNFM,
content, TV at the settings' stroke size; NNFM and the multi-scale term at every ``--scales`` stroke size) the band
shares (``style/texture_scale.py``, over the view's coverage, at the working width) of

* ``dL_dimage``: the loss's gradient with respect to the rendered image,
* ``render_grad``: the colour gradient of every Gaussian rendered back into the view (what the footprints keep),
* ``adam_step``: Adam's first update rendered (lr·sign(g): every colour moves by the same amount),
* ``shared_step``: the same step under one shared normalisation (g / RMS(g)).

Each term alone: the engine's objective (``engine.build_objective()``) with that term's weight 1 and the others 0
(``objective.set_weights``; the broad-strokes term is built on demand), on ``engine.render(view, colours)`` of every
Gaussian's colour.

``time``: one view's render + objective + backward with the broad-strokes (multi-scale) term on (at the settings'
``lambda_multiscale``, or ``--multiscale``; λ_NNFM when the settings have it off) and off (0), the same objective
alternated in one process (a shared machine's load drifts over both alike); medians and their ratio. ``--versus
2,4`` also times the term at those downsampling factors (``MultiScaleStyleLoss.with_factors``) in the same rotation.

    python bench/studies/scale_step.py spectrum --style ../shared/data/styles/starry_night_vangogh.jpg
    python bench/studies/scale_step.py time ../shared/data/scenes/playcanvas/biker.spz --style ...
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine.build import build_stylizer  # noqa: E402
from gstyle_core.style.losses import StyleWeights  # noqa: E402
from gstyle_core.style.texture_scale import band_energies, shares  # noqa: E402

KINDS = ("dL_dimage", "render_grad", "adam_step", "shared_step")
TERMS = tuple(StyleWeights.__dataclass_fields__)  # clip, nnfm, content, tv, multiscale


def engine_at_stylize(args: argparse.Namespace):
    """The engine built as ``gstyle stylize`` builds it, stepped to its first stylization step."""
    engine = build_stylizer(build_request(args)).engine
    while engine.phase != "stylize":
        engine.step()
    return engine


def alone(term: str) -> StyleWeights:
    """Weights with ``term`` at 1 and every other term at 0."""
    return StyleWeights(**{name: float(name == term) for name in TERMS})


def term_loss(engine, objective, image: torch.Tensor, view: int) -> torch.Tensor:
    """The objective's loss of a render of ``view`` (at the weights it has now)."""
    loss, _ = objective(image, engine.content_images[view], view, coverage=engine.objective_coverage(view))
    return loss


def spectrum(args: argparse.Namespace, views: list[int], scales: list[float]) -> list[dict]:
    """Band shares of each term's gradient and first steps (see the module docstring)."""
    engine = engine_at_stylize(args)
    objective = engine.build_objective()
    weights = engine.settings.weights
    default_scale = engine.settings.style_scale
    rows = []
    for scale in scales:
        engine.settings.style_scale = scale
        objective.refresh_style()
        terms = ("nnfm", "content", "tv", "multiscale") if scale == default_scale else ("nnfm", "multiscale")
        for term in terms:
            objective.set_weights(alone(term))  # the broad-strokes term is built the first time it is asked for
            energy = {k: np.zeros(3) for k in KINDS}
            for view in views:
                colours = engine.c_s.clone().requires_grad_(True)
                image = engine.render(view, colours)
                image.retain_grad()
                term_loss(engine, objective, image, view).backward()
                g = colours.grad.detach()  # zero on the Gaussians no training view sees
                mask = engine.objective_coverage(view)
                mask = None if mask is None else mask.numpy()
                visible = g.abs().amax(1) > 0
                with torch.no_grad():
                    energy["dL_dimage"] += band_energies(image.grad.numpy(), mask)
                    energy["render_grad"] += band_energies(engine.render(view, g).numpy(), mask)
                    energy["adam_step"] += band_energies(engine.render(view, torch.sign(g)).numpy(), mask)
                    rms = g[visible].pow(2).mean().sqrt().clamp_min(1e-30)
                    energy["shared_step"] += band_energies(engine.render(view, g / rms).numpy(), mask)
            row = {"S": scale, "term": term, **{k: [round(float(v), 3) for v in shares(e)] for k, e in energy.items()}}
            print(json.dumps(row), flush=True)
            rows.append(row)
    objective.set_weights(weights)
    return rows


def step_time(args: argparse.Namespace, rounds: int, weight: float | None,
              versus: tuple[float, ...] | None = None) -> dict:
    """Median seconds of one view's render + objective + backward, without and with the broad-strokes term (the
    same objective, its weight switched: ``weight``, default the settings' λ, or λ_NNFM when that is 0); with
    ``versus`` also with the term at those downsampling factors."""
    engine = engine_at_stylize(args)
    objective = engine.build_objective()
    base = engine.settings.weights
    if weight is None:
        weight = base.multiscale if base.multiscale > 0 else base.nnfm
    with_term, without = replace(base, multiscale=float(weight)), replace(base, multiscale=0.0)

    def one(weights: StyleWeights, view: int, term=None) -> float:
        objective.set_weights(weights)
        if term is not None:
            objective.loss.multiscale_term = term
        colours = engine.c_s.clone().requires_grad_(True)
        t0 = time.perf_counter()
        image = engine.render(view, colours)
        term_loss(engine, objective, image, view).backward()
        return time.perf_counter() - t0

    n = len(engine.cameras)
    for view in {(r * 5) % n for r in range(rounds)}:  # warm-up: content features are cached per view
        one(without, view)
    one(with_term, 0)  # builds the term if the settings had it off
    shipped = objective.loss.multiscale_term
    runs = [("nnfm", without, None), ("nnfm+multiscale", with_term, shipped)]
    if versus:
        other = shipped.with_factors(versus)
        one(with_term, 0, other)
        runs.append((f"nnfm+multiscale x{','.join(f'{f:g}' for f in versus)}", with_term, other))
    times: dict[str, list[float]] = {name: [] for name, _, _ in runs}
    for r in range(rounds):
        view = (r * 5) % n
        for name, weights, term in runs[r % len(runs):] + runs[:r % len(runs)]:  # rotate which goes first
            times[name].append(one(weights, view, term))
    objective.loss.multiscale_term = shipped
    objective.set_weights(base)
    out = {k: round(float(np.median(v)), 4) for k, v in times.items()}
    out["ratio"] = round(out["nnfm+multiscale"] / out["nnfm"], 3)
    out["factors"] = list(shipped.factors)
    out["lambda_multiscale"] = float(weight)
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
    p.add_argument("--multiscale", type=float, default=None,
                   help="time: the term's λ when on (default: the settings' lambda_multiscale, or λ_NNFM if that is 0)")
    p.add_argument("--versus", default=None, help="time: also the term at these factors, e.g. 2,4")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.mode == "spectrum":
        spectrum(args, [int(v) for v in args.views.split(",")], [float(s) for s in args.scales.split(",")])
    else:
        versus = None if args.versus is None else tuple(float(f) for f in args.versus.split(","))
        step_time(args, args.rounds, args.multiscale, versus)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
