//! [`Pages`]: the structures' large arrays on large pages. The nodes and leaf rows a query
//! reaches at random are mapped fresh from the system and asked for on 2 MiB pages (Linux's
//! transparent huge pages, `madvise(MADV_HUGEPAGE)` before the first write), as Embree's
//! allocator maps its structures. A walk through a scene of tens of megabytes touches a few
//! lines in each of many 4 KiB pages, more than the TLB holds; 2 MiB pages cover it with a
//! few dozen entries.
//!
//! Fresh memory, not the allocator's: memory it hands out again keeps the small pages it was
//! first written on. The large pages are a request (the kernel grants them where it can);
//! elsewhere than Linux, for arrays under 2 MiB, or when the mapping fails, a boxed slice.

use std::ops::{Deref, DerefMut};

/// The size of a large page.
const LARGE: usize = 2 << 20;

/// A fixed-length array on large pages where they apply (see the module
/// documentation); a slice through [`Deref`].
pub struct Pages<T> {
    store: Store<T>,
}

enum Store<T> {
    Boxed(Box<[T]>),
    #[cfg(target_os = "linux")]
    Mapped(mapped::Mapping<T>),
}

impl<T: Clone> Pages<T> {
    /// A copy of `items`.
    pub fn from_slice(items: &[T]) -> Self {
        #[cfg(target_os = "linux")]
        if let Some(m) = mapped::Mapping::copy_of(items) {
            return Self {
                store: Store::Mapped(m),
            };
        }
        Self {
            store: Store::Boxed(items.into()),
        }
    }

    /// `len` copies of `value`.
    pub fn filled(len: usize, value: T) -> Self {
        #[cfg(target_os = "linux")]
        if let Some(m) = mapped::Mapping::filled(len, &value) {
            return Self {
                store: Store::Mapped(m),
            };
        }
        Self {
            store: Store::Boxed(vec![value; len].into()),
        }
    }
}

impl<T> Pages<T> {
    /// The elements as a slice (as [`Vec::as_slice`]).
    #[inline(always)]
    pub fn as_slice(&self) -> &[T] {
        self
    }
}

impl<T: Clone> From<Vec<T>> for Pages<T> {
    /// The vector's elements, moved onto large pages when they span one (else kept where
    /// they are).
    fn from(v: Vec<T>) -> Self {
        if std::mem::size_of_val(v.as_slice()) < LARGE {
            return Self {
                store: Store::Boxed(v.into()),
            };
        }
        Self::from_slice(&v)
    }
}

impl<T> Deref for Pages<T> {
    type Target = [T];
    #[inline(always)]
    fn deref(&self) -> &[T] {
        match &self.store {
            Store::Boxed(b) => b,
            #[cfg(target_os = "linux")]
            Store::Mapped(m) => m.as_slice(),
        }
    }
}

impl<T> DerefMut for Pages<T> {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [T] {
        match &mut self.store {
            Store::Boxed(b) => b,
            #[cfg(target_os = "linux")]
            Store::Mapped(m) => m.as_mut_slice(),
        }
    }
}

impl<'a, T> IntoIterator for &'a Pages<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<T: Clone> Clone for Pages<T> {
    fn clone(&self) -> Self {
        Self::from_slice(self)
    }
}

impl<T> Default for Pages<T> {
    fn default() -> Self {
        Self {
            store: Store::Boxed(Box::default()),
        }
    }
}

impl<T: std::fmt::Debug> std::fmt::Debug for Pages<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.deref().fmt(f)
    }
}

impl<T: PartialEq> PartialEq for Pages<T> {
    fn eq(&self, other: &Self) -> bool {
        self.deref() == other.deref()
    }
}

#[cfg(target_os = "linux")]
mod mapped {
    use super::LARGE;
    use std::ptr::NonNull;

    /// `len` elements at `ptr`, the start of a 2 MiB-aligned span inside an anonymous private
    /// mapping of `map_len` bytes at `base`, owned by this value.
    pub(super) struct Mapping<T> {
        base: NonNull<libc::c_void>,
        map_len: usize,
        ptr: NonNull<T>,
        len: usize,
    }

    // SAFETY: a `Mapping` owns its memory as a `Box<[T]>` would (no other value points into
    // it), so it moves to and is shared between threads as such a box does.
    unsafe impl<T: Send> Send for Mapping<T> {}
    // SAFETY: as for `Send`: `&Mapping` gives `&[T]` only.
    unsafe impl<T: Sync> Sync for Mapping<T> {}

