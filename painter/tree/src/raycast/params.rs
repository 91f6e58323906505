//! The ray caster's per-frame constants, set up on the host exactly as
//! the GPU's uniform receives them (painter/gpu/src/raycast.rs).

use super::MAX_STEPS;
use crate::brush::quat_to_rows;
use crate::lattice::Lattice;
use crate::trace::{Camera, Light};

/// The per-frame constants of the ray caster, as the shader's uniform
/// holds them (painter/gpu/src/raycast.rs uploads exactly these fields).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayParams {
    /// The eye's lattice point clamped into the canvas.
    pub eye_cell: [u32; 3],
    /// The eye minus `eye_cell` in lattice units (the fraction when inside).
    pub eye_rel: [f32; 3],
    pub lattice_unit: f32,
    pub roots: [u32; 3],
    pub max_depth: u32,
    pub extent: [f32; 3],
    pub extent_max: [u32; 3],
    pub tan_fov: [f32; 4],
    pub rot: [[f32; 3]; 3],
    pub background: [f32; 3],
    pub width: u32,
    pub height: u32,
    pub max_steps: u32,
    pub n_roots: u32,
    pub inside: bool,
    /// Skip cells whose parent/child links disagree (spec 7). Off only for
    /// the real-time benchmark's strategies that measure the difference.
    pub skip_invalid: bool,
    /// The ground grid behind everything, a view aid (see
    /// [`RayParams::with_grid`]); spacing 0: none, the background alone.
    pub grid: [f32; 4],
    /// 0 unlit, 1 lit, 2 lit with a shadow ray (spec 6.1; see
    /// [`RayParams::with_light`]).
    pub lit: u32,
    /// The unit direction towards the light, and its intensity.
    pub light: [f32; 4],
    pub ambient: f32,
    /// The level of detail's `lam = min(k·alpha, 1)` (spec 7), 0 for none
    /// (every ray walks to the leaves; see [`RayParams::with_lod`]).
    pub lod: f32,
    /// The camera's view axis `M(q)·(0, 0, -1)`, for the cut's view depths.
    pub forward: [f32; 3],
}

impl RayParams {
    /// The frame constants of `camera` over `tree`'s canvas, computed in
    /// f64 on the host (spec 6, 7: the eye split into a lattice point and a
    /// fraction) and rounded once to f32.
    pub fn new(lat: &Lattice, camera: &Camera) -> Self {
        let lu = lat.lattice_unit;
        let mut eye_cell = [0u32; 3];
        let mut eye_rel = [0f32; 3];
        let mut inside = true;
        for a in 0..3 {
            let x = camera.eye[a] / lu;
            let e = x.floor();
            let phi = x - e;
            let top = (lat.extent[a] - 1) as f64;
            let clamped = e.clamp(0.0, top);
            inside &= e == clamped;
            eye_cell[a] = clamped as u32;
            eye_rel[a] = ((e - clamped) + phi) as f32;
        }
        let rows = quat_to_rows(camera.q);
        let [l, r, u, d] = camera.fov;
        RayParams {
            eye_cell,
            eye_rel,
            lattice_unit: lu as f32,
            roots: lat.roots,
            max_depth: lat.max_depth,
            extent: lat.extent.map(|e| e as f32),
            extent_max: lat.extent.map(|e| (e - 1) as u32),
            tan_fov: [l.tan() as f32, r.tan() as f32, u.tan() as f32, d.tan() as f32],
            rot: rows.map(|row| row.map(|v| v as f32)),
            background: camera.background.map(|v| v as f32),
            width: camera.size[0],
            height: camera.size[1],
            max_steps: MAX_STEPS,
            n_roots: lat.n_roots,
            inside,
            skip_invalid: true,
            grid: [0.0; 4],
            lit: 0,
            light: [0.0; 4],
            ambient: 0.0,
            lod: 0.0,
            forward: [-rows[0][2] as f32, -rows[1][2] as f32, -rows[2][2] as f32],
        }
    }

