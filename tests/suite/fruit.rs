//! Issue "Will it lift this apple without bruising it?": a fruit that is free *and* compliant —
//! it rests, is squeezed, lifted, slips and drops like a rigid free body, and it is pressed
//! by the law of its material (Hertz line contact), so it can bruise. Against closed forms.

use gripsim::contact::compliant::{LineContact, Material};
use gripsim::events::{ContactView, Event, Observer};
use gripsim::{Scenario, Simulation};

const G: f64 = 9.81;

fn scenario(text: &str, sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::from_str(text, "test.toml", &sets).unwrap_or_else(|e| panic!("{e}"))
}

/// A body's position, velocity, angular velocity, contact force and torque at a step.
type BodyState = ([f64; 2], [f64; 2], f64, [f64; 2], f64);

/// Every step's first body and contacts.
#[derive(Default)]
struct Trace {
    t: Vec<f64>,
    dt: Vec<f64>,
    body: Vec<BodyState>,
    contacts: Vec<Vec<ContactView>>,
}

impl Observer for Trace {
    fn on_event(&mut self, e: &Event<'_>) {
        if let Event::StepEnd {
            t,
            dt,
            bodies,
            contacts,
            ..
        } = e
        {
            self.t.push(*t);
            self.dt.push(*dt);
            if let Some(b) = bodies.first() {
                self.body.push((
                    b.position,
                    b.velocity,
                    b.angular_velocity,
                    b.contact_force,
                    b.contact_torque,
                ));
            }
            self.contacts.push(contacts.to_vec());
        }
    }
}

fn run(sc: &Scenario) -> (Simulation, Trace) {
    let mut sim = Simulation::new(sc);
    let mut tr = Trace::default();
    sim.run(&mut tr).unwrap_or_else(|e| panic!("{e}"));
    (sim, tr)
}

/// A 4 cm apple disc of 0.15 kg set down touching a rigid table.
const DISC_ON_TABLE: &str = r#"
name = "compliant-disc-on-table"
[solve]
mode = "dynamic"
t_end = 2.0
dt = 1e-4
stepping = "fixed"
gravity = [0.0, -9.81]
# The law's force is in the residual, so at rest it is m g to the Newton tolerance.
force_tol = 1e-11

[[obstacle]]
name = "table"
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]

[[obstacle]]
name = "fruit"
kind = "circle"
center = [0.0, 0.04]
radius = 0.04
free = true
mass = 0.15
material = "apple"

[friction]
mu_s = 0.5
mu_k = 0.4
"#;

#[test]
fn a_compliant_disc_rests_on_the_table_with_m_g_at_the_laws_indentation() {
    let sc = scenario(DISC_ON_TABLE, &[]);
    let m = sc.bodies[0].mass;
    let (sim, tr) = run(&sc);
    // The law of a 4 cm apple disc (depth 8 cm: a round fruit's diameter) on a rigid plane.
    let apple = Material::preset("apple").unwrap();
    let law = LineContact::new(0.04, f64::INFINITY, 0.08, 0.0, &apple);
    let (delta, _) = law.approach(m * G);
    let b = &sim.bodies[0];
    let sunk = 0.04 - b.pose.c[1];
    println!(
        "rest: centre {:?}, v {:?}, indentation {sunk:.9e} m (law {delta:.9e} m), reaction {:?}",
        b.pose.c,
        b.v,
        tr.body.last().unwrap().3
    );
    assert!(b.v[0].abs() < 1e-9 && b.v[1].abs() < 1e-9, "{:?}", b.v);
    assert!((sunk - delta).abs() < 1e-6 * delta, "{sunk:e} vs {delta:e}");
    for (_, _, _, f, tq) in tr.body.iter().rev().take(100) {
        assert!((f[1] - m * G).abs() < 1e-9 * m * G, "{f:?} vs {}", m * G);
        assert!(f[0].abs() < 1e-9 * m * G && tq.abs() < 1e-9);
    }
    let last = tr.contacts.last().unwrap();
    assert_eq!(last.len(), 1);
    let c = &last[0];
    assert!((c.indentation - delta).abs() < 1e-6 * delta, "{}", c.indentation);
    assert!((c.peak_pressure - law.peak_pressure(m * G)).abs() < 1e-6 * c.peak_pressure);
}
