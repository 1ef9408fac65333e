"""A table of ``gstyle stylize`` runs against issue #34's targets, read from their OUT.json summaries.

One row per summary: scene, painting, preset and levels, wall time, Gaussians after, the NNFM drop and structure at
256 px and at the width the run ended at (``quality.at_final_width``), the coarse ratio (texture-scale figure) and
the speckle ratio at the display's width (``quality.display``), and which targets a row misses (speckle ≤ 1.3,
drop ≥ 30 % and structure ≥ 0.5 where the run ends, coarse ratio ≥ 0.9). Last a ``RESULT`` line with the count of
rows meeting all of them.

    python bench/studies/display_table.py /tmp/runs/*.json [--markdown]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

TARGETS = {"speckle": 1.3, "drop": 0.30, "structure": 0.5, "coarse": 0.9}


def row(path: Path) -> dict:
    """The figures of one OUT.json."""
    s = json.loads(path.read_text())
    q = s["quality"]
    end = q.get("at_final_width") or {"width": q["width"], "nnfm_drop": q["nnfm_drop"], "structure": q["structure"]}
    display = q.get("display") or {}
    settings = s["settings"]
    widths = [settings["working_width"], *settings.get("refine_widths", [])]
    return {"scene": Path(s["scene"]).name, "painting": Path(s["style"]).name, "preset": settings["preset"],
            "levels": "→".join(map(str, widths)), "mode": settings.get("refine_mode", "-"),
            "seconds": s["seconds_total"], "gaussians": s["gaussians_after"],
            "drop_256": q["nnfm_drop"], "structure_256": q["structure"], "end_width": end["width"],
            "drop": end["nnfm_drop"], "structure": end["structure"],
            "coarse": q["texture_scale"]["coarse_ratio"], "speckle": display.get("speckle_ratio")}


def misses(r: dict) -> list[str]:
    """The targets row ``r`` misses."""
    out = []
    if r["speckle"] is None or r["speckle"] > TARGETS["speckle"]:
        out.append("speckle")
    if r["drop"] < TARGETS["drop"]:
        out.append("drop")
    if r["structure"] < TARGETS["structure"]:
        out.append("structure")
    if r["coarse"] < TARGETS["coarse"]:
        out.append("coarse")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("summaries", nargs="+", type=Path, help="OUT.json files of gstyle stylize runs")
    p.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = p.parse_args(argv)
    rows = [row(path) for path in args.summaries]
    head = ("scene", "painting", "preset", "levels", "s", "Gaussians", "drop 256", "structure 256", "end px",
            "drop end", "structure end", "coarse", "speckle", "misses")
    lines = []
    for r in rows:
        speckle = "-" if r["speckle"] is None else f"{r['speckle']:.2f}"
        lines.append((r["scene"], r["painting"], r["preset"], f"{r['levels']} ({r['mode']})", f"{r['seconds']:.0f}",
                      f"{r['gaussians']:,}", f"{100 * r['drop_256']:.1f} %", f"{r['structure_256']:.2f}",
                      str(r["end_width"]), f"{100 * r['drop']:.1f} %", f"{r['structure']:.2f}",
                      f"{r['coarse']:.2f}", speckle, ", ".join(misses(r)) or "none"))
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for line in lines:
            print("| " + " | ".join(line) + " |")
    else:
        for line in (head, *lines):
            print("  ".join(f"{c:>12s}" if i > 3 else f"{c:<22s}" for i, c in enumerate(line)))
    met = sum(not misses(r) for r in rows)
    print(f"RESULT rows={len(rows)} all_targets_met={met} speckle_met={sum(r['speckle'] is not None and r['speckle'] <= TARGETS['speckle'] for r in rows)}")  # noqa: E501
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
