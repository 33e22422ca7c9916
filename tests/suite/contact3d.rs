//! Issue 16, 3D contact (src/rod3d/world.rs, contact3.rs, body3.rs, gripper.rs): a rod at rest
//! on a table carries its weight, no node is inside an obstacle after the corrector, momentum is
//! exchanged exactly with a free fruit, and a sphere grasped by three symmetric fingers stays
//! centred with equal finger forces.

use gripsim::contact::friction::{Coulomb, FrictionTable};
use gripsim::obstacle3::{Obstacle3, Pose3, Shape3, TriMesh, V3};
use gripsim::rod3d::body3::Body3;
use gripsim::rod3d::gripper::{radial, Move3};
use gripsim::rod3d::rod::pos;
use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3, World3};

/// `n` points evenly from `from` to `to` (also used by compliant3d).
pub(crate) fn line(n: usize, from: [f64; 3], to: [f64; 3]) -> Vec<[f64; 3]> {
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            [
                from[0] + s * (to[0] - from[0]),
                from[1] + s * (to[1] - from[1]),
                from[2] + s * (to[2] - from[2]),
            ]
        })
        .collect()
}

fn spec(points: Vec<[f64; 3]>, director: [f64; 3], section: Section3) -> Rod3Spec {
    Rod3Spec {
        points,
        director,
        rest_theta: Vec::new(),
        section,
        youngs_modulus: 1e6,
        shear_modulus: 1e6 / 3.0,
        density: 1000.0,
    }
}

fn node(w: &World3, r: usize, i: usize) -> V3 {
    let q = &w.rods[r].q;
    V3::new(q[pos(i)], q[pos(i) + 1], q[pos(i) + 2])
}

/// The deepest any node of any rod sits below its thickness offset on any surface (m; ≤ 0 is
/// no penetration).
fn worst_penetration(w: &World3) -> f64 {
    let mut worst: f64 = f64::NEG_INFINITY;
    for r in 0..w.rods.len() {
        for i in 0..w.rods[r].rod.n {
            let x = node(w, r, i);
            let surfaces = w
                .obstacles
                .iter()
                .chain(w.bodies.iter().map(|b| &b.obstacle));
            for o in surfaces {
                let p = o.query(&x);
                worst = worst.max(w.offset(r, i, &p.normal) - p.distance);
            }
        }
    }
    worst
}

#[test]
fn a_rod_lying_on_a_table_carries_its_weight() {
    let h = 0.002;
    let section = Section3::Rect { b: 0.01, h };
    // Along x, m₁ (the h direction) vertical: the face sits h/2 under the centreline.
    let rod = spec(
        line(11, [0.0, 0.0, h / 2.0], [0.1, 0.0, h / 2.0]),
        [0.0, 0.0, 1.0],
        section,
    );
    let mut w = World3::new([0.0, 0.0, -9.81]);
    w.add_rod("prong", Sim3::new(Rod3::new(&rod)), section);
    w.obstacles
        .push(Obstacle3::new("table", Shape3::Plane, Pose3::at([0.0; 3])));
    for _ in 0..20 {
        w.step(1e-3).unwrap();
        assert!(worst_penetration(&w) <= 1e-15, "{}", worst_penetration(&w));
    }
    let weight = 9.81 * w.rods[0].rod.mass.iter().step_by(4).sum::<f64>();
    let carried: f64 = w.reactions[0].iter().map(|r| r.z).sum();
    println!("weight {weight:.12e} N, table reaction {carried:.12e} N");
    assert!((carried - weight).abs() <= 1e-12 * weight);
    assert!(w.contacts[0].iter().all(|c| c.is_some()));
    let vmax = w.rods[0].v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(vmax < 1e-12, "{vmax}");
}

