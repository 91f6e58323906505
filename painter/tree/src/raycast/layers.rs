//! Several layers in one ray (spec 6.2): the march that composites, at
//! every step, the interval up to the nearest cell boundary of any layer.
//! The CPU port of `main_layers` in shaders/raycast.wgsl.

use super::*;

/// One contributing layer of a document (spec 6.2): its pools and opacity.
pub struct LayerInput<'a> {
    pub inp: RayInput<'a>,
    pub opacity: f32,
}

/// What a march of several layers leaves (spec 6.2).
struct March {
    colour: [f32; 3],
    direct: [f32; 3],
    trans: f32,
    found: bool,
    s_cur: Vec<Cursor>,
    s_active: Vec<bool>,
}

/// The march of spec 6.2 along `d` from the cursors `cur` (those `active`
/// inside the canvas): every step composites the interval up to the
/// nearest boundary of any layer; `shadow`: only attenuate.
fn march(layers: &[LayerInput], pr: &RayParams, mut cur: Vec<Cursor>, mut active: Vec<bool>, d: [f32; 3], shadow: bool) -> March {
    let n = layers.len();
    let root_size = ldexp(pr.lattice_unit, pr.max_depth as i32);
    let mut out = March { colour: [0.0; 3], direct: [0.0; 3], trans: 1.0, found: false, s_cur: cur.clone(), s_active: vec![false; n] };
    let mut exits = vec![(0f32, 0usize, [0f32; 3]); n];
    let mut u_k = vec![f32::INFINITY; n];
    let mut sig_k = vec![0f32; n];
    let mut steps = 0u32;
    while active.iter().any(|&a| a) {
        let mut u = f32::INFINITY;
        let mut sig = 0f32;
        for k in 0..n {
            u_k[k] = f32::INFINITY;
            sig_k[k] = 0.0;
            if active[k] {
                exits[k] = exit(cur[k].p, d);
                u_k[k] = exits[k].0 * ldexp(1.0, -(cur[k].depth as i32));
                u = u.min(u_k[k]);
                if cur[k].visible {
                    sig_k[k] = layers[k].opacity * layers[k].inp.sigma_of(cur[k].cell);
                }
            }
            sig += sig_k[k];
        }
        let ext = (-sig * (u * root_size)).exp();
        if !shadow && sig > 0.0 {
            let w = out.trans * (1.0 - ext);
            for k in 0..n {
                if sig_k[k] == 0.0 {
                    continue;
                }
                let c = &cur[k];
                let share = sig_k[k] / sig;
                let rgb = layers[k].inp.rgb.get(c.cell as usize).copied().unwrap_or([0; 3]).map(|v| v as f32 / 255.0);
                if pr.lit == 0 {
                    for i in 0..3 {
                        out.colour[i] += w * share * rgb[i];
                    }
                } else {
                    // Shaded at the interval's midpoint in the cursor's frame.
                    let t_mid = u * ldexp(1.0, c.depth as i32) * 0.5;
                    let mu = [0, 1, 2].map(|a| (c.p[a] + t_mid * d[a]).clamp(-0.5, 0.5));
                    let f = shade(&layers[k].inp, pr, c.cell, c.depth, mu);
                    for i in 0..3 {
                        out.colour[i] += w * share * f[0] * rgb[i];
                        out.direct[i] += w * share * f[1] * rgb[i];
                    }
                }
            }
            if pr.lit == 2 && !out.found && out.trans >= 0.5 && out.trans * ext < 0.5 {
                let per_unit = sig * root_size;
                let t_half = ((2.0 * out.trans).ln() / per_unit).min(u);
                out.found = true;
                for k in 0..n {
                    let c = cur[k];
                    let t = t_half * ldexp(1.0, c.depth as i32);
                    out.s_cur[k] = Cursor { p: [0, 1, 2].map(|a| (c.p[a] + t * d[a]).clamp(-0.5, 0.5)), ..c };
                    out.s_active[k] = active[k];
                }
            }
        }
        out.trans *= ext;
        steps += 1;
        if out.trans < T_MIN || steps >= pr.max_steps {
            break;
        }
        for k in 0..n {
            if !active[k] {
                continue;
            }
            let (t, axis, bound) = exits[k];
            if u_k[k] == u {
                match next_cell(&layers[k].inp, pr, &cur[k], t, axis, bound[axis], d) {
                    Some(next) => cur[k] = next,
                    None => active[k] = false,
                }
            } else {
                let t = u * ldexp(1.0, cur[k].depth as i32);
                let c = &mut cur[k];
                c.p = [0, 1, 2].map(|a| (c.p[a] + t * d[a]).clamp(-0.5, 0.5));
            }
        }
    }
    out
}

/// One pixel of several layers (spec 6.2), bottom first.
pub fn trace_pixel_layers(layers: &[LayerInput], params: &RayParams, x: u32, y: u32) -> [u8; 3] {
    let pr = params;
    let rs = ray_start(pr, x, y);
    let d = rs.dir;
    let cur: Vec<Cursor> = layers.iter().map(|l| start_cursor(&l.inp, pr, &rs)).collect();
    let ray = march(layers, pr, cur, vec![rs.running; layers.len()], d, false);
    let mut colour = ray.colour;
    if pr.lit == 1 {
        for i in 0..3 {
            colour[i] += ray.direct[i];
        }
    } else if pr.lit == 2 {
        let l = [pr.light[0], pr.light[1], pr.light[2]];
        let s = if ray.found { march(layers, pr, ray.s_cur.clone(), ray.s_active.clone(), l, true).trans } else { 1.0 };
        for i in 0..3 {
            colour[i] += s * ray.direct[i];
        }
    }
    let back = ground(pr, d);
    for i in 0..3 {
        colour[i] += ray.trans * back[i];
    }
    colour.map(|c| (c * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8)
}

/// A whole image of several layers (spec 6.2), row 0 at the top: one layer
/// at opacity 1 is the one-tree image ([`render`], spec 14.6), any other
/// set the march. No layer: the background (and the grid) alone.
pub fn render_layers(layers: &[LayerInput], params: &RayParams) -> Vec<u8> {
    if let [one] = layers
        && one.opacity == 1.0
    {
        return render(&one.inp, params);
    }
    let mut out = Vec::with_capacity((params.width * params.height * 3) as usize);
    for y in 0..params.height {
        for x in 0..params.width {
            out.extend_from_slice(&trace_pixel_layers(layers, params, x, y));
        }
    }
    out
}
