//! The system allocator, counting allocations and the bytes in use. A binary installs it with
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOCATOR: CountingAllocator = CountingAllocator;
//! ```
//!
//! as `examples/benchmark.rs` does (memory per node), `tests/allocation` (no allocation per step) and
//! `tests/plugin` (no huge allocation for a corrupt groom file). Without it every count reads 0.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicIsize, AtomicU64, Ordering};

/// Allocations and reallocations made so far, by all threads.
pub static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// Allocations and reallocations made so far by this thread (constant-initialised, so reading it
    /// never allocates).
    static THREAD_ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

/// Allocations and reallocations made so far by the calling thread: unlike [`ALLOCATIONS`], blind to
/// other threads (a test harness's main thread allocates while a test runs).
pub fn thread_allocations() -> u64 {
    THREAD_ALLOCATIONS.with(Cell::get)
}

thread_local! {
    /// The largest single allocation or reallocation by this thread since [`reset_thread_largest`], bytes.
    static THREAD_LARGEST: Cell<usize> = const { Cell::new(0) };
}

/// Starts measuring the calling thread's largest single allocation from zero.
pub fn reset_thread_largest() {
    THREAD_LARGEST.with(|largest| largest.set(0));
}

/// The calling thread's largest single allocation since [`reset_thread_largest`], bytes.
pub fn thread_largest() -> usize {
    THREAD_LARGEST.with(Cell::get)
}

fn count_allocation(size: usize) {
    ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    THREAD_ALLOCATIONS.with(|count| count.set(count.get() + 1));
    THREAD_LARGEST.with(|largest| largest.set(largest.get().max(size)));
}
/// Heap bytes allocated and not yet freed.
pub static BYTES_IN_USE: AtomicIsize = AtomicIsize::new(0);

/// The system allocator, counting: see the module's docs.
pub struct CountingAllocator;

// SAFETY: every call is forwarded to the system allocator unchanged; only counters are added.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_allocation(layout.size());
        BYTES_IN_USE.fetch_add(layout.size() as isize, Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        BYTES_IN_USE.fetch_sub(layout.size() as isize, Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_allocation(new_size);
        BYTES_IN_USE.fetch_add(new_size as isize - layout.size() as isize, Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
