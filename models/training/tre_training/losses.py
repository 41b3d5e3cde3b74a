"""Training losses: masked L1, SSIM (as monodepth computes it, 3×3 windows), scale-invariant and
gradient-matching depth terms, and normal angles."""

from __future__ import annotations

import torch
from torch import Tensor
from torch.nn import functional as F

SSIM_C1 = 0.01**2
SSIM_C2 = 0.03**2


def masked_mean(x: Tensor, mask: Tensor) -> Tensor:
    """Mean of `x` over `mask` (same shape, bool); 0 when the mask is empty."""
    m = mask.to(x.dtype)
    return (x * m).sum() / torch.clamp(m.sum(), min=1.0)


def ssim(x: Tensor, y: Tensor) -> Tensor:
    """Per-pixel SSIM of two N×1×H×W maps over 3×3 windows (reflect padding), in [−1, 1]."""
    x = F.pad(x, (1, 1, 1, 1), mode="reflect")
    y = F.pad(y, (1, 1, 1, 1), mode="reflect")
    mx, my = F.avg_pool2d(x, 3, 1), F.avg_pool2d(y, 3, 1)
    sx = F.avg_pool2d(x * x, 3, 1) - mx * mx
    sy = F.avg_pool2d(y * y, 3, 1) - my * my
    sxy = F.avg_pool2d(x * y, 3, 1) - mx * my
    num = (2 * mx * my + SSIM_C1) * (2 * sxy + SSIM_C2)
    den = (mx * mx + my * my + SSIM_C1) * (sx + sy + SSIM_C2)
    return num / den


def depth_loss(pred_m: Tensor, gt_m: Tensor) -> Tensor:
    """L1 + 0.5 · SSIM on log depth (so near and far ground weigh alike), plus a scale-invariant
    term and a gradient-matching term, over pixels with ground truth:
    `|δ| + 0.5 · (1 − SSIM)/2 + 0.5 · SI(δ) + 0.5 · G(δ)` with `δ = log d − log d*`,
    `SI = mean δ² − 0.85 · (mean δ)²` per image (Eigen et al.) and `G` the mean absolute
    horizontal and vertical difference of δ over neighbouring valid pixels, at full and half
    resolution (MegaDepth's gradient loss): relative depth, and steps, right."""
    valid = torch.isfinite(gt_m) & (gt_m > 0)
    lg = torch.log(torch.where(valid, gt_m, torch.ones_like(gt_m)))
    lp = torch.log(torch.clamp(pred_m, min=1e-3))
    lp_filled = torch.where(valid, lp, lg)
    delta = lp - lg
    l1 = masked_mean(delta.abs(), valid)
    s = masked_mean((1 - ssim(lp_filled, lg)) / 2, valid)
    return l1 + 0.5 * (s + scale_invariant(delta, valid) + gradient_match(delta, valid))


def scale_invariant(delta: Tensor, valid: Tensor) -> Tensor:
    """Eigen's scale-invariant log error (λ = 0.85), averaged over the images of a batch."""
    m = valid.to(delta.dtype)
    d = torch.where(valid, delta, torch.zeros_like(delta))
    n = torch.clamp(m.sum((1, 2, 3)), min=1.0)
    mean = d.sum((1, 2, 3)) / n
    mean_sq = (d * d).sum((1, 2, 3)) / n
    return (mean_sq - 0.85 * mean * mean).mean()


def gradient_match(delta: Tensor, valid: Tensor, scales: int = 2) -> Tensor:
    """Mean absolute spatial difference of the log-depth error over pairs of valid pixels,
    summed over `scales` resolutions (halved by 2×2 subsampling)."""
    total = delta.new_zeros(())
    d, v = torch.where(valid, delta, torch.zeros_like(delta)), valid
    for _ in range(scales):
        vx = v[..., :, 1:] & v[..., :, :-1]
        vy = v[..., 1:, :] & v[..., :-1, :]
        gx = (d[..., :, 1:] - d[..., :, :-1]).abs()
        gy = (d[..., 1:, :] - d[..., :-1, :]).abs()
        total = total + masked_mean(gx, vx) + masked_mean(gy, vy)
        d, v = d[..., ::2, ::2], v[..., ::2, ::2]
    return total


def angle_deg(pred: Tensor, gt: Tensor) -> Tensor:
    """Per-pixel angle (degrees) between N×3×H×W unit normals."""
    cos = (pred * gt).sum(1).clamp(-1.0, 1.0)
    return torch.rad2deg(torch.acos(cos))


def normal_loss(pred: Tensor, gt: Tensor, valid: Tensor) -> Tensor:
    """Mean angle in radians (the paper's consistency loss) over valid pixels with ground truth;
    `acos` is clamped away from ±1 so the gradient stays finite."""
    ok = valid[:, 0] > 0.5
    ok = ok & torch.isfinite(gt).all(1)
    g = torch.where(torch.isfinite(gt), gt, torch.zeros_like(gt))
    cos = (pred * g).sum(1).clamp(-1.0 + 1e-6, 1.0 - 1e-6)
    return masked_mean(torch.acos(cos), ok)


def roughness_l1(pred_m: Tensor, gt_m: Tensor, valid: Tensor) -> Tensor:
    """L1 on roughness (metres, reported ×100 as cm for readable numbers) over pixels with both a
    point and ground truth."""
    ok = (valid > 0.5) & torch.isfinite(gt_m)
    g = torch.where(torch.isfinite(gt_m), gt_m, torch.zeros_like(gt_m))
    return masked_mean((pred_m - g).abs() * 100.0, ok)
