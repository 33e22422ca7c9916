//! Fuzz the scenario reader, and run what it accepts when that is small.
//!
//! Input: the TOML text, then any number of `--set` assignments, separated by NUL bytes
//! (`text\0rod.0.E=1e9\0solve.dt=1e-4`). Bytes that are not UTF-8 are replaced (the CLI rejects
//! such a file before the reader sees it), so every seed scenario file is a valid input as is.
//!
//! Checked:
//! - `Scenario::from_str` returns, Ok or Err, without panicking;
//! - an accepted scenario's stored text (what recordings keep, and what `replay` reads back)
//!   is itself accepted, with the same rods and nodes;
//! - an accepted scenario with ≤ 50 nodes and ≤ 2000 nominal steps runs with `NullObserver`
//!   without panicking, and every position and velocity is finite afterwards (also after a
//!   clean `SimError`, since a failed step leaves the last accepted state).
//!
//! To keep one execution short, Newton iterations, contact passes and back-offs are capped at
//! their defaults (the scenario stays valid) and the run is interrupted after 4000 steps
//! (adaptive stepping and time-of-impact splits can take more steps than t_end / dt).

#![no_main]

use gripsim::events::NullObserver;
use gripsim::scenario::{Mode, Stepping};
use gripsim::{Scenario, Simulation};
use libfuzzer_sys::fuzz_target;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

const MAX_NODES: usize = 50;
const MAX_STEPS: f64 = 2000.0;
const MAX_SETS: usize = 8;

fuzz_target!(|data: &[u8]| {
    let mut parts = data.split(|&b| b == 0);
    let text = String::from_utf8_lossy(parts.next().unwrap_or(&[])).into_owned();
    let sets: Vec<String> = parts
        .take(MAX_SETS)
        .map(|p| String::from_utf8_lossy(p).into_owned())
        .collect();

    let Ok(mut sc) = Scenario::from_str(&text, "fuzz.toml", &sets) else {
        return;
    };

    // What a recording stores must read back (replay parses it).
    let again = Scenario::from_str(&sc.text, "fuzz.toml (stored text)", &[]).unwrap_or_else(|e| {
        panic!(
            "the stored text of an accepted scenario is rejected: {e}\n{}",
            sc.text
        )
    });
    assert_eq!(again.rods.len(), sc.rods.len());
    for (a, b) in again.rods.iter().zip(&sc.rods) {
        assert_eq!(a.nodes, b.nodes);
    }

    let nodes: usize = sc.rods.iter().map(|r| r.nodes).sum();
    if nodes > MAX_NODES {
        return;
    }
    let s = &sc.solve;
    if s.mode == Mode::Dynamic {
        let smallest = match s.stepping {
            Stepping::Proximity => s.dt.min(s.dt_near),
            _ => s.dt,
        };
        if !(s.t_end / smallest <= MAX_STEPS) {
            return;
        }
    }
    sc.solve.max_newton_iterations = sc.solve.max_newton_iterations.min(50);
    sc.solve.max_contact_passes = sc.solve.max_contact_passes.min(25);
    sc.solve.max_backoff = sc.solve.max_backoff.min(8);

    let mut sim = Simulation::new(&sc);
    let checks = Arc::new(AtomicU64::new(0));
    let c = checks.clone();
    sim.interrupt = Some(Box::new(move || c.fetch_add(1, Ordering::Relaxed) >= 4000));
    let _ = sim.run(&mut NullObserver);
    for r in 0..sim.rods.len() {
        let name = &sim.rods[r].name;
        for (k, x) in sim.positions(r).iter().enumerate() {
            assert!(
                x.is_finite(),
                "rod {name:?} q[{k}] = {x} after {} steps",
                sim.step
            );
        }
        for (k, x) in sim.velocities(r).iter().enumerate() {
            assert!(
                x.is_finite(),
                "rod {name:?} u[{k}] = {x} after {} steps",
                sim.step
            );
        }
    }
});
