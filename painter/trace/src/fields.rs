//! The rules on the fields of one trace line (spec 12.2): numbers, ranges,
//! names, and the header's, brush's, sample's and camera's fields in the
//! order the spec checks them. Each refusal carries its [`ErrorKind`].

use serde_json::Value;

use octopaint_model::layer_rules::{MAX_LAYERS, name_problem};
use octopaint_model::{
    Brush, Camera, Canvas, LIGHT_INTENSITY_MAX, LayerOp, LayerOpKind, Light, MAX_CAPACITY, MAX_DEPTH_LIMIT, MAX_IMAGE_SIZE, MAX_ROOTS, MAX_STAMPS_PER_SEGMENT,
    Mirror, Mode, Sample, Shape, TINY,
};

use crate::error::{ErrorKind, TraceError};

const SPACING_RANGE: (f64, f64) = (0.01, 100.0);
const ASPECT_RANGE: (f64, f64) = (1e-3, 1e3);
const NOISE_FREQUENCY_MAX: f64 = 1e6;

type R<T> = Result<T, TraceError>;

/// A field's name as messages give it, built only when one is refused (the
/// reader spends its time on accepted fields).
pub(super) trait Field: Copy {
    fn name(self) -> String;
}

impl Field for &str {
    fn name(self) -> String {
        self.to_string()
    }
}

/// Element `.1` of the array field `.0`: `p[1]`.
impl Field for (&str, usize) {
    fn name(self) -> String {
        format!("{}[{}]", self.0, self.1)
    }
}

pub(super) fn fail(line: usize, field: &str, kind: ErrorKind, msg: impl AsRef<str>) -> TraceError {
    TraceError::new(line, kind, format!("{field}: {}", msg.as_ref()))
}

fn range(line: usize, field: &str, msg: impl AsRef<str>) -> TraceError {
    fail(line, field, ErrorKind::Range, msg)
}

/// A JSON value as a message shows it.
pub(super) fn shown(v: &Value) -> String {
    serde_json::to_string(v).unwrap_or_else(|_| "?".into())
}

/// A number field: finite (the JSON reading refused literals beyond f64),
/// then subnormal magnitudes and -0 read as +0 (spec 8.9).
pub(super) fn finite(line: usize, field: impl Field, v: &Value) -> R<f64> {
    let x = match v {
        Value::Number(n) => n.as_f64().expect("serde_json numbers are finite"),
        other => return Err(fail(line, &field.name(), ErrorKind::Type, format!("expected a number, got {}", shown(other)))),
    };
    Ok(if x.abs() < TINY { 0.0 } else { x })
}

/// An integer field: an integer literal, or a number literal whose value is
/// integral (`4.0`), in `[lo, hi]`.
fn int(line: usize, field: impl Field, v: &Value, lo: i64, hi: i64) -> R<i64> {
    let Value::Number(n) = v else {
        return Err(fail(line, &field.name(), ErrorKind::Type, format!("expected an integer, got {}", shown(v))));
    };
    let outside = || range(line, &field.name(), format!("{n} is outside [{lo}, {hi}]"));
    if let Some(i) = n.as_i64() {
        return if lo <= i && i <= hi { Ok(i) } else { Err(outside()) };
    }
    if n.is_u64() {
        return Err(outside()); // beyond i64, so beyond every range here
    }
    let x = n.as_f64().expect("a JSON number");
    if x != x.floor() {
        return Err(fail(line, &field.name(), ErrorKind::Type, format!("expected an integer, got {x:?}")));
    }
    if (lo as f64) <= x && x <= hi as f64 { Ok(x as i64) } else { Err(outside()) }
}

fn ranged(line: usize, field: impl Field, v: &Value, lo: f64, hi: f64) -> R<f64> {
    let x = finite(line, field, v)?;
    if !(lo <= x && x <= hi) {
        return Err(range(line, &field.name(), format!("{x:?} is outside [{lo:?}, {hi:?}]")));
    }
    Ok(x)
}

fn vec_of<'a>(line: usize, field: &str, v: &'a Value, n: usize) -> R<&'a [Value]> {
    match v {
        Value::Array(items) if items.len() == n => Ok(items),
        _ => Err(fail(line, field, ErrorKind::Type, format!("expected an array of {n} numbers"))),
    }
}

