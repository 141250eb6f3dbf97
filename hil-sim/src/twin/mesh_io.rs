//! Triangle meshes from PLY (ASCII or binary), OBJ and STL (ASCII or
//! binary) files. Small hand-written readers: we need only positions and
//! faces, typed errors that name the file, and no extra dependency.

use std::path::Path;

use super::error::TwinError;
use super::mesh::Mesh;

/// Loads a mesh by file extension (`.ply`, `.obj`, `.stl`), multiplying
/// coordinates by `scale_to_m` (0.001 for files in millimetres).
pub fn load_mesh(path: &Path, scale_to_m: f64) -> Result<Mesh, TwinError> {
    let bytes = std::fs::read(path).map_err(TwinError::io(path))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let (mut v, t) = match ext.as_str() {
        "ply" => parse_ply(&bytes),
        "obj" => parse_obj(&bytes),
        "stl" => parse_stl(&bytes),
        _ => Err(format!(
            "unknown mesh extension `{ext}` (want ply, obj or stl)"
        )),
    }
    .map_err(|why| TwinError::MeshParse {
        path: path.to_path_buf(),
        why,
    })?;
    v.iter_mut()
        .flatten()
        .for_each(|c| *c = (*c as f64 * scale_to_m) as f32);
    Mesh::new(&v, &t)
}

type Parsed = Result<(Vec<[f32; 3]>, Vec<[u32; 3]>), String>;

/// Fan-triangulates a polygon.
fn fan(poly: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 1..poly.len().saturating_sub(1) {
        out.push([poly[0], poly[k], poly[k + 1]]);
    }
}

/// Parses Wavefront OBJ: `v x y z` and `f a b c ...` (a, a/b, a/b/c, a//c; negative = relative).
pub fn parse_obj(bytes: &[u8]) -> Parsed {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8: {e}"))?;
    let (mut v, mut t) = (Vec::new(), Vec::new());
    for (ln, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f32> = it
                    .take(3)
                    .map(|s| s.parse::<f32>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| format!("line {}: {e}", ln + 1))?;
                if c.len() != 3 {
                    return Err(format!("line {}: vertex needs 3 coordinates", ln + 1));
                }
                v.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                let mut poly = Vec::new();
                for tok in it {
                    let first = tok.split('/').next().unwrap_or("");
                    let i: i64 = first
                        .parse()
                        .map_err(|e| format!("line {}: face index `{tok}`: {e}", ln + 1))?;
                    let idx = if i < 0 { v.len() as i64 + i } else { i - 1 };
                    if idx < 0 {
                        return Err(format!(
                            "line {}: face index {i} before the first vertex",
                            ln + 1
                        ));
                    }
                    poly.push(idx as u32);
                }
                fan(&poly, &mut t);
            }
            _ => {}
        }
    }
    Ok((v, t))
}

/// Parses STL, binary (80-byte header, count, 50 bytes per triangle) or ASCII.
pub fn parse_stl(bytes: &[u8]) -> Parsed {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        if bytes.len() == 84 + 50 * n {
            let (mut v, mut t) = (Vec::with_capacity(3 * n), Vec::with_capacity(n));
            for k in 0..n {
                let rec = &bytes[84 + 50 * k..84 + 50 * (k + 1)];
                for c in 0..3 {
                    let at = 12 + 12 * c;
                    let f = |o: usize| {
                        f32::from_le_bytes(rec[at + o..at + o + 4].try_into().expect("4 bytes"))
                    };
                    v.push([f(0), f(4), f(8)]);
                }
                let b = 3 * k as u32;
                t.push([b, b + 1, b + 2]);
            }
            return Ok((v, t));
        }
    }
    let text = std::str::from_utf8(bytes)
        .map_err(|_| "neither binary STL (size mismatch) nor ASCII STL".to_string())?;
    let mut v = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        if it.next() == Some("vertex") {
            let c: Vec<f32> = it
                .take(3)
                .map(|s| s.parse::<f32>())
                .collect::<Result<_, _>>()
                .map_err(|e| format!("line {}: {e}", ln + 1))?;
            if c.len() != 3 {
                return Err(format!("line {}: vertex needs 3 coordinates", ln + 1));
            }
            v.push([c[0], c[1], c[2]]);
        }
    }
    if v.len() % 3 != 0 {
        return Err(format!(
            "{} vertices is not a whole number of triangles",
            v.len()
        ));
    }
    let t = (0..v.len() as u32 / 3)
        .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
        .collect();
    Ok((v, t))
}

