"""Where the added texture's bands come from: one stylization probed phase by phase (docs/notes/texture-scale.md).

Builds the engine ``gstyle stylize`` builds for the same options, steps it to the end and renders the evaluation
views (those ``evaluate_run`` measures, 256 px wide) at each phase boundary:

* ``input``: the scene as it came in (its SH bands included, as the figure's "before");
* ``preprocessed``: after pre-processing (splits, clamps, refit), with the ground-truth colours at SH degree 0;
* ``colour-matched``: the start of stylization (c_s after the first colour match);
* ``stylized``: after stylization with its splits and refits, before the final colour match;
* ``final``: the result (the figure's "after").

It prints the band energies (fine / middle / coarse, ``style/texture_scale.py``, weighted by the input's coverage) and
shares of the change between consecutive stages and of ``input → final`` (the texture-scale figure's "added"), beside
the painting's shares at its matched size. Energies of the steps do not add up to the whole: the cross terms between
two changes stay out of each. Last a ``RESULT`` line: the coarse ratio of the stylization's own change
(colour-matched → stylized) and of the whole (the figure's), and the share of the stylization's coarse energy the
final colour match keeps (colour-matched → final over colour-matched → stylized).

``--random-field 0,8,16,32``: for comparison, the shares of a smooth random colour change rendered on the input's
geometry (the same views): i.i.d. normal values on a trilinear lattice of P working-width px at the scene's median
distance (``colour_field.ColourField``, the engine's coherent-strokes lattice; 0: one value per Gaussian), RMS 0.1
about a grey of 0.5, so nothing clips. It shows which shares the scene's edges and occlusions allow a change of each
size, whatever the objective asks.

    python bench/studies/texture_phases.py ../shared/data/scenes/playcanvas/biker.spz \
        --style ../shared/data/styles/mandelbrot_color.png --precision fp32 --random-field 0,8,16,32
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine import colour_field  # noqa: E402
from gstyle_core.engine.build import build_stylizer  # noqa: E402
from gstyle_core.engine.run_figures import evaluation_cameras, run_texture_scale  # noqa: E402
from gstyle_core.fit.model import scene_from_params  # noqa: E402
from gstyle_core.scene import rgb_to_sh_dc  # noqa: E402
from gstyle_core.scene_images import render_scene_image  # noqa: E402
from gstyle_core.style.texture_scale import BAND_NAMES, added_energies, shares  # noqa: E402

EVAL_VIEWS, EVAL_WIDTH = 3, 256  # as evaluate_run
STAGES = ("input", "preprocessed", "colour-matched", "stylized", "final")
RANDOM_FIELD_RMS, RANDOM_FIELD_GREY = 0.1, 0.5


def render_views(scene, cameras, sh_degree: int | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Float64 renders and alphas of ``scene`` from each camera."""
    out = [render_scene_image(scene, c, sh_degree=sh_degree, with_alpha=True) for c in cameras]
    return [np.asarray(o[0], np.float64) for o in out], [np.asarray(o[1], np.float64) for o in out]


def ground_truth_scene(engine):
    """The current geometry with the ground-truth colours (SH degree 0)."""
    scene = scene_from_params(engine.params)
    scene.sh_dc = rgb_to_sh_dc(engine.run_state.gt_rgb().detach().clamp(0, 1).numpy())
    return scene


def stage_renders(engine, scene_in, cameras) -> tuple[dict[str, list[np.ndarray]], list[np.ndarray]]:
    """Run ``engine`` to the end, rendering ``cameras`` at every phase boundary (``STAGES``); returns the renders of
    each stage and the input's alphas (the weights of every change's energies)."""
    if engine.settings.region is not None or getattr(engine, "input_selection", None) is not None:
        raise SystemExit("texture_phases probes whole-scene runs only (no --region)")
    inputs, alphas = render_views(scene_in, cameras)
    images = {"input": inputs}
    boundaries = {"colour_match": ("preprocessed", lambda: ground_truth_scene(engine)),
                  "stylize": ("colour-matched", engine.stylized_scene),
                  "finish": ("stylized", engine.stylized_scene)}
    while not engine.done:
        stage = boundaries.pop(engine.phase, None)
        if stage is not None:
            images[stage[0]] = render_views(stage[1](), cameras)[0]
        engine.step()
    images["final"] = render_views(engine.stylized_scene(), cameras)[0]
    images.setdefault("stylized", images["final"])  # no final colour match (colour_match_after off)
    return images, alphas


