"""ImGui control panel: reads a ``PanelState``, returns a list of ``Command``s. No GL or rendering code here.

``draw.py`` lays the window out from its sections (``run_sections``, ``view``, ``sliders``, ``region``, ``output``),
which share ``widgets``, and the studio's file browser window (``file_browser``); ``params.py`` is the table of engine
parameters the sliders show."""

from .draw import PANEL_WIDTH, draw_panel, shortcut_commands
from .params import Param, param_rows
from .run_sections import decision_lines, format_eta, loss_series
from .state import Command, PanelState

__all__ = ["PANEL_WIDTH", "Command", "PanelState", "Param", "param_rows", "decision_lines", "draw_panel", "format_eta",
           "loss_series", "shortcut_commands"]