#[derive(Clone, Copy, PartialEq)]
enum PlyFormat {
    Ascii,
    Little,
    Big,
}

#[derive(Clone)]
struct PlyProp {
    name: String,
    ty: String,
    /// Count type of a list property.
    list: Option<String>,
}

struct PlyElement {
    name: String,
    count: usize,
    props: Vec<PlyProp>,
}

fn type_size(ty: &str) -> Result<usize, String> {
    Ok(match ty {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return Err(format!("unknown PLY type `{ty}`")),
    })
}

/// Reads one binary scalar as f64.
fn read_bin(b: &[u8], pos: &mut usize, ty: &str, fmt: PlyFormat) -> Result<f64, String> {
    let n = type_size(ty)?;
    let s = b
        .get(*pos..*pos + n)
        .ok_or_else(|| format!("file ends at byte {} inside a {ty}", *pos))?;
    *pos += n;
    let mut a = [0u8; 8];
    a[..n].copy_from_slice(s);
    if fmt == PlyFormat::Big {
        a[..n].reverse();
    }
    Ok(match ty {
        "char" | "int8" => a[0] as i8 as f64,
        "uchar" | "uint8" => a[0] as f64,
        "short" | "int16" => i16::from_le_bytes([a[0], a[1]]) as f64,
        "ushort" | "uint16" => u16::from_le_bytes([a[0], a[1]]) as f64,
        "int" | "int32" => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        "uint" | "uint32" => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        "float" | "float32" => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        _ => f64::from_le_bytes(a),
    })
}

