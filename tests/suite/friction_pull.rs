//! One Coulomb decision in 2D and 3D (`contact::friction::decide_cone`): a contact whose
//! normal reaction pulls (n·R < 0) carries no friction. A stuck contact that pulls slides
//! first and is released if it still pulls; one caught again in the same step after it was
//! released for pulling slides (frictionless) for the rest of that step.
//!
//! The case of issue 33: a 0.1 kg sphere lifted by two stiff straight prongs at a safety margin
//! of 1.5, then the grip relaxed below the friction limit. Coulomb says it slides out and falls;
//! the 3D solver used to hang it on two contacts whose normal reaction pulled (n·R ≈ −0.02 N)
//! while each carried half its weight (0.49 N) of friction, released and caught again every
//! step. The planar analogue relaxes jaw-grasp-hold's jaws after the lift.

use gripsim::events::{Event, Observer};
use gripsim::rod3d::events::{Event3, Observer3};
use gripsim::scenario::three::Scenario3;
use gripsim::{Scenario, Simulation};

/// The issue's scenario: 3d-lift with 11-node straight steel-stiff prongs (E 5 GPa), a 4 cm
/// sphere of 0.1 kg, μ_s = μ_k = 0.6, closed to margin 1.5, lifted 5 cm, then opened by
/// `RELAX` (m) over 0.2 s.
const RELAXED_3D: &str = r#"
name = "3d-relaxed-grip"
dimension = 3
[solve]
dt = 0.002
t_end = 2.654
gravity = [0.0, 0.0, -9.81]
[prong]
nodes = 11
shape = { kind = "straight", length = 0.1 }
E = 5e9
nu = 0.5
density = 5000.0
section = { kind = "rect", b = 0.02, h = 0.01 }
clamped_edges = 1
loss_factor = 0.1
[gripper]
kind = "parallel"
radius = 0.0405
centre = [0.0, 0.0, 0.02]
[contact]
surface = "centreline"
[friction]
mu_s = 0.6
mu_k = 0.6
[fruit]
shape = { kind = "sphere", radius = 0.04 }
centre = [0.0, 0.0, -0.06]
density = 373.02
[[obstacle]]
shape = { kind = "plane" }
at = [0.0, 0.0, -0.1]
normal = [0.0, 0.0, 1.0]
[[move]]
kind = "close"
travel = 0.0005205984391147259
duration = 0.054
[[move]]
kind = "hold"
duration = 0.2
[[move]]
kind = "lift"
height = 0.05
duration = 1.0
[[move]]
kind = "hold"
duration = 0.2
[[move]]
kind = "close"
travel = RELAX
duration = 0.2
[[move]]
kind = "hold"
duration = 2.0
"#;

/// Largest friction on a contact whose normal reaction pulls, over every step.
#[derive(Default)]
struct Pulls {
    steps: u64,
    /// Contact-steps with n·R < 0, and the largest |R_t| among them (N).
    pulling: u64,
    max_friction: f64,
    /// The most negative n·R seen (N).
    min_normal: f64,
    /// The fruit's highest and last height (m).
    top: f64,
    last: f64,
    /// When the fruit first hung 5 mm below its highest point (s).
    fell_at: Option<f64>,
}

impl Pulls {
    fn contact(&mut self, rn: f64, rt: f64) {
        if rn < 0.0 {
            self.pulling += 1;
            self.max_friction = self.max_friction.max(rt.abs());
            self.min_normal = self.min_normal.min(rn);
        }
    }
    fn fruit(&mut self, t: f64, height: f64) {
        if self.steps == 0 {
            self.top = height;
        }
        self.steps += 1;
        self.top = self.top.max(height);
        self.last = height;
        if height < self.top - 0.005 {
            self.fell_at.get_or_insert(t);
        }
    }
}

impl Observer3 for Pulls {
    fn on_event(&mut self, e: &Event3<'_>) {
        if let Event3::Step {
            time,
            contacts,
            bodies,
            ..
        } = e
        {
            for c in *contacts {
                let f = c.friction;
                self.contact(c.normal_reaction, f[0].hypot(f[1]).hypot(f[2]));
            }
            self.fruit(*time, bodies[0].position[2]);
        }
    }
}

impl Observer for Pulls {
    fn on_event(&mut self, e: &Event<'_>) {
        if let Event::StepEnd {
            t,
            contacts,
            bodies,
            ..
        } = e
        {
            for c in *contacts {
                self.contact(c.normal_force, c.friction_force);
            }
            self.fruit(*t, bodies[0].position[1]);
        }
    }
}

/// A pulling contact's friction may be the Newton residual's size, no more (N).
const NO_FRICTION: f64 = 1e-6;

