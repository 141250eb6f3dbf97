//! Binary little-endian PLY: x y z (f32, metres), then optional nx ny nz, red green blue
//! (uchar) and quality (f32, predicted standard deviation in metres).

use std::io::Write;
use std::path::Path;

use crate::point_cloud::PointCloud;

/// What can be wrong when writing a PLY.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// An attribute has another length than the points.
    #[error("{attribute} has {got} entries for {points} points")]
    LengthMismatch {
        /// Which attribute.
        attribute: &'static str,
        /// Its length.
        got: usize,
        /// Number of points.
        points: usize,
    },
    /// The file could not be written.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Writes a cloud as binary little-endian PLY (temp file, then rename).
pub fn write_ply(path: &Path, cloud: &PointCloud) -> Result<(), PlyError> {
    let n = cloud.points_m.len();
    let check = |attribute, got: Option<usize>| match got {
        Some(got) if got != n => Err(PlyError::LengthMismatch {
            attribute,
            got,
            points: n,
        }),
        _ => Ok(()),
    };
    check("normals", cloud.normals.as_ref().map(Vec::len))?;
    check("colours", cloud.colours.as_ref().map(Vec::len))?;
    check("quality", cloud.quality_m.as_ref().map(Vec::len))?;
    super::write_atomically(path, |w| write_body(w, cloud)).map_err(|source| PlyError::Io {
        path: path.to_owned(),
        source,
    })
}

fn write_body(w: &mut dyn Write, cloud: &PointCloud) -> std::io::Result<()> {
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment slscan point cloud, metres\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        cloud.points_m.len()
    );
    if cloud.normals.is_some() {
        header += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if cloud.colours.is_some() {
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if cloud.quality_m.is_some() {
        header += "property float quality\n";
    }
    header += "end_header\n";
    w.write_all(header.as_bytes())?;
    let mut rec = Vec::with_capacity(31);
    for i in 0..cloud.points_m.len() {
        rec.clear();
        for c in cloud.points_m[i] {
            rec.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(n) = &cloud.normals {
            for c in n[i] {
                rec.extend_from_slice(&c.to_le_bytes());
            }
        }
        if let Some(c) = &cloud.colours {
            rec.extend_from_slice(&c[i]);
        }
        if let Some(q) = &cloud.quality_m {
            rec.extend_from_slice(&q[i].to_le_bytes());
        }
        w.write_all(&rec)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_and_record_layout() {
        let cloud = PointCloud {
            points_m: vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
            normals: Some(vec![[0.0, 0.0, 1.0]; 2]),
            colours: Some(vec![[10, 20, 30]; 2]),
            quality_m: Some(vec![1e-5, 2e-5]),
        };
        let dir = std::env::temp_dir().join(format!("slscan-ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("c.ply");
        write_ply(&path, &cloud).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let end = b"end_header\n";
        let pos = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
        let header = std::str::from_utf8(&bytes[..pos]).unwrap();
        assert!(header.contains("element vertex 2") && header.contains("property float quality"));
        let body = &bytes[pos..];
        assert_eq!(body.len(), 2 * (12 + 12 + 3 + 4));
        assert_eq!(f32::from_le_bytes(body[31..35].try_into().unwrap()), 4.0);
        assert_eq!(&body[24..27], &[10, 20, 30]);
        let bad = PointCloud {
            quality_m: Some(vec![0.0]),
            ..cloud
        };
        assert!(matches!(
            write_ply(&dir.join("bad.ply"), &bad),
            Err(PlyError::LengthMismatch { .. })
        ));
        assert!(!dir.join("bad.ply").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
