//! Any bytes as a PLY file, or (first byte 0, 2 or 4) the rest behind a
//! valid ASCII or binary header, so the fuzzer reaches the bodies: no
//! panic, and a cloud that comes back has only finite points and unit
//! normals, one per point.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slscan::io::ply_read::parse_ply;

const HEADERS: [&[u8]; 3] = [
    b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
    b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n",
    b"ply\nformat binary_big_endian 1.0\nelement face 1\nproperty list uchar int vertex_indices\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float quality\nend_header\n",
];

fuzz_target!(|data: &[u8]| {
    let bytes = match data.split_first() {
        Some((&k, rest)) if usize::from(k) < 2 * HEADERS.len() && k % 2 == 0 => {
            [HEADERS[usize::from(k) / 2], rest].concat()
        }
        _ => data.to_vec(),
    };
    if let Ok(c) = parse_ply(&bytes, 1e-3) {
        let n = c.cloud.points.len();
        assert!(n > 0);
        assert!(c.cloud.points.iter().all(|p| p.iter().all(|v| v.is_finite())));
        if let Some(normals) = &c.cloud.normals {
            assert_eq!(normals.len(), n);
            assert!(normals.iter().all(|v| (v.norm() - 1.0).abs() < 1e-9));
        }
        if let Some(colours) = &c.colours {
            assert_eq!(colours.len(), n);
        }
    }
});
