//! The part of OpenCV's `cv::FileStorage` that calibration files use: top-level named
//! nodes holding matrices (`!!opencv-matrix` in YAML, `type_id="opencv-matrix"` in XML),
//! integers, reals, strings and flat number sequences (`imageSize: [ 640, 480 ]`).
//! Nested maps and sequences of anything else are kept as [`Value::Skipped`].
//!
//! ```text
//! bytes --(parse: %YAML -> yaml::parse, <...> -> xml::parse)--> Storage --(to_text)--> YAML / XML
//! ```
//!
//! Why our own reader: FileStorage's YAML is YAML 1.0 with a `%YAML:1.0` directive
//! (a colon where YAML 1.1/1.2 wants a space) and local `!!opencv-matrix` tags; the
//! maintained Rust YAML crates (serde_yaml's successors, yaml-rust2, saphyr) reject the
//! directive outright, and the `opencv` crate binds the C++ library, which the host does
//! not link. The subset is small: one level of `key: value`, a matrix's four fields, and
//! numbers as C's `strtod` writes them (`1.`, `-2.5e-03`, `.Nan`, `.Inf`).
//!
//! Reading never panics on any bytes and allocates no more than a small multiple of the
//! input's size: a matrix's `rows`/`cols` are only compared with the values actually
//! present, never used to size a buffer. Writing keeps every f64 exactly (Rust's shortest
//! round-trip form), so a file read back gives the same numbers bit for bit.

use std::fmt::Write as _;

/// Deepest XML element nesting read (guards the recursion against hostile input).
pub const MAX_DEPTH: usize = 64;

/// The two text forms of a FileStorage file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `%YAML:1.0` and `!!opencv-matrix` nodes (`.yml`, `.yaml`).
    Yaml,
    /// `<opencv_storage>` and `type_id="opencv-matrix"` nodes (`.xml`).
    Xml,
}

/// A matrix's element type, OpenCV's `dt` letter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Depth {
    /// `u`: 8-bit unsigned.
    U8,
    /// `c`: 8-bit signed.
    I8,
    /// `w`: 16-bit unsigned.
    U16,
    /// `s`: 16-bit signed.
    I16,
    /// `i`: 32-bit signed.
    I32,
    /// `f`: 32-bit float.
    F32,
    /// `d`: 64-bit float.
    F64,
}

impl Depth {
    /// The type of a `dt` letter; `None` for one OpenCV calibration files do not use.
    pub fn from_code(code: &str) -> Option<Self> {
        Some(match code {
            "u" => Self::U8,
            "c" => Self::I8,
            "w" => Self::U16,
            "s" => Self::I16,
            "i" => Self::I32,
            "f" => Self::F32,
            "d" => Self::F64,
            _ => return None,
        })
    }

    /// The `dt` letter.
    pub fn code(self) -> char {
        match self {
            Self::U8 => 'u',
            Self::I8 => 'c',
            Self::U16 => 'w',
            Self::I16 => 's',
            Self::I32 => 'i',
            Self::F32 => 'f',
            Self::F64 => 'd',
        }
    }
}

/// A dense 2-D matrix, values row-major (every element type widened to f64, exactly).
#[derive(Clone, Debug, PartialEq)]
pub struct Matrix {
    /// Row count.
    pub rows: usize,
    /// Column count.
    pub cols: usize,
    /// The element type the file gave.
    pub depth: Depth,
    /// `rows * cols` values, row-major.
    pub data: Vec<f64>,
}

impl Matrix {
    /// A `dt: d` matrix; `data` row-major, `rows * cols` long.
    pub fn f64(rows: usize, cols: usize, data: Vec<f64>) -> Self {
        debug_assert_eq!(rows * cols, data.len());
        Self {
            rows,
            cols,
            depth: Depth::F64,
            data,
        }
    }

    /// Element `(r, c)`.
    pub fn at(&self, r: usize, c: usize) -> f64 {
        self.data[r * self.cols + c]
    }
}

