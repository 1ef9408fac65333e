"""The panel's commands that span the session's parts: a control moved (an undo step; the engine takes it from its
next step), another quality, the second painting removed, a result restarted from its original or continued from its
kept run. ``SessionCommands`` is a part of ``StudioApp``; each other part carries out its own commands (their
``commands()``), ``StudioApp.execute`` looks them up."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from gstyle_core.engine.controls import painting_controls

from .events import Handlers
from .panels import PanelState
from .status_line import StatusLine

if TYPE_CHECKING:
    from .engine_link import EngineLink
    from .paintings import Paintings
    from .region_tool import RegionTool
    from .result_undo import ResultUndo
    from .session import Session


class SessionCommands:
    """Owns no state of its own. Built with the panel, the status line, the session, the engine link, the
    paintings, the region tool, the undo (a choice is a step) and ``open_path`` (the file opening's)."""

    def __init__(self, panel: PanelState, status: StatusLine, session: Session, engine: EngineLink,
                 paintings: Paintings, region: RegionTool, undo: ResultUndo, *,
                 open_path: Callable[..., bool]) -> None:
        self.panel, self.status, self.session, self.engine = panel, status, session, engine
        self.paintings, self.region, self.undo, self.open_path = paintings, region, undo, open_path

    def apply_params(self, values: dict[str, float]) -> None:
        """Controls to the panel and the engine (from the next step; a finished run's switch back returns its
        colours)."""
        self.panel.params.update(values)
        if painting_controls() & values.keys() and self.panel.style2_path:  # a restarted engine keeps the mix
            self.paintings.update_style_config()
        self.engine.set_params(values)

    def set_params(self, values: dict[str, float]) -> None:
        """Controls moved in the panel: one undo step (a drag's changes join it)."""
        self.session.history.record({k: self.panel.params.get(k) for k in values}, values)
        self.apply_params(values)

    def restart_quality(self, preset: str) -> None:
        """Restart at another quality (an undo step of its own when no result was replaced)."""
        before, last_step = self.undo.choice_state("quality"), self.session.history.last()
        self.engine.set_quality(preset)
        self.status.say(f"restarting at the {preset} quality")
        self.engine.start()
        self.undo.choice_step("quality", before, last_step)

    def remove_second_painting(self) -> None:
        """Back to one painting; a running engine restarts with it (an undo step of its own when no result was
        replaced)."""
        before, last_step = self.paintings.painting_state(), self.session.history.last()
        self.paintings.remove_second_style()
        self.status.say("back to one painting")
        if self.engine.bridge is not None:
            self.engine.start()
        self.undo.choice_step("painting", before, last_step)

    def restart_from_original(self) -> None:
        """A result is on show: open the scene it came from and stylize it at the quality the panel shows (the
        result's when it opened, or another the artist chose since: ``EngineLink.start``) with the painting(s) and
        controls shown (the result's, ``Paintings.show_result``, or what the artist chose since); the weights a
        studio Refine's level set go back to the preset's unless the artist moved them."""
        info = self.session.result
        if info is None or info.source is None:
            self.status.say("the original scene of this result was not found")
            return
        shown = {k: v for k, v in self.panel.params.items() if k in info.params}  # the original resets the panel
        for name, (level, preset) in info.level_weights.items():  # a Refine's level set these: not the preset's
            if shown.get(name) == level:  # (the artist's own value, moved since, stays)
                shown[name] = preset
        if self.open_path(str(info.source)) and self.engine.bridge is None:
            self.engine.start()
        self.apply_params({k: v for k, v in shown.items() if k in self.panel.params})  # from the first step

    def continue_result(self) -> None:
        """A result whose run was kept (``engine/kept_runs.py``) was opened: open its original and paintings, put its
        region back, and start the engine from that run (where it ended; nothing is stylized again)."""
        info = self.session.result
        if info is None or info.state is None or info.source is None:
            self.status.say("this result's run was not kept or its original is missing: Restart from the original")
            return
        state, config = info.state, info.state_config
        if info.preset:
            self.engine.configure(preset=info.preset)
        for slot, painting in enumerate(info.styles[:2]):
            self.open_path(str(painting), style_slot=slot, record=False)
        if not self.open_path(str(info.source)):
            return
        if config.get("region"):
            self.region.enable(True)
            self.region.set_box(tuple(float(v) for v in config["region"]))
            self.region.set_feather(float(config.get("region_feather") or 0.0))
        self.engine.start(action="continue", resume_from=state)

    def commands(self) -> Handlers:
        """The panel's commands this part carries out."""
        return {"set_params": lambda args: self.set_params(args),
                "restart_quality": lambda args: self.restart_quality(str(args["preset"])),
                "remove_style2": lambda _args: self.remove_second_painting(),
                "restart_from_original": lambda _args: self.restart_from_original(),
                "continue_result": lambda _args: self.continue_result()}