    /// These constants at level of detail `k` for `camera` (spec 7): rays
    /// stop at cells no wider than `k` footprints of a pixel of `camera`'s
    /// image, whose size (the one rendered, so a frame at reduced
    /// resolution is a coarser one) and field of view give the pixel pitch
    /// `alpha = max((tan r - tan l)/w, (tan u - tan d)/h)`, in f64 with
    /// `lam = min(k·alpha, 1)` rounded once to f32. `k = 0`: full depth.
    /// [`check_lod`] says which `k` are accepted.
    pub fn with_lod(mut self, camera: &Camera, k: f64) -> Self {
        let [l, r, u, d] = camera.fov;
        let [w, h] = camera.size.map(f64::from);
        let alpha = ((r.tan() - l.tan()) / w).max((u.tan() - d.tan()) / h);
        let lam = (k * alpha).min(1.0);
        self.lod = if k > 0.0 && lam > 0.0 { lam as f32 } else { 0.0 };
        self
    }

    /// These constants lit by `light` (spec 6.1): its direction normalised
    /// in f64 and rounded once to f32. None or off: unlit.
    pub fn with_light(mut self, light: Option<&Light>) -> Self {
        match light {
            Some(l) if l.on => {
                let [x, y, z] = l.dir;
                let n = (x * x + y * y + z * z).sqrt();
                self.lit = if l.shadows { 2 } else { 1 };
                self.light = [(x / n) as f32, (y / n) as f32, (z / n) as f32, l.intensity as f32];
                self.ambient = l.ambient as f32;
            }
            _ => {
                self.lit = 0;
                self.light = [0.0; 4];
                self.ambient = 0.0;
            }
        }
        self
    }

    /// These constants with the ground grid on the canvas floor (y = 0) for
    /// a camera at `eye` (canvas units): lines every power of ten of
    /// canvas units at or below the eye's height, brighter ones every ten
    /// of those. The eye's x and z are reduced modulo ten spacings in f64,
    /// so the shader's f32 arithmetic sees small numbers anywhere on a
    /// 40 km canvas. No grid with the eye at or below the floor.
    pub fn with_grid(mut self, eye: [f64; 3]) -> Self {
        let h = eye[1];
        if !(h > 0.0 && h.is_finite()) {
            self.grid = [0.0; 4];
            return self;
        }
        let s = 10f64.powf(h.log10().floor());
        let m = 10.0 * s;
        self.grid = [eye[0].rem_euclid(m) as f32, h as f32, eye[2].rem_euclid(m) as f32, s as f32];
        self
    }
}

/// The largest level of detail accepted (spec 7): beyond it every cell of
/// an ordinary view is small anyway (`lam` is capped at 1).
pub const MAX_LOD: f64 = 64.0;

/// The level of detail the window and the headset start at (spec 7):
/// about one cell per pixel.
pub const DEFAULT_LOD: f64 = 1.0;

/// `k` if it is a level of detail (a number in `[0, MAX_LOD]`), or why not.
pub fn check_lod(k: f64) -> Result<f64, String> {
    if (0.0..=MAX_LOD).contains(&k) { Ok(k) } else { Err(format!("level of detail {k}: must be a number in [0, {MAX_LOD}] (0: full depth)")) }
}

/// `--lod K[,K...]` (`octopaint replay`, as `octopaint-ref replay`): the
/// levels of detail every image is drawn at, as (text as given, k): each a
/// decimal number (`0`, `1`, `0.5`) in `[0, MAX_LOD]`, none twice. The text
/// names the image of a k other than 0: `<name>.lod<text>.png`.
pub fn parse_lods(text: &str) -> Result<Vec<(String, f64)>, String> {
    let mut out: Vec<(String, f64)> = Vec::new();
    for part in text.split(',') {
        let decimal = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
        let ok = match part.split_once('.') {
            Some((a, b)) => decimal(a) && decimal(b),
            None => decimal(part),
        };
        if !ok {
            return Err(format!("--lod {text:?}: {part:?} is not a decimal number such as 0, 1 or 0.5"));
        }
        let k = check_lod(part.parse::<f64>().map_err(|e| format!("--lod {text:?}: {e}"))?)?;
        if out.iter().any(|(_, q)| *q == k) {
            return Err(format!("--lod {text:?}: level {part} given twice"));
        }
        out.push((part.to_string(), k));
    }
    Ok(out)
}
