//! Step-size strategies: adaptive error control, time of impact, and which contact force
//! converges under dt refinement.

use gripsim::events::{Event, Observer};
use gripsim::record::summary::{Summary, SummaryCollector};
use gripsim::{Scenario, Simulation};

const DROP: &str = r#"
name = "drop"
[solve]
t_end = 0.15
dt = 1e-4
gravity = [0.0, -9.8]
[[particle]]
name = "ball"
position = [0.0, 0.05]
mass = 0.01
[[obstacle]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"#;

fn run(text: &str, sets: &[&str]) -> (Simulation, Summary) {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let sc = Scenario::from_str(text, "t.toml", &sets).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&sc);
    let mut col = SummaryCollector::new();
    sim.run(&mut col).unwrap_or_else(|e| panic!("{e}"));
    let s = col.finish(&sim.stats, 0.0);
    (sim, s)
}

/// Free flight has a known exact step: from (y, v) over dt, y + v dt − ½ g dt². Every accepted
/// adaptive step's true local error must be within the tolerance atol + rtol·L (L = 1 m for a
/// particle).
#[test]
fn adaptive_steps_meet_their_local_tolerance_in_free_flight() {
    struct Local {
        prev: Option<(f64, f64)>,
        worst: f64,
        steps: u32,
    }
    impl Observer for Local {
        fn on_event(&mut self, e: &Event<'_>) {
            if let Event::StepEnd { dt, rods, .. } = e {
                let (y, v) = (rods[0].q[1], rods[0].u[1]);
                if let (Some((y0, v0)), true) = (self.prev, *dt > 0.0) {
                    if !rods[0].in_contact[0] {
                        let exact = y0 + v0 * dt - 0.5 * 9.8 * dt * dt;
                        self.worst = self.worst.max((y - exact).abs());
                        self.steps += 1;
                    }
                }
                self.prev = Some((y, v));
            }
        }
    }
    for rtol in [1e-4, 1e-6, 1e-8] {
        let text = DROP.replace("t_end = 0.15", "t_end = 0.09");
        let sets = [
            "solve.stepping=\"adaptive\"".to_string(),
            format!("solve.rtol={rtol:e}"),
            "solve.atol=1e-12".to_string(),
        ];
        let sc = Scenario::from_str(&text, "t.toml", &sets).unwrap();
        let mut sim = Simulation::new(&sc);
        let mut l = Local {
            prev: None,
            worst: 0.0,
            steps: 0,
        };
        sim.run(&mut l).unwrap();
        let tol = 1e-12 + rtol * 1.0;
        println!(
            "free flight rtol={rtol:e}: {} steps, worst local error {:.3e} m (tolerance {tol:.1e})",
            l.steps, l.worst
        );
        assert!(l.steps > 3);
        assert!(
            l.worst <= tol * (1.0 + 1e-6),
            "rtol {rtol}: local error {} > {tol}",
            l.worst
        );
    }
}

const CANTILEVER: &str = r#"
name = "cantilever"
[solve]
t_end = 0.1
dt = 1e-5
gravity = [0.0, -9.81]
[[rod]]
name = "beam"
nodes = 20
shape = { kind = "straight", start = [-0.0027027027027027, 0.0], end = [0.1, 0.0] }
E = 1e6
section = { kind = "rect", b = 0.02, h = 0.01 }
density = 1000.0
clamped = [0, 1]
"#;

fn tip(sim: &Simulation) -> [f64; 2] {
    let q = sim.positions(0);
    let n = q.len() / 2;
    [q[2 * n - 2], q[2 * n - 1]]
}

/// A cantilever falling under gravity: the adaptive error against a fine fixed-step reference
/// falls with the tolerance, costs fewer steps than the fixed run of the same accuracy, and the
/// tip error stays within the accumulated local tolerance (steps × (atol + rtol L)).
#[test]
fn adaptive_cantilever_error_follows_the_tolerance() {
    let (reference, _) = run(CANTILEVER, &["solve.dt=1e-6"]);
    let want = tip(&reference);
    let mut last_err = f64::INFINITY;
    let mut last_steps = 0;
    for rtol in [1e-4, 1e-5, 1e-6] {
        let rt = format!("solve.rtol={rtol:e}");
        let (sim, s) = run(
            CANTILEVER,
            &["solve.stepping=\"adaptive\"", &rt, "solve.dt=1e-4"],
        );
        let got = tip(&sim);
        let err = (got[0] - want[0]).hypot(got[1] - want[1]);
        let budget = s.steps as f64 * (1e-9 + rtol * 0.1);
        println!("cantilever adaptive rtol={rtol:e}: {} steps, tip error {err:.3e} m (accumulated tolerance {budget:.3e})", s.steps);
        assert!(err < last_err, "error must fall with rtol");
        assert!(s.steps > last_steps, "steps must grow as rtol falls");
        // The estimate sees backward Euler's leading term only; the elastic oscillation adds
        // error it does not see, so the bound holds within a factor of 3.
        assert!(
            err <= 3.0 * budget,
            "tip error {err} exceeds 3x the accumulated tolerance {budget}"
        );
        last_err = err;
        last_steps = s.steps;
    }
}