/// The value of one top-level node.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// An `opencv-matrix` node.
    Matrix(Matrix),
    /// An integer.
    Int(i64),
    /// A real number.
    Real(f64),
    /// A string (quoted or not in the file).
    Str(String),
    /// A flat sequence of numbers, as OpenCV writes `cv::Size` and `std::vector<double>`.
    Seq(Vec<f64>),
    /// A nested map, a sequence of non-numbers or another type: read over, not kept.
    Skipped,
}

/// One top-level node.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Its name.
    pub key: String,
    /// The 1-based line it starts on (0 for nodes built in memory).
    pub line: usize,
    /// Its value.
    pub value: Value,
}

/// The top-level nodes of a file, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Storage {
    /// The nodes; keys are unique.
    pub nodes: Vec<Node>,
}

impl Storage {
    /// The node named `key`.
    pub fn get(&self, key: &str) -> Option<&Node> {
        self.nodes.iter().find(|n| n.key == key)
    }

    /// Appends a node (for writing; line 0).
    pub fn push(&mut self, key: &str, value: Value) {
        self.nodes.push(Node {
            key: key.to_owned(),
            line: 0,
            value,
        });
    }
}

/// What can be wrong with a FileStorage file.
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    /// The bytes start with neither `%YAML` nor `<`.
    #[error("not an OpenCV FileStorage file: it starts with neither `%YAML` nor an XML tag")]
    UnknownFormat,
    /// The bytes are not UTF-8.
    #[error("line {line}: the file is not UTF-8 text")]
    NotUtf8 {
        /// Line of the first bad byte.
        line: usize,
    },
    /// The text does not have the expected shape.
    #[error("line {line}: expected {expected}, found {found:?}")]
    Syntax {
        /// Line.
        line: usize,
        /// What the reader wanted.
        expected: &'static str,
        /// The start of what it found (at most 40 characters).
        found: String,
    },
    /// A key appears twice at the top level.
    #[error("line {line}: key {key:?} appears a second time")]
    DuplicateKey {
        /// The key.
        key: String,
        /// Line of the second one.
        line: usize,
    },
    /// A matrix node lacks one of `rows`, `cols`, `dt`, `data`.
    #[error("{key} (line {line}): the matrix has no `{field}`")]
    MissingField {
        /// The matrix's key.
        key: String,
        /// Its line.
        line: usize,
        /// The missing field.
        field: &'static str,
    },
    /// A number does not parse.
    #[error("{key} (line {line}): {field} holds {text:?}, not a number")]
    BadNumber {
        /// The node's key.
        key: String,
        /// Its line.
        line: usize,
        /// `rows`, `cols` or `data`.
        field: &'static str,
        /// The text found (at most 40 characters).
        text: String,
    },
    /// A matrix's `dt` is not a single-channel type this reader knows.
    #[error("{key} (line {line}): element type dt = {dt:?} is not one of u c w s i f d (single channel)")]
    UnknownDt {
        /// The matrix's key.
        key: String,
        /// Its line.
        line: usize,
        /// The `dt` found (at most 40 characters).
        dt: String,
    },
    /// `rows * cols` differs from the number of values in `data`.
    #[error("{key} (line {line}): a {rows}x{cols} matrix needs {} values, data holds {count}", (*.rows as u128) * (*.cols as u128))]
    SizeMismatch {
        /// The matrix's key.
        key: String,
        /// Its line.
        line: usize,
        /// `rows` claimed.
        rows: u64,
        /// `cols` claimed.
        cols: u64,
        /// Values found.
        count: usize,
    },
    /// XML elements nest deeper than [`MAX_DEPTH`].
    #[error("line {line}: elements nest deeper than {MAX_DEPTH}")]
    TooDeep {
        /// Line of the element too deep.
        line: usize,
    },
}

