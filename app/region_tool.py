"""The studio's selected-region tool (issue #15, item 4): a box placed in the view or a screen rectangle, the
selection it makes over the input scene's Gaussians, its outline in the view and its hand-over to the engine's config.
A mixin of ``StudioApp`` (it uses the app's scene, camera control, renderers, panel and engine config)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .studio_framing import framebuffer_scale


class RegionTool:
    """``StudioApp``'s region methods; the state lives on the app (``region_enabled``, ``region_box``,
    ``region_rect_mask``, ``engine_region``, ``_region_version``, ``_selection_shown``, ``_box_mask_cache``)."""

    def init_region_state(self) -> None:
        """The selection tool's state (issue #15 item 4): a box in scene coordinates or a screen rectangle's mask of
        the input's Gaussians; highlighted in both renderers; handed to the engine when it (re)starts."""
        self.region_enabled = False
        self.region_box: tuple[float, ...] | None = None
        self.region_rect_mask: np.ndarray | None = None  # the last rectangle's selection (mode "rectangle")
        self.region_feather = 0.0  # the box's soft edge in scene units (the engine's region_feather)
        self._region_version = 0
        self._box_mask_cache: tuple[tuple, np.ndarray] | None = None  # (scene and box, its selection)
        self._selection_shown: dict[str, Any] = {}
        self._rect_start: tuple[float, float] | None = None
        self._region_before_drag: tuple | None = None  # the selection when a Shift+drag started (its undo step)
        self.engine_region: str = ""

    def scene_box(self) -> tuple[float, ...]:
        """The input scene's bounds as a box (x0,y0,z0,x1,y1,z1)."""
        if self.loaded is None or self.loaded.scene.count == 0:
            return (0.0,) * 6
        m = np.asarray(self.loaded.scene.means, np.float64)
        return tuple(float(v) for v in (*m.min(0), *m.max(0)))

    def region_state(self) -> tuple:
        """What the selection is: (tool on, box, rectangle mask) — what undo and redo restore."""
        return self.region_enabled, self.region_box, self.region_rect_mask

    def restore_region(self, state: tuple) -> None:
        """Put back a ``region_state()`` (undo, redo)."""
        self.region_enabled, self.region_box, self.region_rect_mask = state
        self._region_version += 1

    def enable_region(self, on: bool) -> None:
        """The region tool on or off (an undo step)."""
        before = self.region_state()
        self.region_enabled = bool(on)
        self._region_version += 1
        self.history.record_region(before, self.region_state())

    def set_region_box(self, box) -> None:
        """Select the Gaussians centred in ``box`` (turns the tool on; the rectangle's selection is dropped; an undo
        step, one for a whole drag)."""
        from gstyle_core.engine.region import check_region

        before = self.region_state()
        self.region_box = check_region(box)
        self.region_rect_mask = None
        self.region_enabled = True
        self._region_version += 1
        self.history.record_region(before, self.region_state())

    def _box_tool_on(self) -> bool:
        return self.region_enabled and self.region_rect_mask is None and self.region_box is not None

    def move_region_box(self, dx: float, dy: float, width: int, height: int) -> None:
        """Move the region box by (dx, dy) framebuffer pixels in the view: parallel to the image plane at the depth of
        its centre, so the centre follows the mouse."""
        cam = self.control.camera(width, height)
        box = np.asarray(self.region_box, np.float64)
        centre = (box[:3] + box[3:]) / 2
        w2c = np.asarray(cam.world_to_cam, np.float64)
        depth = float((w2c[:3, :3] @ centre + w2c[:3, 3])[2])
        if depth <= 1e-6:  # behind the camera: nothing sensible to follow
            return
        c2w = np.linalg.inv(w2c)
        shift = c2w[:3, 0] * (dx * depth / cam.fx) + c2w[:3, 1] * (dy * depth / cam.fy)
        self.set_region_box(tuple(np.concatenate([box[:3] + shift, box[3:] + shift])))

    def scale_region_box(self, factor: float) -> None:
        """Resize the region box about its centre by ``factor`` along every axis."""
        box = np.asarray(self.region_box, np.float64)
        centre, half = (box[:3] + box[3:]) / 2, (box[3:] - box[:3]) / 2 * float(factor)
        self.set_region_box(tuple(np.concatenate([centre - half, centre + half])))

    def select_rectangle(self, rect, width: int, height: int, before: tuple | None = None) -> int:
        """Select the Gaussians whose centres project into the screen rectangle (x0, y0, x1, y1 in framebuffer
        pixels, y down) of the current view of ``width`` x ``height``; returns how many. ``before``: the selection
        as the drag found it (the undo step goes back there)."""
        from gstyle_core.engine.region import rect_mask

        if self.loaded is None:
            return 0
        mask = rect_mask(self.loaded.scene.means, self.control.camera(width, height), rect)
        if not mask.any():
            self.panel.status = "rectangle selection: no Gaussian centre in it (the selection is unchanged)"
            return 0
        before = before if before is not None else self.region_state()
        self.region_rect_mask = mask
        self.region_enabled = True
        self._region_version += 1
        self.history.record_region(before, self.region_state())
        self.panel.status = f"rectangle selection: {int(mask.sum()):,} Gaussians"
        return int(mask.sum())

    def region_mask(self) -> np.ndarray | None:
        """The selection over the input scene's Gaussians (None: the tool is off)."""
        if not self.region_enabled or self.loaded is None:
            return None
        if self.region_rect_mask is not None:
            return self.region_rect_mask
        from gstyle_core.engine.region import box_mask

        if self.region_box is None:
            self.region_box = self.scene_box()
        key = (id(self.loaded), tuple(self.region_box))  # the panel and the highlight ask every frame: ~7 ms a call
        if self._box_mask_cache is None or self._box_mask_cache[0] != key:  # on 200k Gaussians
            self._box_mask_cache = (key, box_mask(self.loaded.scene.means, self.region_box))
        return self._box_mask_cache[1]

    def _region_to_config(self) -> None:
        """Hand the selection to the engine's config (a box as ``region``, a rectangle as a ``selection`` mask)."""
        for key in ("region", "selection", "region_feather"):
            self.engine_config.pop(key, None)
        mask = self.region_mask()
        if mask is None:
            self.engine_region = ""
        elif self.region_rect_mask is not None:
            self.engine_config["selection"] = mask.copy()
            self.engine_region = f"a rectangle selection ({int(mask.sum()):,} Gaussians)"
        else:
            self.engine_config["region"] = tuple(self.region_box)
            self.engine_region = "box " + ",".join(f"{v:.3g}" for v in self.region_box)
            if self.region_feather > 0:
                self.engine_config["region_feather"] = float(self.region_feather)
                self.engine_region += f", feathered over {self.region_feather:.3g}"

    def _apply_selection(self) -> None:
        """While the region tool is on, the Gaussians outside the selection are drawn dimmed in every view (the
        selected ones as they are, so the style arriving there stays visible; the outline, ``_selection_outline``,
        marks its edge); off, all as they are. Uploaded only when the selection changed."""
        mask = self.region_mask() if self.region_enabled else None
        for name, renderer in (("original", self.original), ("stylized", self.stylized)):
            key = None if mask is None else (self._region_version, id(mask), renderer.count)
            if self._selection_shown.get(name, "never") == key:
                continue
            self._selection_shown[name] = key
            renderer.set_selection(mask if mask is not None and mask.shape == (renderer.count,) else None)

    def _selection_outline(self, width: int, height: int) -> list[tuple[float, float, float, float]]:
        """The footprint of the selected Gaussians' centres in the view (``app/selection_outline.py``), window
        pixels relative to the view; recomputed only when the camera, the view size or the selection changed."""
        from .selection_outline import selection_outline

        mask = self.region_mask()
        if mask is None or self.loaded is None or not mask.any():
            return []
        sx, sy = framebuffer_scale()
        key = (self._region_version, id(mask), self.control.version, width, height, sx, sy)
        cached = self._selection_shown.get("outline")
        if cached is None or cached[0] != key:
            cam = self.control.camera(width, height)
            cached = (key, selection_outline(np.asarray(self.loaded.scene.means)[mask], cam, (sx, sy)))
            self._selection_shown["outline"] = cached
        return cached[1]

    def _region_outline(self, width: int, height: int) -> list[tuple[float, float, float, float]]:
        """The region box's 12 edges projected into the view (window pixels), edges behind the camera left out."""
        if not self.region_enabled or self.region_box is None or self.region_rect_mask is not None:
            return []
        cam = self.control.camera(width, height)
        b = self.region_box
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
