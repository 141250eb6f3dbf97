//! Reads the point clouds other tools write: ASCII and binary (little or big
//! endian) PLY as Open3D, MeshLab and CloudCompare save them. The vertex
//! element's `x y z` (float or double, any scalar type) are required;
//! `nx ny nz`, `red green blue` and `quality` (slscan's convention: each
//! point's predicted sigma, in the file's unit) are taken when present; every
//! other property and element (faces, ...) is skipped. Coordinates are in
//! the file's unit, scaled to metres by the caller's `unit_m`.
//!
//! [`parse_ply`] is the pure parser (bytes in, cloud out; fuzzed in
//! `fuzz/`), [`read_ply`] reads a file.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::fusion::PointCloud;

/// A cloud read from a PLY file.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyCloud {
    /// Points (metres), normals and quality, ready for registration.
    pub cloud: PointCloud,
    /// Per-point colour, when the file has `red green blue`.
    pub colours: Option<Vec<[u8; 3]>>,
}

/// What can be wrong with a PLY file.
#[derive(Debug, thiserror::Error)]
pub enum PlyReadError {
    /// The file could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file does not start with the `ply` magic line.
    #[error("not a PLY file (no `ply` first line)")]
    NotPly,
    /// A header line could not be understood.
    #[error("PLY header line {line}: {reason}")]
    Header {
        /// 1-based header line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// No `element vertex` (a face-only mesh), or one with no vertices.
    #[error("the PLY file has no vertices (a mesh without points, or an empty cloud)")]
    NoVertices,
    /// The vertex element lacks `x`, `y` or `z`.
    #[error("the PLY vertex element has no `{0}` property")]
    MissingCoordinate(&'static str),
    /// The body ends before element `element`'s entry `index`.
    #[error("the PLY body ends early: {element} {index} of {count} is missing or cut")]
    Truncated {
        /// Element name.
        element: String,
        /// 0-based entry.
        index: usize,
        /// Entries the header announced.
        count: usize,
    },
    /// An ASCII value that is not a number of its type.
    #[error("PLY body line {line}: {reason}")]
    Value {
        /// 1-based line of the body.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A vertex with a NaN or infinite coordinate.
    #[error("PLY vertex {index} has a non-finite coordinate")]
    NonFinite {
        /// 0-based vertex.
        index: usize,
    },
    /// A unit that is not a positive finite number.
    #[error("unit {0} m is not a positive finite number")]
    BadUnit(f64),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLittle,
    BinaryBig,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
enum Property {
    Scalar { name: String, kind: Scalar },
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

/// Where the vertex properties we take sit in a vertex record.
#[derive(Clone, Copy, Debug, Default)]
struct Slots {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
    colour: Option<[usize; 3]>,
    quality: Option<usize>,
}

/// Reads the PLY file at `path`; coordinates in units of `unit_m` metres
/// (1e-3 for a file in millimetres).
pub fn read_ply(path: &Path, unit_m: f64) -> Result<PlyCloud, PlyReadError> {
    let bytes = std::fs::read(path).map_err(|source| PlyReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_ply(&bytes, unit_m)
}

/// Parses a whole PLY file's bytes (see the module doc).
pub fn parse_ply(bytes: &[u8], unit_m: f64) -> Result<PlyCloud, PlyReadError> {
    if !(unit_m.is_finite() && unit_m > 0.0) {
        return Err(PlyReadError::BadUnit(unit_m));
    }
    let (format, elements, body) = parse_header(bytes)?;
    let vertex_at = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or(PlyReadError::NoVertices)?;
    let vertex = &elements[vertex_at];
    if vertex.count == 0 {
        return Err(PlyReadError::NoVertices);
    }
    let slots = slots(vertex)?;
    let records = match format {
        Format::Ascii => ascii_records(body, &elements, vertex_at)?,
        Format::BinaryLittle | Format::BinaryBig => {
            binary_records(body, &elements, vertex_at, format == Format::BinaryBig)?
        }
    };
    to_cloud(&records, &slots, unit_m)
}

fn parse_header(bytes: &[u8]) -> Result<(Format, Vec<Element>, &[u8]), PlyReadError> {
    let mut rest = bytes;
    let mut next_line = || -> Option<&str> {
        let end = rest.iter().position(|&b| b == b'\n')?;
        let line = std::str::from_utf8(&rest[..end]).ok();
        rest = &rest[end + 1..];
        Some(line.unwrap_or("\u{fffd}").trim_end_matches('\r'))
    };
    if next_line().map(str::trim) != Some("ply") {
        return Err(PlyReadError::NotPly);
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut line_no = 1;
    loop {
        line_no += 1;
        let header = |reason: &str| PlyReadError::Header {
            line: line_no,
            reason: reason.to_string(),
        };
        let line = next_line().ok_or_else(|| header("the header has no end_header"))?;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] => {}
            ["comment" | "obj_info", ..] => {}
            ["format", kind, _version] => {
                format = Some(match *kind {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLittle,
                    "binary_big_endian" => Format::BinaryBig,
                    _ => return Err(header(&format!("unknown format {kind}"))),
                });
            }
            ["element", name, count] => {
                let count = count
                    .parse::<usize>()
                    .map_err(|_| header(&format!("element count {count} is not a number")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count, item, _name] => {
                let (Some(count), Some(item)) = (Scalar::parse(count), Scalar::parse(item)) else {
                    return Err(header("unknown list property type"));
                };
                let element = elements
                    .last_mut()
                    .ok_or_else(|| header("property before any element"))?;
                element.properties.push(Property::List { count, item });
            }
            ["property", kind, name] => {
                let kind = Scalar::parse(kind)
                    .ok_or_else(|| header(&format!("unknown property type {kind}")))?;
                let element = elements
                    .last_mut()
                    .ok_or_else(|| header("property before any element"))?;
                element.properties.push(Property::Scalar {
                    name: name.to_string(),
                    kind,
                });
            }
            ["end_header"] => break,
            _ => return Err(header(&format!("cannot read `{line}`"))),
        }
    }
    let format = format.ok_or(PlyReadError::Header {
        line: line_no,
        reason: "no format line".into(),
    })?;
    Ok((format, elements, rest))
}

fn slots(vertex: &Element) -> Result<Slots, PlyReadError> {
    let index = |name: &str| {
        vertex
            .properties
            .iter()
            .position(|p| matches!(p, Property::Scalar { name: n, .. } if n == name))
    };
    let xyz = ["x", "y", "z"].map(index);
    let [Some(x), Some(y), Some(z)] = xyz else {
        let missing = ["x", "y", "z"]
            .into_iter()
            .zip(xyz)
            .find(|(_, i)| i.is_none())
            .map_or("x", |(n, _)| n);
        return Err(PlyReadError::MissingCoordinate(missing));
    };
    let triple = |names: [&str; 3]| match names.map(index) {
        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
        _ => None,
    };
    Ok(Slots {
        xyz: [x, y, z],
        normal: triple(["nx", "ny", "nz"]),
        colour: triple(["red", "green", "blue"]),
        quality: index("quality"),
    })
}

/// The vertex element's records: one value per property (lists count as
/// one NaN, never used).
fn ascii_records(
    body: &[u8],
    elements: &[Element],
    vertex_at: usize,
) -> Result<Vec<Vec<f64>>, PlyReadError> {
    let text = String::from_utf8_lossy(body);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let mut records = Vec::new();
    for (e, element) in elements.iter().enumerate().take(vertex_at + 1) {
        if e == vertex_at {
            // The body's own lines bound the allocation, not the header's count.
            records.reserve(element.count.min(text.len() / 2 + 1));
        }
        for index in 0..element.count {
            let truncated = || PlyReadError::Truncated {
                element: element.name.clone(),
                index,
                count: element.count,
            };
            let (line_no, line) = lines.next().ok_or_else(truncated)?;
            let mut words = line.split_whitespace();
            let mut values = Vec::with_capacity(element.properties.len());
            for p in &element.properties {
                let mut word = || words.next().ok_or_else(truncated);
                let value = |w: &str| {
                    w.parse::<f64>().map_err(|_| PlyReadError::Value {
                        line: line_no + 1,
                        reason: format!("`{w}` is not a number"),
                    })
                };
                match p {
                    Property::Scalar { .. } => values.push(value(word()?)?),
                    Property::List { .. } => {
                        let n = value(word()?)?;
                        if !(n >= 0.0 && n.fract() == 0.0 && n <= 1e6) {
                            return Err(PlyReadError::Value {
                                line: line_no + 1,
                                reason: format!("list length {n}"),
                            });
                        }
                        for _ in 0..n as usize {
                            value(word()?)?;
                        }
                        values.push(f64::NAN);
                    }
                }
            }
            if e == vertex_at {
                records.push(values);
            }
        }
    }
    Ok(records)
}

fn binary_records(
    body: &[u8],
    elements: &[Element],
    vertex_at: usize,
    big_endian: bool,
) -> Result<Vec<Vec<f64>>, PlyReadError> {
    let mut at = 0usize;
    let read = |at: &mut usize, kind: Scalar| -> Option<f64> {
        let bytes = body.get(*at..*at + kind.size())?;
        *at += kind.size();
        let mut b = [0u8; 8];
        b[..bytes.len()].copy_from_slice(bytes);
        if big_endian {
            b[..bytes.len()].reverse();
        }
        Some(match kind {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b),
        })
    };
    let mut records = Vec::new();
    for (e, element) in elements.iter().enumerate().take(vertex_at + 1) {
        if e == vertex_at {
            let min_record: usize = element
                .properties
                .iter()
                .map(|p| match p {
                    Property::Scalar { kind, .. } => kind.size(),
                    Property::List { count, .. } => count.size(),
                })
                .sum();
            // The bytes left bound the allocation, not the header's count.
            records.reserve(element.count.min(body.len() / min_record.max(1) + 1));
        }
        for index in 0..element.count {
            let truncated = || PlyReadError::Truncated {
                element: element.name.clone(),
                index,
                count: element.count,
            };
            let mut values = Vec::with_capacity(element.properties.len());
            for p in &element.properties {
                match *p {
                    Property::Scalar { kind, .. } => {
                        values.push(read(&mut at, kind).ok_or_else(truncated)?)
                    }
                    Property::List { count, item } => {
                        let n = read(&mut at, count).ok_or_else(truncated)?;
                        if n.is_nan() || n < 0.0 {
                            return Err(truncated());
                        }
                        let skip = (n as usize)
                            .checked_mul(item.size())
                            .ok_or_else(truncated)?;
                        at = at
                            .checked_add(skip)
                            .filter(|&end| end <= body.len())
                            .ok_or_else(truncated)?;
                        values.push(f64::NAN);
                    }
                }
            }
            if e == vertex_at {
                records.push(values);
            }
        }
    }
    Ok(records)
}

fn to_cloud(records: &[Vec<f64>], slots: &Slots, unit_m: f64) -> Result<PlyCloud, PlyReadError> {
    let v3 = |r: &[f64], s: [usize; 3]| Vector3::new(r[s[0]], r[s[1]], r[s[2]]);
    let mut points = Vec::with_capacity(records.len());
    for (index, r) in records.iter().enumerate() {
        let p = v3(r, slots.xyz) * unit_m;
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(PlyReadError::NonFinite { index });
        }
        points.push(p);
    }
    // A zero or non-finite normal is no direction: drop the normals then.
    let normals = slots.normal.and_then(|s| {
        records
            .iter()
            .map(|r| {
                let n = v3(r, s);
                let norm = n.norm();
                (norm.is_finite() && norm > 0.0).then(|| n / norm)
            })
            .collect::<Option<Vec<_>>>()
    });
    let colours = slots.colour.map(|s| {
        records
            .iter()
            .map(|r| s.map(|i| r[i].clamp(0.0, 255.0) as u8))
            .collect()
    });
    let quality = slots
        .quality
        .map(|q| {
            records
                .iter()
                .map(|r| (r[q] * unit_m) as f32)
                .collect::<Vec<_>>()
        })
        .filter(|q| q.iter().all(|v| v.is_finite()));
    Ok(PlyCloud {
        cloud: PointCloud {
            points,
            normals,
            quality,
        },
        colours,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "ply\nformat ascii 1.0\ncomment by hand\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float curvature\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n1 2 3 255 0 0 0.5\n4 5 6 0 255 0 0.5\n7 8 9.25 0 0 255 0.5\n3 0 1 2\n";

    #[test]
    fn ascii_with_colours_extra_properties_and_faces() {
        let c = parse_ply(ASCII.as_bytes(), 1e-3).unwrap();
        assert_eq!(c.cloud.points.len(), 3);
        assert!((c.cloud.points[2] - Vector3::new(7e-3, 8e-3, 9.25e-3)).norm() < 1e-15);
        assert_eq!(c.colours.unwrap()[1], [0, 255, 0]);
        assert!(c.cloud.normals.is_none() && c.cloud.quality.is_none());
    }

    fn binary(big: bool, faces_first: bool) -> Vec<u8> {
        let fmt = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let face = "element face 1\nproperty list uchar int vertex_indices\n";
        let vertex = "element vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty short extra\n";
        let (first, second) = if faces_first {
            (face, vertex)
        } else {
            (vertex, face)
        };
        let mut out = format!("ply\nformat {fmt} 1.0\n{first}{second}end_header\n").into_bytes();
        let face_body = |out: &mut Vec<u8>| {
            out.push(3);
            for i in [0i32, 1, 0] {
                out.extend(if big {
                    i.to_be_bytes()
                } else {
                    i.to_le_bytes()
                });
            }
        };
        if faces_first {
            face_body(&mut out);
        }
        for v in [[0.1f64, 0.2, 0.3], [-0.4, 0.5, 0.123456789012]] {
            for x in v {
                out.extend(if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                });
            }
            for n in [0.0f32, 0.0, 2.0] {
                out.extend(if big {
                    n.to_be_bytes()
                } else {
                    n.to_le_bytes()
                });
            }
            out.extend(if big {
                7i16.to_be_bytes()
            } else {
                7i16.to_le_bytes()
            });
        }
        if !faces_first {
            face_body(&mut out);
        }
        out
    }

    #[test]
    fn binary_doubles_both_endians_with_faces_before_or_after() {
        for (big, faces_first) in [(false, false), (true, false), (false, true), (true, true)] {
            let c = parse_ply(&binary(big, faces_first), 1.0).unwrap();
            assert_eq!(c.cloud.points[1], Vector3::new(-0.4, 0.5, 0.123456789012));
            // Normals come back unit length.
            assert_eq!(c.cloud.normals.as_ref().unwrap()[0], Vector3::z());
        }
    }

    #[test]
    fn our_own_writer_reads_back() {
        let cloud = crate::point_cloud::PointCloud {
            points_m: vec![[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]],
            normals: Some(vec![[0.0, 0.0, 1.0]; 2]),
            colours: Some(vec![[9, 8, 7]; 2]),
            quality_m: Some(vec![1e-4, 2e-4]),
        };
        let path = std::env::temp_dir().join(format!("slscan-ply-read-{}.ply", std::process::id()));
        crate::io::ply::write_ply(&path, &cloud).unwrap();
        let back = read_ply(&path, 1.0).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(
            back.cloud.points[1],
            Vector3::new(0.4f32 as f64, 0.5f32 as f64, 0.6f32 as f64)
        );
        assert_eq!(back.colours.unwrap()[0], [9, 8, 7]);
        assert_eq!(back.cloud.quality.unwrap()[1], 2e-4f32);
    }

    #[test]
    fn bad_files_are_named_errors() {
        let cases: [(&[u8], &str); 7] = [
            (b"hello\n", "not a PLY"),
            (b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n", "no vertices"),
            (b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n", "no vertices"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n", "no `z`"),
            (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n", "ends early"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 nan 3\n", "non-finite"),
            (b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x00\x00", "ends early"),
        ];
        for (bytes, want) in cases {
            let err = parse_ply(bytes, 1.0).unwrap_err().to_string();
            assert!(err.contains(want), "{err} lacks {want}");
        }
        let mut cut = binary(false, false);
        cut.truncate(cut.len() - 20);
        assert!(matches!(
            parse_ply(&cut, 1.0),
            Err(PlyReadError::Truncated { .. })
        ));
        assert!(matches!(
            parse_ply(ASCII.as_bytes(), 0.0),
            Err(PlyReadError::BadUnit(_))
        ));
    }
}
