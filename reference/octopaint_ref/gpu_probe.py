"""The GPU's ray caster against the bound and the oracle, ray by ray
(docs/precision.md, "The GPU's f16").

    python -m octopaint_ref.gpu_probe --painter painter/target/release/octopaint --out docs/precision

The study's scene (precision.build_scene) is written as a tree dump; the
painter's `octopaint probe` traces every pixel's ray of the study's near
and far cameras through it with the WGSL ray caster (f16 and f32) on the
adapter it finds, and writes one record per ray: where the ray stopped and
why, its last cell and exit point, its start cell and point, and the
direction the shader computed. For every ray this module then measures:

- the angle error of the last exit point (from the exact eye, against the
  shader's direction rounded to the working format, as the study does) and
  whether it is within the bound asin(e0 / L + 5 eps), e0 being the GPU's
  own start error;
- whether the reference's emulation (raycast.cast: every operation
  correctly rounded, no fused multiply-add, subnormals kept), given the
  shader's eye and direction, ends in the same cell after the same steps
  with the same exit point bit for bit, and where not, by how much;
- on a sample of rays, the mpmath path (oracle.exact_path, same direction):
  the same last cell, and the distance between the GPU's exit point and the
  exact one in edges of that cell.

Numbers go to gpu_probe.json and gpu_probe.md in --out, and a plot of the
angle errors against their bounds (gpu_probe.png).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from . import precision as P
from . import ray_error as RE
from .arith import FORMATS
from .camera import split_eye
from .dump import dump_bytes, load_dump, write_atomic
from .jax_setup import configure
from .oracle import exact_path
from .raycast import LEFT, OPAQUE, OVERFLOW, STATUS_NAMES, Ray, cast, device_tree, start_points

CAPACITY = 512  # steps recorded by the emulation (the study's rays need < 200)


def camera_json(cam) -> str:
    """A camera as `octopaint probe --camera` takes it (a trace's camera event)."""
    return json.dumps({"eye": list(cam.eye), "q": list(cam.q), "fov": list(cam.fov), "size": list(cam.size), "background": list(cam.background)})


def run_probe(painter: str, dump_path: str, cam, precision: str, out_path: str) -> dict:
    """Run `octopaint probe`; its arrays (numpy), plus `log` (its stderr).
    Raises RuntimeError with the painter's message when it fails."""
    argv = [painter, "probe", dump_path, "--camera", camera_json(cam), "--precision", precision, "--out", out_path]
    env = dict(os.environ, NODEVICE_SELECT="1")
    r = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(f"octopaint probe failed ({r.returncode}): {r.stderr.strip()}")
    with np.load(out_path) as z:
        out = {k: z[k] for k in z.files}
    out["log"] = r.stderr.strip()
    return out


def _last(rec, steps):
    """The last recorded step of each ray (steps >= 1)."""
    i = np.arange(len(steps))
    k = np.maximum(steps - 1, 0)
    return rec.cell[i, k], rec.depth[i, k], rec.origin[i, k], rec.p_exit[i, k]


def compare(arrays: dict, cam, probe: dict, precision: str, device=None, exact_rays: int = 64) -> dict:
    """Every ray of `probe` (one camera, one precision) against the bound,
    the emulation and (on `exact_rays` evenly spaced rays that did not
    leave at once) mpmath. Returns the summary and per-ray arrays."""
    fmt = FORMATS[precision]
    tree, canvas = device if device is not None else device_tree(arrays)
    D = canvas.max_depth
    n = len(probe["status"])
    dirs = probe["dir"].astype(np.float64)
    d_fmt = probe["dir"].astype(fmt.numpy_dtype).astype(np.float64)
    # The exact eye (f64 split of the camera's eye), for every error.
    lu = canvas.root_size * 2.0**-D
    eye_l, eye_f = split_eye(cam.eye, lu)
    eye_l = np.broadcast_to(np.asarray(eye_l, np.int64), (n, 3))
    eye_f = np.broadcast_to(np.asarray(eye_f, np.float64), (n, 3))
    steps = probe["steps"].astype(np.int64)
    traced = steps > 0
    # The GPU's last exit point and start point, from the exact eye.
    w = RE.offsets_local(probe["origin"], probe["depth"], probe["exit"], eye_l, eye_f, D)
    angle, length = RE.angles(w, d_fmt)
    w0 = RE.offsets_local(probe["start_origin"], probe["start_depth"], probe["start"], eye_l, eye_f, D)
    # e0: how far the start point is from the ray. With the eye inside,
    # its distance from the eye (the study's e0); from outside, its
    # distance from the line eye + t d (the entry point is far along it).
    a0, l0 = RE.angles(w0, d_fmt)
    e0 = l0 if int(probe["inside"]) else l0 * np.sin(np.minimum(a0, np.pi / 2))
    bound = RE.bound(e0, np.where(length > 0, length, 1.0), fmt.eps)
    within = ~traced | (angle <= bound)

    # The emulation, given what the shader was given: its eye split (the
    # host's f32 eye offset) and its directions.
    if int(probe["inside"]):
        em_eye = np.broadcast_to(probe["eye_cell"].astype(np.int64), (n, 3)).copy()
        em_frac = np.broadcast_to(probe["eye_rel"].astype(np.float64), (n, 3)).copy()
    else:
        em_eye, em_frac = eye_l.copy(), eye_f.copy()
    rays = Ray(em_eye, em_frac, dirs)
    s, rec = cast(tree, canvas, rays, precision, "local", max_steps=CAPACITY, record=CAPACITY)
    em_cell, em_depth, em_origin, em_exit = _last(rec, s.steps)
    _, _, sd, so, sp = start_points(tree, canvas, rays, precision, "local")
    same_start = (sd == probe["start_depth"]) & np.all(so == probe["start_origin"], axis=1) & np.all(sp == probe["start"].astype(np.float64), axis=1)
    same_path = (s.steps == steps) & (em_cell == probe["cell"]) & (s.status == probe["status"])
    exit_gpu = probe["exit"].astype(fmt.numpy_dtype)
    exit_em = em_exit.astype(fmt.numpy_dtype)
    same_bits = same_path & np.all(exit_gpu.view(np.uint16 if precision == "f16" else np.uint32) == exit_em.view(np.uint16 if precision == "f16" else np.uint32), axis=1)
    # Where the paths agree but the bits do not: the difference in ulps
    # of the working format at the emulated value.
    ulp = np.spacing(np.abs(exit_em).astype(fmt.numpy_dtype)).astype(np.float64)
    ulps = np.where((same_path & same_start)[:, None], np.abs(probe["exit"].astype(np.float64) - em_exit) / ulp, 0.0).max(axis=1)
    em_w = RE.offsets_local(em_origin, em_depth, em_exit, eye_l, eye_f, D)
    em_angle, _ = RE.angles(em_w, d_fmt)

    # mpmath on a sample: the same direction (rounded as the shader does).
    sample = np.nonzero(traced & (probe["status"] != OVERFLOW))[0]
    sample = sample[np.linspace(0, len(sample) - 1, min(exact_rays, len(sample))).astype(int)] if len(sample) else sample
    exact_same, exact_err = 0, []
    if int(probe["inside"]):
        for i in sample:
            k = int(steps[i])
            ex = exact_path(arrays, eye_l[i], eye_f[i], d_fmt[i], max_steps=k)
            if len(ex.cells) != k or ex.cells[-1] != int(probe["cell"][i]):
                continue
            exact_same += 1
            hi, lo = P.exact_offsets(ex.exit[-1:], eye_l[i], eye_f[i])
            wi = (w[0][i : i + 1], w[1][i : i + 1])
            exact_err.append(float(RE.position_error(wi, (hi, lo))[0] / 2.0 ** (D - int(probe["depth"][i]))))
    statuses = {STATUS_NAMES[k]: int((probe["status"] == k).sum()) for k in (LEFT, OPAQUE, OVERFLOW)}
    worst = int(np.argmax(np.where(traced, angle / np.maximum(bound, 1e-300), 0))) if traced.any() else 0
    summary = {
        "rays": n,
        "traced": int(traced.sum()),
        "status": statuses,
        "max_angle_rad": float(angle[traced].max()) if traced.any() else 0.0,
        "median_angle_rad": float(np.median(angle[traced])) if traced.any() else 0.0,
        "emulated_max_angle_rad": float(em_angle[traced].max()) if traced.any() else 0.0,
        "within_bound": int(within.sum()),
        "worst_ratio_to_bound": float(angle[worst] / bound[worst]) if traced.any() else 0.0,
        "same_start": int(same_start.sum()),
        "same_path": int(same_path.sum()),
        "same_bits": int(same_bits.sum()),
        "same_bits_of_same_start": int((same_bits & same_start).sum()),
        "max_ulps_same_start": float(ulps.max()) if n else 0.0,
        "exact_sampled": len(sample) if int(probe["inside"]) else 0,
        "exact_same_cell": exact_same,
        "exact_max_position_error_edges": max(exact_err) if exact_err else None,
        "adapter": bytes(probe["adapter"]).decode(),
    }
    per_ray = {"angle": angle, "bound": bound, "within": within, "same_start": same_start, "same_path": same_path, "same_bits": same_bits, "ulps": ulps, "traced": traced}
    return {"summary": summary, "rays": per_ray}


def run(painter: str, out: str, size: int = 256, paint: bool = True, exact_rays: int = 64, precisions=("f16", "f32")) -> dict:
    """The whole comparison: the scene, both cameras, each precision."""
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    arrays = P.build_scene(paint=paint)
    device = device_tree(arrays)
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        dump_path = os.path.join(tmp, "scene.npz")
        write_atomic(dump_path, dump_bytes(arrays))
        arrays = load_dump(dump_path)  # as the painter reads it
        for name, cam in (("near", P.near_camera((size, size))), ("far", P.far_camera((size, size)))):
            for precision in precisions:
                probe = run_probe(painter, dump_path, cam, precision, os.path.join(tmp, f"{name}_{precision}.npz"))
                r = compare(arrays, cam, probe, precision, device, exact_rays)
                results[f"{name}_{precision}"] = r
                print(f"{name} {precision}: {r['summary']}", file=sys.stderr)
    report = {k: v["summary"] for k, v in results.items()}
    report["_seconds"] = time.perf_counter() - t0
    report["_size"] = size
    with open(os.path.join(out, "gpu_probe.json"), "w") as f:
        json.dump(report, f, indent=1, sort_keys=True)
    with open(os.path.join(out, "gpu_probe.md"), "w") as f:
        f.write(table(report))
    plot(results, os.path.join(out, "gpu_probe.png"))
    return results, report


def table(report: dict) -> str:
    rows = [
        "| camera | precision | rays | max angle (rad) | emulated max | within bound | same start as emulation | same last cell and steps | same exit bits (of same start) | max ulps apart (same start) | mpmath: same last cell | max position error (edges) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for key in sorted(k for k in report if not k.startswith("_")):
        s = report[key]
        cam, prec = key.split("_")
        exact = f"{s['exact_same_cell']} of {s['exact_sampled']}" if s["exact_sampled"] else "(eye outside)"
        err = f"{s['exact_max_position_error_edges']:.2g}" if s["exact_max_position_error_edges"] is not None else ""
        rows.append(
            f"| {cam} | {prec} | {s['rays']:,} | {s['max_angle_rad']:.2g} | {s['emulated_max_angle_rad']:.2g} | {s['within_bound']:,} "
            f"| {s['same_start']:,} | {s['same_path']:,} | {s['same_bits']:,} ({s['same_bits_of_same_start']:,}) | {s['max_ulps_same_start']:.0f} | {exact} | {err} |"
        )
    adapter = next(v["adapter"] for k, v in report.items() if not k.startswith("_"))
    return "\n".join(rows) + f"\n\nAdapter: {adapter}; {report['_size']}x{report['_size']} rays per camera; {report['_seconds']:.0f} s.\n"


def plot(results: dict, path: str) -> None:
    """Per camera and precision: the histogram of the GPU's angle errors,
    and the smallest bound over the rays (every error must be left of it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(3.6 * len(results), 3.2), squeeze=False)
    for ax, (key, r) in zip(axes[0], results.items()):
        t = r["rays"]["traced"]
        a, b = r["rays"]["angle"][t], r["rays"]["bound"][t]
        lo = np.log10(max(a[a > 0].min() if (a > 0).any() else 1e-12, 1e-20))
        bins = np.logspace(lo, np.log10(b.min()) + 0.3, 60)
        ax.hist(np.maximum(a, 10**lo), bins=bins, color="tab:blue")
        ax.axvline(b.min(), color="k", ls="--", lw=0.9, label=f"bound, smallest: {b.min():.1e}")
        ax.set_xscale("log")
        ax.set_xlabel("angle error of the last exit (rad)")
        ax.set_title(key.replace("_", " "))
        ax.legend(fontsize=7, loc="upper left")
    axes[0][0].set_ylabel("rays")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--painter", required=True, help="the octopaint executable")
    ap.add_argument("--out", required=True, help="folder for gpu_probe.json, .md, .png")
    ap.add_argument("--size", type=int, default=256, help="rays per camera: size x size (default 256)")
    ap.add_argument("--exact-rays", type=int, default=64, help="rays per camera checked against mpmath (default 64)")


def command(a) -> int:
    """Exit status 1 when the painter fails or a ray is beyond its bound."""
    try:
        results, report = run(a.painter, a.out, a.size, exact_rays=a.exact_rays)
    except (RuntimeError, OSError) as e:
        print(f"octopaint-ref gpu-probe: {e}", file=sys.stderr)
        return 1
    print(table(report))
    bad = {k: r["summary"]["rays"] - r["summary"]["within_bound"] for k, r in results.items()}
    if any(bad.values()):
        print(f"rays beyond the bound: {bad}", file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="octopaint-ref gpu-probe", description=__doc__.split("\n\n")[0])
    add_arguments(ap)
    return command(ap.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
