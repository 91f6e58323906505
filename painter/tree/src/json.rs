//! JSON read exactly as Python's `json.loads` reads it (CPython 3.11, the C
//! scanner), because the trace format is defined by the reference reader
//! (spec 12.2): `NaN`, `Infinity` and `-Infinity` are numbers, integers are
//! exact (arbitrary size), a float literal too large for f64 reads as
//! infinite, a repeated key keeps its first position and its last value,
//! strings may hold lone surrogates (`"\ud800"`), and a syntax error carries
//! Python's message and column. No JSON crate does all of this, so the
//! scanner is written out here, as a transcription of `Modules/_json.c`
//! (`scan_once_unicode`, `_parse_object_unicode`, `_parse_array_unicode`,
//! `scanstring_unicode`, `_match_number_unicode`). Positions are counted in
//! code points, as Python counts them.
//!
//! Two limits Python does not have in this form (spec 12.2): a line nested
//! deeper than [`MAX_NESTING`] brackets is refused before it is parsed
//! (Python would raise RecursionError), and an integer literal of more than
//! [`MAX_INT_DIGITS`] digits is refused where it is scanned (Python would
//! raise ValueError). The reference applies the same two rules.

use num_bigint::BigInt;
use std::fmt::Write as _;

use crate::pyrepr::py_float_repr;

/// Deepest bracket nesting a trace line may have.
pub const MAX_NESTING: usize = 512;
/// Most digits an integer literal may have (CPython's int conversion limit).
pub const MAX_INT_DIGITS: usize = 4300;

/// A JSON string as Python holds it: code points, lone surrogates allowed.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct PyStr(pub Vec<u32>);

impl PyStr {
    pub fn is(&self, s: &str) -> bool {
        self.0.len() == s.chars().count() && self.0.iter().zip(s.chars()).all(|(&a, b)| a == b as u32)
    }

    /// The string as Rust text, or None if it holds a lone surrogate.
    pub fn to_string_opt(&self) -> Option<String> {
        self.0.iter().map(|&c| char::from_u32(c)).collect()
    }
}

/// A parsed JSON value with Python's types: int and float are distinct.
#[derive(Clone, Debug, PartialEq)]
pub enum Json {
    Null,
    Bool(bool),
    Int(BigInt),
    Float(f64),
    Str(PyStr),
    Array(Vec<Json>),
    /// Keys in first-insertion order; a repeated key replaced in place.
    Object(Vec<(PyStr, Json)>),
}

impl Json {
    pub fn get(&self, key: &str) -> Option<&Json> {
        match self {
            Json::Object(pairs) => pairs.iter().find(|(k, _)| k.is(key)).map(|(_, v)| v),
            _ => None,
        }
    }

    /// `json.dumps(value)` with Python's defaults: `", "` and `": "`
    /// separators, non-ASCII escaped, floats by repr, NaN and infinities by
    /// name.
    pub fn dumps(&self) -> String {
        let mut out = String::new();
        self.dump_into(&mut out);
        out
    }

    fn dump_into(&self, out: &mut String) {
        match self {
            Json::Null => out.push_str("null"),
            Json::Bool(true) => out.push_str("true"),
            Json::Bool(false) => out.push_str("false"),
            Json::Int(i) => {
                let _ = write!(out, "{i}");
            }
            Json::Float(x) => {
                if x.is_nan() {
                    out.push_str("NaN")
                } else if *x == f64::INFINITY {
                    out.push_str("Infinity")
                } else if *x == f64::NEG_INFINITY {
                    out.push_str("-Infinity")
                } else {
                    out.push_str(&py_float_repr(*x))
                }
            }
            Json::Str(s) => dump_str(s, out),
            Json::Array(items) => {
                out.push('[');
                for (i, v) in items.iter().enumerate() {
                    if i > 0 {
                        out.push_str(", ");
                    }
                    v.dump_into(out);
                }
                out.push(']');
            }
            Json::Object(pairs) => {
                out.push('{');
                for (i, (k, v)) in pairs.iter().enumerate() {
                    if i > 0 {
                        out.push_str(", ");
                    }
                    dump_str(k, out);
                    out.push_str(": ");
                    v.dump_into(out);
                }
                out.push('}');
            }
        }
    }
}

