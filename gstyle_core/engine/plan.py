"""What a preset would cost on this scene and this machine: its steps per kind, priced at measured step times.

``planned_steps`` counts a preset's steps from its settings alone (as the phases plan them; pre-processing as many
rounds as the settings ask, since whether the sizes are even is known only when it starts). ``estimate_seconds``
prices them with this machine's seconds per step of each kind over the studio session (``MachineRates``, fed by the
step reports: a median that settles); ``remaining_seconds`` prices a run's steps still to come. A kind not measured
yet is priced from a measured one by the ratios in ``FALLBACK`` (measured on the demo, 2-core AMD EPYC,
docs/notes/tradeoffs-history.md), and a level's steps by its width. Torch-free: the studio prices the presets in its own
process.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from .levels import MAX_LEVEL_VIEWS

# A step of each kind against a stylization step at the working width (4 views; the demo, 2026-11-26): a ground-truth
# view 0.3, a refit iteration 0.15; a level's ground-truth view and its optimiser step grow with its width (×4 the
# pixels per doubling for the views; a crop step renders a crop the working view's size, its cache and the painting's
# features grow more slowly).
FALLBACK = {"ground_truth": 0.3, "refit": 0.15}
LEVEL_STEP_GROWTH = 0.5  # a crop step at width W costs (1 + this × (W / working − 1)) stylization steps
WHOLE_LEVEL_TAG = "(whole views)"  # in the step messages of a level in the ``whole`` mode (phases/refine.py)


def planned_steps(settings, n_views: int) -> dict[str, float]:
    """Steps of each kind a run with ``settings`` on ``n_views`` training views takes: ``ground_truth``, ``refit``
    (pre-processing's and the splits' iterations), ``stylize``, and per level ``refine_<width>`` (its optimiser
    steps; ``refine_whole_<width>`` in the ``whole`` mode, whose steps cost more) and ``refine_targets_<width>`` (its
    ground-truth views)."""
    s = settings
    views = min(n_views, s.max_views)
    views_total = max(int(round(s.epochs * views)), s.min_steps)
    stylize = max(1, math.ceil(views_total / max(1, s.views_per_step)))
    splits = len([f for f in s.split_at if 0 < round(f * stylize) < stylize]) if s.split_rate > 0 else 0
    out = {"ground_truth": float(views), "stylize": float(stylize),
           "refit": float(max(0, s.preprocess_rounds) * (1 + s.refit_iterations) + splits * (1 + s.refit_iterations))}
    for width in s.refine_widths:
        level_views = max(1, int(round(s.refine_epochs * views)))
        kind = f"refine_whole_{width}" if s.refine_mode == "whole" else f"refine_{width}"
        out[kind] = float(max(1, math.ceil(level_views / max(1, s.views_per_step))))
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


WARMUP_STEPS = 2  # a phase's first steps (the run's start with the UI's own, a split's, a level's: builds, caches)
RATE_SAMPLES = 400  # the newest step times kept of each kind (more than a preview run's steps)
MIN_SAMPLES = 5  # a kind's rate is known from this many steps past their phases' first


@dataclass
class MachineRates:
    """This machine's seconds per step of each kind over a studio session (every run of a scene on a device, restarts
    included), as the quality choice prices the presets: the median of the newest ``RATE_SAMPLES`` steps of a kind,
    each phase's first ``WARMUP_STEPS`` left out, so that neither a phase's start nor a slow or fast burst (other
    work on the machine, the UI busy) moves it much."""

    samples: dict[str, deque] = field(default_factory=dict)
    phase: tuple[str | None, int] = (None, 0)  # the kind of the steps now and how many of them in a row

    def add(self, report: dict) -> None:
        """Count one step report (as ``StepTimes.add``): a kind other than the step before's starts a phase."""
        kind = step_kind(report)
        into = self.phase[1] + 1 if kind == self.phase[0] else 1
        self.phase = (kind, into)
        if kind is not None and into > WARMUP_STEPS:
            self.samples.setdefault(kind, deque(maxlen=RATE_SAMPLES)).append(float(report.get("seconds") or 0.0))

    def new_run(self) -> None:
        """A run starts (a restart): its first steps are a phase's first whatever kind they are."""
        self.phase = (None, 0)

    def median(self, kind: str, least: int = MIN_SAMPLES) -> float | None:
        """The seconds of a step of ``kind`` (None: fewer than ``least`` measured past their phases' start)."""
        values = self.samples.get(kind)
        return statistics.median(values) if values is not None and len(values) >= max(1, least) else None


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
        width, message = int(report.get("width") or 0), str(report.get("message", ""))
        if "ground truth" in message:
            return f"refine_targets_{width}"
        return f"refine_whole_{width}" if WHOLE_LEVEL_TAG in message else f"refine_{width}"
    return None


