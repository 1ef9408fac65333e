"""Does a stylization grow the scene? Its extent probed after every phase, pre-processing round and refit.

Builds the engine ``gstyle stylize`` builds for the same options and steps it, measuring the Gaussian centres each
time the part of the run changes (each pre-processing round's split and refit, the colour match, each colour-gradient
split and its refit, each finer level, the result) against the input's (``cameras.framing.extent_growth``): the radius
of the sphere generated cameras frame (the 5-95 % box, ``generate.robust_centre_radius``), the studio's framing box
(0.5-99.5 %), the largest distance from the input's centre, and the share of Gaussians outside the input's box; a
ratio of 1 is no growth. ``--stop-after PHASE`` stops once that phase is over (e.g. ``preprocess``). Last a
``RESULT`` line with the result's ratios.

    python bench/studies/extent_phases.py assets/demo/fountain.splat \
        --style ../shared/data/styles/starry_night_vangogh.jpg --preset final --stop-after preprocess
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cameras.framing import extent_growth  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from display_phases import built_engine  # noqa: E402


def part_of_run(engine) -> str:
    """What the engine is doing now: its phase, a pre-processing round or a stylization's refit."""
    phase = next((ph for ph in engine.phases if not ph.finished), None)
    if phase is None:
        return "done"
    if phase.name == "preprocess" and phase.started:
        return f"preprocess round {phase.round + 1}"
    if phase.name == "stylize" and getattr(phase, "refit", None) is not None:
        return f"stylize: refit after split {phase.splits_done}"
    if phase.name == "stylize" and phase.started:
        return f"stylize (after {phase.splits_done} split(s))"
    return phase.name


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--stop-after", default=None, metavar="PHASE", help="stop once this phase is over")
    args, engine, scene_in, _ = built_engine(p, argv)
    print(f"{args.scene or 'demo'}: preset {engine.settings.preset}, {scene_in.count:,} Gaussians; ratios to the "
          "input's (1 = no growth)")
    print(f"{'after':42s} {'engine s':>9s} {'Gaussians':>10s} {'5-95 % radius':>14s} {'framing box':>12s} "
          f"{'max distance':>13s} {'outside box':>12s}")

    def row(label: str, seconds: float) -> dict:
        g = extent_growth(scene_in.means, engine.params["means"].detach().numpy())
        print(f"{label:42s} {seconds:9.1f} {engine.gaussian_count:10,d} {g['radius']:14.4f} {g['box']:12.4f} "
              f"{g['max_distance']:13.4f} {g['outside_share']:12.5f}", flush=True)
        return g

    seconds, last, g = 0.0, part_of_run(engine), None
    while not engine.done:
        t0 = time.perf_counter()
        engine.step()
        seconds += time.perf_counter() - t0
        now = part_of_run(engine)
        if now != last:
            g = row(last, seconds)
            if args.stop_after and last.split()[0].rstrip(":") == args.stop_after and \
                    not now.startswith(args.stop_after):
                break
        last = now
    print(f"RESULT radius={g['radius']:.4f} box={g['box']:.4f} max_distance={g['max_distance']:.4f} "
          f"outside_share={g['outside_share']:.5f} engine_seconds={seconds:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