/// Reads a FileStorage file, YAML or XML, told apart by its first characters.
pub fn parse(bytes: &[u8]) -> Result<Storage, StorageError> {
    let text = std::str::from_utf8(bytes).map_err(|e| StorageError::NotUtf8 {
        line: 1 + bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count(),
    })?;
    let start = text.trim_start_matches('\u{feff}').trim_start();
    if start.starts_with("%YAML") {
        super::yaml::parse(text)
    } else if start.starts_with('<') {
        super::xml::parse(text)
    } else {
        Err(StorageError::UnknownFormat)
    }
}

/// Reads FileStorage YAML text (the `%YAML` directive optional).
pub fn parse_yaml(text: &str) -> Result<Storage, StorageError> {
    super::yaml::parse(text)
}

/// Reads FileStorage XML text.
pub fn parse_xml(text: &str) -> Result<Storage, StorageError> {
    super::xml::parse(text)
}

/// The format a file name asks for: `.xml` -> XML, `.yml`/`.yaml` -> YAML, else `None`.
pub fn format_of(path: &std::path::Path) -> Option<Format> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "xml" => Some(Format::Xml),
        "yml" | "yaml" => Some(Format::Yaml),
        _ => None,
    }
}

/// Parses one number as C's `strtod` and OpenCV write it (`1.`, `.5`, `-2.5e-03`,
/// `.Nan`, `.Inf`, `-.Inf`); `None` for anything else (no `inf`/`nan` words, no hex).
pub fn parse_real(token: &str) -> Option<f64> {
    match token.to_ascii_lowercase().as_str() {
        ".inf" | "+.inf" => return Some(f64::INFINITY),
        "-.inf" => return Some(f64::NEG_INFINITY),
        ".nan" => return Some(f64::NAN),
        _ => {}
    }
    let ok = !token.is_empty()
        && token.bytes().any(|b| b.is_ascii_digit())
        && token
            .bytes()
            .all(|b| b.is_ascii_digit() || matches!(b, b'+' | b'-' | b'.' | b'e' | b'E'));
    if ok {
        token.parse().ok()
    } else {
        None
    }
}

/// A scalar's text as a value: integer, real, or string.
pub(super) fn scalar(text: &str) -> Value {
    if let Ok(i) = text.parse::<i64>() {
        Value::Int(i)
    } else if let Some(v) = parse_real(text) {
        Value::Real(v)
    } else {
        Value::Str(text.to_owned())
    }
}

/// At most 40 characters of `s`, for error messages.
pub(super) fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

/// Builds a matrix node from its four fields' texts; `data` holds the values separated
/// by commas and/or whitespace.
pub(super) fn matrix(
    key: &str,
    line: usize,
    rows: Option<&str>,
    cols: Option<&str>,
    dt: Option<&str>,
    data: Option<&str>,
) -> Result<Matrix, StorageError> {
    let missing = |field| StorageError::MissingField {
        key: key.to_owned(),
        line,
        field,
    };
    let count = |field: &'static str, text: Option<&str>| -> Result<u64, StorageError> {
        let text = text.ok_or_else(|| missing(field))?.trim();
        text.parse().map_err(|_| StorageError::BadNumber {
            key: key.to_owned(),
            line,
            field,
            text: clip(text),
        })
    };
    let rows = count("rows", rows)?;
    let cols = count("cols", cols)?;
    let dt = dt.ok_or_else(|| missing("dt"))?.trim();
    let dt = dt.trim_matches(|c| c == '"' || c == '\'');
    let depth = Depth::from_code(dt).ok_or_else(|| StorageError::UnknownDt {
        key: key.to_owned(),
        line,
        dt: clip(dt),
    })?;
    let data = data.ok_or_else(|| missing("data"))?;
    // A `dt: f` matrix is f32 in OpenCV; its 9-digit text rounds back to those values.
    let narrow = |v: f64| {
        if depth == Depth::F32 {
            v as f32 as f64
        } else {
            v
        }
    };
    // Values are collected from the text, so the vector never outgrows the input.
    let mut values = Vec::new();
    for token in data
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
    {
        values.push(narrow(parse_real(token).ok_or_else(|| {
            StorageError::BadNumber {
                key: key.to_owned(),
                line,
                field: "data",
                text: clip(token),
            }
        })?));
    }
    if u128::from(rows) * u128::from(cols) != values.len() as u128 {
        return Err(StorageError::SizeMismatch {
            key: key.to_owned(),
            line,
            rows,
            cols,
            count: values.len(),
        });
    }
    Ok(Matrix {
        // Both fit: their product equals a vector's length.
        rows: rows as usize,
        cols: cols as usize,
        depth,
        data: values,
    })
}

