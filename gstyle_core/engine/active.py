"""The active set of a run: the Gaussians it works on, with gather/scatter between the row spaces it uses.

Three row spaces meet in a run:
- *all*: every current Gaussian (``params``, ``c_s``, the accumulated colour gradient);
- *seen*: the Gaussians some training camera sees (``visibility.py``), in index order: the columns of the colour
  caches; with ``cull_unseen`` off, or when every Gaussian is seen, the same as *all*;
- *active*: the seen Gaussians that are also selected (a region run, ``region.py``); without a region, the seen ones.
Only active Gaussians are pre-processed, split, refitted and optimised. ``None`` index tensors stand for "every row"
inside this class only: callers gather and scatter without asking which case they are in.

A region run also carries ``selected`` (bool over all rows) and ``origin`` (each row's input row); splits extend
both (children inherit their parent's), so they follow the rows through ``split_extras`` / ``take_split_extras``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from .visibility import culling_note, seen_mask

Key = tuple[int, int]  # (geometry version, Gaussian count): when the sets must be worked out again


class ActiveSet:
    """Which Gaussians a run works on, recomputed when the geometry changes (``seen`` needs a visibility pass)."""

    def __init__(self, run: Any, selection: np.ndarray | None) -> None:
        """``run``: the run state (``params``, ``cameras``, ``settings``, ``decisions``, ``counters`` and
        ``geometry_key()``); ``selection``: bool over its Gaussians (None: all)."""
        self.run = run
        self.selected = None if selection is None else torch.as_tensor(selection, dtype=torch.bool)
        self.origin = None if selection is None else torch.arange(len(self.selected))
        self._seen: tuple[Key | None, torch.Tensor | None] = (None, None)
        self._active: tuple[Key | None, tuple[torch.Tensor, torch.Tensor] | None] = (None, None)

    @property
    def region(self) -> bool:
        """True in a region run (a selection was given)."""
        return self.selected is not None

    # --------------------------------------------------------------------------------------------- index sets
    def seen_ids(self) -> torch.Tensor | None:
        """Indices of the Gaussians some training camera sees; None when that is all of them (or culling is off).
        Worked out again whenever the geometry changed (a new version or count): after every split and refit."""
        run, key = self.run, self.run.geometry_key()
        if key == self._seen[0]:
            return self._seen[1]
        n = key[1]
        if not run.settings.cull_unseen:
            run.decisions["culled"] = "off (cull_unseen = False): every Gaussian is rendered, optimised, split"
            ids = None
        else:
            p = run.params
            mask = seen_mask(p["means"], p["quats"], torch.exp(p["log_scales"].detach()),
                             torch.sigmoid(p["opacity_logits"].detach()), run.cameras)
            run.counters["visibility_passes"] += 1
            unseen = n - int(mask.sum())
            run.decisions["culled"] = culling_note(unseen, n, len(run.cameras))
            ids = torch.nonzero(mask).flatten() if unseen else None
        self._seen = (key, ids)
        return ids

    def ids(self) -> torch.Tensor | None:
        """Indices of the active Gaussians; None when that is all of them."""
        if self.selected is None:
            return self.seen_ids()
        return self._region_sets()[0]

    def positions(self) -> torch.Tensor | None:
        """Positions of the active Gaussians among the seen ones (the colour caches' columns); None: all of them."""
        return None if self.selected is None else self._region_sets()[1]

    def _region_sets(self) -> tuple[torch.Tensor, torch.Tensor]:
        key = self.run.geometry_key()
        if key != self._active[0]:
            ids = self.seen_ids()
            n = key[1]
            mask = self.selected.clone()
            pos = torch.arange(n)
            if ids is not None:
                seen = torch.zeros_like(mask)
                seen[ids] = True
                mask &= seen
                pos = torch.full((n,), -1, dtype=torch.long)
                pos[ids] = torch.arange(len(ids))
            active = torch.nonzero(mask).flatten()
            self._active = (key, (active, pos[active]))
        return self._active[1]

    def refit_ids(self) -> torch.Tensor | None:
        """The rows a refit works on: the seen ones (a region's unselected ones render but stay put); None: all."""
        ids = self.seen_ids()
        return torch.arange(len(self.selected)) if ids is None and self.selected is not None else ids

    # --------------------------------------------------------------------------------------------- gather/scatter
    def gather(self, values: torch.Tensor) -> torch.Tensor:
        """The active rows of ``values`` (a view of all rows when every row is active)."""
        ids = self.ids()
        return values if ids is None else values[ids]

    def gather_seen(self, values: torch.Tensor) -> torch.Tensor:
        """The seen rows of ``values``: what the colour caches take."""
        ids = self.seen_ids()
        return values if ids is None else values[ids]

    def scatter(self, target: torch.Tensor, values: torch.Tensor) -> None:
        """In place: the active rows of ``target`` become ``values``."""
        ids = self.ids()
        if ids is None:
            target.copy_(values)
        else:
            target[ids] = values

    def scatter_add(self, target: torch.Tensor, values: torch.Tensor) -> None:
        """In place: ``values`` added to the active rows of ``target``."""
        ids = self.ids()
        if ids is None:
            target += values
        else:
            target.index_add_(0, ids, values)

    def expand(self, values: torch.Tensor, fill: Any = 0) -> torch.Tensor:
        """``values`` of the active rows as a tensor over all rows (``fill`` elsewhere)."""
        ids = self.ids()
        if ids is None:
            return values
        out = torch.full((self.run.geometry_key()[1],) + tuple(values.shape[1:]), fill, dtype=values.dtype)
        out[ids] = values
        return out

    def place_in_seen(self, base: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
        """Colours for the colour caches: the seen rows of ``base`` (all rows, held: no gradient) with the active
        ones replaced by ``values`` (which keep their gradient); ``values`` itself when the active rows are the seen
        ones."""
        pos = self.positions()
        return values if pos is None else self.gather_seen(base).detach().index_put((pos,), values)

    def keep_unselected(self, new: torch.Tensor, old: torch.Tensor) -> torch.Tensor:
        """``new`` on the selected rows, ``old`` on the others (``new`` outside a region run)."""
        return new if self.selected is None else torch.where(self.selected[:, None], new, old)

    # --------------------------------------------------------------------------------------------- splits, state
    def split_extras(self) -> dict[str, torch.Tensor]:
        """Per-row tensors a split must extend (selection and input rows of a region run)."""
        return {} if self.selected is None else {"selected": self.selected, "origin": self.origin}

    def take_split_extras(self, extras: dict[str, torch.Tensor]) -> None:
        """After a split: the extended selection and input rows (``split_extras``' keys)."""
        if self.selected is not None:
            self.selected, self.origin = extras["selected"], extras["origin"]

    def state_dict(self) -> dict[str, Any]:
        """Selection and input rows (None outside a region run)."""
        return {"selected": None if self.selected is None else self.selected.clone(),
                "origin": None if self.origin is None else self.origin.clone()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore ``state_dict()``; ``ValueError`` when one side is a region run and the other is not."""
        if (state.get("selected") is None) != (self.selected is None):
            made, now = ("with", "without") if self.selected is None else ("without", "with")
            raise ValueError(f"the checkpoint was made {made} a selected region, this run is {now} one")
        if self.selected is not None:
            self.selected = torch.as_tensor(state["selected"]).to(torch.bool).clone()
            self.origin = torch.as_tensor(state["origin"]).to(torch.long).clone()
        self._seen = (None, None)
        self._active = (None, None)

