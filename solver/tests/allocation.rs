//! No backend or method allocates inside its time loop: a run of 12 steps makes no more heap
//! allocations than a run of 2, counted by a global allocator that wraps the system's. (Starting
//! a run's worker threads allocates a few times more or less from run to run, so the counts are
//! compared with a margin below the 10 that one allocation per step would add.)

mod common;

use common::case;
use serde_json::json;
use solver::run;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Heap allocations made by running `fields` for `steps` steps of dt = 1e-7.
fn allocations(fields: &serde_json::Value, steps: usize) -> usize {
    let mut case_json = fields.clone();
    case_json["dt"] = json!(1e-7);
    case_json["t_end"] = json!(1e-7 * steps as f64);
    let case = case(case_json);
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let outcome = run(&case).expect("the case runs");
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(outcome.record.steps_done, steps);
    drop(outcome);
    after - before
}

#[test]
fn time_loops_do_not_allocate() {
    let mut cases = Vec::new();
    for dim in [1, 2] {
        for backend in ["stencil", "fft", "neighbour_list"] {
            cases.push(
                json!({ "method": "nonlocal", "dim": dim, "n": 40, "m": 3, "backend": backend,
                               "problem": "manufactured" }),
            );
        }
        for method in ["fd_explicit", "adi"] {
            cases.push(json!({ "method": method, "dim": dim, "n": 40, "problem": "eigenmode" }));
        }
        cases.push(json!({ "method": "pse", "dim": dim, "n": 40, "m": 4, "problem": "eigenmode" }));
    }
    for fields in &cases {
        for threads in [1, 2] {
            let mut fields = fields.clone();
            fields["threads"] = json!(threads);
            // The first run starts what lives for the whole process (rayon's registry, …).
            allocations(&fields, 2);
            let (few, many) = (allocations(&fields, 2), allocations(&fields, 12));
            assert!(
                many < few + 10,
                "{fields}: {few} allocations in 2 steps, {many} in 12"
            );
        }
    }
}
