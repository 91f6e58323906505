"""Camera rays (spec 6) and the eye split into lattice integer plus fraction
(spec 7), computed on the host in f64 numpy, one rounding per operation in
the order the spec writes them. Painter twin: painter/gpu/src/camera.rs.
"""

from __future__ import annotations

import math

import numpy as np

from .brush import quat_to_matrix


def pixel_directions(camera) -> np.ndarray:
    """Unit ray directions in canvas space through every pixel centre,
    f64 [h, w, 3], row 0 at the top (spec 6)."""
    w, h = camera.size
    left, right, up, down = camera.fov
    tl, tr, tu, td = math.tan(left), math.tan(right), math.tan(up), math.tan(down)
    i = np.arange(w, dtype=np.float64)
    j = np.arange(h, dtype=np.float64)
    tx = tl + (i + 0.5) / w * (tr - tl)
    ty = tu - (j + 0.5) / h * (tu - td)
    m = quat_to_matrix(camera.q)
    tx2 = np.broadcast_to(tx[None, :], (h, w))
    ty2 = np.broadcast_to(ty[:, None], (h, w))
    v = [m[r][0] * tx2 + m[r][1] * ty2 + m[r][2] * -1.0 for r in range(3)]
    n = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return np.stack([v[0] / n, v[1] / n, v[2] / n], axis=-1)


def split_eye(eye_canvas, lattice_unit: float):
    """(eye_lattice int64 [3], frac f64 [3]): E = floor(eye / lattice_unit)
    and phi = eye / lattice_unit - E in [0, 1) (spec 7). The division is one
    rounding; E may lie outside the canvas."""
    x = np.asarray(eye_canvas, np.float64) / lattice_unit
    e = np.floor(x)
    return e.astype(np.int64), x - e


def look_at(eye, target) -> tuple:
    """Quaternion [x, y, z, w] turning the camera's -z towards target with
    +y as near up as possible (for experiments; traces carry their own q)."""
    f = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
    z = -f / np.linalg.norm(f)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.stack([x, y, z], axis=1)  # columns: camera axes in canvas space
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    qx = math.copysign(math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    qy = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    qz = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return (qx, qy, qz, w)


def orbit_camera(centre, distance: float, azimuth_deg: float, elevation_deg: float, size, fov_rad: float, background=(0.0, 0.0, 0.0)):
    """A trace.Camera on a sphere around `centre`, looking at it (examples)."""
    from .trace import Camera

    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    offset = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)]) * distance
    eye = np.asarray(centre, np.float64) + offset
    return Camera(tuple(float(v) for v in eye), look_at(eye, centre), (-fov_rad, fov_rad, fov_rad, -fov_rad), tuple(size), tuple(background))
