//! Buffers the engine needs again and again, kept instead of freed and allocated anew.
//!
//! Whether the C allocator keeps a freed buffer's pages or hands them back to the kernel
//! depends on its heuristics (glibc's mmap and trim thresholds, which every earlier
//! allocation of the process moves). Handed back, the next allocation faults its pages
//! in afresh, which on a virtual machine that returns freed memory to its host costs a
//! host fault per page too (docs/design.md, "Memory pages"). The engine's repeated
//! buffers are therefore kept explicitly: the column pass's per-worker block buffers for
//! the chunks of a frame ([`ColumnWorkspace`]), a frame's accumulator, row spectra and
//! column workspace for the frames of a sequence ([`FramePool`]), and the chunks' OTF
//! profiles for the frames of a sequence ([`ProfileCache`]).

use std::any::Any;
use std::borrow::Cow;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use num_complex::{Complex, Complex64};
use rayon::prelude::*;

use super::fft::{FftFloat, RealFft2, SpectrumBuffer};
use super::otf_table::ChunkProfile;
use crate::memory::vec_on_huge_pages;

/// The per-worker buffers of [`super::accumulate_chunk`] (one block of every band of a chunk,
/// and the column plan's scratch), kept from one chunk to the next instead of freed.
///
/// Each parallel job of the column pass leases a set and returns it when done, so a frame
/// allocates about one set per worker, once. Freed instead, 553 KB per set at 1024², they
/// went back to the C allocator after every chunk, and whether it kept their pages or
/// returned them to the kernel depended on its heuristics (its mmap and trim thresholds,
/// which any earlier allocation of the run moves): returned, the next chunk faulted them
/// in afresh, 4 000 extra page faults and 4–10 % more column-pass time per 1024² × 128
/// run. The contents left in a set are never read: every use copies its regions in first.
pub struct ColumnWorkspace<T: FftFloat> {
    free: Mutex<Vec<WorkerBuffers<T>>>,
}

/// One worker's buffers ([`ColumnWorkspace`]).
struct WorkerBuffers<T> {
    blocks: Vec<Complex<T>>,
    scratch: Vec<Complex<T>>,
}

impl<T: FftFloat> Default for ColumnWorkspace<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: FftFloat> ColumnWorkspace<T> {
    /// An empty workspace: sets are allocated as the column pass first needs them.
    pub fn new() -> Self {
        ColumnWorkspace {
            free: Mutex::new(Vec::new()),
        }
    }

    /// Sets allocated so far (all returned between column passes).
    pub fn sets(&self) -> usize {
        self.free.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    /// A set with room for `len` block samples and `fft`'s column scratch: a returned
    /// one if there is one, grown if it is too small, otherwise a new one.
    pub(super) fn lease(&self, len: usize, fft: &RealFft2<T>) -> Lease<'_, T> {
        let zero = Complex::new(T::zero(), T::zero());
        let reused = self.free.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let mut set = reused.unwrap_or_else(|| WorkerBuffers {
            blocks: Vec::new(),
            scratch: Vec::new(),
        });
        let scratch_len = fft.column_region_scratch_len();
        if set.blocks.len() < len {
            set.blocks.resize(len, zero);
        }
        if set.scratch.len() < scratch_len {
            set.scratch.resize(scratch_len, zero);
        }
        Lease {
            workspace: self,
            set: Some(set),
        }
    }
}

/// A set of [`ColumnWorkspace`] buffers in use by one job; returned on drop.
pub(super) struct Lease<'a, T: FftFloat> {
    workspace: &'a ColumnWorkspace<T>,
    set: Option<WorkerBuffers<T>>,
}

impl<T: FftFloat> Lease<'_, T> {
    /// The block buffer and the scratch.
    pub(super) fn buffers(&mut self) -> (&mut Vec<Complex<T>>, &mut Vec<Complex<T>>) {
        let set = self
            .set
            .as_mut()
            .expect("a lease holds its set until dropped");
        (&mut set.blocks, &mut set.scratch)
    }
}

impl<T: FftFloat> Drop for Lease<'_, T> {
    fn drop(&mut self) {
        if let Some(set) = self.set.take() {
            self.workspace
                .free
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(set);
        }
    }
}

