"""What the final colour match (the method's last step) does to the style figures: one run measured with and without it.

Builds the engine ``gstyle stylize`` builds for the same options, steps it to the start of its final colour match
(phase ``finish``) and measures the evaluation views (those ``evaluate_run`` measures) at each width of ``--widths``
(default: the working width and the width the run ends at), as OUT.json defines its figures: the NNFM drop, the
structure kept and the colour distance to the painting (mean and covariance of the covered pixels). One row without the
final match, then one per ``--detail-px`` value: the match with its broad colours taken over that many working pixels
(``match_detail_px``; 0: the plain map of every colour), each from the same colours. Beside each row: the singular
values of the map A (c -> A c + b) a final match would make of that row's renders, and |b|: 1 and 0 when the renders
already have the painting's palette. A last ``RESULT`` line gives the drop at the last width without the match and
with the run's own setting.

    python bench/studies/final_match_cost.py SCENE --style PAINTING --preset balanced [--detail-px 0,4,16]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine.build import build_stylizer  # noqa: E402
from gstyle_core.engine.levels import level_widths  # noqa: E402
from gstyle_core.engine.phases.colour_match import ColourMatch, transfer  # noqa: E402
from gstyle_core.engine.run_figures import evaluation_cameras, figure_evaluator  # noqa: E402
from gstyle_core.machine import set_torch_threads  # noqa: E402

EVAL_VIEWS = 3  # as evaluate_run


class Figures:
    """The figures of the engine's current colours on the evaluation views at ``widths``, against the input scene."""

    def __init__(self, engine, scene_in, style, widths: list[int]) -> None:
        from gstyle_core.scene_images import render_scene_image
        from gstyle_core.style.vgg import load_vgg

        self.engine, self.render = engine, render_scene_image
        vgg = load_vgg(engine.settings.vgg_weights)  # fp32 on the CPU, as the run's figures
        self.views = {}
        for width in widths:
            whole = width <= engine.settings.working_width  # evaluate_run's definition; above it width_figures'
            ev = figure_evaluator(engine, vgg, style, width, whole_frame=whole)
            cams = evaluation_cameras(engine, EVAL_VIEWS, width)
            before, alpha = zip(*(render_scene_image(scene_in, c, with_alpha=True) for c in cams), strict=True)
            initial = ev.measure(list(before), list(before), list(alpha), whole_frame=whole)
            self.views[width] = (ev, cams, list(before), list(alpha), initial["nnfm"], whole)

    def measure(self) -> dict[int, dict[str, float]]:
        """{width: {nnfm_drop, structure, colour}} of the engine's stylized scene now."""
        from gstyle_core.engine.evaluate import structure_kept

        scene, out = self.engine.stylized_scene(), {}
        for width, (ev, cams, before, alpha, initial, whole) in self.views.items():
            after = [self.render(scene, c) for c in cams]
            final = ev.measure(after, before, alpha, whole_frame=whole)
            out[width] = {"nnfm_drop": 1.0 - final["nnfm"] / max(initial, 1e-12),
                          "structure": structure_kept(before, after, alpha), "colour": final["colour"]}
        return out


def remaining_map(engine, final: ColourMatch) -> tuple[np.ndarray, float]:
    """The singular values of the map A and |b| the run's final colour match ``final`` would make of its renders now."""
    A, b = transfer(engine.run_state, *final.renders())
    return np.linalg.svd(A, compute_uv=False), float(np.linalg.norm(b))


def step_to_final_match(engine) -> float:
    """Step ``engine`` until its next step is the final colour match; the engine's seconds."""
    seconds = 0.0
    while not engine.done and not (isinstance(engine.current_phase(), ColourMatch) and engine.current_phase().final):
        t0 = time.perf_counter()
        engine.step()
        seconds += time.perf_counter() - t0
    return seconds


def match_rows(engine, figures: Figures, detail_px: list[float]) -> list[dict]:
    """The figures without the final match and with it at each ``detail_px``, all from the colours it starts from."""
    final = engine.current_phase()
    start, kept_px = engine.run_state.c_s.clone(), engine.settings.match_detail_px
    rows = []
    for px in [None, *detail_px]:
        engine.run_state.c_s, final.done = start.clone(), False
        if px is not None:
            engine.settings.match_detail_px = float(px)
            final.step()
        singular, offset = remaining_map(engine, final)
        rows.append({"detail_px": px, "figures": figures.measure(), "map_singular": singular.round(3).tolist(),
                     "map_offset": round(offset, 3)})
    engine.settings.match_detail_px = kept_px
    engine.run_state.c_s, final.done = start, False
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--widths", default=None, help="widths to measure at, comma-separated (default: the working "
                                                  "width and the width the run ends at)")
    p.add_argument("--detail-px", default="0,4,16", help="the final match's detail widths to try (working px)")
    args = p.parse_args(argv)
    if args.threads:
        set_torch_threads(args.threads)
    engine, scene_in, _, _, style = build_stylizer(build_request(args))
    s = engine.settings
    if not s.colour_match_after:
        raise SystemExit("this run has no final colour match (colour_match_after is off)")
    widths = ([int(w) for w in args.widths.split(",")] if args.widths
              else sorted({s.working_width, level_widths(s.working_width, s.refine_widths)[-1]}))
    seconds = step_to_final_match(engine)
    figures = Figures(engine, scene_in, style, widths)
    rows = match_rows(engine, figures, [float(x) for x in args.detail_px.split(",") if x.strip()])
    print(f"{args.scene or 'demo'} × {', '.join(args.style or ['the bundled painting'])}: preset {s.preset}, "
          f"{engine.gaussian_count:,d} Gaussians, {seconds:.0f} s to the final colour match; the run's own detail "
          f"width {s.match_detail_px:g} px")
    head = "  ".join(f"{f'drop / structure / colour at {w} px':>36s}" for w in widths)
    print(f"{'final colour match':24s} {head}  {'map left: singular values, |b|':>32s}")
    for r in rows:
        name = "none" if r["detail_px"] is None else f"detail {r['detail_px']:g} px"
        cells = "  ".join(f"{100 * f['nnfm_drop']:>20.1f} % / {f['structure']:.2f} / {f['colour']:.3f}"
                          for f in r["figures"].values())
        print(f"{name:24s} {cells}  {' / '.join(f'{v:.2f}' for v in r['map_singular']):>24s}, {r['map_offset']:.2f}")
    last = widths[-1]
    own = next((r for r in rows if r["detail_px"] == s.match_detail_px), None)
    print(f"RESULT width={last} drop_without_match={rows[0]['figures'][last]['nnfm_drop']:.4f} drop_with_match="
          f"{'-' if own is None else format(own['figures'][last]['nnfm_drop'], '.4f')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
