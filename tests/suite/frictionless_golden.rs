//! μ = 0 is today's frictionless solver, bit for bit: every scenario shipped before friction and
//! free bodies existed gives exactly the summary the frictionless solver gave (recorded in
//! tests/golden/frictionless/ by the solver of commit 73a9ceb, before the coupled step).
//!
//! Compared exactly: step, iteration and pass counts, penetration, every peak force, stress,
//! impulse and contact time, every final node position, and the final velocity of every free
//! node. Not compared: wall time, and the velocities and drive force of driven nodes (their
//! recorded velocity became the drive's exact velocity, issue 12, which the free nodes never see).
//! Keys the summary gained later (absent from the golden files) are not compared: every key of
//! a golden file is.

use gripsim::record::summary::SummaryCollector;
use gripsim::{Scenario, Simulation};
use serde_json::Value;

const SCENARIOS: &[&str] = &[
    "cantilever-gravity",
    "cantilever-tip-load",
    "parabolic-beam-flat",
    "point-mass-plane-dt1e-4",
    "point-mass-plane-proximity",
    "point-mass-sine",
    "seed-grasp-e1gpa",
    "seed-grasp-r4",
    "seed-grasp-r5",
    "two-prong-grasp",
];

fn strip(mut v: Value, clamped: &[Vec<bool>]) -> Value {
    let o = v.as_object_mut().expect("summary is an object");
    o.remove("wall_time_s");
    o.remove("grasp");
    // Issue 13's additions (the energy balance, static stability), not in the golden files.
    for k in [
        "energy",
        "energy_closure_rel",
        "min_eigenvalue",
        "unstable_equilibrium",
        "rejected_steps",
        "first_order_node_steps",
        "split_steps",
        "jacobian_factorizations",
    ] {
        o.remove(k);
    }
    for (r, rod) in o["rods"]
        .as_array_mut()
        .expect("rods")
        .iter_mut()
        .enumerate()
    {
        let rod = rod.as_object_mut().expect("rod");
        rod.remove("final_drive_force_n");
        if let Some(vs) = rod
            .get_mut("final_velocities")
            .and_then(Value::as_array_mut)
        {
            for (i, v) in vs.iter_mut().enumerate() {
                if clamped[r][i] {
                    *v = Value::Null;
                }
            }
        }
    }
    v
}

/// `now` with only the keys `then` has, at every depth (a key `then` has and `now` lacks stays
/// absent, so it differs).
fn keys_of(now: &Value, then: &Value) -> Value {
    match (now, then) {
        (Value::Object(a), Value::Object(b)) => Value::Object(
            b.iter()
                .filter_map(|(k, w)| a.get(k).map(|v| (k.clone(), keys_of(v, w))))
                .collect(),
        ),
        (Value::Array(a), Value::Array(b)) => Value::Array(
            a.iter()
                .enumerate()
                .map(|(i, v)| b.get(i).map_or_else(|| v.clone(), |w| keys_of(v, w)))
                .collect(),
        ),
        _ => now.clone(),
    }
}

#[test]
fn shipped_scenarios_match_the_frictionless_solver_bit_for_bit() {
    let root = env!("CARGO_MANIFEST_DIR");
    for name in SCENARIOS {
        let sc = Scenario::load(&crate::common::scenario(name), &[]).unwrap();
        assert!(!sc.friction.any() && sc.bodies.is_empty());
        let mut sim = Simulation::new(&sc);
        let mut col = SummaryCollector::new();
        sim.run(&mut col).unwrap();
        let clamped: Vec<Vec<bool>> = sim.rods.iter().map(|r| r.clamped.clone()).collect();
        let now = strip(
            serde_json::to_value(col.finish(&sim.stats, 0.0)).unwrap(),
            &clamped,
        );
        let text = std::fs::read_to_string(format!("{root}/tests/golden/frictionless/{name}.json"))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let then = strip(serde_json::from_str(&text).unwrap(), &clamped);
        let now = keys_of(&now, &then);
        if now != then {
            let (a, b) = (now.to_string(), then.to_string());
            let at = a
                .bytes()
                .zip(b.bytes())
                .position(|(x, y)| x != y)
                .unwrap_or(0);
            panic!(
                "{name}: the summary differs from the frictionless solver's near …{}… vs …{}…",
                &a[at.saturating_sub(80)..(at + 80).min(a.len())],
                &b[at.saturating_sub(80)..(at + 80).min(b.len())]
            );
        }
        println!("{name}: identical ({} steps)", sim.stats.steps);
    }
}