#[test]
fn no_node_is_inside_any_shape_after_the_corrector() {
    // A clamped prong swept along x over a row of fixed shapes (sphere, ellipsoid, box, mesh)
    // that reach 4 to 6 mm above its tip, with friction. A round section keeps the offset
    // (its radius) independent of the twist, so the check is exact.
    let section = Section3::Circle { r: 0.001 };
    let mut w = World3::new([0.0, 0.0, -9.81]);
    w.friction = FrictionTable {
        default: Coulomb {
            mu_s: 0.4,
            mu_k: 0.3,
        },
        pairs: Vec::new(),
    };
    let mut rod = spec(
        line(16, [0.0, 0.0, 0.0], [0.0, 0.0, -0.06]),
        [1.0, 0.0, 0.0],
        section,
    );
    // Stiff enough (E = 10 MPa) not to trail over the first shape when the sweep starts.
    rod.youngs_modulus = 1e7;
    rod.shear_modulus = 1e7 / 3.0;
    let mut sim = Sim3::new(Rod3::new(&rod));
    sim.clamp_edge(0);
    w.add_rod("prong", sim, section);
    let cube = TriMesh::from_obj(gripsim::obstacle3::mesh::CUBE_OBJ, 0.012).unwrap();
    w.obstacles.push(Obstacle3::new(
        "sphere",
        Shape3::Sphere { radius: 0.01 },
        Pose3::at([0.03, 0.001, -0.062]),
    ));
    w.obstacles.push(Obstacle3::new(
        "ellipsoid",
        Shape3::Ellipsoid {
            semi_axes: [0.008, 0.012, 0.006],
        },
        Pose3::at([0.055, -0.001, -0.06]),
    ));
    w.obstacles.push(Obstacle3::new(
        "box",
        Shape3::Box {
            half: [0.005, 0.01, 0.004],
        },
        Pose3::at([0.08, 0.0, -0.06]),
    ));
    w.obstacles.push(Obstacle3::new(
        "mesh",
        Shape3::Mesh(cube),
        Pose3::at([0.105, 0.002, -0.062]),
    ));
    let (dt, speed) = (2e-4, 0.5);
    let mut worst: f64 = f64::NEG_INFINITY;
    let mut touched = vec![false; 4];
    for k in 1..=1400 {
        let x = speed * dt * k as f64;
        let sim = &mut w.rods[0];
        for i in 0..2 {
            sim.target[pos(i)] = sim.rod.q0[pos(i)] + x;
        }
        w.step(dt).unwrap();
        worst = worst.max(worst_penetration(&w));
        for c in w.contacts[0].iter().flatten() {
            if let gripsim::rod3d::contact3::Surface3::Obstacle(o) = c.surface {
                touched[o] = true;
            }
        }
    }
    println!("worst penetration below the offset: {worst:e} m; touched {touched:?}");
    assert!(touched.iter().all(|t| *t), "{touched:?}");
    assert!(worst <= 1e-12, "{worst}");
}

#[test]
fn momentum_is_exchanged_exactly_with_a_free_fruit() {
    // No gravity: a free rod thrown at a free sphere, with friction between them.
    let section = Section3::Circle { r: 0.001 };
    let mut w = World3::new([0.0; 3]);
    w.friction = FrictionTable {
        default: Coulomb {
            mu_s: 0.5,
            mu_k: 0.4,
        },
        pairs: Vec::new(),
    };
    let rod = spec(
        line(12, [-0.02, -0.03, 0.004], [-0.02, 0.03, 0.006]),
        [0.0, 0.0, 1.0],
        section,
    );
    let mut sim = Sim3::new(Rod3::new(&rod));
    for i in 0..sim.rod.n {
        sim.v[pos(i)] = 2.0;
        sim.v[pos(i) + 1] = 0.3;
    }
    w.add_rod("rod", sim, section);
    w.bodies
        .push(Body3::new("fruit", Shape3::Sphere { radius: 0.01 }, 500.0, [0.0; 3]).unwrap());
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
    let mut contacts = 0;
    let mut worst: f64 = 0.0;
    for _ in 0..100 {
        let rep = w.step(1e-4).unwrap();
        contacts += rep.added;
        worst = worst.max((momentum(&w) - p0).norm() / p0.norm());
    }
    let pb = w.bodies[0].momentum();
    println!("contacts added {contacts}; fruit momentum {pb:?} of {p0:?}; drift {worst:e}");
    assert!(
        contacts > 0 && pb.x > 0.05 * p0.x,
        "the rod must hit and push the fruit"
    );
    assert!(worst < 1e-12, "{worst}");
}

