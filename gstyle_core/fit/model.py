"""A trainable Gaussian model: parameters as a ``ParameterDict`` so that strategies can grow and prune it."""

from __future__ import annotations

import numpy as np
import torch

from ..cameras.camera import Camera
from ..scene import GaussianScene

PARAM_NAMES = ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest")


def camera_tensors(camera: Camera, device: torch.device | str = "cpu") -> tuple[torch.Tensor, torch.Tensor]:
    """World-to-camera matrix and intrinsics of ``camera`` as float32 tensors."""
    viewmat = torch.as_tensor(np.asarray(camera.world_to_cam, np.float32), device=device)
    K = torch.as_tensor(camera.K.astype(np.float32), device=device)
    return viewmat, K


def params_from_scene(scene: GaussianScene, requires_grad: bool = True) -> torch.nn.ParameterDict:
    """Turn a ``GaussianScene`` into trainable float32 parameters."""
    arrays = {
        "means": scene.means,
        "log_scales": scene.log_scales,
        "quats": scene.quats,
        "opacity_logits": scene.opacity_logits,
        "sh_dc": scene.sh_dc,
        "sh_rest": scene.sh_rest,
    }
    return torch.nn.ParameterDict(
        {k: torch.nn.Parameter(torch.as_tensor(np.ascontiguousarray(v, np.float32)), requires_grad=requires_grad)
         for k, v in arrays.items()}
    )


def scene_from_params(params: torch.nn.ParameterDict) -> GaussianScene:
    """Copy trainable parameters back into a ``GaussianScene``."""
    get = {k: params[k].detach().cpu().numpy().astype(np.float32).copy() for k in PARAM_NAMES}
    return GaussianScene(get["means"], get["log_scales"], get["quats"], get["opacity_logits"], get["sh_dc"],
                         get["sh_rest"])


def render_params(
    params: torch.nn.ParameterDict,
    camera: Camera,
    *,
    sh_degree: int = 0,
    colors: torch.Tensor | None = None,
    background: torch.Tensor | None = None,
    backend: str = "fast",
    device: torch.device | str | None = None,
):
    """Render the Gaussians in ``params`` from ``camera``.

    ``colors`` ([N, 3] RGB) replaces the SH colour when given (the stylized colour c_s);
    otherwise SH up to ``sh_degree`` is evaluated (degree 0 = diffuse colour only).
    ``device``: where to render (default: the parameters' device); the parameters are copied there inside the
    autograd graph, so their gradients come back to them. The outputs are on ``device``.
    """
    from ..raster import rasterize

    device = params["means"].device if device is None else torch.device(device)
    params = {k: v.to(device) for k, v in params.items()}
    if colors is not None:
        colors = colors.to(device)
    viewmat, K = camera_tensors(camera, device)
    if colors is None:
        k_rest = (sh_degree + 1) ** 2 - 1
        k_rest = min(k_rest, params["sh_rest"].shape[1])
        sh = torch.cat([params["sh_dc"][:, None, :], params["sh_rest"][:, :k_rest, :]], dim=1)
        degree = int(round((sh.shape[1]) ** 0.5)) - 1
        color_arg, deg_arg = sh, degree
    else:
        color_arg, deg_arg = colors, None
    return rasterize(
        params["means"],
        params["quats"],
        torch.exp(params["log_scales"]),
        torch.sigmoid(params["opacity_logits"]),
        color_arg,
        viewmat,
        K,
        camera.width,
        camera.height,
        background=background,
        sh_degree=deg_arg,
        backend=backend,
    )
