"""A stylization's splits never grow the scene (issue #50 item 4): each child is drawn from its parent's Gaussian
inside the parent's footprint (``ops.child_offset_limit``), so large faint Gaussians at a capture's fringe split into
children that stay where the parent was drawn."""

from __future__ import annotations

import numpy as np
import torch
from test_pipeline import MeanColourObjective

from gstyle_core.cameras.framing import extent_growth
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.fit import ops
from gstyle_core.raster.projection import quat_to_rotmat
from gstyle_core.scene import GaussianScene, logit
from tests.synthetic import blob_scene, ring_cameras


def fringed_scene(core: int = 200, fringe: int = 60, seed: int = 4) -> GaussianScene:
    """A blob of small Gaussians with a ring of large faint ones around it (a capture fading out at its edge)."""
    scene = blob_scene(core, seed=seed, spread=0.4)
    ring = blob_scene(fringe, seed=seed + 1)
    angles = np.linspace(0, 2 * np.pi, fringe, endpoint=False)
    ring.means[:] = np.stack([1.5 * np.cos(angles), np.zeros(fringe), 1.5 * np.sin(angles)], axis=1)
    ring.log_scales[:] = np.log([0.5, 0.3, 0.4]).astype(np.float32)
    ring.opacity_logits[:] = logit(np.full(fringe, 0.05)).astype(np.float32)
    return GaussianScene.concatenate([scene, ring])


def test_children_stay_inside_their_parents_footprint():
    scene = fringed_scene()
    settings = resolve_settings("balanced", "360", 4, working_width=32, refit_iterations=1, refine_widths=())
    eng = Stylizer(scene, ring_cameras(4), np.ones((8, 8, 3), np.float32), settings,
                   objective_factory=MeanColourObjective)
    run = eng.run_state
    for children, divisor in ((8, 6.4), (4, 8.0)):  # the pre-processing's split, the colour-gradient split's
        before = run.params["means"].detach().clone()
        mask = torch.zeros(run.gaussian_count, dtype=torch.bool)
        mask[-60:] = True  # the fringe Gaussians (the last rows: children are appended)
        parents = {k: v.detach()[mask].clone() for k, v in run.params.items()}
        run.split(mask, children, divisor)
        kids = run.params["means"].detach()[-children * 60:].reshape(children, 60, 3)
        rot = quat_to_rotmat(parents["quats"])  # [60, 3, 3], columns: the parent's axes
        local = torch.einsum("nji,cnj->cni", rot, kids - parents["means"][None])
        mahalanobis = (local / torch.exp(parents["log_scales"])[None]).norm(dim=-1)
        limit = ops.child_offset_limit(divisor)
        assert limit == 3 * (1 - 1 / divisor)
        assert float(mahalanobis.max()) <= limit + 1e-4  # the child's 3 σ (σ / divisor) inside the parent's 3 σ
        assert float(mahalanobis.mean()) > 0.3 * limit  # drawn over the parent's Gaussian, not piled on its centre
        reach = max(float(np.linalg.norm(p)) for p in parents["means"].numpy()) + limit * 0.5  # parents' largest σ
        assert float(run.params["means"].detach().norm(dim=-1).max()) <= reach + 1e-4
        growth = extent_growth(before.numpy(), run.params["means"].detach().numpy())
        assert growth["max_distance"] <= reach / float(before.norm(dim=-1).max()) + 1e-4


def test_the_truncated_draw_is_a_normal_restricted_to_the_ball():
    g = torch.Generator().manual_seed(0)
    z = ops.truncated_normal((20000, 3), 2.0, g)
    norms = z.norm(dim=-1)
    assert float(norms.max()) <= 2.0 and abs(float(z.mean())) < 0.02
    # restricted to the ball of radius 2: P(|z| <= 1 given |z| <= 2) = P(chi3 <= 1) / P(chi3 <= 2) = 0.1987 / 0.7385
    assert abs(float((norms <= 1).double().mean()) - 0.1987 / 0.7385) < 0.015
    assert float(ops.truncated_normal((5, 3), 1e-9, g).norm(dim=-1).max()) <= 1e-9 * (1 + 1e-6)
