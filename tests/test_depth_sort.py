"""The viewer's depth sort (app/depth_sort.py): exact up to key quantisation, and its thread (newest view only,
never blocking the caller, clean stop)."""

import threading
from pathlib import Path

import numpy as np
import pytest
from fakes import GatedSort

from app.depth_sort import DepthSorter, SortRequest, depth_order, key_bits
from app.splat_data import back_to_front_order

BIKER = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes" / "playcanvas" / "biker.spz"
NEAR = 0.01


def view_matrix(eye, target) -> np.ndarray:
    from gstyle_core.cameras.generate import look_at

    return look_at(np.asarray(eye, np.float64), np.asarray(target, np.float64), np.array([0.0, -1.0, 0.0]))


def assert_back_to_front_up_to_a_bucket(order, means, view, bits, near=NEAR):
    """Same Gaussians as the exact order; every pair more than one bucket apart in depth is in exact order."""
    z = np.asarray(means, np.float64) @ view[2, :3] + view[2, 3]
    exact = back_to_front_order(means, view, near)
    assert np.array_equal(np.sort(order), np.sort(exact))  # near-plane (and non-finite) culling as before
    zs = z[order]
    width = (zs.max() - zs.min()) / ((1 << bits) - 1)
    slack = width + 4 * np.spacing(np.float32(np.abs(zs).max()))  # depths are float32 inside the kernel
    nearest_before = np.minimum.accumulate(zs)  # the order runs from far to near:
    assert np.all(zs[1:] - nearest_before[:-1] <= slack)  # nothing later is farther by more than a bucket
    return zs


@pytest.mark.parametrize("bits", [10, 16, 20])
def test_random_depths_are_ordered_up_to_one_bucket(bits):
    rng = np.random.default_rng(bits)
    means = rng.normal(0, 2.0, (20_000, 3)).astype(np.float32)
    means[::97] = np.nan  # non-finite Gaussians are left out, as before
    view = view_matrix((0.5, -0.3, -4.0), (0, 0, 0))
    order = depth_order(means, view, NEAR, bits)
    zs = assert_back_to_front_up_to_a_bucket(order, means, view, bits)
    assert (zs <= NEAR).sum() == 0 and len(order) < 20_000  # some were behind the near plane
    if bits == 10:  # coarse keys really do swap close pairs (so the check above can fail)
        assert np.sum(np.diff(zs) > 0) > 0


def test_distinct_buckets_give_the_exact_order_and_ties_keep_the_input_order():
    rng = np.random.default_rng(1)
    means = rng.normal(0, 1, (3000, 3)).astype(np.float32)
    means[:, 2] = rng.permutation(3000).astype(np.float32) * 0.5 + 1.0  # depths 0.5 apart, bucket 1/45 of that
    view = np.eye(4)
    assert np.array_equal(depth_order(means, view, NEAR, 16), back_to_front_order(means, view, NEAR))
    same = np.zeros((5, 3), np.float32) + [0, 0, 2]  # one depth: input order (the sort is stable)
    assert depth_order(same, view, NEAR).tolist() == [0, 1, 2, 3, 4]


def test_subset_sorts_only_those_gaussians():
    rng = np.random.default_rng(2)
    means = rng.normal(0, 1, (5000, 3)).astype(np.float32) + [0, 0, 3]
    subset = rng.choice(5000, 800, replace=False).astype(np.int32)
    view = np.eye(4)
    order = depth_order(means, view, NEAR, 16, subset)
    assert set(order.tolist()) <= set(subset.tolist())
    exact = subset[back_to_front_order(means[subset], view, NEAR)]
    assert np.array_equal(np.sort(order), np.sort(exact))
    z = means[order, 2].astype(np.float64)
    assert np.all(z[1:] - np.minimum.accumulate(z)[:-1] <= (z.max() - z.min()) / 65535 + 1e-6)