/// Python's `py_encode_basestring_ascii`.
fn dump_str(s: &PyStr, out: &mut String) {
    out.push('"');
    for &c in &s.0 {
        match c {
            0x22 => out.push_str("\\\""),
            0x5C => out.push_str("\\\\"),
            0x0A => out.push_str("\\n"),
            0x0D => out.push_str("\\r"),
            0x09 => out.push_str("\\t"),
            0x08 => out.push_str("\\b"),
            0x0C => out.push_str("\\f"),
            0x20..=0x7E => out.push(char::from_u32(c).unwrap_or('?')),
            0x10000.. => {
                let v = c - 0x10000;
                let _ = write!(out, "\\u{:04x}\\u{:04x}", 0xD800 | ((v >> 10) & 0x3FF), 0xDC00 | (v & 0x3FF));
            }
            _ => {
                let _ = write!(out, "\\u{c:04x}");
            }
        }
    }
    out.push('"');
}

/// A syntax error: Python's message and the code-point position of the
/// problem (the column is `pos + 1` on a line without newlines).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JsonError {
    pub msg: String,
    pub pos: usize,
}

/// Either a syntax error (with a column) or one of the two limits (whole
/// message, no column).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParseFailure {
    Syntax(JsonError),
    Limit(String),
}

fn syntax(msg: &str, pos: usize) -> ParseFailure {
    ParseFailure::Syntax(JsonError { msg: msg.to_string(), pos })
}

/// Whitespace as the JSON scanner skips it.
fn is_ws(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\n' | '\r')
}

/// The deepest `[`/`{` nesting of a line, counted outside strings (a `"`
/// opens or closes a string unless an odd run of backslashes precedes it
/// inside one). Unbalanced closers may drive the count below zero.
pub fn nesting_depth(line: &str) -> usize {
    let mut depth: i64 = 0;
    let mut deepest: i64 = 0;
    let mut in_string = false;
    let mut escaped = false;
    for c in line.chars() {
        if in_string {
            if escaped {
                escaped = false;
            } else if c == '\\' {
                escaped = true;
            } else if c == '"' {
                in_string = false;
            }
            continue;
        }
        match c {
            '"' => in_string = true,
            '[' | '{' => {
                depth += 1;
                deepest = deepest.max(depth);
            }
            ']' | '}' => depth -= 1,
            _ => {}
        }
    }
    deepest.max(0) as usize
}

/// `json.loads(line)` for one trace line (after the nesting limit).
pub fn loads(line: &str) -> Result<Json, ParseFailure> {
    let depth = nesting_depth(line);
    if depth > MAX_NESTING {
        return Err(ParseFailure::Limit(format!("brackets nested deeper than {MAX_NESTING} levels")));
    }
    let s: Vec<char> = line.chars().collect();
    if s.first() == Some(&'\u{feff}') {
        return Err(syntax("Unexpected UTF-8 BOM (decode using utf-8-sig)", 0));
    }
    let sc = Scanner { s: &s };
    let mut idx = 0;
    while idx < s.len() && is_ws(s[idx]) {
        idx += 1;
    }
    let (value, mut end) = match sc.scan_once(idx) {
        Ok(v) => v,
        Err(Fail::Stop(p)) => return Err(syntax("Expecting value", p)),
        Err(Fail::Other(f)) => return Err(f),
    };
    while end < s.len() && is_ws(s[end]) {
        end += 1;
    }
    if end != s.len() {
        return Err(syntax("Extra data", end));
    }
    Ok(value)
}

/// StopIteration (no value here: "Expecting value" at that position) or a
/// finished error.
enum Fail {
    Stop(usize),
    Other(ParseFailure),
}

impl From<ParseFailure> for Fail {
    fn from(f: ParseFailure) -> Self {
        Fail::Other(f)
    }
}

struct Scanner<'a> {
    s: &'a [char],
}

