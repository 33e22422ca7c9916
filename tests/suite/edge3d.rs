//! Issue 16, edge contact in 3D (src/rod3d/edge3.rs, src/rod3d/world/edges3.rs,
//! src/obstacle3/segment.rs): a segment resting on a fruit smaller than it, or across a box's
//! ridge, between its nodes is stopped (with nodes only it tunnels), its edge reaction carries
//! the weight, an in-plane 3D run reproduces the planar solver's edge contact, the constraint
//! row matches finite differences of the true gap, and on a free fruit the reaction acts on
//! the body (momentum exchanged exactly).

use gripsim::obstacle3::{Obstacle3, Pose3, Shape3, V3};
use gripsim::rod3d::body3::Body3;
use gripsim::rod3d::contact3::Surface3;
use gripsim::rod3d::rod::pos;
use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3, World3};
use nalgebra::Vector6;

fn line(n: usize, from: [f64; 3], to: [f64; 3]) -> Vec<[f64; 3]> {
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            [0, 1, 2].map(|a| from[a] + s * (to[a] - from[a]))
        })
        .collect()
}

fn spec(points: Vec<[f64; 3]>, e: f64, section: Section3) -> Rod3Spec {
    Rod3Spec {
        points,
        director: [0.0, 0.0, 1.0],
        rest_theta: Vec::new(),
        section,
        youngs_modulus: e,
        shear_modulus: e / 3.0,
        density: 1000.0,
    }
}

fn node(w: &World3, r: usize, i: usize) -> V3 {
    let q = &w.rods[r].q;
    V3::new(q[pos(i)], q[pos(i) + 1], q[pos(i) + 2])
}

/// The deepest any node sits below its offset on any surface (m; ≤ 0: none).
fn node_penetration(w: &World3) -> f64 {
    let mut worst = f64::NEG_INFINITY;
    for r in 0..w.rods.len() {
        for i in 0..w.rods[r].rod.n {
            let x = node(w, r, i);
            for o in w
                .obstacles
                .iter()
                .chain(w.bodies.iter().map(|b| &b.obstacle))
            {
                let p = o.query(&x);
                worst = worst.max(w.offset(r, i, &p.normal) - p.distance);
            }
        }
    }
    worst
}

/// A cube of half-side 1 cm turned 45° about y: a ridge along y at x = 0, z = 1.414 cm.
fn ridge() -> (Shape3, Pose3, f64) {
    let rot = nalgebra::Rotation3::from_axis_angle(&V3::y_axis(), std::f64::consts::FRAC_PI_4);
    let pose = Pose3 {
        position: V3::zeros(),
        rotation: rot,
    };
    (
        Shape3::Box { half: [0.01; 3] },
        pose,
        0.01 * std::f64::consts::SQRT_2,
    )
}

/// What a drop did: the worst segment and node penetration after any step (m), the steps
/// with an edge contact, the edge force and the weight at the end (N).
struct Drop {
    segment: f64,
    nodes: f64,
    held_steps: usize,
    force: f64,
    weight: f64,
}

/// A 4-node, 3 cm rod (round section r = 1 mm, E = 100 MPa) dropped from 0.5 mm above a fixed
/// shape whose top (at height `top`, x = 0) lies under the middle of its middle segment, with
/// nodes at x = ±5 mm straddling it; `steps` steps of 1 ms.
fn drop_on(shape: Shape3, pose: Pose3, top: f64, edges: bool, steps: usize) -> Drop {
    let section = Section3::Circle { r: 0.001 };
    let z = top + 0.001 + 0.0005;
    let mut w = World3::new([0.0, 0.0, -9.81]);
    w.edge_contact = edges;
    w.force_tol = 1e-12;
    let points = vec![
        [-0.015, 0.0, z],
        [-0.005, 0.0, z],
        [0.005, 0.0, z],
        [0.015, 0.0, z],
    ];
    let rod = spec(points, 1e8, section);
    w.add_rod("prong", Sim3::new(Rod3::new(&rod)), section);
    w.obstacles.push(Obstacle3::new("fruit", shape, pose));
    let mut d = Drop {
        segment: f64::NEG_INFINITY,
        nodes: f64::NEG_INFINITY,
        held_steps: 0,
        force: 0.0,
        weight: 9.81 * w.rods[0].rod.mass.iter().step_by(4).sum::<f64>(),
    };
    for _ in 0..steps {
        w.step(1e-3).unwrap();
        d.segment = d.segment.max(w.segment_penetration(0));
        d.nodes = d.nodes.max(node_penetration(&w));
        d.held_steps += usize::from(!w.edges[0].is_empty());
    }
    d.force = w.edges[0].iter().map(|e| e.force).sum();
    d
}

