//! What a cell stores when the stroke maximum at it rises to `a` (spec 8.5,
//! rounded by spec 5): the blend of each mode channel by channel, and the
//! general form through `brush::blend` it must equal bit for bit.
//! Reference twin: `Painting._apply` in reference/octopaint_ref/paint.py.

use super::StrokeState;
use crate::brush::{BlendOf, TINY, blend, quantize_rgb, quantize_sigma};
use octopaint_model::Mode;

/// `v / 255.0` for every stored channel value, computed once (the same
/// correctly rounded quotients the blend would compute each time).
static UNIT_RGB: [f64; 256] = {
    let mut t = [0.0; 256];
    let mut v = 0;
    while v < 256 {
        t[v] = v as f64 / 255.0;
        v += 1;
    }
    t
};

impl StrokeState {
    /// What a cell with `before` stores after blending the colour `colour`
    /// at stroke maximum `a` (spec 8.5, rounded by spec 5).
    #[inline(always)]
    pub(super) fn stored(&self, before_rgb: [u8; 3], before_sigma: f32, colour: [f64; 3], a: f64) -> ([u8; 3], f32) {
        if a == 0.0 && before_sigma.is_finite() {
            // The blend keeps the cell, and rounding a stored value gives
            // it back: `v / 255` to a byte is `v`, and a finite f32 through
            // f64 is itself (half the new children lie outside the brush).
            return (before_rgb, before_sigma);
        }
        if a == 0.0 {
            return self.stored_general(before_rgb, before_sigma, colour, a); // a NaN or infinite density
        }
        let (rgb, sigma) = self.blended(before_rgb, f64::from(before_sigma), colour, a);
        (quantize_rgb(rgb), quantize_sigma(sigma))
    }

    /// `brush::blend` of a cell at `a != 0`, channel by channel, with the
    /// same operations in the same order (so the same bits, unrounded): no
    /// arrays through memory, which the general form moves, and no call.
    #[inline(always)]
    pub(super) fn blended(&self, before_rgb: [u8; 3], bs: f64, colour: [f64; 3], a: f64) -> ([f64; 3], f64) {
        let before = |i: usize| UNIT_RGB[before_rgb[i] as usize];
        match self.brush.mode {
            Mode::Paint | Mode::Pickup => {
                let fresh = bs == 0.0;
                let channel = |i: usize| {
                    let base = if fresh { colour[i] } else { before(i) };
                    base + (colour[i] - base) * a
                };
                ([channel(0), channel(1), channel(2)], bs + (self.sigma_b - bs) * a)
            }
            Mode::Erase => ([before(0), before(1), before(2)], bs * (1.0 - a * self.alpha)),
            Mode::Recolor if bs > 0.0 => {
                let t = a * self.alpha;
                let channel = |i: usize| before(i) + (colour[i] - before(i)) * t;
                ([channel(0), channel(1), channel(2)], bs)
            }
            Mode::Recolor => ([before(0), before(1), before(2)], bs),
            Mode::Mix => {
                let fresh = bs == 0.0;
                let mut wb = self.brush.mix_ratio * a * self.sigma_b;
                if wb < TINY {
                    wb = 0.0;
                }
                let den = bs + wb;
                let channel = |i: usize| {
                    let base = if fresh { colour[i] } else { before(i) };
                    if den > 0.0 { (bs * base + wb * colour[i]) / den } else { base }
                };
                ([channel(0), channel(1), channel(2)], bs + a * self.sigma_b)
            }
        }
    }

    /// [`StrokeState::stored`] for every mode, through `brush::blend`.
    #[inline(never)]
    fn stored_general(&self, before_rgb: [u8; 3], before_sigma: f32, colour: [f64; 3], a: f64) -> ([u8; 3], f32) {
        let before = [UNIT_RGB[before_rgb[0] as usize], UNIT_RGB[before_rgb[1] as usize], UNIT_RGB[before_rgb[2] as usize]];
        let b = &self.brush;
        let (rgb, sigma) =
            blend(&BlendOf { mode: b.mode, sigma_b: self.sigma_b, alpha: self.alpha, mix_ratio: b.mix_ratio }, before, f64::from(before_sigma), colour, a);
        (quantize_rgb(rgb), quantize_sigma(sigma))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::hash32;
    use crate::paint::Painting;
    use octopaint_model::{Brush, Canvas, Shape};

    /// The blends of `StrokeState::stored`, computed channel by channel,
    /// store the same bytes and f32 as the general form through
    /// `brush::blend` in every mode for every kind of input: empty and
    /// filled cells (a NaN and an infinite density too), any stored colour,
    /// mix ratios from 0 to 1, maxima from 0 and tiny to 1, and the edges.
    #[test]
    fn the_paint_blend_stores_what_the_general_blend_stores() {
        let unit = |i: u32| f64::from(hash32(i)) / 4294967296.0;
        for mode in [Mode::Paint, Mode::Pickup, Mode::Erase, Mode::Recolor, Mode::Mix] {
            for i in 0..2000u32 {
                let colour = [unit(7 * i), unit(7 * i + 1), unit(7 * i + 2)];
                let opacity = [1.0, 0.5, unit(7 * i + 3)][i as usize % 3];
                let mut brush = Brush::new(Shape::Sphere, mode, 0.01 + unit(7 * i + 4), colour, opacity, 0.5);
                brush.mix_ratio = [1.0, 0.0, unit(7 * i + 5)][i as usize % 3];
                let mut painting = Painting::new(&Canvas { roots: [1, 1, 1], max_depth: 4, root_size: 1.0, capacity: 64 });
                painting.begin_stroke(&brush);
                let st = painting.stroke.as_ref().expect("stroke");
                let before_rgb = [hash32(i) as u8, (hash32(i) >> 8) as u8, (hash32(i) >> 16) as u8];
                let sigmas = [0.0f32, 1e-30, 0.25, 3.0e5, f32::MAX, unit(i + 11) as f32 * 100.0, f32::NAN, f32::INFINITY];
                let maxima = [0.0, TINY, 1e-6, 0.5, 1.0, unit(i + 13), unit(i + 17) * 1e-3];
                for &before_sigma in &sigmas {
                    for &a in &maxima {
                        if a != 0.0 {
                            // Unrounded, bit for bit: a change of one ulp
                            // rarely moves a stored byte.
                            let before = before_rgb.map(|v| f64::from(v) / 255.0);
                            let bs = f64::from(before_sigma);
                            let (rgb, sigma) = st.blended(before_rgb, bs, colour, a);
                            let (g_rgb, g_sigma) =
                                blend(&BlendOf { mode, sigma_b: st.sigma_b, alpha: st.alpha, mix_ratio: brush.mix_ratio }, before, bs, colour, a);
                            assert_eq!(
                                (rgb.map(f64::to_bits), sigma.to_bits()),
                                (g_rgb.map(f64::to_bits), g_sigma.to_bits()),
                                "{mode:?} {before_rgb:?} {before_sigma} {a}"
                            );
                        }
                        let (fast, general) = (st.stored(before_rgb, before_sigma, colour, a), st.stored_general(before_rgb, before_sigma, colour, a));
                        assert_eq!((fast.0, fast.1.to_bits()), (general.0, general.1.to_bits()), "{mode:?} {before_rgb:?} {before_sigma} {colour:?} {a}");
                    }
                }
            }
        }
    }
}
