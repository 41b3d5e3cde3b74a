"""Circles of imports between modules, of any length, in every crate of the workspace.

Reads each crate's `src/` tree, resolves its `use crate::…`, `use super::…` and `use self::…`
paths (comments and `#[cfg(test)]` modules left out) to the module they name, lifts each import
to the two sibling modules under their common parent, and prints every circle among siblings:
each strongly connected set of two or more (a pair that imports both ways, or a ring
a -> b -> c -> a). Exits 1 when it finds one. Run from the repository root:
`python3 scripts/import_cycles.py`.
"""

import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def modules(src):
    """Module path (a tuple) -> file, for one crate's source tree."""
    found = {}
    for folder, _, files in os.walk(src):
        for name in files:
            if not name.endswith(".rs"):
                continue
            path = os.path.join(folder, name)
            parts = os.path.relpath(path, src)[:-3].split(os.sep)
            if parts[-1] in ("mod", "lib", "main"):
                parts = parts[:-1]
            found[tuple(parts)] = path
    return found


def resolve(current, path):
    """The module path a `crate::` / `super::` / `self::` path names from `current`."""
    parts = path.split("::")
    if parts[0] == "crate":
        base, parts = [], parts[1:]
    elif parts[0] == "super":
        base, parts = list(current[:-1]), parts[1:]
    elif parts[0] == "self":
        base, parts = list(current), parts[1:]
    else:
        return None
    while parts and parts[0] == "super":
        base, parts = base[:-1], parts[1:]
    return tuple(base + parts)


def siblings(a, b):
    """`a` and `b` cut to the two children of their common parent."""
    i = 0
    while i < min(len(a), len(b)) and a[i] == b[i]:
        i += 1
    return a[: i + 1], b[: i + 1]


def circles(graph):
    """The strongly connected sets of two or more nodes of `graph` (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def cycles(src):
    """Every circle of sibling modules of one crate that import each other."""
    mods = modules(src)
    graph = {}
    for mod, path in mods.items():
        with open(path, encoding="utf-8") as f:
            text = f.read()
        text = "\n".join(line for line in text.split("\n") if not line.strip().startswith("//"))
        text = re.split(r"#\[cfg\(test\)\]\s*(?:pub(?:\(crate\))? )?mod \w+ \{", text)[0]
        for used in re.findall(r"\b((?:crate|super|self)(?:::\w+)+)", text):
            target = resolve(mod, used)
            if target is None:
                continue
            named = next(
                (target[:k] for k in range(len(target), 0, -1) if target[:k] in mods), None
            )
            if named is None or mod[: len(named)] == named or named[: len(mod)] == mod:
                continue
            a, b = siblings(mod, named)
            if a != b:
                graph.setdefault(a, set()).add(b)
    return circles(graph)


def main():
    crates = [os.path.join(ROOT, "src")]
    crates += [
        os.path.join(ROOT, "crates", c, "src")
        for c in sorted(os.listdir(os.path.join(ROOT, "crates")))
    ]
    found = False
    for src in crates:
        for circle in cycles(src):
            names = " -> ".join("::".join(m) for m in circle)
            print(f"{os.path.relpath(src, ROOT)}: circle of {len(circle)}: {names}")
            found = True
    print("import circles:", "some" if found else "none")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