#[test]
fn a_segment_resting_on_a_small_sphere_is_stopped_and_carries_the_weight() {
    let (shape, pose) = (Shape3::Sphere { radius: 0.002 }, Pose3::at([0.0; 3]));
    let d = drop_on(shape.clone(), pose, 0.002, true, 300);
    println!(
        "sphere, edges: worst segment penetration {:.3e} m, nodes {:.3e} m; edge force {:.15e} N, weight {:.15e} N, relative {:.2e}",
        d.segment,
        d.nodes,
        d.force,
        d.weight,
        (d.force - d.weight).abs() / d.weight
    );
    assert!(d.segment <= 1e-9, "{}", d.segment);
    assert!(d.nodes <= 1e-12, "{}", d.nodes);
    assert!(
        (d.force - d.weight).abs() <= 1e-9 * d.weight,
        "{} vs {}",
        d.force,
        d.weight
    );
    let d = drop_on(shape, pose, 0.002, false, 300);
    println!(
        "sphere, nodes only: worst segment penetration {:.3e} m",
        d.segment
    );
    assert!(
        d.segment > 1e-3,
        "nodes only must let the sphere through: {}",
        d.segment
    );
}

#[test]
fn a_segment_dropped_across_a_ridge_is_stopped_between_its_nodes() {
    // A round rod on a frictionless knife edge is an inverted pendulum (its centre r above the
    // ridge; it rolls off at the rate √(g/r) from round-off); it must not cut into the box
    // while the ridge holds it, nor after.
    let (shape, pose, top) = ridge();
    let d = drop_on(shape.clone(), pose, top, true, 300);
    println!(
        "ridge, edges: worst segment penetration {:.3e} m, nodes {:.3e} m; {} steps held by the ridge",
        d.segment, d.nodes, d.held_steps
    );
    assert!(d.segment <= 1e-9, "{}", d.segment);
    assert!(d.nodes <= 1e-12, "{}", d.nodes);
    assert!(d.held_steps >= 250, "{}", d.held_steps);
    let d = drop_on(shape, pose, top, false, 300);
    println!(
        "ridge, nodes only: worst segment penetration {:.3e} m",
        d.segment
    );
    assert!(
        d.segment > 1e-3,
        "nodes only must let the ridge in: {}",
        d.segment
    );
    assert_eq!(d.held_steps, 0);
}