/// A real as text that reads back to the same f64 (`.Nan`, `.Inf` as OpenCV writes them).
fn real(v: f64) -> String {
    if v.is_nan() {
        ".Nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { ".Inf" } else { "-.Inf" }.into()
    } else {
        format!("{v:?}")
    }
}

/// A sequence element: integral values without a fraction (OpenCV writes sizes as ints).
fn seq_item(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v}")
    } else {
        real(v)
    }
}

/// Renders the nodes as a FileStorage file (skipped nodes are left out).
pub fn to_text(storage: &Storage, format: Format) -> String {
    match format {
        Format::Yaml => to_yaml(storage),
        Format::Xml => to_xml(storage),
    }
}

fn to_yaml(storage: &Storage) -> String {
    let mut out = String::from("%YAML:1.0\n---\n");
    for node in &storage.nodes {
        let key = &node.key;
        // Writing to a String cannot fail.
        let _ = match &node.value {
            Value::Matrix(m) => {
                let data: Vec<String> = m.data.iter().map(|&v| real(v)).collect();
                let mut lines = data.chunks(4).map(|c| c.join(", "));
                let first = lines.next().unwrap_or_default();
                let rest: String = lines.map(|l| format!(",\n       {l}")).collect();
                writeln!(
                    out,
                    "{key}: !!opencv-matrix\n   rows: {}\n   cols: {}\n   dt: {}\n   data: [ {first}{rest} ]",
                    m.rows,
                    m.cols,
                    m.depth.code()
                )
            }
            Value::Int(i) => writeln!(out, "{key}: {i}"),
            Value::Real(v) => writeln!(out, "{key}: {}", real(*v)),
            Value::Str(s) => writeln!(
                out,
                "{key}: \"{}\"",
                s.replace('\\', "\\\\").replace('"', "\\\"")
            ),
            Value::Seq(s) => {
                let items: Vec<String> = s.iter().map(|&v| seq_item(v)).collect();
                writeln!(out, "{key}: [ {} ]", items.join(", "))
            }
            Value::Skipped => Ok(()),
        };
    }
    out
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn to_xml(storage: &Storage) -> String {
    let mut out = String::from("<?xml version=\"1.0\"?>\n<opencv_storage>\n");
    for node in &storage.nodes {
        let key = &node.key;
        let _ = match &node.value {
            Value::Matrix(m) => {
                let data: Vec<String> = m.data.iter().map(|&v| real(v)).collect();
                let lines: Vec<String> = data.chunks(4).map(|c| c.join(" ")).collect();
                writeln!(
                    out,
                    "<{key} type_id=\"opencv-matrix\">\n  <rows>{}</rows>\n  <cols>{}</cols>\n  <dt>{}</dt>\n  <data>\n    {}</data></{key}>",
                    m.rows,
                    m.cols,
                    m.depth.code(),
                    lines.join("\n    ")
                )
            }
            Value::Int(i) => writeln!(out, "<{key}>{i}</{key}>"),
            Value::Real(v) => writeln!(out, "<{key}>{}</{key}>", real(*v)),
            Value::Str(s) => writeln!(out, "<{key}>\"{}\"</{key}>", xml_escape(s)),
            Value::Seq(s) => {
                let items: Vec<String> = s.iter().map(|&v| seq_item(v)).collect();
                writeln!(out, "<{key}>\n  {}</{key}>", items.join(" "))
            }
            Value::Skipped => Ok(()),
        };
    }
    out.push_str("</opencv_storage>\n");
    out
}
