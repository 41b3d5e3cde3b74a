"""Tests of the numpy DSAC reference and of the shared test vectors it writes."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from tre_training import dsac, make_vectors

# --- hash -----------------------------------------------------------------------------------------


def test_splitmix64_reference_sequence() -> None:
    # SplitMix64 seeded with 0 (Steele, Lea and Flood 2014): state += γ, then mix.
    assert dsac.splitmix64(0) == 0xE220A8397B1DCDAF
    gamma = 0x9E3779B97F4A7C15
    assert dsac.splitmix64(gamma) == 0x6E789E6AA1B965F4
    assert dsac.splitmix64(2 * gamma & dsac.MASK64) == 0x06C45D188009454F


def test_uniform_is_the_top_53_bits() -> None:
    for seed, pixel, hyp, draw in [(0, 0, 0, 0), (7, 1234, 3, 2), (dsac.MASK64, 99, 11, 1)]:
        u = dsac.uniform(seed, pixel, hyp, draw)
        assert 0.0 <= u < 1.0
        assert u == (dsac.uniform_hash(seed, pixel, hyp, draw) >> 11) / 2.0**53
    assert dsac.uniform(7, 1234, 3, 2) != dsac.uniform(7, 1234, 3, 1)
    with pytest.raises(ValueError):
        dsac.uniform(-1, 0, 0, 0)
    with pytest.raises(ValueError):
        dsac.uniform(0, 0, 1 << 32, 0)


# --- fastmath -------------------------------------------------------------------------------------


def _bits(x: np.float32) -> int:
    return int(np.array(x, dtype=np.float32).view(np.uint32))


def test_constants_are_the_rust_literals() -> None:
    assert float(dsac.LN2_HI) == 355.0 / 512.0
    assert abs(float(dsac.LN2_HI) + float(dsac.LN2_LO) - math.log(2.0)) < 1e-11
    assert _bits(dsac.LOG2_E_F32) == 0x3FB8AA3B
    assert dsac.LOG2_E_F64 == 1.4426950408889634
    # A decimal exactly halfway between two float32 values rounds to the even one.
    half_ulp_above_one = "1.000000059604644775390625"
    assert _bits(dsac.f32_literal(half_ulp_above_one)) == _bits(np.float32(1.0))


def test_fast_exp_error_bound() -> None:
    xs = np.linspace(-87.0, 88.0, 400_001, dtype=np.float32)
    rel = np.abs(dsac.fast_exp_f32(xs).astype(np.float64) / np.exp(xs.astype(np.float64)) - 1.0)
    assert rel.max() < 2e-7
    near = np.linspace(-1.0, 1.0, 100_001, dtype=np.float32)
    rel = np.abs(dsac.fast_exp_f32(near).astype(np.float64) / np.exp(near.astype(np.float64)) - 1)
    assert rel.max() < 1.5e-7
    assert float(dsac.fast_exp_f32(0.0)) == 1.0


def test_fast_exp_clamps_and_propagates_nan() -> None:
    e = dsac.fast_exp_f32
    assert _bits(e(-1000.0)) == _bits(e(-87.0))
    assert _bits(e(-np.inf)) == _bits(e(-87.0))
    assert _bits(e(1000.0)) == _bits(e(88.0))
    assert np.isnan(e(np.nan))
    assert np.isfinite(e(88.0)) and e(-87.0) >= np.finfo(np.float32).tiny


def test_logistic_error_bound() -> None:
    ys = np.linspace(-120.0, 120.0, 400_001, dtype=np.float32)
    exact = 1.0 / (1.0 + np.exp2(ys.astype(np.float64)))
    rel = np.abs(dsac.recip_one_plus_exp2_f32(ys).astype(np.float64) / exact - 1.0)
    assert rel.max() < 7e-7
    assert float(dsac.recip_one_plus_exp2_f32(0.0)) == 0.5
    assert float(dsac.recip_one_plus_exp2_f32(-1e9)) == 1.0
    # NaN is taken as +∞: the result at the top of the domain.
    assert _bits(dsac.recip_one_plus_exp2_f32(np.nan)) == _bits(dsac.recip_one_plus_exp2_f32(120.0))


def test_sum_block_order() -> None:
    assert float(dsac.sum_block(np.arange(1.0, 9.0))) == 36.0
    # ((a0 + a4) + (a2 + a6)) + ((a1 + a5) + (a3 + a7)): 1e8 cancels before the 1s are added.
    a = np.array([1e8, 1.0, 0.0, 1.0, -1e8, 1.0, 0.0, 1.0], dtype=np.float32)
    assert float(dsac.sum_block(a)) == 4.0


# --- ρ --------------------------------------------------------------------------------------------


def test_probabilities_match_the_float64_softmax() -> None:
    logits = np.array([((k * 37) % 23) - 11.5 for k in range(49)], dtype=np.float32)
    valid = np.array([k % 7 != 2 for k in range(49)])
    rho = dsac.candidate_probabilities(logits, valid)
    e = np.where(valid, np.exp(logits.astype(np.float64) - 11.5), 0.0)
    expected = e / e.sum()
    assert np.all(rho[~valid] == 0.0)
    assert np.allclose(rho, expected, rtol=4e-7, atol=0.0)


def test_probabilities_ignore_unusable_candidates() -> None:
    logits = np.ones(49, dtype=np.float32)
    logits[[3, 4]] = [np.nan, np.inf]
    rho = dsac.candidate_probabilities(logits, np.ones(49, dtype=bool))
    assert rho[3] == 0.0 and rho[4] == 0.0
    assert abs(rho[0] * 47 - 1.0) < 1e-6
    none = dsac.candidate_probabilities(np.full(49, np.nan, dtype=np.float32), np.ones(49, bool))
    assert np.all(none == 0.0)


# --- sampler --------------------------------------------------------------------------------------


def _random_rho(i: int) -> np.ndarray:
    rho = np.array([make_vectors.unit(0x51, 49 * i + k) for k in range(49)])
    rho[[make_vectors.small_int(0x52, 49 * i + k, 3) == 0 for k in range(49)]] = 0.0
    return rho


def test_sampler_draws_distinct_candidates_with_probability() -> None:
    for i in range(40):
        rho = _random_rho(i)
        for hyp in range(12):
            triple = dsac.sample_triple(rho, seed=i, pixel=1000 + i, hypothesis=hyp)
            assert triple is not None
            assert len(set(triple)) == 3
            assert all(rho[k] > 0.0 for k in triple)


def test_sampler_needs_three_candidates_with_probability() -> None:
    for positive in ([], [24], [3, 40]):
        rho = np.zeros(49)
        rho[positive] = 1.0
        for hyp in range(24):
            assert dsac.sample_triple(rho, seed=9, pixel=5, hypothesis=hyp) is None
    rho = np.zeros(49)
    rho[[3, 10, 24]] = 1.0 / 3.0
    for hyp in range(24):
        assert sorted(dsac.sample_triple(rho, seed=9, pixel=5, hypothesis=hyp)) == [3, 10, 24]


def test_sampler_follows_the_probabilities() -> None:
    rho = np.zeros(49)
    rho[[0, 1, 2, 3]] = [0.7, 0.1, 0.1, 0.1]
    firsts = [dsac.sample_triple(rho, 1, p, 0)[0] for p in range(2000)]
    assert abs(firsts.count(0) / 2000 - 0.7) < 0.05


# --- planes, normals ------------------------------------------------------------------------------


def test_plane_through_and_eq1() -> None:
    plane = dsac.plane_through([0, 0, 0], [1, 0, 0], [0, 1, 0])
    assert plane is not None and plane.normal == (0.0, 0.0, 1.0)
    assert plane.distance([3.0, -1.0, -0.25]) == 0.25
    assert dsac.plane_through([0, 0, 0], [1, 0, 0], [2, 0, 0]) is None
    assert dsac.plane_through([0, 0, 0], [1, 0, 0], [np.nan, 1, 0]) is None


def test_dsac_normals_of_a_plane() -> None:
    points, logits, seed = make_vectors.tilted_plane()
    normals = dsac.dsac_normals(points, logits, seed)
    n = np.array([0.1, -0.6, -0.8]) / np.linalg.norm([0.1, -0.6, -0.8])
    n = n if n @ points[0, 0] <= 0 else -n
    assert np.abs(normals - n).max() < 1e-9


def test_invalid_and_isolated_pixels_get_no_normal() -> None:
    points, logits, seed = make_vectors.holes_and_noise()
    normals = dsac.dsac_normals(points, logits, seed)
    invalid = ~np.array([[dsac.is_valid_point(p) for p in row] for row in points])
    assert np.isnan(normals[invalid]).all()
    assert np.isnan(normals[0, 0]).all()  # fewer than 3 candidates
    assert np.isnan(normals[7, 9]).all()  # only collinear candidates
    assert np.isfinite(normals[~invalid]).sum() == 3 * (np.count_nonzero(~invalid) - 2)


# --- shared test vectors --------------------------------------------------------------------------


def _assert_same(fresh: Any, committed: Any, path: str = "") -> None:
    """Equal JSON, except that float64 normals may differ by 1e-12 (their eigenvectors come
    from LAPACK, whose last bits depend on the build); everything else is exact."""
    if isinstance(fresh, dict):
        assert isinstance(committed, dict) and fresh.keys() == committed.keys(), path
        for k in fresh:
            if k == "normal" and fresh[k] is not None and committed[k] is not None:
                a, b = (np.array([float(c) for c in v]) for v in (fresh[k], committed[k]))
                assert np.abs(a - b).max() <= 1e-12, f"{path}/{k}"
            else:
                _assert_same(fresh[k], committed[k], f"{path}/{k}")
    elif isinstance(fresh, list):
        assert isinstance(committed, list) and len(fresh) == len(committed), path
        for i, (a, b) in enumerate(zip(fresh, committed, strict=True)):
            _assert_same(a, b, f"{path}[{i}]")
    else:
        assert fresh == committed, path


def test_fixture_is_a_fresh_regeneration() -> None:
    text = make_vectors.render()
    assert text == make_vectors.render()
    committed = make_vectors.DEFAULT_OUT.read_text(encoding="utf-8")
    _assert_same(json.loads(text), json.loads(committed))
    assert len(committed.encode("utf-8")) < 300 * 1024


def test_fixture_strings_round_trip() -> None:
    for x in [0.1, 5e-324, -0.0, 1.0 / 3.0, float("inf")]:
        assert float(make_vectors.f64s(x)) == x
    for x in np.array([0.1, 1e-45, 3.4028235e38, -2.5], dtype=np.float32):
        assert np.float32(make_vectors.f32s(x)) == x
    assert make_vectors.f32s(np.float32(np.nan)) == "nan"
