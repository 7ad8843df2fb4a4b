//! The system allocator, counting each thread's allocations and frees: the one counter of the
//! tests that a step allocates nothing (the solvers, the export layer, the Kalman FMUs, the
//! engine). A test binary installs it and counts what a closure does on its own thread:
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOCATOR: spurio_counting_allocator::CountingAllocator =
//!     spurio_counting_allocator::CountingAllocator;
//!
//! let (_, counts) = spurio_counting_allocator::count(|| solver.step(&mut system, 1.0));
//! assert_eq!(counts.allocations, 0);
//! ```
//!
//! Per thread: the test harness's other threads (other tests, output capture) are not counted.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// The system allocator, counting on each thread.
pub struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    static FREES: Cell<u64> = const { Cell::new(0) };
}

/// Adds one to `counter` of this thread (`try_with`: a thread being torn down has no counter
/// left, and is not the one measured).
fn add(counter: &'static std::thread::LocalKey<Cell<u64>>) {
    let _ = counter.try_with(|n| n.set(n.get() + 1));
}

// SAFETY: forwards every call to the system allocator unchanged, only counting.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        add(&ALLOCATIONS);
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        add(&ALLOCATIONS);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        add(&ALLOCATIONS);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        add(&FREES);
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// What this thread asked of the allocator in a [`count`]ed closure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counts {
    /// Allocations and reallocations.
    pub allocations: u64,
    /// Frees.
    pub frees: u64,
}

impl Counts {
    /// Allocations, reallocations and frees together.
    pub fn events(&self) -> u64 {
        self.allocations + self.frees
    }
}

fn now() -> Counts {
    Counts {
        allocations: ALLOCATIONS.with(Cell::get),
        frees: FREES.with(Cell::get),
    }
}

/// Runs `f` and returns its result with what this thread allocated and freed meanwhile (only
/// meaningful in a binary whose global allocator is [`CountingAllocator`]).
pub fn count<R>(f: impl FnOnce() -> R) -> (R, Counts) {
    let before = now();
    let result = f();
    let after = now();
    let counts = Counts {
        allocations: after.allocations - before.allocations,
        frees: after.frees - before.frees,
    };
    (result, counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[global_allocator]
    static ALLOCATOR: CountingAllocator = CountingAllocator;

    #[test]
    fn counts_what_the_closure_allocates_and_frees_on_its_thread() {
        let (_, none) = count(|| std::hint::black_box(1.0f64).sqrt());
        assert_eq!(none, Counts::default());
        let (length, counts) = count(|| {
            let mut v: Vec<u64> = Vec::with_capacity(1);
            v.extend(0..100); // grows: reallocations
            v.len()
        });
        assert_eq!(length, 100);
        assert!(counts.allocations >= 2, "{counts:?}");
        assert_eq!(counts.frees, 1, "{counts:?}");
        // Another thread's allocations are its own: a thousand there, a handful here (the
        // spawn itself).
        let work = || (0..1000).map(|k| vec![k; 8].len()).sum::<usize>();
        let (sum, here) = count(|| std::thread::spawn(work).join());
        assert_eq!(sum.ok(), Some(8000));
        assert!(here.allocations < 100, "{here:?}");
    }
}
