"""A training set from the complete scenes of a `tre synth` run still in progress (or stopped):
`python -m tre_training.partial_set SRC DST`.

`tre synth` writes `dataset.json` only when every scene is done. This writes `DST/dataset.json`
listing the scenes of SRC whose every view folder is in place (each is renamed into place once
written, so a listed folder is complete), with each scene's split computed as `tre synth`
computes it (`draw(seed, scene, 4) < test_fraction`, `crates/tre-synth/src/dataset/scene.rs`),
and links DST's scene folders to SRC's. Training reads DST as it reads a finished set; SRC's run
can go on (`tre synth ... --resume`) and later runs of this pick up the scenes added since.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

MASK = (1 << 64) - 1


def splitmix64(x: int) -> int:
    """`tre_core::geometry::hash::splitmix64`."""
    z = (x + 0x9E3779B97F4A7C15) & MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def draw(seed: int, scene: int, what: int) -> float:
    """`tre_synth::dataset::scene::draw`: a uniform number in [0, 1) for (seed, scene, what)."""
    h = splitmix64(splitmix64(seed ^ 0xDA7A) ^ (scene << 16) ^ what)
    return (h >> 11) * (1.0 / (1 << 53))


def write(src: Path, dst: Path) -> dict:
    cfg_path = src / "dataset.partial.json"
    if (src / "dataset.json").exists():
        cfg = json.loads((src / "dataset.json").read_text())["config"]
    else:
        cfg = json.loads(cfg_path.read_text())
    views = int(cfg["views"])
    scenes = []
    for d in sorted(src.glob("scene_*")):
        if not all((d / f"view_{v}").is_dir() for v in range(views)):
            continue
        s = int(d.name.removeprefix("scene_"))
        split = "test" if draw(int(cfg["seed"]), s, 4) < float(cfg["test_fraction"]) else "train"
        frames = [{"dir": f"{d.name}/view_{v}", "view": v} for v in range(views)]
        scenes.append({"scene": s, "split": split, "frames": frames})
    dst.mkdir(parents=True, exist_ok=True)
    for s in scenes:
        link = dst / f"scene_{s['scene']:05}"
        if not link.exists():
            link.symlink_to((src / link.name).resolve())
    counts = [sum(len(s["frames"]) for s in scenes if s["split"] == k) for k in ("train", "test")]
    manifest = {
        "config": cfg,
        "partial_of": str(src),
        "scenes": scenes,
        "counts": counts,
    }
    (dst / "dataset.json").write_text(json.dumps(manifest, indent=1) + "\n")
    return {"scenes": len(scenes), "train_frames": counts[0], "test_frames": counts[1]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("src", type=Path, help="the folder of a tre synth run")
    ap.add_argument("dst", type=Path, help="where to write dataset.json and the scene links")
    args = ap.parse_args(argv)
    print(json.dumps(write(args.src, args.dst)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
