"""Where the speckle at the display's size comes from: one stylization probed at every phase boundary.

Builds the engine ``gstyle stylize`` builds for the same options, steps it to the end and renders the evaluation views
(those ``evaluate_run`` measures) ``--display-width`` px wide at each boundary: after the first colour match (the start
of stylization), after the stylization at the working width (before any finer level), after each finer level
(``refine_K``), and the result. For each stage it prints the speckle ratio (``style/speckle.py``: the fine share of the
chroma added since the input, against the painting's at its matched size in display pixels), per view and over the
views, the added chroma's fine and whole energy (summed over the views), the energy and fine share of the stage's own
change (against the stage before), the fringe halo and the fringe's near-saturated share (``style/fringe.py``), and the
seconds the engine had spent by then, the structure kept at that width (``evaluate.structure_kept``: the
input's edges against the stage's), and the NNFM drop at the working width (as ``evaluate_run`` measures it: where a
tier's drop at 256 px goes, phase by phase). After pre-processing the new geometry is rendered with the ground-truth
colours. Last a ``RESULT`` line with the ratio after the working width and at the end, the result's structure and
its drop at the working width.

    python bench/studies/display_phases.py --style ../shared/data/styles/the_scream_munch.jpg --refine-widths 512,1024
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine.build import build_stylizer  # noqa: E402
from gstyle_core.engine.evaluate import structure_kept  # noqa: E402
from gstyle_core.engine.run_figures import evaluation_cameras, figure_evaluator  # noqa: E402
from gstyle_core.scene_images import render_scene_image  # noqa: E402
from gstyle_core.style.fringe import fringe_halo  # noqa: E402
from gstyle_core.style.speckle import FINE_BANDS, chroma_energies, display_speckle, fine_share  # noqa: E402
from gstyle_core.style.texture_scale import matched_side  # noqa: E402
from gstyle_core.style.vgg import load_vgg  # noqa: E402

EVAL_VIEWS = 3  # as evaluate_run


def ground_truth_scene(engine):
    """The current geometry with the ground-truth colours (SH degree 0)."""
    from gstyle_core.fit.model import scene_from_params
    from gstyle_core.scene import rgb_to_sh_dc

    scene = scene_from_params(engine.params)
    scene.sh_dc = rgb_to_sh_dc(engine.run_state.gt_rgb().detach().clamp(0, 1).numpy())
    return scene


def working_width_drop(engine, scene_in, style):
    """A function of a scene giving its NNFM drop against ``scene_in`` on the evaluation views at the working width,
    as ``evaluate_run`` measures a run's (fp32 network, every painting vector searched)."""
    s = engine.settings
    cameras = evaluation_cameras(engine, EVAL_VIEWS, s.working_width)
    ev = figure_evaluator(engine, load_vgg(s.vgg_weights), style, s.working_width, whole_frame=True)
    before, alphas = zip(*(render_scene_image(scene_in, c, with_alpha=True) for c in cameras), strict=True)
    before, alphas = list(before), list(alphas)
    initial = ev.measure(before, before, alphas)["nnfm"]

    def drop(scene) -> float:
        after = [render_scene_image(scene, c) for c in cameras]
        return 1.0 - ev.measure(after, before, alphas)["nnfm"] / max(initial, 1e-12)

    return drop


def stage_speckles(engine, scene_in, style, width: int, on_row=None) -> list[dict]:
    """Run ``engine`` to the end; the speckle figure at each phase boundary (module docstring), in order
    (``on_row``: called with each row as it is measured)."""
    s = engine.settings
    cameras = evaluation_cameras(engine, EVAL_VIEWS, width)
    before, alphas = zip(*(render_scene_image(scene_in, c, with_alpha=True) for c in cameras), strict=True)
    paintings = [style] if isinstance(style, np.ndarray) else list(style)
    side = matched_side(s.working_width, s.style_scale, width)
    channels = "luminance" if s.keep_colours else "chroma"

    previous = {"images": list(before)}
    working_drop = working_width_drop(engine, scene_in, style)

    def figure(name: str, seconds: float, scene=None) -> dict:
        scene = scene or engine.stylized_scene()  # built once a stage: every render and the drop measure it
        after, after_alphas = zip(*(render_scene_image(scene, c, with_alpha=True) for c in cameras), strict=True)
        after = list(after)
        fig = display_speckle(list(before), after, list(alphas), paintings, side,
                              None if len(paintings) == 1 else s.style_weights, channels)
        fringe = fringe_halo(list(before), after, list(alphas), list(after_alphas))
        added = sum(chroma_energies(np.asarray(a, np.float64) - b, w, channels)
                    for a, b, w in zip(after, before, alphas, strict=True))
        step = sum(chroma_energies(np.asarray(a, np.float64) - b, w, channels)
                   for a, b, w in zip(after, previous["images"], alphas, strict=True))
        previous["images"] = after
        row = {"stage": name, "seconds": round(seconds, 1), "gaussians": engine.gaussian_count,
                "added_fine_energy": float(added[:FINE_BANDS].sum()), "added_energy": float(added.sum()),
                "change_fine_share": fine_share(step), "change_energy": float(step.sum()), **fig.to_dict(),
                "fringe_halo": fringe.halo, "fringe_near_saturated": fringe.bright_after,
                "structure": structure_kept(list(before), after, list(alphas)),
                "nnfm_drop_working": working_drop(scene)}
        if on_row is not None:
            on_row(row)
        return row

    def current() -> str:  # the phase object that runs now (a refit belongs to the stylization)
        return next((ph.name for ph in engine.phases if not ph.finished), "done")

    rows, engine_seconds, last = [], 0.0, current()
    while not engine.done:
        t0 = time.perf_counter()
        engine.step()
        engine_seconds += time.perf_counter() - t0
        now = current()
        if now != last and last == "preprocess":  # the new geometry with the ground-truth colours
            rows.append(figure("after preprocess (c_gt)", engine_seconds, ground_truth_scene(engine)))
        if now != last and (last in ("colour_match", "stylize") or last.startswith("refine_")) and now != "done":
            rows.append(figure(f"after {last}", engine_seconds))
        last = now
    rows.append(figure("result", engine_seconds))
    return rows


