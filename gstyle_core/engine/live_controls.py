"""What the engine does when live controls change (``controls.Effect``, from ``Stylizer.set_params`` and a resumed
run's kept controls): new weights reach every objective, new content targets after the colour match, the painting's
features extracted again, keep colours switched on or off (``switch_chroma``: turned off before any step changed
the colours since, the colours from before it come back bit for bit), and a finished run's palette match blended
again (``reapply_palette_match``)."""

from __future__ import annotations

from typing import Any

import torch

from .controls import Effect
from .notes import note_loss_terms, note_networks, note_planned_clip, note_style
from .phases.colour_match import ColourMatch, match_content_targets


class LiveControls:
    """The live controls' effects on one engine (a ``Stylizer``)."""

    def __init__(self, engine: Any) -> None:
        self.engine = engine
        # keep colours turned on: c_s before it took the scene's chroma, and the colour version right after
        self.before_keep_colours: tuple[torch.Tensor, int] | None = None

    def carry_out(self, effects: Effect) -> None:
        """What the engine does now for controls that changed (``controls.Effect``)."""
        s, run = self.engine.settings, self.engine.run_state
        if effects & Effect.REWEIGHT:
            for objective in run.level_objectives.values():
                objective.set_weights(s.weights)
            if run.objective is not None:
                run.objective.set_weights(s.weights)
                note_networks(run.decisions, run.objective)
            else:
                note_planned_clip(run.decisions, s)
            note_loss_terms(run.decisions, s, run.objective)
        if effects & Effect.CONTENT_TARGETS and run.content_images:  # past the colour match: new content targets
            match_content_targets(run)
            if effects & Effect.RESTORE_CHROMA:
                self.switch_chroma(s.keep_colours)
        for objective in run.objectives():
            if effects & Effect.CONTENT_TARGETS and hasattr(objective, "clear_content_cache"):
                objective.clear_content_cache()
            if effects & Effect.STYLE_FEATURES and hasattr(objective, "refresh_style"):  # test objectives: none
                objective.refresh_style()  # the painting's features for the settings as they are now
        if effects & Effect.STYLE_FEATURES:
            note_style(run.decisions, s, run.objective, len(run.styles))
        if effects & (Effect.PALETTE_MATCH | Effect.RESTORE_CHROMA):  # (keep colours switched back: the finished
            self.reapply_palette_match()  # colours returned, at the strength set meanwhile)

    def reapply_palette_match(self) -> None:
        """A finished final colour match takes ``settings.palette_match`` at once (``ColourMatch.reapply``: its kept
        colours blended again, nothing fitted); before it has run, it reads the strength when it does."""
        engine = self.engine
        for phase in engine.phases:
            if isinstance(phase, ColourMatch) and phase.reapply(engine.settings.palette_match):
                engine.run_state.colour_version += 1

    def switch_chroma(self, keep: bool) -> None:
        """Keep colours turned on: c_s takes c_gt's chroma, the colours before it kept. Turned off before any step
        changed the colours since: those colours come back bit for bit (after steps, the painting's colours return
        from the next step and the final colour match)."""
        engine = self.engine
        run = engine.run_state
        steps = getattr(engine.current_phase(), "colour_steps", None) or engine.stylize.colour_steps
        before, self.before_keep_colours = self.before_keep_colours, None
        if keep:
            kept = run.c_s.detach().clone()
            steps.restore_chroma()
            run.colour_version += 1
            self.before_keep_colours = (kept, run.colour_version)
        elif before is not None and before[1] == run.colour_version and before[0].shape == run.c_s.shape:
            steps.put_back(before[0])
            run.colour_version += 1
