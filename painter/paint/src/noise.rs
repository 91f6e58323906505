//! Improved Perlin noise with a permutation built from a seed by hashing
//! indices (spec 8.6), so that Python, JAX and Rust give the same values.
//! Reference twin: reference/octopaint_ref/noise.py.

/// lowbias32 (Chris Wellons): a 32-bit integer hash with good avalanche.
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7FEB_352D);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846C_A68B);
    x ^= x >> 16;
    x
}

/// The 512-entry permutation for `seed`: a Fisher-Yates shuffle of 0..255
/// driven by `hash32(seed + i·0x9E3779B9)`, repeated twice.
pub fn permutation(seed: u32) -> [u16; 512] {
    let mut p: [u16; 256] = std::array::from_fn(|i| i as u16);
    for i in (1..256u32).rev() {
        let j = hash32(seed.wrapping_add(i.wrapping_mul(0x9E37_79B9))) % (i + 1);
        p.swap(i as usize, j as usize);
    }
    std::array::from_fn(|i| p[i % 256])
}

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(t: f64, a: f64, b: f64) -> f64 {
    a + t * (b - a)
}

#[inline]
fn grad(h: u16, x: f64, y: f64, z: f64) -> f64 {
    let h = h & 15;
    let u = if h < 8 { x } else { y };
    let v = if h < 4 {
        y
    } else if h == 12 || h == 14 {
        x
    } else {
        z
    };
    (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
}

/// `floor(p) mod 256` of a floored coordinate, exact for every finite
/// value (spec 8.6: `fl / 256` and `256·floor(…)` are exact scalings and
/// the difference is a small integer); NaN (from absurd scales) reads as 0.
#[inline]
fn wrap(fl: f64) -> usize {
    let m = fl - 256.0 * (fl / 256.0).floor();
    if m.is_nan() { 0 } else { m as usize }
}

/// Improved Perlin noise at `p`, in about [-1, 1].
pub fn perlin(perm: &[u16; 512], p: [f64; 3]) -> f64 {
    let fl = p.map(f64::floor);
    let (xi, yi, zi) = (wrap(fl[0]), wrap(fl[1]), wrap(fl[2]));
    let (x, y, z) = (p[0] - fl[0], p[1] - fl[1], p[2] - fl[2]);
    let (u, v, w) = (fade(x), fade(y), fade(z));
    let pm = |i: usize| perm[i] as usize;
    let a = pm(xi) + yi;
    let aa = pm(a) + zi;
    let ab = pm(a + 1) + zi;
    let b = pm(xi + 1) + yi;
    let ba = pm(b) + zi;
    let bb = pm(b + 1) + zi;
    let g = |h: usize, x: f64, y: f64, z: f64| grad(perm[h], x, y, z);
    lerp(
        w,
        lerp(v, lerp(u, g(aa, x, y, z), g(ba, x - 1.0, y, z)), lerp(u, g(ab, x, y - 1.0, z), g(bb, x - 1.0, y - 1.0, z))),
        lerp(
            v,
            lerp(u, g(aa + 1, x, y, z - 1.0), g(ba + 1, x - 1.0, y, z - 1.0)),
            lerp(u, g(ab + 1, x, y - 1.0, z - 1.0), g(bb + 1, x - 1.0, y - 1.0, z - 1.0)),
        ),
    )
}

/// Normalised fBm: `sum_o gain^o · perlin(x·(scale·2^o)) / sum_o gain^o`.
pub fn fbm(perm: &[u16; 512], x: [f64; 3], scale: f64, octaves: u32, gain: f64) -> f64 {
    let mut total = 0.0;
    let mut norm = 0.0;
    let mut amp = 1.0;
    let mut octave_scale = 1.0;
    for _ in 0..octaves {
        let s = scale * octave_scale;
        total += amp * perlin(perm, x.map(|v| v * s));
        norm += amp;
        amp *= gain;
        octave_scale *= 2.0;
    }
    total / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pinned_values_of_spec_8_6() {
        assert_eq!([hash32(0), hash32(1), hash32(2), hash32(3)], [0, 1753845952, 3507691905, 1408362973]);
        assert_eq!(permutation(0)[..8], [121, 98, 175, 60, 155, 88, 12, 152]);
    }

    #[test]
    fn lattice_index_wraps_exactly() {
        assert_eq!(wrap(-1.0), 255);
        assert_eq!(wrap(256.0 * 3.0 + 7.0), 7);
        assert_eq!(wrap(-(2f64.powi(70))), 0);
        assert_eq!(wrap(2f64.powi(60) + 256.0 * 5.0 + 3.0 - 3.0), 0);
        assert_eq!(wrap(f64::NAN), 0);
    }

    #[test]
    fn noise_vanishes_on_integer_points_and_stays_bounded() {
        let p = permutation(7);
        assert_eq!(perlin(&p, [3.0, -4.0, 5.0]), 0.0);
        for i in 0..1000 {
            let x = [i as f64 * 0.173, (i * 7 % 13) as f64 * 0.31, -(i as f64) * 0.057];
            let v = fbm(&p, x, 1.3, 4, 0.5);
            assert!((-1.0..=1.0).contains(&v), "{v}");
        }
    }
}
