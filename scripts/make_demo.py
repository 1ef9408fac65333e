"""Make the bundled demo scene from the fountain sample in ../shared/data (run once; the result is committed).

Keeps the ``count`` splats with the largest opacity × projected area (product of the two largest scales)^0.5,
a simple importance that preserves the silhouette and large surfaces, and writes them as a .splat file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from gstyle_core.io import load_scene, save_scene

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--source", default=str(ROOT.parent / "shared/data/scenes/splat/winter_fountain.cropped.splat"))
    p.add_argument("--count", type=int, default=40_000)
    p.add_argument("--out", default=str(ROOT / "assets/demo/fountain.splat"))
    args = p.parse_args()
    scene, _ = load_scene(args.source)
    top2 = np.sort(scene.log_scales, axis=1)[:, 1:].sum(axis=1)
    importance = scene.opacities * np.exp(0.5 * top2)
    keep = np.sort(np.argsort(-importance)[: args.count])
    save_scene(scene.subset(keep), args.out)
    print(f"wrote {args.out}: {len(keep)} of {scene.count} splats")


if __name__ == "__main__":
    main()