impl Scanner<'_> {
    fn at(&self, i: usize) -> char {
        self.s[i]
    }

    fn skip_ws(&self, mut idx: usize) -> usize {
        while idx < self.s.len() && is_ws(self.s[idx]) {
            idx += 1;
        }
        idx
    }

    fn matches(&self, idx: usize, word: &str) -> bool {
        let n = word.chars().count();
        idx + n <= self.s.len() && self.s[idx..idx + n].iter().copied().eq(word.chars())
    }

    fn scan_once(&self, idx: usize) -> Result<(Json, usize), Fail> {
        let len = self.s.len();
        if idx >= len {
            return Err(Fail::Stop(idx));
        }
        match self.at(idx) {
            '"' => {
                let (s, end) = self.scanstring(idx + 1)?;
                return Ok((Json::Str(s), end));
            }
            '{' => return self.parse_object(idx + 1),
            '[' => return self.parse_array(idx + 1),
            'n' if self.matches(idx, "null") => return Ok((Json::Null, idx + 4)),
            't' if self.matches(idx, "true") => return Ok((Json::Bool(true), idx + 4)),
            'f' if self.matches(idx, "false") => return Ok((Json::Bool(false), idx + 5)),
            'N' if self.matches(idx, "NaN") => return Ok((Json::Float(f64::NAN), idx + 3)),
            'I' if self.matches(idx, "Infinity") => return Ok((Json::Float(f64::INFINITY), idx + 8)),
            '-' if self.matches(idx, "-Infinity") => return Ok((Json::Float(f64::NEG_INFINITY), idx + 9)),
            _ => {}
        }
        self.match_number(idx)
    }

    fn parse_object(&self, start: usize) -> Result<(Json, usize), Fail> {
        let len = self.s.len();
        let mut pairs: Vec<(PyStr, Json)> = Vec::new();
        let mut idx = self.skip_ws(start);
        if idx >= len || self.at(idx) != '}' {
            loop {
                if idx >= len || self.at(idx) != '"' {
                    return Err(syntax("Expecting property name enclosed in double quotes", idx).into());
                }
                let (key, next) = self.scanstring(idx + 1)?;
                idx = self.skip_ws(next);
                if idx >= len || self.at(idx) != ':' {
                    return Err(syntax("Expecting ':' delimiter", idx).into());
                }
                idx = self.skip_ws(idx + 1);
                let (val, next) = self.scan_once(idx)?;
                match pairs.iter_mut().find(|(k, _)| *k == key) {
                    Some(slot) => slot.1 = val,
                    None => pairs.push((key, val)),
                }
                idx = self.skip_ws(next);
                if idx < len && self.at(idx) == '}' {
                    break;
                }
                if idx >= len || self.at(idx) != ',' {
                    return Err(syntax("Expecting ',' delimiter", idx).into());
                }
                idx = self.skip_ws(idx + 1);
            }
        }
        Ok((Json::Object(pairs), idx + 1))
    }

    fn parse_array(&self, start: usize) -> Result<(Json, usize), Fail> {
        let len = self.s.len();
        let mut items = Vec::new();
        let mut idx = self.skip_ws(start);
        if idx >= len || self.at(idx) != ']' {
            loop {
                let (val, next) = self.scan_once(idx)?;
                items.push(val);
                idx = self.skip_ws(next);
                if idx < len && self.at(idx) == ']' {
                    break;
                }
                if idx >= len || self.at(idx) != ',' {
                    return Err(syntax("Expecting ',' delimiter", idx).into());
                }
                idx = self.skip_ws(idx + 1);
            }
        }
        Ok((Json::Array(items), idx + 1))
    }

    /// `scanstring_unicode` with strict=True: `end` is just past the
    /// opening quote. Returns the string and the index past the closing one.
    fn scanstring(&self, end: usize) -> Result<(PyStr, usize), ParseFailure> {
        let len = self.s.len();
        let begin = end - 1;
        let mut out: Vec<u32> = Vec::new();
        let mut end = end;
        loop {
            let mut next = end;
            let mut c = '\0';
            while next < len {
                c = self.at(next);
                if c == '"' || c == '\\' {
                    break;
                }
                if (c as u32) <= 0x1F {
                    return Err(syntax("Invalid control character at", next));
                }
                next += 1;
            }
            if next >= len {
                return Err(syntax("Unterminated string starting at", begin));
            }
            out.extend(self.s[end..next].iter().map(|&ch| ch as u32));
            next += 1;
            if c == '"' {
                end = next;
                break;
            }
            if next == len {
                return Err(syntax("Unterminated string starting at", begin));
            }
            let esc = self.at(next);
            let code: u32;
            if esc != 'u' {
                end = next + 1;
                code = match esc {
                    '"' => '"' as u32,
                    '\\' => '\\' as u32,
                    '/' => '/' as u32,
                    'b' => 8,
                    'f' => 12,
                    'n' => 10,
                    'r' => 13,
                    't' => 9,
                    _ => return Err(syntax("Invalid \\escape", end - 2)),
                };
            } else {
                next += 1;
                end = next + 4;
                if end >= len {
                    return Err(syntax("Invalid \\uXXXX escape", next - 1));
                }
                let mut c1 = self.hex4(next).ok_or_else(|| syntax("Invalid \\uXXXX escape", end - 5))?;
                // A high surrogate followed by `\u` and a low one joins it.
                if (0xD800..=0xDBFF).contains(&c1) && end + 6 < len && self.at(end) == '\\' && self.at(end + 1) == 'u'
                {
                    let end2 = end + 6;
                    let c2 = self.hex4(end + 2).ok_or_else(|| syntax("Invalid \\uXXXX escape", end2 - 5))?;
                    if (0xDC00..=0xDFFF).contains(&c2) {
                        c1 = 0x10000 + (((c1 - 0xD800) << 10) | (c2 - 0xDC00));
                        end = end2;
                    }
                }
                code = c1;
            }
            out.push(code);
        }
        Ok((PyStr(out), end))
    }

    fn hex4(&self, at: usize) -> Option<u32> {
        let mut v = 0u32;
        for i in 0..4 {
            v = (v << 4) | self.at(at + i).to_digit(16).filter(|_| self.at(at + i).is_ascii_hexdigit())?;
        }
        Some(v)
    }

    fn is_digit(&self, i: usize) -> bool {
        self.at(i).is_ascii_digit()
    }

    fn match_number(&self, start: usize) -> Result<(Json, usize), Fail> {
        let end_idx = self.s.len() as isize - 1;
        let mut idx = start as isize;
        let mut is_float = false;
        let at = |i: isize| self.at(i as usize);
        if at(idx) == '-' {
            idx += 1;
            if idx > end_idx {
                return Err(Fail::Stop(start));
            }
        }
        if ('1'..='9').contains(&at(idx)) {
            idx += 1;
            while idx <= end_idx && self.is_digit(idx as usize) {
                idx += 1;
            }
        } else if at(idx) == '0' {
            idx += 1;
        } else {
            return Err(Fail::Stop(start));
        }
        if idx < end_idx && at(idx) == '.' && self.is_digit(idx as usize + 1) {
            is_float = true;
            idx += 2;
            while idx <= end_idx && self.is_digit(idx as usize) {
                idx += 1;
            }
        }
        if idx < end_idx && (at(idx) == 'e' || at(idx) == 'E') {
            let e_start = idx;
            idx += 1;
            if idx < end_idx && (at(idx) == '-' || at(idx) == '+') {
                idx += 1;
            }
            while idx <= end_idx && self.is_digit(idx as usize) {
                idx += 1;
            }
            if self.is_digit(idx as usize - 1) {
                is_float = true;
            } else {
                idx = e_start;
            }
        }
        let text: String = self.s[start..idx as usize].iter().collect();
        let value = if is_float {
            // Rust's parse and Python's float() both round correctly;
            // overflow gives infinity in both.
            Json::Float(text.parse::<f64>().map_err(|_| Fail::Stop(start))?)
        } else {
            let digits = text.trim_start_matches('-').len();
            if digits > MAX_INT_DIGITS {
                return Err(ParseFailure::Limit(format!(
                    "an integer literal of {digits} digits (at most {MAX_INT_DIGITS} are read)"
                ))
                .into());
            }
            Json::Int(text.parse::<BigInt>().map_err(|_| Fail::Stop(start))?)
        };
        Ok((value, idx as usize))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(s: &str) -> (String, usize) {
        match loads(s) {
            Err(ParseFailure::Syntax(e)) => (e.msg, e.pos + 1),
            other => panic!("{s:?}: expected a syntax error, got {other:?}"),
        }
    }

    #[test]
    fn syntax_errors_read_as_python_reports_them() {
        // Each case checked against CPython 3.11's json.loads.
        let cases: &[(&str, &str, usize)] = &[
            ("[1,", "Expecting value", 4),
            ("[", "Expecting value", 2),
            ("{", "Expecting property name enclosed in double quotes", 2),
            ("{\"a\":1,", "Expecting property name enclosed in double quotes", 8),
            ("{\"a\"", "Expecting ':' delimiter", 5),
            ("{\"a\":", "Expecting value", 6),
            ("\"abc", "Unterminated string starting at", 1),
            ("\"ab\\", "Unterminated string starting at", 1),
            ("\"a\\x\"", "Invalid \\escape", 3),
            ("\"\\u12\"", "Invalid \\uXXXX escape", 3),
            ("\"\\u12", "Invalid \\uXXXX escape", 3),
            ("\"\u{1}\"", "Invalid control character at", 2),
            ("1.", "Extra data", 2),
            ("1e+", "Extra data", 2),
            ("-", "Expecting value", 1),
            ("nul", "Expecting value", 1),
            ("-Inf", "Expecting value", 1),
            ("[1 2]", "Expecting ',' delimiter", 4),
            ("{\"a\" 1}", "Expecting ':' delimiter", 6),
            ("{\"a\":1,}", "Expecting property name enclosed in double quotes", 8),
            ("[1,]", "Expecting value", 4),
            ("\u{feff}{}", "Unexpected UTF-8 BOM (decode using utf-8-sig)", 1),
            ("", "Expecting value", 1),
            (" ", "Expecting value", 2),
            ("01", "Extra data", 2),
            ("[-]", "Expecting value", 2),
        ];
        for &(s, msg, col) in cases {
            assert_eq!(err(s), (msg.to_string(), col), "{s:?}");
        }
    }

    #[test]
    fn values_have_python_types() {
        assert_eq!(loads("\"\\u12345\"").unwrap(), Json::Str(PyStr(vec![0x1234, '5' as u32])));
        assert_eq!(loads("\"\\ud800\\u0041\"").unwrap(), Json::Str(PyStr(vec![0xD800, 0x41])));
        assert_eq!(loads("\"\\ud83d\\ude00\"").unwrap(), Json::Str(PyStr(vec![0x1F600])));
        assert!(matches!(loads("NaN").unwrap(), Json::Float(x) if x.is_nan()));
        assert_eq!(loads("-Infinity").unwrap(), Json::Float(f64::NEG_INFINITY));
        assert_eq!(loads("1e999").unwrap(), Json::Float(f64::INFINITY));
        assert_eq!(loads("-0").unwrap(), Json::Int(BigInt::from(0)));
        assert_eq!(loads("4.0").unwrap(), Json::Float(4.0));
        let big = "123456789012345678901234567890";
        assert_eq!(loads(big).unwrap().dumps(), big);
        let obj = loads("{\"a\": 1, \"b\": 2, \"a\": 3}").unwrap();
        assert_eq!(obj.dumps(), "{\"a\": 3, \"b\": 2}");
    }

    #[test]
    fn dumps_escapes_as_python_does() {
        let v = loads("[\"\\u00e9\\n\\u007f\", 1.5e+16, 1e-05, 0.5, \"\\ud83d\\ude00\", null, true]").unwrap();
        assert_eq!(v.dumps(), "[\"\\u00e9\\n\\u007f\", 1.5e+16, 1e-05, 0.5, \"\\ud83d\\ude00\", null, true]");
    }

    #[test]
    fn limits_are_refused_cleanly() {
        let deep = "[".repeat(MAX_NESTING + 1);
        assert!(matches!(loads(&deep), Err(ParseFailure::Limit(_))));
        let ok = format!("{}{}", "[".repeat(MAX_NESTING), "]".repeat(MAX_NESTING));
        assert!(loads(&ok).is_ok());
        let long = "1".repeat(MAX_INT_DIGITS + 1);
        assert!(matches!(loads(&long), Err(ParseFailure::Limit(_))));
        assert!(loads(&"1".repeat(MAX_INT_DIGITS)).is_ok());
    }
}
