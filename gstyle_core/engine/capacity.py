"""What a run does with a capture larger than it can hold: said before the first step, kept in OUT.json.

The run can hold ``max_gaussians`` Gaussians (``--max-gaussians``, or derived from the memory available at start:
``resources.py``). ``plan_capacity`` decides before anything is built:

* **All fit** (the usual case): every Gaussian is stylized; the splits (pre-processing, colour gradient) may add
  Gaussians up to the cap and are cut back past it, each cut noted with its step (``RunState.split``).
* **More than fit**: the run holds the ``max_gaussians`` most visible Gaussians (opacity × area of their two
  largest axes, ``scene.importance_order``; the small faint ones are left out first) and stylizes them without
  splits; every other Gaussian keeps its geometry and takes the stylized colour of its nearest held Gaussian
  (``with_neighbour_colours``, by centre). The result has every input Gaussian, never fewer.

The decision is one line (``CapacityPlan.note``): the CLI prints it before the run starts, OUT.json keeps it under
``decisions.capacity``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..neighbours import nearest_rows
from ..scene import GaussianScene, importance_order


@dataclass(frozen=True)
class CapacityPlan:
    """``held``: sorted input rows the engine holds (None: all of them); ``max_gaussians``: the cap on the count
    after splits; ``note``: the decision in words; ``how``: where the cap came from."""

    held: np.ndarray | None
    max_gaussians: int
    note: str
    how: str = ""

    @property
    def reduced(self) -> bool:
        """True when some Gaussians take their colour from neighbours instead of being stylized."""
        return self.held is not None


def plan_capacity(scene: GaussianScene, max_gaussians: int, how: str) -> CapacityPlan:
    """The plan for ``scene`` under a cap of ``max_gaussians`` Gaussians (``how``: where the cap came from)."""
    n, cap = scene.count, max(1, int(max_gaussians))
    if n <= cap:
        room = cap - n
        splits = (f"splits may add up to {room:,} more and are cut back past that" if room
                  else "no room for splits: they are cut back to none")
        return CapacityPlan(None, cap, f"all {n:,} Gaussians stylized; {splits} (at most {cap:,}: {how})", how)
    held = np.sort(importance_order(scene.log_scales, scene.opacity_logits)[:cap]).astype(np.int64)
    note = (f"{n:,} Gaussians are more than the {cap:,} this run can hold ({how}): the {cap:,} most visible "
            f"(opacity x area) are stylized, without splits; the other {n - cap:,} keep their shape and take the "
            f"stylized colour of their nearest stylized neighbour; all {n:,} are in the result")
    return CapacityPlan(held, cap, note, how)


def held_part(scene: GaussianScene, selection: np.ndarray | None, settings,
              cap: tuple[int, str] | None = None) -> tuple[CapacityPlan, GaussianScene, np.ndarray | None]:
    """The plan of a run with ``settings`` on ``scene`` (its cap: ``cap``, a resumed run's own, else
    ``resources.gaussian_cap``), the part of the scene it holds and that part's rows of ``selection`` (a region's
    bool mask over the scene, or None)."""
    from .resources import gaussian_cap

    plan = plan_capacity(scene, *(cap or gaussian_cap(settings)))
    if not plan.reduced:
        return plan, scene, selection
    return plan, scene.subset(plan.held), None if selection is None else selection[plan.held]


def with_neighbour_colours(stylized: GaussianScene, full_input: GaussianScene, plan: CapacityPlan,
                           stylized_rows: np.ndarray | None = None,
                           selected: np.ndarray | None = None) -> GaussianScene:
    """The whole capture from a run that held ``plan.held``: ``stylized`` (the held Gaussians as the run left them,
    children included) followed by every input Gaussian it did not hold, each with its own geometry and the
    diffuse colour of its nearest Gaussian among ``stylized``'s ``stylized_rows`` (bool; None: all of them), no SH
    bands (a stylized colour does not change with the view). A region run (``selected``: bool over the input's
    rows) changes only the selected ones: the others are the input's rows exactly, SH bands included."""
    if not plan.reduced:
        return stylized
    rest = np.ones(full_input.count, bool)
    rest[plan.held] = False
    others = full_input.subset(rest)
    recolour = np.ones(others.count, bool) if selected is None else np.asarray(selected, bool)[rest]
    sources = np.arange(stylized.count) if stylized_rows is None else np.flatnonzero(stylized_rows)
    if recolour.any() and len(sources):
        near = sources[nearest_rows(stylized.means[sources], others.means[recolour])]
        others.sh_dc[recolour] = stylized.sh_dc[near].astype(others.sh_dc.dtype)
    degree = max(stylized.sh_degree, others.sh_degree)  # one SH layout for both parts
    stylized, others = (p if p.sh_degree == degree else p.with_sh_degree(degree) for p in (stylized, others))
    others.sh_rest[recolour] = 0.0
    return GaussianScene(
        means=np.concatenate([stylized.means, others.means]).astype(np.float32),
        log_scales=np.concatenate([stylized.log_scales, others.log_scales]).astype(np.float32),
        quats=np.concatenate([stylized.quats, others.quats]).astype(np.float32),
        opacity_logits=np.concatenate([stylized.opacity_logits, others.opacity_logits]).astype(np.float32),
        sh_dc=np.concatenate([stylized.sh_dc, others.sh_dc]).astype(np.float32),
        sh_rest=np.concatenate([stylized.sh_rest, others.sh_rest]),
    )