def test_nothing_in_front_and_key_bits_from_the_count():
    means = np.array([[0, 0, -1.0], [0, 0, 0.001]], np.float32)
    assert depth_order(means, np.eye(4), NEAR).size == 0
    assert depth_order(np.zeros((0, 3), np.float32), np.eye(4), NEAR).size == 0
    assert [key_bits(n) for n in (100, 200_000, 1_200_000, 6_000_000)] == [10, 16, 18, 20]
    with pytest.raises(ValueError, match="key bits"):
        depth_order(means, np.eye(4), NEAR, 24)


@pytest.mark.skipif(not BIKER.is_file(), reason="shared/data playcanvas/biker.spz absent")
def test_real_capture_depths_are_ordered_up_to_one_bucket():
    from gstyle_core.cameras.generate import finite_points, robust_centre_radius
    from gstyle_core.io import load_scene

    scene, _ = load_scene(BIKER)
    centre, radius = robust_centre_radius(finite_points(scene.means))
    for k, angle in enumerate(np.linspace(0, 2 * np.pi, 4, endpoint=False)):
        eye = centre + radius * np.array([1.5 * np.sin(angle), -0.3, 1.5 * np.cos(angle)])
        view = view_matrix(eye, centre)
        bits = (16, key_bits(scene.count))[k % 2]
        assert_back_to_front_up_to_a_bucket(depth_order(scene.means, view, NEAR, bits), scene.means, view, bits)


def request(key, means, z_offset=0.0) -> SortRequest:
    return SortRequest(key, means, np.array([0.0, 0.0, 1.0, z_offset]), NEAR)


def test_only_the_newest_pending_view_is_sorted_and_submit_never_blocks():
    means = np.random.default_rng(3).normal(0, 1, (1000, 3)).astype(np.float32) + [0, 0, 3]
    sort = GatedSort()
    sorter = DepthSorter(sort)
    sorter.submit(request("a", means))
    assert sort.started.wait(30)  # the thread is inside sort "a", held at the gate
    submitter = threading.Thread(target=lambda: [sorter.submit(request(k, means, 0.1 * i))
                                                 for i, k in enumerate("bcd")])
    submitter.start()
    submitter.join(10)
    assert not submitter.is_alive()  # three submits returned while a sort was running
    assert sorter.take() is None  # nothing finished yet
    sort.gate.set()
    assert sorter.idle(30)
    assert sort.keys == ["a", "d"]  # b and c were replaced before they started
    assert (sorter.stats.submitted, sorter.stats.sorted, sorter.stats.dropped) == (4, 2, 2)
    result = sorter.take()
    assert result.key == "d" and np.array_equal(result.order, depth_order(means, request("d", means, 0.2).view_row,
                                                                          NEAR))
    assert sorter.take() is None  # taken once
    sorter.stop()
    assert not sorter.running


def test_wait_returns_the_named_order_and_stop_ends_a_running_sort_cleanly():
    means = np.random.default_rng(4).normal(0, 1, (500, 3)).astype(np.float32) + [0, 0, 3]
    sorter = DepthSorter()
    sorter.submit(request(1, means))
    result = sorter.wait(1, timeout=30)
    assert result is not None and result.key == 1 and result.order.size == 500
    sort = GatedSort()
    gated = DepthSorter(sort)
    gated.submit(request(2, means))
    assert sort.started.wait(30)
    stopper = threading.Thread(target=gated.stop)
    stopper.start()
    sort.gate.set()  # the running sort finishes, then the thread ends
    stopper.join(30)
    assert not stopper.is_alive() and not gated.running
    with pytest.raises(RuntimeError, match="stopped"):
        gated.submit(request(3, means))
    sorter.stop()
    assert not sorter.running


def test_a_failed_sort_is_reported_to_the_caller():
    def broken(request, scratch):
        raise ValueError("bad means")

    sorter = DepthSorter(broken)
    sorter.submit(request("x", np.zeros((3, 3), np.float32)))
    with pytest.raises(RuntimeError, match="depth sort failed: bad means"):
        sorter.wait("x", timeout=30)
    sorter.stop()
