//! Issue 10: Coulomb friction in the modified mass method and free rigid bodies, against the
//! closed forms of references.md (incline, resting body, momentum balance).

use gripsim::events::{ContactView, Event, Observer};
use gripsim::{Scenario, Simulation};

fn scenario(text: &str, sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::from_str(text, "test.toml", &sets).unwrap_or_else(|e| panic!("{e}"))
}

fn shipped(name: &str, sets: &[&str]) -> Scenario {
    let path = format!("{}/scenarios/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(std::path::Path::new(&path), &sets).unwrap_or_else(|e| panic!("{e}"))
}

/// A body's position, velocity, angular velocity, contact force and contact torque at a step.
type BodyState = ([f64; 2], [f64; 2], f64, [f64; 2], f64);

/// Every step's particle/body state and contacts.
#[derive(Default)]
struct Trace {
    t: Vec<f64>,
    dt: Vec<f64>,
    q0: Vec<[f64; 2]>,
    u0: Vec<[f64; 2]>,
    body: Vec<BodyState>,
    contacts: Vec<Vec<ContactView>>,
    slips: usize,
    sticks: usize,
}

impl Observer for Trace {
    fn on_event(&mut self, e: &Event<'_>) {
        match e {
            Event::StepEnd {
                t,
                dt,
                rods,
                bodies,
                contacts,
                ..
            } => {
                self.t.push(*t);
                self.dt.push(*dt);
                if let Some(r) = rods.first() {
                    self.q0.push([r.q[0], r.q[1]]);
                    self.u0.push([r.u[0], r.u[1]]);
                }
                if let Some(b) = bodies.first() {
                    self.body.push((
                        gripsim::events::xy(b.position),
                        gripsim::events::xy(b.velocity),
                        b.angular_velocity[2],
                        gripsim::events::xy(b.contact_force),
                        b.contact_torque[2],
                    ));
                }
                self.contacts.push(contacts.to_vec());
            }
            Event::FrictionChanged(f) => {
                if f.stuck {
                    self.sticks += 1
                } else {
                    self.slips += 1
                }
            }
            _ => {}
        }
    }
}

fn run(sc: &Scenario) -> (Simulation, Trace) {
    let mut sim = Simulation::new(sc);
    let mut tr = Trace::default();
    sim.run(&mut tr).unwrap_or_else(|e| panic!("{e}"));
    (sim, tr)
}

const G: f64 = 9.81;

/// A particle on a plane inclined at θ through the origin, released from rest on it.
fn incline(theta_deg: f64, mu_s: f64, mu_k: f64) -> Scenario {
    let th = theta_deg.to_radians();
    scenario(
        &format!(
            r#"
name = "incline"
[solve]
t_end = 0.1
dt = 1e-4
gravity = [0.0, -{G}]
[[particle]]
name = "block"
position = [0.0, 0.0]
mass = 0.05
[[obstacle]]
kind = "plane"
point = [0.0, 0.0]
normal = [{nx:e}, {ny:e}]
[friction]
mu_s = {mu_s}
mu_k = {mu_k}
"#,
            nx = -th.sin(),
            ny = th.cos()
        ),
        &[],
    )
}

#[test]
fn incline_stick_below_the_friction_angle() {
    // tan 30° = 0.5774 < mu_s: the block must not move.
    for (theta, mu_s) in [(30.0, 0.6), (20.0, 0.4), (10.0, 0.18)] {
        let th: f64 = f64::to_radians(theta);
        assert!(th.tan() < mu_s);
        let (_, tr) = run(&incline(theta, mu_s, 0.8 * mu_s));
        let moved = tr.q0.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max);
        println!(
            "θ = {theta}°, μs = {mu_s}: largest displacement {moved:.3e} m, {} stick→slip",
            tr.slips
        );
        assert!(moved < 1e-12, "θ = {theta}: moved {moved:e} m");
        assert_eq!(tr.slips, 0);
        // Every step: the block is stuck with |R_t|/R_n = tan θ exactly.
        for cs in tr.contacts.iter().skip(1) {
            let c = &cs[0];
            assert!(c.stuck);
            let ratio = c.friction_force.abs() / c.normal_force;
            assert!(
                (ratio - th.tan()).abs() < 1e-9 * th.tan(),
                "{ratio} vs {}",
                th.tan()
            );
        }
    }
}

#[test]
fn incline_slides_with_the_kinetic_acceleration() {
    for (theta, mu_s, mu_k) in [(30.0, 0.4, 0.3), (45.0, 0.5, 0.2), (20.0, 0.3, 0.1)] {
        let th: f64 = f64::to_radians(theta);
        assert!(th.tan() > mu_s);
        let expect = G * (th.sin() - mu_k * th.cos());
        let (_, tr) = run(&incline(theta, mu_s, mu_k));
        // Acceleration along the slope from the velocity increments (backward Euler is exact
        // for a constant force).
        let down = [-th.cos(), -th.sin()];
        let speed: Vec<f64> = tr
            .u0
            .iter()
            .map(|u| u[0] * down[0] + u[1] * down[1])
            .collect();
        let n = speed.len();
        let mut worst = 0.0f64;
        for k in 2..n {
            let a = (speed[k] - speed[k - 1]) / tr.dt[k];
            worst = worst.max(((a - expect) / expect).abs());
        }
        let a_mean = speed[n - 1] / tr.t[n - 1];
        println!("θ = {theta}°: a = {a_mean:.9} m/s² vs g(sinθ − μk cosθ) = {expect:.9}, worst step rel. error {worst:.2e}");
        assert!(worst < 1e-6, "θ = {theta}: rel. error {worst:e}");
        assert!(((a_mean - expect) / expect).abs() < 1e-6);
        assert!(tr.slips >= 1);
        // The block stays on the plane.
        let n_ = [-th.sin(), th.cos()];
        for q in &tr.q0 {
            assert!((q[0] * n_[0] + q[1] * n_[1]).abs() < 1e-12);
        }
    }
}

