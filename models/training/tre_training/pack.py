"""The training and evaluation frames in a pack small enough to travel to a machine that has
neither `../shared/data` nor `tre` (a lent GPU: 64 MiB per call, the repository included):
`python -m tre_training.pack pack OUT [--synthetic N]` here, `python -m tre_training.pack unpack
OUT` there.

What the pack holds, per split: each frame's RGB as a JPEG (quality 95) and its depth as a 16-bit
PNG (units of `DEPTH_UNIT_M`, 0 = none; a real frame's sensor depth too), its intrinsics and
mounting, and for the real frames the metadata of `real.load_real`. `pack` reads the caches
training wrote (`data/sensor256/.cache/train.npz`, `data/real256/{train,val,test}.npz`), making
them where missing (the synthetic set itself must exist: `tre synth`, as `train_depth_real.sh`
runs it, and `../shared/data` beside the repository);
`unpack` writes them back in the same format, so `train_real` and `eval_real` read them as they
read their own. The synthetic set travels as a random subset of its train frames (`--synthetic`,
seeded), with `dataset.json` for the manifest. What changes on the way: RGB goes through JPEG
(the synthetic set already draws JPEG artefacts as one of its effects), depth is rounded to 2 mm
and clipped at 131 m; normals, roughness and boundaries are not packed (the depth net does not
read them) and come back as none.
"""

from __future__ import annotations

import argparse
import io
import json
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from .data import Split, load_split

REPO = Path(__file__).resolve().parents[3]
SYNTH = REPO / "data" / "sensor256"
REAL = REPO / "data" / "real256"
DEPTH_UNIT_M = 0.002
"""Metres per unit of a packed depth PNG (16 bits: up to 131 m)."""


def _jpeg(rgb: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="JPEG", quality=95)
    return buf.getvalue()


def _png16(depth_m: np.ndarray) -> bytes:
    d = np.nan_to_num(depth_m, nan=0.0)
    q = np.clip(np.round(d / DEPTH_UNIT_M), 0, 65535).astype(np.uint16)
    buf = io.BytesIO()
    Image.fromarray(q).save(buf, format="PNG", compress_level=9)
    return buf.getvalue()


def _blobs(items: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    offsets = np.cumsum([0] + [len(b) for b in items]).astype(np.int64)
    return np.frombuffer(b"".join(items), np.uint8), offsets


def _unblob(data: np.ndarray, offsets: np.ndarray, i: int) -> bytes:
    return data[offsets[i] : offsets[i + 1]].tobytes()


def pack_split(s: Split, rows: np.ndarray, out: Path, meta: list[dict] | None) -> int:
    sensor_differs = not np.array_equal(s.depth_m[rows], s.depth_sensor_m[rows], equal_nan=True)
    arrays: dict[str, np.ndarray] = {}
    arrays["rgb"], arrays["rgb_offsets"] = _blobs([_jpeg(s.rgb[i]) for i in rows])
    arrays["depth"], arrays["depth_offsets"] = _blobs([_png16(s.depth_m[i]) for i in rows])
    if sensor_differs:
        sensor = [_png16(s.depth_sensor_m[i]) for i in rows]
        arrays["sensor"], arrays["sensor_offsets"] = _blobs(sensor)
    arrays["intrinsics"] = s.intrinsics[rows]
    arrays["mounting"] = s.mounting[rows]
    arrays["shape"] = np.array(s.depth_m.shape[1:], np.int64)
    if meta is not None:
        arrays["meta"] = np.array(json.dumps([meta[i] for i in rows]))
    np.savez(out, **arrays)
    return out.stat().st_size


def unpack_split(path: Path) -> tuple[Split, list[dict] | None]:
    with np.load(path, allow_pickle=False) as z:
        a = {k: z[k] for k in z.files}
    h, w = (int(v) for v in a["shape"])
    n = len(a["rgb_offsets"]) - 1

    def depth(key: str, i: int) -> np.ndarray:
        q = np.asarray(Image.open(io.BytesIO(_unblob(a[key], a[f"{key}_offsets"], i))))
        return np.where(q > 0, q.astype(np.float32) * np.float32(DEPTH_UNIT_M), np.nan)

    rgb = np.stack(
        [
            np.asarray(Image.open(io.BytesIO(_unblob(a["rgb"], a["rgb_offsets"], i))))
            for i in range(n)
        ]
    )
    depth_m = np.stack([depth("depth", i) for i in range(n)]).astype(np.float32)
    key = "sensor" if "sensor" in a else "depth"
    sensor = depth_m if key == "depth" else np.stack([depth(key, i) for i in range(n)])
    s = Split(
        rgb=rgb.astype(np.uint8),
        depth_m=depth_m,
        depth_sensor_m=sensor.astype(np.float32),
        normals=np.full((n, h, w, 3), np.nan, np.float16),
        roughness_m=np.full((n, h, w), np.nan, np.float32),
        boundary=np.zeros((n, h, w), bool),
        intrinsics=a["intrinsics"].astype(np.float32),
        mounting=a["mounting"].astype(np.float32),
    )
    meta = json.loads(str(a["meta"])) if "meta" in a else None
    return s, meta


def pack(out: Path, synthetic: int, seed: int) -> dict:
    from . import real

    out.mkdir(parents=True, exist_ok=True)
    sizes = {}
    # The training cache when there (written by the first training on the set), else the set.
    s = load_split(SYNTH, "train", SYNTH / ".cache" / "train.npz")
    rng = np.random.default_rng(seed)
    rows = np.sort(rng.choice(len(s), min(synthetic, len(s)), replace=False))
    sizes["synthetic_train"] = pack_split(s, rows, out / "synthetic_train.npz", None)
    shutil.copy(SYNTH / "dataset.json", out / "dataset.json")
    for split in ("train", "val", "test"):
        s, meta = real.load_real(split, cache=REAL / f"{split}.npz")
        sizes[f"real_{split}"] = pack_split(s, np.arange(len(s)), out / f"real_{split}.npz", meta)
    info = {
        "synthetic_frames": len(rows),
        "seed": seed,
        "bytes": sizes,
        "depth_unit_m": DEPTH_UNIT_M,
    }
    (out / "pack.json").write_text(json.dumps(info, indent=1) + "\n")
    return info


def unpack(src: Path, synth: Path = SYNTH, real_dir: Path = REAL) -> dict:
    (synth / ".cache").mkdir(parents=True, exist_ok=True)
    real_dir.mkdir(parents=True, exist_ok=True)
    s, _ = unpack_split(src / "synthetic_train.npz")
    np.savez(synth / ".cache" / "train.npz", **s.__dict__)
    shutil.copy(src / "dataset.json", synth / "dataset.json")
    counts = {"synthetic_train": len(s)}
    for split in ("train", "val", "test"):
        s, meta = unpack_split(src / f"real_{split}.npz")
        np.savez(real_dir / f"{split}.npz", meta=json.dumps(meta), **s.__dict__)
        counts[f"real_{split}"] = len(s)
    return counts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("verb", choices=["pack", "unpack"])
    ap.add_argument("dir", type=Path, help="the pack's folder")
    ap.add_argument("--synthetic", type=int, default=600, help="synthetic train frames packed")
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args(argv)
    if args.verb == "pack":
        print(json.dumps(pack(args.dir, args.synthetic, args.seed)))
    else:
        print(json.dumps(unpack(args.dir)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
