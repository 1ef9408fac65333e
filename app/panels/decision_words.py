"""The engine's decisions worded for an artist (issue #35 item 6): a few plain lines the *Decisions* section shows
first (what it computes on, at which widths, how strokes and colours are matched, what it leaves alone); the
engine's own lines follow under *Engine details*. Only decisions the engine made are worded; an unknown or
missing one gives no line."""

from __future__ import annotations

import re
from typing import Any


def _device(value: str) -> str:
    kind, _, rest = value.partition(" ")
    if kind == "cuda":
        card = rest.split("):", 1)[0].strip("( ")
        return f"Computing on the GPU ({card.split(' (')[0]})"
    if kind == "mps":
        return "Computing the networks on the Apple GPU, the rest on the CPU"
    return "Computing on the CPU"


def _levels(value: str) -> str:
    widths = re.findall(r"(\d+) px", value.split(",", 1)[0])
    if len(widths) < 2:
        return ""
    return f"Paints at {widths[0]} px wide first, then sharpens at {', '.join(widths[1:])} px"


def _levels_capped(value: str) -> str:
    match = re.search(r"photos are (\d+) px wide", value)
    return f"Ends at the photos' width, {match.group(1)} px: a wider level would only enlarge them" if match else ""


def _strokes(value: str) -> str:
    match = re.search(r"matched at (\S+) px[^:]*: stroke size ([\d.]+)", value)
    if not match:
        return ""
    return f"Brush strokes as the painting shows them at {match.group(1)} px (stroke size {match.group(2)})"


def _colours(value: str) -> str:
    return "Colours: " + value.split(" (", 1)[0]


def _culled(value: str) -> str:
    match = re.match(r"([\d,]+) of ([\d,]+) Gaussians", value)
    if not match or match.group(1).replace(",", "") == "0":
        return ""
    if match.group(1) == "1":
        return "1 splat no camera sees is left as it is"
    return f"{match.group(1)} splats no camera sees are left as they are"


def _preprocess(value: str) -> str:
    match = re.match(r"(\d+) round", value)
    if not match:
        return ""
    rounds = int(match.group(1))
    if rounds == 0:
        return "Splat sizes already even: no splitting before the painting"
    return f"Large flat splats split first ({rounds} round{'s' if rounds > 1 else ''}) so strokes can cross them"


def _large_shapes(decisions: dict[str, Any]) -> str:
    clip = str(decisions.get("clip", ""))
    if "broad_strokes" in decisions and not str(decisions["broad_strokes"]).startswith("off"):
        return "Large shapes: the painting's strokes matched at half, quarter and eighth size (no CLIP weights)"
    if "substitute" in clip:
        return "Large shapes: a coarse stand-in for CLIP (no CLIP weights found)"
    if "weights from" in clip:
        return "Large shapes: CLIP"
    return ""


def _lod(value: str) -> str:
    match = re.match(r"([\d,]+) Gaussians as ([\d,]+) parents at (\d+) px", value)
    if not match:
        return ""
    return (f"Paints {match.group(1)} splats as {match.group(2)} groups at {match.group(3)} px; "
            "every splat is exported with its own shape")


def _precision(value: str) -> str:
    kind = value.split(" ", 1)[0].rstrip(":")
    if kind not in ("bf16", "fp32"):
        return ""
    return f"Networks in {kind}" + (" (faster on this machine, the same result)" if kind == "bf16" else "")


WORDINGS = (("device", _device), ("lod", _lod), ("levels", _levels),
            ("levels_capped", _levels_capped), ("style_scale", _strokes),
            ("colours", _colours), ("clip", None), ("preprocess", _preprocess), ("culled", _culled),
            ("precision", _precision))


def artist_lines(decisions: dict[str, Any]) -> list[str]:
    """The decisions an artist cares about, one plain line each, in a fixed order (the large-shapes line in
    ``clip``'s place: it reads ``clip`` and ``broad_strokes``)."""
    lines = [_large_shapes(decisions) if word is None else word(str(decisions[key]))
             for key, word in WORDINGS if word is None or decisions.get(key) not in (None, "")]
    return [line for line in lines if line]
