"""The partial set's split must be the one `tre synth` gives each scene."""

import json

from tre_training.partial_set import draw, splitmix64, write

# `tre synth --out DIR --scenes 16 --seed 2031 --width 64 --no-ply`: scenes[].split of its
# dataset.json (the test scenes).
TEST_SCENES_2031 = [1, 4, 6, 8, 10, 11]


def test_splitmix64_reference():
    assert splitmix64(0) == 0xE220A8397B1DCDAF


def test_split_matches_tre_synth():
    got = [s for s in range(16) if draw(2031, s, 4) < 0.2]
    assert got == TEST_SCENES_2031


def test_lists_complete_scenes_only(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    cfg = {"views": 2, "seed": 2031, "test_fraction": 0.2}
    src.mkdir()
    (src / "dataset.partial.json").write_text(json.dumps(cfg))
    for s, views in ((0, 2), (1, 2), (2, 1)):
        for v in range(views):
            (src / f"scene_{s:05}" / f"view_{v}").mkdir(parents=True)
    (src / "scene_00003" / "view_0.partial").mkdir(parents=True)
    out = write(src, dst)
    assert out == {"scenes": 2, "train_frames": 2, "test_frames": 2}
    m = json.loads((dst / "dataset.json").read_text())
    assert [(s["scene"], s["split"]) for s in m["scenes"]] == [(0, "train"), (1, "test")]
    assert (dst / "scene_00001" / "view_1").is_dir()
