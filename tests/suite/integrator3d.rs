//! Issue 33 item 6, the 3D integrators (src/rod3d/world/bdf3.rs): BDF2 and TR-BDF2 are second
//! order on a free 3D swing with twist (backward Euler first), TR-BDF2 keeps the energy of an
//! undamped swing better than backward Euler, and the 3D lift gives one verdict under every
//! integrator. `cargo test --release --test suite integrator3d -- --nocapture` prints the
//! tables of docs/verification.md.

use gripsim::rod3d::rod::{angle, pos};
use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3, World3};
use gripsim::scenario::Integrator;

const G: [f64; 3] = [0.0, 0.0, -9.81];

/// A cantilever along +x (8 nodes, 10 cm, 10 × 5 mm section, E = 1 MPa), clamped at edge 0,
/// under gravity along −z, set swinging out of its plane (the tip moving along +y) and
/// twisting (every free edge angle turning at 20 rad/s times its distance along the rod).
fn swing(integrator: Integrator) -> World3 {
    let n = 8;
    let points = (0..n)
        .map(|i| [0.1 * i as f64 / (n - 1) as f64, 0.0, 0.0])
        .collect();
    let spec = Rod3Spec {
        points,
        director: [0.0, 0.0, 1.0],
        rest_theta: Vec::new(),
        section: Section3::Rect { b: 0.01, h: 0.005 },
        youngs_modulus: 1e6,
        shear_modulus: 1e6 / 3.0,
        density: 1000.0,
    };
    let mut sim = Sim3::new(Rod3::new(&spec));
    sim.clamp_edge(0);
    for i in 2..n {
        let s = i as f64 / (n - 1) as f64;
        sim.v[pos(i) + 1] = 0.3 * s * s;
        if i < n - 1 {
            sim.v[angle(i)] = 20.0 * s;
        }
    }
    let mut w = World3::new(G);
    w.force_tol = 1e-12;
    w.step_tol = 1e-16;
    w.integrator = integrator;
    w.add_rod("rod", sim, Section3::Rect { b: 0.01, h: 0.005 });
    w
}

/// The rod's DOFs after `t_end` at step `dt`.
fn run(integrator: Integrator, dt: f64, t_end: f64) -> Vec<f64> {
    let mut w = swing(integrator);
    let steps = (t_end / dt).round() as usize;
    for _ in 0..steps {
        w.step(dt)
            .unwrap_or_else(|e| panic!("{integrator:?} dt {dt}: {e}"));
    }
    assert!((w.time - t_end).abs() < 1e-9 * t_end, "{}", w.time);
    w.rods[0].q.clone()
}

/// Largest difference of the positions (m) and of the edge angles (rad).
fn errors(q: &[f64], r: &[f64]) -> (f64, f64) {
    let (mut ex, mut eth) = (0.0f64, 0.0f64);
    for (k, (a, b)) in q.iter().zip(r).enumerate() {
        if k % 4 == 3 {
            eth = eth.max((a - b).abs());
        } else {
            ex = ex.max((a - b).abs());
        }
    }
    (ex, eth)
}

/// Errors at t = 0.05 s for dt = 1e-4 / 5e-5 / 2.5e-5 / 1.25e-5 against the run at
/// 1.25e-5 / 16, and the observed orders log₂(e(dt)/e(dt/2)) of positions and angles.
fn order(integrator: Integrator) -> Vec<(f64, f64, f64, f64, f64)> {
    let (t_end, dt0) = (0.05, 1e-4);
    let reference = run(integrator, dt0 / 8.0 / 16.0, t_end);
    let mut rows: Vec<(f64, f64, f64, f64, f64)> = Vec::new();
    for k in 0..4 {
        let dt = dt0 / f64::from(1 << k);
        let (ex, eth) = errors(&run(integrator, dt, t_end), &reference);
        let (px, pth) = match rows.last() {
            Some(&(_, x0, t0, _, _)) => ((x0 / ex).log2(), (t0 / eth).log2()),
            None => (f64::NAN, f64::NAN),
        };
        rows.push((dt, ex, eth, px, pth));
    }
    println!("{integrator:?}: dt, position error (m), angle error (rad), observed orders");
    for (dt, ex, eth, px, pth) in &rows {
        println!("  {dt:.3e}  {ex:.3e}  {eth:.3e}  {px:.2}  {pth:.2}");
    }
    rows
}

#[test]
fn tr_bdf2_and_bdf2_are_second_order_on_a_twisting_3d_swing() {
    let tables = [Integrator::TrBdf2, Integrator::Bdf2].map(|i| (i, order(i)));
    let rows = order(Integrator::BackwardEuler);
    for (integrator, rows) in tables {
        for &(dt, ex, eth, px, pth) in &rows[1..] {
            assert!(
                (1.8..=2.2).contains(&px),
                "{integrator:?} dt {dt}: x order {px} ({ex})"
            );
            assert!(
                (1.8..=2.2).contains(&pth),
                "{integrator:?} dt {dt}: θ order {pth} ({eth})"
            );
        }
    }
    for &(dt, ex, eth, px, pth) in &rows[1..] {
        assert!(
            (0.75..=1.25).contains(&px),
            "backward Euler dt {dt}: x order {px} ({ex})"
        );
        assert!(
            (0.75..=1.25).contains(&pth),
            "backward Euler dt {dt}: θ order {pth} ({eth})"
        );
    }
}