def add_set_option(p: argparse.ArgumentParser) -> None:
    """``--set NAME=VALUE`` (repeatable): any StylizeSettings field on top of the stylize options."""
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="any StylizeSettings field on top of the options (a Python literal: 6, 0.5, (512,), 'whole')")


def with_set_options(request, items: list[str]):
    """``request`` with the ``--set`` items as settings overrides (their values read as Python literals)."""
    for item in items:
        name, _, value = item.partition("=")
        request.overrides[name.strip()] = ast.literal_eval(value.strip())
    return request


def built_engine(p: argparse.ArgumentParser, argv: list[str] | None):
    """Parse ``argv`` with ``p`` (the stylize options and ``--set`` added here) and build the engine ``gstyle
    stylize`` builds for them: ``(args, engine, input scene, painting)``."""
    add_stylize_arguments(p)
    add_set_option(p)
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    engine, scene_in, _, _, style = build_stylizer(with_set_options(build_request(args), args.set))
    return args, engine, scene_in, style


def print_row(r: dict) -> None:
    """One stage's line of the table, printed as soon as it is measured."""
    views = " / ".join("-" if v is None else f"{v:.2f}" for v in r["speckle_ratio_per_view"])
    ratio = "-" if r["speckle_ratio"] is None else f"{r['speckle_ratio']:.2f}"
    print(f"{r['stage']:28s} {r['seconds']:9.1f} {r['gaussians']:10,d} {ratio:>8s}  {views:18s} "
          f"{r['added_fine_energy']:8.0f} / {r['added_energy']:7.0f}  {r['change_energy']:19.0f}, "
          f"{r['change_fine_share']:.2f}  {r['fringe_halo']:+6.3f} {r['fringe_near_saturated']:10.1%} "
          f"{r['structure']:9.3f} {100 * r['nnfm_drop_working']:7.1f} %", flush=True)


def parse_weights(text: str) -> dict[str, float]:
    """``"nnfm=400,edges=4000"`` as {λ name: value}; the names are ``StyleWeights``' fields (``ValueError`` else)."""
    from dataclasses import fields

    from gstyle_core.style.losses import StyleWeights

    names = {f.name for f in fields(StyleWeights)}
    out: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, _, value = item.partition("=")
        if name.strip() not in names:
            raise ValueError(f"unknown λ weight {name.strip()!r} (choose from {', '.join(sorted(names))})")
        out[name.strip()] = float(value)
    return out


def with_level_weights(engine, weights: dict[str, float]) -> None:
    """A probe of where the finer levels' λ weights act: each level objective the engine builds from now on (its
    steps at the level's width, ``phases/refine.py``) takes ``weights`` over the run's own; the run's objective (the
    stylization and the levels' working-width steps) keeps the run's."""
    from dataclasses import replace

    run = engine.run_state
    build = run.level_objective

    def level_objective(width, terms):
        new = (int(width), terms) not in run.level_objectives
        objective = build(width, terms)
        if new:
            objective.set_weights(replace(run.settings.weights, **weights))
        return objective

    run.level_objective = level_objective


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", default=None, help="also write the rows to this file")
    p.add_argument("--level-weights", default="", metavar="NAME=VALUE,...",
                   help="λ weights of the finer levels' steps at their width only, e.g. nnfm=400,edges=4000 with "
                        "--lambda-nnfm 200 --lambda-edges 0 for the run (a probe: no stylize option does this)")
    args, engine, scene_in, style = built_engine(p, argv)
    if args.level_weights:
        with_level_weights(engine, parse_weights(args.level_weights))
    width = args.display_width or 1024
    print(f"{args.scene or 'demo'} × {', '.join(args.style or ['the bundled painting'])}: preset "
          f"{engine.settings.preset}, working width {engine.settings.working_width}, levels "
          f"{list(engine.settings.refine_widths)} ({engine.settings.refine_mode}); speckle at {width} px")
    print(f"{'stage':28s} {'engine s':>9s} {'Gaussians':>10s} {'speckle':>8s}  {'per view':18s} "
          f"{'added fine / all':>18s}  {'this stage: energy, fine share':>30s}  {'halo':>6s} {'saturated':>10s} "
          f"{'structure':>9s} {'drop at ' + str(engine.settings.working_width) + ' px':>9s}", flush=True)
    rows = stage_speckles(engine, scene_in, style, width, on_row=print_row)
    print(f"painting at {rows[-1]['painting_side']} px (fine share {rows[-1]['painting_fine_share']})")
    working = next((r for r in rows if r["stage"] == "after stylize"), rows[-1])
    print(f"RESULT speckle_after_working_width={working['speckle_ratio']} speckle_result={rows[-1]['speckle_ratio']} "
          f"structure_result={rows[-1]['structure']:.3f} drop_working_result={rows[-1]['nnfm_drop_working']:.4f} "
          f"engine_seconds={rows[-1]['seconds']}")
    if args.json:
        Path(args.json).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