#[test]
fn incline_frictionless_is_the_old_solver() {
    // μ = 0 explicitly and no [friction] at all: bit-identical runs.
    let with = incline(30.0, 0.0, 0.0);
    let mut without = with.clone();
    without.friction = Default::default();
    let (a, _) = run(&with);
    let (b, _) = run(&without);
    assert_eq!(a.positions(0), b.positions(0));
    assert_eq!(a.velocities(0), b.velocities(0));
    let expect = G * 0.5;
    let v = a.velocities(0);
    let speed = v[0].hypot(v[1]);
    assert!((speed / 0.1 - expect).abs() < 1e-9 * expect);
}

#[test]
fn fruit_dropped_on_a_table_rests_with_reaction_mg() {
    let sc = shipped("fruit-on-table", &[]);
    let m = sc.bodies[0].mass;
    let (sim, tr) = run(&sc);
    let b = &sim.bodies[0];
    println!(
        "final centre {:?}, v {:?}, ω {:e}, table reaction {:?}",
        b.pose.c,
        b.v,
        b.v[2],
        tr.body.last().unwrap().3
    );
    // At rest on the table: the centre one radius above it, no motion.
    assert!((b.pose.c[1] - 0.04).abs() < 1e-12, "{:?}", b.pose.c);
    assert!(
        b.v[0].abs() < 1e-9 && b.v[1].abs() < 1e-9 && b.v[2].abs() < 1e-7,
        "{:?}",
        b.v
    );
    // The last 100 steps: the table's reaction is m g every step.
    for (_, _, _, f, tq) in tr.body.iter().rev().take(100) {
        assert!(
            (f[1] - m * G).abs() < 1e-9 * m * G,
            "reaction {f:?} vs m g = {}",
            m * G
        );
        assert!(f[0].abs() < 1e-9 * m * G && tq.abs() < 1e-9);
    }
    // It slid after landing (kinetic friction), then stuck.
    assert!(tr.slips >= 1, "the landing must slide");
    let last = tr.contacts.last().unwrap();
    assert!(last.len() == 1 && last[0].stuck && last[0].rod == usize::MAX);
}

#[test]
fn fruit_momentum_changes_by_the_contact_and_gravity_impulses() {
    let sc = shipped("fruit-on-table", &[]);
    let m = sc.bodies[0].mass;
    let j = sc.bodies[0].inertia;
    let (_, tr) = run(&sc);
    // Over windows of every length from the start: Δ(m v) = Σ F dt + m g t, Δ(J ω) = Σ τ dt.
    let (mut px, mut py, mut l) = (0.0, 0.0, 0.0);
    let v0 = tr.body[0].1;
    let w0 = tr.body[0].2;
    let mut worst = 0.0f64;
    for k in 1..tr.body.len() {
        let (_, v, w, f, tq) = tr.body[k];
        let dt = tr.dt[k];
        px += f[0] * dt;
        py += (f[1] - m * G) * dt;
        l += tq * dt;
        let scale = m * G * tr.t[k];
        let ex = (m * (v[0] - v0[0]) - px).abs() / scale;
        let ey = (m * (v[1] - v0[1]) - py).abs() / scale;
        let er = (j * (w - w0) - l).abs() / (scale * 0.04);
        worst = worst.max(ex).max(ey).max(er);
    }
    println!("momentum balance: worst relative error {worst:.2e}");
    assert!(worst < 1e-9, "{worst:e}");
}

#[test]
fn free_body_mass_keys_set_mass_inertia_and_hold_tolerance() {
    let r: f64 = 0.04;
    let path = format!(
        "{}/scenarios/fruit-on-table.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).unwrap();
    assert_eq!(text.matches("mass = 0.15\n").count(), 1);
    // mass = density × area × depth; inertia of a disc m r²/2; hold tolerance 10 % of r.
    let sc = scenario(
        &text.replace("mass = 0.15\n", "density = 900.0\ndepth = 0.03\n"),
        &[],
    );
    let b = &sc.bodies[0];
    let m = 900.0 * std::f64::consts::PI * r * r * 0.03;
    assert!((b.mass - m).abs() < 1e-12 * m, "{} vs {m}", b.mass);
    assert!((b.inertia - m * r * r / 2.0).abs() < 1e-12 * b.inertia);
    assert!((b.hold_tolerance - 0.1 * r).abs() < 1e-15);
    // An inertia override changes how the landing spin decays and where the fruit stops.
    let stiff = shipped(
        "fruit-on-table",
        &["obstacle.1.inertia=1e-3", "obstacle.1.hold_tolerance=0.001"],
    );
    assert_eq!(stiff.bodies[0].inertia, 1e-3);
    assert_eq!(stiff.bodies[0].hold_tolerance, 0.001);
    let (a, _) = run(&shipped("fruit-on-table", &[]));
    let (b2, _) = run(&stiff);
    let d = (a.bodies[0].pose.c[0] - b2.bodies[0].pose.c[0]).abs();
    println!("rest position moves by {d:.3e} m with the inertia override");
    assert!(d > 1e-6);
}
