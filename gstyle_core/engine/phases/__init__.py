"""The phases of a stylization run, in order (each its own module, one interface: ``base.Phase``):

1. ``ground_truth``: one view per step: the scene's photos, or renders of the input scene (with its SH).
2. ``preprocess``: rounds of flat-Gaussian split + refit with elongation clamps, or skipped (``preprocess.py``).
3. ``colour_match``: one step: c_gt mapped onto the painting's palette to start c_s; the content targets
   (``colour_match.py``).
4. ``stylize``: optimiser steps on c_s, with colour-gradient splits (``colour_split.py``) each followed by a
   ``refit`` (``refit.py``; reported as the phase ``refit``).
5. ``refine_K``: one per finer level (``settings.refine_widths``, coarse to fine): the ground truth at the level's
   width, then optimiser steps on c_s from the colours as they are, on crops or whole views at that width
   (``refine.py``; reported as the phase ``refine``).
6. ``finish``: one step: the stylized colours matched to the painting once more (the same ``ColourMatch``), when
   ``settings.colour_match_after``; ``settings.palette_match`` blends the matched colours with the ones before it
   (0: those, 1: the full match), and a finished run takes a new strength at once.
They share a ``RunState`` (``engine/run_state.py``) and its active set (``engine/active.py``); the runner
``engine/stylizer.Stylizer`` steps them and collects their checkpoints.
"""

from .base import Phase, StepReport
from .colour_match import ColourMatch
from .colour_split import ColourSplit
from .ground_truth import GroundTruth
from .preprocess import Preprocess
from .refine import Refine
from .refit import Refit
from .stylize import Stylize

__all__ = ["Phase", "StepReport", "GroundTruth", "Preprocess", "Refit", "ColourMatch", "ColourSplit", "Stylize",
           "Refine"]
