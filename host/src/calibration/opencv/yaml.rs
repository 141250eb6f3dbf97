//! Reader of FileStorage YAML: `%YAML:1.0`, then one `key: value` per top-level line.
//!
//! ```yaml
//! %YAML:1.0
//! ---
//! M1: !!opencv-matrix
//!    rows: 3
//!    cols: 3
//!    dt: d
//!    data: [ 1.2924345416408203e+03, 0., 6.3950000000000000e+02, 0.,
//!        1.2924345416408203e+03, 4.7950000000000000e+02, 0., 0., 1. ]
//! image_width: 1280
//! calibration_time: "Mon Dec  1 10:00:00 2026"
//! ```
//!
//! Lines indented deeper than the top level belong to the node above them; a matrix's
//! fields (and `data` spread over several lines) are read from that block joined into
//! one text, so any line breaking OpenCV chooses reads the same.

use super::storage::{clip, matrix, parse_real, scalar, Node, Storage, StorageError, Value};

/// One non-blank, non-comment line.
struct Line<'a> {
    no: usize,
    indent: usize,
    text: &'a str,
}

/// Cuts a `#` comment that starts a word outside quotes.
fn strip_comment(s: &str) -> &str {
    let mut quote = None;
    let mut prev_space = true;
    for (i, c) in s.char_indices() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), _) if c == q => quote = None,
            (None, '#') if prev_space => return &s[..i],
            _ => {}
        }
        prev_space = c.is_whitespace();
    }
    s
}

/// Reads FileStorage YAML text (the `%YAML` directive is optional here).
pub fn parse(text: &str) -> Result<Storage, StorageError> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim_start_matches('\u{feff}');
        let body = strip_comment(raw).trim_end();
        let trimmed = body.trim_start();
        let indent = body.len() - trimmed.len();
        let directive = indent == 0
            && (trimmed.starts_with('%') || trimmed.starts_with("---") || trimmed == "...");
        if trimmed.is_empty() || directive {
            continue;
        }
        lines.push(Line {
            no: i + 1,
            indent,
            text: trimmed,
        });
    }
    let mut storage = Storage::default();
    let mut seen = std::collections::HashSet::new();
    let base = lines.first().map_or(0, |l| l.indent);
    let mut i = 0;
    while i < lines.len() {
        let head = &lines[i];
        if head.indent != base {
            return Err(syntax(head.no, "a top-level `key: value`", head.text));
        }
        let end = i
            + 1
            + lines[i + 1..]
                .iter()
                .take_while(|l| l.indent > base)
                .count();
        let block = &lines[i + 1..end];
        let (key, rest) = split_key(head.text)
            .ok_or_else(|| syntax(head.no, "a top-level `key: value`", head.text))?;
        if !seen.insert(key) {
            return Err(StorageError::DuplicateKey {
                key: key.to_owned(),
                line: head.no,
            });
        }
        let value = node_value(key, head.no, rest, block)?;
        storage.nodes.push(Node {
            key: key.to_owned(),
            line: head.no,
            value,
        });
        i = end;
    }
    Ok(storage)
}

fn syntax(line: usize, expected: &'static str, found: &str) -> StorageError {
    StorageError::Syntax {
        line,
        expected,
        found: clip(found),
    }
}

/// `key: rest` (or `key:` alone), the key unquoted; `None` without a colon.
fn split_key(text: &str) -> Option<(&str, &str)> {
    let colon = text
        .char_indices()
        .find(|&(i, c)| c == ':' && text[i + 1..].chars().next().is_none_or(char::is_whitespace))?
        .0;
    let key = text[..colon].trim().trim_matches(|c| c == '"' || c == '\'');
    (!key.is_empty() && !key.starts_with('-')).then(|| (key, text[colon + 1..].trim()))
}

/// The rest of the head line and the block under it, as one text.
fn joined(rest: &str, block: &[Line]) -> String {
    let mut s = rest.to_owned();
    for l in block {
        s.push(' ');
        s.push_str(l.text);
    }
    s
}

fn node_value(key: &str, line: usize, rest: &str, block: &[Line]) -> Result<Value, StorageError> {
    const MATRIX_TAGS: [&str; 2] = ["!!opencv-matrix", "!<tag:yaml.org,2002:opencv-matrix>"];
    if let Some(tag) = MATRIX_TAGS.iter().find(|t| rest.starts_with(**t)) {
        let text = joined(&rest[tag.len()..], block);
        let fields = flow_fields(&text).ok_or_else(|| {
            syntax(
                line,
                "matrix fields `rows: .. cols: .. dt: .. data: [ .. ]`",
                &text,
            )
        })?;
        let field = |name: &str| fields.iter().find(|(k, _)| *k == name).map(|(_, v)| *v);
        return Ok(Value::Matrix(matrix(
            key,
            line,
            field("rows"),
            field("cols"),
            field("dt"),
            field("data"),
        )?));
    }
    if rest.is_empty() || rest.starts_with('!') || rest.starts_with('{') || rest.starts_with('&') {
        // A nested map, a block sequence, another type: not part of the subset.
        return Ok(Value::Skipped);
    }
    if rest.starts_with('[') {
        let text = joined(rest, block);
        let Some(inner) = text[1..].split_once(']').map(|(a, _)| a) else {
            return Err(syntax(line, "a sequence closed by `]`", &text));
        };
        let items: Option<Vec<f64>> = inner
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(parse_real)
            .collect();
        return Ok(items.map_or(Value::Skipped, Value::Seq));
    }
    if !block.is_empty() {
        // A plain scalar folded over several lines: no calibration key is written so.
        return Ok(Value::Skipped);
    }
    Ok(match rest.chars().next() {
        Some(q @ ('"' | '\'')) => Value::Str(unquote(&rest[1..], q)),
        _ => scalar(rest),
    })
}

/// The text of a quoted scalar after its opening quote (`\"`, `\\` and `''` unescaped).
fn unquote(s: &str, quote: char) -> String {
    let mut out = String::new();
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if quote == '"' => {
                if let Some(n) = chars.next() {
                    out.push(match n {
                        'n' => '\n',
                        't' => '\t',
                        other => other,
                    });
                }
            }
            c if c == quote => {
                if quote == '\'' && chars.peek() == Some(&'\'') {
                    chars.next();
                    out.push('\'');
                } else {
                    break;
                }
            }
            c => out.push(c),
        }
    }
    out
}

/// `k: v k: [ a, b ] ...` (commas and braces allowed) as `(key, value)` pairs; a `[`
/// value runs to its `]`. `None` when a key lacks its colon or a `[` its `]`.
fn flow_fields(text: &str) -> Option<Vec<(&str, &str)>> {
    let mut fields = Vec::new();
    let mut s = text;
    loop {
        s = s.trim_start_matches(|c: char| c.is_whitespace() || matches!(c, ',' | '{' | '}'));
        if s.is_empty() {
            return Some(fields);
        }
        let colon = s.find(':')?;
        let key = s[..colon].trim();
        if key.is_empty() || key.contains(char::is_whitespace) {
            return None;
        }
        s = s[colon + 1..].trim_start();
        let value;
        if let Some(inner) = s.strip_prefix('[') {
            let close = inner.find(']')?;
            value = &inner[..close];
            s = &inner[close + 1..];
        } else {
            let end = s
                .find(|c: char| c.is_whitespace() || matches!(c, ',' | '}'))
                .unwrap_or(s.len());
            value = &s[..end];
            s = &s[end..];
        }
        fields.push((key, value));
    }
}
