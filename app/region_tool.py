"""The studio's selected-region tool (issue #15, item 4): a box placed in the view or a screen rectangle, the
selection it makes over the input scene's Gaussians, its outline in the view and its hand-over to the engine's config.
``RegionTool`` is a part of ``StudioApp``."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .camera_control import CameraControl
from .edit_history import EditHistory
from .events import Events, Handlers, SceneShown
from .open_files import LoadedScene
from .panels import PanelState
from .renderer import SplatRenderer
from .status_line import StatusLine
from .studio_framing import framebuffer_scale


class RegionTool:
    """The selection tool's state (issue #15 item 4): a box in scene coordinates or a screen rectangle's mask of the
    input's Gaussians; highlighted in the renderers; handed to the engine when it (re)starts. Built with the panel,
    the status line, the camera control, the edit history (each change is an undo step), ``loaded`` (the scene on
    show: the session's), the renderers it highlights in (name, renderer) and the events (a new scene resets it)."""

    def __init__(self, panel: PanelState, status: StatusLine, control: CameraControl, history: EditHistory,
                 loaded: Callable[[], LoadedScene | None], renderers: Sequence[tuple[str, SplatRenderer]],
                 events: Events) -> None:
        self.panel, self.status, self.control, self.history = panel, status, control, history
        self.loaded, self.renderers = loaded, renderers
        self.enabled = False
        self.box: tuple[float, ...] | None = None
        self.rect_mask: np.ndarray | None = None  # the last rectangle's selection (mode "rectangle")
        self.feather = 0.0  # the box's soft edge in scene units (the engine's region_feather)
        self.engine_region: str = ""  # what the engine was last started with ("": the whole scene)
        self._version = 0
        self._box_mask_cache: tuple[tuple, np.ndarray] | None = None  # (scene and box, its selection)
        self._selection_shown: dict[str, Any] = {}
        self._rect_start: tuple[float, float] | None = None
        self._before_drag: tuple | None = None  # the selection when a Shift+drag started (its undo step)
        events.subscribe(SceneShown, self._scene_shown)

    def _scene_shown(self, _event: SceneShown) -> None:
        """Another scene: no selection."""
        self.box, self.rect_mask, self.enabled = None, None, False
        self._version += 1

    def scene_box(self) -> tuple[float, ...]:
        """The input scene's bounds as a box (x0,y0,z0,x1,y1,z1)."""
        loaded = self.loaded()
        if loaded is None or loaded.scene.count == 0:
            return (0.0,) * 6
        m = np.asarray(loaded.scene.means, np.float64)
        return tuple(float(v) for v in (*m.min(0), *m.max(0)))

    def state(self) -> tuple:
        """What the selection is: (tool on, box, rectangle mask) — what undo and redo restore."""
        return self.enabled, self.box, self.rect_mask

    def restore(self, state: tuple) -> None:
        """Put back a ``state()`` (undo, redo)."""
        self.enabled, self.box, self.rect_mask = state
        self._version += 1

    def enable(self, on: bool) -> None:
        """The region tool on or off (an undo step)."""
        before = self.state()
        self.enabled = bool(on)
        self._version += 1
        self.history.record_region(before, self.state())

    def set_feather(self, value: float) -> None:
        """The box's soft edge in scene units (0: hard)."""
        self.feather = max(0.0, float(value))

    def set_box(self, box: Sequence[float]) -> None:
        """Select the Gaussians centred in ``box`` (turns the tool on; the rectangle's selection is dropped; an undo
        step, one for a whole drag)."""
        from gstyle_core.engine.region import check_region

        before = self.state()
        self.box = check_region(box)
        self.rect_mask = None
        self.enabled = True
        self._version += 1
        self.history.record_region(before, self.state())

    def box_tool_on(self) -> bool:
        """The tool is on with a box (Alt + drag moves it, Alt + wheel resizes it)."""
        return self.enabled and self.rect_mask is None and self.box is not None

    def move_box(self, dx: float, dy: float, width: int, height: int) -> None:
        """Move the region box by (dx, dy) framebuffer pixels in the view: parallel to the image plane at the depth of
        its centre, so the centre follows the mouse."""
        cam = self.control.camera(width, height)
        box = np.asarray(self.box, np.float64)
        centre = (box[:3] + box[3:]) / 2
        w2c = np.asarray(cam.world_to_cam, np.float64)
        depth = float((w2c[:3, :3] @ centre + w2c[:3, 3])[2])
        if depth <= 1e-6:  # behind the camera: nothing sensible to follow
            return
        c2w = np.linalg.inv(w2c)
        shift = c2w[:3, 0] * (dx * depth / cam.fx) + c2w[:3, 1] * (dy * depth / cam.fy)
        self.set_box(tuple(np.concatenate([box[:3] + shift, box[3:] + shift])))

    def scale_box(self, factor: float) -> None:
        """Resize the region box about its centre by ``factor`` along every axis."""
        box = np.asarray(self.box, np.float64)
        centre, half = (box[:3] + box[3:]) / 2, (box[3:] - box[:3]) / 2 * float(factor)
        self.set_box(tuple(np.concatenate([centre - half, centre + half])))

    # ----------------------------------------------------------------- the rectangle (Shift + drag in the view)
    def start_rectangle(self, at: tuple[float, float]) -> None:
        """A Shift + drag starts at ``at`` (framebuffer pixels in the view): the tool is on, the undo step starts."""
        self._rect_start = at
        self._before_drag = self.state()  # the undo step starts here
        self.enabled = True

    def drag_rectangle(self, mouse: tuple[float, float], scale: tuple[float, float]) -> None:
        """The rectangle being dragged to ``mouse`` (window pixels in the view; ``scale``: framebuffer pixels per
        window pixel), drawn by the panel."""
        if self._rect_start is not None:
            self.panel.region_drag = (self._rect_start[0] / scale[0], self._rect_start[1] / scale[1], *mouse)

    def end_rectangle(self, at: tuple[float, float], width: int, height: int) -> None:
        """The drag ends at ``at``: select what the rectangle holds (a rectangle of at least 2 pixels each way)."""
        start, self._rect_start = self._rect_start, None
        self.panel.region_drag = None
        if start is not None and abs(at[0] - start[0]) >= 2 and abs(at[1] - start[1]) >= 2:
            self.select_rectangle((*start, *at), width, height, before=self._before_drag)

    def select_rectangle(self, rect: Sequence[float], width: int, height: int, before: tuple | None = None) -> int:
        """Select the Gaussians whose centres project into the screen rectangle (x0, y0, x1, y1 in framebuffer
        pixels, y down) of the current view of ``width`` x ``height``; returns how many. ``before``: the selection
        as the drag found it (the undo step goes back there)."""
        from gstyle_core.engine.region import rect_mask

        loaded = self.loaded()
        if loaded is None:
            return 0
        mask = rect_mask(loaded.scene.means, self.control.camera(width, height), rect)
        if not mask.any():
            self.status.say("rectangle selection: no Gaussian centre in it (the selection is unchanged)")
            return 0
        before = before if before is not None else self.state()
        self.rect_mask = mask
        self.enabled = True
        self._version += 1
        self.history.record_region(before, self.state())
        self.status.say(f"rectangle selection: {int(mask.sum()):,} Gaussians")
        return int(mask.sum())

    def mask(self) -> np.ndarray | None:
        """The selection over the input scene's Gaussians (None: the tool is off)."""
        loaded = self.loaded()
        if not self.enabled or loaded is None:
            return None
        if self.rect_mask is not None:
            return self.rect_mask
        from gstyle_core.engine.region import box_mask

        if self.box is None:
            self.box = self.scene_box()
        key = (id(loaded), tuple(self.box))  # the panel and the highlight ask every frame: ~7 ms a call
        if self._box_mask_cache is None or self._box_mask_cache[0] != key:  # on 200k Gaussians
            self._box_mask_cache = (key, box_mask(loaded.scene.means, self.box))
        return self._box_mask_cache[1]

    def engine_entries(self) -> dict[str, Any]:
        """The selection for the engine's config (a box as ``region``, a rectangle as a ``selection`` mask; none
        while the tool is off), and what it is in words (``engine_region``) from now on."""
        mask = self.mask()
        entries: dict[str, Any] = {}
        if mask is None:
            self.engine_region = ""
        elif self.rect_mask is not None:
            entries["selection"] = mask.copy()
            self.engine_region = f"a rectangle selection ({int(mask.sum()):,} Gaussians)"
        else:
            entries["region"] = tuple(self.box)
            self.engine_region = "box " + ",".join(f"{v:.3g}" for v in self.box)
            if self.feather > 0:
                entries["region_feather"] = float(self.feather)
                self.engine_region += f", feathered over {self.feather:.3g}"
        return entries

    def apply_selection(self) -> None:
        """While the region tool is on, the Gaussians outside the selection are drawn dimmed in every view (the
        selected ones as they are, so the style arriving there stays visible; the outline, ``_selection_outline``,
        marks its edge); off, all as they are. Uploaded only when the selection changed."""
        mask = self.mask() if self.enabled else None
        for name, renderer in self.renderers:
            key = None if mask is None else (self._version, id(mask), renderer.count)
            if self._selection_shown.get(name, "never") == key:
                continue
            self._selection_shown[name] = key
            renderer.set_selection(mask if mask is not None and mask.shape == (renderer.count,) else None)

    def _selection_outline(self, width: int, height: int) -> list[tuple[float, float, float, float]]:
        """The footprint of the selected Gaussians' centres in the view (``app/selection_outline.py``), window
        pixels relative to the view; recomputed only when the camera, the view size or the selection changed."""
        from .selection_outline import selection_outline

        mask, loaded = self.mask(), self.loaded()
        if mask is None or loaded is None or not mask.any():
            return []
        sx, sy = framebuffer_scale()
        key = (self._version, id(mask), self.control.version, width, height, sx, sy)
        cached = self._selection_shown.get("outline")
        if cached is None or cached[0] != key:
            cam = self.control.camera(width, height)
            cached = (key, selection_outline(np.asarray(loaded.scene.means)[mask], cam, (sx, sy)))
            self._selection_shown["outline"] = cached
        return cached[1]

    def _box_outline(self, width: int, height: int) -> list[tuple[float, float, float, float]]:
        """The region box's 12 edges projected into the view (window pixels), edges behind the camera left out."""
        if not self.enabled or self.box is None or self.rect_mask is not None:
            return []
        cam = self.control.camera(width, height)
        b = self.box
        corners = np.array([[b[3 * (i & 1)], b[1 + 3 * ((i >> 1) & 1)], b[2 + 3 * ((i >> 2) & 1)]] for i in range(8)])
        pc = corners @ np.asarray(cam.world_to_cam)[:3, :3].T + np.asarray(cam.world_to_cam)[:3, 3]
        sx, sy = framebuffer_scale()
        edges = []
        for i in range(8):
            for bit in (1, 2, 4):
                j = i | bit
                if j == i or min(pc[i, 2], pc[j, 2]) <= 1e-3:
                    continue
                (u0, v0), (u1, v1) = ((cam.fx * pc[k, 0] / pc[k, 2] + cam.cx, cam.fy * pc[k, 1] / pc[k, 2] + cam.cy)
                                      for k in (i, j))
                edges.append((u0 / sx, v0 / sy, u1 / sx, v1 / sy))
        return edges

    # ----------------------------------------------------------------- the panel
    def fill_panel(self, view_size: tuple[int, int], engine_running: bool) -> None:
        """The region section and the overlays of the view (``view_size``): the tool, its box or rectangle, the
        selection's size, what a running engine (``engine_running``) was started with, the outlines."""
        p = self.panel
        p.region_enabled = self.enabled
        mask = self.mask()
        p.region_mode = "rectangle" if self.rect_mask is not None else "box"
        if self.box is not None:
            p.region_box = tuple(self.box)
        p.region_feather = float(self.feather)
        p.region_selected = int(mask.sum()) if mask is not None else 0
        loaded = self.loaded()
        p.region_total = loaded.scene.count if loaded is not None else 0
        p.region_in_engine = self.engine_region if engine_running else ""
        width, height = view_size
        p.region_outline = self._box_outline(width, height)
        p.selection_outline = self._selection_outline(width, height)

    def commands(self) -> Handlers:
        """The panel's commands this part carries out: the tool on or off, its box, its feather, fit the scene."""
        return {"region_enable": lambda args: self.enable(bool(args.get("on", True))),
                "region_box": lambda args: self.set_box(args["box"]),
                "region_feather": lambda args: self.set_feather(args["value"]),
                "region_fit": lambda _args: self.set_box(self.scene_box())}
