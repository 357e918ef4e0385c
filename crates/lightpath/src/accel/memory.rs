//! Large traversal arrays (wide BVH nodes, packed triangle blocks) asked for in
//! transparent huge pages where the kernel offers them.
//!
//! Rays that wander over a big mesh touch a new 4 KiB page at almost every node and leaf:
//! tens of megabytes of nodes overflow the TLB, and each miss costs a page walk on top of
//! the cache miss. Backing the arrays with 2 MiB pages removes most of those walks. It is
//! only a hint (`madvise(MADV_HUGEPAGE)`): where the kernel has transparent huge pages
//! off, or on other systems, the arrays are ordinary allocations.

use rayon::prelude::*;

/// Collects `iter` into a vector whose buffer was advised into huge pages before it was
/// written (so its pages are faulted in huge rather than collapsed later).
pub(crate) fn collect_huge<T: Send>(iter: impl IndexedParallelIterator<Item = T>) -> Vec<T> {
    let mut v = Vec::with_capacity(iter.len());
    advise_huge_pages(
        v.as_mut_ptr() as *mut u8,
        v.capacity() * std::mem::size_of::<T>(),
    );
    iter.collect_into_vec(&mut v);
    v
}

/// An empty vector with room for `capacity` elements, advised into huge pages (for a
/// large array filled by pushes).
pub(crate) fn with_capacity_huge<T>(capacity: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(capacity);
    advise_huge_pages(
        v.as_mut_ptr() as *mut u8,
        v.capacity() * std::mem::size_of::<T>(),
    );
    v
}

/// Below this a buffer cannot hold an aligned huge page.
#[cfg(target_os = "linux")]
const HUGE_PAGE: usize = 2 << 20;

#[cfg(target_os = "linux")]
fn advise_huge_pages(ptr: *mut u8, bytes: usize) {
    if bytes < 2 * HUGE_PAGE {
        return;
    }
    const PAGE: usize = 4096;
    let start = (ptr as usize).div_ceil(PAGE) * PAGE;
    let end = (ptr as usize + bytes) / PAGE * PAGE;
    // SAFETY: the range lies inside an allocation this function's caller owns, and
    // MADV_HUGEPAGE changes how pages are backed, never their contents. Failure (no THP
    // support) leaves an ordinary allocation, so the result is ignored.
    unsafe {
        libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_ptr: *mut u8, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collects_in_order_small_and_large() {
        for n in [0usize, 5, 3 << 20] {
            let v = collect_huge((0..n).into_par_iter().map(|i| i as u32 * 3));
            assert_eq!(v.len(), n);
            assert!(v.iter().enumerate().all(|(i, &x)| x == i as u32 * 3));
        }
    }
}
