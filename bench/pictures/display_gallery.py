"""Pictures at a display's size for docs/gallery.md: one scene's runs side by side, each view 1024 px wide, with crops
at full size (1 render pixel = 1 picture pixel), where single-splat confetti and strokes can be judged.

    python bench/pictures/display_gallery.py INPUT_SCENE OUT_preview.ply OUT_balanced.ply OUT_final.ply \
        --labels input,preview,balanced,final --out docs/display_demo_scream.jpg [--view 5] [--crop 320]

The first file is the input scene (its "before"); the cameras are generated around it as ``gstyle stylize`` does
(or ``--cameras``). The picture: a row per file; each row is the view at 1024 px shown at half size (the scene's box)
beside a full-size crop of ``--crop`` px from the middle of the scene. Prints where the crop was taken.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.scene_images import load_scene_and_cameras, render_scene_image  # noqa: E402


def covered_box(alpha: np.ndarray, margin: int = 8) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) of the pixels the scene covers, grown by ``margin``."""
    rows, cols = np.flatnonzero((alpha > 1 / 255).any(1)), np.flatnonzero((alpha > 1 / 255).any(0))
    h, w = alpha.shape
    if not len(rows):
        return 0, 0, w, h
    return (max(0, cols[0] - margin), max(0, rows[0] - margin), min(w, cols[-1] + 1 + margin),
            min(h, rows[-1] + 1 + margin))


def main(argv: list[str] | None = None) -> int:
    from PIL import Image, ImageDraw

    from gstyle_core.io import load_scene

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes", nargs="+", help="the input scene, then the stylized .ply files")
    p.add_argument("--labels", default=None, help="one label per file, comma-separated")
    p.add_argument("--cameras", default=None)
    p.add_argument("--view", type=int, default=5, help="the camera to render")
    p.add_argument("--width", type=int, default=1024)
    p.add_argument("--crop", type=int, default=320, help="side of the full-size crop (px)")
    p.add_argument("--out", required=True)
    args = p.parse_args(argv)
    labels = args.labels.split(",") if args.labels else [Path(s).stem for s in args.scenes]
    _, _, cams = load_scene_and_cameras(args.scenes[0], args.cameras)
    cam = list(cams)[args.view % len(cams)].resized_to_width(args.width)
    renders = []
    for path in args.scenes:
        scene, _ = load_scene(path)
        renders.append(render_scene_image(scene, cam, with_alpha=True))
    x0, y0, x1, y1 = covered_box(renders[0][1])
    cx, cy = (x0 + x1) // 2, (y0 + y1) // 2
    half = args.crop // 2
    crop = (max(0, cx - half), max(0, cy - half))
    rows = []
    for (image, _), label in zip(renders, labels, strict=True):
        rgb = (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)
        whole = Image.fromarray(rgb[y0:y1, x0:x1])
        whole = whole.resize((max(1, whole.width // 2), max(1, whole.height // 2)), Image.LANCZOS)
        part = Image.fromarray(rgb[crop[1]:crop[1] + args.crop, crop[0]:crop[0] + args.crop])
        height = max(whole.height, part.height)
        row = Image.new("RGB", (whole.width + part.width + 8, height + 18), (255, 255, 255))
        row.paste(whole, (0, 18))
        row.paste(part, (whole.width + 8, 18))
        ImageDraw.Draw(row).text((4, 3), f"{label}: view {args.view} at {args.width} px (half size) | crop at full "
                                         f"size", fill=(0, 0, 0))
        rows.append(row)
    sheet = Image.new("RGB", (max(r.width for r in rows), sum(r.height for r in rows)), (255, 255, 255))
    y = 0
    for row in rows:
        sheet.paste(row, (0, y))
        y += row.height
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out, quality=90)
    print(f"wrote {out}: {len(rows)} rows; crop {args.crop} px at ({crop[0]}, {crop[1]}) of the {args.width}-px view")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
