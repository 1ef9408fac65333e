"""Texture-scale table (``gstyle_core/style/texture_scale.py``) for ``gstyle stylize`` outputs and for paintings.

For each OUT (``.ply``, ``.json`` or the stem of a run): the band shares (fine / middle / coarse) of what stylization
added, ``OUT_after.png − OUT_before.png`` inside the scene, beside the painting's own at the size it was matched (its
OUT.json's stroke size × working width, in the evaluation images' pixels). The PNGs carry no alpha: the scene is the
pixels that are not background (black, any channel above 1/255) in either image. A diagnostic column beside it,
``residual``: the shares of ``after − T(before)``, T the affine colour map fitted (least squares, over the scene) from
before to after: what remains once the scene's own detail, recoloured by the colour matches, is taken out (the
figure counts that recoloured detail as added). For each ``--painting``: its shares at each ``--side`` (long side).

    python bench/studies/texture_scale.py /tmp/scale/cli_demo_starry_S1.ply /tmp/scale/cli_demo_starry_S2.ply
    python bench/studies/texture_scale.py --painting ../shared/data/styles/starry_night_vangogh.jpg --side 128 256 512
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.images import load_style_image  # noqa: E402
from gstyle_core.outputs import SUMMARY, companion, output_base  # noqa: E402
from gstyle_core.style.texture_scale import (  # noqa: E402
    BAND_NAMES,
    band_shares,
    matched_side,
    painting_shares,
    texture_scale,
)

BACKGROUND_LEVEL = 1.0 / 255.0


def read_png(path: Path) -> np.ndarray:
    """An 8-bit PNG as float [H, W, 3] in [0, 1]."""
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), np.float64) / 255.0


def scene_mask(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Pixels that are not black background in either image (1.0 / 0.0)."""
    return ((before.max(-1) > BACKGROUND_LEVEL) | (after.max(-1) > BACKGROUND_LEVEL)).astype(np.float64)


def recolour_residual_shares(before: np.ndarray, after: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Shares of ``after − T(before)`` inside ``mask``, T the least-squares affine colour map from before to after
    over the masked pixels."""
    inside = mask > 0
    design = np.c_[before[inside], np.ones(int(inside.sum()))]
    coef, *_ = np.linalg.lstsq(design, after[inside], rcond=None)
    mapped = np.c_[before.reshape(-1, 3), np.ones(before.shape[0] * before.shape[1])] @ coef
    return band_shares(after - mapped.reshape(after.shape) * mask[..., None], mask)


def out_row(path: str | Path) -> dict:
    """The figure of one ``gstyle stylize`` output (its PNGs and OUT.json)."""
    stem = Path(path)
    stem = stem.with_suffix("") if stem.suffix == ".json" else output_base(stem)  # the CLI's companion rule
    before, after = read_png(companion(stem, "_before.png")), read_png(companion(stem, "_after.png"))
    json_path = companion(stem, SUMMARY)
    if not json_path.exists():  # written before issue #25 cut OUT at its last dot: x_S0.5.ply -> x_S0.json
        json_path = stem.with_suffix(".json")
    summary = json.loads(json_path.read_text())
    s = summary["settings"]
    width = int(summary.get("quality", {}).get("width", 256))
    style = summary["style"]
    paths = [entry["path"] for entry in summary.get("styles", [])] or (style if isinstance(style, list) else [style])
    weights = [entry.get("weight", 1.0) for entry in summary.get("styles", [])] or None
    side = matched_side(s["working_width"], s["style_scale"], width)
    mask = scene_mask(before, after)
    fig = texture_scale(before, after, mask, [load_style_image(p) for p in paths], side, weights)
    q = summary.get("quality", {})
    return {"name": stem.name, "figure": fig, "residual": recolour_residual_shares(before, after, mask),
            "nnfm_drop": q.get("nnfm_drop"), "structure": q.get("structure"),
            "scale": s["style_scale"], "width": s["working_width"]}


def fmt(values) -> str:
    """Three shares as 0.xx / 0.xx / 0.xx."""
    return " / ".join(f"{v:.3f}" for v in values)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("outs", nargs="*", help="gstyle stylize outputs (OUT.ply, OUT.json or the stem)")
    p.add_argument("--painting", nargs="*", default=[], help="paintings to measure alone")
    p.add_argument("--side", nargs="*", type=int, default=[256], help="long sides (px) for --painting")
    args = p.parse_args(argv)
    bands = " / ".join(BAND_NAMES)
    if args.outs:
        print(f"{'run':34s} {'S':>4s} {'width':>5s}  added {bands:22s} painting {bands:22s} coarse ratio  "
              "NNFM drop  structure  residual " + bands)
        for out in args.outs:
            r = out_row(out)
            f = r["figure"]
            drop = "" if r["nnfm_drop"] is None else f"{100 * r['nnfm_drop']:.1f} %"
            structure = "" if r["structure"] is None else f"{r['structure']:.3f}"
            print(f"{r['name']:34s} {r['scale']:4g} {r['width']:5d}  {fmt(f.added):28s} {fmt(f.painting):31s} "
                  f"{f.coarse_ratio:12.2f}  {drop:>9s}  {structure:>9s}  {fmt(r['residual'])}")
    for painting in args.painting:
        image = load_style_image(painting)
        for side in args.side:
            print(f"{Path(painting).name:34s} at {side:4d} px: {fmt(painting_shares(image, side))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
