"""Pre-processing: rounds of flat-Gaussian splits, each followed by a refit with elongation clamps.

Skipped when the active Gaussians' sizes are already even (unless ``force_preprocess``) or when the settings ask
for 0 rounds (``engine/flat_split.py`` has the criteria). A round is one split step, then the refit's steps.
"""

from __future__ import annotations

from typing import Any

from ..flat_split import (
    evenness_verdict,
    flat_split_mask,
    gaussian_areas,
    projected_size_px,
    shown_split_mask,
    size_evenness,
)
from ..levels import end_width
from .base import Phase, StepReport
from .refit import Refit


class Preprocess(Phase):
    """``rounds`` rounds of split + refit, decided when the run reaches the phase."""

    name = "preprocess"

    def __init__(self, run) -> None:
        super().__init__(run)
        self.rounds = 0  # decided by ``start``
        self.round = 0
        self.too_small = 0  # flat Gaussians not split because their children could not show
        self.refit: Refit | None = None

    def start(self) -> None:
        super().start()
        run, s = self.run, self.run.settings
        # the sizes of the Gaussians the cameras see (and that are selected)
        crit = size_evenness(run.active.gather(run.params["log_scales"]), s.preprocess_gamma)
        run.decisions["size_evenness"] = {k: round(v, 4) for k, v in crit.items()}
        even, figures = evenness_verdict(crit)
        rounds = s.preprocess_rounds
        if rounds <= 0:
            run.decisions["preprocess"] = f"off (0 rounds in the settings); {figures}"
        elif even and not s.force_preprocess:
            run.decisions["preprocess"] = f"skipped: Gaussian sizes already even ({figures})"
            rounds = 0
        else:
            why = "forced although the sizes are even" if even else "sizes uneven"
            run.decisions["preprocess"] = f"{rounds} round(s), {why} ({figures})"
        run.decisions["preprocess_rounds"] = rounds
        self.rounds = max(0, rounds)

    @property
    def finished(self) -> bool:
        return self.started and self.round >= self.rounds

    def remaining_steps(self) -> int:
        per_round = 1 + self.run.settings.refit_iterations
        rounds = self.rounds if self.started else max(0, self.run.settings.preprocess_rounds)  # planned until then
        left = max(0, rounds - self.round) * per_round
        if self.refit is not None:  # the split and part of the refit are done
            left -= per_round - self.refit.remaining_steps()
        return left

    def step(self) -> StepReport:
        if self.refit is None:
            rep = self._split()
        else:
            rep = self.refit.step()
        if self.refit.finished:
            self.refit = None
            self.round += 1
        return rep

    def _split(self) -> StepReport:
        """Split the flat Gaussians among the active ones (unseen and unselected ones never split); start the
        round's refit."""
        run, s = self.run, self.run.settings
        gamma = s.preprocess_gamma * s.preprocess_gamma_growth**self.round
        log_scales = run.params["log_scales"]
        mask = run.active.expand(flat_split_mask(run.active.gather(log_scales), gamma, s.preprocess_cap), fill=False)
        flat = int(mask.sum())
        final_cams = [c.resized_to_width(end_width(s)) for c in run.cameras]
        mask = shown_split_mask(mask, projected_size_px(run.params["means"], log_scales, final_cams),
                                s.preprocess_scale_divisor, s.preprocess_min_child_px)
        aggregates = run.aggregate_rows()  # merged parents: their children are the finer detail, not samples
        if aggregates is not None:
            mask = mask & ~aggregates
        n = run.split(mask, s.preprocess_children, s.preprocess_scale_divisor,
                      priority=gaussian_areas(run.params["log_scales"]))
        self.too_small += flat - int(mask.sum())
        run.decisions["preprocess_unsplit"] = (
            f"{self.too_small:,} flat Gaussian(s) left whole: their children would be below "
            f"{s.preprocess_min_child_px:g} px "
            f"at {final_cams[0].width} px, the width the run ends at")
        self.refit = Refit.preprocessing(run)
        self.refit.start()
        return self.report(geometry_changed=True,
                           message=f"pre-processing round {self.round + 1}: split {n} flat Gaussians (γ={gamma:.3f})")

    def state_dict(self) -> dict[str, Any]:
        return {**super().state_dict(), "rounds": self.rounds, "round": self.round, "too_small": self.too_small,
                "refit": None if self.refit is None else self.refit.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        super().load_state_dict(state)
        self.rounds, self.round = int(state["rounds"]), int(state["round"])
        self.too_small = int(state.get("too_small", 0))
        self.refit = None
        if state["refit"] is not None:  # built as a fresh round's refit is, then its saved state
            self.refit = Refit.preprocessing(self.run)
            self.refit.load_state_dict(state["refit"])
