//! `scanner-alloc`: global allocators that count, for tests and checks across the workspace —
//! [`Counting`] (allocations per thread: the per-frame path allocates nothing) and [`Peak`] (the
//! process's live heap and its peak: memory limits). A crate of its own, so that a crate's tests
//! that need it build that crate and this one alone.
#![deny(missing_docs)]

/// A global allocator that counts allocations per thread (the test harness allocates on other
/// threads while a test runs). Install it in a test binary with
/// `#[global_allocator] static A: scanner_tests::Counting = scanner_tests::Counting;` and
/// measure with [`allocations_during`].
pub struct Counting;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

// SAFETY: forwards to the system allocator unchanged; only counts.
#[allow(unsafe_code)]
unsafe impl std::alloc::GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
}

/// Allocations this thread made so far (with [`Counting`] installed).
pub fn allocations() -> usize {
    ALLOCATIONS.with(std::cell::Cell::get)
}

/// Allocations this thread makes while `f` runs (with [`Counting`] installed).
pub fn allocations_during(f: impl FnOnce()) -> usize {
    let before = allocations();
    f();
    allocations() - before
}

/// A global allocator that tracks the live heap bytes of the whole process and their peak (for
/// memory limits: the host's peak for a crafted stream, the fuzz target's per-input check).
/// Install with `#[global_allocator] static A: scanner_tests::Peak = scanner_tests::Peak;`.
pub struct Peak;

static LIVE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
static PEAK: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

fn grew(by: usize) {
    use std::sync::atomic::Ordering::Relaxed;
    let now = LIVE.fetch_add(by, Relaxed) + by;
    PEAK.fetch_max(now, Relaxed);
}

// SAFETY: forwards to the system allocator unchanged; only counts live bytes.
#[allow(unsafe_code)]
unsafe impl std::alloc::GlobalAlloc for Peak {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        LIVE.fetch_sub(layout.size(), std::sync::atomic::Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new: usize) -> *mut u8 {
        if new >= layout.size() {
            grew(new - layout.size());
        } else {
            LIVE.fetch_sub(layout.size() - new, std::sync::atomic::Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.realloc(ptr, layout, new) }
    }
}

/// Live heap bytes now (with [`Peak`] installed).
pub fn live_bytes() -> usize {
    LIVE.load(std::sync::atomic::Ordering::Relaxed)
}

/// The peak of live heap bytes since the last [`reset_peak`] (with [`Peak`] installed).
pub fn peak_bytes() -> usize {
    PEAK.load(std::sync::atomic::Ordering::Relaxed)
}

/// Starts a new peak from the live bytes now.
pub fn reset_peak() {
    PEAK.store(live_bytes(), std::sync::atomic::Ordering::Relaxed);
}
