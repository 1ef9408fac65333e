"""Pictures of the artist controls (docs/notes/artist-controls.md): the same views of several scenes, a labelled row
each.

    .venv/bin/python bench/pictures/control_pictures.py --scene SCENE [--cameras CAMS] --out docs/X.jpg \\
        --row "input=SCENE" --row "The Starry Night=out/mix/starry.ply" --row "mix 0.5=out/mix/mix.ply" ...

Every row renders ``--views`` cameras of ``SCENE`` (spread around its camera list, as the gallery does) at ``--width``
px each; the rows are cropped to the columns and rows that the first row covers and labelled on the left.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

LABEL_WIDTH = 150


def render_rows(scene: str | None, cameras: str | None, rows: list[tuple[str, str]], views: int, width: int
                ) -> np.ndarray:
    """[H, W, 3] uint8: one labelled strip of ``views`` renders per (label, scene path) row, cropped to the extent of
    the first row's scene (``scene_images.scene_rows``)."""
    from gstyle_core.io import load_scene
    from gstyle_core.scene_images import load_scene_and_cameras, scene_rows

    _base, _report, cams = load_scene_and_cameras(scene, cameras)
    strips = scene_rows([load_scene(path)[0] for _label, path in rows], cams.cameras, views, width)
    return np.concatenate([_labelled(s, label) for s, (label, _) in zip(strips, rows, strict=True)], axis=0)


def _labelled(strip: np.ndarray, label: str) -> np.ndarray:
    """``strip`` (float [0,1] or uint8) with a black label column on its left."""
    from PIL import Image, ImageDraw

    img = np.asarray(strip)
    if img.dtype != np.uint8:
        img = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
    canvas = Image.new("RGB", (img.shape[1] + LABEL_WIDTH, img.shape[0]), (0, 0, 0))
    canvas.paste(Image.fromarray(img), (LABEL_WIDTH, 0))
    draw = ImageDraw.Draw(canvas)
    y = img.shape[0] // 2 - 8
    for line in label.split("\\n"):
        draw.text((8, y), line, fill=(235, 235, 235))
        y += 14
    return np.asarray(canvas)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default=None, help="the scene whose cameras frame every row (default: the demo)")
    p.add_argument("--cameras", default=None, help="its cameras (default: the scene's own or generated)")
    p.add_argument("--row", action="append", required=True, metavar="LABEL=SCENE",
                   help="a labelled row (a '\\n' in the label breaks the line)")
    p.add_argument("--views", type=int, default=3)
    p.add_argument("--width", type=int, default=384)
    p.add_argument("--out", required=True, help="output .jpg/.png")
    args = p.parse_args(argv)
    rows = []
    for spec in args.row:
        label, sep, path = spec.partition("=")
        if not sep:
            p.error(f"--row must be LABEL=SCENE, got {spec!r}")
        rows.append((label, path))
    from PIL import Image

    picture = render_rows(args.scene, args.cameras, rows, args.views, args.width)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(picture).save(args.out, quality=90)
    print(f"wrote {args.out} ({picture.shape[1]}x{picture.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
