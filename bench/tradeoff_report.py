"""The atlas's CSV, Pareto fronts, plots and tables (``bench/tradeoff.py`` writes and reads them through this), and the
tiers' table of the README and docs/tiers.md, generated from the CSV between ``TABLE_BEGIN`` and ``TABLE_END``
(``tiers_table``; ``tests/test_bench_tradeoff.py`` keeps the pages equal to it).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

KEY = ("tier", "device", "scene", "painting", "knob")  # a point; rows of the same key replace each other (--merge)
FIGURES = ("seconds", "seconds_min", "seconds_max", "repeats", "gaussians", "working_width", "end_width",
           "nnfm_drop", "structure", "nnfm_drop_end", "structure_end", "nnfm_drop_1024", "speckle_1024",
           "structure_1024", "coarse_ratio", "colour", "consistency", "consistency_input", "nnfm_drop_spread",
           "structure_1024_spread")
CONTEXT = ("machine", "torch", "code", "measured", "load_before", "load_after", "pareto")
COLUMNS = KEY + FIGURES + CONTEXT
INTEGERS = ("repeats", "gaussians", "working_width", "end_width")
PERCENT = ("nnfm_drop", "nnfm_drop_end", "nnfm_drop_1024")  # README figures written as percentages
MIN_STRUCTURE = 0.5  # edge correlation (at 1024 px) below which the scene is considered lost (issue #14's threshold)
SHIPPED = "as shipped"


def keeps_structure(point: dict) -> bool:
    """Whether the run kept the scene's structure at the display's size (1024 px; rows without it count)."""
    value = point.get("structure_1024")
    return value in (None, "") or float(value) >= MIN_STRUCTURE


def front_figure(points: list[dict]) -> str:
    """The style figure a group's front and plot use: the NNFM drop at 1024 px, a display's size, where every point
    of the group has it (every tier is measured there on the same views against the painting at that width; what a
    finer level buys shows there, not at 256 px), else the drop at 256 px (rows of atlases before it)."""
    return "nnfm_drop_1024" if points and all(p.get("nnfm_drop_1024") not in (None, "") for p in points) \
        else "nnfm_drop"


def pareto(points: list[dict]) -> list[bool]:
    """True for points that keep the structure and that no such point beats on both time (lower) and NNFM drop
    (higher; ``front_figure``): a stronger style bought by losing the scene is not a trade-off."""
    kept = [p for p in points if keeps_structure(p)]
    key = front_figure(points)

    def beats(q: dict, p: dict) -> bool:
        t_q, t_p, d_q, d_p = float(q["seconds"]), float(p["seconds"]), float(q[key]), float(p[key])
        return q is not p and t_q <= t_p and d_q >= d_p and (t_q < t_p or d_q > d_p)

    return [keeps_structure(p) and not any(beats(q, p) for q in kept) for p in points]


def group_name(row: dict) -> str:
    """The front a point belongs to: its device, scene and painting (tiers and knobs are its points)."""
    return f"{row['device']}: {row['scene']} / {row['painting']}"


def mark_fronts(rows: list[dict]) -> None:
    """Set each row's ``pareto`` flag within its group (``group_name``)."""
    for name in {group_name(r) for r in rows}:
        points = [r for r in rows if group_name(r) == name]
        for r, flag in zip(points, pareto(points), strict=True):
            r["pareto"] = flag


def read_rows(path: Path) -> list[dict]:
    """The CSV's rows, numbers back to numbers ({} cells left out); [] when there is no CSV yet."""
    if not path.is_file():
        return []
    rows = []
    with path.open(newline="", encoding="utf-8") as fh:
        for raw in csv.DictReader(fh):
            row: dict = {}
            for k, v in raw.items():
                if v in ("", None):
                    continue
                if k in FIGURES or k in ("load_before", "load_after"):
                    row[k] = int(v) if k in INTEGERS else float(v)
                else:
                    row[k] = v == "True" if k == "pareto" else v
            rows.append(row)
    return rows


def merged(old: list[dict], new: list[dict]) -> list[dict]:
    """``old`` with the points ``new`` measured again replaced, the new ones added (in their order)."""
    keys = {tuple(r[k] for k in KEY) for r in new}
    return [r for r in old if tuple(r[k] for k in KEY) not in keys] + new


