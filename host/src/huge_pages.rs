//! Large per-scan buffers on transparent huge pages.
//!
//! At 6 MP the organised result and the cloud are ~400 MB of fresh memory per scan;
//! backed by 4 KiB pages that is ~100 000 page faults, which cost about as much CPU as
//! the whole decode. Advising huge pages before the first touch makes it ~200 faults.
//! Advisory only: where transparent huge pages are off (or not on Linux) nothing
//! changes but the speed.

/// `len` copies of `value` in a fresh vector whose memory is advised for huge pages
/// before it is first written.
pub fn filled_vec<T: Clone>(len: usize, value: T) -> Vec<T> {
    let mut v = Vec::with_capacity(len);
    advise_spare_capacity(&mut v);
    v.resize(len, value);
    v
}

/// Advises the kernel to back `v`'s unused capacity with huge pages (whole 2 MiB pages
/// inside it only; small vectors are left alone).
fn advise_spare_capacity<T>(v: &mut Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let spare = v.spare_capacity_mut();
        let bytes = std::mem::size_of_val(spare);
        let start = spare.as_mut_ptr() as usize;
        let first = start.next_multiple_of(HUGE);
        let end = (start + bytes) / HUGE * HUGE;
        if bytes >= 2 * HUGE && end > first {
            // SAFETY: [first, end) lies inside this vector's own allocation, and
            // MADV_HUGEPAGE only changes how the kernel backs the pages, never their
            // contents or validity. A failure (THP unsupported) is harmless: ignored.
            unsafe { libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filled_vec_is_filled() {
        for len in [0usize, 3, 5 << 20] {
            let v = filled_vec(len, 7u16);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|&x| x == 7));
        }
    }
}
