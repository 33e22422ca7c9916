//! Issue 33 item 3: a compliant fruit in 3D (src/contact/compliant.rs `PointContact`,
//! src/rod3d/world/compliant3.rs). A flat prong face pressed on a compliant sphere settles on
//! Hertz's contact radius, peak pressure and indentation; a vertical jaw holds a compliant
//! sphere exactly down to μ_s ΣN = m g; the shipped 3d-apple is held and not bruised, also at
//! dt/2 and with twice the nodes; a material on a box or mesh fruit is refused.

use crate::common::{gripsim, scenario, text};
use crate::contact3d::line;
use gripsim::contact::compliant::{Material, PointContact};
use gripsim::contact::friction::{Coulomb, FrictionTable};
use gripsim::obstacle3::{Obstacle3, Pose3, Shape3};
use gripsim::rod3d::body3::Body3;
use gripsim::rod3d::rod::pos;
use gripsim::rod3d::run3::run;
use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3, World3};
use gripsim::scenario::three::Scenario3;

fn spec(points: Vec<[f64; 3]>, director: [f64; 3], section: Section3) -> Rod3Spec {
    Rod3Spec {
        points,
        director,
        rest_theta: Vec::new(),
        section,
        youngs_modulus: 1e9,
        shear_modulus: 1e9 / 2.6,
        density: 1000.0,
    }
}

fn apple() -> Material {
    Material::preset("apple").unwrap()
}

/// E* of a rigid prong on apple flesh.
fn e_star() -> f64 {
    1.0 / apple().compliance()
}

/// A three-node rigid-faced prong lying along x on the top of a compliant `shape` (centred at
/// the origin, its top at z = `top`), the h side vertical, its middle node pushed down by `f`,
/// after 100 steps of 1 ms. Stuck by friction (μ 1): frictionless, a point pressed on the top
/// of a sphere is in unstable equilibrium (it slides off).
fn press_on_top(shape: Shape3, top: f64, section: Section3, f: f64) -> World3 {
    let Section3::Rect { h, .. } = section else {
        panic!("a rect section")
    };
    let z = top + h / 2.0;
    let rod = spec(
        line(3, [-0.01, 0.0, z], [0.01, 0.0, z]),
        [0.0, 0.0, 1.0],
        section,
    );
    let mut w = World3::new([0.0, 0.0, 0.0]);
    w.friction = FrictionTable {
        default: Coulomb {
            mu_s: 1.0,
            mu_k: 1.0,
        },
        pairs: Vec::new(),
    };
    let mut sim = Sim3::new(Rod3::new(&rod));
    sim.load[pos(1) + 2] = -f;
    w.add_rod("prong", sim, section);
    w.obstacles
        .push(Obstacle3::new("apple", shape, Pose3::at([0.0; 3])));
    w.materials.push(Some(apple()));
    w.prong_compliance = vec![0.0];
    for _ in 0..100 {
        w.step(1e-3).unwrap();
    }
    w
}

#[test]
fn a_flat_face_pressed_on_a_compliant_sphere_settles_on_hertz() {
    let (r, h, f) = (0.0375, 0.002, 2.0);
    let section = Section3::Rect { b: 0.01, h };
    // Three nodes along x, the h side vertical: the middle node's face rests on the top of the
    // sphere (the others are 1.3 mm above it), pushed down by F at the middle node.
    let w = press_on_top(Shape3::Sphere { radius: r }, r, section, f);
    let pressed = w.pressed();
    assert_eq!(pressed.len(), 1, "{pressed:?}");
    let p = pressed[0];
    // Hertz (Johnson 1985 §4.2): a = (3FR/4E*)^{1/3}, p₀ = 3F/(2πa²), δ = a²/R.
    let a = (3.0 * f * r / (4.0 * e_star())).cbrt();
    let p0 = 3.0 * f / (2.0 * std::f64::consts::PI * a * a);
    let delta = a * a / r;
    // The indentation the node actually sits at: its height under the undeformed surface.
    let z = w.rods[0].q[pos(1) + 2];
    let sunk = r + h / 2.0 - z;
    let err = |x: f64, y: f64| (x / y - 1.0).abs();
    println!(
        "hertz: F {:.9} N, a {:.6e} m (Hertz {a:.6e}, err {:.2e}), p0 {:.6e} Pa (Hertz {p0:.6e}, \
         err {:.2e}), node sunk {sunk:.6e} m (Hertz δ {delta:.6e}, err {:.2e})",
        p.force,
        p.radii.0,
        err(p.radii.0, a),
        p.pressure,
        err(p.pressure, p0),
        err(sunk, delta)
    );
    assert!(err(p.force, f) < 1e-5, "{}", p.force);
    assert!(err(p.radii.0, a) < 0.02 && err(p.radii.1, a) < 0.02);
    assert!(err(p.pressure, p0) < 0.02);
    assert!(err(sunk, delta) < 0.02, "{sunk} vs {delta}");
    // Settled: at rest, the sphere's reaction on the node carries F.
    assert!(
        w.rods[0].v.iter().all(|v| v.abs() < 1e-6),
        "{:?}",
        w.rods[0].v
    );
    assert!((w.reactions[0][1].z - f).abs() < 1e-5 * f);
}

