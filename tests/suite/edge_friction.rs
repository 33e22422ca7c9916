//! Issue 32: planar edge contact with Coulomb friction and on free bodies
//! (`[contact] points = "edges"`): a bar on two small discs sticks below the friction angle and
//! slides at the Coulomb rate above it, its edge forces closing the momentum balance; friction of
//! a segment on a free disc exchanges momentum exactly; a throw settles; the shipped grasps in
//! edge mode.

use gripsim::events::{ContactView, Event, Observer};
use gripsim::record::summary::{Summary, SummaryCollector};
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

/// A body's position, velocity, angular velocity, contact force and contact torque.
type BodyState = ([f64; 2], [f64; 2], f64, [f64; 2], f64);

/// Every step of a run: rod 0's positions and velocities, body 0, the contacts; event counts.
#[derive(Default)]
struct Trace {
    t: Vec<f64>,
    dt: Vec<f64>,
    q: Vec<Vec<f64>>,
    u: Vec<Vec<f64>>,
    body: Vec<BodyState>,
    contacts: Vec<Vec<ContactView>>,
    passes: Vec<u32>,
    edge_switches: usize,
    node_switches: usize,
    handed_over: usize,
    added: usize,
    released: usize,
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
                passes,
                ..
            } => {
                self.t.push(*t);
                self.dt.push(*dt);
                self.passes.push(*passes);
                if let Some(r) = rods.first() {
                    self.q.push(r.q.to_vec());
                    self.u.push(r.u.to_vec());
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
            Event::FrictionChanged(f) if f.segment != usize::MAX => self.edge_switches += 1,
            Event::FrictionChanged(_) => self.node_switches += 1,
            Event::ConstraintAdded(_) => self.added += 1,
            Event::ConstraintReleased(_, why) => {
                self.released += 1;
                if *why == gripsim::events::ReleaseReason::HandedOver {
                    self.handed_over += 1;
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

fn summary(sc: &Scenario) -> Summary {
    let mut sim = Simulation::new(sc);
    let mut col = SummaryCollector::new();
    sim.run(&mut col).unwrap_or_else(|e| panic!("{e}"));
    col.finish(&sim.stats, 0.0)
}

const G: f64 = 9.81;

/// A stiff 3-node bar lying on two small fixed discs, each under the middle of one of its
/// segments (edge contacts at s = 1/2), gravity tilted by θ along the bar. With its masses
/// lumped (1/4, 1/2, 1/4) the supports at s = 1/2 carry it without bending it; sliding, the
/// load shifts to the leading disc and the bar bends a little (hence E = 2e13 Pa: nearly rigid).
fn bar_on_discs(theta_deg: f64, mu_s: f64, mu_k: f64) -> Scenario {
    let th = theta_deg.to_radians();
    scenario(
        &format!(
            r#"
name = "bar-on-discs"
[solve]
t_end = 0.1
dt = 1e-4
gravity = [{gx:e}, {gy:e}]
[[rod]]
name = "bar"
nodes = 3
shape = {{ kind = "straight", start = [-0.05, 0.0], end = [0.05, 0.0] }}
E = 2e13
section = {{ kind = "rect", b = 0.01, h = 0.005 }}
density = 7800.0
[contact]
surface = "centreline"
points = "edges"
[[obstacle]]
name = "left"
kind = "circle"
center = [-0.025, -0.005]
radius = 0.005
[[obstacle]]
name = "right"
kind = "circle"
center = [0.025, -0.005]
radius = 0.005
[friction]
mu_s = {mu_s}
mu_k = {mu_k}
"#,
            gx = -G * th.sin(),
            gy = -G * th.cos()
        ),
        &[],
    )
}

/// Σ m_i Δu_i/Δt − M g − Σ (contact forces) of rod 0 at step k (N): the discrete momentum
/// balance, which the reported forces must close.
fn balance(sim: &Simulation, tr: &Trace, k: usize) -> [f64; 2] {
    let rod = &sim.rods[0];
    let g = sim.scenario.solve.gravity;
    let mut out = [0.0; 2];
    for i in 0..rod.n {
        for a in 0..2 {
            let du = tr.u[k][2 * i + a] - tr.u[k - 1][2 * i + a];
            out[a] += rod.mass[i] * (du / tr.dt[k] - g[a]);
        }
    }
    for c in tr.contacts[k].iter().filter(|c| c.rod == 0) {
        let t = [-c.normal[1], c.normal[0]];
        for a in 0..2 {
            out[a] -= c.normal_force * c.normal[a] + c.friction_force * t[a];
        }
    }
    out
}

#[test]
fn a_bar_on_two_small_discs_sticks_below_the_friction_angle() {
    for (theta, mu_s) in [(30.0, 0.6), (20.0, 0.4), (10.0, 0.18)] {
        let th: f64 = f64::to_radians(theta);
        let (sim, tr) = run(&bar_on_discs(theta, mu_s, 0.8 * mu_s));
        let mass: f64 = sim.rods[0].mass.iter().sum();
        let q0 = &tr.q[0];
        let moved =
            tr.q.iter()
                .flat_map(|q| q.iter().zip(q0).map(|(a, b)| (a - b).abs()))
                .fold(0.0, f64::max);
        let mut worst_ratio = 0.0f64;
        let mut worst_balance = 0.0f64;
        for k in 1..tr.t.len() {
            let cs = &tr.contacts[k];
            assert_eq!(cs.len(), 2, "two edge contacts at step {k}: {cs:?}");
            for c in cs {
                // At the foot of the perpendicular from the disc's centre (the first step's
                // contact is caught where gravity's first predictor put the bar).
                assert!(c.stuck && c.segment != usize::MAX, "{c:?}");
                assert!((c.weight - 0.5).abs() < 1e-5, "{c:?}");
            }
            let n: f64 = cs.iter().map(|c| c.normal_force).sum();
            let f: f64 = cs.iter().map(|c| c.friction_force).sum();
            worst_ratio = worst_ratio.max((f.abs() / n - th.tan()).abs() / th.tan());
            let b = balance(&sim, &tr, k);
            worst_balance = worst_balance.max(b[0].hypot(b[1]) / (mass * G));
        }
        println!(
            "θ = {theta}°, μs = {mu_s}: moved {moved:.3e} m, |F_t|/F_n off tan θ by {worst_ratio:.2e}, \
             momentum balance off by {worst_balance:.2e} M g, {} edge stick→slip",
            tr.edge_switches
        );
        assert!(moved < 1e-12, "θ = {theta}: moved {moved:e} m");
        assert_eq!(tr.edge_switches, 0);
        // (The first step stops the falling bar: its ringing, 1e-14 m, is 1e-9 of M g.)
        assert!(worst_ratio < 1e-6, "{worst_ratio:e}");
        assert!(worst_balance < 1e-9, "{worst_balance:e}");
    }
}

#[test]
fn a_bar_on_two_small_discs_slides_with_the_kinetic_acceleration() {
    for (theta, mu_s, mu_k) in [(30.0, 0.4, 0.3), (45.0, 0.5, 0.2), (20.0, 0.3, 0.1)] {
        let th: f64 = f64::to_radians(theta);
        let expect = G * (th.sin() - mu_k * th.cos());
        // Half the run: the middle node does not reach the leading disc.
        let mut sc = bar_on_discs(theta, mu_s, mu_k);
        sc.solve.t_end = 0.05;
        let (sim, tr) = run(&sc);
        let rod = &sim.rods[0];
        let mass: f64 = rod.mass.iter().sum();
        // The centre of mass's speed down the slope (−x).
        let speed: Vec<f64> =
            tr.u.iter()
                .map(|u| -(0..rod.n).map(|i| rod.mass[i] * u[2 * i]).sum::<f64>() / mass)
                .collect();
        let n = speed.len();
        let (mut worst, mut worst_balance) = (0.0f64, 0.0f64);
        for k in 2..n {
            let a = (speed[k] - speed[k - 1]) / tr.dt[k];
            worst = worst.max(((a - expect) / expect).abs());
            let b = balance(&sim, &tr, k);
            worst_balance = worst_balance.max(b[0].hypot(b[1]) / (mass * G));
            for c in &tr.contacts[k] {
                assert!(!c.stuck && c.segment != usize::MAX, "{c:?}");
                assert!(
                    (c.friction_force.abs() - mu_k * c.normal_force).abs() < 1e-12,
                    "{c:?}"
                );
            }
        }
        let flat = tr.q.iter().flat_map(|q| q.chunks(2).map(|p| p[1].abs()));
        let off = flat.fold(0.0, f64::max);
        println!(
            "θ = {theta}°: a worst step rel. error {worst:.2e} vs g(sinθ − μk cosθ) = {expect:.6}; \
             balance {worst_balance:.2e} M g; bar off the discs' tops by {off:.2e} m"
        );
        assert!(worst < 1e-6, "θ = {theta}: rel. error {worst:e}");
        assert!(worst_balance < 1e-9, "{worst_balance:e}");
        assert!(tr.edge_switches >= 2, "{}", tr.edge_switches);
        assert!(off < 1e-9, "{off:e}");
    }
}

/// Momentum of a free body over a run: Δ(m v) = Σ (F + m g) Δt and Δ(J ω) = Σ τ Δt over windows
/// of every length from the start, F and τ the step's reported contact force and torque on it;
/// the worst error relative to m g t (and m g t times the body's size for the rotation).
fn body_momentum_error(tr: &Trace, m: f64, j: f64, g: [f64; 2], size: f64) -> f64 {
    let (mut px, mut py, mut l) = (0.0, 0.0, 0.0);
    let (v0, w0) = (tr.body[0].1, tr.body[0].2);
    let mut worst = 0.0f64;
    for k in 1..tr.body.len() {
        let (_, v, w, f, tq) = tr.body[k];
        let dt = tr.dt[k];
        px += (f[0] + m * g[0]) * dt;
        py += (f[1] + m * g[1]) * dt;
        l += tq * dt;
        let scale = m * G * tr.t[k];
        let ex = (m * (v[0] - v0[0]) - px).abs() / scale;
        let ey = (m * (v[1] - v0[1]) - py).abs() / scale;
        let er = (j * (w - w0) - l).abs() / (scale * size);
        worst = worst.max(ex).max(ey).max(er);
    }
    worst
}

/// A stiff bar lying across a free disc (on a frictionless table) and a small fixed peg, thrown
/// along itself: friction on the disc's top, between the bar's nodes, drags and spins it.
const BAR_ON_FREE_DISC: &str = r#"
name = "bar-on-free-disc"
[solve]
t_end = 0.06
dt = 1e-4
[[rod]]
name = "bar"
nodes = 3
shape = { kind = "straight", start = [-0.07, 0.04], end = [0.03, 0.04] }
E = 2e11
section = { kind = "rect", b = 0.01, h = 0.005 }
density = 7800.0
velocity = [0.2, 0.0]
[contact]
surface = "centreline"
points = "edges"
[[obstacle]]
name = "table"
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[obstacle]]
name = "peg"
kind = "circle"
center = [-0.055, 0.035]
radius = 0.005
[[obstacle]]
name = "disc"
kind = "circle"
center = [0.0, 0.02]
radius = 0.02
free = true
mass = 0.05
[friction]
mu_s = 0.5
mu_k = 0.4
[[friction.pair]]
between = ["disc", "table"]
mu_s = 0.0
mu_k = 0.0
"#;

#[test]
fn edge_friction_on_a_free_disc_exchanges_momentum_exactly() {
    let sc = scenario(BAR_ON_FREE_DISC, &[]);
    let (m, j) = (sc.bodies[0].mass, sc.bodies[0].inertia);
    let (sim, tr) = run(&sc);
    let worst = body_momentum_error(&tr, m, j, sim.scenario.solve.gravity, 0.02);
    // The edge contact on the disc: how many steps, stuck and sliding; never a node contact.
    let on_disc: Vec<&ContactView> = tr
        .contacts
        .iter()
        .flatten()
        .filter(|c| c.rod == 0 && c.obstacle == 2)
        .collect();
    let edge = on_disc
        .iter()
        .filter(|c| c.segment == 1 && c.body == 0)
        .count();
    let stuck = on_disc.iter().filter(|c| c.stuck).count();
    let mass: f64 = sim.rods[0].mass.iter().sum();
    let worst_balance = (1..tr.t.len())
        .map(|k| {
            let b = balance(&sim, &tr, k);
            b[0].hypot(b[1]) / (mass * G)
        })
        .fold(0.0, f64::max);
    let b = &sim.bodies[0];
    let per_step = sim.stats.newton_iterations as f64 / sim.stats.steps as f64;
    println!(
        "disc: {} steps with the bar's edge contact ({stuck} stuck), v = {:?}; body momentum \
         error {worst:.2e}; the bar's balance {worst_balance:.2e} M g; {} edge switches; \
         penetration {:.2e} m; {per_step:.2} Newton iterations a step",
        edge, b.v, tr.edge_switches, sim.stats.max_penetration
    );
    // The coupled Jacobian is exact: Newton converges in a couple of updates a step.
    assert!(per_step < 3.0, "{per_step}");
    assert!(
        edge > 400 && edge == on_disc.len(),
        "{edge} of {}",
        on_disc.len()
    );
    assert!(stuck > 0 && stuck < edge, "{stuck}");
    assert!(
        b.v[0] > 1e-3 && b.v[2] < -0.05,
        "dragged and spun: {:?}",
        b.v
    );
    assert!(worst < 1e-9, "{worst:e}");
    assert!(worst_balance < 1e-9, "{worst_balance:e}");
    assert!(sim.stats.max_penetration < 1e-9);
}

/// A soft prong thrown at a fixed fruit on a table with friction, tumbling on both.
fn throw(points: &str, vx: f64, spin: f64) -> Scenario {
    scenario(
        &format!(
            r#"
name = "throw"
[solve]
t_end = 0.25
dt = 1e-4
[[rod]]
name = "prong"
nodes = 8
shape = {{ kind = "straight", start = [-0.06, 0.16], end = [0.01, {y1}] }}
E = 5e6
section = {{ kind = "rect", b = 0.02, h = 0.008 }}
density = 1100.0
velocity = [{vx}, -1.5]
[contact]
points = "{points}"
surface = "face"
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
[[obstacle]]
name = "block"
kind = "polygon"
vertices = [[0.05, 0.0], [0.09, 0.0], [0.09, 0.03], [0.05, 0.03]]
[friction]
mu_s = 0.6
mu_k = 0.5
"#,
            y1 = 0.16 + spin
        ),
        &[],
    )
}

#[test]
fn a_prong_thrown_on_a_fruit_and_a_table_with_friction_settles_every_step() {
    for (vx, spin) in [(0.5, 0.0), (1.0, 0.02), (-0.3, -0.01)] {
        let sc = throw("edges", vx, spin);
        let (sim, tr) = run(&sc);
        let edge_steps = tr
            .contacts
            .iter()
            .filter(|cs| cs.iter().any(|c| c.segment != usize::MAX))
            .count();
        let most = tr.passes.iter().max().copied().unwrap_or(0);
        println!(
            "vx {vx}, tilt {spin}: {} steps, {edge_steps} with an edge contact; {} edge and {} node \
             stick/slip switches, {} hand-overs; most contact changes in a step {most}; \
             penetration {:.2e} m",
            tr.t.len() - 1,
            tr.edge_switches,
            tr.node_switches,
            tr.handed_over,
            sim.stats.max_penetration
        );
        assert!((sim.t - 0.25).abs() < 1e-12, "ran to the end");
        assert!(edge_steps > 20, "{edge_steps}");
        assert!(tr.edge_switches > 0);
        assert!(
            sim.stats.max_penetration < 1e-9,
            "{}",
            sim.stats.max_penetration
        );
    }
}

#[test]
fn pick_and_place_in_edge_mode_holds_the_fruit_without_cutting_into_it() {
    let face = ["contact.surface=face"];
    let nodes = summary(&shipped("pick-and-place", &face));
    let edges = summary(&shipped(
        "pick-and-place",
        &["contact.surface=face", "contact.points=edges"],
    ));
    let (gn, ge) = (nodes.grasp.unwrap(), edges.grasp.unwrap());
    let (mn, me) = (gn.min_safety_margin.unwrap(), ge.min_safety_margin.unwrap());
    println!(
        "pick-and-place, face: nodes margin {mn:.4} (lift {:.4}), grip {:.4} N, penetration {:.2e} m \
         (nodes only); edges margin {me:.4} (lift {:.4}), grip {:.4} N, penetration {:.2e} m (nodes \
         and segments); steps {} / {}, Newton iterations {} / {}, contact passes {} / {}",
        gn.safety_margin_at_lift.unwrap(),
        gn.peak_grip_force_n,
        nodes.max_penetration_m,
        ge.safety_margin_at_lift.unwrap(),
        ge.peak_grip_force_n,
        edges.max_penetration_m,
        nodes.steps,
        edges.steps,
        nodes.newton_iterations,
        edges.newton_iterations,
        nodes.contact_passes,
        edges.contact_passes,
    );
    assert!(gn.held && ge.held && !ge.dropped);
    assert!(
        edges.max_penetration_m <= 1e-9,
        "{}",
        edges.max_penetration_m
    );
    assert!((me - mn).abs() < 0.05 * mn, "{me} vs {mn}");
}

/// Two stiff straight jaws 2 m long, clamped at both ends, squeeze a free 8 cm disc (0.1 kg,
/// no table) at their middle, the middle of their segment 100 (nodes 9.95 mm apart): they
/// close by a prescribed travel (a squeeze of margin ≈ 1.2 at μ = 0.6 stops the falling disc), settle,
/// and then (with `lift`) accelerate upwards at `lift` m/s² for a second. Why this rig: the
/// disc slides along the jaws, so the normal force must not depend on where along a jaw the
/// contact is. On a cantilever jaw it does (compliance ∝ a³: 3 Δa/a, some 11 % for 2.5 mm at
/// 7 cm), which at a margin of 0.9995 runs away; at the middle of a clamped–clamped beam the
/// compliance is stationary (relative change 12 (Δa/L)²), and so is the polyline's at the
/// middle of a segment (between nodes it is stiffer by 12 (Δ/L)² · 2 s (1 − s), Δ the node
/// spacing): the disc slides from 1.45 mm above the middle to 1.4 mm below it, and its normal
/// force changes by about 1e-5. Light jaws (ρ = 10 kg/m³): their inertia does not load them
/// when they accelerate.
fn long_jaws(points: &str, lift: Option<f64>) -> Scenario {
    let lift_phase = match lift {
        Some(a) => format!(
            r#"
[[actuator.phase]]
name = "lift"
kind = "translate"
direction = [0.0, 1.0]
law = "constant_acceleration"
acceleration = {a:e}
end = {{ duration = 1.0 }}
"#
        ),
        None => String::new(),
    };
    scenario(
        &format!(
            r#"
name = "long-jaws"
[solve]
t_end = {t_end}
dt = 1e-4
[[rod]]
name = "right"
nodes = 202
shape = {{ kind = "straight", start = [0.0452, 1.0], end = [0.0452, -1.0] }}
E = 2e11
section = {{ kind = "rect", b = 0.02, h = 0.01 }}
density = 10.0
loss_factor = 0.1
clamped = [0, 1, 200, 201]
actuator = "gripper"
[[rod]]
name = "left"
nodes = 202
shape = {{ kind = "straight", start = [-0.0452, 1.0], end = [-0.0452, -1.0] }}
E = 2e11
section = {{ kind = "rect", b = 0.02, h = 0.01 }}
density = 10.0
loss_factor = 0.1
clamped = [0, 1, 200, 201]
actuator = "gripper"
mirror = true
[contact]
surface = "face"
points = "{points}"
[[obstacle]]
name = "fruit"
kind = "circle"
center = [0.0, 0.0018]
radius = 0.04
free = true
mass = 0.1
[friction]
mu_s = 0.6
mu_k = 0.6
[[actuator]]
name = "gripper"
mirror_x = 0.0
[[actuator.phase]]
name = "close"
kind = "translate"
direction = [-1.0, 0.0]
law = "constant_velocity"
speed = 0.05
end = {{ travel = 0.000323 }}
[[actuator.phase]]
name = "settle"
kind = "hold"
end = {{ duration = 0.1 }}
{lift_phase}
"#,
            t_end = if lift.is_some() { 1.1 } else { 0.1 }
        ),
        &[],
    )
}

/// Σ N of the prongs on the fruit at step k.
fn grip(tr: &Trace, k: usize) -> f64 {
    tr.contacts[k]
        .iter()
        .filter(|c| c.rod != usize::MAX && c.obstacle == 0)
        .map(|c| c.normal_force)
        .sum()
}

#[test]
fn a_disc_between_stiff_jaws_at_a_margin_just_below_one_slides_at_the_coulomb_rate() {
    let (m, mu) = (0.1, 0.6);
    // The squeeze the settled jaws hold the disc with (the runs are deterministic: the same
    // until the lift begins).
    let (_, settle) = run(&long_jaws("edges", None));
    let k0 = settle.t.len() - 1;
    let n0 = grip(&settle, k0);
    let margin0 = mu * n0 / (m * G);
    // Accelerating up at a, the disc's weight is m (g + a): a margin of 0.9995 of that.
    let lift = G * (margin0 / 0.9995 - 1.0);
    let expect = 0.5 * (G + lift) * (1.0 - 0.9995);
    let slide = |points: &str| {
        let (sim, tr) = run(&long_jaws(points, Some(lift)));
        let rel = |k: usize| tr.body[k].0[1] - tr.q[k][1];
        let end = tr.t.len() - 1;
        let d = rel(k0) - rel(end);
        let n_end = grip(&tr, end);
        let touching = tr.contacts[end].iter().any(|c| c.rod != usize::MAX);
        (d, n_end, touching, sim.bodies[0].pose.c, tr)
    };
    let (d_edges, n_edges, touch_edges, _, tr) = slide("edges");
    let edge_steps = tr.contacts[k0..]
        .iter()
        .filter(|cs| {
            cs.iter()
                .any(|c| c.segment != usize::MAX && c.obstacle == 0)
        })
        .count();
    let (d_nodes, n_nodes, touch_nodes, c_nodes, _) = slide("nodes");
    println!(
        "settled squeeze Σ N = {n0:.6} N (margin {margin0:.5}); lift at {lift:.5} m/s²: the Coulomb \
         rate ½ (g + a)(1 − 0.9995) = {expect:.5e} m in the second. Edges: slid {d_edges:.5e} m \
         ({:+.2} %), Σ N at the end {n_edges:.6} N, touching {touch_edges}, {edge_steps} steps on \
         segments. Nodes only: slid {d_nodes:.5e} m, Σ N at the end {n_nodes:.6} N, touching \
         {touch_nodes}, the disc at {c_nodes:?}",
        100.0 * (d_edges / expect - 1.0)
    );
    assert!(margin0 > 1.05 && margin0 < 1.5, "{margin0}");
    assert!(
        (d_edges / expect - 1.0).abs() < 0.05,
        "{d_edges} vs {expect}"
    );
    assert!(
        touch_edges && (n_edges / n0 - 1.0).abs() < 1e-3,
        "{n_edges} vs {n0}"
    );
    assert!(edge_steps > 9000, "{edge_steps}");
    // During the slide every contact on the fruit is an edge contact sliding at μ_k N.
    for c in tr.contacts[k0 + 100..]
        .iter()
        .flatten()
        .filter(|c| c.rod != usize::MAX)
    {
        assert!(c.segment == 100 && !c.stuck, "{c:?}");
        assert!(
            (c.friction_force.abs() - mu * c.normal_force).abs() < 1e-12,
            "{c:?}"
        );
    }
    // Nodes only: the squeeze is at nodes 100 and 101, 5 mm above and below the equator,
    // where the disc is 0.31 mm narrower: the jaws' travel never grips it there, and it falls
    // between them until the narrowing jaws catch it far below.
    assert!(d_nodes > 0.1, "{d_nodes}");
}
