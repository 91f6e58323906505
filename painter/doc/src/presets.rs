//! Brush presets (docs/desktop.md "Brush presets"): named brushes an artist
//! keeps, in `brushes.json` in the platform's config folder
//! ([`octopaint_platform::folders::config_folder`]). The file is read when
//! a front end starts and replaced atomically and durably at every change
//! ([`octopaint_platform::durable::write`]); without one, the starting set
//! ([`starting_set`]) stands in until the first change writes it. A file
//! that cannot be read or is malformed is never written over: the front end
//! shows the starting set, says why, and refuses changes until the file is
//! mended or removed.
//!
//! ```text
//! {"format": "octopaint-brushes", "version": 1,
//!  "brushes": [{"name": "fine liner", "shape": "sphere", "mode": "paint", "radius": 0.002, ...}]}
//! ```
//!
//! Each brush holds a `name` and a trace's `brush` event fields (spec 12),
//! checked by the trace reader's own rules.

use std::path::{Path, PathBuf};

use octopaint_tree::trace::{Brush, Mode, Shape, parse_brush};
use serde_json::{Value, json};

/// The file's name in the config folder.
pub const FILE_NAME: &str = "brushes.json";
/// At most this many presets, names of at most this many characters, and
/// files of at most this many bytes.
pub const MAX_PRESETS: usize = 256;
pub const MAX_NAME_CHARS: usize = 48;
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// One named brush.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    pub name: String,
    pub brush: Brush,
}

/// Why a presets file was not read, or a change was refused.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum PresetError {
    #[error("{path}: {reason}")]
    Unreadable { path: PathBuf, reason: String },
    #[error("{path}: {reason}; fix or remove the file (presets are not saved over it)")]
    Malformed { path: PathBuf, reason: String },
    #[error("{0}")]
    Refused(String),
}

/// The presets shipped: a few brushes for the common jobs.
pub fn starting_set() -> Vec<Preset> {
    let b = |shape, mode, radius, color, opacity, hardness| Brush::new(shape, mode, radius, color, opacity, hardness);
    let mut noise = b(Shape::Noise, Mode::Paint, 0.05, [0.85, 0.88, 0.95], 0.35, 0.1);
    noise.noise.frequency = 2.0;
    noise.noise.octaves = 4;
    let mut haze = b(Shape::Sphere, Mode::Mix, 0.08, [0.75, 0.8, 0.9], 0.15, 0.0);
    haze.mix_ratio = 0.5;
    vec![
        Preset { name: "fine liner".into(), brush: b(Shape::Sphere, Mode::Paint, 0.002, [0.1, 0.1, 0.12], 0.9, 0.8) },
        Preset { name: "soft round".into(), brush: b(Shape::Sphere, Mode::Paint, 0.02, [0.8, 0.35, 0.2], 0.7, 0.3) },
        Preset { name: "hard block".into(), brush: b(Shape::Box, Mode::Paint, 0.015, [0.55, 0.55, 0.6], 1.0, 0.9) },
        Preset { name: "haze".into(), brush: haze },
        Preset { name: "cloud".into(), brush: noise },
        Preset { name: "recolour".into(), brush: b(Shape::Sphere, Mode::Recolor, 0.03, [0.2, 0.5, 0.9], 0.6, 0.4) },
        Preset { name: "eraser".into(), brush: b(Shape::Sphere, Mode::Erase, 0.02, [0.0, 0.0, 0.0], 1.0, 0.6) },
    ]
}

/// The presets file in the platform's config folder, if one is known.
pub fn default_path() -> Option<PathBuf> {
    Some(octopaint_platform::folders::config_folder()?.join(FILE_NAME))
}

/// A name a preset may have: 1 to MAX_NAME_CHARS characters, no control
/// characters, not blank at either end.
pub fn valid_name(name: &str) -> bool {
    let n = name.chars().count();
    (1..=MAX_NAME_CHARS).contains(&n) && !name.chars().any(char::is_control) && name.trim() == name
}

/// The file's text for `presets`.
pub fn to_json(presets: &[Preset]) -> String {
    let brushes: Vec<Value> = presets
        .iter()
        .map(|p| {
            let mut o = octopaint_tree::trace_write::brush_fields(&p.brush);
            o.as_object_mut().expect("an object").insert("name".into(), json!(p.name));
            o
        })
        .collect();
    let mut text = serde_json::to_string_pretty(&json!({"format": "octopaint-brushes", "version": 1, "brushes": brushes})).expect("plain JSON");
    text.push('\n');
    text
}

