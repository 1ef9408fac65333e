"""The one place where every loader's output is checked and repaired.

Every reader in ``gstyle_core.io`` decodes its format into a ``GaussianScene`` and then calls
``validate_and_repair``. The rules, applied in this order, are:

1. **Drop**: a Gaussian whose mean, log-scale or quaternion holds NaN or +/-inf is removed
   (there is no sensible value to put there). The count is returned as ``dropped``.
2. **Zero non-finite appearance**: NaN/inf in ``sh_dc`` or ``sh_rest`` becomes 0 (SH 0 = grey 0.5 for the
   DC term, no view dependence for the rest). A NaN opacity logit becomes 0 (opacity 0.5).
3. **Clamp log-scales** to ``[log(1e-7), log(1e4)]`` (std-devs between 1e-7 and 1e4 scene units):
   smaller values underflow the covariance in float32, larger ones cover any real scene many times.
4. **Quaternions**: an all-zero (norm < 1e-8) quaternion becomes the identity (1, 0, 0, 0); one whose norm
   differs from 1 by more than 1e-5 is divided by its norm. Already-unit quaternions are left bit-for-bit
   untouched, so a load -> save -> load round trip is exact.
5. **Clamp opacity logits** to ``[-40, 40]`` (sigmoid is exactly 0 or 1 in float32 beyond that; +/-inf becomes
   +/-40, the same convention PlayCanvas uses for alpha 0 and 1).

Formats that store *linear* scales (``.splat``) convert them with ``log_of_linear_scales``, which clamps
zero, negative or non-finite-small scales up to 1e-7 before the log (rule 3's lower bound) and reports them.

Each rule that changes something adds one short string with a count to the returned ``repairs`` list.
"""

from __future__ import annotations

import numpy as np

from ..scene import GaussianScene

MIN_SCALE = 1e-7
MAX_SCALE = 1e4
LOG_SCALE_MIN = float(np.float32(np.log(MIN_SCALE)))  # exact in float32
LOG_SCALE_MAX = float(np.float32(np.log(MAX_SCALE)))
OPACITY_LOGIT_LIMIT = 40.0
QUAT_ZERO_NORM = 1e-8
QUAT_NORM_TOLERANCE = 1e-5


def log_of_linear_scales(scales: np.ndarray) -> tuple[np.ndarray, int]:
    """Natural log of linear std-devs; values <= 1e-7 (zero, negative) are clamped up first.

    Returns the log-scales (float32) and how many values were clamped. NaN stays NaN (rule 1 drops it).
    """
    s = np.asarray(scales, np.float64)
    too_small = s < MIN_SCALE  # NaN compares False and is left for the drop rule
    clamped = np.where(too_small, MIN_SCALE, s)
    with np.errstate(over="ignore", invalid="ignore"):
        return np.log(clamped).astype(np.float32), int(too_small.sum())


def validate_and_repair(scene: GaussianScene) -> tuple[GaussianScene, list[str], int]:
    """Apply the module's rules; return the repaired scene, repair descriptions and the dropped count."""
    repairs: list[str] = []
    finite_geometry = (
        np.isfinite(scene.means).all(axis=1)
        & np.isfinite(scene.log_scales).all(axis=1)
        & np.isfinite(scene.quats).all(axis=1)
    )
    dropped = int((~finite_geometry).sum())
    if dropped:
        scene = scene.subset(finite_geometry)
        repairs.append(f"dropped {dropped:,} Gaussians with NaN/inf position, scale or rotation")
    else:
        scene = scene.subset(slice(None))  # work on copies, never on the caller's arrays

    bad_sh = ~np.isfinite(scene.sh_dc).all(axis=1)
    if scene.sh_rest.size:
        bad_sh |= ~np.isfinite(scene.sh_rest).all(axis=(1, 2))
    if bad_sh.any():
        scene.sh_dc[~np.isfinite(scene.sh_dc)] = 0.0
        scene.sh_rest[~np.isfinite(scene.sh_rest)] = 0.0
        repairs.append(f"set NaN/inf colour/SH coefficients to 0 in {int(bad_sh.sum()):,} Gaussians")

    nan_opacity = np.isnan(scene.opacity_logits)
    if nan_opacity.any():
        scene.opacity_logits[nan_opacity] = 0.0
        repairs.append(f"set {int(nan_opacity.sum()):,} NaN opacities to 0.5")

    out_of_range = (scene.log_scales < LOG_SCALE_MIN) | (scene.log_scales > LOG_SCALE_MAX)
    if out_of_range.any():
        np.clip(scene.log_scales, LOG_SCALE_MIN, LOG_SCALE_MAX, out=scene.log_scales)
        repairs.append(f"clamped scales of {int(out_of_range.any(axis=1).sum()):,} Gaussians to [1e-7, 1e4]")

    norms = np.sqrt(np.square(scene.quats.astype(np.float64)).sum(axis=1))
    zero = norms < QUAT_ZERO_NORM
    if zero.any():
        scene.quats[zero] = (1.0, 0.0, 0.0, 0.0)
        repairs.append(f"replaced {int(zero.sum()):,} zero quaternions with the identity")
    off_unit = ~zero & (np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE)
    if off_unit.any():
        scene.quats[off_unit] = (scene.quats[off_unit] / norms[off_unit, None]).astype(np.float32)
        repairs.append(f"renormalised {int(off_unit.sum()):,} quaternions")

    extreme = np.abs(scene.opacity_logits) > OPACITY_LOGIT_LIMIT
    if extreme.any():
        np.clip(scene.opacity_logits, -OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT, out=scene.opacity_logits)
        repairs.append(f"clamped {int(extreme.sum()):,} opacity logits to [-40, 40]")
    return scene, repairs, dropped
