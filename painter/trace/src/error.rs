//! A refused trace: its line and the [`ErrorKind`] both readers agree on
//! (spec 12.2; `traces/malformed/expected.json` holds them to it); the
//! message is this reader's own.

/// What is wrong with a refused trace, as the short stable code of spec
/// 12.2 that both readers must agree on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The file cannot be read (line 0).
    Io,
    /// Bytes that are not UTF-8.
    Utf8,
    /// A line that is not JSON under the rules of spec 12.2.
    Json,
    /// No `ddo-trace` header first, or a version this reader does not know.
    Header,
    /// A line or field of the wrong JSON type.
    Type,
    /// A required field is absent.
    Missing,
    /// A value outside what its field allows.
    Range,
    /// More work or memory than the limits allow (stamps per segment,
    /// roots, the cell budget against the roots).
    Budget,
    /// An unknown `ev`.
    Event,
    /// An event out of place (time going back, a sample outside a stroke,
    /// undo with nothing to undo, ...).
    EventOrder,
    /// A render or snapshot name that is no plain name or is used twice.
    Name,
    /// A `layer` event or a stroke the document cannot take (spec 14.2).
    Layer,
    /// An `import` event's file: unreadable, another digest, or not a voxel
    /// set for this canvas (spec 15.2).
    Import,
}

impl ErrorKind {
    pub const ALL: [ErrorKind; 13] = [
        ErrorKind::Io,
        ErrorKind::Utf8,
        ErrorKind::Json,
        ErrorKind::Header,
        ErrorKind::Type,
        ErrorKind::Missing,
        ErrorKind::Range,
        ErrorKind::Budget,
        ErrorKind::Event,
        ErrorKind::EventOrder,
        ErrorKind::Name,
        ErrorKind::Layer,
        ErrorKind::Import,
    ];

    /// The code as the spec writes it.
    pub fn code(self) -> &'static str {
        match self {
            ErrorKind::Io => "io",
            ErrorKind::Utf8 => "utf8",
            ErrorKind::Json => "json",
            ErrorKind::Header => "header",
            ErrorKind::Type => "type",
            ErrorKind::Missing => "missing",
            ErrorKind::Range => "range",
            ErrorKind::Budget => "budget",
            ErrorKind::Event => "event",
            ErrorKind::EventOrder => "event-order",
            ErrorKind::Name => "name",
            ErrorKind::Layer => "layer",
            ErrorKind::Import => "import",
        }
    }

    pub fn from_code(code: &str) -> Option<ErrorKind> {
        ErrorKind::ALL.into_iter().find(|k| k.code() == code)
    }
}

/// A trace that must not be replayed: where (1-based line, 0 when the file
/// cannot be read), what kind of error, and a message naming the field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.text())]
pub struct TraceError {
    pub line: usize,
    pub kind: ErrorKind,
    pub message: String,
}

impl TraceError {
    pub fn new(line: usize, kind: ErrorKind, message: impl Into<String>) -> Self {
        TraceError { line, kind, message: message.into() }
    }

    /// `line N: MESSAGE` (the message alone at line 0).
    pub fn text(&self) -> String {
        if self.line == 0 { self.message.clone() } else { format!("line {}: {}", self.line, self.message) }
    }
}