def random_field_shares(scene_in, engine, cameras, alphas, cells_px: list[float], seed: int = 0) -> dict[str, list]:
    """Shares of a random colour change of each lattice size (module docstring) rendered from ``cameras``."""
    base = copy.deepcopy(scene_in)
    n = base.count
    means = torch.as_tensor(np.asarray(base.means, np.float32))
    footprint = colour_field.pixel_footprint(means.numpy(), engine.cameras)

    def render_colours(rgb: np.ndarray) -> list[np.ndarray]:
        base.sh_dc = rgb_to_sh_dc(rgb.astype(np.float32))
        return render_views(base, cameras, sh_degree=0)[0]

    grey = render_colours(np.full((n, 3), RANDOM_FIELD_GREY))
    gen = torch.Generator().manual_seed(seed)
    out = {}
    for px in cells_px:
        if px <= 0:
            change = torch.randn(n, 3, generator=gen)
        else:
            field = colour_field.ColourField(means, px * footprint, lr=0.0)
            with torch.no_grad():
                field.values.copy_(torch.randn(field.values.shape, generator=gen))
                change = field.sample()
        change = RANDOM_FIELD_RMS * change / change.std()
        rgb = np.clip(RANDOM_FIELD_GREY + change.numpy(), 0.0, 1.0)
        out[f"{px:g} px"] = shares(added_energies(grey, render_colours(rgb), alphas)).tolist()
    return out


def fmt(values) -> str:
    return " / ".join(f"{v:.2f}" for v in values)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--random-field", default="", metavar="P1,P2",
                   help="lattice sizes (px; 0: per Gaussian) of random colour changes to measure beside the run")
    p.add_argument("--json", default=None, help="also write the figures to this file")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    cells = [float(x) for x in args.random_field.split(",") if x.strip()]
    engine, scene_in, _, _, style = build_stylizer(build_request(args))
    cameras = evaluation_cameras(engine, EVAL_VIEWS, EVAL_WIDTH)
    t0 = time.perf_counter()
    images, alphas = stage_renders(engine, scene_in, cameras)
    seconds = time.perf_counter() - t0
    steps = [*zip(STAGES, STAGES[1:], strict=False), ("colour-matched", "final"), ("input", "final")]
    rows = {f"{a} → {b}": added_energies(images[a], images[b], alphas).tolist() for a, b in steps}
    figure = run_texture_scale(engine, style, images["input"], images["final"], alphas, EVAL_WIDTH).to_dict()
    painting = list(figure["painting"].values())
    print(f"{args.scene or 'demo'} × {', '.join(args.style or ['the bundled painting'])}: {engine.gaussian_count:,} "
          f"Gaussians, {seconds:.0f} s; painting at {figure['painting_side']} px: {fmt(painting)} "
          f"({' / '.join(BAND_NAMES)})")
    print(f"{'change':34s} {'energy f / m / c':>26s}   shares f / m / c   coarse ratio")
    for name, energy in rows.items():
        share = shares(np.asarray(energy))
        print(f"{name:34s} {' / '.join(f'{e:7.1f}' for e in energy):>26s}   {fmt(share):16s}   "
              f"{share[2] / painting[2]:.2f}")
    fields = random_field_shares(scene_in, engine, cameras, alphas, cells) if cells else {}
    for name, share in fields.items():
        print(f"random change, lattice {name:>7s}: {fmt(share)}")
    own, whole = shares(np.asarray(rows["colour-matched → stylized"])), shares(np.asarray(rows["input → final"]))
    kept = rows["colour-matched → final"][2] / max(rows["colour-matched → stylized"][2], 1e-12)
    print(f"RESULT stylization_coarse_ratio={own[2] / painting[2]:.2f} added_coarse_ratio={whole[2] / painting[2]:.2f} "
          f"coarse_energy_kept_by_final_match={kept:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"scene": args.scene, "style": args.style, "seconds": seconds,
                                               "painting": painting, "changes": rows, "random_field": fields,
                                               "settings": engine.settings.to_dict()}, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
