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
        }
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
