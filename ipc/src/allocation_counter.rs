//! Counting the heap allocations a piece of code makes on the current thread, for the tests that
//! check a control loop's hot path (feature `testing`).
//!
//! A test binary installs [`CountingAllocator`] as its global allocator and wraps the code under
//! test in [`count_allocations`] (or [`start`] ... [`stop`] across callbacks):
//!
//! ```text
//! #[global_allocator]
//! static ALLOCATOR: harvest_ipc::allocation_counter::CountingAllocator =
//!     harvest_ipc::allocation_counter::CountingAllocator;
//! ```
//!
//! Only the current thread's allocations count, so other test threads do not disturb the
//! figure. Reallocations count as allocations; frees do not.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// The system allocator, counting the allocations of threads that switched counting on.
pub struct CountingAllocator;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn note_allocation() {
    // `try_with`: the thread-locals may already be gone while a thread exits.
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = ALLOCATIONS.try_with(|count| count.set(count.get() + 1));
    }
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counting touches only
// const-initialised thread-locals, which never allocate.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_allocation();
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note_allocation();
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note_allocation();
        // SAFETY: forwarded with the caller's pointer, layout and size.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded with the caller's pointer and layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Starts counting this thread's allocations from zero.
///
/// Panics if [`CountingAllocator`] is not the global allocator (every count would read zero).
pub fn start() {
    ALLOCATIONS.with(|count| count.set(0));
    COUNTING.with(|counting| counting.set(true));
    std::hint::black_box(Box::new(0u8));
    let seen = ALLOCATIONS.with(Cell::get);
    assert_eq!(
        seen, 1,
        "CountingAllocator is not this binary's #[global_allocator]"
    );
    ALLOCATIONS.with(|count| count.set(0));
}

/// Whether this thread is counting.
pub fn is_counting() -> bool {
    COUNTING.with(Cell::get)
}

/// Stops counting; returns the allocations since [`start`].
pub fn stop() -> u64 {
    COUNTING.with(|counting| counting.set(false));
    ALLOCATIONS.with(Cell::get)
}

/// Runs `f` and returns its result with the number of allocations it made on this thread.
pub fn count_allocations<R>(f: impl FnOnce() -> R) -> (R, u64) {
    start();
    let result = f();
    (result, stop())
}
