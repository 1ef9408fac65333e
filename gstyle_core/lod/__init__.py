"""A level of detail at the run's width: Gaussians far below a pixel in every training view merged into parents.

``cut.build_cut`` groups such Gaussians into cells about a pixel wide at their depth (``footprint``) and merges each
group by moment matching (``moments``); the engine stylizes the parents, and ``carry.expand_to_children`` writes
every input Gaussian back with its own geometry and its own colour plus its parent's change.
"""

from .carry import expand_to_children
from .cut import LodCut, build_cut
from .moments import covariances, merge_groups

__all__ = ["LodCut", "build_cut", "covariances", "expand_to_children", "merge_groups"]
