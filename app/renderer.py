"""GL splat renderer: owns the GL objects that draw one set of Gaussians with one or more colour layers.

Per-Gaussian data lives in textures (4096 Gaussians per row) of one of two layouts (``splat_data.LAYOUTS``):
"compact" (the default: means and opacities float32, quaternions, scales, colours and SH coefficients half
floats; 32 bytes of geometry a Gaussian, 8 a colour layer, 96 for SH of degree 3) or "float32" (RGBA32F
throughout: 64, 16 and 192 bytes), kept as the reference the compact one is compared with. Drawing takes two
passes:

* projection (``shaders/splat_project.vert``, transform feedback): one vertex-shader invocation per Gaussian, in
  back-to-front order, writes its 2D centre, conic, opacity and quad axes into a buffer. It runs only when the
  camera, the target or the geometry changed: streamed colours, the compare view's second layer and the slices of
  a progressive build all reuse it;
* draw (``shaders/splat.vert`` + ``splat.geom`` + ``splat.frag``): one non-instanced draw of points, which the
  geometry stage expands into each splat's quad (its 3-sigma box along its own axes, shrunk to where the fragment
  stage would discard alpha < 1/255 anyway); the vertex stage only fetches the colour. Instancing cost a fixed
  amount per instance on llvmpipe; what remains is fill (every splat covers at least ~18 pixels after the
  0.3 px^2 dilation): ``bench/studies/gl_frame_parts.py`` splits a moving frame's time into its parts. On a software GL
  the draw goes in calls of ``draw_chunk`` splats, each waiting for the one before it (llvmpipe's memory).

The back-to-front order is the renderer's part ``DrawOrder`` (``app/renderer_order.py``); ``render(wait=True)``
(the default: screenshots, exports, tests) waits for the order of its own view. Uploads are split:
``update_colors`` rewrites one colour texture, ``update_geometry`` the four geometry textures.

Colour layers: any name -> [N, 3] RGB. The special layer ``"sh"`` (present when the scene was given SH
coefficients that are not all zero; all-zero bands are dropped) is view dependent: its coefficients are uploaded
once into a texture array (``sh_texture_layers``) and the projection pass evaluates them for each camera with the
rasterizer's conventions (the original scene in the viewer); the stylized scene uses plain diffuse layers.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import moderngl
import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.scene import used_sh_degree

from .depth_sort import DEFAULT_BITS, DepthSorter
from .gl_io import gl_dtype, is_software_gl, set_filter, set_scissor, target_size, texture_bytes
from .renderer_order import NEAR, DrawOrder, Gaussians, draw_points
from .shader_loader import program_sources, shader_source, with_defines
from .splat_data import (
    TEXTURE_WIDTH,
    check_geometry,
    check_layout,
    colors_from_arrays,
    geometry_textures,
    importance_order,
    pack_rgba,
    sh_texture_layers,
    texture_dtype,
    texture_rows,
)

SH_LAYER = "sh"
DIFFUSE_LAYER = "diffuse"
SELECTION_LAYER = "__selection__"  # the highlighted Gaussians (r = 1), see ``set_selection``
PROJECTED_VARYINGS = ("out_center", "out_conic", "out_axes")  # 2 + 4 + 4 floats per Gaussian
PROJECTED_STRIDE = 40  # bytes per projected Gaussian
PROJECTED_SH_STRIDE = 52  # with the SH colour (+ 3 floats, "out_rgb"): only a renderer with SH coefficients
SH_UNIT = 4  # texture unit of the SH coefficients in the projection pass (0-3: geometry)
SOFTWARE_DRAW_CHUNK = 32768  # splats a draw call on a software GL (``SplatRenderer.draw_chunk``)


class SplatRenderer:
    """Draw Gaussians into a moderngl framebuffer, matching ``gstyle_core.raster.rasterize``'s maths."""

    def __init__(self, ctx: moderngl.Context, sorter: DepthSorter | None = None, layout: str = "compact") -> None:
        self.ctx = ctx
        self.layout = check_layout(layout)
        self._dtype = texture_dtype(layout)  # of the colour and SH textures
        self.program = ctx.program(**program_sources("splat"))
        self.project_program = self._projection_program(sh=False)
        self._project_sh_program: moderngl.Program | None = None  # with the SH colour, made with the first SH
        self._order = DrawOrder(ctx, sorter)  # the back-to-front order (app/renderer_order.py)
        self._projected = ctx.buffer(reserve=PROJECTED_SH_STRIDE)
        self._vaos: dict[bool, tuple[moderngl.VertexArray, moderngl.VertexArray]] = {}  # with SH: (draw, project)
        self._projected_for: tuple | None = None
        self._geometry: list[moderngl.Texture] = []
        self._scale_unit = 1.0  # what the stored scales are multiplied by (compact layout: 2^-k)
        self._layers: dict[str, moderngl.Texture] = {}
        self._means = np.zeros((0, 3), np.float32)
        self._by_importance = np.zeros(0, np.int32)  # Gaussians most important first (reduced detail keeps a prefix)
        self._sh: moderngl.TextureArray | None = None  # SH coefficients (layer "sh"), see sh_texture_layers
        self._sh_degree = -1
        self._sh_count = 0
        self.sort_bits = DEFAULT_BITS  # depth key bits (app/depth_sort.py)
        self.geometry_version = 0
        self.content_version = 0  # bumped by every geometry or colour upload (the view cache's key)
        self.projection_count = 0  # how many projection passes ran (one per new camera/target/geometry)
        self.uploads = {"geometry": 0, "colors": 0}  # texture uploads so far (colours: any layer, SH included)
        self.highlight = False  # a selection is drawn highlighted (the Gaussians outside it dimmed)
        # Splats a draw call, each call waiting for the one before it to be rasterised (0: one call). llvmpipe
        # bins a draw into scenes of up to 36 MiB as far ahead of its rasteriser threads as the draw goes, and
        # keeps every scene it had in flight, memory included, for reuse: one unthrottled draw of 1.2 M splats
        # at 800x600 left 536 MB behind, drawn 32,768 at a time 48 MB, in the same time (docs/studio-performance).
        self.draw_chunk = SOFTWARE_DRAW_CHUNK if is_software_gl(ctx) else 0

    # ----------------------------------------------------------------- data
    @property
    def count(self) -> int:
        """Number of Gaussians currently loaded."""
        return int(self._means.shape[0])

    @property
    def sort_count(self) -> int:
        """Orders received from the sorter and uploaded (for tests and stats)."""
        return self._order.sort_count

    @property
    def last_wait_ms(self) -> float:
        """How long the last ``prepare`` waited for a sort (0 unless asked to wait)."""
        return self._order.last_wait_ms

    @property
    def sorter(self) -> DepthSorter:
        """The thread that sorts this renderer's Gaussians."""
        return self._order.sorter

    @property
    def has_order(self) -> bool:
        """An order of the current geometry's Gaussians is loaded (perhaps of an older view)."""
        return self._order.key is not None or not self.count

    @property
    def order_detail(self) -> float:
        """Fraction of the Gaussians the loaded order was sorted from (the detail it draws)."""
        return self._order.detail(self.count)

    def order(self) -> np.ndarray:
        """The draw order in use (int32 Gaussian indices, back to front), read back from the index buffer."""
        return self._order.read()

    def prepare(self, camera: Camera, detail: float = 1.0, wait: bool = True) -> bool:
        """Bring the draw order up to date for ``camera`` (``DrawOrder.prepare``); True when the order in use is this
        request's."""
        gaussians = Gaussians(self._means, self._by_importance, self.geometry_version, self.sort_bits)
        return self._order.prepare(gaussians, camera, detail, wait)

    @property
    def layers(self) -> list[str]:
        """Names of the colour layers available to ``render``."""
        return sorted(k for k in self._layers if not k.startswith("__")) + ([SH_LAYER] if self._sh is not None else [])

    def set_scene(self, arrays: Mapping[str, np.ndarray]) -> None:
        """Replace everything: geometry (means, log_scales, quats, opacity_logits) and colours.

        Colours come from ``colors`` [N,3] or ``sh_dc`` [N,3] (layer "diffuse"); with ``sh_dc`` and a non-empty
        ``sh_rest`` [N,K,3] the view-dependent layer "sh" is available too.
        """
        n = check_geometry(arrays)
        colors = colors_from_arrays(arrays)
        for tex in self._layers.values():
            tex.release()
        self._layers = {}
        self._drop_sh()
        if "sh_dc" in arrays:
            rest = np.asarray(arrays.get("sh_rest", np.zeros((n, 0, 3))), np.float32).reshape(n, -1, 3)
            degree = used_sh_degree(rest)  # all-zero bands add nothing: no SH layer for a scene without real SH
            if degree > 0:
                self._upload_sh(np.asarray(arrays["sh_dc"], np.float32), rest[:, : (degree + 1) ** 2 - 1], degree)
        self.update_geometry(arrays)
        self.update_colors(colors, DIFFUSE_LAYER)

    def update_geometry(self, arrays: Mapping[str, np.ndarray]) -> None:
        """Upload new geometry; colour layers whose length no longer matches are dropped."""
        n = check_geometry(arrays)
        data, self._scale_unit = geometry_textures(arrays, self.layout)
        if self._geometry and self._geometry[0].size[1] == data[0].shape[0]:
            for tex, content in zip(self._geometry, data, strict=True):
                tex.write(content)
        else:
            for tex in self._geometry:
                tex.release()
            self._geometry = [self._texture(content) for content in data]
        if n != self.count:  # the old order's indices mean nothing now; with the same count it is drawn until the
            self._order.forget()  # new geometry's order arrives (as after a camera move)
        self._means = np.asarray(arrays["means"], np.float32).copy()  # replaced, never written: the sorter reads it
        self._by_importance = importance_order(arrays["log_scales"], arrays["opacity_logits"])
        if self._sh is not None and self._sh_count != n:
            self._drop_sh()
        for name in [k for k, v in self._layers.items() if getattr(v, "extra", None) != n]:
            self._layers.pop(name).release()
        if SELECTION_LAYER not in self._layers:
            self.highlight = False
        self.geometry_version += 1
        self.uploads["geometry"] += 1
        self.content_version += 1

    def update_colors(self, colors: np.ndarray, layer: str = DIFFUSE_LAYER) -> None:
        """Upload RGB [N, 3] colours into a named layer (N must match the geometry)."""
        colors = np.asarray(colors, np.float32)
        if colors.shape != (self.count, 3):
            raise ValueError(f"colours must have shape [{self.count}, 3], got {list(colors.shape)}")
        if layer == SH_LAYER:
            raise ValueError(f"layer name {SH_LAYER!r} is reserved for SH colours")
        content = pack_rgba(np.nan_to_num(colors, nan=0.0, posinf=1.0, neginf=0.0), self._dtype)
        tex = self._layers.get(layer)
        if tex is not None and tex.size[1] == content.shape[0]:
            tex.write(content)
        else:
            if tex is not None:
                tex.release()
            tex = self._texture(content)
            self._layers[layer] = tex
        tex.extra = self.count
        self.uploads["colors"] += 1
        if not layer.startswith("__"):  # internal layers (view-dependent SH) follow the camera, already in any key
            self.content_version += 1

    def set_selection(self, mask: np.ndarray | None) -> None:
        """Draw the Gaussians where ``mask`` (bool [N]) is False dimmed, the others as they are; None draws them
        all as they are. A new geometry of another count drops the selection."""
        if mask is None:
            if self.highlight:
                self.highlight = False
                self.content_version += 1
            return
        mask = np.asarray(mask, bool)
        if mask.shape != (self.count,):
            raise ValueError(f"selection must have shape [{self.count}], got {list(mask.shape)}")
        self.update_colors(np.repeat(mask[:, None], 3, axis=1).astype(np.float32), SELECTION_LAYER)
        self.highlight = True
        self.content_version += 1

    # ----------------------------------------------------------------- drawing
    def render(self, camera: Camera, fbo: moderngl.Framebuffer, background: Sequence[float] = (0.0, 0.0, 0.0),
               layer: str = DIFFUSE_LAYER, scissor: tuple[int, int, int, int] | None = None,
               clear: bool = True, instances: tuple[int, int] | None = None, detail: float = 1.0,
               wait: bool = True) -> int:
        """Draw with ``camera`` into ``fbo``'s viewport (whose size should be camera.width x camera.height).

        ``scissor`` = (x, y, width, height) in GL framebuffer pixels (y up) limits drawing (and clearing).
        ``instances`` = (first, count) draws only that slice of the back-to-front order (progressive rendering:
        slices drawn in order, without clearing in between, add up to the whole image). ``detail`` < 1 draws only
        that fraction of the Gaussians, the most important first (opacity × area, ``importance_order``): the quick
        preview of a moving camera. ``wait``: draw with the order of this view and detail (waiting for its sort);
        False: with the newest finished order (nothing is drawn before the first one). Returns the number of
        Gaussians in the order drawn from (those in front of the camera).
        """
        fbo.use()
        width, height = target_size(fbo)
        set_scissor(self.ctx, scissor)
        if clear:
            fbo.clear(*[float(c) for c in background[:3]], 1.0)
        if self.count:
            self.prepare(camera, detail, wait)
            colour_tex = self._colour_texture(layer)
            self._project(camera)
            self._bind(width, height, colour_tex)
            self.ctx.enable(moderngl.BLEND)
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            first, count = (0, self._order.instances) if instances is None else instances
            first = min(max(int(first), 0), self._order.instances)
            count = min(max(int(count), 0), self._order.instances - first)
            if count:
                draw_points(self.ctx, self._arrays()[0], first, count, self.draw_chunk)
            self.ctx.disable(moderngl.BLEND)
        set_scissor(self.ctx, None)
        return self._order.instances if self.count else 0

    def projected(self) -> dict[str, np.ndarray]:
        """The last projection pass's output in draw order: ``center`` [M, 2] (pixels), ``conic`` [M, 4] (a, b, c,
        opacity), ``axes`` [M, 4] (the quad's half axes; zero = culled), ``rgb`` [M, 3] (SH colour, zero without)."""
        m = self._order.instances
        data = np.frombuffer(self._projected.read(size=self._stride * m), np.float32).reshape(m, -1)
        rgb = data[:, 10:13] if self._stride == PROJECTED_SH_STRIDE else np.zeros((m, 3), np.float32)
        return {"center": data[:, 0:2], "conic": data[:, 2:6], "axes": data[:, 6:10], "rgb": rgb}

    def gl_memory(self) -> dict[str, int]:
        """Bytes of this renderer's GL objects by part: ``geometry``, ``colours`` (every layer), ``sh``,
        ``projected`` (the projection pass's output) and ``order`` (the index buffer). On llvmpipe they live in
        host memory."""
        return {"geometry": sum(texture_bytes(t) for t in self._geometry),
                "colours": sum(texture_bytes(t) for t in self._layers.values()),
                "sh": texture_bytes(self._sh) if self._sh is not None else 0,
                "projected": self._projected.size, "order": self._order.index_buffer.size}

    def release(self) -> None:
        """Stop the sorter and free all GL objects."""
        self._order.sorter.stop()
        self._drop_sh()
        programs = [self.project_program] + ([self._project_sh_program] if self._project_sh_program else [])
        vaos = [vao for pair in self._vaos.values() for vao in pair]
        for obj in [*self._geometry, *self._layers.values(), *vaos, self._order.index_buffer,
                    self._projected, self.program, *programs]:
            obj.release()
        self._geometry, self._layers = [], {}

    # ----------------------------------------------------------------- internals
    def _texture(self, content: np.ndarray) -> moderngl.Texture:
        tex = self.ctx.texture((TEXTURE_WIDTH, content.shape[0]), 4, content, dtype=gl_dtype(content.dtype))
        set_filter(tex, moderngl.NEAREST)
        return tex

    def _project(self, camera: Camera) -> None:
        """Run the projection pass unless its inputs (camera, order, geometry) are those of the last run."""
        key = (np.asarray(camera.world_to_cam, np.float32).tobytes(), float(camera.fx), float(camera.fy),
               float(camera.cx), float(camera.cy), int(camera.width), int(camera.height), self.geometry_version,
               self._order.sort_count)
        if key == self._projected_for or not self._order.instances:
            return
        needed = self._stride * self._order.instances
        if needed > self._projected.size:
            self._projected.orphan(needed)
        prog = self._project_sh_program if self._sh is not None else self.project_program
        for unit, tex in enumerate(self._geometry):
            tex.use(unit)
            prog[f"u_geom{unit}"].value = unit
        if self.layout == "compact":
            prog["u_scale_unit"].value = self._scale_unit
        prog["u_tex_width"].value = TEXTURE_WIDTH
        prog["u_world_to_cam"].write(np.asarray(camera.world_to_cam, np.float32).T.tobytes())
        prog["u_intrinsics"].value = (float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy))
        prog["u_image_size"].value = (float(camera.width), float(camera.height))
        prog["u_viewport_origin"].value = (0.0, 0.0)
        prog["u_near"].value = NEAR
        if self._sh is not None:
            self._sh.use(SH_UNIT)
            prog["u_sh"].value = SH_UNIT
            prog["u_sh_degree"].value = self._sh_degree
            prog["u_camera_pos"].value = tuple(float(v) for v in camera.position)
        self._arrays()[1].transform(self._projected, mode=moderngl.POINTS, vertices=self._order.instances)
        self._projected_for = key
        self.projection_count += 1

    @property
    def _stride(self) -> int:
        """Bytes a Gaussian of the projection pass's output (the SH colour only where there are SH)."""
        return PROJECTED_SH_STRIDE if self._sh is not None else PROJECTED_STRIDE

    def _projection_program(self, sh: bool) -> moderngl.Program:
        """The projection pass of this layout, writing the SH colour too when ``sh``."""
        defines = (["COMPACT_GEOMETRY"] if self.layout == "compact" else []) + (["SH_COLOUR"] if sh else [])
        varyings = [*PROJECTED_VARYINGS, "out_rgb"] if sh else list(PROJECTED_VARYINGS)
        return self.ctx.program(vertex_shader=with_defines(shader_source("splat_project.vert"), *defines),
                                varyings=varyings)

    def _arrays(self) -> tuple[moderngl.VertexArray, moderngl.VertexArray]:
        """The (draw, projection) vertex arrays of the current output layout (with or without the SH colour)."""
        sh = self._sh is not None
        if sh not in self._vaos:
            content = (self._projected, "2f 4f 4f 3f", "in_center", "in_conic", "in_axes", "in_rgb") if sh else \
                (self._projected, "2f 4f 4f", "in_center", "in_conic", "in_axes")
            program = self._project_sh_program if sh else self.project_program
            index = (self._order.index_buffer, "1i", "in_index")
            self._vaos[sh] = (self.ctx.vertex_array(self.program, [content, index]),
                              self.ctx.vertex_array(program, [index]))
        return self._vaos[sh]

    def _colour_texture(self, layer: str) -> moderngl.Texture | None:
        """The layer's colour texture; None for the SH layer (its colours come from the projection pass)."""
        if layer == SH_LAYER:
            if self._sh is None:
                raise ValueError("this scene has no SH coefficients (layer 'sh')")
            return None
        if layer not in self._layers:
            raise ValueError(f"unknown colour layer {layer!r}; have {', '.join(self.layers) or 'none'}")
        return self._layers[layer]

    def _upload_sh(self, sh_dc: np.ndarray, sh_rest: np.ndarray, degree: int) -> None:
        """Upload the coefficients of the SH layer once: a texture array written one layer at a time."""
        n = sh_dc.shape[0]
        layers = -(-3 * (degree + 1) ** 2 // 4)
        tex = self.ctx.texture_array((TEXTURE_WIDTH, texture_rows(n), layers), 4, dtype=gl_dtype(self._dtype))
        set_filter(tex, moderngl.NEAREST)
        if self._project_sh_program is None:
            self._project_sh_program = self._projection_program(sh=True)
        for j, content in enumerate(sh_texture_layers(sh_dc, sh_rest, self._dtype)):
            tex.write(content, viewport=(0, 0, j, TEXTURE_WIDTH, content.shape[0], 1))
        self._sh, self._sh_degree, self._sh_count = tex, degree, n
        self.uploads["colors"] += 1

    def _drop_sh(self) -> None:
        if self._sh is not None:
            self._sh.release()
        self._sh, self._sh_degree, self._sh_count = None, -1, 0

    def _bind(self, width: int, height: int, colour_tex: moderngl.Texture | None) -> None:
        colour = colour_tex if colour_tex is not None else self._layers[DIFFUSE_LAYER]  # (not read for SH)
        colour.use(0)
        prog = self.program
        prog["u_color"].value = 0
        prog["u_projected_rgb"].value = int(colour_tex is None)
        highlight = self.highlight and SELECTION_LAYER in self._layers
        (self._layers[SELECTION_LAYER] if highlight else colour).use(1)
        prog["u_select"].value = 1
        prog["u_highlight"].value = int(highlight)
        prog["u_tex_width"].value = TEXTURE_WIDTH
        prog["u_target_size"].value = (float(width), float(height))

