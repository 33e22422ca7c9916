//! The dim-tagged event contract (src/events.rs): a planar run says dimension 2 and fills
//! every 3-vector's z with 0, a contact serialises as many components as its run has, and a
//! 3D run sends the same `Event` stream with dimension 3 (tests at the end of this file).

use gripsim::events::{ContactView, Event, Observer, Scene};
use gripsim::{Scenario, Simulation};

fn contact(dim: u8) -> ContactView {
    ContactView {
        rod: 1,
        node: 4,
        obstacle: 2,
        body: usize::MAX,
        point: [0.5, -0.25, 0.125],
        normal: [0.0, 0.6, 0.8],
        tangent: [1.0, 0.0, 0.0],
        normal_force: 2.0,
        friction_force: 0.5,
        slip_velocity: 0.0,
        stuck: true,
        utilisation: 0.5,
        mu_s: 0.5,
        indentation: 0.0,
        half_width: 0.0,
        half_width_minor: 0.0,
        peak_pressure: 0.0,
        bruise_pressure: 0.0,
        bruise_half_width: 0.0,
        segment: usize::MAX,
        weight: 0.0,
        first: usize::MAX,
        last: usize::MAX,
        dim,
    }
}

#[test]
fn a_contact_serialises_the_components_of_its_dimension() {
    let two = serde_json::to_value(contact(2)).unwrap();
    assert_eq!(two["point"], serde_json::json!([0.5, -0.25]));
    assert_eq!(two["normal"], serde_json::json!([0.0, 0.6]));
    assert_eq!(two["tangent"], serde_json::json!([1.0, 0.0]));
    assert_eq!(two["rod"], serde_json::json!(1));
    assert_eq!(two["body"], serde_json::Value::Null);
    assert_eq!(two["segment"], serde_json::Value::Null);
    assert_eq!(two["dim"], serde_json::json!(2));
    let three = serde_json::to_value(contact(3)).unwrap();
    assert_eq!(three["point"], serde_json::json!([0.5, -0.25, 0.125]));
    assert_eq!(three["normal"], serde_json::json!([0.0, 0.6, 0.8]));
    assert_eq!(three["tangent"], serde_json::json!([1.0, 0.0, 0.0]));
    assert_eq!(three["dim"], serde_json::json!(3));
}

/// What a planar run's events say about their dimension.
#[derive(Default)]
struct Dims {
    dimension: u8,
    planar_obstacles: usize,
    steps: usize,
    rod_dims: Vec<u8>,
    contacts: usize,
    bodies: usize,
    /// Largest |z| of any contact point, normal or tangent and of any body vector.
    max_z: f64,
    /// Largest |t − (−n_y, n_x, 0)| of a contact's tangent.
    tangent_error: f64,
    /// Largest |q − (0, 0, sin θ/2, cos θ/2)| of a body's rotation.
    rotation_error: f64,
    frames: usize,
    twist_stress: usize,
}

impl Observer for Dims {
    fn on_event(&mut self, e: &Event<'_>) {
        match e {
            Event::RunStart(info) => {
                self.dimension = info.dimension;
                if let Scene::Planar { obstacles } = info.scene {
                    self.planar_obstacles = obstacles.len();
                }
            }
            Event::StepEnd {
                rods,
                bodies,
                contacts,
                ..
            } => {
                self.steps += 1;
                for r in rods.iter() {
                    self.rod_dims.push(r.dim);
                    assert_eq!(r.q.len(), 2 * r.in_contact.len());
                    self.frames += usize::from(r.frames.is_some());
                    self.twist_stress += r.twist_stress.len();
                }
                for c in contacts.iter() {
                    self.contacts += 1;
                    assert_eq!(c.dim, 2);
                    for z in [c.point[2], c.normal[2], c.tangent[2]] {
                        self.max_z = self.max_z.max(z.abs());
                    }
                    let t = [-c.normal[1], c.normal[0]];
                    let d = (c.tangent[0] - t[0]).hypot(c.tangent[1] - t[1]);
                    self.tangent_error = self.tangent_error.max(d);
                }
                for b in bodies.iter() {
                    self.bodies += 1;
                    for z in [
                        b.position[2],
                        b.velocity[2],
                        b.contact_force[2],
                        b.angular_velocity[0],
                        b.angular_velocity[1],
                        b.contact_torque[0],
                        b.contact_torque[1],
                    ] {
                        self.max_z = self.max_z.max(z.abs());
                    }
                    let (s, c) = (0.5 * b.angle).sin_cos();
                    let q = b.rotation;
                    let d = [q[0], q[1], q[2] - s, q[3] - c]
                        .iter()
                        .fold(0.0f64, |m, x| m.max(x.abs()));
                    self.rotation_error = self.rotation_error.max(d);
                }
            }
            _ => {}
        }
    }
}

#[test]
fn a_planar_run_sends_dimension_2_with_z_zero() {
    let path = crate::common::scenario("jaw-grasp-hold");
    let text = std::fs::read_to_string(&path).unwrap();
    let sets = vec!["solve.t_end=0.1".to_string()];
    let sc = Scenario::from_str(&text, &path.display().to_string(), &sets).unwrap();
    let mut d = Dims::default();
    Simulation::new(&sc).run(&mut d).unwrap();
    assert_eq!(d.dimension, 2);
    assert_eq!(d.planar_obstacles, sc.obstacles.len());
    assert!(d.steps > 1000, "{}", d.steps);
    assert!(d.rod_dims.iter().all(|&k| k == 2));
    assert!(
        d.contacts > 100 && d.bodies > 1000,
        "{} {}",
        d.contacts,
        d.bodies
    );
    assert_eq!(d.max_z, 0.0);
    assert_eq!(d.tangent_error, 0.0);
    assert!(d.rotation_error < 1e-15, "{}", d.rotation_error);
    assert_eq!((d.frames, d.twist_stress), (0, 0));
}