#[test]
fn a_flat_face_pressed_on_a_compliant_ellipsoid_settles_on_elliptical_hertz() {
    // Semi-axes (50, 30, 40) mm: at the top (0, 0, c) the principal curvatures are c/a² along x
    // and c/b² along y (closed form), so A = c/(2a²), B = c/(2b²).
    let (sa, h, f) = ([0.05, 0.03, 0.04], 0.002, 2.0);
    let section = Section3::Rect { b: 0.01, h };
    let w = press_on_top(Shape3::Ellipsoid { semi_axes: sa }, sa[2], section, f);
    let top = sa[2] + h / 2.0;
    let p = w.pressed()[0];
    let (ca, cb) = (sa[2] / (2.0 * sa[0] * sa[0]), sa[2] / (2.0 * sa[1] * sa[1]));
    let law = PointContact::new(ca, cb, e_star());
    let delta = law.approach(f);
    let (a, b) = law.radii(delta);
    let p0 = 3.0 * f / (2.0 * std::f64::consts::PI * a * b);
    let sunk = top - w.rods[0].q[pos(1) + 2];
    let err = |x: f64, y: f64| (x / y - 1.0).abs();
    println!(
        "ellipsoid: a {:.6e} b {:.6e} m (Hertz {a:.6e} {b:.6e}), p0 {:.6e} Pa (Hertz {p0:.6e}), \
         sunk {sunk:.6e} m (Hertz {delta:.6e}), e {:.6}",
        p.radii.0, p.radii.1, p.pressure, law.ecc
    );
    assert!(err(p.radii.0, a) < 0.02 && err(p.radii.1, b) < 0.02);
    assert!(err(p.pressure, p0) < 0.02 && err(sunk, delta) < 0.02);
    // An ellipse, elongated along the flatter x direction.
    assert!(p.radii.0 > 1.2 * p.radii.1);
}

#[test]
fn a_compliant_sphere_resting_on_a_table_settles_on_hertz() {
    // The fruit–table contact is compliant too: the sphere sinks by Hertz's δ under its weight.
    let r = 0.0375;
    let mut w = World3::new([0.0, 0.0, -9.81]);
    w.obstacles.push(Obstacle3::new(
        "table",
        Shape3::Plane,
        Pose3::at([0.0, 0.0, -r]),
    ));
    let mut body = Body3::new("apple", Shape3::Sphere { radius: r }, 905.0, [0.0; 3]).unwrap();
    body.material = Some(apple());
    w.bodies.push(body);
    // dt 5 ms: backward Euler damps the contact's rebound (ω Δt ≈ 1.2) within the run.
    for _ in 0..200 {
        w.step(5e-3).unwrap();
    }
    let f = w.bodies[0].mass * 9.81;
    let a = (3.0 * f * r / (4.0 * e_star())).cbrt();
    let (delta, p0) = (a * a / r, 3.0 * f / (2.0 * std::f64::consts::PI * a * a));
    let sunk = -w.bodies[0].centre().z;
    let on = w.pressed_on_obstacles();
    assert_eq!(on.len(), 1, "{on:?}");
    let (force, d, radii, p) = (on[0].force, on[0].indentation, on[0].radii, on[0].pressure);
    println!(
        "table: F {force:.9} N (mg {f:.9}), sunk {sunk:.6e} m (Hertz {delta:.6e}), a {:.6e} m \
         (Hertz {a:.6e}), p0 {p:.6e} Pa (Hertz {p0:.6e})",
        radii.0
    );
    let err = |x: f64, y: f64| (x / y - 1.0).abs();
    assert!(err(force, f) < 1e-6 && err(d, delta) < 1e-5);
    assert!(err(sunk, delta) < 0.02 && err(radii.0, a) < 0.02 && err(p, p0) < 0.02);
    assert!(w.bodies[0].v.norm() < 1e-6);
}

