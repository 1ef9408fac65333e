"""The level of detail (``gstyle_core/lod``): merges exact on moments, the cut independent of the file's order, the
colour carry-back exact on re-merging, regions never mixed, and a run that writes every input Gaussian."""

from __future__ import annotations

import numpy as np
import pytest

from gstyle_core.cameras.camera import Camera
from gstyle_core.lod import build_cut, covariances, expand_to_children, merge_groups
from gstyle_core.lod.moments import gaussian_weights, matrices_to_quats, rotation_matrices, surface_areas
from gstyle_core.scene import GaussianScene, logit, rgb_to_sh_dc


def _random_scene(n: int, seed: int = 0, spread: float = 1.0, log_scale: float = -3.0, sh_bands: int = 0,
                  opacity: tuple[float, float] = (0.05, 0.3)) -> GaussianScene:
    rng = np.random.default_rng(seed)
    quats = rng.normal(size=(n, 4)).astype(np.float32)
    return GaussianScene(
        means=(rng.normal(size=(n, 3)) * spread).astype(np.float32),
        log_scales=(log_scale + rng.normal(size=(n, 3)) * 0.3).astype(np.float32),
        quats=quats * rng.uniform(0.5, 3.0, (n, 1)).astype(np.float32),  # not unit: the merge normalises
        opacity_logits=logit(rng.uniform(*opacity, n)),
        sh_dc=rgb_to_sh_dc(rng.uniform(0.2, 0.8, (n, 3))).astype(np.float32),
        sh_rest=rng.normal(size=(n, sh_bands, 3)).astype(np.float32) * 0.1)


def _orbit(n_views: int = 4, radius: float = 6.0, width: int = 64) -> list[Camera]:
    cams = []
    for k in range(n_views):
        a = 2 * np.pi * k / n_views
        eye = np.array([radius * np.sin(a), 0.0, -radius * np.cos(a)])
        fwd = -eye / np.linalg.norm(eye)
        right = np.cross([0.0, 1.0, 0.0], fwd)
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        w2c = np.eye(4)
        w2c[:3, :3] = np.stack([right, down, fwd])
        w2c[:3, 3] = -w2c[:3, :3] @ eye
        cams.append(Camera(width, width, width * 1.2, width * 1.2, width / 2, width / 2, w2c))
    return cams


def test_rotation_round_trip():
    q = np.random.default_rng(3).normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    back = matrices_to_quats(rotation_matrices(q))
    assert np.allclose(np.abs(np.sum(back * q, axis=1)), 1.0, atol=1e-9)  # the same rotation (q and -q alike)


def test_merge_keeps_total_weight_mean_and_covariance():
    scene = _random_scene(400, seed=1)
    groups = np.random.default_rng(2).integers(0, 30, scene.count)
    parents, total = merge_groups(scene, groups, 30)
    w = gaussian_weights(scene.log_scales, scene.opacity_logits)
    means = scene.means.astype(np.float64)
    cov_children = covariances(scene.log_scales, scene.quats)
    cov_parents = covariances(parents.log_scales, parents.quats)
    for g in range(30):
        m = groups == g
        share = w[m] / w[m].sum()
        mean = share @ means[m]
        d = means[m] - mean
        cov = np.einsum("n,nij->ij", share, cov_children[m] + d[:, :, None] * d[:, None, :])
        assert total[g] == pytest.approx(w[m].sum(), rel=1e-12)
        assert np.allclose(parents.means[g], mean, atol=1e-5)
        assert np.allclose(cov_parents[g], cov, rtol=1e-4, atol=1e-9 * np.abs(cov).max())
        # the parent's weight (opacity × area) is the children's total where it is not clamped at opacity 1
        alpha = 1 / (1 + np.exp(-float(parents.opacity_logits[g])))
        assert alpha * surface_areas(np.exp(parents.log_scales[g:g + 1].astype(np.float64)))[0] == pytest.approx(
            w[m].sum(), rel=1e-4)
        assert np.allclose(parents.sh_dc[g], share @ scene.sh_dc[m].astype(np.float64), atol=1e-6)


def test_a_group_of_one_is_the_gaussian_itself_and_transparent_groups_stay_finite():
    scene = _random_scene(5, seed=4)
    parents, _ = merge_groups(scene, np.arange(5), 5)
    assert np.allclose(covariances(parents.log_scales, parents.quats),
                       covariances(scene.log_scales, scene.quats), rtol=1e-4, atol=1e-12)
    assert np.allclose(parents.opacity_logits, scene.opacity_logits, atol=1e-3)
    clear = _random_scene(6, seed=5)
    clear.opacity_logits[:] = -200.0  # opacity 0: weights 0
    clear.log_scales[:3] = -300.0  # and degenerate scales
    parents, _ = merge_groups(clear, np.zeros(6, np.int64), 1)
    for name in ("means", "log_scales", "quats", "opacity_logits", "sh_dc"):
        assert np.isfinite(getattr(parents, name)).all()


def _dense_scene(seed: int = 0) -> GaussianScene:
    """A cluster of many tiny Gaussians (far below a pixel at 64 px from 6 units) and a few large ones."""
    tiny = _random_scene(3000, seed=seed, spread=0.15, log_scale=-6.0, sh_bands=3)
    big = _random_scene(40, seed=seed + 1, spread=1.0, log_scale=-1.5, sh_bands=3)
    return GaussianScene.concatenate([tiny, big])


