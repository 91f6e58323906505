//! What a cell exports: its extinction and colour, and, for a cell with
//! children seen at its own depth (an export coarser than the tree), the
//! aggregate of its leaves (docs/export.md, "Values").

use octopaint_tree::pool::{NONE, Tree};

/// A cell's exported value: extinction per canvas unit and sRGB-encoded
/// colour in [0, 1] (spec 5), in f64 until a format rounds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Value {
    pub sigma: f64,
    pub rgb: [f64; 3],
}

impl Value {
    pub const EMPTY: Value = Value { sigma: 0.0, rgb: [0.0; 3] };
}

/// How colours are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourSpace {
    /// Linear (Blender's volume and glTF's vertex colours expect it).
    Linear,
    /// The stored sRGB encoding, as the painter blends it.
    Srgb,
}

impl ColourSpace {
    pub fn encode(self, rgb: [f64; 3]) -> [f32; 3] {
        match self {
            ColourSpace::Srgb => rgb.map(|v| v as f32),
            ColourSpace::Linear => rgb.map(|v| srgb_to_linear(v) as f32),
        }
    }
}

/// The sRGB transfer function inverted (IEC 61966-2-1).
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

/// A leaf's own value.
pub fn leaf_value(tree: &Tree, c: u32) -> Value {
    let i = c as usize;
    Value { sigma: f64::from(tree.sigma()[i]), rgb: tree.rgb()[i].map(|v| f64::from(v) / 255.0) }
}

/// The value of cell `c` seen at its own depth: a leaf's own; for a cell
/// with children, the volume-weighted mean extinction of its leaves (what a
/// ray crossing the whole cell sees to first order) and their colour
/// weighted by extinction times volume, so that empty leaves do not pale it
/// (a plain volume-weighted mean where every leaf is empty).
pub fn cell_value(tree: &Tree, c: u32) -> Value {
    if tree.first_child()[c as usize] == NONE {
        return leaf_value(tree, c);
    }
    let d0 = i32::from(tree.depth()[c as usize]);
    let (mut sigma, mut rgb_dense, mut rgb_all, mut w_dense) = (0.0, [0.0f64; 3], [0.0f64; 3], 0.0);
    let mut stack = vec![c];
    while let Some(x) = stack.pop() {
        let fc = tree.first_child()[x as usize];
        if fc != NONE {
            stack.extend(fc..fc + 8);
            continue;
        }
        // Volume relative to c: 8^-(d - d0), a power of two, exact.
        let w = (2.0f64).powi(-3 * (i32::from(tree.depth()[x as usize]) - d0));
        let v = leaf_value(tree, x);
        sigma += v.sigma * w;
        for a in 0..3 {
            rgb_all[a] += v.rgb[a] * w;
            rgb_dense[a] += v.rgb[a] * v.sigma * w;
        }
        w_dense += v.sigma * w;
    }
    let rgb = if w_dense > 0.0 { rgb_dense.map(|v| (v / w_dense).clamp(0.0, 1.0)) } else { rgb_all };
    Value { sigma, rgb }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-15);
        // 0.5 in sRGB is 0.214 linear (the usual table value 0.21404).
        assert!((srgb_to_linear(0.5) - 0.214_041_140_5).abs() < 1e-9);
        // Continuous at the knee but for the standard's own rounding of
        // its constants (a jump of 2.3e-9, far below an 8-bit step).
        let k = 0.04045;
        assert!((srgb_to_linear(k) - srgb_to_linear(k + 1e-12)).abs() < 3e-9);
    }
}
