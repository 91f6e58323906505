"""A flame graph (SVG) from `perf script` output, with no dependency beyond
Python: stacks are folded root first, each frame is a box as wide as the
share of samples whose stack passes through it, and hovering a box shows
its name and share (docs/benchmarks.md, "Where the time goes").

    perf record --call-graph dwarf -F 250 -o perf.data PROGRAM ARGS...
    perf script -i perf.data | python3 painter/bench/flamegraph.py --title T > out.svg

Frames are function names with Rust's hashes and generic arguments cut
short. `--keep-thread NAME` keeps only samples of threads whose name
starts with NAME; `--below REGEX` keeps only stacks that pass through a
function whose name matches REGEX, drawn from the outermost such frame up
(to leave a benchmark's set-up and digest out)."""

import argparse
import hashlib
import html
import re
import sys

WIDTH = 1200
ROW = 17
FONT = 11
MIN_PX = 0.3  # boxes narrower than this are not drawn


def _plain(text):
    """`text` without generic arguments: every <...> group dropped."""
    out, depth = [], 0
    for ch in text:
        if ch == "<":
            depth += 1
        elif ch == ">":
            depth = max(0, depth - 1)
        elif depth == 0:
            out.append(ch)
    return "".join(out)


def _group(text):
    """A top-level <...> of a path: `<impl a::T>` is T, `<a::A as b::B>` is
    `A as B`, anything else loses its generics."""
    text = text.strip()
    last = lambda p: _plain(p).strip().rstrip(":").split("::")[-1]
    if text.startswith("impl "):
        return last(text[5:])
    if " as " in text:
        a, b = text.split(" as ", 1)
        return f"{last(a)} as {last(b)}"
    return last(text)


def short(name):
    """A frame's name without the hash, the offset and generic arguments."""
    name = re.sub(r"\+0x[0-9a-f]+$", "", name)
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(name):  # split the path at its top-level <...>
        if ch == "<":
            if depth == 0:
                parts.append(_plain(name[start:i]))
                start = i + 1
                # At the start or after `::` the group names a type
                # (`<impl T>`, `<A as B>`); after a name it is arguments.
                qualified = i == 0 or name[:i].endswith("::")
            depth += 1
        elif ch == ">" and depth > 0:
            depth -= 1
            if depth == 0:
                if qualified:
                    parts.append(_group(name[start:i]))
                start = i + 1
    parts.append(_plain(name[start:]))
    name = "".join(parts).replace("{{closure}}", "{closure}").replace("{{vtable.shim}}", "{vtable.shim}")
    return name or "?"


def fold(lines, keep_thread, below):
    """Counts of root-first stacks (tuples of frame names)."""
    counts = {}
    comm, frames = None, []

    def flush():
        if comm is None or not frames:
            return
        if keep_thread and not comm.startswith(keep_thread):
            return
        stack = [short(f) for f in reversed(frames)]
        if below:
            cut = next((i for i, f in enumerate(stack) if below.search(f)), None)
            if cut is None:
                return
            stack = stack[cut:]
        key = tuple(stack)
        counts[key] = counts.get(key, 0) + 1

    for line in lines:
        if not line.strip():
            flush()
            comm, frames = None, []
        elif line[0] not in " \t":
            flush()
            comm, frames = line.split()[0], []
        else:
            parts = line.split(None, 1)
            if len(parts) < 2:
                continue
            sym = parts[1].rsplit(" (", 1)[0].strip()
            frames.append(sym if sym and sym != "[unknown]" else "[unknown]")
    flush()
    return counts


def colour(name):
    h = int(hashlib.md5(name.encode()).hexdigest()[:6], 16)
    return f"rgb({205 + h % 50},{80 + (h >> 8) % 120},{(h >> 16) % 60})"


def render(counts, title):
    total = sum(counts.values())
    if total == 0:
        raise SystemExit("flamegraph: no samples matched")
    # A tree of frames: name -> [count, children].
    root = [total, {}]
    for stack, n in counts.items():
        node = root
        for f in stack:
            child = node[1].setdefault(f, [0, {}])
            child[0] += n
            node = child
    boxes = []

    def walk(node, x, level):
        for name, child in sorted(node[1].items()):
            w = child[0] / total * WIDTH
            if w >= MIN_PX:
                boxes.append((x, level, w, name, child[0]))
                walk(child, x, level + 1)
            x += w

    walk(root, 0.0, 0)
    levels = max((b[1] for b in boxes), default=0) + 1
    height = (levels + 3) * ROW
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" '
        f'font-family="monospace" font-size="{FONT}">',
        '<rect width="100%" height="100%" fill="#fafafa"/>',
        f'<text x="{WIDTH / 2}" y="{ROW}" text-anchor="middle" font-size="{FONT + 3}">{html.escape(title)} ({total} samples)</text>',
    ]
    chars = lambda w: int((w - 4) / (FONT * 0.6))
    for x, level, w, name, n in boxes:
        y = height - (level + 2) * ROW
        tip = f"{name}: {n} samples, {100 * n / total:.1f}%"
        out.append(f'<g><title>{html.escape(tip)}</title><rect x="{x:.2f}" y="{y}" width="{w:.2f}" height="{ROW - 1}" fill="{colour(name)}" rx="1"/>')
        k = chars(w)
        if k >= 3:
            # The box shows the end of the path (the whole name is in the
            # tooltip): `Painting::step`, not its crate and module.
            # A closure keeps its function: `Painting::paint_new_cells::{closure}`.
            keep = 3 if name.endswith("}") else 2
            label = "::".join(name.split("::")[-keep:])
            label = label if len(label) <= k else label[: k - 2] + ".."
            out.append(f'<text x="{x + 2:.2f}" y="{y + ROW - 5}">{html.escape(label)}</text>')
        out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--title", default="flame graph")
    ap.add_argument("--keep-thread", default="")
    ap.add_argument("--below", default="")
    a = ap.parse_args()
    below = re.compile(a.below) if a.below else None
    sys.stdout.write(render(fold(sys.stdin, a.keep_thread, below), a.title))


if __name__ == "__main__":
    main()