/// Kinetic + elastic + gravitational energy of the world's one rod (J).
fn energy(w: &World3) -> f64 {
    let sim = &w.rods[0];
    let gravity: f64 = (0..sim.rod.n)
        .map(|i| -sim.rod.mass[pos(i) + 2] * G[2] * sim.q[pos(i) + 2])
        .sum();
    sim.kinetic_energy() + sim.elastic_energy(&sim.q) + gravity
}

/// The energy lost over 0.3 s of the undamped swing at dt = 1e-3 (J), and the energy at the
/// start.
fn energy_loss(integrator: Integrator) -> (f64, f64) {
    let mut w = swing(integrator);
    let e0 = energy(&w);
    for _ in 0..300 {
        w.step(1e-3)
            .unwrap_or_else(|e| panic!("{integrator:?}: {e}"));
    }
    (e0 - energy(&w), e0)
}

#[test]
fn tr_bdf2_keeps_the_energy_of_an_undamped_3d_swing_better_than_backward_euler() {
    let (be, e0) = energy_loss(Integrator::BackwardEuler);
    let (bdf2, _) = energy_loss(Integrator::Bdf2);
    let (tr, _) = energy_loss(Integrator::TrBdf2);
    println!(
        "energy lost over 0.3 s at dt = 1e-3 (of {e0:.4e} J): backward Euler {be:.4e} J, \
         BDF2 {bdf2:.4e} J, TR-BDF2 {tr:.4e} J"
    );
    assert!(be > 0.0 && tr.abs() < 0.01 * be, "BE {be}, TR-BDF2 {tr}");
    assert!(bdf2.abs() < 0.05 * be, "BE {be}, BDF2 {bdf2}");
}

/// The 3D lift's summary under `integrator`.
fn lift(integrator: &str) -> serde_json::Value {
    let d = tempfile::tempdir().unwrap();
    let json = d.path().join("s.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gripsim"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["run", "scenarios/3d-lift.toml", "--no-record", "--summary"])
        .arg(&json)
        .args(["--set", &format!("solve.integrator=\"{integrator}\"")])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{integrator}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

#[test]
fn the_3d_lift_is_held_under_every_integrator() {
    let be = lift("backward_euler");
    let z0 = be["grasp"]["final_position_m"][2].as_f64().unwrap();
    for integrator in ["backward_euler", "bdf2", "tr_bdf2"] {
        let v = if integrator == "backward_euler" {
            be.clone()
        } else {
            lift(integrator)
        };
        let g = &v["grasp"];
        let z = g["final_position_m"][2].as_f64().unwrap();
        let margin = g["safety_margin_at_lift"].as_f64().unwrap();
        println!(
            "{integrator}: {} steps, {} Newton iterations, verdict {}, final z {z:.5} m, \
             margin at the lift {margin:.3}, max slip {} m",
            v["steps"], v["newton_iterations"], g["verdict"], g["max_slip_m"]
        );
        assert_eq!(g["verdict"], "held", "{integrator}: {g}");
        assert!((z - z0).abs() < 1e-4, "{integrator}: z {z} against {z0}");
        assert!((margin - 4.02).abs() < 0.1, "{integrator}: margin {margin}");
    }
}

#[test]
fn a_3d_file_refuses_the_planar_step_size_keys_by_name() {
    let cases = [
        (
            "solve.stepping=\"adaptive\"",
            "solve.stepping",
            "fixed steps",
        ),
        ("solve.rtol=1e-3", "solve.rtol", "fixed steps"),
        (
            "solve.time_of_impact=true",
            "solve.time_of_impact",
            "fixed steps",
        ),
        ("solve.dt_max=1e-3", "solve.dt_max", "fixed steps"),
        (
            "solve.integrator=\"bdf3\"",
            "solve.integrator",
            "did you mean \"bdf2\"",
        ),
    ];
    for (set, key, says) in cases {
        let d = tempfile::tempdir().unwrap();
        let json = d.path().join("s.json");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_gripsim"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["run", "scenarios/3d-lift.toml", "--no-record", "--summary"])
            .arg(&json)
            .args(["--set", set])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{set}: {err}");
        assert!(err.contains("scenarios/3d-lift.toml"), "{err}");
        assert!(err.contains(&format!("key `{key}`")), "{err}");
        assert!(err.contains(says), "{err}");
        assert!(!json.exists(), "{set}: nothing written");
    }
}
