"""Frame pacing for the splat view on a software GL (llvmpipe): the scene is drawn into offscreen textures and
shown with one textured quad, so the UI never waits for a whole splat render.

On llvmpipe a splat frame costs its fragments: 40k Gaussians at 800×600 cover each pixel ~12 times and take
~100 ms on 2 cores, three times a 30 fps frame. Three rules keep the frame time within a budget:

1. Nothing changed (same camera, same colours and geometry, same view mode) -> the last image is shown again;
   no splat is drawn.
2. The camera moved -> the scene is drawn at once at a reduced resolution chosen by ``ResolutionGovernor`` from
   the measured cost of earlier frames (fill cost ∝ pixels, so scale ∝ sqrt(budget / cost)), and upscaled; when
   even the smallest scale is over budget, only the most important fraction of the Gaussians is drawn (every
   splat covers ~18 pixels at any resolution, so below that scale the cost follows the count). The cost measured
   is the raster's alone (projection and draw): the depth sort runs on the renderers' sorter threads, and a moving
   frame draws with the newest order they finished (a renderer with no order yet keeps the last image on screen).
3. Once the camera has been still for ``still_delay`` seconds, or when only colours/geometry changed (the worker
   streaming), the full-resolution image is built progressively: consecutive slices of the back-to-front order
   are blended into an accumulation texture, as many per frame as fit the budget (the slice size adapts to the
   measured time). Back-to-front slices drawn in order without clearing compose to exactly the one-pass image;
   a build starts once the order of its view is sorted (requested as soon as the camera stops), and starts over
   if the order changes under it.
   It is shown when complete; a newer change waits for the running build to finish, so streaming never starves it,
   and streamed changes start at most one build per ``rebuild_interval`` seconds, and only when builds so far took
   at most ``build_duty`` of the wall time (a build of a large scene costs hundreds of ms of both cores: the
   worker keeps its CPU share).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import moderngl
import numpy as np

from gstyle_core.cameras.camera import Camera

from .gl_io import set_filter
from .renderer import SplatRenderer
from .shader_loader import program_sources

_CORNERS = np.array([-1, -1, 1, -1, -1, 1, 1, 1], np.float32)


class ResolutionGovernor:
    """Chooses the render scale (fraction of the window's pixels per side) and, below the smallest scale, the detail
    (fraction of the Gaussians drawn, most important first) of immediate renders.

    Scale goes first: fill cost ∝ pixels, so scale ∝ sqrt(budget / cost). But every splat covers some pixels whatever
    the resolution (the 0.3 px² dilation: ~18 px at least), so at ``min_scale`` the cost is ∝ Gaussians drawn and
    the detail goes down ∝ budget / cost, and comes back up before the scale does."""

    def __init__(self, budget_ms: float = 20.0, min_scale: float = 0.25, step: float = 1 / 16,
                 min_detail: float = 0.01) -> None:
        self.budget_ms = budget_ms
        self.min_scale = min_scale
        self.step = step
        self.min_detail = min_detail
        self.scale = 1.0
        self.detail = 1.0

    def observe(self, ms: float, scale: float, detail: float = 1.0) -> float:
        """Record that a render at ``scale`` and ``detail`` took ``ms``; returns the scale to use next (the detail
        to use next is ``self.detail``)."""
        ratio = self.budget_ms / max(ms, 1e-3)
        if detail < 1.0 or (scale <= self.min_scale and ratio < 1.0):
            ideal = min(detail * ratio, 1.0)
            blended = math.sqrt(self.detail * ideal)  # geometric mean: damp oscillation
            level = self._quantise(blended, self.detail) if blended >= 2 * self.step else \
                self._quantise_halving(blended, self.detail)
            self.detail = float(min(1.0, max(self.min_detail, level)))
            return self.scale
        ideal = scale * math.sqrt(ratio)
        blended = math.sqrt(self.scale * min(ideal, 1.0))
        self.scale = float(min(1.0, max(self.min_scale, self._quantise(blended, self.scale))))
        return self.scale

    @staticmethod
    def _quantise_halving(value: float, current: float) -> float:
        """Below two steps the detail moves by halves (1/16, 1/32, ...): a 1.5 M capture's moving frames need a
        few percent of its Gaussians, and steps of 1/16 would jump from 6 % to the floor."""
        exponent = math.log2(max(value, 1e-9))
        return 2.0 ** (math.ceil(exponent - 1e-9) if value > current else math.floor(exponent + 1e-9))

    def _quantise(self, value: float, current: float) -> float:
        """Few distinct levels (few texture reallocations and re-sorts); round towards the change."""
        steps = value / self.step
        return (math.ceil(steps - 1e-9) if value > current else math.floor(steps + 1e-9)) * self.step


@dataclass
class ViewPass:
    """One renderer/layer drawn into the columns [x0, x1) (fractions of the width) of the view."""

    renderer: SplatRenderer
    layer: str
    x0: float = 0.0
    x1: float = 1.0


@dataclass
class _Build:
    key: tuple
    camera: Camera
    passes: list[ViewPass]
    pass_index: int = 0
    first: int = 0
    started: bool = False
    orders: tuple = ()  # the renderers' order versions (sort_count) the build draws with


@dataclass
class ViewStats:
    """Counters of what the view did (tests and the panel read them)."""

    frames: int = 0
    reused: int = 0  # frames that drew no splat
    no_order: int = 0  # moving frames that kept the last image because a renderer had no order yet
    immediate: int = 0  # reduced-resolution renders after a camera move
    last_detail: float = 1.0  # fraction of the Gaussians the last immediate render drew
    slices: int = 0  # progressive slices drawn
    builds_completed: int = 0
    last_scale: float = 1.0
    shown_full: bool = False


class SceneView:
    """Draws the scene through offscreen textures with the three rules of this module's docstring."""

    def __init__(self, ctx: moderngl.Context, *, budget_ms: float = 20.0, still_delay: float = 0.15,
                 rebuild_interval: float = 0.5, build_duty: float = 0.25,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.ctx = ctx
        self.governor = ResolutionGovernor(budget_ms)
        self.budget_ms = budget_ms
        self.still_delay = still_delay
        self.rebuild_interval = rebuild_interval  # streamed colours: at most one new build per this many seconds
        self._last_build_start = -math.inf
        self.build_duty = build_duty  # streamed colours: builds take at most this fraction of the wall time
        self._last_build_ms = 0.0  # drawing time of the last completed build
        self._build_ms = 0.0
        self.clock = clock
        self.stats = ViewStats()
        self.progressive = True  # False: every change is drawn at full resolution at once (tests, screenshots)
        self.first_slice = 4096  # Gaussians in the first slice, before any rate is measured
        self.min_slice = 256
        self._program = ctx.program(**program_sources("image"))
        self._quad_buffer = ctx.buffer(_CORNERS.tobytes())
        self._quad = ctx.vertex_array(self._program, [(self._quad_buffer, "2f", "in_corner")])
        self._fbos: dict[str, moderngl.Framebuffer] = {}
        self._shown: str | None = None  # name of the FBO on screen
        self._shown_key: tuple | None = None
        self._build: _Build | None = None
        self._pending: tuple[tuple, Camera, list[ViewPass]] | None = None
        self._camera_key: tuple | None = None
        self._last_move = -math.inf
        self._slice_rate = 0.0  # Gaussians per ms of the last slices (0 = unknown)

    # ----------------------------------------------------------------- public
    def draw(self, target: moderngl.Framebuffer, camera: Camera, passes: Sequence[ViewPass], mode_key: tuple,
             background: Sequence[float]) -> None:
        """Bring the view up to date within the budget and show it in ``target``'s viewport."""
        now = self.clock()
        self.stats.frames += 1
        self._background = tuple(float(c) for c in background[:3])
        passes = list(passes)
        cam_key = (camera.world_to_cam.tobytes(), camera.fx, camera.fy, camera.cx, camera.cy, camera.width,
                   camera.height)
        moved = cam_key != self._camera_key
        if moved:
            self._camera_key, self._last_move = cam_key, now
        key = (cam_key, mode_key, *(p.renderer.content_version for p in passes))
        drew = False
        if not self.progressive:
            if key != self._shown_key:
                drew = self._immediate(camera, passes, key)
        elif key != self._shown_key:
            if moved or self._shown is None:
                drew = self._immediate(camera, passes, key)
            if self._shown_key != key or not self.stats.shown_full:
                self._queue(key, camera, passes, cancel=moved)
            elif self._pending is not None and self._pending[0] == key:  # queued by a frame that had no order yet
                self._pending = None
        ready = self._pending is not None and not moved and self._orders_ready(*self._pending[1:])  # sorts early
        if (self._build is None and ready and now - self._last_move >= self.still_delay
                and (not self.stats.shown_full or now - self._last_build_start >= self._streamed_gap())):
            self._build = _Build(*self._pending)
            self._pending = None
            self._last_build_start = now
        if self._build is not None and now - self._last_move >= self.still_delay:
            drew = self._advance_build() or drew
        if not drew:
            self.stats.reused += 1
        self._blit(target)

    @property
    def building(self) -> bool:
        """A full-resolution image is being built or waits to be (more frames are needed to show it)."""
        return self._build is not None or self._pending is not None

    def release(self) -> None:
        """Free the GL objects."""
        for fbo in self._fbos.values():
            for att in fbo.color_attachments:
                att.release()
            fbo.release()
        self._fbos = {}
        for obj in (self._quad, self._quad_buffer, self._program):
            obj.release()

    # ----------------------------------------------------------------- internals
    def _streamed_gap(self) -> float:
        """Seconds between the starts of two builds for streamed changes."""
        return max(self.rebuild_interval, self._last_build_ms / 1e3 / max(self.build_duty, 1e-3))

    def _fbo(self, name: str, size: tuple[int, int]) -> moderngl.Framebuffer:
        fbo = self._fbos.get(name)
        if fbo is None or fbo.size != size:
            if fbo is not None:
                fbo.color_attachments[0].release()
                fbo.release()
            tex = self.ctx.texture(size, 4)
            set_filter(tex, moderngl.LINEAR)
            fbo = self.ctx.framebuffer([tex])
            self._fbos[name] = fbo
        return fbo

    def _orders_ready(self, camera: Camera, passes: Sequence[ViewPass], detail: float = 1.0) -> bool:
        """Every pass's renderer draws with the order of ``camera`` at ``detail`` (each one not sorted yet is asked
        for; nothing waits)."""
        return all([p.renderer.prepare(camera, detail, wait=False) for p in passes])

    def _draw_passes(self, fbo: moderngl.Framebuffer, camera: Camera, passes: Sequence[ViewPass],
                     instances: tuple[int, int] | None = None, only: int | None = None, detail: float = 1.0) -> int:
        width = camera.width
        total = 0
        for i, p in enumerate(passes):
            if only is not None and i != only:
                continue
            x0, x1 = (int(round(np.clip(v, 0.0, 1.0) * width)) for v in (p.x0, p.x1))
            scissor = None if (x0, x1) == (0, width) else (x0, 0, max(x1 - x0, 0), camera.height)
            if scissor is not None and scissor[2] == 0:
                continue
            total += p.renderer.render(camera, fbo, self._background, p.layer, scissor=scissor, clear=False,
                                       instances=instances, detail=detail, wait=not self.progressive)
        return total

    def _immediate(self, camera: Camera, passes: list[ViewPass], key: tuple) -> bool:
        scale = self.governor.scale if self.progressive else 1.0
        detail = self.governor.detail if self.progressive else 1.0
        cam = camera if scale >= 1.0 else camera.scaled(scale)
        # sorts are asked for here, outside the raster's measured time
        exact = all([p.renderer.prepare(cam, detail, wait=not self.progressive) for p in passes])
        if not all(p.renderer.has_order for p in passes):
            self.stats.no_order += 1
            return False
        drawn = max(p.renderer.order_detail for p in passes)  # the detail of the newest finished orders
        name = "low" if scale < 1.0 else self._spare_full()
        fbo = self._fbo(name, (cam.width, cam.height))
        fbo.use()
        fbo.clear(*self._background, 1.0)
        t0 = self.clock()
        self._draw_passes(fbo, cam, passes, detail=detail)
        self.ctx.finish()
        if self.progressive:
            self.governor.observe((self.clock() - t0) * 1e3, scale, drawn)
        self._shown = name
        self._shown_key = key
        self.stats.immediate += 1
        self.stats.last_scale = scale
        self.stats.last_detail = drawn
        self.stats.shown_full = scale >= 1.0 and drawn >= 1.0 and exact  # else a build follows
        return True

    def _fbo_name(self, fbo: moderngl.Framebuffer) -> str:
        return next(name for name, f in self._fbos.items() if f is fbo)

    def _spare_full(self) -> str:
        """Name of the full-size FBO that is not on screen (two alternate: one shown, one being built)."""
        return "full_b" if self._shown == "full_a" else "full_a"

    def _queue(self, key: tuple, camera: Camera, passes: list[ViewPass], cancel: bool) -> None:
        if cancel:
            self._build = None
        if self._build is not None and self._build.key == key:
            return
        self._pending = (key, camera, passes)

    def _advance_build(self) -> bool:
        b = self._build
        fbo = self._fbo(self._spare_full(), (b.camera.width, b.camera.height))
        orders = tuple(p.renderer.sort_count for p in b.passes)
        if not b.started or orders != b.orders:  # a new order (new geometry) under the build: it starts over
            if not self._orders_ready(b.camera, b.passes):
                b.started = False
                return False
            fbo.use()
            fbo.clear(*self._background, 1.0)
            b.started, b.orders, b.pass_index, b.first = True, orders, 0, 0
            self._build_ms = 0.0
        spent = 0.0
        drew = False
        while b.pass_index < len(b.passes) and spent < self.budget_ms:
            renderer = b.passes[b.pass_index].renderer
            remaining_ms = self.budget_ms - spent
            count = (max(self.min_slice, int(self._slice_rate * remaining_ms)) if self._slice_rate > 0
                     else self.first_slice)
            t0 = self.clock()
            total = self._draw_passes(fbo, b.camera, b.passes, instances=(b.first, count), only=b.pass_index)
            self.ctx.finish()
            ms = (self.clock() - t0) * 1e3
            spent += ms
            self._build_ms += ms
            drawn = min(count, max(total - b.first, 0))
            if drawn:
                rate = drawn / max(ms, 1e-3)
                self._slice_rate = rate if self._slice_rate <= 0 else math.sqrt(self._slice_rate * rate)
            self.stats.slices += 1
            drew = True
            b.first += count
            if b.first >= total or renderer.count == 0:
                b.pass_index += 1
                b.first = 0
        if b.pass_index >= len(b.passes):
            self._shown = self._fbo_name(fbo)
            self._shown_key = b.key
            self._build = None
            self._last_build_ms = self._build_ms
            self.stats.builds_completed += 1
            self.stats.shown_full = True
            self.stats.last_scale = 1.0
        return drew

    def _blit(self, target: moderngl.Framebuffer) -> None:
        target.use()
        width, height = target.viewport[2], target.viewport[3]
        if self._shown is None:
            target.clear(*self._background, 1.0)
            return
        tex = self._fbos[self._shown].color_attachments[0]
        tex.use(0)
        self._program["u_image"].value = 0
        # FBO textures hold row 0 at the bottom (GL): a rectangle of negative height puts uv row 0 there.
        self._program["u_rect"].value = (0.0, float(height), float(width), -float(height))
        self._program["u_target_size"].value = (float(width), float(height))
        self.ctx.disable(moderngl.BLEND)
        self._quad.render(moderngl.TRIANGLE_STRIP)
