"""The `octopaint-ref` command line: replay, check, export."""

from __future__ import annotations

import argparse
import sys

from .check import check_arrays
from .dump import DumpError, layer_trees, load_dump
from .jax_setup import configure
from .trace import TraceError, read_trace


def _cmd_replay(args) -> int:
    try:
        trace = read_trace(args.trace)
    except TraceError as e:
        print(f"octopaint-ref: {args.trace}: {e}", file=sys.stderr)
        return 2
    from .replay import parse_lods, print_stats, replay

    try:
        lods = parse_lods(args.lod)
    except ValueError as e:
        print(f"octopaint-ref: {e}", file=sys.stderr)
        return 2

    def warn(msg):
        print(f"octopaint-ref: warning: {args.trace}: {msg}", file=sys.stderr)

    stats = replay(trace, args.out, warn=warn, lods=lods)
    if not args.quiet:
        print_stats(stats)
        for p in stats.written:
            print(p)
    return 0


def _cmd_check(args) -> int:
    status = 0
    for path in args.dumps:
        try:
            arrays = load_dump(path)
        except DumpError as e:
            print(f"{e}", file=sys.stderr)
            status = 1
            continue
        layers = layer_trees(arrays)
        problems = []
        for k, tree in enumerate(layers):
            prefix = f"layer {k}: " if "layer_count" in arrays else ""
            problems.extend(prefix + p for p in check_arrays(tree))
        if problems:
            status = 1
            for p in problems:
                print(f"{path}: {p}")
        else:
            n = sum(len(t["parent"]) for t in layers)
            live = sum(int((t["depth"] != 255).sum()) for t in layers)
            of = f", {len(layers)} layers" if "layer_count" in arrays else ""
            print(f"{path}: ok ({n} cells, {live} in use{of})")
    return status


def _cmd_export(args) -> int:
    import time

    from .export import ExportError, export_regions, load_input, summary, write_export

    def warn(msg):
        print(f"octopaint-ref: warning: {args.input}: {msg}", file=sys.stderr)

    try:
        arrays, replay_seconds = load_input(args.input, warn=warn, depth=args.depth)
        t0 = time.perf_counter()
        out = export_regions(arrays, args.depth, args.colour)
        seconds = time.perf_counter() - t0
    except (TraceError, ExportError) as e:
        print(f"octopaint-ref: {args.input}: {e}", file=sys.stderr)
        return 2
    try:
        write_export(args.voxels, out)
    except OSError as e:
        print(f"octopaint-ref: {args.voxels}: cannot write: {e.strerror or e}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(summary(out, seconds, replay_seconds), file=sys.stderr)
    return 0


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="octopaint-ref", description="Octopaint reference implementation")
    sub = ap.add_subparsers(dest="cmd", required=True)
    rp = sub.add_parser("replay", help="replay a trace, writing <name>.npz at snapshots and <name>.png at renders")
    rp.add_argument("trace", help="a .jsonl trace")
    rp.add_argument("--out", required=True, help="output folder (created if missing)")
    rp.add_argument("--quiet", action="store_true", help="print nothing but warnings and errors")
    rp.add_argument(
        "--lod",
        default="0",
        metavar="K[,K...]",
        help="levels of detail of every image (spec 7): 0 (the default) walks to the leaves and writes <name>.png; "
        "any other k writes <name>.lod<k>.png, k as given",
    )
    rp.set_defaults(func=_cmd_replay)
    ck = sub.add_parser("check", help="validate tree dumps: structure, balance, g3 against brute force")
    ck.add_argument("dumps", nargs="+", help=".npz tree dumps")
    ck.set_defaults(func=_cmd_check)
    ex = sub.add_parser(
        "export",
        help="resample a painting at one export depth and write its regions (.npz), the oracle for the painter's OpenVDB export",
        description="Resample the painting at export depth E, as the painter's voxel export does, and write every "
        "active region (a leaf no deeper than E, or a cell of depth E aggregating its leaves) to an .npz: "
        "origin int32 (N,3) voxel origins, log2_edge uint8 (N,), density f32 (N,), color f32 (N,3), "
        "depth uint32, voxel_size f64, colour_space str.",
    )
    ex.add_argument("input", help="a tree dump (.npz) or a trace (.jsonl, replayed in memory; its final tree is exported)")
    ex.add_argument("--voxels", required=True, metavar="OUT.npz", help="the .npz of regions to write (atomically, mode 0644)")
    ex.add_argument(
        "--depth",
        type=int,
        metavar="E",
        help="export depth: a voxel is a cell of depth E (default: the deepest depth of a painted leaf, "
        "capped at the deepest depth whose voxel indices fit 32-bit coordinates)",
    )
    ex.add_argument(
        "--colour",
        choices=("linear", "srgb"),
        default="linear",
        help="colour encoding written: linear (the default; what Blender and glTF expect) or srgb (as stored and blended)",
    )
    ex.add_argument("--quiet", action="store_true", help="print nothing but warnings and errors (no summary line)")
    ex.set_defaults(func=_cmd_export)
    # The study's commands: each module gives its arguments and its command.
    from . import gpu_probe, lit_precision, precision_scale

    for name, module, text in (
        ("precision", precision_scale, "the angle bound on N rays from a depth-24 leaf, sharded over devices and processes, resumable"),
        ("gpu-probe", gpu_probe, "the painter's GPU ray caster against the angle bound, the emulation and mpmath, ray by ray"),
        ("lit-precision", lit_precision, "lit renders of the lit traces with f16, f32 and f64 traversal, against f64, lit and unlit"),
    ):
        p = sub.add_parser(name, help=text, description=module.__doc__.split("\n\n")[0])
        module.add_arguments(p)
        p.set_defaults(func=module.command)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
