"""Camera geometry in PyTorch, as serving does it in `crates/tre-core/src/geometry` (batched, NCHW).

Points are camera-frame metres (OpenCV: x right, y down, z forward); invalid points are 0 with
`valid = 0` beside them, since NaN cannot flow through a network.
"""

from __future__ import annotations

import torch
from torch import Tensor

MAX_PRIOR_DEPTH_M = 20.0
"""Flat-ground prior depth where the ray misses the ground (at or above the horizon)."""


def pixel_rays(intrinsics: Tensor, height: int, width: int) -> Tensor:
    """N×3×H×W rays `((u − cx)/fx, (v − cy)/fy, 1)` for N×4 intrinsics (fx, fy, cx, cy)."""
    n = intrinsics.shape[0]
    dev, dt = intrinsics.device, intrinsics.dtype
    u = torch.arange(width, device=dev, dtype=dt).view(1, 1, width)
    v = torch.arange(height, device=dev, dtype=dt).view(1, height, 1)
    fx, fy, cx, cy = (intrinsics[:, i].view(n, 1, 1) for i in range(4))
    x = ((u - cx) / fx).expand(n, height, width)
    y = ((v - cy) / fy).expand(n, height, width)
    return torch.stack([x, y, torch.ones_like(x)], dim=1)


def back_project(depth_m: Tensor, intrinsics: Tensor) -> tuple[Tensor, Tensor]:
    """Points (N×3×H×W) and validity (N×1×H×W, 0/1) from N×1×H×W depth (≤ 0 or NaN: none)."""
    valid = torch.isfinite(depth_m) & (depth_m > 0)
    d = torch.where(valid, depth_m, torch.zeros_like(depth_m))
    rays = pixel_rays(intrinsics, depth_m.shape[2], depth_m.shape[3])
    return rays * d, valid.to(depth_m.dtype)


def prior_depth(intrinsics: Tensor, mounting: Tensor, height: int, width: int) -> Tensor:
    """Depth of flat ground seen by a camera at `mounting` (N×2: pitch rad down, height m).

    The gravity-down direction in the camera frame is `(0, cos β, sin β)`, so the ray through
    pixel (u, v) meets the ground at `z = h / (y·cos β + sin β)` with `y = (v − cy)/fy`; where
    that is not positive or exceeds `MAX_PRIOR_DEPTH_M`, `MAX_PRIOR_DEPTH_M`. Serving's
    `pipeline::prior_depth` computes the same map.
    """
    rays = pixel_rays(intrinsics, height, width)
    n = mounting.shape[0]
    pitch = mounting[:, 0].view(n, 1, 1)
    cam_h = mounting[:, 1].view(n, 1, 1)
    down = rays[:, 1] * torch.cos(pitch) + torch.sin(pitch)
    z = cam_h / torch.clamp(down, min=1e-6)
    z = torch.where((down > 0) & (z < MAX_PRIOR_DEPTH_M), z, torch.full_like(z, MAX_PRIOR_DEPTH_M))
    return z.unsqueeze(1)


def unfold7(x: Tensor, fill: float = 0.0) -> Tensor:
    """N×C×H×W → N×C×49×H×W: the 7×7 window of every pixel, candidate k = (dy+3)·7 + (dx+3),
    `fill` outside the image."""
    _n, _c, h, w = x.shape
    padded = torch.nn.functional.pad(x, (3, 3, 3, 3), value=fill)
    cols = [padded[:, :, dy : dy + h, dx : dx + w] for dy in range(7) for dx in range(7)]
    return torch.stack(cols, dim=2)