fn run_3d(relax: f64) -> (gripsim::rod3d::run3::Summary3, Pulls) {
    let text = RELAXED_3D.replace("RELAX", &format!("{relax:e}"));
    let sc = Scenario3::from_str(&text, "3d-relaxed-grip", std::path::Path::new(".")).unwrap();
    let mut p = Pulls::default();
    let s = gripsim::rod3d::run3::run_observed(&sc, None, &mut p).unwrap();
    (s, p)
}

#[test]
fn a_3d_sphere_whose_grip_is_relaxed_below_the_friction_limit_falls() {
    // The issue's relaxation (margin 0.9) and three more below the limit.
    for relax in [-8.238975645890288e-06, -8.0e-6, -8.5e-6, -1.2e-5] {
        let (s, p) = run_3d(relax);
        let z = s.fruit_end.unwrap()[2];
        println!(
            "relax {relax:e} m: fruit lifted to z = {:.5} m, 5 mm lower at t = {:?} s, ends at \
             z = {z:.6} m; contacts released {}, switches {}; {} pulling contact-steps, \
             n·R ≥ {:.3e} N, their friction ≤ {:.3e} N; finger forces {:?}",
            p.top,
            p.fell_at,
            s.contacts_released,
            s.friction_switches,
            p.pulling,
            p.min_normal,
            p.max_friction,
            s.finger_forces
        );
        assert!(p.top > -0.0105, "relax {relax:e}: lifted only to {}", p.top);
        assert!(
            (z + 0.06).abs() < 1e-4,
            "relax {relax:e}: the sphere must fall to the table (z = -0.06), ends at {z}"
        );
        assert!(
            p.max_friction <= NO_FRICTION,
            "relax {relax:e}: a pulling contact carries {} N of friction",
            p.max_friction
        );
        assert!(
            s.contacts_released <= 20,
            "relax {relax:e}: {} contacts released",
            s.contacts_released
        );
    }
}

#[test]
fn a_3d_sphere_whose_grip_is_relaxed_above_the_friction_limit_stays_held() {
    // Opened by half as much: margin ≈ 1.2, held where the lift left it.
    let (s, p) = run_3d(-4.0e-6);
    let z = s.fruit_end.unwrap()[2];
    println!(
        "relax -4e-6 m: fruit at z = {z:.6} m (top {:.6}); released {}; pulling contact-steps {}",
        p.top, s.contacts_released, p.pulling
    );
    assert!((z - p.top).abs() < 1e-3, "held at {} from {}", z, p.top);
    assert!(p.max_friction <= NO_FRICTION);
}

/// Run a planar scenario given as text, watching its contacts.
fn run_planar(text: &str, name: &str) -> Pulls {
    let sc = Scenario::from_str(text, name, &[]).unwrap();
    let mut sim = Simulation::new(&sc);
    let mut p = Pulls::default();
    sim.run(&mut p).unwrap();
    println!(
        "{name}: fruit's top y = {:.5} m, 5 mm lower at t = {:?} s, ends at y = {:.6} m; \
         {} pulling contact-steps, n·R ≥ {:.3e} N, their friction ≤ {:.3e} N",
        p.top, p.fell_at, p.last, p.pulling, p.min_normal, p.max_friction
    );
    p
}

#[test]
fn a_planar_fruit_whose_jaws_relax_below_the_friction_limit_falls() {
    let text = std::fs::read_to_string(crate::common::scenario("jaw-grasp-hold")).unwrap();
    // After the lift (it ends at 0.954 s): hold, open each jaw by 0.7 mm (the grip falls from
    // 1.14 N to about 0.71 N a jaw: margin 0.87), hold.
    let text = text.replace("t_end = 0.9\n", "t_end = 1.4\n")
        + r#"
[[actuator.phase]]
name = "hold"
kind = "hold"
end = { duration = 0.05 }
[[actuator.phase]]
name = "relax"
kind = "translate"
direction = [1.0, 0.0]
law = "s_curve"
distance = 0.0007
duration = 0.1
[[actuator.phase]]
name = "hang"
kind = "hold"
"#;
    let p = run_planar(&text, "jaw-relaxed");
    assert!(p.top > -0.021, "lifted only to {}", p.top);
    assert!((p.last + 0.06).abs() < 1e-4, "ends at {}", p.last);
    assert!(p.max_friction <= NO_FRICTION, "{}", p.max_friction);
    // The fruit that slides out of the jaws during the lift (μ_s 0.4, margin 0.91).
    let text = std::fs::read_to_string(crate::common::scenario("jaw-grasp-drop")).unwrap();
    let p = run_planar(&text, "jaw-grasp-drop");
    assert!((p.last + 0.06).abs() < 1e-4, "ends at {}", p.last);
    assert!(p.max_friction <= NO_FRICTION, "{}", p.max_friction);
}
