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
    /// Newton failures (step, rod, node, reason) that cost a dt back-off.
    failures: Vec<(u64, usize, usize, String)>,
}

impl Observer for Trace {
    fn on_event(&mut self, e: &Event<'_>) {
        if let Event::NewtonFailed {
            step,
            rod,
            node,
            reason,
            ..
        } = e
        {
            self.failures.push((*step, *rod, *node, reason.to_string()));
        }
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
                    gripsim::events::xy(b.position),
                    gripsim::events::xy(b.velocity),
                    b.angular_velocity[2],
                    gripsim::events::xy(b.contact_force),
                    b.contact_torque[2],
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
    assert!(
        (c.indentation - delta).abs() < 1e-6 * delta,
        "{}",
        c.indentation
    );
    assert!((c.peak_pressure - law.peak_pressure(m * G)).abs() < 1e-6 * c.peak_pressure);
}

/// The run's summary (as `gripsim run --summary` writes it).
fn summary(sc: &Scenario) -> gripsim::record::summary::Summary {
    let mut sim = Simulation::new(sc);
    let mut col = gripsim::record::summary::SummaryCollector::new();
    sim.run(&mut col).unwrap_or_else(|e| panic!("{e}"));
    col.finish(&sim.stats, 0.0)
}

#[test]
fn a_compliant_fruit_dropped_from_10_cm_bruises_and_from_1_cm_does_not() {
    // Apple flesh (E 1.5 MPa, bruising above 0.1 MPa) on a rigid table, the impact resolved
    // in time (dt 1e-5 s: ~400 steps per contact) and at half that step.
    let mut peaks = Vec::new();
    for (h, bruised) in [(0.10, true), (0.01, false)] {
        for dt in ["1e-5", "5e-6"] {
            let t_end = (2.0 * h / G).sqrt() + 0.01;
            let sc = scenario(
                DISC_ON_TABLE,
                &[
                    &format!("obstacle.1.center=[0.0,{}]", 0.04 + h),
                    &format!("solve.t_end={t_end}"),
                    &format!("solve.dt={dt}"),
                ],
            );
            let s = summary(&sc);
            let p = s.contact_pressure.expect("the table pressed the fruit");
            println!(
                "drop {h} m, dt {dt}: peak force {:.3} N, p0 {:.1} kPa ({:.3} of the bruise \
                 threshold) on {:?}, bruised {}",
                p.peak_contact_force_n,
                p.max_pressure_pa / 1e3,
                p.bruise_ratio,
                p.max_pressure_node.rod,
                p.bruised
            );
            assert_eq!(p.bruised, bruised, "drop from {h} m");
            assert_eq!(p.max_pressure_node.rod, "table");
            peaks.push(p.max_pressure_pa);
        }
    }
    // The peak pressure converges in dt (backward Euler's damping of the impact: first order).
    for pair in peaks.chunks(2) {
        assert!((pair[0] - pair[1]).abs() < 0.02 * pair[1], "{pair:?}");
    }
}

fn shipped(name: &str, sets: &[&str]) -> Scenario {
    let path = format!("{}/scenarios/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(std::path::Path::new(&path), &sets).unwrap_or_else(|e| panic!("{e}"))
}

/// The jaw grasp's S-curve lift: peak acceleration 5.7735 D / T² (D = 4 cm, T = 0.6 s); friction
/// holds the fruit iff μ_s ΣN ≥ m (g + a), a safety margin μ_s ΣN / (m g) ≥ 1 + a/g.
fn lift_threshold() -> f64 {
    let a = 10.0 / 3.0f64.sqrt() * 0.04 / 0.36;
    1.0 + a / G
}

#[test]
fn jaws_hold_a_compliant_fruit_exactly_where_friction_carries_it() {
    // The shipped jaw grasp with an apple's flesh on the free fruit: the friction of the jaws
    // scaled so that the margin at the lift is 2 % above and below m (g + a) / (m g).
    let need = lift_threshold();
    for integrator in ["backward_euler", "tr_bdf2"] {
        let base = [
            "obstacle.1.material=apple".to_string(),
            format!("solve.integrator={integrator}"),
        ];
        let sets: Vec<&str> = base.iter().map(String::as_str).collect();
        let s = summary(&shipped("jaw-grasp-hold", &sets));
        let g = s.grasp.unwrap();
        let m0 = g.safety_margin_at_lift.unwrap();
        let p = s.contact_pressure.expect("the jaws press the apple");
        println!(
            "{integrator}: margin at the lift {m0:.4} (mu_s 0.6), held {}, peak p0 {:.1} kPa",
            g.held,
            p.max_pressure_pa / 1e3
        );
        assert!(g.held && !p.bruised);
        for (f, held) in [(1.02, true), (0.98, false)] {
            let mu = 0.6 * f * need / m0;
            let mut sets = base.to_vec();
            for k in 0..2 {
                sets.push(format!("friction.pair.{k}.mu_s={mu}"));
                sets.push(format!("friction.pair.{k}.mu_k={}", 0.8 * mu));
            }
            let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
            let g = summary(&shipped("jaw-grasp-hold", &sets)).grasp.unwrap();
            println!(
                "  {f} x threshold: margin {:.4} (needed {need:.4}): held {} dropped {}",
                g.safety_margin_at_lift.unwrap(),
                g.held,
                g.dropped
            );
            assert_eq!((g.held, g.dropped), (held, !held), "{integrator} {f}");
        }
    }
}

/// Over windows of every length from the start: Δ(m v) = Σ F dt + m g t and Δ(J ω) = Σ τ dt,
/// with F and τ the contact force and moment the step reports on the body. Returns the worst
/// relative error (of m g t, and of m g t × the body's radius for the moment).
fn momentum_error(tr: &Trace, m: f64, j: f64, radius: f64) -> f64 {
    let (mut px, mut py, mut l) = (0.0, 0.0, 0.0);
    let (v0, w0) = (tr.body[0].1, tr.body[0].2);
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
        let er = (j * (w - w0) - l).abs() / (scale * radius);
        worst = worst.max(ex).max(ey).max(er);
    }
    worst
}

#[test]
fn a_compliant_fruits_momentum_changes_by_its_contact_and_gravity_impulses() {
    // The jaw grasp on an apple: squeezed (compliant contacts held by friction), lifted, and
    // its own compliant contact with the table; then with friction too weak, so it slides.
    for (mu, points) in [
        ("0.6", "nodes"),
        ("0.3", "nodes"),
        ("0.6", "edges"),
        ("0.3", "edges"),
    ] {
        let sets = [
            "obstacle.1.material=apple".to_string(),
            format!("contact.points={points}"),
            format!("friction.pair.0.mu_s={mu}"),
            format!("friction.pair.1.mu_s={mu}"),
            "friction.pair.0.mu_k=0.25".to_string(),
            "friction.pair.1.mu_k=0.25".to_string(),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let sc = shipped("jaw-grasp-hold", &sets);
        let (m, j) = (sc.bodies[0].mass, sc.bodies[0].inertia);
        let (_, tr) = run(&sc);
        let worst = momentum_error(&tr, m, j, 0.04);
        let slid = tr
            .contacts
            .iter()
            .flatten()
            .any(|c| c.rod != usize::MAX && c.normal_force > 0.0 && !c.stuck);
        println!(
            "mu_s {mu}, {points}: momentum balance worst relative error {worst:.2e}, slid {slid}, \
             Newton failures {:?}",
            tr.failures
        );
        assert!(worst < 1e-9, "{worst:e}");
    }
}

#[test]
fn a_stiffer_fruit_approaches_the_rigid_fruit_monotonically() {
    // The jaw grasp with fruit flesh of growing stiffness: the margin at the lift (the grip
    // the squeeze ends on) grows monotonically towards its limit, and every run holds. The
    // limit is the rigid fruit's run but for the prong's own face compliance, which the law's
    // E* keeps as E_fruit → ∞ (E* → E_prong / (1 − ν_p²) = 67 MPa for these jaws): within 0.1 %.
    let rigid = summary(&shipped("jaw-grasp-hold", &[])).grasp.unwrap();
    let m_rigid = rigid.safety_margin_at_lift.unwrap();
    let mut last = 0.0;
    for e in [1e6, 1e7, 1e8, 1e9, 1e12] {
        let set = format!("obstacle.1.material={{E={e},nu=0.3,bruise_pressure=1e5}}");
        let g = summary(&shipped("jaw-grasp-hold", &[&set])).grasp.unwrap();
        let m = g.safety_margin_at_lift.unwrap();
        println!(
            "E_fruit {e:e}: margin at the lift {m:.6} (rigid {m_rigid:.6}, {:+.3} %), held {}",
            100.0 * (m / m_rigid - 1.0),
            g.held
        );
        assert!(g.held && !g.dropped);
        assert!(m > last, "not monotone at E = {e:e}: {m} after {last}");
        last = m;
    }
    assert!(
        (last - m_rigid).abs() < 1e-3 * m_rigid,
        "{last} vs {m_rigid}"
    );
    assert!(rigid.held);
}

#[test]
fn a_material_on_a_shape_that_cannot_carry_one_is_a_located_error() {
    let bin = env!("CARGO_BIN_EXE_gripsim");
    let d = tempfile::tempdir().unwrap();
    let table = "[[obstacle]]\nname = \"table\"\nkind = \"plane\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n";
    let cases = [
        (
            format!("{table}material = \"apple\"\n"),
            vec![
                "obstacle.0.material",
                "\"apple\"",
                "plane",
                "cannot carry a material",
            ],
        ),
        (
            format!(
                "{table}[[obstacle]]\nname = \"pear\"\nkind = \"ellipse\"\ncenter = [0.0, 0.05]\n\
                 a = 0.03\nb = 0.04\nfree = true\nmass = 0.2\nmaterial = \"apple\"\n"
            ),
            vec![
                "obstacle.1.material",
                "free ellipse",
                "circles only",
                "radius",
            ],
        ),
    ];
    for (i, (body, words)) in cases.iter().enumerate() {
        let path = d.path().join(format!("s{i}.toml"));
        std::fs::write(
            &path,
            format!("name = \"m\"\n[solve]\nmode = \"dynamic\"\nt_end = 0.01\ndt = 1e-4\n{body}"),
        )
        .unwrap();
        let out = std::process::Command::new(bin)
            .arg("validate")
            .arg(&path)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("s{i}.toml")), "{err}");
        for w in words {
            assert!(err.contains(w), "{w:?} in {err}");
        }
    }
}