/// The presets in a file's text; the reason when it is malformed.
pub fn from_json(text: &str) -> Result<Vec<Preset>, String> {
    let v: Value = serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    if v.get("format").and_then(Value::as_str) != Some("octopaint-brushes") {
        return Err("not a presets file (\"format\" is not \"octopaint-brushes\")".into());
    }
    if v.get("version").and_then(Value::as_u64) != Some(1) {
        return Err(format!("version {} is not one this painter reads (1)", v.get("version").map_or("missing".into(), Value::to_string)));
    }
    let list = v.get("brushes").and_then(Value::as_array).ok_or("\"brushes\" is not a list")?;
    if list.len() > MAX_PRESETS {
        return Err(format!("{} brushes, more than {MAX_PRESETS}", list.len()));
    }
    let mut out: Vec<Preset> = Vec::with_capacity(list.len());
    for (i, o) in list.iter().enumerate() {
        let at = |what: String| format!("brush {}: {what}", i + 1);
        let name = o.get("name").and_then(Value::as_str).ok_or_else(|| at("no \"name\" string".into()))?;
        if !valid_name(name) {
            return Err(at(format!("the name {name:?} is empty, longer than {MAX_NAME_CHARS} characters, padded or has control characters")));
        }
        if out.iter().any(|p| p.name == name) {
            return Err(at(format!("the name {name:?} is taken by an earlier brush")));
        }
        let brush = parse_brush(0, o).map_err(|e| at(format!("{name:?}: {}", e.text())))?;
        out.push(Preset { name: name.to_string(), brush });
    }
    Ok(out)
}

/// The presets at `path`: the starting set when there is no file; an
/// error (never a guess) when it cannot be read or is malformed.
pub fn load(path: &Path) -> Result<Vec<Preset>, PresetError> {
    let unreadable = |e: std::io::Error| PresetError::Unreadable { path: path.to_path_buf(), reason: octopaint_tree::trace::io_reason(&e) };
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(starting_set()),
        Err(e) => return Err(unreadable(e)),
    };
    let malformed = |reason: String| PresetError::Malformed { path: path.to_path_buf(), reason };
    if !meta.is_file() {
        return Err(malformed("not a file".into()));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(malformed(format!("{} bytes, more than {MAX_FILE_BYTES}", meta.len())));
    }
    let text = String::from_utf8(std::fs::read(path).map_err(unreadable)?).map_err(|_| malformed("not UTF-8 text".into()))?;
    from_json(&text).map_err(malformed)
}

/// Write `presets` to `path` atomically and durably, making its folder
/// if needed.
pub fn save(path: &Path, presets: &[Preset]) -> Result<(), PresetError> {
    let failed = |e: std::io::Error| PresetError::Unreadable { path: path.to_path_buf(), reason: octopaint_tree::trace::io_reason(&e) };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(failed)?;
    }
    octopaint_platform::durable::write(path, to_json(presets).as_bytes()).map_err(failed)
}

/// A front end's presets: the list, where it lives, and whether changes
/// may be written (not over a file that could not be read).
#[derive(Debug)]
pub struct Presets {
    pub list: Vec<Preset>,
    path: Option<PathBuf>,
    /// Why changes are refused (the file could not be read), if they are.
    pub blocked: Option<PresetError>,
}

impl Presets {
    /// The presets of `path` (None: no config folder; the starting set,
    /// kept in memory). A file that cannot be read leaves the starting set
    /// in use and blocks changes, with the reason.
    pub fn open(path: Option<PathBuf>) -> Presets {
        match path.as_deref().map(load) {
            None => Presets { list: starting_set(), path: None, blocked: None },
            Some(Ok(list)) => Presets { list, path, blocked: None },
            Some(Err(e)) => Presets { list: starting_set(), path, blocked: Some(e) },
        }
    }

    /// Keep `brush` under `name`, replacing a preset of that name (in its
    /// place) or adding one at the end, and write the file. On a refusal
    /// or a failed write the list is as it was.
    pub fn put(&mut self, name: &str, brush: Brush) -> Result<(), PresetError> {
        if !valid_name(name) {
            return Err(PresetError::Refused(format!("a preset's name has 1 to {MAX_NAME_CHARS} characters, no control characters: {name:?}")));
        }
        let mut list = self.list.clone();
        match list.iter().position(|p| p.name == name) {
            Some(i) => list[i].brush = brush,
            None if list.len() >= MAX_PRESETS => return Err(PresetError::Refused(format!("{MAX_PRESETS} presets already; delete one first"))),
            None => list.push(Preset { name: name.to_string(), brush }),
        }
        self.commit(list)
    }

