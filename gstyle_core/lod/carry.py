"""Back from the parents to every input Gaussian: the leaves stay the truth.

A run on a cut ends with rows that each descend from one parent (``lineage``; a split parent has several). Rows of
parents that are input Gaussians held as they were are the result as the run made them. A merged parent's children
are written instead of its rows, each with its own geometry and its own colour plus the change of its parent's
nearest descendant (``deltas``: the stylized colour minus the colour the row had before stylization). The parent's
colour is the weighted mean of its children's (``moments``), so the children re-merged give the parent's new colour
exactly, and each child keeps its own difference from the others: its detail. Unselected children of a region run
are the input's rows exactly.
"""

from __future__ import annotations

import numpy as np

from ..neighbours import nearest_rows
from ..scene import GaussianScene, rgb_to_sh_dc
from .cut import LodCut


def descendant_rows(lineage: np.ndarray, positions: np.ndarray, parents: np.ndarray,
                    child_positions: np.ndarray) -> np.ndarray:
    """For children of the parents ``parents`` (at ``child_positions``) the row that carries their parent's change:
    the parent's only descendant (``lineage``: each row's parent), or, where a parent was split into several, the
    nearest by centre among the descendants of split parents."""
    n_parents = int(max(lineage.max(initial=-1), parents.max(initial=-1))) + 1
    count = np.bincount(lineage, minlength=n_parents)
    first = np.full(n_parents, -1, np.int64)
    first[lineage[::-1]] = np.arange(len(lineage))[::-1]
    out = first[parents]
    crowded = count[parents] != 1
    if crowded.any():
        pool = np.flatnonzero(count[lineage] > 1)
        pool = pool[np.isin(lineage[pool], parents[crowded])]
        if len(pool) == 0:  # a parent with no descendant left (not in a run): the nearest of all rows
            pool = np.arange(len(lineage))
        out[crowded] = pool[nearest_rows(positions[pool], child_positions[crowded])]
    return out


def carried_colours(own: np.ndarray, change: np.ndarray, keep_colours: bool = False) -> np.ndarray:
    """Children's colours: their own RGB plus their parent's change, in [0, 1]; with ``keep_colours`` each keeps its
    own hue and chroma (only the luminance changes, as the run's colours do: ``style.keep_colours``)."""
    own = np.asarray(own)
    out = own + change.astype(own.dtype, copy=False)
    if keep_colours:
        import torch

        from ..style.keep_colours import with_chroma_of

        out = with_chroma_of(torch.from_numpy(out), torch.from_numpy(np.ascontiguousarray(own))).numpy()
    return np.clip(out, 0.0, 1.0, out=out)


def expand_to_children(rows: GaussianScene, deltas: np.ndarray, lineage: np.ndarray, cut: LodCut,
                       full_input: GaussianScene, full_selection: np.ndarray | None = None,
                       keep_colours: bool = False) -> GaussianScene:
    """The whole capture from a run on ``cut``: ``rows`` (the run's result; ``lineage``: each row's parent in
    ``cut.parents``; ``deltas``: each row's colour change, RGB [R, 3]) with every merged parent's rows replaced by its
    children of ``full_input``. Stylized children have no SH bands (a stylized colour does not change with the view);
    a region's unselected ones (``full_selection`` False) are the input's rows exactly; ``keep_colours``: each child
    keeps its hue (``carried_colours``)."""
    lineage = np.asarray(lineage, np.int64)
    keep = ~cut.merged[lineage]
    children = np.flatnonzero(cut.merged[cut.child_parent])
    if len(children) == 0:
        return rows
    kids = full_input.subset(children)
    if len(lineage) and (~keep).any():
        source = descendant_rows(lineage, rows.means, cut.child_parent[children], full_input.means[children])
        change = np.asarray(deltas, np.float64)[source]
    else:  # no descendant of a merged parent is left (cannot happen in a run): the children as they came in
        change = np.zeros((len(children), 3))
    recolour = np.ones(len(children), bool) if full_selection is None else np.asarray(full_selection, bool)[children]
    rgb = carried_colours(kids.rgb.astype(np.float64), change, keep_colours)
    kids.sh_dc[recolour] = rgb_to_sh_dc(rgb[recolour]).astype(kids.sh_dc.dtype)
    degree = max(rows.sh_degree, kids.sh_degree)
    held, kids = (p if p.sh_degree == degree else p.with_sh_degree(degree) for p in (rows.subset(keep), kids))
    kids.sh_rest[recolour] = 0.0
    return GaussianScene.concatenate([held, kids])
