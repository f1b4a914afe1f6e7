//! `update` never touches the heap: a counting global allocator watches every call, including
//! the first one after construction, refused windows and windows of varying size (`1..=m`).
//! (faer's per-thread packing buffers are allocated by the constructor's warm-up.)

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use common::filters::all_filters;
use common::*;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // `try_with`: the thread-local may already be gone while a thread shuts down.
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

#[test]
fn update_does_not_allocate() {
    for (n, m) in [(10, 30), (40, 30), (120, 30)] {
        let mut g = rng(n as u64);
        let theta = random_vec(&mut g, n, 1.0);
        let stream = windows(&mut g, n, m, 6, &theta, 1e-3, false);
        let bad_b = vec![f64::NAN; 2];
        let bad_a = vec![0.5; 2 * n];
        for mut f in all_filters(n, m) {
            let before = allocations();
            for w in &stream {
                f.update(&w.a, &w.b).unwrap();
                assert!(f.update(&bad_a, &bad_b).is_err());
            }
            let used = allocations() - before;
            assert_eq!(used, 0, "{} ({n}×{m}) allocated {used} times", f.name());
        }
    }
}

#[test]
fn the_counter_sees_allocations() {
    let before = allocations();
    let v = std::hint::black_box(vec![1.0f64; 16]);
    assert!(allocations() > before);
    drop(v);
}