/// The in-plane press of tests/suite/contact3d.rs on a peg smaller than a segment: the planar
/// solver in edge mode, then the 3D world; the largest difference of any node (m) and the
/// tip's travel (m), the most edge contacts at once.
#[test]
fn an_in_plane_3d_press_on_a_small_peg_reproduces_the_planar_edge_contact() {
    let (nodes, dt, steps) = (12usize, 1e-4, 1000usize);
    let (cx, cy, rad) = (-0.012, -0.068, 0.002);
    let text = format!(
        r#"
name = "planar-peg"
[solve]
mode = "dynamic"
t_end = {t_end:e}
dt = {dt:e}
stepping = "fixed"
gravity = [0.0, -9.81]
force_tol = 1e-12
[[rod]]
name = "prong"
nodes = {nodes}
shape = {{ kind = "straight", start = [0.0, 0.0], end = [0.0, -0.1] }}
E = 1e6
section = {{ kind = "rect", b = 0.02, h = 0.01 }}
density = 1000.0
clamped = [0, 1]
drive = {{ kind = "constant_velocity", velocity = [-0.2, 0.0] }}
[contact]
surface = "centreline"
points = "edges"
[[obstacle]]
kind = "circle"
center = [{cx:e}, {cy:e}]
radius = {rad:e}
"#,
        t_end = dt * steps as f64
    );
    let sc =
        gripsim::Scenario::from_str(&text, "planar.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    let mut planar = gripsim::Simulation::new(&sc);
    planar
        .run(&mut gripsim::events::NullObserver)
        .unwrap_or_else(|e| panic!("{e}"));
    let p = planar.positions(0).to_vec();

    let section = Section3::Rect { b: 0.02, h: 0.01 };
    let mut rod = spec(line(nodes, [0.0; 3], [0.0, -0.1, 0.0]), 1e6, section);
    rod.director = [1.0, 0.0, 0.0];
    let mut sim = Sim3::new(Rod3::new(&rod));
    sim.clamp_edge(0);
    let mut w = World3::new([0.0, -9.81, 0.0]);
    w.side = gripsim::rod3d::ContactSide3::Centreline;
    w.edge_contact = true;
    w.force_tol = 1e-12;
    w.add_rod("prong", sim, section);
    w.obstacles.push(Obstacle3::new(
        "peg",
        Shape3::Sphere { radius: rad },
        Pose3::at([cx, cy, 0.0]),
    ));
    let (mut most, mut node_steps, mut seg) = (0, 0, f64::NEG_INFINITY);
    for k in 1..=steps {
        let s = &mut w.rods[0];
        for i in 0..2 {
            s.target[pos(i)] = s.rod.q0[pos(i)] - 0.2 * dt * k as f64;
        }
        w.step(dt).unwrap();
        most = most.max(w.edges[0].len());
        node_steps += usize::from(w.contacts[0].iter().any(|c| c.is_some()));
        seg = seg.max(w.segment_penetration(0));
    }
    let (mut worst, mut z) = (0.0f64, 0.0f64);
    for i in 0..nodes {
        let x = node(&w, 0, i);
        worst = worst
            .max((x.x - p[2 * i]).abs())
            .max((x.y - p[2 * i + 1]).abs());
        z = z.max(x.z.abs());
    }
    let travel = (node(&w, 0, nodes - 1) - V3::new(0.0, -0.1, 0.0)).norm();
    println!(
        "in-plane peg press, {nodes} nodes, {steps} steps: {most} edge contacts at most, {node_steps} steps with a node contact; worst segment penetration {seg:.2e} m; tip moved {travel:.6e} m; max |3D − planar| = {worst:.2e} m ({:.2e} relative); max |z| = {z:e}",
        worst / travel
    );
    assert!(most > 0, "the peg must meet a segment between nodes");
    assert!(seg <= 1e-9, "{seg}");
    assert!(worst / travel < 1e-9, "{worst}");
    assert_eq!(z, 0.0);
}

#[test]
fn the_edge_row_matches_finite_differences_of_the_gap_to_a_free_box() {
    // A free box turned so a ridge faces a segment; the segment hovers 0.3 mm off it with the
    // ridge between its nodes. The constraint row (w₀ n, w₁ n, −Gᵀ n) of the edge contact must
    // be the gradient of the true gap: the signed distance of the held point from the body
    // moved by ΔX = (Δc, φ), less the offset.
    let section = Section3::Rect { b: 0.004, h: 0.002 };
    let (shape, pose, top) = ridge();
    let mut w = World3::new([0.0; 3]);
    w.edge_contact = true;
    let z = top + 0.001 + 0.0003;
    let rod = spec(
        line(3, [-0.006, 0.001, z], [0.008, -0.001, z + 0.001]),
        1e6,
        section,
    );
    w.add_rod("prong", Sim3::new(Rod3::new(&rod)), section);
    let mut body = Body3::new("box", shape, 800.0, [0.0; 3]).unwrap();
    body.obstacle.pose.rotation = pose.rotation;
    body.start = body.obstacle.pose;
    w.bodies.push(body);
    let e = w
        .edge_contact_at(0, 0, Surface3::Body(0))
        .expect("the ridge lies between the nodes");
    assert!(e.lever.norm() > 0.01, "{:?}", e.lever);
    let q0 = w.rods[0].q.clone();
    let gap = |w: &mut World3, q: &[f64], dx: &Vector6<f64>| -> f64 {
        let b = &mut w.bodies[0];
        b.dx = *dx;
        b.place();
        let p = e.held_point(q);
        b.obstacle.query(&p).distance - e.offset
    };
    let zero = Vector6::zeros();
    let g0 = gap(&mut w, &q0, &zero);
    assert!((g0 - e.violation(&q0, &zero)).abs() < 1e-15, "{g0}");
    let a = e.body_row();
    let h = 1e-7;
    let mut worst: f64 = 0.0;
    for k in 0..2 {
        for c in 0..3 {
            let (mut qp, mut qm) = (q0.clone(), q0.clone());
            qp[pos(e.segment + k) + c] += h;
            qm[pos(e.segment + k) + c] -= h;
            let fd = (gap(&mut w, &qp, &zero) - gap(&mut w, &qm, &zero)) / (2.0 * h);
            let row = e.weights()[k] * e.normal[c];
            worst = worst.max((fd - row).abs());
        }
    }
    for f in 0..6 {
        let mut d = Vector6::zeros();
        d[f] = h;
        let fd = (gap(&mut w, &q0, &d) - gap(&mut w, &q0, &(-d))) / (2.0 * h);
        worst = worst.max((fd + a[f]).abs() / if f < 3 { 1.0 } else { e.lever.norm() });
    }
    println!("edge row vs FD of the gap: worst difference {worst:.2e} (per unit of n)");
    assert!(worst < 1e-6, "{worst}");
}

#[test]
fn a_free_fruit_smaller_than_a_segment_is_pushed_with_momentum_exchanged_exactly() {
    // No gravity: a rod whose nodes straddle a free 2 mm sphere is thrown at it.
    let section = Section3::Circle { r: 0.0005 };
    let mut w = World3::new([0.0; 3]);
    w.edge_contact = true;
    let rod = spec(
        line(4, [-0.006, -0.015, 0.0], [-0.006, 0.015, 0.0]),
        1e7,
        section,
    );
    let mut sim = Sim3::new(Rod3::new(&rod));
    for i in 0..sim.rod.n {
        sim.v[pos(i)] = 1.0;
    }
    w.add_rod("rod", sim, section);
    w.bodies.push(
        Body3::new(
            "berry",
            Shape3::Sphere { radius: 0.002 },
            1000.0,
            [0.0, 0.001, 0.0],
        )
        .unwrap(),
    );
    let momentum = |w: &World3| -> V3 {
        let s = &w.rods[0];
        let mut p = w.bodies[0].momentum();
        for i in 0..s.rod.n {
            for a in 0..3 {
                p[a] += s.rod.mass[pos(i) + a] * s.v[pos(i) + a];
            }
        }
        p
    };
    let p0 = momentum(&w);
    let (mut drift, mut seg, mut edge_steps) = (0.0f64, f64::NEG_INFINITY, 0);
    for _ in 0..100 {
        w.step(1e-4).unwrap();
        drift = drift.max((momentum(&w) - p0).norm() / p0.norm());
        seg = seg.max(w.segment_penetration(0));
        edge_steps += usize::from(!w.edges[0].is_empty());
    }
    let pb = w.bodies[0].momentum();
    let nodes = w.contacts[0].iter().flatten().count();
    println!(
        "{edge_steps} steps with an edge contact, {nodes} node contacts at the end; berry momentum {pb:?} of {p0:?}; drift {drift:.2e}; worst segment penetration {seg:.2e} m"
    );
    assert!(
        edge_steps > 0 && pb.x > 0.1 * p0.x,
        "the segment must push the berry"
    );
    assert!(drift < 1e-12, "{drift}");
    assert!(seg <= 1e-9, "{seg}");
}

#[test]
fn edge_points_are_read_from_a_3d_scenario() {
    use gripsim::scenario::contact::ContactPoints;
    use gripsim::scenario::three::Scenario3;
    let good = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/3d-two-finger-sphere.toml"
    ))
    .unwrap();
    let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios"));
    let sc = Scenario3::from_str(&good, "g.toml", dir).unwrap();
    assert_eq!(sc.points, ContactPoints::Nodes);
    let edges = good.replace(
        "surface = \"face\"",
        "surface = \"face\"\npoints = \"edges\"",
    );
    let sc = Scenario3::from_str(&edges, "g.toml", dir).unwrap();
    assert_eq!(sc.points, ContactPoints::Edges);
    let (w, _) = gripsim::rod3d::run3::build(&sc).unwrap();
    assert!(w.edge_contact);
    let bad = good.replace(
        "surface = \"face\"",
        "surface = \"face\"\npoints = \"edge\"",
    );
    let e = Scenario3::from_str(&bad, "b.toml", dir)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("b.toml: key `contact.points` = \"edge\": unknown contact points"),
        "{e}"
    );
    assert!(!e.contains('\n'), "{e}");
}