/// With time of impact on, the step that starts the contact ends on the plane (within 1e-9 m)
/// at the crossing time of the discrete trajectory; under adaptive stepping that time approaches
/// the analytic √(2H/g) with the tolerance.
#[test]
fn time_of_impact_lands_the_point_mass_on_the_plane() {
    /// The first step that ends with the ball on the plane (|y| ≤ 1e-9 m) or in contact.
    struct Onset {
        at: Option<(f64, f64)>,
        steps: u32,
    }
    impl Observer for Onset {
        fn on_event(&mut self, e: &Event<'_>) {
            if let Event::StepEnd { t, rods, .. } = e {
                if self.at.is_none() {
                    self.steps += 1;
                    if rods[0].in_contact[0] || rods[0].q[1].abs() <= 1e-9 {
                        self.at = Some((*t, rods[0].q[1]));
                    }
                }
            }
        }
    }
    let t_exact = (2.0 * 0.05 / 9.8f64).sqrt();
    let v = (2.0 * 9.8 * 0.05f64).sqrt();
    // Fixed steps: backward Euler's fall runs ahead of the parabola by g t dt/2, so the crossing
    // is early by at most dt/2. Adaptive: the position error is at most the accumulated local
    // tolerance, steps × (atol + rtol·1 m), which shifts the crossing by that over v.
    let adaptive = |rtol: &'static str| {
        vec![
            "solve.time_of_impact=true",
            "solve.stepping=\"adaptive\"",
            rtol,
            "solve.atol=1e-12",
        ]
    };
    for (sets, fixed_dt, local_tol) in [
        (vec!["solve.time_of_impact=true"], 1e-4, 0.0),
        (
            vec!["solve.time_of_impact=true", "solve.dt=1e-5"],
            1e-5,
            0.0,
        ),
        (adaptive("solve.rtol=1e-6"), 0.0, 1e-6),
        (adaptive("solve.rtol=1e-8"), 0.0, 1e-8),
    ] {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let sc = Scenario::from_str(DROP, "t.toml", &sets).unwrap();
        let mut sim = Simulation::new(&sc);
        let mut o = Onset { at: None, steps: 0 };
        sim.run(&mut o).unwrap();
        let (t, y) = o.at.expect("contact");
        let tol = if fixed_dt > 0.0 {
            fixed_dt / 2.0
        } else {
            o.steps as f64 * local_tol / v
        };
        println!("{sets:?}: contact at t = {t:.9} s (analytic {t_exact:.9}, tolerance {tol:.2e} s), y = {y:.3e} m");
        assert!(y.abs() <= 1e-9, "{sets:?}: lands {y} m from the plane");
        assert!(
            (t - t_exact).abs() <= tol,
            "{sets:?}: contact at {t}, analytic {t_exact}, tolerance {tol}"
        );
    }
    // Without time of impact the contact step ends wherever the step grid puts it.
    let (_, s) = run(DROP, &[]);
    assert!(s.contact_onset_time_s.unwrap() > t_exact - 1e-4);
}

/// Eq. 2's reaction at impact is a momentum change over one step, so its peak grows like 1/dt;
/// the impulse-consistent force (contact impulse over a fixed 1 ms window) converges at first
/// order to m v/τ + m g.
#[test]
fn impulse_consistent_force_converges_while_eq2_peak_grows_like_one_over_dt() {
    let (m, g, h, tau) = (0.01, 9.8f64, 0.05, 1e-3);
    let limit = m * (2.0 * g * h).sqrt() / tau + m * g;
    let mut prev_err = f64::INFINITY;
    for dt in [1e-3, 1e-4, 1e-5, 1e-6] {
        let d = format!("solve.dt={dt:e}");
        let (_, s) = run(DROP, &[&d, "solve.time_of_impact=true"]);
        let err = (s.peak_impulse_consistent_force_n - limit).abs();
        let eq2_dt = s.peak_reaction_force_n * dt;
        println!(
            "dt={dt:e}: eq. 2 peak {:.1} N (x dt = {eq2_dt:.6} N s), impulse-consistent {:.6} N (error {err:.3e} N)",
            s.peak_reaction_force_n, s.peak_impulse_consistent_force_n
        );
        // Eq. 2 peak × dt is the impact momentum m v: the peak itself ∝ 1/dt.
        assert!((eq2_dt - m * (2.0 * g * h).sqrt()).abs() < 0.01 * m * (2.0 * g * h).sqrt());
        // First order: the error falls about tenfold per tenfold refinement.
        if prev_err.is_finite() {
            let ratio = prev_err / err;
            assert!(ratio > 6.0 && ratio < 16.0, "dt={dt}: error ratio {ratio}");
        }
        prev_err = err;
    }
}
