"""The fringe halo of stylized results at a display's size (``style/fringe.py``), with a picture of the fringe.

    python bench/studies/fringe_halo.py INPUT_SCENE OUT_a.ply [OUT_b.ply ...] --labels before_fix,after_fix \
        [--width 1024] [--views 3] [--picture docs/fringe.jpg --view 0 --crop 384]

Renders the evaluation views ``gstyle stylize`` measures (``--views`` of the input's cameras, spread as
``choose_views`` spreads them; generated around the input as the run generates them, or ``--cameras``) ``--width``
px wide, for the input and each result, and prints per file the halo (the fringe's luminance lift over the body's),
both lifts and the near-saturated share of the fringe, then a ``RESULT`` line. ``--picture``: one row per file (the
input first) of a full-size ``--crop`` px crop of view ``--view`` where the input's fringe is densest.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.atomic import atomic_path  # noqa: E402
from gstyle_core.engine.view_choice import choose_views  # noqa: E402
from gstyle_core.scene_images import load_scene_and_cameras, render_scene_image  # noqa: E402
from gstyle_core.style.fringe import FRINGE_ALPHA, fringe_halo  # noqa: E402


def densest_fringe(alpha: np.ndarray, crop: int) -> tuple[int, int]:
    """(x0, y0) of the ``crop`` px square holding the most fringe pixels of ``alpha`` [H, W] (a coarse search)."""
    fringe = ((alpha > FRINGE_ALPHA[0]) & (alpha < FRINGE_ALPHA[1])).astype(np.float64)
    h, w = fringe.shape
    stride = max(1, crop // 4)
    best, at = -1.0, (0, 0)
    for y in range(0, max(1, h - crop + 1), stride):
        for x in range(0, max(1, w - crop + 1), stride):
            count = float(fringe[y:y + crop, x:x + crop].sum())
            if count > best:
                best, at = count, (x, y)
    return at


def picture(rows: list[np.ndarray], labels: list[str], alpha: np.ndarray, crop: int, out: str) -> str:
    """Write the crops of ``rows`` ([H, W, 3] renders of one view) side by side as a JPEG; returns where."""
    from PIL import Image, ImageDraw

    x0, y0 = densest_fringe(alpha, crop)
    tiles = []
    for image, label in zip(rows, labels, strict=True):
        rgb = (np.clip(image[y0:y0 + crop, x0:x0 + crop], 0, 1) * 255 + 0.5).astype(np.uint8)
        tile = Image.new("RGB", (rgb.shape[1], rgb.shape[0] + 16), (255, 255, 255))
        tile.paste(Image.fromarray(rgb), (0, 16))
        ImageDraw.Draw(tile).text((3, 2), label, fill=(0, 0, 0))
        tiles.append(tile)
    sheet = Image.new("RGB", (sum(t.width for t in tiles) + 6 * (len(tiles) - 1), tiles[0].height), (255,) * 3)
    x = 0
    for tile in tiles:
        sheet.paste(tile, (x, 0))
        x += tile.width + 6
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="JPEG", quality=88)
    return f"{path} ({crop} px crop at ({x0}, {y0}), full size)"


def main(argv: list[str] | None = None) -> int:
    from gstyle_core.io import load_scene

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes", nargs="+", help="the input scene, then the stylized .ply files")
    p.add_argument("--labels", default=None, help="one label per stylized file, comma-separated")
    p.add_argument("--cameras", default=None)
    p.add_argument("--width", type=int, default=1024)
    p.add_argument("--views", type=int, default=3)
    p.add_argument("--picture", default=None, help="write crops of the fringe to this JPEG")
    p.add_argument("--view", type=int, default=0, help="which of the evaluation views the picture shows")
    p.add_argument("--crop", type=int, default=384)
    args = p.parse_args(argv)
    if len(args.scenes) < 2:
        p.error("give the input scene and at least one stylized result")
    labels = args.labels.split(",") if args.labels else [Path(s).stem for s in args.scenes[1:]]
    if len(labels) != len(args.scenes) - 1:
        p.error(f"{len(labels)} label(s) for {len(args.scenes) - 1} result(s)")
    scene_in, _, cams = load_scene_and_cameras(args.scenes[0], args.cameras)
    cams = [list(cams)[i].resized_to_width(args.width) for i in choose_views(list(cams), args.views)]
    before, alpha = zip(*(render_scene_image(scene_in, c, with_alpha=True) for c in cams), strict=True)
    print(f"{args.scenes[0]}: {len(cams)} views at {args.width} px; fringe = input alpha in {FRINGE_ALPHA}")
    print(f"{'result':24s} {'halo':>7s} {'fringe lift':>12s} {'body lift':>10s} {'saturated before':>17s} "
          f"{'after':>7s} {'body after':>11s}")
    shown, results = [before[args.view % len(cams)]], []
    for path, label in zip(args.scenes[1:], labels, strict=True):
        scene, _ = load_scene(path)
        after, alpha_after = zip(*(render_scene_image(scene, c, with_alpha=True) for c in cams), strict=True)
        fig = fringe_halo(list(before), list(after), list(alpha), list(alpha_after))
        results.append((label, fig))
        shown.append(after[args.view % len(cams)])
        print(f"{label:24s} {fig.halo:+7.3f} {fig.lift_fringe:+12.3f} {fig.lift_body:+10.3f} "
              f"{fig.bright_before:17.1%} {fig.bright_after:7.1%} {fig.bright_body:11.1%}")
    if args.picture:
        where = picture(shown, ["input", *labels], alpha[args.view % len(cams)], args.crop, args.picture)
        print(f"wrote {where} of evaluation view {args.view % len(cams)}")
    print("RESULT " + " ".join(f"{label}_halo={fig.halo:.4f} {label}_saturated={fig.bright_after:.4f}"
                               for label, fig in results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
