"""The studio's takes (issue #15, item 6): loading an exported take into its own renderer, comparing it with the
current run, forgetting it, and shelving new exports (``app/takes.py`` keeps the list). A mixin of ``StudioApp``."""

from __future__ import annotations

import json
from pathlib import Path

from gstyle_core.errors import GStyleError

from .export import summary_path
from .splat_data import scene_arrays
from .takes import settings_line


class TakesView:
    """``StudioApp``'s take methods; the state lives on the app (``takes``, ``take_view``, ``take_shown``,
    ``compare_with_take``)."""

    def show_take(self, index: int, compare: bool = True) -> bool:
        """Load take ``index`` (its exported file) into the take view; ``compare``: stylized left, the take right,
        else the take alone. False (status says why) when its file cannot be read."""
        if not 0 <= index < len(self.takes.takes):
            return False
        take = self.takes.takes[index]
        if self.take_shown != take.path:
            try:
                scene = self.takes.load(index)
            except (GStyleError, OSError) as exc:
                self.panel.status = f"take {take.name}: cannot read {Path(take.path).name}: {exc}"
                return False
            self.take_view.set_scene(scene_arrays(scene))
            self.take_shown = take.path
        self.compare_with_take = compare
        self.view_mode = "compare" if compare else "take"
        self.panel.status = f"{'comparing with' if compare else 'showing'} {take.name} ({Path(take.path).name})"
        return True

    def compare_with_original(self) -> None:
        """Compare view: stylized left, the original right (no take)."""
        self.compare_with_take = False
        self.view_mode = "compare"
        self.panel.status = "comparing with the original"

    def set_view_mode(self, mode: str) -> None:
        """A view mode from the radio buttons or C: "compare" compares with the original (T compares with the
        takes); "take" shows the take loaded, else the newest one."""
        if mode == "compare":
            self.compare_with_original()
        elif mode == "take" and self.takes.takes and self.take_shown is None:
            self.show_take(0, compare=False)
        else:
            if self.panel.status.startswith(("comparing with", "showing")):
                self.panel.status = ""  # "comparing with take N" no longer holds
            self.view_mode = mode

    def forget_take(self, index: int) -> None:
        """Take a take off the shelf (its file stays); the view leaves it if it was shown."""
        take = self.takes.forget(index)
        if take is not None and take.path == self.take_shown:
            self.take_shown, self.compare_with_take = None, False
            if self.view_mode == "take":
                self.view_mode = "stylized"

    def view_key(self) -> str:
        """What the stylized view shows now: the engine run and its geometry and colour versions ("" before any)."""
        st = self.bridge.state if self.bridge is not None else None
        snap = st.snapshot if st is not None else None
        if not snap:
            return ""
        return f"{id(st.exported)}:{snap.get('geometry_version')}:{snap.get('colour_version')}"

    def _shelve_exports(self, exported: list[str]) -> None:
        """New exports become takes (the Gaussian count from the export's JSON summary)."""
        for written in exported:
            path = Path(written)
            try:
                summary = json.loads(summary_path(path).read_text())
                gaussians, line = int(summary["gaussians"]), settings_line(summary)
            except (OSError, ValueError, KeyError, TypeError, AttributeError):
                gaussians, line = self.stylized.count, ""
            self.takes.add(path, gaussians, view_key=self.view_key(), settings=line)
