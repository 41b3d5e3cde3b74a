"""Losses: zero (one, for SSIM) where prediction equals truth, growing with the error."""

from __future__ import annotations

import math

import pytest

torch = pytest.importorskip(
    "torch", reason="PyTorch is not installed (never in CI); pip install -r requirements.txt"
)
# Imported after the skip: it imports torch itself.
from tre_training import losses  # noqa: E402


def test_ssim_is_one_for_identical_maps_and_less_otherwise():
    x = torch.rand(2, 1, 16, 16, generator=torch.Generator().manual_seed(0))
    assert torch.allclose(losses.ssim(x, x), torch.ones_like(x), atol=1e-5)
    assert losses.ssim(x, x.flip(-1)).mean() < 0.9


def test_depth_loss_is_zero_on_truth_and_ignores_missing_depth():
    gt = 1.0 + torch.rand(1, 1, 16, 16)
    gt[0, 0, :4] = float("nan")
    assert losses.depth_loss(gt.nan_to_num(1.0), gt).item() < 1e-6
    worse = losses.depth_loss(gt.nan_to_num(1.0) * 1.1, gt).item()
    assert abs(worse - math.log(1.1)) < 0.02  # the L1 term on log depth dominates


def test_scale_invariant_and_gradient_terms():
    gt = 1.0 + torch.rand(2, 1, 16, 16)
    valid = torch.ones_like(gt, dtype=torch.bool)
    delta = torch.full_like(gt, math.log(1.5))
    # A uniform scale costs the SI term only 15% of its square and the gradient term nothing.
    assert abs(losses.scale_invariant(delta, valid).item() - 0.15 * math.log(1.5) ** 2) < 1e-6
    assert losses.gradient_match(delta, valid).item() < 1e-7
    # A step in the error (a wrong edge) costs the gradient term.
    step = torch.zeros_like(gt)
    step[..., 8:] = 0.2
    assert losses.gradient_match(step, valid).item() > 0.01
    # Missing depth is left out: a step that only touches invalid pixels costs nothing.
    valid[..., 8:] = False
    assert losses.gradient_match(step, valid).item() < 1e-7


def test_normal_loss_is_the_mean_angle():
    n = torch.zeros(1, 3, 4, 4)
    n[:, 2] = 1.0
    side = torch.zeros_like(n)
    side[:, 0] = 1.0
    valid = torch.ones(1, 1, 4, 4)
    assert losses.normal_loss(n, n, valid).item() < 1e-2
    assert abs(losses.normal_loss(side, n, valid).item() - math.pi / 2) < 1e-3
    gt = n.clone()
    gt[:, :, 0, 0] = float("nan")
    valid[:, :, 1, 1] = 0
    assert abs(losses.normal_loss(side, gt, valid).item() - math.pi / 2) < 1e-3


def test_roughness_l1_is_in_centimetres_over_valid_pixels():
    gt = torch.full((1, 1, 4, 4), 0.02)
    gt[0, 0, 0, 0] = float("nan")
    pred = torch.full_like(gt, 0.03)
    valid = torch.ones_like(gt)
    assert abs(losses.roughness_l1(pred, gt, valid).item() - 1.0) < 1e-5
    assert losses.roughness_l1(gt.nan_to_num(0.02), gt, valid).item() < 1e-6
