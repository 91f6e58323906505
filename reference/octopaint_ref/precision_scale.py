"""The precision study at scale: the paper's angle bound (docs/precision.md)
checked on any number of rays, sharded over every local device with
`jax.shard_map` and over processes with `jax.distributed`, checkpointed per
shard so that an interrupted run goes on where it stopped.

    octopaint-ref precision --rays 10000000 --precision f16 --checkpoint DIR

Rays start at the study's eye (in a leaf of depth `--depth`, 24 by default)
and run to the canvas boundary through the graded tree (density ignored);
ray i's direction is hashed from i alone, so any shard can be rebuilt
anywhere. Each shard of `--shard` rays is traced on a mesh of the process's
devices (shard_map: every device runs its own rays' loops, no collective
per step), and reduced to a summary holding only integers and maxima: the
ray count, the rays within asin(e0/L + 5 eps), a histogram of log10 of the
final angle error over fixed bins, the largest error with the smallest ray
index that reaches it, and the largest e0. Summaries merge by sums and
maxima, so the result is the same bits whatever the number of devices,
processes or shards, and whatever order shards finish in.

Several processes (hosts, or several on one host): start the same command
in each with `--coordinator HOST:PORT --processes N --process-id I`. Process
I takes shards I, I + N, ...; their summaries are gathered with JAX's
collectives (gloo on CPU) and every process reduces them the same way;
process 0 writes `--out`. Every process must hold the same number of
devices (JAX gathers over a mesh of processes x devices). A simulated
multi-device CPU:
`XLA_FLAGS=--xla_force_host_platform_device_count=8`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

# log10(angle in rad) bins: [-inf, -20), [-20, -19.75), ..., [0, inf).
BIN_EDGES = np.arange(-20.0, 0.0 + 1e-9, 0.25)
N_BINS = len(BIN_EDGES) + 1


def empty_summary() -> dict:
    return {"rays": 0, "within": 0, "hist": [0] * N_BINS, "max_angle": -1.0, "argmax": -1, "max_e0": 0.0}


def merge(a: dict, b: dict) -> dict:
    """The summary of two disjoint sets of rays: sums and maxima only, ties
    of the largest angle broken by the smaller ray index, so that merging is
    associative and commutative, exactly."""
    if (b["max_angle"], -b["argmax"]) > (a["max_angle"], -a["argmax"]):
        top, arg = b["max_angle"], b["argmax"]
    else:
        top, arg = a["max_angle"], a["argmax"]
    return {
        "rays": a["rays"] + b["rays"],
        "within": a["within"] + b["within"],
        "hist": [x + y for x, y in zip(a["hist"], b["hist"])],
        "max_angle": top,
        "argmax": arg,
        "max_e0": max(a["max_e0"], b["max_e0"]),
    }


def summarise(first: int, angle: np.ndarray, within: np.ndarray, e0: np.ndarray) -> dict:
    """The summary of rays first, first + 1, ... (f64 angles, bool, f64)."""
    with np.errstate(divide="ignore"):
        bins = np.searchsorted(BIN_EDGES, np.log10(angle), side="right")
    i = int(np.argmax(angle))  # the first index reaching the maximum
    return {
        "rays": int(len(angle)),
        "within": int(within.sum()),
        "hist": np.bincount(bins, minlength=N_BINS).astype(int).tolist(),
        "max_angle": float(angle[i]),
        "argmax": first + i,
        "max_e0": float(e0.max()),
    }


def directions(first: int, count: int) -> np.ndarray:
    """Unit directions of rays first .. first + count - 1, uniform on the
    sphere, each from its global index alone (a stream of its own)."""
    from .precision import sphere_directions

    return sphere_directions(count, stream=41, first=first)


class Tracer:
    """The study's scene on a mesh of this process's devices."""

    def __init__(self, precision: str, frame: str, depth: int, capacity: int, native: bool = False):
        import jax
        from jax.sharding import Mesh
        from jax.sharding import PartitionSpec as P

        from . import precision as PR
        from .arith import FORMATS, format_of
        from .raycast import Ray, Setup, device_tree, trace_ray

        arrays = PR.build_scene(paint=False, depth=depth)
        self.arrays = arrays
        self.tree, self.canvas = device_tree({**arrays, "sigma": np.zeros_like(arrays["sigma"])})
        self.eye, self.frac = PR.eye_split()
        self.precision, self.frame = precision, frame
        self.eps = FORMATS[precision].eps
        self.devices = jax.local_devices()
        mesh = Mesh(np.array(self.devices), ("rays",))
        setup = Setup(self.canvas, format_of(f"{precision}-native" if native else precision), frame, int(capacity), 1)
        self.setup = setup

        def local(tree, eye, frac, dirs):
            rays = Ray(eye, frac, dirs)
            bg = jax.numpy.zeros(3)
            one = lambda ray: trace_ray(tree, setup, ray, bg, np.uint64(0), last_only=True)
            return jax.vmap(one)(rays)

        spec = P("rays")
        self._trace = jax.jit(
            jax.shard_map(local, mesh=mesh, in_specs=(P(), spec, spec, spec), out_specs=spec, check_vma=False)
        )

    def shard(self, first: int, count: int) -> dict:
        """Trace rays first .. first + count - 1 and summarise them."""
        from . import precision as PR
        from . import ray_error as RE

        n_dev = len(self.devices)
        padded = -(-count // n_dev) * n_dev
        dirs = directions(first, count)
        rays = PR.rays_from(self.eye, self.frac, dirs)
        pad = padded - count
        eye = np.concatenate([rays.eye_lattice, np.full((pad, 3), -1, np.int64)])
        frac = np.concatenate([rays.frac, np.zeros((pad, 3))])
        d = np.concatenate([dirs, np.tile([[-1.0, 0.0, 0.0]], (pad, 1))])
        s, rec = self._trace(self.tree, eye, frac, d)
        steps = np.asarray(s.steps)[:count]
        if (steps >= self.setup.max_steps).any():
            raise RuntimeError(f"rays {first}..{first + count - 1}: a ray reached --capacity {self.setup.max_steps} cells")
        pick = lambda a: np.asarray(a)[:count, 0]
        w = PR.offsets(self.frame, self.canvas, pick(rec.origin), pick(rec.depth), pick(rec.p_exit), rays.eye_lattice, rays.frac)
        fmt_dirs = dirs.astype(PR.FORMATS[self.precision].numpy_dtype).astype(np.float64)
        angle, length = RE.angles(w, fmt_dirs)
        _, e0, _ = PR.start_error(self.tree, self.canvas, rays, self.precision, self.frame)
        within = angle <= RE.bound(e0, length, self.eps)
        return summarise(first, angle, within, e0)


def _write_json(path: str, obj) -> None:
    from .dump import write_atomic

    write_atomic(path, (json.dumps(obj, indent=1, sort_keys=True) + "\n").encode())


def run(args) -> dict | None:
    import jax

    if args.processes > 1:
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
        jax.distributed.initialize(args.coordinator, num_processes=args.processes, process_id=args.process_id)
    t0 = time.perf_counter()
    if args.arith == "native" and args.precision == "f64":
        raise SystemExit("octopaint-ref: precision: --arith native is for f16 and f32 (f64 is native already)")
    tracer = Tracer(args.precision, args.frame, args.depth, args.capacity, native=args.arith == "native")
    shards = [(k, k * args.shard, min(args.shard, args.rays - k * args.shard)) for k in range(-(-args.rays // args.shard))]
    mine = [sh for sh in shards if sh[0] % args.processes == args.process_id]
    if args.checkpoint:
        os.makedirs(args.checkpoint, exist_ok=True)
    total = empty_summary()
    done = computed = 0
    for k, first, count in mine:
        # Native shards are named apart: a checkpoint folder resumed with the
        # other --arith never mixes the two.
        prefix = "native_" if args.arith == "native" else ""
        path = os.path.join(args.checkpoint, f"{prefix}shard_{k:07d}.json") if args.checkpoint else None
        if path and os.path.exists(path):
            with open(path) as f:
                summary = json.load(f)
        else:
            if args.stop_after is not None and computed >= args.stop_after:
                print(f"octopaint-ref: precision: stopped after {computed} shards (--stop-after)", file=sys.stderr)
                return None
            summary = tracer.shard(first, count)
            computed += 1
            if path:
                _write_json(path, summary)
        total = merge(total, summary)
        done += count
        if not args.quiet:
            rate = done / max(time.perf_counter() - t0, 1e-9)
            print(
                f"\r[process {args.process_id}] {done:,}/{sum(c for _, _, c in mine):,} rays, {rate:,.0f} rays/s, "
                f"{len(tracer.devices)} devices, max angle {total['max_angle']:.3g} rad",
                end="",
                file=sys.stderr,
                flush=True,
            )
    if not args.quiet:
        print(file=sys.stderr)
    if args.processes > 1:
        from jax.experimental import multihost_utils

        packed = np.array([total["rays"], total["within"], total["argmax"], *total["hist"]], np.int64)
        maxima = np.array([total["max_angle"], total["max_e0"]], np.float64)
        all_packed = np.asarray(multihost_utils.process_allgather(packed))
        all_maxima = np.asarray(multihost_utils.process_allgather(maxima))
        total = empty_summary()
        for p, m in zip(all_packed, all_maxima):
            part = {"rays": int(p[0]), "within": int(p[1]), "argmax": int(p[2]), "hist": [int(v) for v in p[3:]],
                    "max_angle": float(m[0]), "max_e0": float(m[1])}
            total = merge(total, part)
    result = {
        "precision": args.precision,
        "arith": args.arith,
        "frame": args.frame,
        "eye_depth": args.depth,
        "eps": tracer.eps,
        "bin_edges_log10_rad": BIN_EDGES.tolist(),
        **total,
        "within_pct": 100.0 * total["within"] / max(total["rays"], 1),
    }
    if args.out and args.process_id == 0:
        _write_json(args.out, result)
    if not args.quiet and args.process_id == 0:
        seconds = time.perf_counter() - t0
        print(
            f"octopaint-ref: precision: {total['rays']:,} rays ({args.precision} {args.frame}, eye depth {args.depth}) on "
            f"{len(tracer.devices)} devices x {args.processes} processes in {seconds:.1f} s; within the bound: "
            f"{result['within_pct']:.4f}%; max angle {total['max_angle']:.3g} rad (ray {total['argmax']})",
            file=sys.stderr,
        )
    return result


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--rays", type=int, required=True, help="number of rays (hashed directions 0 .. N-1)")
    ap.add_argument("--precision", choices=("f16", "f32", "f64"), default="f16")
    ap.add_argument("--frame", choices=("local", "world"), default="local")
    ap.add_argument(
        "--arith",
        choices=("emulated", "native"),
        default="emulated",
        help="emulated: every operation rounded as IEEE says (the study); native: computed in the format's own type by XLA on the device",
    )
    ap.add_argument("--depth", type=int, default=24, help="depth of the eye's leaf (4 .. 24)")
    ap.add_argument("--shard", type=int, default=4096, help="rays per shard (the unit of checkpointing)")
    ap.add_argument("--capacity", type=int, default=512, help="most cells a ray may cross")
    ap.add_argument("--checkpoint", help="folder of per-shard summaries: a rerun skips the shards found there")
    ap.add_argument("--out", help="the result (JSON), written by process 0")
    ap.add_argument("--coordinator", default="localhost:12355", help="HOST:PORT of process 0 (several processes)")
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--process-id", type=int, default=0)
    ap.add_argument("--stop-after", type=int, help=argparse.SUPPRESS)  # tests: interrupt after K new shards
    ap.add_argument("--quiet", action="store_true")


def main(argv=None) -> int:
    from .jax_setup import configure  # JAX is imported where it is used, as below

    configure()
    ap = argparse.ArgumentParser(prog="octopaint-ref precision", description=__doc__.split("\n\n")[0])
    add_arguments(ap)
    return command(ap.parse_args(argv))


def command(args) -> int:
    """`octopaint-ref precision`: 0 done, 2 bad arguments, 3 stopped early."""
    if not (args.rays > 0 and args.shard > 0 and 4 <= args.depth <= 24 and 0 <= args.process_id < args.processes):
        print("octopaint-ref: precision: need --rays > 0, --shard > 0, --depth in 4..24, 0 <= --process-id < --processes", file=sys.stderr)
        return 2
    result = run(args)
    if result is not None and args.out is None and args.process_id == 0:
        print(json.dumps(result, sort_keys=True))
    return 0 if result is not None else 3


if __name__ == "__main__":
    sys.exit(main())
