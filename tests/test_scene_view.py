"""Frame pacing of the studio's scene view: reuse, reduced-resolution renders while moving, progressive builds."""

import numpy as np
import pytest

moderngl = pytest.importorskip("moderngl")

from synthetic import blob_scene, look_at_camera  # noqa: E402

from app.gl_io import read_rgb  # noqa: E402
from app.renderer import SplatRenderer  # noqa: E402
from app.scene_view import ResolutionGovernor, SceneView, ViewPass  # noqa: E402
from app.studio import scene_arrays  # noqa: E402

W, H = 96, 72
BG = (0.0, 0.0, 0.0)


class FakeClock:
    """Advances 1 ms per reading (so a slice 'takes' 1 ms); tests add frame intervals to ``t``."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 1e-3
        return self.t


@pytest.fixture()
def scene(ctx):
    r = SplatRenderer(ctx)
    r.set_scene(scene_arrays(blob_scene(3000, seed=1)))
    yield r
    r.release()


def camera(angle: float = 0.0):
    return look_at_camera((3 * np.sin(angle), -0.4, -3 * np.cos(angle)), (0, 0, 0), W, H)


def one_pass(ctx, renderer, cam, layer="diffuse"):
    fbo = ctx.framebuffer([ctx.texture((W, H), 4)])
    renderer.render(cam, fbo, BG, layer)
    return read_rgb(fbo)


def shown(ctx, view, cam, passes, key=("stylized",)):
    fbo = ctx.framebuffer([ctx.texture((W, H), 4)])
    view.draw(fbo, cam, passes, key, BG)
    return read_rgb(fbo)


def shown_built(ctx, view, clock, cam, renderer, frames=300):
    """Frames of a still camera ``cam`` until ``view`` shows its build whole (at most ``frames``), the sorter idle
    before each (the frames are quicker than a thread's wake-up on a busy machine); the last image shown."""
    img = None
    for _ in range(frames):
        clock.t += 0.05
        assert renderer.sorter.idle(30)
        img = shown(ctx, view, cam, [ViewPass(renderer, "diffuse")])
        if view.stats.shown_full:
            break
    return img


def test_governor_lowers_scale_for_slow_frames_and_recovers():
    g = ResolutionGovernor(budget_ms=20.0, min_scale=0.25)
    for _ in range(10):
        g.observe(100.0 * g.scale ** 2, g.scale)  # fill-bound: 100 ms at full resolution
    assert 0.35 <= g.scale <= 0.5  # sqrt(20/100) = 0.45, quantised down to 1/16 steps
    g.observe(1e4, g.scale)
    assert g.scale >= 0.25  # never below the floor
    for _ in range(20):
        g.observe(1.0, g.scale)
    assert g.scale == 1.0


def test_governor_lowers_detail_once_the_smallest_scale_is_over_budget_and_restores_it_first():
    g = ResolutionGovernor(budget_ms=20.0, min_scale=0.25, min_detail=0.1)

    def cost(scale, detail):  # every splat covers some pixels at any scale: 60 ms per whole set, + fill
        return detail * (60.0 + 100.0 * scale**2)

    for _ in range(30):
        g.observe(cost(g.scale, g.detail), g.scale, g.detail)
    assert g.scale == 0.25
    assert 0.2 <= g.detail <= 0.35  # 20 / 66 ms = 0.3 of the Gaussians
    assert cost(g.scale, g.detail) <= 25.0
    g.observe(1e6, g.scale, g.detail)
    assert g.detail >= 0.1  # never below the floor
    seen = []
    for _ in range(40):  # a cheaper scene: detail comes back to 1 before the scale grows
        g.observe(0.2 * cost(g.scale, g.detail), g.scale, g.detail)
        seen.append((g.detail, g.scale))
    assert all(scale == 0.25 for detail, scale in seen if detail < 1.0)
    assert g.detail == 1.0 and g.scale > 0.25


def test_reduced_detail_draws_the_most_important_gaussians_only(ctx):
    from app.splat_data import importance_ranks

    scene = blob_scene(2000, seed=5)
    renderer = SplatRenderer(ctx)
    renderer.set_scene(scene_arrays(scene))
    fbo = ctx.framebuffer([ctx.texture((W, H), 4)])
    cam = camera(0.0)
    everything = renderer.render(cam, fbo)
    part = renderer.render(cam, fbo, detail=0.25)
    ranks = importance_ranks(scene.log_scales, scene.opacity_logits)
    in_front = renderer._means @ cam.world_to_cam[:3, :3].T + cam.world_to_cam[:3, 3]
    expected = int(np.sum((ranks < int(np.ceil(0.25 * scene.count))) & (in_front[:, 2] > 0.01)))
    assert part == expected < everything
    s = np.sort(scene.log_scales, axis=1)
    score = s[:, 1] + s[:, 2] + np.log(1 / (1 + np.exp(-scene.opacity_logits)))
    assert score[ranks == 0] == score.max()


def test_progressive_slices_compose_to_the_one_pass_image(ctx, scene):
    clock = FakeClock()
    view = SceneView(ctx, budget_ms=1e-6, clock=clock)  # budget below any slice: one slice per frame
    view.first_slice = 700
    view.governor.scale = 0.5
    cam = camera(0.3)
    scene.prepare(cam)  # its order sorted (a moving frame draws with the newest finished order, never waits)
    img = shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    assert view.stats.immediate == 1 and view.stats.last_scale == 0.5 and not view.stats.shown_full
    for _ in range(200):
        clock.t += 0.05
        img = shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
        if view.stats.shown_full:
            break
    assert view.stats.shown_full and view.stats.builds_completed == 1
    assert view.stats.slices >= 2  # really built in pieces
    assert np.array_equal(img, one_pass(ctx, scene, cam))


def test_unchanged_view_draws_no_splat(ctx, scene):
    clock = FakeClock()
    view = SceneView(ctx, clock=clock)
    view.progressive = False
    cam = camera(0.1)
    first = shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    sorts, slices, immediate = scene.sort_count, view.stats.slices, view.stats.immediate
    for _ in range(5):
        clock.t += 0.1
        again = shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    assert np.array_equal(first, again)
    assert (scene.sort_count, view.stats.slices, view.stats.immediate) == (sorts, slices, immediate)
    assert view.stats.reused == 5


def test_moving_camera_renders_at_once_and_refines_when_still(ctx, scene):
    clock = FakeClock()
    view = SceneView(ctx, budget_ms=1e-6, still_delay=0.15, clock=clock)
    view.governor.scale = 0.5
    scene.prepare(camera(0.0))  # an order to draw with from the first frame on (later ones may be a frame old)
    for i in range(4):  # moving: a reduced-resolution render every frame, no progressive slice
        clock.t += 0.02
        shown(ctx, view, camera(0.1 * i), [ViewPass(scene, "diffuse")])
    assert view.stats.immediate == 4 and view.stats.slices == 0
    cam = camera(0.3)
    img = shown_built(ctx, view, clock, cam, scene)
    assert view.stats.slices > 0 and np.array_equal(img, one_pass(ctx, scene, cam))


def test_streamed_colours_do_not_starve_the_build(ctx, scene):
    clock = FakeClock()
    view = SceneView(ctx, budget_ms=1e-6, clock=clock)
    view.progressive = False
    cam = camera(0.2)
    shown(ctx, view, cam, [ViewPass(scene, "diffuse")])  # full-resolution start
    view.progressive = True
    rng = np.random.default_rng(0)
    colors = None
    for _ in range(60):  # the worker sends new colours every frame
        clock.t += 0.05
        colors = rng.uniform(0, 1, (scene.count, 3)).astype(np.float32)
        scene.update_colors(colors)
        shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    assert view.stats.builds_completed >= 1  # a newer change waits for the running build
    for _ in range(200):  # the stream stops: the last colours are shown exactly, at full resolution
        clock.t += 0.05
        img = shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    assert np.array_equal(img, one_pass(ctx, scene, cam))


def test_expensive_builds_of_streamed_colours_keep_to_their_duty_cycle(ctx, scene):
    clock = FakeClock()  # a slice 'takes' 1 ms: a build of 10 slices 10 ms
    view = SceneView(ctx, budget_ms=1e-6, rebuild_interval=0.0, build_duty=0.002, clock=clock)
    view.first_slice = view.min_slice = 300  # 3000 Gaussians: 10 slices per build, one per frame
    view.progressive = False
    cam = camera(0.2)
    shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    view.progressive = True
    rng = np.random.default_rng(1)
    for _ in range(100):  # new colours every frame for 5 s
        clock.t += 0.05
        scene.update_colors(rng.uniform(0, 1, (scene.count, 3)).astype(np.float32))
        shown(ctx, view, cam, [ViewPass(scene, "diffuse")])
    # 10 ms of drawing at a duty of 0.2 %: one build per 5 s (without the rule: one every 10 frames, 10 in all)
    assert 1 <= view.stats.builds_completed <= 2


def test_compare_passes_split_the_view(ctx, scene):
    other = SplatRenderer(ctx)
    arrays = scene_arrays(blob_scene(3000, seed=1))
    arrays["sh_dc"] = np.zeros_like(arrays["sh_dc"]) + 2.0  # bright original
    other.set_scene(arrays)
    view = SceneView(ctx)
    view.progressive = False
    cam = camera(0.0)
    img = shown(ctx, view, cam, [ViewPass(scene, "diffuse", 0.0, 0.5), ViewPass(other, "diffuse", 0.5, 1.0)],
                key=("compare", 0.5))
    left, right = one_pass(ctx, scene, cam), one_pass(ctx, other, cam)
    assert np.array_equal(img[:, : W // 2], left[:, : W // 2])
    assert np.array_equal(img[:, W // 2:], right[:, W // 2:])
    other.release()


class SortCostsClock(SplatRenderer):
    """A renderer whose every new sort request costs ``cost`` seconds of the view's clock where it is asked for
    (as the old sort on the frame did): the governor must not see it."""

    def __init__(self, ctx, clock, cost, sorter=None):
        super().__init__(ctx, sorter)
        self.clock, self.cost = clock, cost

    def prepare(self, camera, detail=1.0, wait=True):
        before = self.sorter.stats.submitted
        ready = super().prepare(camera, detail, wait)
        if self.sorter.stats.submitted > before:
            self.clock.t += self.cost
        return ready


def test_moving_frames_never_wait_for_a_sort_and_only_the_raster_sets_the_detail(ctx):
    from fakes import GatedSort

    from app.depth_sort import DepthSorter

    clock, sort = FakeClock(), GatedSort()
    sort.gate.set()
    r = SortCostsClock(ctx, clock, 0.5, DepthSorter(sort))
    r.set_scene(scene_arrays(blob_scene(3000, seed=1)))
    r.prepare(camera(0.0))
    sort.gate.clear()  # from now on every sort is held until the end of the test
    view = SceneView(ctx, budget_ms=20.0, clock=clock)
    for i in range(1, 6):
        clock.t += 0.02
        shown(ctx, view, camera(0.1 * i), [ViewPass(r, "diffuse")])
    assert view.stats.immediate == 5 and r.sort_count == 1  # all drawn with the first order, none waited
    assert r.sorter.stats.submitted == 6 and r.last_wait_ms == 0.0
    assert (view.governor.scale, view.governor.detail) == (1.0, 1.0)  # 500 ms per sort: not the raster's
    sort.gate.set()
    r.release()


def test_a_build_starts_once_its_order_is_sorted(ctx):
    from fakes import GatedSort

    from app.depth_sort import DepthSorter

    clock, sort = FakeClock(), GatedSort()
    sort.gate.set()
    r = SplatRenderer(ctx, DepthSorter(sort))
    r.set_scene(scene_arrays(blob_scene(3000, seed=1)))
    r.prepare(camera(0.0))
    sort.gate.clear()
    view = SceneView(ctx, budget_ms=1e-6, clock=clock)
    view.governor.scale = 0.5
    cam = camera(0.4)
    for _ in range(10):  # still for 0.5 s: the build waits for the order of its view
        clock.t += 0.05
        shown(ctx, view, cam, [ViewPass(r, "diffuse")])
    assert view.stats.slices == 0 and view.building and view.stats.immediate == 1
    sort.gate.set()
    img = shown_built(ctx, view, clock, cam, r)
    assert view.stats.slices > 0 and np.array_equal(img, one_pass(ctx, r, cam))
    r.release()


def test_a_first_frame_without_an_order_keeps_the_background_until_the_sort_lands(ctx):
    from fakes import GatedSort

    from app.depth_sort import DepthSorter

    clock, sort = FakeClock(), GatedSort()
    r = SplatRenderer(ctx, DepthSorter(sort))
    r.set_scene(scene_arrays(blob_scene(3000, seed=1)))
    view = SceneView(ctx, clock=clock)
    cam = camera(0.2)
    first = shown(ctx, view, cam, [ViewPass(r, "diffuse")])  # its sort is held: nothing to draw with, no wait
    assert view.stats.no_order == 1 and view.stats.immediate == 0 and first.max() == 0
    sort.gate.set()
    assert r.sorter.idle(30)
    clock.t += 0.02
    img = shown(ctx, view, cam, [ViewPass(r, "diffuse")])
    assert view.stats.immediate == 1 and view.stats.shown_full and np.array_equal(img, one_pass(ctx, r, cam))
    assert not view.building  # the exact full image is on screen: no build of the same image follows
    r.release()


def test_moving_frames_sort_for_the_governors_detail(ctx, scene):
    clock = FakeClock()
    view = SceneView(ctx, budget_ms=1e-6, clock=clock)  # every frame over budget: detail down to its floor
    scene.prepare(camera(0.0))  # all Gaussians sorted
    for i in range(1, 8):
        clock.t += 0.02
        shown(ctx, view, camera(0.1 * i), [ViewPass(scene, "diffuse")])
        assert scene.sorter.idle(30)
    assert view.governor.detail == view.governor.min_detail
    assert scene.order_detail < 0.1 and view.stats.last_detail < 0.1  # the orders followed the governor down