/// One frame's working buffers: the f64 accumulator (`[fx][fy]`), the row spectra of a
/// chunk and the column pass's workspace.
pub(super) struct FrameBuffers<T: FftFloat> {
    /// The accumulator, all zeros when leased.
    pub acc_t: Vec<Complex64>,
    /// Row spectra, one per band of a chunk (added as needed; their contents are
    /// overwritten by every row pass).
    pub rowspecs: Vec<SpectrumBuffer<T>>,
    /// The column pass's per-worker buffers.
    pub columns: ColumnWorkspace<T>,
}

/// Frame buffers kept by an [`super::Imager`] between the frames it images (one set per
/// frame in flight), so that a sequence allocates them once instead of once per frame.
/// A returned accumulator is zeroed on its next lease (in parallel, 9 MB at 1024²: well
/// under a millisecond, against a fault per page for fresh memory).
#[derive(Default)]
pub(super) struct FramePool {
    free: Mutex<Vec<Box<dyn Any + Send>>>,
}

impl std::fmt::Debug for FramePool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kept = self.free.lock().map_or(0, |v| v.len());
        write!(f, "FramePool {{ kept: {kept} }}")
    }
}

impl FramePool {
    /// Buffers for a frame whose accumulator holds `acc_len` samples, in precision `T`: a
    /// kept set (accumulator zeroed) if there is one, otherwise a new one.
    pub fn lease<T: FftFloat>(&self, acc_len: usize) -> FrameBuffers<T> {
        let kept = {
            let mut free = self.free.lock().unwrap_or_else(|e| e.into_inner());
            let at = free.iter().position(|b| {
                b.downcast_ref::<FrameBuffers<T>>()
                    .is_some_and(|f| f.acc_t.len() == acc_len)
            });
            at.map(|i| free.swap_remove(i))
        };
        match kept.and_then(|b| b.downcast::<FrameBuffers<T>>().ok()) {
            Some(mut buffers) => {
                let zero = Complex64::new(0.0, 0.0);
                buffers
                    .acc_t
                    .par_chunks_mut(1 << 16)
                    .for_each(|c| c.fill(zero));
                *buffers
            }
            None => FrameBuffers {
                acc_t: vec_on_huge_pages(acc_len, Complex64::new(0.0, 0.0)),
                rowspecs: Vec::new(),
                columns: ColumnWorkspace::new(),
            },
        }
    }

    /// Drops every kept set.
    pub fn clear(&self) {
        self.free.lock().unwrap_or_else(|e| e.into_inner()).clear();
    }

    /// Keeps `buffers` for a later frame.
    pub fn give_back<T: FftFloat>(&self, buffers: FrameBuffers<T>) {
        self.free
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(Box::new(buffers));
    }

    /// Frame buffer sets kept now.
    pub fn kept(&self) -> usize {
        self.free.lock().map_or(0, |v| v.len())
    }
}

/// Most bytes of chunk profiles an imager keeps for a sequence
/// ([`super::Imager::keep_chunk_profiles`]; the rest are rebuilt per frame): 64 profiles
/// of the 8 192 intervals the every-component SWIR sensor needs (256 KiB each), so a
/// sequence of up to 256 such bands reuses all of them and a longer one does not grow
/// the run's memory with its band count.
pub const PROFILE_CACHE_BYTES: usize = 16 << 20;

/// The OTF profiles of a frame's chunks ([`ChunkProfile`], one per chunk of bands), kept by
/// an [`super::Imager`] for the next frame of a sequence: a chunk's profile depends only on
/// its wavelengths, which are the same in every frame, and building it (refining its ρ
/// grid against the component tables) takes 0.33–0.35 ms per chunk for the benchmark
/// SWIR sensor (`examples/bench_profile.rs`; 6–9 % of the CPU time of a 512² sequence
/// before profiles were kept). Off by default (a single frame has no use for it);
/// [`ProfileCache::keep`] turns it on with a byte budget (the run's pipeline gives it what
/// its memory budget leaves, at most [`PROFILE_CACHE_BYTES`]).
///
/// Never blocks: a frame that finds a chunk's profile missing builds it (frames in flight
/// may both build it; the values are the same, one is kept).
pub(super) struct ProfileCache {
    cells: Vec<OnceLock<ChunkProfile>>,
    /// Bytes kept so far, and the most that may be (0: keep none).
    bytes: AtomicUsize,
    budget: AtomicUsize,
}