/// Parses PLY (ascii, binary_little_endian, binary_big_endian): vertex x y z
/// and face vertex_indices / vertex_index lists; other elements are skipped.
pub fn parse_ply(bytes: &[u8]) -> Parsed {
    let end = bytes
        .windows(10)
        .position(|w| w == b"end_header")
        .ok_or("no end_header")?;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| "header is not text")?;
    // The body starts after the header's line end (\n or \r\n).
    let mut body = end + 10;
    if bytes.get(body) == Some(&b'\r') {
        body += 1;
    }
    if bytes.get(body) == Some(&b'\n') {
        body += 1;
    }
    let mut fmt = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", "ascii", ..] => fmt = Some(PlyFormat::Ascii),
            ["format", "binary_little_endian", ..] => fmt = Some(PlyFormat::Little),
            ["format", "binary_big_endian", ..] => fmt = Some(PlyFormat::Big),
            ["element", name, count] => elements.push(PlyElement {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| format!("bad count in `{line}`"))?,
                props: vec![],
            }),
            ["property", "list", ct, ty, name] => elements
                .last_mut()
                .ok_or("property before element")?
                .props
                .push(PlyProp {
                    name: name.to_string(),
                    ty: ty.to_string(),
                    list: Some(ct.to_string()),
                }),
            ["property", ty, name] => elements
                .last_mut()
                .ok_or("property before element")?
                .props
                .push(PlyProp {
                    name: name.to_string(),
                    ty: ty.to_string(),
                    list: None,
                }),
            _ => {}
        }
    }
    let fmt = fmt.ok_or("no format line")?;
    let text: Vec<&str> = if fmt == PlyFormat::Ascii {
        std::str::from_utf8(&bytes[body..])
            .map_err(|_| "ASCII body is not text")?
            .split_whitespace()
            .collect()
    } else {
        Vec::new()
    };
    let mut tok = 0usize;
    let mut pos = body;
    let mut next = |ty: &str| -> Result<f64, String> {
        if fmt == PlyFormat::Ascii {
            let s = text.get(tok).ok_or("ASCII body ends early")?;
            tok += 1;
            s.parse::<f64>().map_err(|e| format!("value `{s}`: {e}"))
        } else {
            read_bin(bytes, &mut pos, ty, fmt)
        }
    };
    let (mut v, mut t) = (Vec::new(), Vec::new());
    for el in &elements {
        let xyz: Vec<Option<usize>> = ["x", "y", "z"]
            .iter()
            .map(|n| el.props.iter().position(|p| p.name == *n))
            .collect();
        for _ in 0..el.count {
            let mut vals = [0.0f64; 3];
            let mut poly = Vec::new();
            for (pi, p) in el.props.iter().enumerate() {
                match &p.list {
                    Some(ct) => {
                        let n = next(ct)? as usize;
                        for _ in 0..n {
                            let i = next(&p.ty)?;
                            if el.name == "face"
                                && (p.name == "vertex_indices" || p.name == "vertex_index")
                            {
                                poly.push(i as u32);
                            }
                        }
                    }
                    None => {
                        let x = next(&p.ty)?;
                        if let Some(axis) = xyz.iter().position(|a| *a == Some(pi)) {
                            vals[axis] = x;
                        }
                    }
                }
            }
            if el.name == "vertex" {
                v.push(vals.map(|c| c as f32));
            } else if el.name == "face" {
                fan(&poly, &mut t);
            }
        }
    }
    Ok((v, t))
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD_OBJ: &str = "# unit quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2/2 3/3 4/4\n";

    #[test]
    fn obj_quad_is_two_triangles() {
        let (v, t) = parse_obj(QUAD_OBJ.as_bytes()).unwrap();
        assert_eq!(v.len(), 4);
        assert_eq!(t, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(parse_obj(b"v 0 0\n").is_err());
    }

    #[test]
    fn ply_ascii_and_binary_agree() {
        let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 255\n1 0 0 0\n0 1 0 9\n3 0 1 2\n";
        let (va, ta) = parse_ply(ascii.as_bytes()).unwrap();
        let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
        for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            p.iter()
                .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
            bin.push(7);
        }
        bin.push(3);
        [0i32, 1, 2]
            .iter()
            .for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
        let (vb, tb) = parse_ply(&bin).unwrap();
        assert_eq!((va, ta), (vb, tb));
        assert!(parse_ply(&bin[..bin.len() - 2]).is_err());
    }

    #[test]
    fn stl_binary_and_ascii() {
        let mut bin = vec![0u8; 80];
        bin.extend_from_slice(&1u32.to_le_bytes());
        bin.extend_from_slice(&[0u8; 12]);
        for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            p.iter()
                .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
        }
        bin.extend_from_slice(&[0u8; 2]);
        let (v, t) = parse_stl(&bin).unwrap();
        assert_eq!((v.len(), t.len()), (3, 1));
        let ascii = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n";
        assert_eq!(parse_stl(ascii.as_bytes()).unwrap(), (v, t));
    }

    #[test]
    fn load_scales_and_reports_bad_files() {
        let dir = std::env::temp_dir().join(format!("twin-meshio-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("q.obj");
        std::fs::write(&p, QUAD_OBJ).unwrap();
        let m = load_mesh(&p, 0.001).unwrap();
        assert_eq!(m.triangle_count(), 2);
        let bad = dir.join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nf 1 2 x\n").unwrap();
        assert!(matches!(
            load_mesh(&bad, 1.0),
            Err(TwinError::MeshParse { .. })
        ));
        assert!(matches!(
            load_mesh(&dir.join("none.stl"), 1.0),
            Err(TwinError::Io { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