/// Three 20-node fingers around a free 2 cm sphere, no gravity, squeezed to 0.2 N each.
fn three_finger_grasp() -> (World3, gripsim::rod3d::gripper::Gripper3) {
    let section = Section3::Rect { b: 0.008, h: 0.002 };
    // E = 100 MPa: the fingers' first bending period (~25 ms) is short against the squeeze.
    let mut w = World3::new([0.0; 3]);
    w.friction = FrictionTable {
        default: Coulomb {
            mu_s: 0.5,
            mu_k: 0.4,
        },
        pairs: Vec::new(),
    };
    let mut prong = spec(
        line(20, [0.0; 3], [0.0, 0.0, -0.05]),
        [1.0, 0.0, 0.0],
        section,
    );
    prong.youngs_modulus = 1e8;
    prong.shear_modulus = 1e8 / 3.0;
    let mut g = radial(&mut w, &prong, 3, 0.024, [0.0; 3], 1);
    g.moves = vec![
        Move3::Squeeze {
            speed: 0.05,
            force: 0.2,
            max_travel: 0.015,
        },
        Move3::Hold { duration: 0.02 },
    ];
    w.bodies.push(
        Body3::new(
            "fruit",
            Shape3::Sphere { radius: 0.02 },
            900.0,
            [0.0, 0.0, -0.035],
        )
        .unwrap(),
    );
    (w, g)
}

#[test]
fn a_sphere_grasped_by_three_symmetric_fingers_stays_centred_with_equal_forces() {
    let (mut w, mut g) = three_finger_grasp();
    let dt = 2e-4;
    let mut k = 0;
    while !g.done() {
        k += 1;
        g.drive(&mut w, k as f64 * dt, dt);
        let rep = w.step(dt).unwrap();
        if k % 50 == 0 || rep.released > 0 {
            let n: usize = w.contacts.iter().map(|c| c.iter().flatten().count()).sum();
            eprintln!(
                "step {k}: {rep:?} contacts {n} forces {:?} travel {}",
                g.finger_forces(&w),
                g.travel
            );
        }
        assert!(k < 2000, "the squeeze never reached its force");
    }
    let f = g.finger_forces(&w);
    let mean = f.iter().sum::<f64>() / 3.0;
    let spread = f.iter().fold(0.0f64, |m, x| m.max((x - mean).abs())) / mean;
    let c = w.bodies[0].centre();
    println!("{k} steps; finger forces {f:?} N, relative spread {spread:e}; fruit centre {c:?}");
    assert!(mean > 0.1, "{mean}");
    assert!(spread < 1e-9, "{spread}");
    assert!(c.x.hypot(c.y) < 1e-12, "{c:?}");
}

