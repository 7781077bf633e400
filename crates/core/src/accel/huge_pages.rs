//! Large arrays backed by 2 MiB pages where the system offers them (Linux transparent huge
//! pages in `madvise` mode, as on Debian): a million-triangle tree spans tens of megabytes,
//! and with 4 KiB pages most node and leaf visits of a ray would also miss the address
//! translation caches. Fewer, larger pages also make the first touch of the memory (page
//! faults while building) much cheaper. Elsewhere these are ordinary vectors.

/// An empty vector with room for `capacity` elements, its memory advised for huge pages.
pub fn vec_with_capacity<T>(capacity: usize) -> Vec<T> {
    let mut v: Vec<T> = Vec::with_capacity(capacity);
    advise(v.as_mut_ptr().cast(), capacity * size_of::<T>());
    v
}

/// Asks that the whole 2 MiB pages inside `len` bytes at `ptr` be huge pages. Only a hint:
/// nothing happens below 4 MiB, where it would not pay, or where it is refused.
fn advise(ptr: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        if len < 2 * HUGE {
            return;
        }
        let start = (ptr as usize).next_multiple_of(HUGE);
        let end = (ptr as usize + len) / HUGE * HUGE;
        if end > start {
            // SAFETY: the range lies inside the allocation; MADV_HUGEPAGE changes no contents.
            unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, len);
}

#[cfg(test)]
mod tests {
    #[test]
    fn advised_vectors_are_ordinary_vectors() {
        let mut v = super::vec_with_capacity::<[f32; 8]>(1 << 20);
        assert!(v.capacity() >= 1 << 20 && v.is_empty());
        v.extend((0..1 << 20).map(|i| [i as f32; 8]));
        assert_eq!(v[123_456], [123_456.0; 8]);
        assert!(super::vec_with_capacity::<u8>(0).is_empty());
    }
}
