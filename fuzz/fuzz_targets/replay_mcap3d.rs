//! Fuzz the 3D recording reader of `gripsim replay` with raw file bytes.
//!
//! The input is written to a file (the reader takes a path, as the CLI does) and read with
//! `replay::three::check` (read, every step checked, the spike/sticking rules) and, when that
//! succeeds, diffed against itself with `replay::diff3::diff`. Any `Err` is fine; a panic is a
//! finding. A run that reads must diff clean against itself.
//!
//! The seeds (fuzz/seeds/replay_mcap3d/, fuzz/make_seeds.py) are a 3-step two-finger run as
//! written (zstd chunks with CRCs) and the same messages unchunked and uncompressed without
//! `/scene`, so that mutations reach the `gripsim.Step3` messages and not only the container.

#![no_main]

use gripsim::replay::{diff3, three, Thresholds, Tolerances};
use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        dir.join(format!("gripsim-fuzz3d-{}.mcap", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    std::fs::write(path, data).expect("write the scratch file");
    let th = Thresholds::default();
    let Ok(report) = three::check(path, &th) else {
        return;
    };
    let _ = three::format_check(&report);
    let rep = diff3::diff(path, path, &Tolerances::default(), &th)
        .expect("a run that reads is comparable with itself");
    let _ = diff3::format_diff(&rep);
    assert!(rep.within_tolerance, "a run differs from itself");
});
