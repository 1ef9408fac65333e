"""Command-line value types of the stylization options (``--style-scale``, ``--palette-match``, ``--style-weights``,
``--region``, ``--colour-field``, ``--display-width``, ``--refine-widths``), shared by ``gstyle stylize`` and
``gstyle-studio``: a bad value is one line from argparse (exit status 2), not a traceback; and the palette match's own
check, which the controls table uses too (the stroke size's is ``style/painting_size.py``'s). Nothing here imports
torch, the settings or the controls (no import cycle through them)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from ..style.painting_size import check_style_scale


def argument_type(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """An argparse ``type`` from a parser that raises ``ValueError`` saying why: argparse then reports the reason in
    one line (and exits with status 2) instead of a traceback."""
    def checked(text: str) -> Any:
        try:
            return parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    return checked


def check_palette_match(strength: Any) -> float:
    """``strength`` as a float if it is a usable palette-match strength (0 to 1), else ``ValueError`` saying why."""
    try:
        value = float(strength)
    except (TypeError, ValueError):
        raise ValueError(f"palette match must be a number, got {strength!r}") from None
    if not 0.0 <= value <= 1.0:  # NaN fails too
        raise ValueError(f"palette match must lie from 0 (the strokes' colours) to 1 (the full match), got {strength}")
    return value


def _style_scale(text: str) -> float:
    """``--style-scale``: a finite number above 0."""
    return check_style_scale(float(text))


def _style_weights(text: str) -> tuple[float, ...]:
    """``--style-weights``: numbers separated by commas, each finite and >= 0, not all 0."""
    from ..style.mix import normalise_style_weights, parse_style_weights

    values = parse_style_weights(text)
    normalise_style_weights(values, len(values))
    return tuple(values)


def _region(text: str) -> tuple[float, ...]:
    """``--region``: six comma-separated finite numbers, low corner first."""
    from .region import parse_region

    return parse_region(text)


MAX_DISPLAY_WIDTH = 8192


def _display_width(text: str) -> int:
    """``--display-width``: 0 (no display figure) or a whole number of pixels from 16 to ``MAX_DISPLAY_WIDTH``."""
    try:
        width = int(text)
    except ValueError:
        raise ValueError(f"expected a whole number of pixels, got {text!r}") from None
    if width != 0 and not 16 <= width <= MAX_DISPLAY_WIDTH:
        raise ValueError(f"must be 0 (skip the figure) or 16 to {MAX_DISPLAY_WIDTH} px, got {width}")
    return width


def _widths(text: str) -> tuple[int, ...]:
    """``--refine-widths``: whole numbers of pixels separated by commas, ascending (an empty string or 0: none)."""
    from .levels import check_refine_widths

    parts = [p.strip() for p in text.split(",") if p.strip()]
    if parts == ["0"]:
        return ()
    try:
        widths = tuple(int(p) for p in parts)
    except ValueError:
        raise ValueError(f"expected widths in pixels separated by commas, e.g. 512,1024, got {text!r}") from None
    return check_refine_widths(widths)


def _on_off(text: str) -> bool:
    """A switch given a value: 1/on/yes/true or 0/off/no/false (any case)."""
    word = text.strip().lower()
    if word in ("1", "on", "yes", "true"):
        return True
    if word in ("0", "off", "no", "false"):
        return False
    raise ValueError(f"expected 1 or 0 (on or off), got {text!r}")


def _lod_pixels(text: str) -> float:
    """``--lod-pixels``: the level of detail's cell size, a finite number of pixels from 0.25 to 64."""
    value = float(text)
    if not 0.25 <= value <= 64.0:  # NaN fails too
        raise ValueError(f"must lie from 0.25 to 64 px, got {text}")
    return value


style_scale_arg = argument_type(_style_scale)
lod_pixels_arg = argument_type(_lod_pixels)
palette_match_arg = argument_type(check_palette_match)  # --palette-match: 0 to 1
on_off_arg = argument_type(_on_off)
style_weights_arg = argument_type(_style_weights)
region_arg = argument_type(_region)
display_width_arg = argument_type(_display_width)
widths_arg = argument_type(_widths)