fn vec_finite<const N: usize>(line: usize, field: &str, v: &Value) -> R<[f64; N]> {
    let items = vec_of(line, field, v, N)?;
    let mut out = [0.0; N];
    for (i, x) in items.iter().enumerate() {
        out[i] = finite(line, (field, i), x)?;
    }
    Ok(out)
}

fn vec_ranged<const N: usize>(line: usize, field: &str, v: &Value, lo: f64, hi: f64) -> R<[f64; N]> {
    let items = vec_of(line, field, v, N)?;
    let mut out = [0.0; N];
    for (i, x) in items.iter().enumerate() {
        out[i] = ranged(line, (field, i), x, lo, hi)?;
    }
    Ok(out)
}

fn quat(line: usize, field: &str, v: &Value) -> R<[f64; 4]> {
    let q: [f64; 4] = vec_finite(line, field, v)?;
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if !n2.is_finite() || n2.sqrt() < 1e-12 {
        return Err(range(line, field, "zero or non-finite quaternion"));
    }
    Ok(q)
}

pub(super) fn require<'a>(line: usize, obj: &'a Value, key: &str, prefix: &str) -> R<&'a Value> {
    obj.get(key).ok_or_else(|| fail(line, &format!("{prefix}{key}"), ErrorKind::Missing, "missing"))
}

/// `[A-Za-z0-9._-]+`, not `.` or `..`.
pub fn is_valid_name(s: &str) -> bool {
    !s.is_empty() && s != "." && s != ".." && s.chars().all(|c| c.is_ascii_alphanumeric() || "._-".contains(c))
}

pub(super) fn name(line: usize, v: &Value) -> R<String> {
    match v {
        Value::String(s) if is_valid_name(s) => Ok(s.clone()),
        _ => Err(fail(line, "name", ErrorKind::Name, format!("{} is not a name of [A-Za-z0-9._-]+ (no paths)", shown(v)))),
    }
}

fn one_of<T: Copy>(line: usize, field: &str, v: &Value, names: &[&str], values: &[T]) -> R<T> {
    if let Value::String(s) = v
        && let Some(i) = names.iter().position(|n| n == s)
    {
        return Ok(values[i]);
    }
    Err(range(line, field, format!("{} is not one of {}", shown(v), names.join(", "))))
}

pub fn parse_canvas(line: usize, obj: &Value) -> R<Canvas> {
    if !obj.is_object() {
        return Err(fail(line, "canvas", ErrorKind::Type, "expected an object"));
    }
    let roots_v = vec_of(line, "canvas.roots", require(line, obj, "roots", "canvas.")?, 3)?;
    let mut roots = [0u32; 3];
    for (i, x) in roots_v.iter().enumerate() {
        roots[i] = int(line, ("canvas.roots", i), x, 1, 1 << 16)? as u32;
    }
    let max_depth = int(line, "canvas.max_depth", require(line, obj, "max_depth", "canvas.")?, 0, MAX_DEPTH_LIMIT)?;
    for (i, &r) in roots.iter().enumerate() {
        if (u64::from(r) << max_depth) > 1 << 32 {
            return Err(range(line, &format!("canvas.roots[{i}]"), format!("{r} roots of depth {max_depth} exceed the u32 lattice")));
        }
    }
    let root_size = finite(line, "canvas.root_size", require(line, obj, "root_size", "canvas.")?)?;
    if !(1e-9..=1e12).contains(&root_size) {
        return Err(range(line, "canvas.root_size", format!("{root_size:?} is outside [1e-9, 1e12]")));
    }
    let n_roots = roots.iter().map(|&r| u64::from(r)).product::<u64>();
    if n_roots > MAX_ROOTS {
        return Err(fail(line, "canvas.roots", ErrorKind::Budget, format!("{n_roots} roots are more than the {MAX_ROOTS} allowed")));
    }
    let padded = n_roots.div_ceil(8) * 8;
    let capacity = int(line, "canvas.capacity", require(line, obj, "capacity", "canvas.")?, 8, MAX_CAPACITY)?;
    if (capacity as u64) < padded {
        return Err(fail(line, "canvas.capacity", ErrorKind::Budget, format!("{capacity} is below the {padded} cells the roots need")));
    }
    Ok(Canvas { roots, max_depth: max_depth as u32, root_size, capacity: capacity as u32 })
}

