//! Any bytes as a 2-D `.npy` file (frames of `reconstruct`, phase maps of
//! `calibrate`), or (first byte 0..=3) the rest behind a valid header of
//! each element type, so the fuzzer reaches the data: no panic, and an
//! array that comes back holds exactly height x width values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slscan::io::npy::decode_npy_2d;

/// A version-1 header for `descr` and a 4 x 3 shape, padded to 64 bytes.
fn header(descr: &str) -> Vec<u8> {
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': (4, 3), }}");
    let pad = (64 - (10 + dict.len() + 1) % 64) % 64;
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&((dict.len() + pad + 1) as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    out.push(b'\n');
    out
}

fuzz_target!(|data: &[u8]| {
    let bytes = match data.split_first() {
        Some((&k, rest)) if k < 4 => {
            let descr = ["|u1", "<u2", "<f4", "<f8"][usize::from(k)];
            [header(descr).as_slice(), rest].concat()
        }
        _ => data.to_vec(),
    };
    if let Ok(a) = decode_npy_2d(&bytes) {
        assert_eq!(a.values.data.len(), a.values.width * a.values.height);
    }
});
