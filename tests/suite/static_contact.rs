//! Static mode with an obstacle: a tip-loaded cantilever resting on a rigid disc. The load ramp
//! may not step through the disc, and the reported reaction is the equilibrium contact force.
//!
//! The case: L = 0.1 m of free length from the clamp at the first edge's midpoint
//! (references.md, "where the clamp is"), rect section b × h = 0.02 × 0.002 m, E = 1 MPa
//! (EI = 1.3333e-5 N·m²), tip load P = 2 EI/L² = 2.6667e-3 N downward, centreline contact with
//! a rigid circle of radius 11 mm centred at (0.08, −0.011): the unloaded beam touches its top.
//!
//! Print the numbers with `cargo test --release --test suite static_contact:: -- --nocapture`.

use gripsim::events::{Event, Fanout, Observer};
use gripsim::record::summary::SummaryCollector;
use gripsim::{Scenario, Simulation};

const L: f64 = 0.1;
const EI: f64 = 1e6 * 0.02 * 0.002 * 0.002 * 0.002 / 12.0;
const P: f64 = 2.0 * EI / (L * L);
const R: f64 = 0.011;
const C: [f64; 2] = [0.08, -0.011];

/// The inextensible elastica resting on the circle: (contact force F, arc length s_c and slope
/// θ_c of the contact point, tip position).
#[derive(Debug, Clone, Copy)]
struct Elastica {
    force: f64,
    s_c: f64,
    theta_c: f64,
    tip: [f64; 2],
}

/// y = (x, y, θ, θ'); EI θ'' = G_x sin θ − G_y cos θ with G the force the part beyond s puts
/// on the rod (the tip load, plus the contact force before the contact point).
fn rk4(y: [f64; 4], len: f64, g: [f64; 2], steps: usize) -> [f64; 4] {
    let f = |y: [f64; 4]| {
        [
            y[2].cos(),
            y[2].sin(),
            y[3],
            (g[0] * y[2].sin() - g[1] * y[2].cos()) / EI,
        ]
    };
    let h = len / steps as f64;
    let mut y = y;
    let add = |y: [f64; 4], k: [f64; 4], s: f64| std::array::from_fn(|j| y[j] + s * k[j]);
    for _ in 0..steps {
        let k1 = f(y);
        let k2 = f(add(y, k1, h / 2.0));
        let k3 = f(add(y, k2, h / 2.0));
        let k4 = f(add(y, k3, h));
        y = std::array::from_fn(|j| y[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]));
    }
    y
}