#[test]
fn the_shipped_berry_scenario_is_held_by_edges_and_slips_between_nodes_without_them() {
    use gripsim::scenario::three::Scenario3;
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/3d-berry-edges.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios"));
    let sc = Scenario3::from_str(&text, "3d-berry-edges.toml", dir).unwrap();
    let mut seen = EdgeEvents::default();
    let s = gripsim::rod3d::run3::run_observed(&sc, None, &mut seen).unwrap();
    println!(
        "recorded: {} steps with edge contacts, last {:?}",
        seen.steps, seen.last
    );
    // The events carry each finger's edge contact: its point on the berry (3 mm from the
    // centre), its weight inside the segment, and the finger force as its normal reaction.
    let last = seen.last.expect("edge contacts in the step events");
    let c = V3::new(0.0, 0.0, -0.035);
    assert!(seen.steps > 0 && last.len() == 2, "{last:?}");
    for e in &last {
        assert!(e.weight > 0.0 && e.weight < 1.0, "{e:?}");
        assert!(
            ((V3::from(e.point) - c).norm() - 0.003).abs() < 1e-12,
            "{e:?}"
        );
        assert_eq!(e.friction, [0.0; 3]);
    }
    println!(
        "edges: {} steps, squeezed at {:?} s, finger forces {:?} N, {} contacts added, worst penetration {:.2e} m",
        s.steps, s.squeezed_at, s.finger_forces, s.contacts_added, s.worst_penetration
    );
    let f = &s.finger_forces;
    assert!(f[0] >= 0.05 && (f[0] - f[1]).abs() <= 1e-9 * f[0], "{f:?}");
    assert!(s.contacts_added >= 2, "{}", s.contacts_added);
    assert!(s.worst_penetration <= 1e-9, "{}", s.worst_penetration);
    let nodes = text.replace("points = \"edges\"", "points = \"nodes\"");
    let sc = Scenario3::from_str(&nodes, "3d-berry-edges.toml", dir).unwrap();
    let s = gripsim::rod3d::run3::run(&sc, None).unwrap();
    println!(
        "nodes only: finger forces {:?} N, {} contacts added",
        s.finger_forces, s.contacts_added
    );
    assert_eq!((s.contacts_added, s.max_grip_force), (0, 0.0));
}

