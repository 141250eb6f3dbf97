//! Reader of FileStorage XML: `<opencv_storage>` holding one element per node.
//!
//! ```xml
//! <?xml version="1.0"?>
//! <opencv_storage>
//! <M1 type_id="opencv-matrix">
//!   <rows>3</rows>
//!   <cols>3</cols>
//!   <dt>d</dt>
//!   <data>
//!     1.2924345416408203e+03 0. 6.3950000000000000e+02 0.
//!     1.2924345416408203e+03 4.7950000000000000e+02 0. 0. 1.</data></M1>
//! <image_width>1280</image_width>
//! <imageSize>
//!   1280 1024</imageSize>
//! </opencv_storage>
//! ```
//!
//! A small tokenizer builds the element tree (depth capped at [`MAX_DEPTH`], so hostile
//! nesting cannot overflow the stack), then the children of `<opencv_storage>` become
//! nodes: `type_id="opencv-matrix"` a matrix, text a scalar or a number sequence,
//! anything with child elements [`Value::Skipped`].

use super::storage::{
    clip, matrix, parse_real, scalar, Node, Storage, StorageError, Value, MAX_DEPTH,
};

/// One element: name, attributes, its own text, its children.
struct Element {
    name: String,
    line: usize,
    attrs: Vec<(String, String)>,
    text: String,
    children: Vec<Element>,
}

struct Reader<'a> {
    s: &'a str,
    pos: usize,
    line: usize,
}

impl<'a> Reader<'a> {
    fn rest(&self) -> &'a str {
        &self.s[self.pos..]
    }

    fn advance(&mut self, n: usize) {
        self.line += self.s[self.pos..self.pos + n].matches('\n').count();
        self.pos += n;
    }

    fn error(&self, expected: &'static str) -> StorageError {
        StorageError::Syntax {
            line: self.line,
            expected,
            found: clip(self.rest()),
        }
    }

    fn skip_space(&mut self) {
        let n = self.rest().len() - self.rest().trim_start().len();
        self.advance(n);
    }

    /// Skips up to and past `end`; an error when it never comes.
    fn skip_past(&mut self, end: &str, expected: &'static str) -> Result<(), StorageError> {
        let at = self.rest().find(end).ok_or_else(|| self.error(expected))?;
        self.advance(at + end.len());
        Ok(())
    }

    /// Skips the prolog: `<?xml ...?>`, comments, `<!DOCTYPE ...>`, whitespace.
    fn skip_misc(&mut self) -> Result<(), StorageError> {
        loop {
            self.skip_space();
            let r = self.rest();
            if r.starts_with("<?") {
                self.skip_past("?>", "`?>` closing the declaration")?;
            } else if r.starts_with("<!--") {
                self.skip_past("-->", "`-->` closing the comment")?;
            } else if r.starts_with("<!") {
                self.skip_past(">", "`>` closing the declaration")?;
            } else {
                return Ok(());
            }
        }
    }

    fn name(&mut self) -> Result<String, StorageError> {
        let r = self.rest();
        let end = r
            .find(|c: char| c.is_whitespace() || matches!(c, '>' | '/' | '='))
            .unwrap_or(r.len());
        if end == 0 {
            return Err(self.error("a tag name"));
        }
        self.advance(end);
        Ok(r[..end].to_owned())
    }

    /// An element starting at `<`, with all it holds.
    fn element(&mut self, depth: usize) -> Result<Element, StorageError> {
        if depth > MAX_DEPTH {
            return Err(StorageError::TooDeep { line: self.line });
        }
        let line = self.line;
        if !self.rest().starts_with('<') {
            return Err(self.error("`<`"));
        }
        self.advance(1);
        let name = self.name()?;
        let mut attrs = Vec::new();
        loop {
            self.skip_space();
            let r = self.rest();
            if r.starts_with("/>") {
                self.advance(2);
                return Ok(Element {
                    name,
                    line,
                    attrs,
                    text: String::new(),
                    children: Vec::new(),
                });
            }
            if r.starts_with('>') {
                self.advance(1);
                break;
            }
            let attr = self.name()?;
            self.skip_space();
            if !self.rest().starts_with('=') {
                return Err(self.error("`=` after an attribute name"));
            }
            self.advance(1);
            self.skip_space();
            let quote = match self.rest().chars().next() {
                Some(q @ ('"' | '\'')) => q,
                _ => return Err(self.error("a quoted attribute value")),
            };
            self.advance(1);
            let end = self
                .rest()
                .find(quote)
                .ok_or_else(|| self.error("the attribute value's closing quote"))?;
            let value = unescape(&self.rest()[..end]);
            self.advance(end + 1);
            attrs.push((attr, value));
        }
        let mut text = String::new();
        let mut children = Vec::new();
        loop {
            let r = self.rest();
            let lt = r.find('<').ok_or_else(|| self.error("a closing tag"))?;
            text.push_str(&unescape(&r[..lt]));
            self.advance(lt);
            let r = self.rest();
            if r.starts_with("<!--") {
                self.skip_past("-->", "`-->` closing the comment")?;
            } else if r.starts_with("<![CDATA[") {
                let end = r.find("]]>").ok_or_else(|| self.error("`]]>`"))?;
                text.push_str(&r[9..end]);
                self.advance(end + 3);
            } else if r.starts_with("</") {
                self.advance(2);
                let close = self.name()?;
                self.skip_space();
                if close != name || !self.rest().starts_with('>') {
                    return Err(self.error("the closing tag of the open element"));
                }
                self.advance(1);
                return Ok(Element {
                    name,
                    line,
                    attrs,
                    text,
                    children,
                });
            } else {
                children.push(self.element(depth + 1)?);
            }
        }
    }
}

