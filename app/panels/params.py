"""The panel's engine parameters: each a slider (a loss term's λ with an on/off checkbox), derived from the table of
live controls (``gstyle_core.engine.controls``): the sliders, their reset values and "Reset all" follow it."""

from __future__ import annotations

from dataclasses import dataclass

from gstyle_core.engine.controls import panel_controls


@dataclass(frozen=True)
class Param:
    """One engine parameter shown as a slider (a row of ``gstyle_core.engine.controls``); a loss term's λ also
    gets an on/off checkbox."""

    key: str
    label: str
    default: float
    low: float
    high: float
    tooltip: str
    log: bool = True
    fmt: str = "%.3g"

    @property
    def is_term(self) -> bool:
        """True for a loss term's weight (λ), which can be switched off (weight 0) and on again."""
        return self.key.startswith("lambda_")


def _rows(widget: str) -> tuple[Param, ...]:
    """Every live control the panel shows as ``widget`` ("slider" or "checkbox"; ``controls.panel_controls``)."""
    return tuple(Param(c.name, c.label, c.default, c.low, c.high, c.tooltip, c.log, c.fmt)
                 for c in panel_controls(widget))


def param_rows() -> tuple[Param, ...]:
    """The parameter section's sliders."""
    return _rows("slider")


COARSE_CLIP_TOOLTIP = (
    "Large patterns: the painting's large-scale colour and texture. The engine's coarse (CLIP substitute) term "
    "(lambda_clip, --lambda-clip): no CLIP ViT-B/32 weights were found, so the style's large-scale colour and "
    "texture statistics (VGG features of 4x smaller images) are matched instead of CLIP's embedding.")


def switch_rows() -> tuple[Param, ...]:
    """The parameter section's checkboxes (keep colours, coherent strokes)."""
    return _rows("checkbox")
