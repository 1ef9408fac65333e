"""The studio's session: the scene on show with its cameras, the stylized result it is (if one), and the edit history
(undo and redo, ``app/edit_history.py``). Showing a scene tells the other parts (``SceneShown``); the panel's scene
fields, its sliders' preset values and the result's lines are the session's."""

from __future__ import annotations

from gstyle_core.cameras.camera import Camera
from gstyle_core.engine.controls import cli_control_names

from .edit_history import EditHistory
from .engine_link import EngineLink
from .events import Events, SceneShown
from .open_files import LoadedScene
from .panels import PanelState
from .result_files import ResultInfo, read_result


class Session:
    """The scene, its cameras, the result it is and the edit history; built with the panel, the events and the
    engine link (whose config says the preset and the controls the sliders start from)."""

    def __init__(self, panel: PanelState, events: Events, engine: EngineLink) -> None:
        self.panel, self.events, self.engine = panel, events, engine
        self.history = EditHistory()  # Ctrl+Z / Ctrl+Shift+Z over the parameter changes (app/edit_history.py)
        self.loaded: LoadedScene | None = None
        self.cameras: list[Camera] = []
        self.result: ResultInfo | None = None  # the scene shown is a stylized result: it opens as one

    def set_scene(self, loaded: LoadedScene) -> None:
        """Show a new scene: the parts follow (``SceneShown``: the renderers, the framing, the region, the engine's
        config); the panel's sliders go to the preset's values for it; a stylized result opens as one (its settings
        in the panel; no engine starts on it by itself)."""
        result = read_result(loaded.path)
        self.events.publish(SceneShown(loaded, result))
        self.loaded, self.cameras, self.result = loaded, list(loaded.cameras), result
        p = self.panel
        p.scene_path = loaded.path
        p.defaults = self.preset_params(with_overrides=False)
        p.params = self.preset_params(with_overrides=True)
        p.switched_off.clear()
        p.result_line = result.line if result else ""
        p.result_source = (str(result.source or result.source_named)) if result else ""
        p.result_source_found = bool(result and result.source)
        p.result_continuable = bool(result and result.source and result.state)
        if result is not None:
            p.params.update({k: v for k, v in result.params.items() if k in p.params})

    def preset_params(self, with_overrides: bool) -> dict[str, float]:
        """The preset's slider values for this scene's kind (``resolve_settings`` + ``ui_params``): what "reset"
        restores, and (``with_overrides``: with the engine config's values) the sliders before the worker reports
        its engine's."""
        from gstyle_core.cameras import classify_scene_kind
        from gstyle_core.engine.settings import resolve_settings, ui_params

        config = self.engine.config
        kind = config.get("scene_kind", "auto")
        if kind == "auto":
            kind = classify_scene_kind(self.cameras)
        preset = config.get("preset") or "preview"
        keys = (*cli_control_names(), "style_weights")  # the engine config's controls (ENGINE_OPTIONS)
        overrides = {k: config.get(k) for k in keys} if with_overrides else {}
        overrides["clip_weights"] = config.get("clip_weights")  # CLIP or not sets 360° λ_CLIP
        try:
            return ui_params(resolve_settings(preset, kind, max(1, len(self.cameras)),
                                              defaults=config.get("defaults"), **overrides))
        except ValueError:  # an unknown preset: the worker reports the error when it starts
            return dict(self.panel.params)

    def input_path(self) -> str | None:
        """The input of the scene on show: a result's original when it was found, else the scene's own file (None:
        no scene)."""
        if self.loaded is None:
            return None
        return str(self.result.source) if self.result is not None and self.result.source else self.loaded.path

    def fill_panel(self) -> None:
        """What Ctrl+Z and Ctrl+Shift+Z would put back."""
        history = self.history
        self.panel.undo_note = history.done[-1].brings_back("undo") if history.done else ""
        self.panel.redo_note = history.undone[-1].brings_back("redo") if history.undone else ""
