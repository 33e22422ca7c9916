//! The one run API (`gripsim::run`): a scenario of either dimension read as its text says,
//! run to its end with the one summary, and stopped by its `Stop` with the summary as far as
//! it went. The CLI's `run --summary` writes the same summary (wall time aside).

use crate::common::{gripsim, scenario};
use gripsim::events::NullObserver;
use gripsim::run::{run, AnyScenario, Stop};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

fn without_wall(mut v: serde_json::Value) -> serde_json::Value {
    v.as_object_mut().unwrap().remove("wall_time_s");
    v
}

#[test]
fn one_call_runs_either_dimension_as_the_cli_does() {
    for (name, dim) in [("jaw-grasp-hold", 2), ("3d-two-finger-sphere", 3)] {
        let (text, sc) = AnyScenario::read(&scenario(name), &[]).unwrap();
        assert_eq!(sc.dimension(), dim);
        let out = run(&sc, &text, &mut NullObserver, None).unwrap();
        assert!(out.error.is_none(), "{name}: {:?}", out.error);
        assert!(out.summary.completed && out.summary.dimension == dim);
        let dir = tempfile::tempdir().unwrap();
        let json = dir.path().join("s.json");
        crate::common::run_ok(
            gripsim()
                .args(["run", "--no-record", "--quiet", "--summary"])
                .arg(&json)
                .arg(scenario(name)),
        );
        let cli: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let api = serde_json::to_value(&out.summary).unwrap();
        assert_eq!(without_wall(api), without_wall(cli), "{name}");
        println!(
            "{name}: dimension {dim}, {} steps, same summary as the CLI",
            out.summary.steps
        );
    }
}

#[test]
fn a_stop_ends_either_dimension_with_the_summary_so_far() {
    for name in ["jaw-grasp-hold", "3d-two-finger-sphere"] {
        let (text, sc) = AnyScenario::read(&scenario(name), &[]).unwrap();
        let asked = Arc::new(AtomicU64::new(0));
        let a = asked.clone();
        // Stop when asked the 50th time (between steps).
        let stop: Stop = Arc::new(move || a.fetch_add(1, Ordering::Relaxed) >= 50);
        let out = run(&sc, &text, &mut NullObserver, Some(stop)).unwrap();
        let e = out.error.expect("stopped");
        assert!(e.interrupted(), "{name}: {e}");
        assert!(!out.summary.completed, "{name}");
        assert!(
            out.summary.steps >= 40 && out.summary.steps <= 50,
            "{name}: {} steps",
            out.summary.steps
        );
        assert!(out
            .summary
            .error
            .as_deref()
            .unwrap()
            .contains("interrupted"));
    }
}

#[test]
fn either_dimension_takes_its_overrides_and_names_a_bad_one() {
    let sets = ["friction.mu_s=1.2".to_string()];
    for name in ["jaw-grasp-hold", "3d-lift"] {
        let (_, sc) = AnyScenario::read(&scenario(name), &sets).unwrap();
        let mu = match &sc {
            AnyScenario::Planar(s) => s.friction.default.mu_s,
            AnyScenario::Spatial(s) => s.friction.default.mu_s,
        };
        assert_eq!(mu, 1.2, "{name}");
        let bad = ["friction.mu_s=-1".to_string()];
        let e = AnyScenario::read(&scenario(name), &bad).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("friction.mu_s") && msg.contains("-1"),
            "{name}: {msg}"
        );
    }
}
