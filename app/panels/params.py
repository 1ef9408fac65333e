"""The panel's engine parameters: each a log-scale slider (a loss term's λ with an on/off checkbox), and the
tooltips of the other engine controls. One table: the sliders, their reset values and "Reset all" follow it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Param:
    """One engine parameter shown as a log-scale slider; a loss term's λ also gets an on/off checkbox."""

    key: str
    label: str
    default: float
    low: float
    high: float
    tooltip: str

    @property
    def is_term(self) -> bool:
        """True for a loss term's weight (λ), which can be switched off (weight 0) and on again."""
        return self.key.startswith("lambda_")


PARAMS = (
    Param("lambda_clip", "lambda CLIP", 10.0, 1e-2, 1e3,
          "Weight of the CLIP term: matches the style's large-scale patterns and layout of colour."),
    Param("lambda_nnfm", "lambda NNFM", 100.0, 1e-1, 1e4,
          "Weight of the nearest-neighbour feature matching term: brush strokes and local texture (VGG)."),
    Param("lambda_content", "lambda content", 0.05, 1e-4, 10.0,
          "Weight of content preservation: keeps the scene recognisable (VGG features of the photo)."),
    Param("lambda_tv", "lambda TV", 1e-4, 1e-7, 1e-1, "Weight of total variation: smooths noisy pixels."),
    Param("strength", "style strength", 1.0, 0.1, 100.0,
          "Style strength: multiplies the style terms (CLIP and NNFM) against content preservation; 1 keeps the "
          "lambda values as they are, more paints harder, less keeps more of the scene."),
    Param("style_scale", "stroke size", 1.0, 0.25, 4.0,
          "Stroke size: the scale at which the painting's brush strokes are matched (its image resized to this times "
          "the working width before its VGG features are taken): 2 matches the painting at twice that size, 0.5 at "
          "half; at the preview's 256 px the visible change is subtle (README). "
          "Changing it re-extracts the painting's features from the next step on (--style-scale)."),
    Param("split_rate", "split rate", 0.05, 1e-3, 0.5,
          "Fraction of Gaussians split where the style gradient is largest (finer detail, more Gaussians)."),
    Param("lr", "learning rate", 0.1, 1e-3, 1.0, "Starting learning rate of the colour optimisation."),
)
COARSE_CLIP_TOOLTIP = (
    "Weight of the coarse (CLIP substitute) term: no CLIP ViT-B/32 weights were found, so the style's large-scale "
    "colour and texture statistics (VGG features of 4x smaller images) are matched instead of CLIP's embedding.")
KEEP_COLOURS_TOOLTIP = (
    "Keep the scene's colours: it keeps its hues and takes only the painting's light and dark pattern (colour "
    "match and networks on luminance; each Gaussian's own chroma restored after every step). Turned on mid-run the "
    "hues come back at once; turned off, the painting's colours are matched again from the next step and at the "
    "end (--keep-colours).")
STYLE_MIX_TOOLTIP = (
    "Share of the second painting: 0 is the first alone, 1 the second alone. Every style term is the weighted sum of "
    "its terms against each painting, and the colours match the weighted palette; changed mid-run it applies from "
    "the next step (--style A --style B --style-weights).")
