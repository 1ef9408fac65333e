"""What ``gstyle batch`` writes at the end: ``batch.csv`` (a row per job, its figures from OUT.json's ``quality``)
and ``contact_sheet.png`` (scenes as rows, a plan's runs one after another, paintings as columns, each cell the
job's after picture over a line of its figures; a failed job's cell grey)."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from ..atomic import atomic_path, atomic_write_text
from ..outputs import companion
from .jobs import Job, summary_path

CSV_COLUMNS = ("scene", "painting", "run", "status", "seconds", "preset", "nnfm_initial", "nnfm_final", "nnfm_drop",
               "structure", "speckle_ratio", "speckle_width", "out")
CELL_WIDTH, TEXT_HEIGHT = 256, 30  # a cell: the picture 256 px wide, two lines of text below
PICTURE_HEIGHT, MAX_PICTURE_HEIGHT = 192, 512  # the picture's box: the tallest picture's height at that width, capped
# (192 where no job has a picture)
FAILED_GREY = (128, 128, 128)


def job_figures(job: Job) -> dict:
    """The CSV's figures of a finished job from its OUT.json (empty for a failed job or one without a summary):
    NNFM drop = 1 − final / initial NNFM distance, structure kept, speckle ratio at the display width."""
    try:
        summary = json.loads(summary_path(job).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    q = summary.get("quality", {})
    initial, final = q.get("initial", {}).get("nnfm"), q.get("final", {}).get("nnfm")
    display = q.get("display") or {}
    return {"preset": summary.get("settings", {}).get("preset"), "nnfm_initial": initial, "nnfm_final": final,
            "nnfm_drop": 1 - final / initial if initial and final is not None else None,
            "structure": q.get("structure"), "speckle_ratio": display.get("speckle_ratio"),
            "speckle_width": display.get("width"), "seconds_total": summary.get("seconds_total")}


def csv_rows(jobs: list[Job]) -> list[dict]:
    """A row per job; a job done in an earlier batch has the seconds its summary records."""
    rows = []
    for job in jobs:
        figures = job_figures(job) if job.status != "failed" else {}
        seconds = job.seconds if job.seconds is not None else figures.get("seconds_total")
        row = {"scene": job.scene, "painting": job.painting, "run": job.run, "status": job.status, "out": str(job.out),
               "seconds": None if seconds is None else round(seconds, 2), **figures}
        rows.append({key: ("" if row.get(key) is None else _rounded(row[key])) for key in CSV_COLUMNS})
    return rows


def _rounded(value):
    """Figures to 4 decimals; other values as they are."""
    return round(value, 4) if isinstance(value, float) else value


def write_csv(jobs: list[Job], path: Path) -> Path:
    """``batch.csv``, written atomically."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(csv_rows(jobs))
    atomic_write_text(path, text.getvalue())
    return path


def figures_line(figures: dict) -> str:
    """A cell's line of figures."""
    parts = []
    if figures.get("nnfm_drop") is not None:
        parts.append(f"NNFM -{100 * figures['nnfm_drop']:.0f}%")
    if figures.get("structure") is not None:
        parts.append(f"structure {figures['structure']:.2f}")
    if figures.get("speckle_ratio") is not None:
        parts.append(f"speckle {figures['speckle_ratio']:.2f}")
    return ", ".join(parts) or "no figures"


def picture_height(jobs: list[Job]) -> int:
    """The height of the sheet's picture boxes: the tallest after picture scaled to the cell width."""
    from PIL import Image

    heights = []
    for job in jobs:
        after = companion(job.out, "_after.png")
        if job.status != "failed" and after.exists():
            with Image.open(after) as picture:
                heights.append(-(-CELL_WIDTH * picture.height // picture.width))
    return min(max(heights), MAX_PICTURE_HEIGHT) if heights else PICTURE_HEIGHT


def cell(job: Job, font, height: int):
    """The job's cell: its after picture fitted in the picture box ``height`` px high (grey with "failed" if it
    failed), its name and figures below."""
    from PIL import Image, ImageDraw, ImageOps

    image = Image.new("RGB", (CELL_WIDTH, height + TEXT_HEIGHT), "white")
    draw = ImageDraw.Draw(image)
    after = companion(job.out, "_after.png")
    if job.status == "failed" or not after.exists():
        draw.rectangle((0, 0, CELL_WIDTH - 1, height - 1), fill=FAILED_GREY)
        draw.text((CELL_WIDTH // 2, height // 2), "failed", fill="white", font=font, anchor="mm")
        words = "failed"
    else:
        with Image.open(after) as picture:
            fitted = ImageOps.contain(picture.convert("RGB"), (CELL_WIDTH, height))
        image.paste(fitted, ((CELL_WIDTH - fitted.width) // 2, (height - fitted.height) // 2))
        words = figures_line(job_figures(job))
    name = f"{Path(job.scene).name} x {Path(job.painting).name}" + (f" ({job.run})" if job.run else "")
    draw.text((4, height + 2), name, fill="black", font=font)
    draw.text((4, height + 16), words, fill="black", font=font)
    return image


def write_contact_sheet(jobs: list[Job], path: Path) -> Path:
    """``contact_sheet.png``: a row per run and scene, a column per painting (in the order planned; a run without
    a painting leaves its cell white), written atomically."""
    from PIL import Image, ImageFont

    font, box = ImageFont.load_default(), picture_height(jobs)
    height = box + TEXT_HEIGHT
    rows = list(dict.fromkeys((job.run, job.scene) for job in jobs))
    columns = list(dict.fromkeys(job.painting for job in jobs))
    sheet = Image.new("RGB", (CELL_WIDTH * max(1, len(columns)), height * max(1, len(rows))), "white")
    for job in jobs:
        row, col = rows.index((job.run, job.scene)), columns.index(job.painting)
        sheet.paste(cell(job, font, box), (col * CELL_WIDTH, row * height))
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="PNG")
    return path