#[test]
fn an_in_plane_3d_press_reproduces_the_planar_solver() {
    // A straight prong hanging along −y, its top edge driven at 0.2 m/s towards a fixed round
    // fruit in its plane, under in-plane gravity: the planar solver (circle) and the 3D world
    // (sphere centred in the plane) take the same steps.
    let (nodes, dt, steps) = (12usize, 1e-4, 600usize);
    let text = format!(
        r#"
name = "planar-press"
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
points = "nodes"
[[obstacle]]
kind = "circle"
center = [-0.045, -0.07]
radius = 0.04
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
    let mut rod = spec(
        line(nodes, [0.0; 3], [0.0, -0.1, 0.0]),
        [1.0, 0.0, 0.0],
        section,
    );
    rod.shear_modulus = 1e6 / 3.0;
    let mut sim = Sim3::new(Rod3::new(&rod));
    sim.clamp_edge(0);
    let mut w = World3::new([0.0, -9.81, 0.0]);
    w.side = gripsim::rod3d::ContactSide3::Centreline;
    w.force_tol = 1e-12;
    w.add_rod("prong", sim, section);
    w.obstacles.push(Obstacle3::new(
        "fruit",
        Shape3::Sphere { radius: 0.04 },
        Pose3::at([-0.045, -0.07, 0.0]),
    ));
    let mut touched = 0;
    for k in 1..=steps {
        let s = &mut w.rods[0];
        for i in 0..2 {
            s.target[pos(i)] = s.rod.q0[pos(i)] - 0.2 * dt * k as f64;
        }
        w.step(dt).unwrap();
        touched = touched.max(w.contacts[0].iter().flatten().count());
    }
    let mut worst: f64 = 0.0;
    let mut z: f64 = 0.0;
    for i in 0..nodes {
        let x = node(&w, 0, i);
        worst = worst
            .max((x.x - p[2 * i]).abs())
            .max((x.y - p[2 * i + 1]).abs());
        z = z.max(x.z.abs());
    }
    let travel = (node(&w, 0, nodes - 1) - V3::new(0.0, -0.1, 0.0)).norm();
    println!(
        "in-plane press, {nodes} nodes, {steps} steps: {touched} nodes in contact at most; tip moved {travel:.6e} m; max |3D − planar| = {worst:.2e} m ({:.2e} relative); max |z| = {z:e}",
        worst / travel
    );
    assert!(touched > 0, "the prong must reach the fruit");
    assert!(worst / travel < 1e-9, "{worst}");
    assert_eq!(z, 0.0);
}

#[test]
fn bad_3d_scenarios_name_file_key_and_value() {
    use gripsim::scenario::three::Scenario3;
    let good = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/3d-two-finger-sphere.toml"
    ))
    .unwrap();
    let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios"));
    let sc = Scenario3::from_str(&good, "g.toml", dir).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((sc.fingers, sc.prong.points.len()), (2, 10));
    assert!(gripsim::scenario::three::is_3d(&good));
    let cases = [
        (
            "gravity = [0.0, 0.0, -9.81]",
            "gravity = [0.0, -9.81]",
            "b.toml: key `solve.gravity` = [0.0, -9.81]: expected a 3D vector [x, y, z]",
        ),
        (
            "kind = \"parallel\"",
            "kind = \"paralel\"",
            "b.toml: key `gripper.kind` = \"paralel\": unknown gripper kind",
        ),
        (
            "radius = 0.058",
            "radius = -0.058",
            "b.toml: key `gripper.radius` = -0.058",
        ),
        (
            "kind = \"squeeze\"",
            "kind = \"sqeeze\"",
            "b.toml: key `move.0.kind` = \"sqeeze\": unknown move",
        ),
        (
            "density = 900.0",
            "density = 900.0\nmass = 1.0",
            "b.toml: key `fruit.mass` = 1.0: unknown key",
        ),
        (
            "nu = 0.5",
            "nu = 0.7",
            "b.toml: key `prong.nu` = 0.7: Poisson's ratio",
        ),
    ];
    for (from, to, want) in cases {
        assert!(good.contains(from), "{from}");
        let bad = good.replacen(from, to, 1);
        let e = Scenario3::from_str(&bad, "b.toml", dir)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(want), "{e}\n  wanted: {want}");
        assert!(!e.contains('\n'), "{e}");
    }
    let mesh = good.replace(
        "shape = { kind = \"sphere\", radius = 0.05 }",
        "shape = { kind = \"mesh\", file = \"no-such.obj\" }",
    );
    let e = Scenario3::from_str(&mesh, "b.toml", dir)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("b.toml: key `fruit.shape.file` = \"no-such.obj\": cannot read"),
        "{e}"
    );
}
