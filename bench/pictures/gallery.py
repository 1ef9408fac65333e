"""The gallery of docs/gallery.md: ``gstyle stylize`` (preview preset, defaults) per scene × painting, then a
before/after picture at a width where strokes can be judged, and a table row of what the run measured.

    .venv/bin/python bench/pictures/gallery.py [--pairs demo:starry,fountain:wave] [--width 512] [--docs docs]

Scenes and paintings are looked up in ``../shared/data`` (see ``bench/studies/strokes_sweep.py``); the demo is bundled.
Writes ``docs/gallery_<scene>_<painting>.jpg`` (input above, stylized below, three views around the scene) and
prints a Markdown row per pair: wall time, Gaussians, NNFM before → after, structure, colour distance.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from bench.studies.strokes_sweep import SCENES, STYLES, find_file  # noqa: E402
from gstyle_core.outputs import SUMMARY, companion  # noqa: E402

# Scenes fitted here first (``gstyle fit``), stylized with their photos as ground truth: key -> (scene, cameras).
FITTED = {"fern": (ROOT / "out" / "fern.ply", Path("scenes") / "llff_fern")}


def make_pair(scene_key: str, style_key: str, data: Path, docs: Path, width: int, extra: list[str]) -> str:
    """Stylize one pair with the CLI, write its picture, return its table row."""
    from PIL import Image

    from gstyle_core.io import load_scene
    from gstyle_core.scene_images import before_after_picture, load_scene_and_cameras

    if scene_key in FITTED:
        fitted, photos = FITTED[scene_key]
        if not fitted.is_file():
            raise SystemExit(f"{fitted} not found: fit it first (gstyle fit {data / photos} --out {fitted})")
        scene, cameras = str(fitted), str(data / photos)
    else:
        scene, cameras = find_file(data, SCENES, scene_key), None
    style = find_file(data, STYLES, style_key)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.ply"
        cmd = [sys.executable, "-m", "gstyle_core.cli", "stylize", *([scene] if scene else []), "--style", style,
               "--preset", "preview", "--out", str(out), *(["--cameras", cameras] if cameras else []), *extra]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        summary = json.loads(companion(out, SUMMARY).read_text())
        before, _report, cams = load_scene_and_cameras(scene, cameras)
        after, _ = load_scene(out)
        picture = before_after_picture(before, after, cams.cameras, n_views=3, width=width)
    name = docs / f"gallery_{scene_key}_{style_key}.jpg"
    Image.fromarray((picture.clip(0, 1) * 255 + 0.5).astype("uint8")).save(name, quality=90)
    q = summary["quality"]
    return (f"| {scene_key} ({summary['gaussians_before']:,} → {summary['gaussians_after']:,}) | {style_key} | "
            f"{wall:.0f} s | {q['initial']['nnfm']:.3f} → {q['final']['nnfm']:.3f} (**−{100 * q['nnfm_drop']:.0f} %**)"
            f" | {q['structure']:.2f} | {q['initial']['colour']:.3f} → {q['final']['colour']:.3f} | `{name.name}` |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--pairs", default="demo:starry,fountain:mandelbrot,biker:wave")
    p.add_argument("--data", default=str(ROOT.parent / "shared" / "data"))
    p.add_argument("--docs", default=str(ROOT / "docs"))
    p.add_argument("--width", type=int, default=512, help="width of each view in the picture")
    p.add_argument("extra", nargs="*", help="more gstyle stylize options after --")
    args = p.parse_args()
    docs = Path(args.docs)
    docs.mkdir(parents=True, exist_ok=True)
    print("| scene (Gaussians before → after) | painting | wall | NNFM before → after | structure | colour | picture |")
    print("|---|---|---|---|---|---|---|")
    for pair in args.pairs.split(","):
        scene_key, style_key = pair.split(":")
        print(make_pair(scene_key, style_key, Path(args.data), docs, args.width, args.extra), flush=True)


if __name__ == "__main__":
    main()
