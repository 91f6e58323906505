"""Module circles inside each crate of the painter, held to a baseline.

    python3 painter/tools/module_circles.py            # check (make test runs it)
    python3 painter/tools/module_circles.py --print    # list the circles found now

A crate's top-level modules (src/X.rs or src/X/) import one another through
`crate::X` paths. A circle is a set of modules that all reach one another
that way. Cargo forbids circles between crates, not inside one, so this
script is the check inside: it fails when a circle appears that the baseline
(module_circles.baseline beside it) does not allow, or an allowed circle
takes in a module it did not hold. A circle that shrank or went is reported
so that the baseline can be tightened; the baseline only ever loses lines.

Comments, doc comments, string literals and `#[cfg(test)] mod` blocks are
left out: a test may reach anywhere, and a doc link is no dependency.
"""
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The crates' folder and the baseline; the script's own tests point them elsewhere.
PAINTER = os.environ.get("MODULE_CIRCLES_ROOT", os.path.dirname(HERE))
BASELINE = os.environ.get("MODULE_CIRCLES_BASELINE", os.path.join(HERE, "module_circles.baseline"))


def strip(text):
    """The Rust source without comments, string and char literals."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:i + 8]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = text.find('"' + hashes, i + len(hashes) + 2)
            i = n if end < 0 else end + 1 + len(hashes)
            out.append('""')
        elif c == '"':
            i += 1
            while i < n and text[i] != '"':
                i += 2 if text[i] == "\\" else 1
            i += 1
            out.append('""')
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:i + 4]) or text.startswith("'\\u{", i):
            i = text.find("'", i + 2) + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def without_tests(code):
    """`code` less its `#[cfg(test)] mod name { ... }` blocks."""
    out, at = [], 0
    for m in re.finditer(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{", code):
        if m.start() < at:
            continue
        depth, i = 1, m.end()
        while i < len(code) and depth:
            depth += {"{": 1, "}": -1}.get(code[i], 0)
            i += 1
        out.append(code[at:m.start()])
        at = i
    out.append(code[at:])
    return "".join(out)


def crate_modules(src):
    """Top-level module name -> its source files (test-only files left out)."""
    mods = {}
    for root, _, files in os.walk(src):
        for f in sorted(files):
            if not f.endswith(".rs"):
                continue
            rel = os.path.relpath(os.path.join(root, f), src)
            parts = rel[:-3].split(os.sep)
            if parts in (["lib"], ["main"]) or parts[-1] == "tests":
                continue
            mods.setdefault(parts[0], []).append(os.path.join(root, f))
    return mods


def edges(mods):
    graph = {m: set() for m in mods}
    for m, files in mods.items():
        for p in files:
            with open(p, encoding="utf-8") as fh:
                code = without_tests(strip(fh.read()))
            used = set(re.findall(r"\bcrate::(\w+)", code))
            # `use crate::{a, b::c}` groups
            for group in re.findall(r"\bcrate::\{([^}]*)\}", code):
                used.update(re.findall(r"(?:^|,)\s*(\w+)", group))
            graph[m].update(u for u in used if u in mods and u != m)
    return graph


def circles(graph):
    """Strongly connected sets of more than one module (Tarjan)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = set()
            while True:
                w = stack.pop()
                on.discard(w)
                scc.add(w)
                if w == v:
                    break
            if len(scc) > 1:
                found.append(frozenset(scc))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def crates():
    for name in sorted(os.listdir(PAINTER)):
        src = os.path.join(PAINTER, name, "src")
        if os.path.isfile(os.path.join(PAINTER, name, "Cargo.toml")) and os.path.isdir(src):
            yield name, src


def read_baseline():
    allowed = {}
    if os.path.exists(BASELINE):
        with open(BASELINE, encoding="utf-8") as fh:
            for line in fh:
                line = line.split("#", 1)[0].strip()
                if line:
                    crate, _, mods = line.partition(":")
                    allowed.setdefault(crate.strip(), []).append(frozenset(mods.split()))
    return allowed


def main(argv):
    found = {name: circles(edges(crate_modules(src))) for name, src in crates()}
    if "--print" in argv:
        for crate, cs in found.items():
            for c in cs:
                print(f"{crate}: {' '.join(sorted(c))}")
        return 0
    allowed = read_baseline()
    bad, loose = [], []
    for crate, cs in found.items():
        for c in cs:
            if not any(c <= a for a in allowed.get(crate, [])):
                bad.append(f"{crate}: {' '.join(sorted(c))}")
    for crate, als in allowed.items():
        for a in als:
            if a not in found.get(crate, []):
                loose.append(f"{crate}: {' '.join(sorted(a))}")
    for line in loose:
        print(f"module_circles: a circle of the baseline shrank or went; tighten {os.path.relpath(BASELINE)} to what --print lists: {line}")
    for line in bad:
        print(f"module_circles: a new module circle, or an allowed one grown: {line}", file=sys.stderr)
    if bad:
        print("Break it: move what both sides need into a module that imports neither (docs/architecture.md, \"Module circles\").", file=sys.stderr)
        return 1
    n = sum(len(cs) for cs in found.values())
    print(f"module_circles: {n} circle(s), all within the baseline")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
