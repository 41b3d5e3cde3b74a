"""scripts/import_cycles.py: circles of any length among sibling modules, on small crates
written for the test."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))
import import_cycles as ic


def crate(tmp_path: Path, files: dict[str, str]) -> Path:
    src = tmp_path / "src"
    for name, text in files.items():
        path = src / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return src


def test_a_ring_of_three_is_a_circle_and_a_chain_is_not(tmp_path):
    src = crate(
        tmp_path,
        {
            "lib.rs": "mod a;\nmod b;\nmod c;\nmod d;\n",
            "a.rs": "use super::b::B;\n",
            "b.rs": "use crate::c::C;\n",
            "c.rs": "use super::a::A;\n// use super::d::D;\n",
            "d.rs": "use super::a::A;\n",
        },
    )
    assert ic.cycles(str(src)) == [[("a",), ("b",), ("c",)]]


def test_test_modules_and_children_do_not_count(tmp_path):
    src = crate(
        tmp_path,
        {
            "lib.rs": "mod a;\nmod b;\n",
            "a.rs": "use super::b::B;\nmod inner;\n",
            "a/inner.rs": "use super::super::a::X;\n",
            "b.rs": "pub struct B;\n#[cfg(test)]\nmod tests {\n    use super::super::a::A;\n}\n",
        },
    )
    assert ic.cycles(str(src)) == []


def test_a_pair_is_a_circle_of_two(tmp_path):
    src = crate(
        tmp_path,
        {
            "lib.rs": "mod a;\nmod b;\n",
            "a.rs": "use super::b::B;\n",
            "b.rs": "use crate::a::A;\n",
        },
    )
    assert ic.cycles(str(src)) == [[("a",), ("b",)]]
