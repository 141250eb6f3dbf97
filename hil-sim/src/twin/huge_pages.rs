//! Fresh per-pose maps on transparent huge pages.
//!
//! A 1 MP pose writes ~80 MB of fresh maps: on 4 KiB pages ~20,000 page faults
//! per pose, a seventh of the set-up's CPU time in a profile. Advised for huge
//! pages before their first write, they fault in 2 MiB at a time. The host
//! library does the same for its scan buffers (`slscan::huge_pages`); the twin
//! keeps these few lines of its own rather than depend on the host.

/// `v`, its allocation advised for huge pages. A zeroed vector (`vec![0; n]`)
/// from fresh memory is not touched until written, so its first writers (the
/// parallel row fill) fault its pages in 2 MiB at a time; memory the allocator
/// reused is already mapped, and advising it changes nothing.
pub(crate) fn advised<T>(v: Vec<T>) -> Vec<T> {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let bytes = std::mem::size_of_val(v.as_slice());
        let start = v.as_ptr() as usize;
        let first = start.next_multiple_of(HUGE);
        let end = (start + bytes) / HUGE * HUGE;
        if end > first {
            // SAFETY: [first, end) lies inside the vector's own allocation, and
            // MADV_HUGEPAGE only changes how the kernel backs the pages, never
            // their contents. A failure (THP unsupported) is harmless: ignored.
            unsafe { libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE) };
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advised_vectors_keep_their_contents() {
        for n in [0usize, 5, 3 << 20] {
            let v = advised(vec![[1.5f32, 0.0, -2.0]; n]);
            assert_eq!(v.len(), n);
            assert!(v.iter().all(|x| *x == [1.5, 0.0, -2.0]));
        }
    }
}
