//! The structures' large arrays asked for on large pages: the nodes and leaf rows a query
//! reaches at random are requested on 2 MiB pages (Linux's transparent huge pages,
//! `madvise(MADV_HUGEPAGE)` before the first write), as Embree's allocator requests them for
//! its structures. A walk through a scene of tens of megabytes touches a few lines in each of
//! many 4 KiB pages, more than the TLB holds; 2 MiB pages cover it with a few dozen entries.
//!
//! A request, not a guarantee: the kernel backs with large pages only the whole, aligned
//! 2 MiB spans of memory not yet written (an allocation the allocator takes fresh from the
//! system, as it does for large arrays; memory it reuses keeps its small pages until the
//! kernel merges them). Elsewhere than Linux, and for arrays under 2 MiB, plain vectors.

/// The size of a large page.
const LARGE: usize = 2 << 20;

/// An empty vector with room for `capacity` elements, its room asked for on large pages when
/// it spans 2 MiB (see the module documentation). Fill it by `push`, `extend` or `resize`
/// without passing `capacity`: a reallocation loses the request.
pub fn with_capacity<T>(capacity: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(capacity);
    advise(v.spare_capacity_mut());
    v
}

/// `len` copies of `value` ([`with_capacity`] filled).
pub fn filled<T: Clone>(len: usize, value: T) -> Vec<T> {
    let mut v = with_capacity(len);
    v.resize(len, value);
    v
}

/// `v` moved onto large pages: copied once into a vector from [`with_capacity`] when it spans
/// a large page, else returned as it is.
pub fn moved<T: Clone>(v: Vec<T>) -> Vec<T> {
    if std::mem::size_of_val(v.as_slice()) < LARGE {
        return v;
    }
    let mut out = with_capacity(v.len());
    out.extend_from_slice(&v);
    out
}

/// Asks Linux to back the whole 4 KiB pages of `room` (not yet written) with large pages.
#[cfg(target_os = "linux")]
fn advise<T>(room: &mut [std::mem::MaybeUninit<T>]) {
    const PAGE: usize = 4096;
    let bytes = std::mem::size_of_val(room);
    if bytes < LARGE {
        return;
    }
    let start = room.as_mut_ptr() as usize;
    let first = start.next_multiple_of(PAGE);
    let end = (start + bytes) / PAGE * PAGE;
    if end > first {
        // SAFETY: `first..end` lies inside `room`, memory this vector owns and has not
        // written; `MADV_HUGEPAGE` is a hint that changes no byte of it (the kernel may back
        // it with large pages or not). A failure (a kernel without transparent huge pages)
        // leaves the memory as it was, so the result is not needed.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise<T>(_room: &mut [std::mem::MaybeUninit<T>]) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_hold_what_plain_ones_do() {
        for len in [0, 1, 1000, (3 << 20) / 4 + 5] {
            let v = filled(len, 7u32);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|&x| x == 7));
            let plain: Vec<u64> = (0..len as u64).collect();
            assert_eq!(moved(plain.clone()), plain);
        }
    }
}
