"""What a preset would cost on this scene and this machine: its steps per kind, priced at this run's step times.

``planned_steps`` counts a preset's steps from its settings alone (as the phases plan them; pre-processing as many
rounds as the settings ask, since whether the sizes are even is known only when it starts). ``estimate_seconds``
prices them with seconds per step of each kind measured in the running engine (``StepTimes``, fed by the step
reports); a kind not measured yet is priced from a measured one by the ratios in ``FALLBACK`` (measured on the demo,
2-core AMD EPYC, docs/tradeoffs.md), and a level's steps by its width. Torch-free: the studio prices the presets in
its own process.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .levels import MAX_LEVEL_VIEWS

# A step of each kind against a stylization step at the working width (4 views; the demo, 2026-11-26): a ground-truth
# view 0.3, a refit iteration 0.15; a level's ground-truth view and its optimiser step grow with its width (×4 the
# pixels per doubling for the views; a crop step renders a crop the working view's size, its cache and the painting's
# features grow more slowly).
FALLBACK = {"ground_truth": 0.3, "refit": 0.15}
LEVEL_STEP_GROWTH = 0.5  # a crop step at width W costs (1 + this × (W / working − 1)) stylization steps


def planned_steps(settings, n_views: int) -> dict[str, float]:
    """Steps of each kind a run with ``settings`` on ``n_views`` training views takes: ``ground_truth``, ``refit``
    (pre-processing's and the splits' iterations), ``stylize``, and per level ``refine_<width>`` (its optimiser
    steps) and ``refine_targets_<width>`` (its ground-truth views)."""
    s = settings
    views = min(n_views, s.max_views)
    views_total = max(int(round(s.epochs * views)), s.min_steps)
    stylize = max(1, math.ceil(views_total / max(1, s.views_per_step)))
    splits = len([f for f in s.split_at if 0 < round(f * stylize) < stylize]) if s.split_rate > 0 else 0
    out = {"ground_truth": float(views), "stylize": float(stylize),
           "refit": float(max(0, s.preprocess_rounds) * (1 + s.refit_iterations) + splits * (1 + s.refit_iterations))}
    for width in s.refine_widths:
        level_views = max(1, int(round(s.refine_epochs * views)))
        out[f"refine_{width}"] = float(max(1, math.ceil(level_views / max(1, s.views_per_step))))
        out[f"refine_targets_{width}"] = float(min(views, MAX_LEVEL_VIEWS))
    return out


@dataclass
class StepTimes:
    """Seconds per step of each kind, measured from step reports (``add``)."""

    seconds: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)

    def add(self, report: dict) -> None:
        """Count one step report (its ``phase``, ``seconds``, ``width`` and ``message``)."""
        kind = step_kind(report)
        if kind is None:
            return
        self.seconds[kind] = self.seconds.get(kind, 0.0) + float(report.get("seconds") or 0.0)
        self.counts[kind] = self.counts.get(kind, 0) + 1

    def mean(self, kind: str) -> float | None:
        """The mean seconds of a step of ``kind`` (None: none measured)."""
        return self.seconds[kind] / self.counts[kind] if self.counts.get(kind) else None


STYLIZED_PHASES = ("stylize", "refit", "refine", "finish", "done")  # the phases whose colours are stylized ones


def step_kind(report: dict) -> str | None:
    """The kind of a step report, as ``planned_steps`` counts: ground truth, refit (pre-processing included),
    stylize, a level's targets or steps; None for the colour matches (one step each, priced as nothing)."""
    phase = report.get("phase")
    if phase in ("ground_truth", "stylize"):
        return phase
    if phase in ("preprocess", "refit"):
        return "refit"
    if phase == "refine":
        width = int(report.get("width") or 0)
        return f"refine_targets_{width}" if "ground truth" in str(report.get("message", "")) else f"refine_{width}"
    return None


def estimate_seconds(plan: dict[str, float], times: StepTimes, working_width: int) -> float | None:
    """Seconds ``plan`` takes at ``times``' step costs; None until a stylization step has been measured (every other
    kind falls back on it)."""
    return _priced(plan, {}, times, working_width, None)


def remaining_seconds(plan: dict[str, float], times: StepTimes, working_width: int,
                      prior: StepTimes | None = None) -> float | None:
    """Seconds left of a run planned as ``plan`` whose steps so far are ``times`` (counted per kind): each kind's
    steps still to come at its measured cost, else at ``prior``'s (the run before, on a restart), else priced from
    the stylization step (``fallback_cost``). None while no stylization step is known from either (early in a
    first run: the ground-truth and refit steps are 10-20x cheaper and would promise far too little)."""
    return _priced(plan, times.counts, times, working_width, prior)


def _priced(plan: dict[str, float], done: dict[str, int], times: StepTimes, working_width: int,
            prior: StepTimes | None) -> float | None:
    """Seconds of ``plan``'s steps beyond ``done`` (per kind), each at ``times``' cost of its kind, else
    ``prior``'s, else ``fallback_cost``; None without a stylization step's cost from either."""
    stylize = times.mean("stylize") or (prior.mean("stylize") if prior is not None else None)
    if stylize is None:
        return None
    total = 0.0
    for kind, steps in plan.items():
        left = max(0.0, steps - done.get(kind, 0))
        cost = times.mean(kind) or (prior.mean(kind) if prior is not None else None)
        total += left * (cost if cost is not None else fallback_cost(kind, stylize, working_width, times))
    return total


def fallback_cost(kind: str, stylize: float, working_width: int, times: StepTimes) -> float:
    """A step of ``kind`` not measured in this run, priced from the stylization step (``FALLBACK``)."""
    if kind in FALLBACK:
        return FALLBACK[kind] * stylize
    width = int(kind.rsplit("_", 1)[1])
    scale = width / max(1, working_width)
    if kind.startswith("refine_targets_"):
        gt = times.mean("ground_truth") or FALLBACK["ground_truth"] * stylize
        return gt * scale * scale
    return stylize * (1.0 + LEVEL_STEP_GROWTH * (scale - 1.0))