/// Shoot from the clamp (x = y = θ = 0) with unknowns u = (θ'(0), F, s_c, θ_c): the contact
/// force F acts along the circle's outward normal n = (−sin θ_c, cos θ_c) at s_c. Conditions:
/// the contact point is on the circle with the rod tangent to it (x(s_c) = C + R n and
/// θ(s_c) = θ_c) and the tip carries no moment (θ'(L) = 0). Newton with a central-difference
/// Jacobian; `steps` RK4 steps over the whole length. Returns the solution and the points
/// of the rod every step (to check that it touches the circle nowhere else).
fn elastica(steps: usize) -> (Elastica, Vec<[f64; 2]>) {
    let shoot = |u: [f64; 4], points: Option<&mut Vec<[f64; 2]>>| {
        let n = [-u[3].sin(), u[3].cos()];
        let g = [u[1] * n[0], u[1] * n[1] - P];
        let m1 = ((steps as f64 * u[2] / L).round() as usize).max(2);
        let m2 = steps.saturating_sub(m1).max(2);
        let mut y = [0.0, 0.0, 0.0, u[0]];
        let mut pts = vec![[0.0; 2]];
        for _ in 0..m1 {
            y = rk4(y, u[2] / m1 as f64, g, 1);
            pts.push([y[0], y[1]]);
        }
        let yc = y;
        for _ in 0..m2 {
            y = rk4(y, (L - u[2]) / m2 as f64, [0.0, -P], 1);
            pts.push([y[0], y[1]]);
        }
        if let Some(p) = points {
            *p = pts;
        }
        let res = [
            yc[0] - C[0] - R * n[0],
            yc[1] - C[1] - R * n[1],
            yc[2] - u[3],
            y[3] * L,
        ];
        (res, [y[0], y[1]])
    };
    let mut u = [-0.1, 3e-3, 0.08, 0.0];
    let scale = [1.0, 1e-3, L, 1.0];
    for _ in 0..50 {
        let (r, _) = shoot(u, None);
        let mut a = [[0.0; 5]; 4];
        for j in 0..4 {
            let h = 1e-6 * scale[j];
            let (mut up, mut um) = (u, u);
            up[j] += h;
            um[j] -= h;
            let (rp, _) = shoot(up, None);
            let (rm, _) = shoot(um, None);
            for i in 0..4 {
                a[i][j] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        for i in 0..4 {
            a[i][4] = -r[i];
        }
        let d = gauss(a);
        for j in 0..4 {
            u[j] += d[j];
        }
        if (0..4).all(|j| d[j].abs() < 1e-14 * scale[j]) {
            break;
        }
    }
    let mut pts = Vec::new();
    let (r, tip) = shoot(u, Some(&mut pts));
    assert!(r.iter().all(|x| x.abs() < 1e-13), "shooting residual {r:?}");
    let e = Elastica {
        force: u[1],
        s_c: u[2],
        theta_c: u[3],
        tip,
    };
    (e, pts)
}

/// Gaussian elimination with partial pivoting on an augmented 4 × 5 matrix.
fn gauss(mut a: [[f64; 5]; 4]) -> [f64; 4] {
    for c in 0..4 {
        let p = (c..4)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        let pivot = a[c];
        for row in a.iter_mut().skip(c + 1) {
            let f = row[c] / pivot[c];
            for (x, y) in row.iter_mut().zip(pivot).skip(c) {
                *x -= f * y;
            }
        }
    }
    let mut x = [0.0; 4];
    for i in (0..4).rev() {
        let s: f64 = (i + 1..4).map(|k| a[i][k] * x[k]).sum();
        x[i] = (a[i][4] - s) / a[i][i];
    }
    x
}

/// The reference: the shooting at 4 000 RK4 steps, which 8 000 reproduce to 1e-12.
#[test]
fn the_elastica_resting_on_the_disc() {
    let (e, pts) = elastica(4000);
    let (e2, _) = elastica(8000);
    println!(
        "elastica on the disc: contact force {:.10e} N at s = {:.10} m (slope {:.10} rad), \
         tip ({:.10}, {:.10}) m; P = {P:.10e} N",
        e.force, e.s_c, e.theta_c, e.tip[0], e.tip[1]
    );
    assert!((e.force - e2.force).abs() < 1e-12 * e.force);
    assert!((e.tip[0] - e2.tip[0]).abs() < 1e-14 && (e.tip[1] - e2.tip[1]).abs() < 1e-14);
    // The figures the issue quotes: 3.6138 mN, tip (0.0999, −0.00197) m.
    assert!((e.force - 3.6138e-3).abs() < 1e-7, "{}", e.force);
    assert!((e.tip[0] - 0.0999).abs() < 1e-4 && (e.tip[1] + 0.00197).abs() < 1e-5);
    // Tangent contact at one point: the rest of the rod clears the circle.
    let clear = pts
        .iter()
        .map(|p| (p[0] - C[0]).hypot(p[1] - C[1]) - R)
        .fold(f64::INFINITY, f64::min);
    assert!(
        clear > -1e-12,
        "the elastica enters the circle by {clear:e} m"
    );
}

fn beam_on_disc(nodes: usize, points: &str) -> String {
    let dl = L / (nodes as f64 - 1.5);
    format!(
        r#"
name = "beam-on-disc"
[solve]
mode = "static"
gravity = [0.0, 0.0]
[contact]
surface = "centreline"
points = "{points}"
[[rod]]
name = "beam"
nodes = {nodes}
shape = {{ kind = "straight", start = [{start:e}, 0.0], end = [{L}, 0.0] }}
E = 1e6
section = {{ kind = "rect", b = 0.02, h = 0.002 }}
density = 1000.0
clamped = [0, 1]
loads = [{{ node = {tip}, force = [0.0, {load:e}] }}]
[[obstacle]]
kind = "circle"
center = [{cx:e}, {cy:e}]
radius = {R:e}
"#,
        start = -dl / 2.0,
        tip = nodes - 1,
        load = -P,
        cx = C[0],
        cy = C[1],
    )
}

/// What the ramp did: the deepest any node and any segment went into the disc over every
/// load step's output (m, negative inside), the load steps, and the last step's contact force
/// (the resultant of every contact on the disc), contacts and tip.
#[derive(Default)]
struct Ramp {
    steps: usize,
    node_gap: f64,
    segment_gap: f64,
    force: [f64; 2],
    contacts: Vec<(usize, usize, f64)>,
    tip: [f64; 2],
}

impl Observer for Ramp {
    fn on_event(&mut self, e: &Event<'_>) {
        let Event::StepEnd { rods, contacts, .. } = e else {
            return;
        };
        self.steps += 1;
        let q = rods[0].q;
        let n = q.len() / 2;
        let gap = |p: [f64; 2]| (p[0] - C[0]).hypot(p[1] - C[1]) - R;
        for i in 2..n {
            self.node_gap = self.node_gap.min(gap([q[2 * i], q[2 * i + 1]]));
        }
        for i in 1..n - 1 {
            let (a, b) = ([q[2 * i], q[2 * i + 1]], [q[2 * i + 2], q[2 * i + 3]]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let s = (((C[0] - a[0]) * e[0] + (C[1] - a[1]) * e[1]) / (e[0] * e[0] + e[1] * e[1]))
                .clamp(0.0, 1.0);
            self.segment_gap = self
                .segment_gap
                .min(gap([a[0] + s * e[0], a[1] + s * e[1]]));
        }
        self.force = [0.0; 2];
        self.contacts.clear();
        for c in contacts.iter() {
            let t = [-c.normal[1], c.normal[0]];
            self.force[0] += c.normal_force * c.normal[0] + c.friction_force * t[0];
            self.force[1] += c.normal_force * c.normal[1] + c.friction_force * t[1];
            let w = if c.segment == usize::MAX {
                0.0
            } else {
                c.weight
            };
            self.contacts.push((c.node, c.segment, w));
        }
        self.tip = [q[2 * n - 2], q[2 * n - 1]];
    }
}

fn ramp(nodes: usize, points: &str) -> (Ramp, gripsim::record::summary::Summary) {
    let sc = Scenario::from_str(&beam_on_disc(nodes, points), "t.toml", &[])
        .unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&sc);
    let (mut ramp, mut col) = (Ramp::default(), SummaryCollector::new());
    let mut both = Fanout::new();
    both.push(&mut ramp);
    both.push(&mut col);
    sim.run(&mut both).unwrap_or_else(|e| panic!("{e}"));
    drop(both);
    let s = col.finish(&sim.stats, 0.0);
    (ramp, s)
}

/// The ramp follows the contact path at 25, 50 and 100 nodes, nodes only and edges: no node
/// (edges: no segment) inside the disc at any load step, the tip on the near side. With edge
/// contact the contact force and the tip match the elastica within 0.5 % from 50 nodes, and the
/// summary's peak reaction is that force (the edge contact's multiplier, not a node's share).
#[test]
fn a_tip_loaded_cantilever_rests_on_a_disc_at_the_elastica() {
    let (e, _) = elastica(4000);
    let tol = 1e-10 * L;
    let deflection = (e.tip[0] - L).hypot(e.tip[1]);
    for nodes in [25usize, 50, 100] {
        for points in ["nodes", "edges"] {
            let (r, s) = ramp(nodes, points);
            let force = r.force[0].hypot(r.force[1]);
            let ef = (force - e.force) / e.force;
            let et = (r.tip[0] - e.tip[0]).hypot(r.tip[1] - e.tip[1]) / deflection;
            println!(
                "{nodes:3} nodes, {points}: {} load steps, contact force {force:.6e} N ({:+.3} %), \
                 tip ({:.6}, {:.6}) m (off by {:.3} % of the deflection), peak reaction {:.6e} N, \
                 contacts (node, segment, weight) {:?}, deepest node {:.1e} m, segment {:.1e} m",
                r.steps - 1,
                100.0 * ef,
                r.tip[0],
                r.tip[1],
                100.0 * et,
                s.peak_reaction_force_n,
                r.contacts,
                -r.node_gap.min(0.0),
                -r.segment_gap.min(0.0),
            );
            assert!(
                r.node_gap > -tol,
                "{nodes} {points}: a node entered by {:e}",
                r.node_gap
            );
            assert!(
                r.tip[1] > -0.003 && r.tip[0] > 0.099,
                "{nodes} {points}: {:?}",
                r.tip
            );
            assert!(
                !r.contacts.is_empty(),
                "{nodes} {points}: resting on the disc"
            );
            if points == "edges" {
                assert!(
                    r.segment_gap > -tol,
                    "{nodes}: a segment entered by {:e}",
                    r.segment_gap
                );
                assert!(
                    (s.peak_reaction_force_n - force).abs() < 1e-9 * force,
                    "{nodes}: peak reaction {} against the contact force {force}",
                    s.peak_reaction_force_n
                );
            }
            if points == "edges" && nodes >= 50 {
                assert!(ef.abs() < 0.005 && et < 0.005, "{nodes}: {ef} {et}");
            }
        }
    }
}

/// Ten times the load (P = 20 EI/L²): the free beam's solution of a long increment swings
/// its nodes through the disc and out the other side, and such increments are cut. Whatever
/// the first increment (the whole load, a quarter, a hundredth), the ramp ends at the same
/// equilibrium, and no node (edges: no segment) is inside the disc at any load step.
#[test]
fn a_ten_times_heavier_load_ends_at_one_equilibrium_whatever_the_load_step() {
    let tol = 1e-10 * L;
    for (nodes, points) in [(25usize, "nodes"), (50, "edges")] {
        let mut forces = Vec::new();
        for step in ["1.0", "0.25", "0.01"] {
            let text = beam_on_disc(nodes, points).replace(
                "gravity = [0.0, 0.0]",
                &format!("gravity = [0.0, 0.0]\nload_step = {step}"),
            );
            let sets = [format!("rod.0.loads.0.force=[0.0,{:e}]", -10.0 * P)];
            let sc = Scenario::from_str(&text, "t.toml", &sets).unwrap_or_else(|e| panic!("{e}"));
            let mut sim = Simulation::new(&sc);
            let mut r = Ramp::default();
            sim.run(&mut r).unwrap_or_else(|e| panic!("{e}"));
            let st = &sim.stats;
            println!(
                "{nodes} nodes, {points}, load_step {step}: {} load steps, {} cut at a crossing, \
                 {} Newton back-offs; contact force ({:.7e}, {:.7e}) N at {:?}, tip ({:.6}, {:.6}) m, \
                 deepest node {:.1e} m, segment {:.1e} m",
                st.steps,
                st.split_steps,
                st.backoffs,
                r.force[0],
                r.force[1],
                r.contacts,
                r.tip[0],
                r.tip[1],
                -r.node_gap.min(0.0),
                -r.segment_gap.min(0.0),
            );
            assert!(
                r.node_gap > -tol,
                "{nodes} {points} {step}: {:e}",
                r.node_gap
            );
            if points == "edges" {
                assert!(r.segment_gap > -tol, "{nodes} {step}: {:e}", r.segment_gap);
            }
            if step == "0.25" && points == "nodes" {
                assert!(st.split_steps > 0, "the crossing cuts are exercised");
            }
            forces.push((r.force, r.tip));
        }
        for (f, tip) in &forces[1..] {
            let (f0, tip0) = forces[0];
            let df = (f[0] - f0[0]).hypot(f[1] - f0[1]) / f0[0].hypot(f0[1]);
            assert!(df < 1e-4, "{nodes} {points}: {f:?} against {f0:?}");
            assert!(
                (tip[0] - tip0[0]).hypot(tip[1] - tip0[1]) < 1e-7,
                "{tip:?} {tip0:?}"
            );
        }
    }
}

/// A static run with no obstacle takes none of the contact code's new paths: the shipped
/// elastica scenario ends on the bits it ended on before (commit 0bf4213).
#[test]
fn a_static_run_without_an_obstacle_is_unchanged() {
    let text = include_str!("../../scenarios/cantilever-tip-load.toml");
    let sc = Scenario::from_str(text, "cantilever-tip-load.toml", &[]).unwrap();
    let mut sim = Simulation::new(&sc);
    let stats = sim.run(&mut gripsim::events::NullObserver).unwrap();
    let q = sim.positions(0);
    let tip = [q[98].to_bits(), q[99].to_bits()];
    assert_eq!(
        tip,
        [0x3fb8_2925_d55c_d9b5, 0xbf9e_e852_318f_b094],
        "{:?}",
        [q[98], q[99]]
    );
    assert_eq!((stats.steps, stats.newton_iterations), (3, 39));
}
