//! Large buffers and the pages behind them.
//!
//! The engine streams a few frame-sized buffers through the cache for every chunk of bands
//! (row spectra, the f64 accumulator, the frequency grid, band planes read from files).
//! On 4 KiB pages each needs one TLB entry and, on first touch, one page fault per 4 KiB.
//! Many Linux systems enable transparent huge pages on request only (`madvise` mode), so
//! these buffers ask for them ([`advise_huge_pages`]): 2 MiB pages, 512 times fewer
//! entries and faults. The advice is a hint: values never depend on it, and where the
//! kernel declines (or off Linux) nothing changes. [`prefetch_read`] is the cache's
//! counterpart: it asks for lines ahead of a read, again a hint.

/// Size of a transparent huge page on x86-64 and most other Linux targets, bytes.
const HUGE_PAGE_BYTES: usize = 2 << 20;

/// Asks the kernel to back the whole 2 MiB pages inside `v`'s allocation (its capacity)
/// with huge pages (`MADV_HUGEPAGE`). It takes effect on the pages' first touch, so call
/// it before the buffer is first written: right after `Vec::with_capacity`, or after
/// `vec![0; n]` of a large buffer (fresh zero pages from the kernel, not yet touched).
pub fn advise_huge_pages<V>(v: &Vec<V>) {
    #[cfg(target_os = "linux")]
    {
        let (ptr, bytes) = (v.as_ptr() as usize, v.capacity() * std::mem::size_of::<V>());
        let start = ptr.div_ceil(HUGE_PAGE_BYTES) * HUGE_PAGE_BYTES;
        let end = (ptr + bytes) / HUGE_PAGE_BYTES * HUGE_PAGE_BYTES;
        if end > start {
            // SAFETY: advice on whole pages inside an allocation the caller owns;
            // MADV_HUGEPAGE changes neither contents nor validity. A failure only means
            // the advice was not taken.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// A vector of `len` copies of `value` on huge pages where the kernel grants them
/// ([`advise_huge_pages`] before the fill).
///
/// The fill is the pages' first touch, and it runs on the rayon pool, one huge page per
/// task: a fresh page costs a fault and the kernel's zeroing, and in a virtual machine
/// that hands freed memory back to its host (free page reporting) also the host's
/// fault, about 1 ms per MiB on the benchmark machine. Spread over the workers, a
/// frame's buffers are ready in about half the time.
pub fn vec_on_huge_pages<V: Clone + Send + Sync>(len: usize, value: V) -> Vec<V> {
    use rayon::prelude::*;
    let mut v: Vec<V> = Vec::with_capacity(len);
    advise_huge_pages(&v);
    let per_task = (HUGE_PAGE_BYTES / std::mem::size_of::<V>().max(1)).max(1);
    v.spare_capacity_mut()[..len]
        .par_chunks_mut(per_task)
        .for_each(|c| {
            for x in c {
                x.write(value.clone());
            }
        });
    // SAFETY: every one of the first `len` elements was written just above.
    unsafe { v.set_len(len) };
    v
}

/// Asks the CPU to bring the cache lines of `data` into its caches ahead of a read: a hint
/// (values never depend on it; it never faults; nothing off x86-64).
#[inline]
pub fn prefetch_read<V>(data: &[V]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        const LINE: usize = 64;
        let p = data.as_ptr() as *const i8;
        for offset in (0..std::mem::size_of_val(data)).step_by(LINE) {
            // SAFETY: `p + offset` lies inside `data`; a prefetch only hints the cache.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = data;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The huge-page hint changes nothing about the values: empty, below one huge page,
    /// and across several.
    #[test]
    fn vectors_on_huge_pages_hold_their_values() {
        for len in [0usize, 1, 1000, 3 << 20] {
            let v = vec_on_huge_pages(len, 2.5f32);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|x| *x == 2.5));
        }
        let mut w: Vec<u8> = Vec::with_capacity(5 << 20);
        advise_huge_pages(&w);
        w.extend(std::iter::repeat_n(7u8, 5 << 20));
        assert!(w.iter().all(|x| *x == 7));
    }
}
