"""A labelled grid of the pictures ``bench/tradeoff.py --sweep scale --pictures DIR`` saved (the
script before the atlas: ``git show b66d182:bench/tradeoff.py``): one row per setting
found (as shipped; coherent strokes off; broad strokes off), one column per stroke size, the input first.

    .venv/bin/python bench/pictures/stroke_grid.py DIR/biker_starry --out docs/stroke_size_biker.jpg [--crop 0.5]

``--crop F`` keeps the central F of each picture's width and height (strokes at full size in a page-wide figure);
``--zoom Z`` enlarges each picture Z times (nearest neighbour: every rendered pixel stays a visible block).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

SIZES = ("0.5", "1", "2")
ROWS = (("", "as shipped"), ("_no_coherent_strokes", "coherent strokes off"),
        ("_no_broad_strokes", "broad strokes off"))
LABEL_H = 22


def central_crop(img: Image.Image, fraction: float) -> Image.Image:
    """The central ``fraction`` of ``img``'s width and height."""
    if fraction >= 1:
        return img
    w, h = img.size
    cw, ch = max(1, round(w * fraction)), max(1, round(h * fraction))
    left, top = (w - cw) // 2, (h - ch) // 2
    return img.crop((left, top, left + cw, top + ch))


def labelled(img: Image.Image, text: str) -> Image.Image:
    """``img`` with ``text`` on a black band above it."""
    out = Image.new("RGB", (img.width, img.height + LABEL_H), "black")
    out.paste(img, (0, LABEL_H))
    ImageDraw.Draw(out).text((6, 4), text, fill="white")
    return out


def grid(folder: Path, crop: float, zoom: int = 1) -> Image.Image:
    """The input, then the stroke sizes with the term on; below, the same with it off (the sizes that were run)."""
    def tile(name: str, text: str) -> Image.Image:
        path = folder / f"{name}.png"
        if not path.is_file():
            raise SystemExit(f"{path} not found: run bench/tradeoff.py --sweep scale --pictures first")
        img = central_crop(Image.open(path).convert("RGB"), crop)
        if zoom > 1:
            img = img.resize((img.width * zoom, img.height * zoom), Image.NEAREST)
        return labelled(img, text)

    source = tile("input", "input")
    blank = Image.new("RGB", source.size, "black")
    rows = [[source if not suffix else blank] + [tile(f"stroke_{s}{suffix}", f"stroke size {s}, {text}")
                                                 for s in SIZES if (folder / f"stroke_{s}{suffix}.png").is_file()]
            for suffix, text in ROWS]
    rows = [row for row in rows if len(row) > 1]
    w = max(sum(t.width for t in row) for row in rows)
    h = sum(max(t.height for t in row) for row in rows)
    canvas = Image.new("RGB", (w, h), "black")
    y = 0
    for row in rows:
        x = 0
        for t in row:
            canvas.paste(t, (x, y))
            x += t.width
        y += max(t.height for t in row)
    return canvas


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", help="a DIR/<scene>_<style> folder of bench/tradeoff.py --pictures")
    p.add_argument("--out", required=True, help="the JPEG to write")
    p.add_argument("--crop", type=float, default=1.0, help="keep the central fraction of each picture")
    p.add_argument("--zoom", type=int, default=1, help="enlarge each picture this many times")
    args = p.parse_args()
    image = grid(Path(args.folder), args.crop, args.zoom)
    from gstyle_core.atomic import atomic_write

    with atomic_write(Path(args.out), "wb") as fh:
        image.save(fh, format="JPEG", quality=90)
    print(f"wrote {args.out} ({image.width}x{image.height}, {np.prod(image.size):,} px)")


if __name__ == "__main__":
    main()
