"""The four learned stages of TRENet (Fig. 5) and the end-to-end baseline, in PyTorch.

All five share one backbone, `ResUNet`: the GeoNet-R-like residual U-Net of Fig. 5b (residual
blocks of two 3×3 conv + batch norm + LeakyReLU(0.2)), made light enough for 2 CPU cores: widths
8-16-24-32-48 at strides 1-2-4-8-16, the decoder stops at half resolution and a full-resolution
1×1 fusion with the stem's features brings the detail back. Inputs are normalised inside the
graph, so the ONNX files take raw values: `rgb` in [0, 1], points in metres, `valid` 0/1.

Spatial sizes must be multiples of `STRIDE`.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch.nn import functional as F

STRIDE = 16
"""H and W must be multiples of this."""
WIDTHS = (8, 16, 24, 32, 48)
"""Channels at strides 1, 2, 4, 8, 16."""
RGB_MEAN = 0.45
RGB_STD = 0.25
POINT_SCALE_M = 4.0
"""Points are divided by this before they enter a net."""
DETAIL_GAIN = 20.0
"""Local point deviations (metres) are multiplied by this (5 cm → 1)."""
CENTROID_STEP_M = 0.05
"""The centroid net's output unit, metres."""
ROUGHNESS_STEP_M = 0.02
"""The end-to-end baseline's output unit, metres."""


class ConvBlock(nn.Sequential):
    """3×3 conv (no bias) + batch norm + LeakyReLU(0.2)."""

    def __init__(self, cin: int, cout: int, stride: int = 1) -> None:
        super().__init__(
            nn.Conv2d(cin, cout, 3, stride, 1, bias=False),
            nn.BatchNorm2d(cout),
            nn.LeakyReLU(0.2),
        )


class ResBlock(nn.Module):
    """Two conv blocks with a residual connection from the block's input to its output."""

    def __init__(self, cin: int, cout: int, stride: int = 1) -> None:
        super().__init__()
        self.body = nn.Sequential(ConvBlock(cin, cout, stride), ConvBlock(cout, cout))
        self.skip = (
            nn.Identity()
            if cin == cout and stride == 1
            else nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))
        )

    def forward(self, x: Tensor) -> Tensor:
        return self.body(x) + self.skip(x)


class ResUNet(nn.Module):
    """Residual U-Net from `cin` to `cout` channels at the input's resolution."""

    def __init__(self, cin: int, cout: int, widths: tuple[int, ...] = WIDTHS) -> None:
        super().__init__()
        self.stem = ConvBlock(cin, widths[0])
        self.down = nn.ModuleList(
            ResBlock(widths[i - 1], widths[i], stride=2) for i in range(1, len(widths))
        )
        self.up = nn.ModuleList(
            ConvBlock(widths[i] + widths[i - 1], widths[i - 1])
            for i in range(len(widths) - 1, 1, -1)
        )
        self.fuse = nn.Sequential(nn.Conv2d(widths[1] + widths[0], widths[0], 1), nn.LeakyReLU(0.2))
        self.head = nn.Conv2d(widths[0], cout, 1)

    def forward(self, x: Tensor) -> Tensor:
        skips = [self.stem(x)]
        for block in self.down:
            skips.append(block(skips[-1]))
        y = skips.pop()
        for block in self.up:
            skip = skips.pop()
            y = block(torch.cat([F.interpolate(y, size=skip.shape[2:], mode="nearest"), skip], 1))
        stem = skips.pop()
        y = F.interpolate(y, size=stem.shape[2:], mode="bilinear", align_corners=False)
        return self.head(self.fuse(torch.cat([y, stem], 1)))


def rgb_features(rgb: Tensor) -> Tensor:
    """`rgb` in [0, 1] → zero-mean, unit-ish features."""
    return (rgb - RGB_MEAN) / RGB_STD


def point_features(points_m: Tensor, valid: Tensor) -> Tensor:
    """Points (N×3×H×W, metres) and validity → 7 channels: scaled points, their deviation from
    the valid 3×3 mean (the local shape, amplified), and the validity itself."""
    p = points_m * valid
    total = F.avg_pool2d(p, 3, 1, 1, count_include_pad=False)
    count = F.avg_pool2d(valid, 3, 1, 1, count_include_pad=False)
    local_mean = total / torch.clamp(count, min=1e-3)
    detail = (p - local_mean) * valid * DETAIL_GAIN
    return torch.cat([p / POINT_SCALE_M, torch.clamp(detail, -5.0, 5.0), valid], 1)


class DepthNet(nn.Module):
    """RGB + flat-ground prior depth → depth (m): `depth = prior · exp(net)` (Fig. 5, stage 1)."""

    input_names = ("rgb", "prior_depth_m")
    output_names = ("depth_m",)

    def __init__(self) -> None:
        super().__init__()
        self.net = ResUNet(4, 1)

    def forward(self, rgb: Tensor, prior_depth_m: Tensor) -> Tensor:
        log_prior = torch.log(torch.clamp(prior_depth_m, min=0.05))
        x = torch.cat([rgb_features(rgb), log_prior - 1.0], 1)
        return torch.exp(log_prior + torch.clamp(self.net(x), -4.0, 4.0))