/// Collects the edge contacts (weight > 0) of the step events.
#[derive(Default)]
struct EdgeEvents {
    steps: usize,
    last: Option<Vec<gripsim::rod3d::events::Contact3>>,
}

impl gripsim::rod3d::events::Observer3 for EdgeEvents {
    fn on_event(&mut self, e: &gripsim::rod3d::events::Event3<'_>) {
        if let gripsim::rod3d::events::Event3::Step { contacts, .. } = e {
            let edges: Vec<_> = contacts
                .iter()
                .filter(|c| c.weight > 0.0)
                .copied()
                .collect();
            if !edges.is_empty() {
                self.steps += 1;
                self.last = Some(edges);
            }
        }
    }
}

/// A cube of half-sides 1 × 5 × 1 cm turned 45° about y (a 10 cm ridge along y on top), then
/// tilted by `phi` about x: the ridge rises along d = (0, cos φ, sin φ); its top line passes
/// through Rx(φ)(0, 0, 1.414 cm); the outward normal there, square to d and to x, is
/// n = (0, −sin φ, cos φ).
fn tilted_ridge(phi: f64) -> (Obstacle3, V3, V3, V3) {
    let tilt = nalgebra::Rotation3::from_axis_angle(&V3::x_axis(), phi);
    let turn = nalgebra::Rotation3::from_axis_angle(&V3::y_axis(), std::f64::consts::FRAC_PI_4);
    let pose = Pose3 {
        position: V3::zeros(),
        rotation: tilt * turn,
    };
    let top = tilt * V3::new(0.0, 0.0, 0.01 * std::f64::consts::SQRT_2);
    let o = Obstacle3::new(
        "ridge",
        Shape3::Box {
            half: [0.01, 0.05, 0.01],
        },
        pose,
    );
    (o, top, tilt * V3::y(), tilt * V3::z())
}