pub fn parse_brush(line: usize, obj: &Value) -> R<Brush> {
    let shape = one_of(line, "shape", require(line, obj, "shape", "")?, &octopaint_model::SHAPES, &Shape::ALL)?;
    let mode = one_of(line, "mode", require(line, obj, "mode", "")?, &octopaint_model::MODES, &Mode::ALL)?;
    let radius = finite(line, "radius", require(line, obj, "radius", "")?)?;
    if radius <= 0.0 {
        return Err(range(line, "radius", format!("{radius:?} must be > 0")));
    }
    let color = vec_ranged::<3>(line, "color", require(line, obj, "color", "")?, 0.0, 1.0)?;
    let opacity = ranged(line, "opacity", require(line, obj, "opacity", "")?, 0.0, 1.0)?;
    let hardness = ranged(line, "hardness", require(line, obj, "hardness", "")?, 0.0, 1.0)?;
    let mut b = Brush::new(shape, mode, radius, color, opacity, hardness);
    if let Some(v) = obj.get("spacing") {
        b.spacing = ranged(line, "spacing", v, SPACING_RANGE.0, SPACING_RANGE.1)?;
    }
    if let Some(v) = obj.get("mix_ratio") {
        b.mix_ratio = ranged(line, "mix_ratio", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("pickup_rate") {
        b.pickup_rate = ranged(line, "pickup_rate", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("aspect") {
        b.aspect = vec_ranged::<3>(line, "aspect", v, ASPECT_RANGE.0, ASPECT_RANGE.1)?;
    }
    if let Some(n) = obj.get("noise") {
        if !n.is_object() {
            return Err(fail(line, "noise", ErrorKind::Type, "expected an object"));
        }
        if let Some(v) = n.get("frequency") {
            let f = finite(line, "noise.frequency", v)?;
            if !(0.0 < f && f <= NOISE_FREQUENCY_MAX) {
                return Err(range(line, "noise.frequency", format!("{f:?} is outside (0, 1e6]")));
            }
            b.noise.frequency = f;
        }
        if let Some(v) = n.get("octaves") {
            b.noise.octaves = int(line, "noise.octaves", v, 1, 8)? as u32;
        }
        if let Some(v) = n.get("seed") {
            b.noise.seed = int(line, "noise.seed", v, 0, 0xFFFF_FFFF)? as u32;
        }
        if let Some(v) = n.get("gain") {
            b.noise.gain = ranged(line, "noise.gain", v, 0.0, 1.0)?;
        }
    }
    Ok(b)
}

/// The `mirror` event (spec 8.11): `axes` 3 booleans, then `centre` 3
/// finite numbers.
pub fn parse_mirror(line: usize, obj: &Value) -> R<Mirror> {
    let items = vec_of(line, "axes", require(line, obj, "axes", "")?, 3)?;
    let mut axes = [false; 3];
    for (i, x) in items.iter().enumerate() {
        axes[i] = x.as_bool().ok_or_else(|| fail(line, &format!("axes[{i}]"), ErrorKind::Type, format!("expected true or false, got {x}")))?;
    }
    let centre = vec_finite::<3>(line, "centre", require(line, obj, "centre", "")?)?;
    Ok(Mirror { axes, centre })
}

pub fn parse_sample(line: usize, obj: &Value) -> R<Sample> {
    let mut s = Sample::at(vec_finite::<3>(line, "p", require(line, obj, "p", "")?)?);
    if let Some(v) = obj.get("pressure") {
        s.pressure = ranged(line, "pressure", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("q") {
        s.q = quat(line, "q", v)?;
    }
    Ok(s)
}

pub fn parse_camera(line: usize, obj: &Value) -> R<Camera> {
    let eye = vec_finite::<3>(line, "eye", require(line, obj, "eye", "")?)?;
    let q = quat(line, "q", require(line, obj, "q", "")?)?;
    let fov = vec_finite::<4>(line, "fov", require(line, obj, "fov", "")?)?;
    let half_pi = std::f64::consts::FRAC_PI_2;
    for (i, &a) in fov.iter().enumerate() {
        if !(-half_pi < a && a < half_pi) {
            return Err(range(line, &format!("fov[{i}]"), format!("{a:?} is outside (-pi/2, pi/2)")));
        }
    }
    let [left, right, up, down] = fov;
    if !(left < right) {
        return Err(range(line, "fov", "angles not ordered: left must be < right"));
    }
    if !(down < up) {
        return Err(range(line, "fov", "angles not ordered: down must be < up"));
    }
    let size_v = vec_of(line, "size", require(line, obj, "size", "")?, 2)?;
    let mut size = [0u32; 2];
    for (i, x) in size_v.iter().enumerate() {
        size[i] = int(line, ("size", i), x, 1, MAX_IMAGE_SIZE)? as u32;
    }
    let mut background = [0.0; 3];
    if let Some(v) = obj.get("background") {
        background = vec_ranged::<3>(line, "background", v, 0.0, 1.0)?;
    }
    Ok(Camera { eye, q, fov, size, background })
}

fn boolean(line: usize, field: &str, v: &Value) -> R<bool> {
    v.as_bool().ok_or_else(|| fail(line, field, ErrorKind::Type, format!("expected true or false, got {v}")))
}

/// The `light` event (spec 6.1): `on` first; when on, `dir` (finite, not
/// zero), then the optional `intensity`, `ambient` and `shadows`.
pub fn parse_light(line: usize, obj: &Value) -> R<Light> {
    if let Some(v) = obj.get("on")
        && !boolean(line, "on", v)?
    {
        return Ok(Light::OFF);
    }
    let dir: [f64; 3] = vec_finite(line, "dir", require(line, obj, "dir", "")?)?;
    let n2 = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
    if !n2.is_finite() || n2.sqrt() < 1e-12 {
        return Err(range(line, "dir", "zero or non-finite direction"));
    }
    let mut l = Light { dir, ..Light::default() };
    if let Some(v) = obj.get("intensity") {
        l.intensity = ranged(line, "intensity", v, 0.0, LIGHT_INTENSITY_MAX)?;
    }
    if let Some(v) = obj.get("ambient") {
        l.ambient = ranged(line, "ambient", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("shadows") {
        l.shadows = boolean(line, "shadows", v)?;
    }
    Ok(l)
}

/// Whether the segment between samples `a` and `b` would place more than
/// 65,536 stamps (spec 8.4): `floor(L / (spacing·r_min)) + 1` with
/// `r_min` the smaller pressure's radius; a zero-length segment places
/// none, and a quotient that overflows counts as too many.
pub fn segment_too_long(brush: &Brush, a: &Sample, b: &Sample) -> bool {
    if brush.shape == Shape::Sphere {
        return false;
    }
    let d = [b.p[0] - a.p[0], b.p[1] - a.p[1], b.p[2] - a.p[2]];
    let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if length == 0.0 {
        return false;
    }
    let r_min = brush.radius * (0.25 + 0.75 * a.pressure.min(b.pressure));
    let quotient = length / (brush.spacing * r_min);
    !quotient.is_finite() || quotient.floor() + 1.0 > MAX_STAMPS_PER_SEGMENT
}

fn layer_ref(line: usize, obj: &Value) -> R<String> {
    match require(line, obj, "layer", "")? {
        Value::String(s) => Ok(s.clone()),
        other => Err(fail(line, "layer", ErrorKind::Type, format!("expected a layer name, got {}", shown(other)))),
    }
}

fn layer_name(line: usize, obj: &Value) -> R<String> {
    match require(line, obj, "name", "")? {
        Value::String(s) => match name_problem(s) {
            Some(why) => Err(range(line, "name", why)),
            None => Ok(s.clone()),
        },
        other => Err(fail(line, "name", ErrorKind::Type, format!("expected a string, got {}", shown(other)))),
    }
}

/// The `layer` event (spec 14.2): `op`, then its fields in order. The rules
/// that need the document (names, locks, counts) are octopaint_model::layer_rules's.
pub fn parse_layer(line: usize, obj: &Value) -> R<LayerOp> {
    let op = require(line, obj, "op", "")?;
    let Value::String(code) = op else {
        return Err(fail(line, "op", ErrorKind::Type, format!("expected a string, got {}", shown(op))));
    };
    let Some(kind) = LayerOpKind::ALL.into_iter().find(|k| k.code() == code) else {
        let all: Vec<&str> = LayerOpKind::ALL.iter().map(|k| k.code()).collect();
        return Err(range(line, "op", format!("{} is not one of {}", shown(op), all.join(", "))));
    };
    let mut out = LayerOp::new(kind);
    if kind == LayerOpKind::Add {
        out.name = Some(layer_name(line, obj)?);
        return Ok(out);
    }
    out.layer = Some(layer_ref(line, obj)?);
    match kind {
        LayerOpKind::Rename | LayerOpKind::Duplicate => out.name = Some(layer_name(line, obj)?),
        LayerOpKind::Move => {
            let to = int(line, "to", require(line, obj, "to", "")?, 0, MAX_LAYERS as i64 - 1)?;
            out.to = Some(to as usize);
        }
        LayerOpKind::Set => {
            out.visible = obj.get("visible").map(|v| boolean(line, "visible", v)).transpose()?;
            out.opacity = obj.get("opacity").map(|v| ranged(line, "opacity", v, 0.0, 1.0)).transpose()?.map(|x| x as f32);
            out.locked = obj.get("locked").map(|v| boolean(line, "locked", v)).transpose()?;
            if out.visible.is_none() && out.opacity.is_none() && out.locked.is_none() {
                return Err(fail(line, "visible", ErrorKind::Missing, "set needs visible, opacity or locked"));
            }
        }
        _ => {}
    }
    Ok(out)
}

/// The fields of an `import` event (spec 15.2): `file`, `sha256`, optional
/// `name`. The reader then reads the file.
pub(super) fn parse_import_fields(line: usize, obj: &Value) -> R<(String, String, Option<String>)> {
    let file = match require(line, obj, "file", "")? {
        Value::String(s) => s.clone(),
        other => return Err(fail(line, "file", ErrorKind::Type, format!("expected a string, got {}", shown(other)))),
    };
    let parts: Vec<&str> = file.split('/').collect();
    if parts.len() > 8 || !parts.iter().all(|p| is_valid_name(p)) {
        return Err(fail(line, "file", ErrorKind::Name, format!("{} is not a relative path of 1 to 8 plain names", shown(&Value::String(file.clone())))));
    }
    let sha = match require(line, obj, "sha256", "")? {
        Value::String(s) => s.clone(),
        other => return Err(fail(line, "sha256", ErrorKind::Type, format!("expected a string, got {}", shown(other)))),
    };
    if sha.len() != 64 || !sha.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)) {
        return Err(range(line, "sha256", format!("{} is not 64 lowercase hexadecimal digits", shown(&Value::String(sha.clone())))));
    }
    let name = match obj.get("name") {
        None => None,
        Some(Value::String(s)) => {
            if let Some(why) = name_problem(s) {
                return Err(range(line, "name", why));
            }
            Some(s.clone())
        }
        Some(other) => return Err(fail(line, "name", ErrorKind::Type, format!("expected a string, got {}", shown(other)))),
    };
    Ok((file, sha, name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_plain() {
        assert!(is_valid_name("a.b-c_9"));
        for bad in ["", ".", "..", "a/b", "a\n", "a b", "é"] {
            assert!(!is_valid_name(bad), "{bad:?}");
        }
    }

    #[test]
    fn integer_fields_take_integral_numbers_only() {
        let v = |s: &str| serde_json::from_str::<Value>(s).unwrap();
        assert_eq!(int(1, "x", &v("4.0"), 0, 28), Ok(4));
        assert_eq!(int(1, "x", &v("-0.0"), 0, 28), Ok(0));
        assert_eq!(int(1, "x", &v("4.5"), 0, 28).unwrap_err().kind, ErrorKind::Type);
        assert_eq!(int(1, "x", &v("true"), 0, 28).unwrap_err().kind, ErrorKind::Type);
        assert_eq!(int(1, "x", &v("1e300"), 0, 28).unwrap_err().kind, ErrorKind::Range);
        assert_eq!(int(1, "x", &v("18446744073709551615"), 0, 28).unwrap_err().kind, ErrorKind::Range);
        assert_eq!(int(1, "x", &v("-9223372036854775808"), 0, 28).unwrap_err().kind, ErrorKind::Range);
        assert_eq!(int(1, "x", &v("28"), 0, 28), Ok(28));
    }

    #[test]
    fn overflowing_segments_are_refused_not_crashed() {
        let b = Brush::new(Shape::Box, Mode::Paint, 1e-300, [0.0; 3], 1.0, 0.5);
        assert!(segment_too_long(&b, &Sample::at([1e300, 0.0, 0.0]), &Sample::at([-1e300, 0.0, 0.0])));
        assert!(!segment_too_long(&b, &Sample::at([1.0, 0.0, 0.0]), &Sample::at([1.0, 0.0, 0.0])));
    }
}