class NeighbourNet(nn.Module):
    """RGB + points → 49 logits per pixel over its 7×7 neighbours (ρ after the softmax)."""

    input_names = ("rgb", "points_m", "valid")
    output_names = ("logits",)

    def __init__(self) -> None:
        super().__init__()
        self.net = ResUNet(10, 49)

    def forward(self, rgb: Tensor, points_m: Tensor, valid: Tensor) -> Tensor:
        return self.net(torch.cat([rgb_features(rgb), point_features(points_m, valid)], 1))


class NormalRefiner(nn.Module):
    """Initial normals + RGB + points → refined unit normals (`n0 + Δ`, normalised)."""

    input_names = ("rgb", "points_m", "valid", "normals_init")
    output_names = ("normals",)

    def __init__(self) -> None:
        super().__init__()
        self.net = ResUNet(13, 3)

    def forward(self, rgb: Tensor, points_m: Tensor, valid: Tensor, normals_init: Tensor) -> Tensor:
        x = torch.cat([rgb_features(rgb), point_features(points_m, valid), normals_init], 1)
        n = normals_init + self.net(x)
        return n / torch.clamp(torch.linalg.vector_norm(n, dim=1, keepdim=True), min=1e-6)


class CentroidNet(nn.Module):
    """Points + normals + RGB → the centroid of each point's local plane (edge-aware surface
    reconstruction); roughness is then Eq. 1, `|n · (p − c)|`, outside the net."""

    input_names = ("rgb", "points_m", "valid", "normals")
    output_names = ("centroid_m",)

    def __init__(self) -> None:
        super().__init__()
        self.net = ResUNet(13, 3)

    def forward(self, rgb: Tensor, points_m: Tensor, valid: Tensor, normals: Tensor) -> Tensor:
        x = torch.cat([rgb_features(rgb), point_features(points_m, valid), normals], 1)
        return points_m + CENTROID_STEP_M * self.net(x)


class EndToEnd(nn.Module):
    """The end-to-end baseline (the paper's GeoNet-R row): RGB + prior depth → roughness (m),
    with the compute of the depth net plus the centroid net."""

    input_names = ("rgb", "prior_depth_m")
    output_names = ("roughness_m",)

    def __init__(self) -> None:
        super().__init__()
        self.net = ResUNet(4, 1, widths=tuple(int(w * 1.5) for w in WIDTHS))

    def forward(self, rgb: Tensor, prior_depth_m: Tensor) -> Tensor:
        log_prior = torch.log(torch.clamp(prior_depth_m, min=0.05))
        x = torch.cat([rgb_features(rgb), log_prior - 1.0], 1)
        return ROUGHNESS_STEP_M * F.softplus(self.net(x))


NETS: dict[str, type[nn.Module]] = {
    "depth_net": DepthNet,
    "neighbour_net": NeighbourNet,
    "normal_refiner": NormalRefiner,
    "centroid_net": CentroidNet,
    "end_to_end": EndToEnd,
}
"""Stage name → class; the names are the ONNX file stems and manifest keys."""

INPUT_CHANNELS = {
    "rgb": 3,
    "prior_depth_m": 1,
    "points_m": 3,
    "valid": 1,
    "normals_init": 3,
    "normals": 3,
}
OUTPUT_CHANNELS = {"depth_m": 1, "logits": 49, "normals": 3, "centroid_m": 3, "roughness_m": 1}


def example_inputs(name: str, n: int = 1, h: int = 64, w: int = 64, seed: int = 0) -> list[Tensor]:
    """Plausible inputs for stage `name`: random RGB, a tilted ground plane 1–3 m away, unit
    normals; used for FLOP counts, export and the parity vectors."""
    g = torch.Generator().manual_seed(seed)
    out = []
    for inp in NETS[name].input_names:
        c = INPUT_CHANNELS[inp]
        if inp == "rgb":
            out.append(torch.rand(n, c, h, w, generator=g))
        elif inp == "prior_depth_m":
            ramp = torch.linspace(3.0, 1.0, h).view(1, 1, h, 1).expand(n, 1, h, w)
            out.append(ramp.contiguous())
        elif inp == "points_m":
            z = 1.0 + 2.0 * torch.rand(n, 1, h, w, generator=g)
            xy = torch.rand(n, 2, h, w, generator=g) - 0.5
            out.append(torch.cat([xy * z, z], 1))
        elif inp == "valid":
            out.append((torch.rand(n, 1, h, w, generator=g) > 0.1).float())
        else:
            v = torch.randn(n, 3, h, w, generator=g)
            out.append(v / torch.linalg.vector_norm(v, dim=1, keepdim=True))
    return out


def conv_flops(model: nn.Module, inputs: list[Tensor]) -> int:
    """Multiply-adds × 2 of every convolution for one forward pass over `inputs`."""
    total = 0

    def hook(mod: nn.Module, _inp: tuple[Tensor, ...], out: Tensor) -> None:
        nonlocal total
        assert isinstance(mod, nn.Conv2d)
        k = mod.kernel_size[0] * mod.kernel_size[1] * mod.in_channels // mod.groups
        total += 2 * out.numel() * k

    handles = [m.register_forward_hook(hook) for m in model.modules() if isinstance(m, nn.Conv2d)]
    with torch.no_grad():
        model.eval()
        model(*inputs)
    for h in handles:
        h.remove()
    return total