def test_the_cut_merges_the_tiny_keeps_the_large_and_ignores_the_file_order():
    scene, cams = _dense_scene(), _orbit()
    cut = build_cut(scene, cams, 64, 2.0)
    assert cut.parent_count < scene.count // 3
    assert not cut.merged[cut.child_parent[-40:]].any()  # the large ones held as they are
    order = np.random.default_rng(9).permutation(scene.count)
    shuffled = build_cut(scene.subset(order), cams, 64, 2.0)
    assert shuffled.parent_count == cut.parent_count
    key = np.lexsort(cut.parents.means.T)
    key2 = np.lexsort(shuffled.parents.means.T)
    assert np.allclose(cut.parents.means[key], shuffled.parents.means[key2], atol=1e-5)
    assert f"{scene.count:,} Gaussians as {cut.parent_count:,} parents at 64 px" in cut.note
    finer = build_cut(scene, cams, 256, 2.0)
    assert finer.parent_count > cut.parent_count  # a finer width, a finer cut


def test_carry_back_re_merges_to_the_parents_new_colour():
    scene, cams = _dense_scene(1), _orbit()
    cut = build_cut(scene, cams, 64, 2.0)
    rng = np.random.default_rng(5)
    delta = rng.uniform(-0.1, 0.1, (cut.parent_count, 3))
    rows = cut.parents.with_sh_degree(0)
    rows.sh_dc = rgb_to_sh_dc(np.clip(cut.parents.rgb + delta, 0, 1)).astype(np.float32)
    out = expand_to_children(rows, delta, np.arange(cut.parent_count), cut, scene)
    assert out.count == scene.count  # every input Gaussian, once
    merged_children = np.flatnonzero(cut.merged[cut.child_parent])
    kids = out.subset(np.arange(out.count - len(merged_children), out.count))
    assert np.array_equal(kids.means, scene.means[merged_children])  # their own geometry
    assert np.abs(kids.sh_rest).max() == 0  # a stylized colour does not change with the view
    parent_of_kid = cut.child_parent[merged_children]
    ids, groups = np.unique(parent_of_kid, return_inverse=True)
    remerged, _ = merge_groups(kids, groups, len(ids))
    assert np.allclose(remerged.rgb, rows.rgb[ids], atol=1e-5)
    # each child keeps its own difference from its parent
    assert np.allclose(kids.rgb - rows.rgb[parent_of_kid], scene.rgb[merged_children] - cut.parents.rgb[parent_of_kid],
                       atol=1e-5)


def test_a_split_parents_children_take_their_nearest_descendants_change():
    scene, cams = _dense_scene(2), _orbit()
    cut = build_cut(scene, cams, 64, 2.0)
    p = int(np.flatnonzero(cut.merged)[0])
    rows = GaussianScene.concatenate([cut.parents.with_sh_degree(0), cut.parents.subset([p, p]).with_sh_degree(0)])
    rows.means[-2] += 5.0  # two descendants of p, one far off
    lineage = np.concatenate([np.arange(cut.parent_count), [p, p]])
    deltas = np.zeros((rows.count, 3))
    deltas[p] = 0.1
    deltas[-1] = 0.1
    deltas[-2] = -0.3
    out = expand_to_children(rows, deltas, lineage, cut, scene)
    kids = np.flatnonzero(cut.child_parent == p)
    pos = {tuple(m): i for i, m in enumerate(out.means)}
    for k in kids:
        got = out.rgb[pos[tuple(scene.means[k])]]
        assert np.allclose(got, np.clip(scene.rgb[k] + 0.1, 0, 1), atol=1e-5)


def test_a_region_is_never_merged_with_the_rest_and_its_outside_comes_back_exactly():
    scene, cams = _dense_scene(3), _orbit()
    selection = scene.means[:, 0] > 0
    cut = build_cut(scene, cams, 64, 2.0, selection)
    for p in np.flatnonzero(cut.merged):
        assert len(set(selection[cut.child_parent == p])) == 1
    assert np.array_equal(cut.parent_selection[cut.child_parent], selection)
    rows = cut.parents
    deltas = np.where(cut.parent_selection[:, None], 0.2, 0.0)
    out = expand_to_children(rows, deltas, np.arange(rows.count), cut, scene, selection)
    outside = np.flatnonzero(~selection & cut.merged[cut.child_parent])
    pos = {tuple(m): i for i, m in enumerate(out.means)}
    idx = [pos[tuple(scene.means[k])] for k in outside]
    assert np.array_equal(out.sh_dc[idx], scene.sh_dc[outside])
    assert np.array_equal(out.sh_rest[idx], scene.sh_rest[outside])  # SH bands included


def test_a_scene_with_nothing_below_the_cut_holds_every_gaussian():
    scene = _random_scene(50, seed=7, log_scale=-1.0)
    cut = build_cut(scene, _orbit(), 64, 2.0)
    assert not cut.merged.any() and cut.parent_count == scene.count
    assert np.array_equal(cut.parents.means, scene.means)
    with pytest.raises(ValueError, match="above 0 px"):
        build_cut(scene, _orbit(), 64, 0.0)
