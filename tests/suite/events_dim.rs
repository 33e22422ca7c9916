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
        dim,
        ..ContactView::BLANK
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

mod spatial {
    use gripsim::events::{Event, Fanout, Observer, Scene};
    use gripsim::record::summary::SummaryCollector;
    use gripsim::rod3d::events::{Event3, Observer3};
    use gripsim::rod3d::run3::{run_both, Events};
    use gripsim::scenario::three::Scenario3;

    fn lift() -> Scenario3 {
        let path = crate::common::scenario("3d-lift");
        Scenario3::load(&path).unwrap_or_else(|e| panic!("{e}"))
    }

    /// What the one stream of a 3D run says, step by step.
    #[derive(Default)]
    struct Stream {
        dimension: u8,
        shapes: usize,
        steps: u64,
        /// Largest |Σ (−force on the rods at the body's contacts) + Σ (the table's force on
        /// the body) − the body's contact force| over the steps (N), and the steps the body
        /// hung in the fingers alone.
        imbalance: f64,
        held_only_by_fingers: u64,
        /// Largest total normal force of one finger on the fruit (N).
        peak_finger: f64,
        /// Largest |reaction| of a node (N).
        peak_reaction: f64,
        last_q: Vec<Vec<f64>>,
        fruit_end: [f64; 3],
        phases: Vec<usize>,
        added: u64,
        body_added: u64,
        ended: bool,
    }

    impl Observer for Stream {
        fn on_event(&mut self, e: &Event<'_>) {
            match e {
                Event::RunStart(info) => {
                    self.dimension = info.dimension;
                    if let Scene::Spatial { shapes } = info.scene {
                        self.shapes = shapes.len();
                    }
                }
                Event::StepEnd {
                    step,
                    dt,
                    rods,
                    bodies,
                    contacts,
                    ..
                } => {
                    self.steps = *step;
                    for r in rods.iter() {
                        assert_eq!((r.dim, r.q.len()), (3, 3 * r.in_contact.len()));
                        for f in r.reaction.chunks_exact(3) {
                            let m = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
                            self.peak_reaction = self.peak_reaction.max(m);
                        }
                    }
                    self.last_q = rods.iter().map(|r| r.q.to_vec()).collect();
                    let b = &bodies[0];
                    self.fruit_end = b.position;
                    let mut sum = [0.0; 3];
                    let mut fingers = vec![0.0f64; rods.len()];
                    let (mut own, mut rods_on) = (0, 0);
                    for c in contacts.iter() {
                        let f: Vec<f64> = (0..3)
                            .map(|a| c.normal_force * c.normal[a] + c.friction_force * c.tangent[a])
                            .collect();
                        if c.rod == usize::MAX && c.node == 0 {
                            own += 1;
                            (0..3).for_each(|a| sum[a] += f[a]);
                        } else if c.body == 0 {
                            rods_on += 1;
                            fingers[c.rod] += c.normal_force.max(0.0);
                            (0..3).for_each(|a| sum[a] -= f[a]);
                        }
                    }
                    self.peak_finger = fingers.iter().fold(self.peak_finger, |m, &x| m.max(x));
                    if *dt > 0.0 {
                        let d =
                            (0..3).fold(0.0f64, |m, a| m.max((sum[a] - b.contact_force[a]).abs()));
                        self.imbalance = self.imbalance.max(d);
                        self.held_only_by_fingers += u64::from(own == 0 && rods_on > 0);
                    }
                }
                Event::PhaseChanged { to, .. } => self.phases.push(to.unwrap_or(usize::MAX)),
                Event::ConstraintAdded(_) => self.added += 1,
                Event::BodyContactChanged { added: true, .. } => self.body_added += 1,
                Event::RunEnd { error, .. } => self.ended = error.is_none(),
                _ => {}
            }
        }
    }

    /// The 3D stream's last rod DOFs.
    #[derive(Default)]
    struct Dofs(Vec<Vec<f64>>);

    impl Observer3 for Dofs {
        fn on_event(&mut self, e: &Event3<'_>) {
            if let Event3::Step { rods, .. } = e {
                self.0 = rods.iter().map(|r| r.q.to_vec()).collect();
            }
        }
    }

    #[test]
    fn a_3d_lift_sends_the_one_stream_balanced_at_every_step() {
        let sc = lift();
        let (mut stream, mut summary, mut dofs) =
            (Stream::default(), SummaryCollector::new(), Dofs::default());
        let mut fan = Fanout::new();
        fan.push(&mut stream);
        fan.push(&mut summary);
        let mut events = Events {
            text: "",
            obs: &mut fan,
        };
        let s3 = run_both(&sc, None, &mut dofs, &mut events, &|| false).unwrap();
        eprintln!(
            "3d-lift: {} steps, imbalance {:e} N, {} steps in the fingers alone, peak finger {} N, peak reaction {} N",
            stream.steps, stream.imbalance, stream.held_only_by_fingers, stream.peak_finger, stream.peak_reaction
        );
        assert_eq!(stream.dimension, 3);
        assert_eq!(stream.shapes, 2, "the table and the fruit");
        assert!(stream.ended);
        assert_eq!(stream.steps, s3.steps);
        assert_eq!(stream.steps, 17749);
        // Momentum: what the fingers and the table give the fruit is what its own equations
        // of motion say it got, at every step; for most of them it hangs in the fingers.
        assert!(
            stream.imbalance < 1e-9,
            "imbalance {:e} N",
            stream.imbalance
        );
        assert!(
            stream.held_only_by_fingers > 2500,
            "{}",
            stream.held_only_by_fingers
        );
        // The fruit ends where the 3D run says, and each finger's peak grip is the summary's.
        assert_eq!(Some(stream.fruit_end), s3.fruit_end);
        let g = s3.grasp.as_ref().unwrap();
        assert!(
            (stream.peak_finger - g.peak_grip_force_n).abs() <= 1e-12 * g.peak_grip_force_n,
            "{} vs {}",
            stream.peak_finger,
            g.peak_grip_force_n
        );
        // The positions are the DOFs' x, y, z.
        for (q, d) in stream.last_q.iter().zip(&dofs.0) {
            for (i, x) in q.chunks_exact(3).enumerate() {
                assert_eq!(x, &d[4 * i..4 * i + 3]);
            }
        }
        assert_eq!(stream.phases, vec![1, 2, 3, usize::MAX]);
        assert!(stream.added >= 2 && stream.body_added >= 1);
        // The planar summary reads the strided stream (its counters come from the run's
        // stats): the run completed, its peak reaction and final positions.
        let stats = gripsim::solver::RunStats {
            steps: s3.steps,
            t: s3.t_end,
            ..Default::default()
        };
        let sum = summary.finish(&stats, 0.0);
        assert!(sum.completed);
        assert_eq!(sum.scenario, "3d-lift");
        assert_eq!(sum.peak_reaction_force_n, stream.peak_reaction);
        assert!(sum.peak_reaction_force_n > 0.5 && sum.peak_reaction_force_n < 2.0);
        let rod = &sum.rods[0];
        let last = &stream.last_q[0];
        assert_eq!(rod.final_positions[9], [last[27], last[28]]);
    }
}
