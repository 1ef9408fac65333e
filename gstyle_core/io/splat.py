"""antimatter15 ``.splat``: 32 bytes per Gaussian, little-endian, no header.

Record: position f32 x3, scale f32 x3 (linear std-devs), colour RGBA u8 x4 (rgb = 0.5 + C0 * sh_dc,
a = sigmoid(opacity)), rotation u8 x4 (w, x, y, z), each byte = clip(round(q * 128 + 128), 0, 255) of the
unit quaternion.

Round-trip tolerance (what ``save_scene(..., fmt="splat")`` loses): positions are exact; log-scales within
float32 exp/log error (~1e-6 relative); colours within 0.5/255 after clipping to [0, 1]; opacity within
0.5/255 after clipping to [1e-6, 1 - 1e-6]; each quaternion component within 0.5/128 before
renormalisation (a rotation error of at most ~1 degree); SH degree > 0 is dropped.
"""

from __future__ import annotations

from typing import IO

import numpy as np

from ..errors import SceneFormatError
from ..scene import GaussianScene, logit, rgb_to_sh_dc, sh_dc_to_rgb, sigmoid
from .validate import log_of_linear_scales

RECORD = np.dtype([("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rot", "u1", 4)])
assert RECORD.itemsize == 32


def read_splat(data: bytes, name: str) -> tuple[GaussianScene, int, list[str], list[str]]:
    """Decode a .splat file; returns scene, count, repairs (scale clamps) and warnings."""
    if len(data) % RECORD.itemsize:
        raise SceneFormatError(
            f"{name}: .splat size {len(data):,} is not a multiple of 32 bytes "
            f"(truncated or not a .splat file)"
        )
    rec = np.frombuffer(data, RECORD)
    log_scales, clamped = log_of_linear_scales(rec["scale"])
    repairs = [f"clamped {clamped:,} zero/negative scales to 1e-7"] if clamped else []
    quats = (rec["rot"].astype(np.float32) - 128.0) / 128.0
    norms = np.linalg.norm(quats, axis=1, keepdims=True)
    quats = np.divide(
        quats, norms, out=np.zeros_like(quats), where=norms > 0
    )  # zero stays zero: validate fixes it
    rgba = rec["rgba"].astype(np.float32) / 255.0
    scene = GaussianScene(
        means=rec["position"].astype(np.float32),
        log_scales=log_scales,
        quats=quats.astype(np.float32),
        opacity_logits=logit(rgba[:, 3]),
        sh_dc=rgb_to_sh_dc(rgba[:, :3]),
        sh_rest=np.zeros((len(rec), 0, 3), np.float32),
    )
    return scene, len(rec), repairs, []


def encode_splat(scene: GaussianScene) -> bytes:
    """Quantise a scene to .splat records (SH beyond degree 0 is dropped)."""
    rec = np.zeros(scene.count, RECORD)
    rec["position"] = scene.means
    rec["scale"] = scene.scales
    rgb = np.clip(sh_dc_to_rgb(scene.sh_dc), 0.0, 1.0)
    alpha = sigmoid(scene.opacity_logits)
    rec["rgba"][:, :3] = np.round(rgb * 255.0)
    rec["rgba"][:, 3] = np.round(np.clip(alpha, 0.0, 1.0) * 255.0)
    q = scene.quats.astype(np.float64)
    norms = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.divide(q, norms, out=np.tile([1.0, 0.0, 0.0, 0.0], (len(q), 1)), where=norms > 0)
    rec["rot"] = np.clip(np.round(q * 128.0 + 128.0), 0, 255)
    return rec.tobytes()


def write_splat(fh: IO[bytes], scene: GaussianScene) -> None:
    """Write the .splat records to an open binary file."""
    fh.write(encode_splat(scene))


def looks_like_splat(data: bytes) -> bool:
    """Content sniffing for header-less data: size a multiple of 32 and the first records plausible."""
    if not data or len(data) % RECORD.itemsize:
        return False
    rec = np.frombuffer(data, RECORD, min(len(data) // RECORD.itemsize, 1024))
    with np.errstate(invalid="ignore", over="ignore"):
        finite = np.isfinite(rec["position"]).all() and np.isfinite(rec["scale"]).all()
        q = (rec["rot"].astype(np.float32) - 128.0) / 128.0
        unit = np.abs(np.linalg.norm(q, axis=1) - 1.0) < 0.05
    return bool(finite and (rec["scale"] >= 0).mean() > 0.99 and unit.mean() > 0.9)
