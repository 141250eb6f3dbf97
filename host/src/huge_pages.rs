//! Large per-scan buffers on transparent huge pages, filled in parallel.
//!
//! At 6 MP the organised result and the cloud are ~390 MB of fresh memory per scan;
//! backed by 4 KiB pages that is ~100 000 page faults, which cost about as much CPU as
//! the whole decode. Advising huge pages before the first touch makes it ~200 faults.
//! Advisory only: where transparent huge pages are off (or not on Linux) nothing
//! changes but the speed.

/// `len` copies of `value` in a fresh vector whose memory is advised for huge pages
/// before it is first written, and written by all rayon threads: the kernel's clearing
/// of the fresh pages (most of the cost) then runs in parallel, not in the caller alone.
pub fn filled_vec<T: Clone + Send + Sync>(len: usize, value: T) -> Vec<T> {
    use rayon::prelude::*;
    let mut v = Vec::with_capacity(len);
    advise_allocation(v.spare_capacity_mut());
    v.par_extend(rayon::iter::repeat_n(value, len));
    v
}

/// Resizes `v` to `len` elements: in place when its allocation is large enough, else a
/// fresh one on huge pages, filled in parallel (see [`filled_vec`]).
pub(crate) fn sized<T: Clone + Send + Sync>(v: &mut Vec<T>, len: usize, fill: T) {
    if v.capacity() >= len {
        v.resize(len, fill);
    } else {
        // Free the old allocation first: a scan's buffers are hundreds of MB.
        *v = Vec::new();
        *v = filled_vec(len, fill);
    }
}

/// Advises the kernel to back `v`'s allocation with huge pages (whole 2 MiB pages inside
/// it only; small vectors are left alone). Pages already touched keep their backing.
fn advise_allocation<T>(v: &[T]) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let bytes = std::mem::size_of_val(v);
        let start = v.as_ptr() as usize;
        let first = start.next_multiple_of(HUGE);
        let end = (start + bytes) / HUGE * HUGE;
        if bytes >= 2 * HUGE && end > first {
            // SAFETY: [first, end) lies inside this slice's own allocation, and
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