/// A vertical jaw: two weightless vertical pads pressed with `grip` N each at their middle node
/// on a free compliant sphere of mass `m` (apple, R 37.5 mm) under gravity, with μ_s = μ_k =
/// `mu`. Returns how far the sphere fell in 0.3 s (m).
fn jaw_fall(mu: f64, grip: f64) -> f64 {
    let (r, h) = (0.0375, 0.004);
    let section = Section3::Rect { b: 0.01, h };
    let g = 9.81;
    let mut w = World3::new([0.0, 0.0, -g]);
    w.friction = FrictionTable {
        default: Coulomb { mu_s: mu, mu_k: mu },
        pairs: Vec::new(),
    };
    for side in [-1.0, 1.0] {
        let x = side * (r + h / 2.0);
        // Along z, m₁ (the h side) along x: the face h/2 off the centreline towards the sphere.
        let rod = spec(
            line(3, [x, 0.0, -0.01], [x, 0.0, 0.01]),
            [1.0, 0.0, 0.0],
            section,
        );
        let mut sim = Sim3::new(Rod3::new(&rod));
        for i in 0..3 {
            // Weightless, the ends held in height, pressed at the middle.
            sim.load[pos(i) + 2] = sim.rod.mass[pos(i) + 2] * g;
            if i != 1 {
                sim.fixed[pos(i) + 2] = true;
                sim.target[pos(i) + 2] = sim.q[pos(i) + 2];
            }
        }
        sim.load[pos(1)] = -side * grip;
        w.add_rod(if side < 0.0 { "left" } else { "right" }, sim, section);
    }
    w.prong_compliance = vec![0.0; 2];
    let mut body = Body3::new("apple", Shape3::Sphere { radius: r }, 905.0, [0.0; 3]).unwrap();
    body.material = Some(apple());
    w.bodies.push(body);
    for _ in 0..300 {
        w.step(1e-3).unwrap();
    }
    -w.bodies[0].centre().z
}