    /// Delete the preset `name` and write the file.
    pub fn delete(&mut self, name: &str) -> Result<(), PresetError> {
        let list: Vec<Preset> = self.list.iter().filter(|p| p.name != name).cloned().collect();
        if list.len() == self.list.len() {
            return Err(PresetError::Refused(format!("no preset named {name:?}")));
        }
        self.commit(list)
    }

    fn commit(&mut self, list: Vec<Preset>) -> Result<(), PresetError> {
        if let Some(e) = &self.blocked {
            return Err(e.clone());
        }
        if let Some(path) = &self.path {
            save(path, &list)?;
        }
        self.list = list;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_starting_set_round_trips_through_its_file() {
        let set = starting_set();
        assert!(set.len() >= 5 && set.iter().all(|p| valid_name(&p.name)));
        assert_eq!(from_json(&to_json(&set)).unwrap(), set);
    }

    #[test]
    fn no_file_gives_the_starting_set_and_the_first_change_writes_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join(FILE_NAME);
        let mut p = Presets::open(Some(path.clone()));
        assert_eq!((p.list.clone(), p.blocked.is_none()), (starting_set(), true));
        assert!(!path.exists());
        let mut mine = Brush::new(Shape::Cone, Mode::Mix, 0.5, [0.1, 0.2, 0.3], 0.4, 0.5);
        mine.spacing = 0.7;
        p.put("my cone", mine).unwrap();
        p.put("soft round", mine).unwrap(); // replaced in place
        p.delete("eraser").unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back, p.list);
        assert_eq!(back.last().unwrap(), &Preset { name: "my cone".into(), brush: mine });
        assert_eq!(back.iter().find(|q| q.name == "soft round").unwrap().brush, mine);
        assert!(!back.iter().any(|q| q.name == "eraser"));
        assert_eq!(back.len(), starting_set().len());
    }

    #[test]
    fn a_malformed_file_is_reported_and_never_written_over() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(FILE_NAME);
        let ok = to_json(&starting_set());
        let cases = [
            ("{", "not JSON"),
            ("[]", "not a presets file"),
            ("{\"format\": \"octopaint-brushes\", \"version\": 1, \"brushes\": [3]}", "brush 1: no \"name\" string"),
            (&*ok.replace("\"version\": 1", "\"version\": 2"), "version 2"),
            (&*ok.replace("\"fine liner\"", "\"soft round\""), "taken by an earlier brush"),
            (&*ok.replace("\"fine liner\"", "\"\""), "is empty"),
            (&*ok.replacen("\"radius\": 0.002", "\"radius\": -1.0", 1), "brush 1: \"fine liner\": radius: -1.0 must be > 0"),
            (&*ok.replacen("\"mode\": \"paint\"", "\"mode\": \"smudge\"", 1), "mode"),
            (&*ok.replacen("\"opacity\": 0.9", "\"opacity\": 1e400", 1), "not JSON"),
        ];
        for (text, want) in cases {
            std::fs::write(&path, text).unwrap();
            let err = load(&path).unwrap_err();
            assert!(matches!(err, PresetError::Malformed { .. }) && err.to_string().contains(want), "{text:.60}: {err}");
            let mut p = Presets::open(Some(path.clone()));
            assert_eq!(p.list, starting_set());
            assert!(p.put("new", Brush::new(Shape::Sphere, Mode::Paint, 1.0, [0.0; 3], 1.0, 0.5)).is_err());
            assert_eq!(std::fs::read_to_string(&path).unwrap(), text, "the file is left as it was");
        }
        std::fs::write(&path, vec![b'x'; MAX_FILE_BYTES as usize + 1]).unwrap();
        assert!(load(&path).unwrap_err().to_string().contains("more than"));
    }

    #[test]
    fn changes_are_checked_before_anything_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(FILE_NAME);
        let mut p = Presets::open(Some(path.clone()));
        let b = Brush::new(Shape::Sphere, Mode::Paint, 1.0, [0.0; 3], 1.0, 0.5);
        for bad in ["", " padded", "tab\there", &"x".repeat(MAX_NAME_CHARS + 1)] {
            assert!(matches!(p.put(bad, b), Err(PresetError::Refused(_))), "{bad:?}");
        }
        assert!(matches!(p.delete("no such"), Err(PresetError::Refused(_))));
        assert!(!path.exists(), "nothing written for a refusal");
        for i in p.list.len()..MAX_PRESETS {
            p.list.push(Preset { name: format!("p{i}"), brush: b });
        }
        assert!(matches!(p.put("one more", b), Err(PresetError::Refused(_))));
        p.put("p7", b).unwrap(); // replacing is still allowed
        assert_eq!(load(&path).unwrap().len(), MAX_PRESETS);
    }
}