/// Replaces the five predefined entities and numeric references.
fn unescape(s: &str) -> String {
    if !s.contains('&') {
        return s.to_owned();
    }
    let mut out = String::new();
    let mut rest = s;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        rest = &rest[amp..];
        let Some(semi) = rest.find(';').filter(|&i| i <= 10) else {
            out.push('&');
            rest = &rest[1..];
            continue;
        };
        let entity = &rest[1..semi];
        let c = match entity {
            "lt" => Some('<'),
            "gt" => Some('>'),
            "amp" => Some('&'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            _ => entity
                .strip_prefix("#x")
                .map(|h| u32::from_str_radix(h, 16))
                .or_else(|| entity.strip_prefix('#').map(str::parse))
                .and_then(Result::ok)
                .and_then(char::from_u32),
        };
        match c {
            Some(c) => {
                out.push(c);
                rest = &rest[semi + 1..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

/// Reads FileStorage XML text.
pub fn parse(text: &str) -> Result<Storage, StorageError> {
    let mut r = Reader {
        s: text.trim_start_matches('\u{feff}'),
        pos: 0,
        line: 1,
    };
    r.skip_misc()?;
    let root = r.element(0)?;
    if root.name != "opencv_storage" {
        return Err(StorageError::Syntax {
            line: root.line,
            expected: "the root element <opencv_storage>",
            found: clip(&root.name),
        });
    }
    let mut storage = Storage::default();
    let mut seen = std::collections::HashSet::new();
    for e in &root.children {
        if !seen.insert(e.name.as_str()) {
            return Err(StorageError::DuplicateKey {
                key: e.name.clone(),
                line: e.line,
            });
        }
        storage.nodes.push(Node {
            key: e.name.clone(),
            line: e.line,
            value: node_value(e)?,
        });
    }
    Ok(storage)
}

fn node_value(e: &Element) -> Result<Value, StorageError> {
    let type_id = e
        .attrs
        .iter()
        .find(|(k, _)| k == "type_id")
        .map(|(_, v)| v.as_str());
    match type_id {
        Some("opencv-matrix") => {
            let field = |name: &str| {
                e.children
                    .iter()
                    .find(|c| c.name == name)
                    .map(|c| c.text.as_str())
            };
            Ok(Value::Matrix(matrix(
                &e.name,
                e.line,
                field("rows"),
                field("cols"),
                field("dt"),
                field("data"),
            )?))
        }
        Some(_) => Ok(Value::Skipped),
        None if !e.children.is_empty() => Ok(Value::Skipped),
        None => {
            let text = e.text.trim();
            if let Some(inner) = text.strip_prefix('"') {
                return Ok(Value::Str(
                    inner.strip_suffix('"').unwrap_or(inner).to_owned(),
                ));
            }
            let tokens: Vec<&str> = text.split_whitespace().collect();
            if tokens.len() > 1 {
                let items: Option<Vec<f64>> = tokens.iter().map(|t| parse_real(t)).collect();
                return Ok(items.map_or_else(|| Value::Str(text.to_owned()), Value::Seq));
            }
            Ok(scalar(text))
        }
    }
}
