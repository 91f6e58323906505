"""The `octopaint-ref` command line: replay, check."""

from __future__ import annotations

import argparse
import sys

from .check import check_arrays
from .dump import DumpError, load_dump
from .trace import TraceError, read_trace


def _cmd_replay(args) -> int:
    try:
        trace = read_trace(args.trace)
    except TraceError as e:
        print(f"octopaint-ref: {args.trace}: {e}", file=sys.stderr)
        return 2
    from .replay import print_stats, replay

    def warn(msg):
        print(f"octopaint-ref: warning: {args.trace}: {msg}", file=sys.stderr)

    stats = replay(trace, args.out, warn=warn)
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
        problems = check_arrays(arrays)
        if problems:
            status = 1
            for p in problems:
                print(f"{path}: {p}")
        else:
            n = len(arrays["parent"])
            live = int((arrays["depth"] != 255).sum())
            print(f"{path}: ok ({n} cells, {live} in use)")
    return status


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="octopaint-ref", description="Octopaint reference implementation")
    sub = ap.add_subparsers(dest="cmd", required=True)
    rp = sub.add_parser("replay", help="replay a trace, writing <name>.npz at snapshots and <name>.png at renders")
    rp.add_argument("trace", help="a .jsonl trace")
    rp.add_argument("--out", required=True, help="output folder (created if missing)")
    rp.add_argument("--quiet", action="store_true", help="print nothing but warnings and errors")
    rp.set_defaults(func=_cmd_replay)
    ck = sub.add_parser("check", help="validate tree dumps: structure, balance, g3 against brute force")
    ck.add_argument("dumps", nargs="+", help=".npz tree dumps")
    ck.set_defaults(func=_cmd_check)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