/// A one-segment rod (2 nodes at x = ±5 mm, round r = 0.5 mm) resting across a ridge tilted
/// by `phi` with μ_s = 0.5, μ_k = 0.4, for `steps` steps of 1 ms: the centre's velocity along
/// the ridge (m/s, positive uphill), the edge contact's force (normal, friction, world) and
/// whether it is stuck at the end, and the steps with an edge contact.
fn rest_on_tilted_ridge(phi: f64, steps: usize) -> (f64, f64, V3, bool, usize) {
    let (o, top, d, n) = tilted_ridge(phi);
    let r = 0.0005;
    let c = top + n * r;
    let section = Section3::Circle { r };
    let mut w = World3::new([0.0, 0.0, -9.81]);
    w.edge_contact = true;
    w.force_tol = 1e-12;
    w.friction.default = gripsim::contact::friction::Coulomb {
        mu_s: 0.5,
        mu_k: 0.4,
    };
    let points = vec![[c.x - 0.005, c.y, c.z], [c.x + 0.005, c.y, c.z]];
    w.add_rod(
        "rod",
        Sim3::new(Rod3::new(&spec(points, 1e8, section))),
        section,
    );
    w.obstacles.push(o);
    let mut held = 0;
    for _ in 0..steps {
        w.step(1e-3).unwrap();
        held += usize::from(w.edges[0].len() == 1);
    }
    let s = &w.rods[0];
    let v = V3::new(
        0.5 * (s.v[pos(0)] + s.v[pos(1)]),
        0.5 * (s.v[pos(0) + 1] + s.v[pos(1) + 1]),
        0.5 * (s.v[pos(0) + 2] + s.v[pos(1) + 2]),
    );
    let e = w.edges[0]
        .first()
        .copied()
        .expect("an edge contact at the end");
    let stuck = matches!(e.grip, gripsim::rod3d::contact3::Grip3::Stick { .. });
    (v.dot(&d), e.force, e.friction, stuck, held)
}

#[test]
fn a_segment_across_a_tilted_ridge_sticks_below_the_friction_angle_and_slides_above_it() {
    // Below tan φ = μ_s the point between the nodes sticks: no motion, friction = m g sin φ
    // uphill, normal force m g cos φ.
    let steps = 100;
    let m = 1000.0 * std::f64::consts::PI * 0.0005f64.powi(2) * 0.01;
    let g = 9.81;
    let phi = 20f64.to_radians();
    let (_, _, d, n) = tilted_ridge(phi);
    let (v, fnorm, fric, stuck, held) = rest_on_tilted_ridge(phi, steps);
    let rel_n = (fnorm - m * g * phi.cos()).abs() / (m * g);
    let rel_t = (fric - d * (m * g * phi.sin())).norm() / (m * g);
    println!(
        "tilted ridge φ = 20° (tan φ = {:.3} < μ_s = 0.5): stuck {stuck}, held {held}/{steps} steps, centre velocity along the ridge {v:.3e} m/s; normal force {fnorm:.15e} N (m g cos φ {:.15e}, rel {rel_n:.2e}); friction {fric:?} vs m g sin φ uphill (rel {rel_t:.2e})",
        phi.tan(),
        m * g * phi.cos()
    );
    assert!(stuck && held == steps, "{stuck} {held}");
    assert!(v.abs() < 1e-12, "{v}");
    // Newton stops at its round-off floor (updates ≤ 1e-12 L): the forces to ~1e-8.
    assert!(rel_n < 1e-7 && rel_t < 1e-7, "{rel_n} {rel_t}");
    assert!(fric.dot(&n).abs() < 1e-15);
    // Above it the point slides down with g (sin φ − μ_k cos φ): after k steps of implicit
    // Euler from rest under a constant force, v = k dt a.
    let phi = 35f64.to_radians();
    let (v, fnorm, fric, stuck, held) = rest_on_tilted_ridge(phi, steps);
    let a = g * (phi.sin() - 0.4 * phi.cos());
    let expect = -(steps as f64) * 1e-3 * a;
    let rel = (v - expect).abs() / expect.abs();
    let rel_k = (fric.norm() - 0.4 * fnorm).abs() / fnorm;
    println!(
        "tilted ridge φ = 35° (tan φ = {:.3} > μ_s): stuck {stuck}, held {held}/{steps} steps; velocity along the ridge {v:.15e} m/s, expected −k dt g (sin φ − μ_k cos φ) = {expect:.15e} (relative {rel:.2e}); |friction| / normal force − μ_k: {rel_k:.2e}",
        phi.tan()
    );
    assert!(!stuck && held == steps, "{stuck} {held}");
    assert!(rel < 1e-6, "{v} vs {expect}");
    assert!(rel_k < 1e-12, "{rel_k}");
}