def write_rows(rows: list[dict], path: Path) -> None:
    """Mark the fronts and write the CSV atomically (every column, empty where a row has nothing)."""
    from gstyle_core.atomic import atomic_write_text

    mark_fronts(rows)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: (f"{r[k]:.5g}" if isinstance(r.get(k), float) else r.get(k, "")) for k in COLUMNS})
    atomic_write_text(path, buf.getvalue())


def plot(rows: list[dict], folder: Path, stem: str) -> list[Path]:
    """A plot per device (``folder/STEM_DEVICE.png``): NNFM drop (``front_figure``) against wall time, a panel per
    scene / painting, the Pareto front in red, points that lose the structure at 1024 px as ×. [] without
    matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed (pip install -e .[bench]): no plot")
        return []
    from gstyle_core.atomic import atomic_write

    written = []
    for device in sorted({r["device"] for r in rows}):
        mine = [r for r in rows if r["device"] == device]
        groups = sorted({(r["scene"], r["painting"]) for r in mine})
        cols = min(3, len(groups))
        nrows = -(-len(groups) // cols)
        fig, axes = plt.subplots(nrows, cols, figsize=(5.0 * cols, 3.8 * nrows), squeeze=False)
        for ax in axes.flat[len(groups):]:
            ax.set_visible(False)
        for ax, (scene, painting) in zip(axes.flat, groups, strict=False):
            draw_group(ax, [r for r in mine if (r["scene"], r["painting"]) == (scene, painting)])
            ax.set_title(f"{scene} / {painting}", fontsize=10)
        fig.suptitle(f"{device}: {mine[0].get('machine', '')}", fontsize=9)
        fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / (3.8 * nrows)))  # room for the suptitle
        path = folder / f"{stem}_{device}.png"
        with atomic_write(path, "wb") as fh:
            fig.savefig(fh, format="png", dpi=100)
        plt.close(fig)
        written.append(path)
    return written


def point_label(r: dict) -> str:
    """A point's name on a plot and in the table: its tier, and its knob where it is not as shipped."""
    return r["tier"] if r["knob"] == SHIPPED else f"{r['tier']}, {r['knob']}"


