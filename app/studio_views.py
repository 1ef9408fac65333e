"""The studio's views: the renderers of the original scene, the stylized one and a take (``app/takes.py``), the
paced scene view that draws them (``app/scene_view.py``), the view mode, the compare view's divider and what its
right side shows."""

from __future__ import annotations

import moderngl
import numpy as np

from gstyle_core.cameras.camera import Camera

from .camera_control import CameraControl
from .events import Events, SceneShown
from .gl_io import set_scissor, target_size
from .panels import PanelState
from .renderer import DIFFUSE_LAYER, SH_LAYER, SplatRenderer
from .scene_view import SceneView, ViewPass
from .splat_data import scene_arrays

DIVIDER_COLOUR = (1.0, 1.0, 1.0)
BACKGROUND = (0.0, 0.0, 0.0)


class Views:
    """Owns the renderers, the scene view, the view mode, the divider and the take shown (its file, and whether the
    compare view compares with it). Built with the GL context, the panel, the camera control and the events (a
    new scene goes into the original and stylized renderers)."""

    def __init__(self, ctx: moderngl.Context, panel: PanelState, control: CameraControl, events: Events) -> None:
        self.ctx, self.panel, self.control = ctx, panel, control
        self.original = SplatRenderer(ctx)
        self.stylized = SplatRenderer(ctx)
        self.take_view = SplatRenderer(ctx)  # the take being looked at or compared with (app/takes.py)
        self.take_shown: str | None = None  # its file (None: no take loaded)
        self.view = SceneView(ctx)
        self.mode = "stylized"
        self.divider = 0.5  # compare split position, fraction of the width
        self.compare_with_take = False  # compare view: stylized left, the loaded take (True) or the original right
        events.subscribe(SceneShown, self._scene_shown)

    def _scene_shown(self, event: SceneShown) -> None:
        """The original with its SH; the stylized one starting from its diffuse colours."""
        arrays = scene_arrays(event.loaded.scene)
        self.original.set_scene(arrays)
        self.stylized.set_scene({k: v for k, v in arrays.items() if k != "sh_rest"})
        self.panel.gaussians = event.loaded.scene.count

    # ----------------------------------------------------------------- what is shown
    def set_mode(self, mode: str) -> None:
        """Show ``mode`` ("stylized", "original", "compare", "ground truth", "take")."""
        self.mode = mode

    def compare(self, with_take: bool) -> None:
        """The compare view: stylized left, the take loaded (``with_take``) or the original right."""
        self.compare_with_take = with_take
        self.mode = "compare"

    def show_take(self, path: str, arrays: dict[str, np.ndarray] | None, compare: bool) -> None:
        """The take in ``path`` (``arrays``: its scene, loaded anew; None: it is loaded already), compared with the
        stylized view (``compare``) or alone."""
        if arrays is not None:
            self.take_view.set_scene(arrays)
            self.take_shown = path
        self.compare_with_take = compare
        self.mode = "compare" if compare else "take"

    def drop_take(self, mode: str | None = None) -> None:
        """No take shown any more; ``mode``: the view mode from now on (None: the view leaves "take" only)."""
        self.take_shown, self.compare_with_take = None, False
        if mode is not None:
            self.mode = mode
        elif self.mode == "take":
            self.mode = "stylized"

    def set_divider(self, fraction: float) -> None:
        """The compare view's split, as a fraction of the width."""
        self.divider = float(np.clip(fraction, 0.0, 1.0))

    # ----------------------------------------------------------------- drawing
    def render(self, target: moderngl.Framebuffer, camera: Camera, progressive: bool) -> None:
        """Show the current view mode in ``target`` (its viewport) from ``camera``, paced by ``SceneView``
        (``progressive``; False: the exact current state at full resolution)."""
        width, height = target_size(target)
        if self.original.count == 0:
            target.use()
            target.clear(*BACKGROUND, 1.0)
            return
        mode = self.mode
        divider = float(np.clip(self.divider, 0.0, 1.0))
        take = self.take_shown is not None and self.take_view.count > 0
        if mode == "original":
            passes = [ViewPass(self.original, self._original_layer())]
        elif mode == "ground truth" and "gt" in self.stylized.layers:
            passes = [ViewPass(self.stylized, "gt")]
        elif mode == "take" and take:
            passes = [ViewPass(self.take_view, self._take_layer())]
        elif mode == "compare":
            right = (self.take_view, self._take_layer()) if take and self.compare_with_take else (
                self.original, self._original_layer())
            passes = [ViewPass(self.stylized, DIFFUSE_LAYER, 0.0, divider), ViewPass(*right, divider, 1.0)]
        else:
            passes = [ViewPass(self.stylized, DIFFUSE_LAYER)]
        self.view.progressive = progressive
        mode_key = (mode, divider, tuple(p.layer for p in passes), tuple(id(p.renderer) for p in passes))
        self.view.draw(target, camera, passes, mode_key, BACKGROUND)
        if mode == "compare":
            x0, y0 = target.viewport[:2]
            split = int(round(divider * width))
            set_scissor(self.ctx, (x0 + max(split - 1, 0), y0, 2, height))
            target.clear(*DIVIDER_COLOUR, 1.0)
            set_scissor(self.ctx, None)

    def _original_layer(self) -> str:
        return SH_LAYER if SH_LAYER in self.original.layers else DIFFUSE_LAYER

    def _take_layer(self) -> str:
        return SH_LAYER if SH_LAYER in self.take_view.layers else DIFFUSE_LAYER

    # ----------------------------------------------------------------- the panel
    def fill_panel(self) -> None:
        """The view's fields of the panel: its mode, field of view, ground truth, Gaussians, notes, divider."""
        p = self.panel
        p.view_mode = self.mode
        p.fov_deg = self.control.pose.fov_y_deg
        p.has_ground_truth = "gt" in self.stylized.layers
        p.gaussians = self.stylized.count
        p.viewer_notes = self.viewer_notes()
        p.divider = float(self.divider)

    def viewer_notes(self) -> list[str]:
        """What the viewer evaluates and skips (panel "Decisions"): view-dependent SH, sorts, uploads."""
        renderers = (self.original, self.stylized)
        if SH_LAYER in self.original.layers:
            sh = ("viewer SH: evaluated for the original scene only, on the GPU once per camera from coefficients "
                  "uploaded once; the stylized scene is diffuse")
        else:
            sh = "viewer SH: none evaluated (the scene has no view-dependent SH)"
        sorts = sum(r.sort_count for r in renderers)
        colours = sum(r.uploads["colors"] for r in renderers)
        geometry = sum(r.uploads["geometry"] for r in renderers)
        return [sh, f"viewer work: {sorts} depth sorts (view changes only, off the UI thread), {colours} colour and "
                    f"{geometry} geometry uploads (changes only)"]

    def release(self) -> None:
        """Free the scene view and the renderers (their GL objects, their sorter threads)."""
        self.view.release()
        self.original.release()
        self.stylized.release()
        self.take_view.release()