#[test]
fn friction_of_a_segment_on_a_free_box_ridge_drags_it_with_momentum_exchanged_exactly() {
    // No gravity: a one-segment rod (nodes straddling the ridge of a free box) is thrown at
    // the ridge and along it; only friction can push the box along the ridge (y), the normal
    // is square to it.
    let (shape, pose, top) = ridge();
    let shape = match shape {
        Shape3::Box { .. } => Shape3::Box {
            half: [0.01, 0.05, 0.01],
        },
        s => s,
    };
    let section = Section3::Circle { r: 0.0005 };
    let mut w = World3::new([0.0; 3]);
    w.edge_contact = true;
    w.force_tol = 1e-12;
    w.friction.default = gripsim::contact::friction::Coulomb {
        mu_s: 0.5,
        mu_k: 0.4,
    };
    let z = top + 0.0005 + 0.0002;
    let mut sim = Sim3::new(Rod3::new(&spec(
        line(2, [-0.004, 0.0, z], [0.006, 0.0, z]),
        1e8,
        section,
    )));
    for i in 0..2 {
        sim.v[pos(i) + 1] = 0.3;
        sim.v[pos(i) + 2] = -1.0;
    }
    w.add_rod("rod", sim, section);
    let mut body = Body3::new("box", shape, 100.0, [0.0; 3]).unwrap();
    body.obstacle.pose.rotation = pose.rotation;
    body.start = body.obstacle.pose;
    w.bodies.push(body);
    let momentum = |w: &World3| -> V3 {
        let s = &w.rods[0];
        let mut p = w.bodies[0].momentum();
        for i in 0..s.rod.n {
            for a in 0..3 {
                p[a] += s.rod.mass[pos(i) + a] * s.v[pos(i) + a];
            }
        }
        p
    };
    let p0 = momentum(&w);
    let (mut drift, mut held, mut stuck, mut slid) = (0.0f64, 0, 0, 0);
    let mut fy = 0.0f64;
    for _ in 0..200 {
        w.step(1e-4).unwrap();
        drift = drift.max((momentum(&w) - p0).norm() / p0.norm());
        for e in &w.edges[0] {
            held += 1;
            fy = fy.max(e.friction.y.abs());
            match e.grip {
                gripsim::rod3d::contact3::Grip3::Stick { .. } => stuck += 1,
                _ => slid += 1,
            }
        }
    }
    let pb = w.bodies[0].momentum();
    println!(
        "free box ridge: {held} steps with an edge contact ({stuck} stuck, {slid} sliding), largest friction along the ridge {fy:.3e} N; box momentum {pb:?} of {p0:?}; drift {drift:.2e}"
    );
    assert!(held > 0 && fy > 0.0, "{held} {fy}");
    assert!(
        pb.y > 1e-3 * p0.norm(),
        "friction must drag the box along the ridge: {pb:?}"
    );
    assert!(drift < 1e-12, "{drift}");
}