impl std::fmt::Debug for ProfileCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ProfileCache {{ budget: {}, kept: {} }}",
            self.budget.load(Ordering::Relaxed),
            self.kept()
        )
    }
}

impl ProfileCache {
    /// A cache for `chunks` chunks, keeping nothing until [`ProfileCache::keep`].
    pub fn new(chunks: usize) -> Self {
        ProfileCache {
            cells: (0..chunks).map(|_| OnceLock::new()).collect(),
            bytes: AtomicUsize::new(0),
            budget: AtomicUsize::new(0),
        }
    }

    /// Keeps profiles from now on while they hold at most `max_bytes` in all (0: keep no
    /// more; those kept already stay).
    pub fn keep(&self, max_bytes: usize) {
        self.budget.store(max_bytes, Ordering::Relaxed);
    }

    /// Profiles kept so far.
    pub fn kept(&self) -> usize {
        self.cells.iter().filter(|c| c.get().is_some()).count()
    }

    /// Chunk `chunk`'s profile: the kept one, or `build()`'s, kept for the next frame if
    /// keeping is on and the budget allows.
    pub fn get_or_build(
        &self,
        chunk: usize,
        build: impl FnOnce() -> ChunkProfile,
    ) -> Cow<'_, ChunkProfile> {
        let Some(cell) = self.cells.get(chunk) else {
            return Cow::Owned(build());
        };
        if let Some(p) = cell.get() {
            return Cow::Borrowed(p);
        }
        let profile = build();
        let budget = self.budget.load(Ordering::Relaxed);
        if budget == 0 {
            return Cow::Owned(profile);
        }
        let size = profile.heap_bytes();
        let before = self.bytes.fetch_add(size, Ordering::Relaxed);
        if before + size > budget {
            self.bytes.fetch_sub(size, Ordering::Relaxed);
            return Cow::Owned(profile);
        }
        match cell.set(profile) {
            Ok(()) => Cow::Borrowed(cell.get().expect("set just above")),
            Err(profile) => {
                // Another frame kept the same profile first.
                self.bytes.fetch_sub(size, Ordering::Relaxed);
                Cow::Owned(profile)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::otf_table::{bench_swir_otf, RadialTables};

    /// Kept profiles are served again (the same object), only with keeping on, never
    /// beyond the byte budget (the chunk over it is built and handed back, not kept), and
    /// a chunk index outside the cache is built every time.
    #[test]
    fn profiles_are_kept_within_the_budget_and_served_again() {
        let otf = bench_swir_otf();
        let tables = RadialTables::new(&otf, 1.0, 1.7);
        let wavelengths: [&[f64]; 3] = [&[1.0, 1.1, 1.2, 1.3], &[1.35, 1.4], &[1.5, 1.6, 1.7]];
        let build = |c: usize| tables.chunk_profile(&otf, wavelengths[c], 2e4);
        let bytes: Vec<usize> = (0..3).map(|c| build(c).heap_bytes()).collect();
        assert!(bytes.iter().all(|b| *b >= 257 * 32));

        let off = ProfileCache::new(3);
        assert!(matches!(off.get_or_build(0, || build(0)), Cow::Owned(_)));
        assert_eq!(off.kept(), 0);

        off.keep(bytes[0] + bytes[1]);
        for c in 0..3 {
            let p = off.get_or_build(c, || build(c));
            assert_eq!(*p, build(c), "chunk {c}");
            assert_eq!(matches!(p, Cow::Borrowed(_)), c < 2, "chunk {c}");
        }
        assert_eq!(off.kept(), 2);
        // Kept ones are served without building; the one over the budget is built again.
        let again = off.get_or_build(1, || panic!("chunk 1 was kept"));
        assert_eq!(*again, build(1));
        assert!(matches!(off.get_or_build(2, || build(2)), Cow::Owned(_)));
        assert!(matches!(off.get_or_build(7, || build(0)), Cow::Owned(_)));
        assert_eq!(off.kept(), 2);
    }
}
