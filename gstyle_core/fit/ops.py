"""Tensor operations that grow or shrink a Gaussian set while keeping Adam's state aligned.

Each operation takes the ``ParameterDict``, the per-parameter optimisers and an optional dict of extra per-Gaussian
tensors (accumulators, the stylized colour c_s, ...) and edits all of them consistently.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from ..raster.projection import quat_to_rotmat

Optimizers = dict[str, torch.optim.Optimizer]
FOOTPRINT_SIGMA = 3.0  # a Gaussian is drawn out to 3 σ (the rasterizer's screen radius, ``raster.projection``)
MAX_REDRAWS = 64  # draws of a child's offset before the last few are pulled onto the allowed ellipsoid


def child_offset_limit(scale_divisor: float) -> float:
    """How far (in the parent's σ, Mahalanobis) a child of scale σ / ``scale_divisor`` may sit from its parent's
    centre with its own footprint (``FOOTPRINT_SIGMA`` of its σ) inside the parent's: 3 (1 − 1 / divisor). Children
    drawn from the whole Gaussian land up to 3-4 σ out: a large faint Gaussian at a capture's fringe then puts
    children (and, after refits, colour) beyond where anything was, and the scene grows."""
    return FOOTPRINT_SIGMA * max(0.0, 1.0 - 1.0 / float(scale_divisor))


def truncated_normal(shape: tuple[int, ...], limit: float, generator: torch.Generator | None = None,
                     dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """Standard normal 3-vectors [..., 3] drawn again wherever their norm exceeds ``limit`` (the normal
    distribution restricted to that ball); after ``MAX_REDRAWS`` rounds any left (a tiny ``limit``) are scaled onto
    it."""
    noise = torch.randn(shape, generator=generator, dtype=dtype)
    for _ in range(MAX_REDRAWS):
        outside = noise.norm(dim=-1) > limit
        count = int(outside.sum())
        if count == 0:
            return noise
        noise[outside] = torch.randn((count, shape[-1]), generator=generator, dtype=dtype)
    norms = noise.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    return torch.where(norms > limit, noise * (limit / norms), noise)


def _edit(
    params: torch.nn.ParameterDict,
    optimizers: Optimizers,
    param_fn: Callable[[str, torch.Tensor], torch.Tensor],
    state_fn: Callable[[str, torch.Tensor], torch.Tensor],
) -> None:
    """Replace each parameter by ``param_fn(name, p)`` and each Adam moment by ``state_fn(key, moment)``."""
    for name in list(params.keys()):
        old = params[name]
        new = torch.nn.Parameter(param_fn(name, old.detach()), requires_grad=old.requires_grad)
        opt = optimizers.get(name)
        if opt is not None:
            group = opt.param_groups[0]
            st = opt.state.pop(old, None)
            if st:
                for key, val in list(st.items()):
                    if key != "step" and torch.is_tensor(val) and val.shape[:1] == old.shape[:1]:
                        st[key] = state_fn(key, val)
                opt.state[new] = st
            group["params"] = [new]
        params[name] = new


def remove(params: torch.nn.ParameterDict, optimizers: Optimizers, extras: dict[str, torch.Tensor],
           mask: torch.Tensor) -> None:
    """Remove the Gaussians where ``mask`` is True."""
    keep = ~mask
    _edit(params, optimizers, lambda _n, p: p[keep], lambda _k, v: v[keep])
    for k, v in extras.items():
        extras[k] = v[keep]


def duplicate(params: torch.nn.ParameterDict, optimizers: Optimizers, extras: dict[str, torch.Tensor],
              mask: torch.Tensor) -> None:
    """Append an exact copy of each Gaussian where ``mask`` is True (Adam moments of copies start at zero)."""
    sel = torch.where(mask)[0]
    _edit(params, optimizers, lambda _n, p: torch.cat([p, p[sel]]),
          lambda _k, v: torch.cat([v, torch.zeros_like(v[sel])]))
    for k, v in extras.items():
        extras[k] = torch.cat([v, v[sel]])


def split(
    params: torch.nn.ParameterDict,
    optimizers: Optimizers,
    extras: dict[str, torch.Tensor],
    mask: torch.Tensor,
    n_children: int = 2,
    scale_divisor: float = 1.6,
    generator: torch.Generator | None = None,
    max_offset: float | None = None,
) -> None:
    """Replace each Gaussian where ``mask`` is True by ``n_children`` samples of itself.

    Children are placed at points drawn from the parent's own Gaussian (with ``max_offset``: within that many of its
    σ from its centre, Mahalanobis; ``child_offset_limit`` keeps every child's footprint inside its parent's, so
    such a split never grows the scene), their scales are the parent's divided by ``scale_divisor`` (i.e.
    ``log(scale_divisor)`` less in log space); everything else (colours, opacity, rotation and every extra such as
    c_s) is inherited.
    """
    sel = torch.where(mask)[0]
    if len(sel) == 0:
        return
    rest = torch.where(~mask)[0]
    scales = torch.exp(params["log_scales"].detach()[sel])
    rot = quat_to_rotmat(params["quats"].detach()[sel])
    if max_offset is None:
        noise = torch.randn((n_children, len(sel), 3), generator=generator, dtype=scales.dtype)
    else:
        noise = truncated_normal((n_children, len(sel), 3), max_offset, generator, scales.dtype)
    offsets = torch.einsum("nij,cnj->cni", rot, scales[None] * noise)
    log_div = math.log(scale_divisor)

    def child(name: str, p: torch.Tensor) -> torch.Tensor:
        parent = p[sel]
        if name == "means":
            kids = (parent[None] + offsets).reshape(-1, 3)
        elif name == "log_scales":
            kids = (parent - log_div).repeat(n_children, 1)
        else:
            kids = parent.repeat((n_children,) + (1,) * (p.dim() - 1))
        return torch.cat([p[rest], kids])

    def moment(_k: str, v: torch.Tensor) -> torch.Tensor:
        return torch.cat([v[rest], torch.zeros((n_children * len(sel),) + v.shape[1:], dtype=v.dtype)])

    _edit(params, optimizers, child, moment)
    for k, v in extras.items():
        extras[k] = torch.cat([v[rest], v[sel].repeat((n_children,) + (1,) * (v.dim() - 1))])