def estimate_seconds(plan: dict[str, float], rates: MachineRates, working_width: int) -> float | None:
    """Seconds ``plan`` takes at the session's step rates (``MachineRates``); None until a stylization step's rate is
    known (every other kind falls back on it)."""
    return _priced(plan, {}, rates.median, working_width)


def remaining_seconds(plan: dict[str, float], times: StepTimes, working_width: int,
                      rates: MachineRates | None = None) -> float | None:
    """Seconds left of a run planned as ``plan`` whose steps so far are ``times`` (counted per kind): each kind's
    steps still to come at the session's rate of its kind (``rates``: the runs before a restart's included), else at
    this run's mean so far, else priced from the stylization step (``fallback_cost``). None while no stylization
    step's cost is known (early in a first run: the ground-truth and refit steps are 10-20x cheaper and would promise
    far too little) nor guessed from theirs (``guessed_stylize``). A rate counts from its first step past a phase's
    start (a phase's first steps, slower, would swing the figure)."""
    def cost(kind: str) -> float | None:
        known = rates.median(kind, least=1) if rates is not None else None
        return known if known is not None else times.mean(kind)

    return _priced(plan, times.counts, cost, working_width, guess=True)


def guessed_stylize(cost: Callable[[str], float | None]) -> float | None:
    """A stylization step's cost from the cheaper kinds measured (``FALLBACK``'s ratios; their median), else None."""
    guesses = [known / ratio for kind, ratio in FALLBACK.items() if (known := cost(kind))]
    return statistics.median(guesses) if guesses else None


def _priced(plan: dict[str, float], done: dict[str, int], cost: Callable[[str], float | None],
            working_width: int, guess: bool = False) -> float | None:
    """Seconds of ``plan``'s steps beyond ``done`` (per kind), each at ``cost`` of its kind, else ``fallback_cost``;
    None without a stylization step's cost (``guess``: or one ``guessed_stylize``)."""
    stylize = cost("stylize")
    if stylize is None and guess:
        stylize = guessed_stylize(cost)
    if stylize is None:
        return None
    total = 0.0
    for kind, steps in plan.items():
        left = max(0.0, steps - done.get(kind, 0))
        known = stylize if kind == "stylize" else cost(kind)
        total += left * (known if known is not None else fallback_cost(kind, stylize, working_width, cost))
    return total


def fallback_cost(kind: str, stylize: float, working_width: int, cost: Callable[[str], float | None]) -> float:
    """A step of ``kind`` not measured, priced from the stylization step (``FALLBACK``; a level's ground-truth view
    from the measured ground-truth view's ``cost`` when there is one)."""
    if kind in FALLBACK:
        return FALLBACK[kind] * stylize
    width = int(kind.rsplit("_", 1)[1])
    scale = width / max(1, working_width)
    if kind.startswith("refine_targets_"):
        gt = cost("ground_truth") or FALLBACK["ground_truth"] * stylize
        return gt * scale * scale
    if kind.startswith("refine_whole_"):  # every other step a whole view at the level's width, scale² the pixels
        return stylize * (1.0 + scale * scale) / 2.0
    return stylize * (1.0 + LEVEL_STEP_GROWTH * (scale - 1.0))
