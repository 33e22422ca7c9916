//! `replay check` and `diff` stream: their peak heap does not grow with the run (issue 12 item
//! 6; before, the whole run was loaded: 3.3 GB for check and 6.5 GB for diff on a 1.9 M-step
//! run). The peak of live heap bytes is counted by a global allocator while a short and a
//! four times longer recording of the same scenario are checked and diffed.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Peak;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

unsafe impl GlobalAlloc for Peak {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            grew(new_size - layout.size());
        } else {
            LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Peak = Peak;

/// The tests of this binary one at a time: the counter sees every thread's allocations.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Peak live heap (bytes above what was live before) while `f` runs.
fn peak_of(f: impl FnOnce()) -> usize {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    f();
    PEAK.load(Ordering::Relaxed) - base
}

fn record(path: &Path, t_end: &str) {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = Command::new(env!("CARGO_BIN_EXE_gripsim"))
        .current_dir(root)
        .args([
            "run",
            "scenarios/point-mass-plane-proximity.toml",
            "-q",
            "--detail",
            "step",
        ])
        .args(["--set", &format!("solve.t_end={t_end}"), "--mcap"])
        .arg(path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
}

#[test]
fn check_and_diff_memory_does_not_grow_with_the_run() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let (short, long) = (dir.path().join("short.mcap"), dir.path().join("long.mcap"));
    // Proximity stepping: 1e-6 s steps from t ≈ 0.1 s on.
    record(&short, "0.11");
    record(&long, "0.17");
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    assert!(
        size(&long) > 3 * size(&short),
        "{} vs {}",
        size(&long),
        size(&short)
    );
    let th = gripsim::replay::Thresholds::default();
    let tol = gripsim::replay::Tolerances::default();
    let mut steps = Vec::new();
    let mut check = |p: &Path| {
        peak_of(|| {
            let (rep, _) = gripsim::replay::check(p, &th).unwrap();
            steps.push(rep.steps);
        })
    };
    let (cs, cl) = (check(&short), check(&long));
    assert!(steps[1] > 3 * steps[0], "{steps:?}");
    let diff = |p: &Path| {
        peak_of(|| {
            let rep = gripsim::replay::diff::diff_files(p, p, &tol, &th).unwrap();
            assert!(rep.within_tolerance);
        })
    };
    let (ds, dl) = (diff(&short), diff(&long));
    // One chunk, the detector's windows and two steps per run: the same peak (within 25 %)
    // for a recording over three times longer; a loaded run would take 3x.
    assert!(
        cl * 4 < cs * 5,
        "check: {cs} bytes for {} steps, {cl} for {}",
        steps[0],
        steps[1]
    );
    assert!(dl * 4 < ds * 5, "diff: {ds} bytes short, {dl} long");
}

/// Issue 34 item 18: a 3D `replay check` streams too (it read the whole file and kept every
/// step: 128 MB for a 39 MB recording). The two-finger sphere to 0.05 s and to 0.2 s (four
/// times the steps): the same peak within 25 %.
#[test]
fn check_memory_of_a_3d_run_does_not_grow_with_the_run() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let root = env!("CARGO_MANIFEST_DIR");
    let record3 = |path: &Path, t_end: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_gripsim"))
            .current_dir(root)
            .args(["run", "scenarios/3d-two-finger-sphere.toml", "-q"])
            .args(["--set", &format!("solve.t_end={t_end}"), "--mcap"])
            .arg(path)
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
    };
    let (short, long) = (dir.path().join("short.mcap"), dir.path().join("long.mcap"));
    record3(&short, "0.05");
    record3(&long, "0.2");
    let th = gripsim::replay::Thresholds::default();
    let mut steps = Vec::new();
    let mut check = |p: &Path| {
        peak_of(|| {
            let rep = gripsim::replay::three::check(p, &th).unwrap();
            steps.push(rep.steps);
        })
    };
    let (cs, cl) = (check(&short), check(&long));
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    println!(
        "3D check: {cs} bytes peak for {} steps ({} bytes of file), {cl} for {} ({} bytes)",
        steps[0],
        size(&short),
        steps[1],
        size(&long)
    );
    assert!(steps[1] > 3 * steps[0], "{steps:?}");
    assert!(
        cl * 4 < cs * 5,
        "3D check: {cs} bytes for {} steps, {cl} for {}",
        steps[0],
        steps[1]
    );
}