    impl<T: Clone> Mapping<T> {
        /// A mapping of `len` elements, each written by `init(i)` once, on memory asked for
        /// on large pages; `None` when the elements span less than a large page or the system
        /// refuses the mapping.
        fn with(len: usize, mut init: impl FnMut(usize) -> T) -> Option<Self> {
            let bytes = len.checked_mul(std::mem::size_of::<T>())?;
            if bytes < LARGE || std::mem::align_of::<T>() > LARGE {
                return None;
            }
            // Whole large pages, and one more to align the start.
            let span = bytes.checked_next_multiple_of(LARGE)?;
            let map_len = span.checked_add(LARGE)?;
            // SAFETY: a new anonymous private mapping (no address asked for, no file): it
            // aliases no memory of this program.
            let base = unsafe {
                libc::mmap(
                    std::ptr::null_mut(),
                    map_len,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                )
            };
            if base == libc::MAP_FAILED {
                return None;
            }
            // Never null: the system picks the address (no `MAP_FIXED`).
            let base = NonNull::new(base)?;
            let offset = (base.as_ptr() as usize).next_multiple_of(LARGE) - base.as_ptr() as usize;
            // SAFETY: `offset < LARGE < map_len`: the address lies inside the mapping.
            let ptr = unsafe { base.byte_add(offset) }.cast::<T>();
            // Owned from here: an early end (a panic in `init`) unmaps it.
            let mut m = Self {
                base,
                map_len,
                ptr,
                len: 0,
            };
            // SAFETY: `ptr .. ptr + span` lies inside the mapping (`offset < LARGE`, `map_len =
            // span + LARGE`), which nothing has written yet; `MADV_HUGEPAGE` is a hint that
            // changes no byte (a kernel without transparent huge pages refuses it and leaves
            // the memory as it was, so the result is not needed).
            unsafe { libc::madvise(m.ptr.as_ptr().cast(), span, libc::MADV_HUGEPAGE) };
            for i in 0..len {
                // SAFETY: element `i < len` lies inside the span (`len * size_of::<T>() <=
                // span`), aligned (the span starts 2 MiB-aligned; `T`'s alignment divides
                // its size); the write initialises it before `len` counts it, so that a panic
                // in `init` drops only written elements.
                unsafe { m.ptr.as_ptr().add(i).write(init(i)) };
                m.len = i + 1;
            }
            Some(m)
        }

        pub(super) fn copy_of(items: &[T]) -> Option<Self> {
            Self::with(items.len(), |i| items[i].clone())
        }

        pub(super) fn filled(len: usize, value: &T) -> Option<Self> {
            Self::with(len, |_| value.clone())
        }
    }

    impl<T> Mapping<T> {
        #[inline(always)]
        pub(super) fn as_slice(&self) -> &[T] {
            // SAFETY: `ptr` holds `len` initialised elements (`with`), owned by `self`.
            unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
        }

        #[inline(always)]
        pub(super) fn as_mut_slice(&mut self) -> &mut [T] {
            // SAFETY: as in `as_slice`, borrowed mutably through `self`.
            unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr(), self.len) }
        }
    }

    impl<T> Drop for Mapping<T> {
        fn drop(&mut self) {
            // SAFETY: the `len` elements are initialised and owned by `self` (dropped once,
            // here); `base .. base + map_len` is the mapping `with` made, unmapped once, after
            // them; no slice of it outlives `self`.
            unsafe {
                std::ptr::drop_in_place(self.as_mut_slice());
                libc::munmap(self.base.as_ptr(), self.map_len);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_hold_what_vectors_do() {
        for len in [0, 1, 1000, (3 << 20) / 4 + 5, (4 << 20) / 4] {
            let v = Pages::filled(len, 7u32);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|&x| x == 7));
            let plain: Vec<u64> = (0..len as u64).collect();
            let mut moved = Pages::from(plain.clone());
            assert_eq!(&moved[..], &plain[..]);
            let copy = moved.clone();
            if len > 0 {
                moved[len - 1] = 1;
                assert_eq!(copy[len - 1], len as u64 - 1, "a clone is its own memory");
            }
            assert_eq!(copy, Pages::from_slice(&plain));
        }
    }
}