#[test]
fn the_shipped_two_finger_sphere_grasp_in_edge_mode_agrees_with_nodes_only() {
    // The 5 cm sphere is big against the 1.1 cm segments: where a node already follows the
    // sphere (normal within 30° of a segment's), the segment's penetration is the faceting of
    // the sphere (a chord from that node: at most L²/(8 R) on radius R), which node contact
    // accepts; edge contacts hold only where no node follows. The grip must then agree with
    // nodes only.
    use gripsim::scenario::three::Scenario3;
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/3d-two-finger-sphere.toml"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios"));
    let sc = Scenario3::from_str(&text, "3d-two-finger-sphere.toml", dir).unwrap();
    let nodes = gripsim::rod3d::run3::run(&sc, None).unwrap();
    // The same run stepped here, to measure what its summary does not: how deep the segments
    // cut into the sphere between the nodes.
    let (mut w, mut g) = gripsim::rod3d::run3::build(&sc).unwrap();
    let mut chord = f64::NEG_INFINITY;
    for k in 1..=nodes.steps {
        g.drive(&mut w, k as f64 * sc.dt, sc.dt);
        w.step(sc.dt).unwrap();
        chord = chord
            .max(w.segment_penetration(0))
            .max(w.segment_penetration(1));
    }
    let edges = text.replace(
        "surface = \"face\"",
        "surface = \"face\"\npoints = \"edges\"",
    );
    let sc = Scenario3::from_str(&edges, "3d-two-finger-sphere.toml", dir).unwrap();
    let (w, _) = gripsim::rod3d::run3::build(&sc).unwrap();
    let q = &w.rods[0].q;
    let longest = (0..w.rods[0].rod.n - 1)
        .map(|i| {
            let d = (0..3).map(|a| q[pos(i + 1) + a] - q[pos(i) + a]);
            d.map(|x| x * x).sum::<f64>().sqrt()
        })
        .fold(0.0, f64::max);
    let facet = longest * longest / (8.0 * 0.05);
    println!("nodes only: the segments cut {chord:.3e} m into the sphere at worst");
    let s = gripsim::rod3d::run3::run(&sc, None).unwrap();
    let (fe, fn_) = (&s.finger_forces, &nodes.finger_forces);
    let rel = (fe[0] - fn_[0]).abs() / fn_[0];
    let fruit = (V3::from(s.fruit_end.unwrap()) - V3::from(nodes.fruit_end.unwrap())).norm();
    println!(
        "3d-two-finger-sphere, edges: {} steps, squeezed at {:?} s, finger forces {:?} N, {} contacts added, {} switches, worst penetration {:.3e} m (faceting bound L²/8R = {:.3e} m, L = {:.4} m)",
        s.steps, s.squeezed_at, fe, s.contacts_added, s.friction_switches, s.worst_penetration, facet, longest
    );
    println!(
        "nodes only: {} steps, squeezed at {:?} s, finger forces {:?} N; finger force difference {rel:.2e} relative; fruit ends {fruit:.2e} m apart",
        nodes.steps, nodes.squeezed_at, fn_
    );
    assert!((fe[0] - fe[1]).abs() <= 1e-9 * fe[0], "{fe:?}");
    assert!(rel < 0.05, "{fe:?} vs {fn_:?}");
    let (te, tn) = (s.squeezed_at.unwrap(), nodes.squeezed_at.unwrap());
    assert!((te - tn).abs() < 0.01 * tn, "{te} vs {tn}");
    assert!(fruit < 1e-9, "{fruit}");
    // Faceting as with nodes only (to 1 %: the runs differ slightly); about L²/(8 R) (the
    // offsets of a node and of a segment, each from its own material frames, differ a little).
    assert!(
        (s.worst_penetration - chord).abs() <= 0.01 * chord,
        "{} vs {chord}",
        s.worst_penetration
    );
    assert!(
        chord > 0.5 * facet && chord < 2.0 * facet,
        "{chord} vs {facet}"
    );
}