def draw_group(ax, points: list[dict]) -> None:
    """One panel: the points (× where the structure is lost), their names, the front (``front_figure`` up)."""
    key = front_figure(points)
    kept = [r for r in points if keeps_structure(r)]
    lost = [r for r in points if not keeps_structure(r)]
    ax.scatter([r["seconds"] for r in kept], [100 * r[key] for r in kept], c="tab:blue", s=22)
    if lost:
        ax.scatter([r["seconds"] for r in lost], [100 * r[key] for r in lost], c="tab:gray", s=30,
                   marker="x", label=f"structure at 1024 px < {MIN_STRUCTURE:g}")
    for r in points:
        if "seconds_min" in r and "seconds_max" in r:
            ax.plot([r["seconds_min"], r["seconds_max"]], [100 * r[key]] * 2, c="tab:blue", lw=1)
        ax.annotate(point_label(r), (r["seconds"], 100 * r[key]), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    front = sorted((r for r in points if r.get("pareto")), key=lambda r: r["seconds"])
    ax.plot([r["seconds"] for r in front], [100 * r[key] for r in front], "-o", c="tab:red", ms=5,
            label="Pareto front")
    ax.set_xlabel("wall time (s, median of the repeats)")
    ax.set_ylabel("NNFM drop at 1024 px (%)" if key == "nnfm_drop_1024" else "NNFM drop at 256 px, every tier (%)")
    ax.grid(alpha=0.3)
    ax.margins(0.15)
    ax.legend(fontsize=7, loc="best")


TABLE_HEAD = ("tier / knob", "device", "scene / painting", "s (min–max)", "drop 256 px", "structure 256 px",
              "end px: drop / structure", "1024 px: drop / structure / speckle", "coarse", "colour",
              "consistency (input)", "front")


def markdown_table(rows: list[dict]) -> list[str]:
    """The table of docs/notes/tradeoffs.md from the CSV's rows."""
    def num(r: dict, key: str, fmt: str) -> str:
        return "—" if r.get(key) in (None, "") else format(float(r[key]), fmt)

    def percent(r: dict, key: str) -> str:
        return "—" if r.get(key) in (None, "") else f"{100 * float(r[key]):.1f} %"

    lines = ["| " + " | ".join(TABLE_HEAD) + " |", "|" + "---|" * len(TABLE_HEAD)]
    for r in rows:
        repeated = int(r.get("repeats", 1)) > 1
        spread = f" ({num(r, 'seconds_min', '.0f')}–{num(r, 'seconds_max', '.0f')})" if repeated else ""
        drop_spread = (f" (Δ {100 * float(r['nnfm_drop_spread']):.1f})"  # the repeats' spread, in points
                       if repeated and r.get("nnfm_drop_spread") not in (None, "") else "")
        lines.append(
            f"| {point_label(r)} | {r['device']} | {r['scene']} / {r['painting']} | {num(r, 'seconds', '.0f')}{spread}"
            f" | {100 * float(r['nnfm_drop']):.1f} %{drop_spread} | {num(r, 'structure', '.2f')} | {r['end_width']}: "
            f"{100 * float(r['nnfm_drop_end']):.1f} % / {num(r, 'structure_end', '.2f')} | "
            f"{percent(r, 'nnfm_drop_1024')} / {num(r, 'structure_1024', '.2f')} / {num(r, 'speckle_1024', '.2f')} | "
            f"{num(r, 'coarse_ratio', '.2f')} | "
            f"{num(r, 'colour', '.3f')} | {num(r, 'consistency', '.4f')} ({num(r, 'consistency_input', '.4f')}) | "
            f"{'yes' if r.get('pareto') else ''} |")
    return lines

TIERS = ("preview", "balanced", "final")
TABLE_BEGIN, TABLE_END = "<!-- atlas-table begin -->", "<!-- atlas-table end -->"


def _shipped(rows: list[dict], tier: str, device: str, scenes: set[str], paintings: set[str]) -> list[dict]:
    return [r for r in rows if r.get("knob") == SHIPPED and r["tier"] == tier and r["device"] == device
            and r["scene"] in scenes and r["painting"] in paintings]


def tiers_table(rows: list[dict]) -> list[str]:
    """The tiers' table of the README and docs/tiers.md: per tier the demo × The Starry Night in bf16 on the CPU (its
    seconds and its figures at 1024 px), the range of seconds over the demo and the fern after three paintings on the
    CPU, and the demo × The Great Wave on CUDA; a dash where the atlas has no row."""
    def cell(points: list[dict], key: str, fmt: str) -> str:
        if not points or points[0].get(key) in (None, ""):
            return "–"
        value = float(points[0][key])
        return f"{100 * value:.1f} %" if key in PERCENT else format(value, fmt)

    def span(points: list[dict]) -> str:
        if not points:
            return "–"
        low, high = (f"{v:.0f}" for v in (min(float(p["seconds"]) for p in points),
                                          max(float(p["seconds"]) for p in points)))
        return f"{low} s" if low == high else f"{low}–{high} s"

    lines = ["| tier | CPU: demo × Starry Night | NNFM drop at 1024 px | structure | speckle | CPU: 2 scenes × 3 "
             "paintings | GPU: demo × Great Wave |", "|---|---|---|---|---|---|---|"]
    for tier in TIERS:
        demo = _shipped(rows, tier, "cpu-bf16", {"fountain"}, {"starry"})
        spread = _shipped(rows, tier, "cpu-bf16", {"fountain", "fern"}, {"starry", "wave", "autumn"})
        gpu = _shipped(rows, tier, "cuda", {"fountain"}, {"wave"})
        lines.append(f"| `{tier}` | {span(demo)} | {cell(demo, 'nnfm_drop_1024', '')} | "
                     f"{cell(demo, 'structure_1024', '.2f')} | {cell(demo, 'speckle_1024', '.2f')} | {span(spread)} | "
                     f"{span(gpu)} |")
    return lines


def generated_block(text: str) -> list[str] | None:
    """The lines between a page's atlas-table markers; None for a page without them."""
    if TABLE_BEGIN not in text:
        return None
    return text.partition(TABLE_BEGIN)[2].partition(TABLE_END)[0].strip("\n").splitlines()


def with_tiers_table(text: str, rows: list[dict]) -> str:
    """``text`` with the block between its atlas-table markers replaced by ``tiers_table(rows)``."""
    head, _, rest = text.partition(TABLE_BEGIN)
    _, end, tail = rest.partition(TABLE_END)
    if not end:
        raise ValueError(f"a page has {TABLE_BEGIN} without {TABLE_END}")
    return head + TABLE_BEGIN + "\n" + "\n".join(tiers_table(rows)) + "\n" + TABLE_END + tail
