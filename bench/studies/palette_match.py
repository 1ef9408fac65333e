"""The palette match (issue #48 item 5) at several strengths on one finished run: what the final colour match does
to the style figures, from the colours the strokes left (0) to the method's full match (1).

Builds the engine ``gstyle stylize`` builds for the same options (default: the bundled demo and painting, preset
``preview``), runs it once, then for each strength of ``--strengths`` sets ``palette_match`` on the finished engine
(nothing runs again: the final match's two ends are kept and blended), renders one view ``--display-width`` px wide
to ``OUT_DIR/palette_match_T.png`` and measures the run's quality figures as OUT.json gives them (``evaluate_run``):
the NNFM drop and the structure kept on the evaluation views, the colour distance to the painting, and the speckle
at the display's width. One row per strength, the seconds the blend took, and a last ``RESULT`` line.

    python bench/studies/palette_match.py [SCENE] [--style PAINTING] [--preset preview] [--working-width 64]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine.build import build_stylizer  # noqa: E402
from gstyle_core.engine.run_figures import evaluate_run  # noqa: E402
from gstyle_core.machine import set_torch_threads  # noqa: E402
from gstyle_core.scene_images import render_scene_image, save_png  # noqa: E402


def strength_row(built, strength: float, view: int, width: int, out_dir: Path) -> dict:
    """Set the finished engine's palette match to ``strength``, render view ``view`` ``width`` px wide into
    ``out_dir`` and measure the run's figures (the speckle at that width); the row of the table."""
    engine = built.engine
    t0 = time.perf_counter()
    engine.set_params(palette_match=strength)
    blend_seconds = time.perf_counter() - t0
    cam = engine.full_cameras[view % len(engine.full_cameras)].resized_to_width(width)
    picture = out_dir / f"palette_match_{strength:g}.png"
    save_png(picture, render_scene_image(engine.stylized_scene(), cam))
    q = evaluate_run(engine, built.scene, built.style, display_width=width)
    return {"strength": strength, "nnfm_drop": q["nnfm_drop"], "structure": q["structure"],
            "colour": q["final"]["colour"], "speckle": q["display"]["speckle_ratio"], "seconds": blend_seconds,
            "picture": str(picture)}


def print_table(rows: list[dict]) -> None:
    """The rows, then the ``RESULT`` line."""
    print(f"{'palette match':>13s}  {'NNFM drop':>9s}  {'structure':>9s}  {'colour':>7s}  {'speckle':>7s}  "
          f"{'blend s':>8s}  picture")
    for r in rows:
        speckle = "-" if r["speckle"] is None else f"{r['speckle']:.2f}"
        print(f"{r['strength']:>13g}  {100 * r['nnfm_drop']:>7.1f} %  {r['structure']:>9.3f}  {r['colour']:>7.3f}  "
              f"{speckle:>7s}  {r['seconds']:>8.4f}  {r['picture']}")
    cells = " ".join(f"t{r['strength']:g}:drop={r['nnfm_drop']:.4f},structure={r['structure']:.3f},speckle="
                     f"{'-' if r['speckle'] is None else format(r['speckle'], '.3f')}" for r in rows)
    print(f"RESULT {cells}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--strengths", default="0,0.5,1", help="palette-match strengths to show, comma-separated")
    p.add_argument("--view", type=int, default=0, help="the camera whose view is rendered (default 0)")
    p.add_argument("--out-dir", default="out", help="where the pictures go (default out/)")
    args = p.parse_args(argv)
    strengths = [float(x) for x in args.strengths.split(",") if x.strip()]
    if args.threads:
        set_torch_threads(args.threads)
    built = build_stylizer(build_request(args))
    engine, s = built.engine, built.engine.settings
    if not s.colour_match_after:
        raise SystemExit("this run has no final colour match (colour_match_after is off)")
    width = args.display_width or 1024
    t0 = time.perf_counter()
    engine.run()
    seconds = time.perf_counter() - t0
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"{args.scene or 'demo'} × {', '.join(args.style or ['the bundled painting'])}: preset {s.preset}, "
          f"{s.working_width} px, {engine.gaussian_count:,d} Gaussians, run once in {seconds:.0f} s; pictures and "
          f"speckle at {width} px")
    print_table([strength_row(built, t, args.view, width, out_dir) for t in strengths])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
