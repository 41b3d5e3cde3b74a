"""The pack that carries the training frames to a machine without them: what comes back."""

import numpy as np

from tre_training.data import Split
from tre_training.pack import DEPTH_UNIT_M, pack_split, unpack_split


def split(n: int, h: int, w: int, rng: np.random.Generator) -> Split:
    xx = np.mgrid[0:h, 0:w][1]
    rgb = np.stack([(xx * 4 + i * 9) % 256 for i in range(3)], -1)
    rgb = np.broadcast_to(rgb, (n, h, w, 3)).astype(np.uint8)
    depth = (0.5 + 70.0 * rng.random((n, h, w))).astype(np.float32)
    depth[:, :3] = np.nan
    sensor = depth + 0.01
    sensor[:, -2:] = np.nan
    return Split(
        rgb=rgb,
        depth_m=depth,
        depth_sensor_m=sensor,
        normals=np.zeros((n, h, w, 3), np.float16),
        roughness_m=np.zeros((n, h, w), np.float32),
        boundary=np.ones((n, h, w), bool),
        intrinsics=rng.random((n, 4)).astype(np.float32),
        mounting=rng.random((n, 2)).astype(np.float32),
    )


def test_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    s = split(4, 32, 48, rng)
    meta = [{"name": f"f{i}", "size": [48, 32]} for i in range(4)]
    rows = np.array([1, 3])
    pack_split(s, rows, tmp_path / "p.npz", meta)
    got, got_meta = unpack_split(tmp_path / "p.npz")
    assert got_meta == [meta[1], meta[3]]
    assert got.rgb.shape == (2, 32, 48, 3)
    assert np.abs(got.rgb.astype(int) - s.rgb[rows].astype(int)).mean() < 3
    for a, b in ((got.depth_m, s.depth_m[rows]), (got.depth_sensor_m, s.depth_sensor_m[rows])):
        assert np.array_equal(np.isnan(a), np.isnan(b))
        ok = ~np.isnan(b)
        assert np.abs(a[ok] - b[ok]).max() <= DEPTH_UNIT_M / 2 + 1e-5
    assert np.array_equal(got.intrinsics, s.intrinsics[rows])
    assert np.isnan(got.normals).all() and not got.boundary.any()


def test_sensor_depth_equal_to_the_target_is_not_packed_twice(tmp_path):
    rng = np.random.default_rng(2)
    s = split(2, 16, 16, rng)
    s.depth_sensor_m = s.depth_m.copy()
    pack_split(s, np.arange(2), tmp_path / "p.npz", None)
    assert "sensor" not in np.load(tmp_path / "p.npz").files
    got, meta = unpack_split(tmp_path / "p.npz")
    assert meta is None
    assert np.array_equal(got.depth_m, got.depth_sensor_m, equal_nan=True)