#[test]
fn a_vertical_jaw_holds_a_compliant_sphere_down_to_mu_sum_n_equals_mg() {
    let grip = 2.0;
    let m = Body3::new("a", Shape3::Sphere { radius: 0.0375 }, 905.0, [0.0; 3])
        .unwrap()
        .mass;
    let mu_star = m * 9.81 / (2.0 * grip);
    // Bracket, then bisect the friction coefficient on held (fell < 1 mm) / dropped.
    let (mut lo, mut hi) = (0.5 * mu_star, 1.5 * mu_star);
    assert!(jaw_fall(lo, grip) > 0.01, "μ = {lo} must drop it");
    assert!(jaw_fall(hi, grip) < 1e-3, "μ = {hi} must hold it");
    for _ in 0..10 {
        let mid = 0.5 * (lo + hi);
        if jaw_fall(mid, grip) < 1e-3 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let found = 0.5 * (lo + hi);
    println!(
        "jaw: m {m:.6} kg, threshold mu {found:.6} vs m g / (2 N) = {mu_star:.6}: ratio {:.5}",
        found / mu_star
    );
    assert!((found / mu_star - 1.0).abs() < 0.02, "{found} vs {mu_star}");
}

fn apple_case(sets: &[&str]) -> gripsim::rod3d::run3::Summary3 {
    let path = scenario("3d-apple");
    let text = std::fs::read_to_string(&path).unwrap();
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let sc = Scenario3::from_str_with(&text, "3d-apple.toml", path.parent().unwrap(), &sets)
        .unwrap_or_else(|e| panic!("{e}"));
    run(&sc, None).unwrap_or_else(|e| panic!("{sets:?}: {e}"))
}

#[test]
fn the_apple_is_held_and_not_bruised_at_dt_over_2_and_twice_the_nodes() {
    for sets in [&[][..], &["solve.dt=1e-4"][..], &["prong.nodes=20"][..]] {
        let s = apple_case(sets);
        let g = s.grasp.as_ref().unwrap();
        let p = s.contact_pressure.as_ref().unwrap();
        println!(
            "3d-apple {sets:?}: held {} slip {:.3e} m, margin {:?}, peak force {:.4} N, p0 {:.4e} Pa \
             (ratio {:.3}), a {:.3e} m, indentation {:.3e} m",
            g.held,
            g.max_slip_m,
            g.safety_margin_at_lift,
            p.peak_contact_force_n,
            p.max_pressure_pa,
            p.bruise_ratio,
            p.half_width_at_max_m,
            p.max_indentation_m
        );
        assert!(g.held, "{sets:?}: {g:?}");
        assert!(
            !p.bruised && p.bruise_ratio > 0.2 && p.bruise_ratio < 1.0,
            "{p:?}"
        );
        assert!(
            p.max_indentation_m > 0.0 && p.peak_contact_force_n > 1.0,
            "{p:?}"
        );
    }
}

#[test]
fn a_material_on_a_box_or_mesh_fruit_is_refused_naming_the_key() {
    let src = std::fs::read_to_string(scenario("3d-apple")).unwrap();
    for (shape, kind) in [
        (
            r#"shape = { kind = "box", half = [0.03, 0.03, 0.03] }"#,
            "box",
        ),
        (
            r#"shape = { kind = "mesh", file = "meshes/berry.obj", scale = 1.0 }"#,
            "mesh",
        ),
    ] {
        let bad = src.replace(r#"shape = { kind = "sphere", radius = 0.0375 }"#, shape);
        assert_ne!(bad, src);
        let dir = std::env::temp_dir().join(format!("gripsim-compliant3d-{kind}"));
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        // A closed tetrahedron.
        let obj =
            "v 0.03 0 0\nv 0 0.03 0\nv 0 0 0.03\nv 0 0 0\nf 1 2 3\nf 1 4 2\nf 2 4 3\nf 3 4 1\n";
        std::fs::write(dir.join("meshes/berry.obj"), obj).unwrap();
        let file = dir.join("bad.toml");
        std::fs::write(&file, &bad).unwrap();
        let out = gripsim()
            .arg("run")
            .arg(&file)
            .arg("--no-record")
            .output()
            .unwrap();
        let msg = text(&out);
        assert_eq!(out.status.code(), Some(2), "{kind}: {msg}");
        assert!(msg.contains("fruit.material"), "{kind}: {msg}");
        assert!(
            msg.contains(kind) && msg.contains("sphere"),
            "{kind}: {msg}"
        );
    }
}

/// A compliant fruit may start at rest on its table, sunk by its Hertz indentation under its
/// weight (3d-apple: 2.770e-4 m), but not deeper: 1 mm in is an overlap, refused with the depth.
#[test]
fn a_compliant_fruit_may_start_resting_in_its_table_but_not_deeper() {
    let ok = gripsim()
        .arg("validate")
        .arg(scenario("3d-apple"))
        .output()
        .unwrap();
    assert_eq!(ok.status.code(), Some(0), "{}", text(&ok));
    let deep = gripsim()
        .arg("validate")
        .arg(scenario("3d-apple"))
        .args(["--set", "obstacle.0.at=[0.0, 0.0, -0.0965]"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&deep.stderr);
    assert_eq!(deep.status.code(), Some(2), "{}", text(&deep));
    assert!(
        err.contains("fruit.centre") && err.contains("starts 1.000e-3 m inside"),
        "{err}"
    );
}

/// `gripsim run --check` on a 3D compliant apple applies the bruise rule to the live contact
/// pressures, as on a planar run: squeezed with 5 N per finger both prongs' node 4 go 1.14x
/// over the bruise pressure (flagged, exit 1, in the JSON too); as shipped (0.90x) it is clean;
/// `[expect] bruised = true` turns the first into "expected" and the second into "missing".
#[test]
fn a_live_3d_check_flags_a_bruise() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("check.json");
    let run = |sets: &[&str]| {
        let mut c = gripsim();
        c.args(["run", "--no-record", "-q", "--check", "--check-json"])
            .arg(&json)
            .arg(scenario("3d-apple"));
        for s in sets {
            c.args(["--set", s]);
        }
        c.output().unwrap()
    };
    let squeezed = run(&["move.0.force=5"]);
    let out = text(&squeezed);
    assert_eq!(squeezed.status.code(), Some(1), "{out}");
    assert!(
        out.contains("bruise        2") && out.contains("1.14x the threshold"),
        "{out}"
    );
    assert!(
        out.contains("rod finger0 node 4") && out.contains("rod finger1 node 4"),
        "{out}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["bruise"].as_array().unwrap().len(), 2, "{report}");
    assert_eq!(report["flagged"], true);

    let shipped = run(&[]);
    assert_eq!(shipped.status.code(), Some(0), "{}", text(&shipped));

    let expected = run(&["move.0.force=5", "expect.bruised=true"]);
    let out = text(&expected);
    assert_eq!(expected.status.code(), Some(0), "{out}");
    assert!(
        out.contains("expected  bruised as the scenario expects"),
        "{out}"
    );
    let missing = run(&["expect.bruised=true"]);
    let out = text(&missing);
    assert_eq!(missing.status.code(), Some(1), "{out}");
    assert!(out.contains("bruise    missing"), "{out}");
}
