//! The step loop allocates nothing: a run with no sink makes the same number of heap
//! allocations whether it takes 1 000 or 6 000 steps (all of them are set-up), under every
//! integrator (TR-BDF2's rollback buffers are allocated once, at its first step). The
//! allocations are counted per thread, the run's own.

use gripsim::events::NullObserver;
use gripsim::{Scenario, Simulation};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    /// Allocations made by this thread: the test harness's own threads (which print and
    /// allocate while a test runs, more so on a loaded machine) are not the step loop's.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: a thread being torn down has no thread-locals left; its allocations are not
    // counted.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_of_run(t_end: &str, extra: &[&str]) -> (usize, u64) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-grasp-r5.toml");
    let mut sets = vec![format!("solve.t_end={t_end}")];
    sets.extend(extra.iter().map(|s| s.to_string()));
    let sc = Scenario::load(&path, &sets).unwrap();
    let mut sim = Simulation::new(&sc);
    let before = ALLOCATIONS.with(Cell::get);
    let stats = sim.run(&mut NullObserver).unwrap();
    (ALLOCATIONS.with(Cell::get) - before, stats.steps)
}

#[test]
fn the_step_loop_does_not_allocate() {
    for extra in [
        vec![],
        vec!["solve.stepping=\"proximity\""],
        vec!["solve.stepping=\"adaptive\"", "solve.time_of_impact=true"],
        vec!["solve.integrator=\"bdf2\""],
        vec![
            "solve.stepping=\"adaptive\"",
            "solve.time_of_impact=true",
            "solve.integrator=\"bdf2\"",
        ],
        vec!["solve.integrator=\"tr_bdf2\""],
        vec![
            "solve.stepping=\"adaptive\"",
            "solve.time_of_impact=true",
            "solve.integrator=\"tr_bdf2\"",
        ],
    ] {
        let (short, s1) = allocations_of_run("0.01", &extra);
        let (long, s2) = allocations_of_run("0.06", &extra);
        assert!(s2 > s1, "{extra:?}");
        // The count sees the run (its set-up allocates).
        assert!(short > 0, "{extra:?}: no allocation counted");
        // The long run passes through contact (first contact at t = 0.0398 s).
        assert_eq!(
            short, long,
            "{extra:?}: {short} allocations over {s1} steps, {long} over {s2} steps"
        );
    }
}
