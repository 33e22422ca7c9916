//! Stage 3, the 3D rod core (src/rod3d): every gradient and Hessian against finite
//! differences, the in-plane cantilever against the planar solver, out-of-plane bending of a
//! b ≠ h section against the elastica, twist under an end torque, Greenhill's torsional
//! buckling, momentum and energy.

use gripsim::events::NullObserver;
use gripsim::rod3d::energy::{node_derivatives, node_energy, stretch, EdgeFrame, NodeElastic};
use gripsim::rod3d::kernel;
use gripsim::rod3d::rod::{angle, pos};
use gripsim::rod3d::solver::{assemble, assemble_into, damping_into};
use gripsim::rod3d::symband::{BandSink, SymBand};
use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3};
use gripsim::scenario::three::Scenario3;
use gripsim::solver::banded::BandLu;
use gripsim::{Scenario, Simulation};

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
    fn unit(&mut self) -> [f64; 3] {
        let v = [
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        ];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    }
}

/// max |a − b| / scale.
fn rel_err(a: &[f64], b: &[f64], scale: f64) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A random old frame near the direction `e` (within ~0.3 rad).
fn old_frame(r: &mut Lcg, e: [f64; 3]) -> EdgeFrame {
    let l = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
    let w = r.unit();
    let t = [
        e[0] / l + 0.3 * w[0],
        e[1] / l + 0.3 * w[1],
        e[2] / l + 0.3 * w[2],
    ];
    let lt = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    let t = [t[0] / lt, t[1] / lt, t[2] / lt];
    let a = cross(t, r.unit());
    let la = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    EdgeFrame {
        t,
        a1: [a[0] / la, a[1] / la, a[2] / la],
    }
}

#[test]
fn stretch_gradient_and_hessian_match_finite_differences() {
    let mut r = Lcg(5);
    let h = 1e-6;
    for case in 0..200 {
        let x: [f64; 6] = std::array::from_fn(|_| r.range(-1.0, 1.0));
        let (ea, rest) = (r.range(0.5, 5.0), r.range(0.3, 2.0));
        let (mut g, mut hs) = ([0.0; 6], [[0.0; 6]; 6]);
        stretch(&x, ea, rest, &mut g, Some(&mut hs));
        let mut gfd = [0.0; 6];
        for k in 0..6 {
            let (mut xp, mut xm) = (x, x);
            xp[k] += h;
            xm[k] -= h;
            let mut d = [0.0; 6];
            gfd[k] = (stretch(&xp, ea, rest, &mut d, None) - stretch(&xm, ea, rest, &mut d, None))
                / (2.0 * h);
            let (mut gp, mut gm) = ([0.0; 6], [0.0; 6]);
            stretch(&xp, ea, rest, &mut gp, None);
            stretch(&xm, ea, rest, &mut gm, None);
            let col: Vec<f64> = (0..6).map(|i| (gp[i] - gm[i]) / (2.0 * h)).collect();
            let exact: Vec<f64> = (0..6).map(|i| hs[i][k]).collect();
            let scale = max_abs(&exact).max(1e-3);
            assert!(rel_err(&exact, &col, scale) < 1e-6, "case {case} col {k}");
        }
        let scale = max_abs(&g).max(1e-3);
        assert!(
            rel_err(&g, &gfd, scale) < 1e-6,
            "case {case}: {g:?} {gfd:?}"
        );
    }
}

/// A random bent and twisted stencil with random old frames, rest values and stiffnesses.
fn random_stencil(r: &mut Lcg) -> ([f64; 11], [EdgeFrame; 2], f64, NodeElastic) {
    let x0 = [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)];
    let e = r.unit();
    let mut f = r.unit();
    // Keep the turning angle below ~2 rad (κb = 2 tan(φ/2) stays moderate).
    if e[0] * f[0] + e[1] * f[1] + e[2] * f[2] < -0.4 {
        f = [-f[0], -f[1], -f[2]];
    }
    let (le, lf) = (r.range(0.3, 1.5), r.range(0.3, 1.5));
    let x1 = [x0[0] + le * e[0], x0[1] + le * e[1], x0[2] + le * e[2]];
    let x2 = [x1[0] + lf * f[0], x1[1] + lf * f[1], x1[2] + lf * f[2]];
    let x = [
        x0[0],
        x0[1],
        x0[2],
        r.range(-3.0, 3.0),
        x1[0],
        x1[1],
        x1[2],
        r.range(-3.0, 3.0),
        x2[0],
        x2[1],
        x2[2],
    ];
    let old = [old_frame(r, e), old_frame(r, f)];
    let p = NodeElastic {
        ei1: r.range(0.5, 3.0),
        ei2: r.range(0.5, 3.0),
        gj: r.range(0.5, 3.0),
        kappa_bar: [r.range(-1.0, 1.0), r.range(-1.0, 1.0)],
        twist_bar: r.range(-1.0, 1.0),
    };
    (x, old, r.range(-0.5, 0.5), p)
}

#[test]
fn bending_and_twisting_gradient_and_hessian_match_finite_differences() {
    let mut r = Lcg(17);
    let h = 1e-6;
    let (mut worst_g, mut worst_h) = (0.0f64, 0.0f64);
    for case in 0..300 {
        let (x, old, rt, p) = random_stencil(&mut r);
        let o = [&old[0], &old[1]];
        let (mut g, mut hs) = ([0.0; 11], [[0.0; 11]; 11]);
        node_derivatives(&x, o, rt, &p, &mut g, &mut hs);
        let mut gfd = [0.0; 11];
        for k in 0..11 {
            let (mut xp, mut xm) = (x, x);
            xp[k] += h;
            xm[k] -= h;
            gfd[k] = (node_energy(&xp, o, rt, &p) - node_energy(&xm, o, rt, &p)) / (2.0 * h);
            let (mut gp, mut gm, mut dummy) = ([0.0; 11], [0.0; 11], [[0.0; 11]; 11]);
            node_derivatives(&xp, o, rt, &p, &mut gp, &mut dummy);
            node_derivatives(&xm, o, rt, &p, &mut gm, &mut dummy);
            let col: Vec<f64> = (0..11).map(|i| (gp[i] - gm[i]) / (2.0 * h)).collect();
            let exact: Vec<f64> = (0..11).map(|i| hs[i][k]).collect();
            let scale = hs.iter().flatten().fold(1e-3f64, |m, v| m.max(v.abs()));
            let e = rel_err(&exact, &col, scale);
            worst_h = worst_h.max(e);
            assert!(
                e < 1e-6,
                "case {case} Hessian column {k}: {exact:?} vs {col:?}"
            );
            for (i, row) in hs.iter().enumerate() {
                assert!((row[k] - hs[k][i]).abs() <= 1e-12 * scale, "symmetry");
            }
        }
        let e = rel_err(&g, &gfd, max_abs(&g).max(1e-3));
        worst_g = worst_g.max(e);
        assert!(e < 1e-6, "case {case}: {g:?} vs {gfd:?}");
    }
    println!("bend+twist FD check, 300 stencils: gradient {worst_g:.2e}, Hessian {worst_h:.2e}");
}

fn helix(n: usize, radius: f64, pitch: f64, turns: f64) -> Vec<[f64; 3]> {
    (0..n)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * turns * i as f64 / (n - 1) as f64;
            [radius * a.cos(), radius * a.sin(), pitch * a]
        })
        .collect()
}

fn spec(points: Vec<[f64; 3]>, director: [f64; 3], section: Section3) -> Rod3Spec {
    Rod3Spec {
        points,
        director,
        rest_theta: vec![],
        section,
        youngs_modulus: 1e6,
        shear_modulus: 1e6 / 3.0,
        density: 1000.0,
    }
}

#[test]
fn assembled_gradient_and_banded_hessian_match_finite_differences() {
    // A helical rod with natural twist, deformed and twisted away from rest.
    let mut s = spec(
        helix(7, 0.02, 0.005, 0.6),
        [0.0, 0.0, 1.0],
        Section3::Rect { b: 0.004, h: 0.002 },
    );
    s.rest_theta = vec![0.0, 0.1, 0.3, 0.2, -0.1, 0.4];
    let sim = Sim3::new(Rod3::new(&s));
    let mut r = Lcg(23);
    let q: Vec<f64> = sim
        .q
        .iter()
        .enumerate()
        .map(|(k, v)| {
            v + if k % 4 == 3 {
                r.range(-0.5, 0.5)
            } else {
                r.range(-2e-3, 2e-3)
            }
        })
        .collect();
    let nd = q.len();
    let (rod, fr, rt) = (&sim.rod, &sim.frames, &sim.ref_twist);
    let mut g = vec![0.0; nd];
    let mut band = BandLu::new(nd, 10, 10);
    assemble(rod, fr, rt, &q, &mut g, Some(&mut band), &[]);
    let energy = |q: &[f64]| {
        let mut d = vec![0.0; nd];
        assemble(rod, fr, rt, q, &mut d, None, &[])
    };
    let h = 1e-7;
    let mut gfd = vec![0.0; nd];
    let hscale = (0..nd).fold(0.0f64, |m, i| m.max(band.get(i, i).abs()));
    for k in 0..nd {
        let (mut qp, mut qm) = (q.clone(), q.clone());
        qp[k] += h;
        qm[k] -= h;
        gfd[k] = (energy(&qp) - energy(&qm)) / (2.0 * h);
        let (mut gp, mut gm) = (vec![0.0; nd], vec![0.0; nd]);
        assemble(rod, fr, rt, &qp, &mut gp, None, &[]);
        assemble(rod, fr, rt, &qm, &mut gm, None, &[]);
        for i in 0..nd {
            let fd = (gp[i] - gm[i]) / (2.0 * h);
            let err = (band.get(i, k) - fd).abs() / hscale;
            assert!(err < 1e-6, "H[{i}][{k}] = {} vs FD {fd}", band.get(i, k));
        }
    }
    let e = rel_err(&g, &gfd, max_abs(&g));
    println!("assembled gradient FD rel err {e:.2e}");
    assert!(e < 1e-6, "{g:?}\n{gfd:?}");
    // At rest the energy and the gradient vanish: natural curvature and twist are the rest shape's.
    let mut g0 = vec![0.0; nd];
    let e0 = assemble(rod, fr, rt, &sim.q, &mut g0, None, &[]);
    assert!(
        e0.abs() < 1e-20 && max_abs(&g0) < 1e-9 * max_abs(&g),
        "{e0} {g0:?}"
    );
}

const L: f64 = 0.1;

/// Straight nodes along x from −dl/2 to `end` with spacing dl (the planar verification's
/// cantilever: clamp edge 0 has its midpoint at x = 0).
fn straight(nodes: usize, dl: f64) -> Vec<[f64; 3]> {
    (0..nodes)
        .map(|i| [-dl / 2.0 + dl * i as f64, 0.0, 0.0])
        .collect()
}

fn planar_cantilever(nodes: usize, p: f64) -> Vec<f64> {
    let dl = L / (nodes as f64 - 1.5);
    let text = format!(
        r#"
name = "cantilever"
[solve]
mode = "static"
gravity = [0.0, 0.0]
force_tol = 1e-13
[[rod]]
name = "beam"
nodes = {nodes}
shape = {{ kind = "straight", start = [{start:e}, 0.0], end = [0.1, 0.0] }}
E = 1e6
section = {{ kind = "rect", b = 0.02, h = 0.01 }}
density = 1000.0
clamped = [0, 1]
loads = [{{ node = {last}, force = [0.0, {f:e}] }}]
"#,
        start = -dl / 2.0,
        last = nodes - 1,
        f = -p
    );
    let sc = Scenario::from_str(&text, "planar.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&sc);
    sim.run(&mut NullObserver).unwrap_or_else(|e| panic!("{e}"));
    sim.positions(0).to_vec()
}

/// A 3D cantilever along x, clamp edge 0, static tip load `force`.
fn cantilever3(nodes: usize, section: Section3, force: [f64; 3], director: [f64; 3]) -> Sim3 {
    let dl = L / (nodes as f64 - 1.5);
    let mut sim = Sim3::new(Rod3::new(&spec(straight(nodes, dl), director, section)));
    sim.clamp_edge(0);
    sim.force_tol = 1e-13;
    let tip = pos(nodes - 1);
    sim.load[tip..tip + 3].copy_from_slice(&force);
    sim.solve_static(4).unwrap_or_else(|e| panic!("{e}"));
    sim
}

#[test]
fn in_plane_cantilever_reproduces_the_planar_solver() {
    let nodes = 30;
    let ei = 1e6 * 0.02 * 0.01f64.powi(3) / 12.0;
    let p = 1.0 * ei / (L * L);
    let planar = planar_cantilever(nodes, p);
    let sim = cantilever3(
        nodes,
        Section3::Rect { b: 0.02, h: 0.01 },
        [0.0, -p, 0.0],
        [0.0, 1.0, 0.0],
    );
    let mut worst = 0.0f64;
    for i in 0..nodes {
        let x = sim.rod.node(&sim.q, i);
        worst = worst.max((x[0] - planar[2 * i]).abs());
        worst = worst.max((x[1] - planar[2 * i + 1]).abs());
        assert!(x[2].abs() < 1e-15, "node {i} left the plane: z = {}", x[2]);
    }
    let tip = -planar[2 * nodes - 1];
    println!(
        "in-plane cantilever, {nodes} nodes: tip deflection {tip:.9e} m, max |3D − planar| = {worst:.2e} m ({:.2e} relative)",
        worst / tip
    );
    assert!(tip > 0.025, "the load must bend the beam: {tip}");
    assert!(worst / tip < 1e-9, "3D vs planar: {worst:e} m on {tip:e} m");
    // No twist appears in a planar problem.
    let twist = (0..nodes - 1).fold(0.0f64, |m, i| m.max(sim.q[angle(i)].abs()));
    assert!(twist < 1e-12, "twist {twist}");
}

/// Tip deflection along `dir` (1: y, in the plane of m₁; 2: z, along m₂) over L for a load
/// P = α EI/L² with EI the section's second moment for that direction.
fn elastica_tip(nodes: usize, dir: usize) -> (f64, f64) {
    // b (along m₂ = z) = 1 mm, h (along m₁ = y) = 2 mm: I₁ = 4 I₂; thin enough that
    // stretch is negligible next to the discretisation error (EA L²/EI₂ = 1.2e5).
    let s = Section3::Rect { b: 0.001, h: 0.002 };
    let ei = 1e6 * if dir == 1 { s.i1() } else { s.i2() };
    let mut f = [0.0; 3];
    f[dir] = -ei / (L * L);
    let sim = cantilever3(nodes, s, f, [0.0, 1.0, 0.0]);
    let tip = sim.rod.node(&sim.q, nodes - 1);
    let other = tip[3 - dir].abs();
    assert!(other < 1e-12, "the tip left the loaded plane by {other}");
    (-tip[dir] / L, (L - tip[0]) / L)
}

#[test]
fn out_of_plane_load_bends_with_the_other_second_moment() {
    // Elastica, α = P L²/EI = 1: δv/L = 0.30172, δh/L = 0.05643 (references.md, the planar
    // verification's values).
    let want = (0.30172, 0.05643);
    for dir in [1, 2] {
        let mut errs = vec![];
        for n in [25usize, 50] {
            let (dv, dh) = elastica_tip(n, dir);
            let e = (dv - want.0).abs() / want.0;
            println!(
                "3D cantilever, load along {}, {n} nodes: dv/L = {dv:.6} (err {:.4} %), dh/L = {dh:.6}",
                if dir == 1 { "m1 (EI1)" } else { "m2 (EI2)" },
                e * 100.0
            );
            errs.push(e);
            if n == 50 {
                assert!(e < 0.005, "dir {dir}: dv/L = {dv} (err {e})");
                assert!(
                    (dh - want.1).abs() / want.1 < 0.01,
                    "dir {dir}: dh/L = {dh}"
                );
            }
        }
        assert!(errs[1] < errs[0], "error must shrink: {errs:?}");
    }
    // The same force along m₂ bends 4× as far at small loads (I₁/I₂ = (h/b)² = 4).
    let s = Section3::Rect { b: 0.001, h: 0.002 };
    let p = 0.003 * 1e6 * s.i2() / (L * L);
    let y = cantilever3(50, s, [0.0, -p, 0.0], [0.0, 1.0, 0.0]);
    let z = cantilever3(50, s, [0.0, 0.0, -p], [0.0, 1.0, 0.0]);
    let ratio = z.rod.node(&z.q, 49)[2] / y.rod.node(&y.q, 49)[1];
    println!("small load: z/y tip deflection ratio {ratio:.6} (I1/I2 = 4)");
    assert!((ratio - 4.0).abs() < 4.0 * 2e-3, "ratio {ratio}");
}

/// Straight rod whose first and last edges have their midpoints at x = 0 and x = L.
fn between_clamps(nodes: usize, section: Section3) -> Sim3 {
    let dl = L / (nodes as f64 - 2.0);
    Sim3::new(Rod3::new(&spec(
        straight(nodes, dl),
        [0.0, 1.0, 0.0],
        section,
    )))
}

#[test]
fn end_torque_twists_by_tl_over_gj() {
    for section in [
        Section3::Rect { b: 0.004, h: 0.002 },
        Section3::Rect { b: 0.003, h: 0.003 },
    ] {
        let nodes = 21;
        let mut sim = between_clamps(nodes, section);
        sim.clamp_edge(0);
        sim.force_tol = 1e-13;
        let gj = sim.rod.gj;
        let t = 0.01 * gj / L; // φ = 0.01 rad
        sim.load[angle(nodes - 2)] = t;
        sim.solve_static(1).unwrap_or_else(|e| panic!("{e}"));
        let phi = sim.q[angle(nodes - 2)] - sim.q[angle(0)];
        let want = t * L / gj;
        println!(
            "end torque {t:.4e} N m on {section:?}: twist {phi:.12e} rad, T L/(G J) = {want:.12e}"
        );
        assert!((phi - want).abs() / want < 1e-9, "{phi} vs {want}");
        let moved = (0..nodes).fold(0.0f64, |m, i| {
            let (x, x0) = (sim.rod.node(&sim.q, i), sim.rod.node(&sim.rod.q0, i));
            m.max((0..3).fold(0.0f64, |a, k| a.max((x[k] - x0[k]).abs())))
        });
        assert!(moved < 1e-15, "the centreline moved by {moved}");
    }
}

/// Greenhill: both end edges clamped in direction (the far one free to slide along the axis),
/// the far edge's material angle turned to Φ = T L/(G J) over 0.05 s, and a 1e-4 L initial
/// kink. Returns the largest lateral excursion in the last 0.1 s of a 0.8 s run.
fn greenhill(torque_ratio: f64) -> (f64, f64) {
    let nodes = 40;
    let s = Section3::Rect { b: 0.005, h: 0.005 };
    let mut sim = between_clamps(nodes, s);
    sim.clamp_edge(0);
    for i in [nodes - 2, nodes - 1] {
        sim.fixed[pos(i) + 1] = true;
        sim.fixed[pos(i) + 2] = true;
    }
    let last = angle(nodes - 2);
    sim.fixed[last] = true;
    // Critical torque for clamped ends: T L/EI = 8.9868, the first root of tan(x/2) = x/2
    // (Greenhill 1883; Ziegler, Principles of Structural Stability, §3.3).
    let t_cr = 8.9868 * sim.rod.ei1 / L;
    let phi = torque_ratio * t_cr * L / sim.rod.gj;
    for i in 2..nodes - 2 {
        let x = sim.q[pos(i)];
        sim.q[pos(i) + 1] += 1e-4 * L * (std::f64::consts::PI * x / L).sin();
    }
    let (dt, ramp, end) = (1e-3, 0.05, 0.8);
    let mut late = 0.0f64;
    while sim.time < end - 1e-12 {
        sim.target[last] = phi * ((sim.time + dt) / ramp).min(1.0);
        sim.step(dt)
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.time));
        if sim.time > end - 0.1 {
            for i in 0..nodes {
                let x = sim.rod.node(&sim.q, i);
                late = late.max((x[1] * x[1] + x[2] * x[2]).sqrt());
            }
        }
    }
    let twist = sim.q[last] - sim.q[angle(0)];
    (late / L, twist)
}

#[test]
fn greenhill_rod_stays_straight_below_the_critical_torque_and_buckles_above() {
    let (below, tw) = greenhill(0.9);
    println!("Greenhill 0.9 T_cr: late lateral excursion {below:.3e} L, end twist {tw:.4} rad");
    assert!(below < 1e-4, "0.9 T_cr must stay straight: {below} L");
    let (above, tw) = greenhill(1.1);
    println!("Greenhill 1.1 T_cr: late lateral excursion {above:.3e} L, end twist {tw:.4} rad");
    assert!(above > 1e-2, "1.1 T_cr must buckle: {above} L");
}

#[test]
fn free_rod_conserves_momentum_and_does_not_gain_energy() {
    let mut s = spec(
        helix(30, 0.02, 0.004, 1.0),
        [0.0, 0.0, 1.0],
        Section3::Rect { b: 0.003, h: 0.002 },
    );
    s.rest_theta = (0..29).map(|i| 0.05 * i as f64).collect();
    let mut sim = Sim3::new(Rod3::new(&s));
    sim.force_tol = 1e-12;
    let mut r = Lcg(99);
    for k in 0..sim.v.len() {
        sim.v[k] = if k % 4 == 3 {
            r.range(-5.0, 5.0)
        } else {
            r.range(-0.2, 0.2)
        };
    }
    let momentum = |sim: &Sim3| -> [f64; 3] {
        let mut p = [0.0; 3];
        for i in 0..sim.rod.n {
            for (k, pk) in p.iter_mut().enumerate() {
                *pk += sim.rod.mass[pos(i) + k] * sim.v[pos(i) + k];
            }
        }
        p
    };
    let p0 = momentum(&sim);
    let scale = (0..sim.rod.n)
        .map(|i| sim.rod.mass[pos(i)] * 0.2)
        .sum::<f64>();
    let mut energy = sim.kinetic_energy() + sim.elastic_energy(&sim.q.clone());
    let e0 = energy;
    let mut worst = 0.0f64;
    for _ in 0..300 {
        sim.step(2e-4).unwrap_or_else(|e| panic!("{e}"));
        let p = momentum(&sim);
        for k in 0..3 {
            worst = worst.max((p[k] - p0[k]).abs() / scale);
        }
        let e = sim.kinetic_energy() + sim.elastic_energy(&sim.q.clone());
        assert!(e <= energy * (1.0 + 1e-9), "energy grew: {energy} → {e}");
        energy = e;
    }
    println!("free 3D rod, 300 steps: momentum drift {worst:.2e} (relative), energy {e0:.6e} → {energy:.6e} J");
    assert!(worst < 1e-9, "momentum drift {worst}");
    assert!(energy < e0, "implicit Euler dissipates");
}

#[test]
fn free_fall_gains_exactly_m_g_t_of_momentum_and_stays_unstrained() {
    let s = spec(
        helix(20, 0.02, 0.004, 0.7),
        [0.0, 0.0, 1.0],
        Section3::Rect { b: 0.003, h: 0.002 },
    );
    let mut sim = Sim3::new(Rod3::new(&s));
    sim.gravity = [0.0, -9.81, 2.0];
    let dt = 1e-3;
    for _ in 0..100 {
        sim.step(dt).unwrap_or_else(|e| panic!("{e}"));
    }
    let total: f64 = (0..sim.rod.n).map(|i| sim.rod.mass[pos(i)]).sum();
    for k in 0..3 {
        let p: f64 = (0..sim.rod.n)
            .map(|i| sim.rod.mass[pos(i) + k] * sim.v[pos(i) + k])
            .sum();
        let want = total * sim.gravity[k] * sim.time;
        assert!(
            (p - want).abs() <= 1e-12 * total * 9.81 * sim.time,
            "{k}: {p} vs {want}"
        );
    }
    let e = sim.elastic_energy(&sim.q.clone());
    println!("free fall 0.1 s: elastic energy {e:.3e} J");
    assert!(e < 1e-20, "a falling rod stays at rest shape: {e}");
}

/// Is the stiffness (Hessian on the free DOFs) of the rod's current state positive definite?
/// Dense Cholesky of the free block.
fn stable(sim: &Sim3) -> bool {
    let nd = sim.q.len();
    let mut band = BandLu::new(nd, 10, 10);
    let mut g = vec![0.0; nd];
    let (rod, fr, rt) = (&sim.rod, &sim.frames, &sim.ref_twist);
    assemble(rod, fr, rt, &sim.q, &mut g, Some(&mut band), &sim.fixed);
    let free: Vec<usize> = (0..nd).filter(|&k| !sim.fixed[k]).collect();
    let m = free.len();
    let mut a: Vec<Vec<f64>> = free
        .iter()
        .map(|&i| free.iter().map(|&j| band.get(i, j)).collect())
        .collect();
    for j in 0..m {
        let d = a[j][j] - (0..j).map(|k| a[j][k] * a[j][k]).sum::<f64>();
        if d <= 0.0 {
            return false;
        }
        a[j][j] = d.sqrt();
        for i in j + 1..m {
            let s = a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>();
            a[i][j] = s / a[j][j];
        }
    }
    true
}

/// The straight rod between clamps (far end free to slide axially) with its far material angle
/// turned so that the transmitted torque is `ratio` × Greenhill's clamped value.
fn twisted_between_clamps(nodes: usize, ratio: f64) -> Sim3 {
    let mut sim = between_clamps(nodes, Section3::Rect { b: 0.005, h: 0.005 });
    sim.clamp_edge(0);
    for i in [nodes - 2, nodes - 1] {
        sim.fixed[pos(i) + 1] = true;
        sim.fixed[pos(i) + 2] = true;
    }
    let last = angle(nodes - 2);
    sim.fixed[last] = true;
    sim.target[last] = ratio * 8.9868 * sim.rod.ei1 / L * L / sim.rod.gj;
    sim.force_tol = 1e-12;
    sim.solve_static(1).unwrap_or_else(|e| panic!("{e}"));
    sim
}

#[test]
fn greenhill_critical_torque_from_the_stiffness_converges_to_8_987_ei_over_l() {
    // Bisect the transmitted torque at which the straight twisted rod's stiffness stops being
    // positive definite; clamped ends: T_cr L/EI = 8.9868.
    let mut errs = vec![];
    let mut tcrs = vec![];
    for nodes in [20usize, 40, 80] {
        let (mut lo, mut hi) = (0.5, 1.5);
        assert!(stable(&twisted_between_clamps(nodes, lo)));
        assert!(!stable(&twisted_between_clamps(nodes, hi)));
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            if stable(&twisted_between_clamps(nodes, mid)) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let tcr = 0.5 * (lo + hi) * 8.9868;
        let err = (tcr - 8.9868).abs() / 8.9868;
        println!(
            "Greenhill, {nodes} nodes: stiffness loses definiteness at T L/EI = {tcr:.5} (err {:.3} %)",
            err * 100.0
        );
        errs.push(err);
        tcrs.push(tcr);
    }
    // Second-order convergence (the twist per edge is ~0.4 rad at 40 nodes), and the
    // Richardson extrapolation of 40 and 80 nodes lands on Greenhill's value.
    for w in errs.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!(order > 1.7 && order < 2.3, "order {order}: {errs:?}");
    }
    let extrapolated = tcrs[2] + (tcrs[2] - tcrs[1]) / 3.0;
    println!("Greenhill, Richardson 40/80 nodes: T L/EI = {extrapolated:.5}");
    assert!(
        (extrapolated - 8.9868).abs() / 8.9868 < 1e-3,
        "{extrapolated}"
    );
}

/// The hand-derived kernel (src/rod3d/kernel.rs) against the dual-number stencil: the same
/// gradient and Hessian to ~1e-9 relative on random bent and twisted stencils with random old
/// frames, natural curvature and twist and EI₁ ≠ EI₂; and against finite differences.
#[test]
fn hand_derived_bending_and_twisting_equal_the_dual_number_reference() {
    let mut r = Lcg(29);
    let (mut worst_g, mut worst_h, mut worst_fd) = (0.0f64, 0.0f64, 0.0f64);
    for case in 0..1000 {
        let (x, old, rt, p) = random_stencil(&mut r);
        let o = [&old[0], &old[1]];
        let (mut g, mut hs) = ([0.0; 11], [[0.0; 11]; 11]);
        let en = node_derivatives(&x, o, rt, &p, &mut g, &mut hs);
        let (mut gk, mut hk) = ([0.0; 11], [[0.0; 11]; 11]);
        let ek = kernel::node_derivatives(&x, o, rt, &p, &mut gk, &mut hk);
        assert!(
            (en - ek).abs() <= 1e-13 * en.abs().max(1e-3),
            "case {case} energy"
        );
        let eg = rel_err(&g, &gk, max_abs(&g).max(1e-3));
        let scale = hs.iter().flatten().fold(1e-3f64, |m, v| m.max(v.abs()));
        let eh = rel_err(hs.as_flattened(), hk.as_flattened(), scale);
        assert!(eg < 1e-9, "case {case} gradient: {g:?} vs {gk:?} ({eg:e})");
        assert!(
            eh < 1e-9,
            "case {case} Hessian: {hs:?}\n vs {hk:?} ({eh:e})"
        );
        worst_g = worst_g.max(eg);
        worst_h = worst_h.max(eh);
        // Finite differences of the kernel's own gradient.
        let step = 1e-6;
        for k in 0..11 {
            let (mut xp, mut xm) = (x, x);
            xp[k] += step;
            xm[k] -= step;
            let (mut gp, mut gm, mut dummy) = ([0.0; 11], [0.0; 11], [[0.0; 11]; 11]);
            kernel::node_derivatives(&xp, o, rt, &p, &mut gp, &mut dummy);
            kernel::node_derivatives(&xm, o, rt, &p, &mut gm, &mut dummy);
            let col: Vec<f64> = (0..11).map(|i| (gp[i] - gm[i]) / (2.0 * step)).collect();
            let exact: Vec<f64> = (0..11).map(|i| hk[i][k]).collect();
            let e = rel_err(&exact, &col, scale);
            assert!(e < 1e-6, "case {case} FD column {k}: {e:e}");
            worst_fd = worst_fd.max(e);
        }
    }
    println!(
        "hand-derived vs dual numbers, 1000 stencils: gradient {worst_g:.2e}, Hessian {worst_h:.2e}; \
         vs FD {worst_fd:.2e}"
    );
}

/// The banded Cholesky factor (src/rod3d/symband.rs) solves a random symmetric positive
/// definite band system like the LU with pivoting, and refuses an indefinite one.
#[test]
fn banded_cholesky_solves_like_lu_and_refuses_indefinite_matrices() {
    let (n, k) = (37, 10);
    let mut r = Lcg(41);
    let (mut s, mut lu) = (SymBand::new(n, k), BandLu::new(n, k, k));
    for i in 0..n {
        for j in i.saturating_sub(k)..=i {
            let v = if i == j {
                8.0 + r.next()
            } else {
                r.range(-0.5, 0.5)
            };
            BandSink::add(&mut s, i, j, v);
            lu.add(i, j, v);
            if i != j {
                BandSink::add(&mut s, j, i, v);
                lu.add(j, i, v);
            }
        }
    }
    let b: Vec<f64> = (0..n).map(|_| r.range(-1.0, 1.0)).collect();
    let (mut x, mut y) = (b.clone(), b.clone());
    s.factor().unwrap();
    s.solve(&mut x);
    lu.factor().unwrap();
    lu.solve(&mut y);
    let err = rel_err(&x, &y, max_abs(&y));
    assert!(err < 1e-14, "{err:e}");
    let mut neg = SymBand::new(3, 1);
    for (i, v) in [1.0, -1.0, 1.0].into_iter().enumerate() {
        BandSink::add(&mut neg, i, i, v);
    }
    assert_eq!(neg.factor(), Err(1));
}

/// The column-by-column factor at the rods' bandwidth (10) with identity rows and columns
/// (fixed or eliminated DOFs, as the step's matrices have) solves like LU, and several
/// right-hand sides solved together (`solve_many`, zero above row `first`) give what one
/// solve per column gives.
#[test]
fn banded_cholesky_with_identity_rows_and_many_right_hand_sides() {
    let (n, k) = (44, 10);
    let mut r = Lcg(7);
    let ident = |i: usize| i < 7 || i % 9 == 4;
    let (mut s, mut lu) = (SymBand::new(n, k), BandLu::new(n, k, k));
    for i in 0..n {
        for j in i.saturating_sub(k)..=i {
            let v = match (i == j, ident(i) || ident(j)) {
                (true, true) => 1.0,
                (false, true) => 0.0,
                (true, false) => 6.0 + r.next(),
                (false, false) => r.range(-0.5, 0.5),
            };
            BandSink::add(&mut s, i, j, v);
            lu.add(i, j, v);
            if i != j {
                BandSink::add(&mut s, j, i, v);
                lu.add(j, i, v);
            }
        }
    }
    s.factor().unwrap();
    lu.factor().unwrap();
    let first = 13;
    let cols: Vec<Vec<f64>> = (0..4)
        .map(|_| {
            (0..n)
                .map(|i| if i < first { 0.0 } else { r.range(-1.0, 1.0) })
                .collect()
        })
        .collect();
    let mut many = cols.clone();
    let mut refs: Vec<&mut [f64]> = many.iter_mut().map(|c| c.as_mut_slice()).collect();
    s.solve_many(&mut refs, first);
    for (b, got) in cols.iter().zip(&many) {
        let (mut x, mut y) = (b.clone(), b.clone());
        s.solve(&mut x);
        lu.solve(&mut y);
        let scale = max_abs(&y);
        let (e_lu, e_one) = (rel_err(&x, &y, scale), rel_err(got, &x, scale));
        assert!(e_lu < 1e-14 && e_one < 1e-14, "{e_lu:e} {e_one:e}");
        for i in (0..n).filter(|&i| ident(i)) {
            assert_eq!(x[i], b[i], "identity row {i}");
        }
    }
}

/// The dynamic steps of a clamped helix go through the Cholesky factor (no LU fallback), and
/// a step through LU instead gives the same state to rounding.
#[test]
fn dynamic_steps_use_the_cholesky_factor_and_agree_with_lu() {
    let points = helix(30, 0.02, 0.01, 0.5);
    let mut sim = Sim3::new(Rod3::new(&spec(
        points,
        [0.0, 0.0, 1.0],
        Section3::Rect { b: 0.004, h: 0.002 },
    )));
    sim.clamp_edge(0);
    sim.gravity = [0.0, -9.81, 0.0];
    for _ in 0..20 {
        sim.step(1e-4).unwrap();
    }
    assert_eq!(sim.lu_solves, 0);
    assert!(sim.newton_iterations >= 20);
    // The same Newton step solved by LU (assembled into the general band).
    let nd = sim.q.len();
    let (fr, rt) = (sim.frames.clone(), sim.ref_twist.clone());
    let q = sim.q.clone();
    let (mut g, mut band, mut chol) =
        (vec![0.0; nd], BandLu::new(nd, 10, 10), SymBand::new(nd, 10));
    assemble(&sim.rod, &fr, &rt, &q, &mut g, Some(&mut band), &sim.fixed);
    assemble_into(&sim.rod, &fr, &rt, &q, &mut g, Some(&mut chol), &sim.fixed);
    let mut worst = 0.0f64;
    for i in 0..nd {
        for j in i.saturating_sub(10)..=i {
            worst = worst.max((band.get(i, j) - chol.get(i, j)).abs());
            worst = worst.max((band.get(j, i) - chol.get(i, j)).abs());
        }
    }
    let scale = (0..nd).fold(0.0f64, |m, i| m.max(band.get(i, i).abs()));
    assert!(worst <= 1e-14 * scale, "{worst:e} of {scale:e}");
    for i in 0..nd {
        band.add(i, i, sim.rod.mass[i] * 1e8);
        BandSink::add(&mut chol, i, i, sim.rod.mass[i] * 1e8);
    }
    let (mut x, mut y) = (g.clone(), g.clone());
    chol.factor().unwrap();
    chol.solve(&mut x);
    band.factor().unwrap();
    band.solve(&mut y);
    let err = rel_err(&x, &y, max_abs(&y));
    println!("Cholesky vs LU on a helix step Jacobian: {err:.2e}");
    // Both are backward stable; their difference is rounding times the condition number of
    // the step Jacobian (stretching against bending of a thin section, ~1e4 here).
    assert!(err < 1e-10, "{err:e}");
}

/// Records a 3D run through the event interface: observing does not change the run (bit for
/// bit against the unobserved one), and the CSV (z, twist, material frame) reads back to the
/// exact numbers of the state.
#[test]
fn csv_of_a_3d_run_reads_back_to_the_exact_state() {
    use gripsim::record::csv3::{Csv3, HEADER};
    use gripsim::rod3d::events::{Event3, NullObserver3, Observer3};
    let make = || {
        let mut sim = Sim3::new(Rod3::new(&Rod3Spec {
            rest_theta: (0..11).map(|i| 0.05 * i as f64).collect(),
            ..spec(
                helix(12, 0.02, 0.01, 0.5),
                [0.0, 0.0, 1.0],
                Section3::Rect { b: 0.004, h: 0.002 },
            )
        }));
        sim.clamp_edge(0);
        sim.gravity = [0.0, -9.81, 0.0];
        sim
    };
    let (mut a, mut b) = (make(), make());
    let mut csv = Csv3::new();
    csv.on_event(&Event3::Start {
        rods: &[a.info("prong", [0.001, 0.002])],
    });
    let steps = 15u64;
    for s in 1..=steps {
        a.step_observed(1e-4, s, &mut csv).unwrap();
        b.step_observed(1e-4, s, &mut NullObserver3).unwrap();
    }
    assert_eq!(a.q, b.q);
    assert_eq!(a.v, b.v);
    let dir = std::env::temp_dir().join(format!("gripsim-csv3-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("run.csv");
    csv.finish(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(text.starts_with(HEADER));
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), steps as usize * 12);
    let view = a.view();
    let last = &rows[rows.len() - 12..];
    let num = |s: &str| s.parse::<f64>().unwrap();
    let mut z_max = 0.0f64;
    let mut twist_max = 0.0f64;
    for (i, r) in last.iter().enumerate() {
        assert_eq!(r.len(), 15);
        assert_eq!((r[0], r[2], r[3]), ("15", "prong", &*i.to_string()));
        let x = view.node(i);
        assert_eq!([num(r[4]), num(r[5]), num(r[6])], x);
        assert_eq!(num(r[11]), view.twist(i));
        if i + 1 < 12 {
            assert_eq!(num(r[10]), view.theta(i));
            let (m1, _) = view.material_frame(i);
            assert_eq!([num(r[12]), num(r[13]), num(r[14])], m1);
        } else {
            assert_eq!((r[10], r[12]), ("", ""));
        }
        z_max = z_max.max(x[2].abs());
        twist_max = twist_max.max(view.twist(i).abs());
    }
    println!(
        "3D CSV: {} rows, max |z| {z_max:.4} m, max |twist| {twist_max:.4}",
        rows.len()
    );
    assert!(z_max > 0.01 && twist_max > 0.01);
}

/// A 3D run recorded as `.rrd` (centre line, material frame arrows): `rerun rrd verify`
/// accepts it, and it holds a chunk for each logged entity.
#[test]
fn rrd_of_a_3d_run_verifies() {
    use gripsim::record::rerun3::Rrd3;
    use gripsim::rod3d::events::{Event3, Observer3};
    let mut sim = Sim3::new(Rod3::new(&spec(
        helix(20, 0.02, 0.01, 0.5),
        [0.0, 0.0, 1.0],
        Section3::Rect { b: 0.004, h: 0.002 },
    )));
    sim.clamp_edge(0);
    sim.gravity = [0.0, -9.81, 0.0];
    let dir = std::env::temp_dir().join(format!("gripsim-rrd3-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("helix.rrd");
    let mut rrd = Rrd3::create(&path, "helix").unwrap();
    rrd.on_event(&Event3::Start {
        rods: &[sim.info("prong", [0.001, 0.002])],
    });
    for s in 1..=100 {
        sim.step_observed(2e-4, s, &mut rrd).unwrap();
    }
    rrd.finish().unwrap();
    let out = std::process::Command::new(crate::common::venv().join("bin/rerun"))
        .args(["rrd", "verify"])
        .arg(&path)
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the rerun CLI runs");
    assert!(
        out.status.success(),
        "rerun rrd verify failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::metadata(&path).unwrap().len();
    println!("3D .rrd: 100 steps, 20 nodes, {bytes} bytes, verified");
    assert!(bytes > 10_000);
    if std::env::var_os("GRIPSIM_KEEP_RRD3").is_none() {
        std::fs::remove_dir_all(&dir).unwrap();
    } else {
        println!("kept {}", path.display());
    }
}

/// A clamped helical prong (bending about both axes, twist, stretch) swinging under gravity
/// with Kelvin–Voigt damping τ: energies of the swing (dissipated by damping and by the
/// integrator, each step's work computed on its own) and the largest closure error over it.
fn damped_swing(tau: f64, steps: usize) -> (f64, f64, f64, f64) {
    let mut s = spec(
        helix(16, 0.02, 0.006, 0.75),
        [0.0, 0.0, 1.0],
        Section3::Rect { b: 0.004, h: 0.002 },
    );
    s.rest_theta = (0..15).map(|i| 0.1 * i as f64).collect();
    let mut sim = Sim3::new(Rod3::new(&s));
    sim.clamp_edge(0);
    sim.gravity = [0.0, -9.81, 0.0];
    sim.force_tol = 1e-12;
    sim.damping_time = tau;
    let dt = 1e-4;
    let potential = |sim: &Sim3| -> f64 {
        (0..sim.q.len())
            .filter(|k| k % 4 != 3)
            .map(|k| -sim.rod.mass[k] * sim.gravity[k % 4] * sim.q[k])
            .sum()
    };
    let total = |sim: &Sim3| sim.kinetic_energy() + sim.elastic_energy(&sim.q) + potential(sim);
    let e0 = total(&sim);
    let (mut damped, mut integrator, mut worst, mut moving) = (0.0, 0.0, 0.0f64, 0.0f64);
    let mut g = vec![0.0; sim.q.len()];
    for _ in 0..steps {
        let prev = sim.clone();
        sim.step(dt).unwrap_or_else(|e| panic!("{e}"));
        let dq: Vec<f64> = sim.q.iter().zip(&prev.q).map(|(a, b)| a - b).collect();
        // Material damping: the viscous force's work over the step, dt Σ τ k ṡ² ≥ 0.
        let (rod, fr) = (&sim.rod, &prev.frames);
        let p = damping_into::<SymBand>(rod, fr, &sim.q, &prev.q, dt, tau, &mut g, None, &[]);
        damped += dt * p;
        // Backward Euler: ½ m |Δv|² + E(q_k) − E(q_k+1) + ∇E(q_k+1)·Δq, start-of-step frames.
        assemble(rod, fr, &prev.ref_twist, &sim.q, &mut g, None, &[]);
        let grad_dq: f64 = g.iter().zip(&dq).map(|(a, b)| a * b).sum();
        let b = prev.elastic_energy(&prev.q) - prev.elastic_energy(&sim.q) + grad_dq;
        let dv2: f64 = (0..sim.q.len())
            .map(|k| sim.rod.mass[k] * (sim.v[k] - prev.v[k]).powi(2))
            .sum();
        integrator += 0.5 * dv2 + b;
        moving = moving.max(sim.kinetic_energy() + sim.elastic_energy(&sim.q));
        worst = worst.max((total(&sim) + damped + integrator - e0).abs());
    }
    (damped, integrator, worst / moving, sim.kinetic_energy())
}

#[test]
fn damped_swing_closes_the_energy_balance_and_material_damping_dissipates() {
    // loss factor 0.3 at 10 Hz, as a silicone rubber: τ = 0.3/(2π 10) s.
    let tau = 0.3 / (2.0 * std::f64::consts::PI * 10.0);
    let (damped, integrator, closure, kinetic) = damped_swing(tau, 1500);
    let (_, integrator0, closure0, kinetic0) = damped_swing(0.0, 1500);
    println!(
        "damped swing, 1 500 steps of 1e-4 s: dissipated by damping {damped:.4e} J, by the \
         integrator {integrator:.4e} J (undamped {integrator0:.4e} J), closure {closure:.2e} \
         (undamped {closure0:.2e}) of the largest kinetic + elastic energy; final kinetic \
         {kinetic:.3e} J (undamped {kinetic0:.3e} J)"
    );
    assert!(closure < 1e-6 && closure0 < 1e-6, "{closure} {closure0}");
    assert!(damped > 0.0 && integrator > 0.0);
    assert!(
        damped > integrator,
        "material damping dominates at dt = 1e-4 s"
    );
    assert!(kinetic < kinetic0);
}

#[test]
fn scenario_loss_factor_sets_the_damping_time_and_bad_values_name_the_key() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/3d-two-finger-sphere.toml"
    );
    // The shipped file's own loss factor taken out.
    let text: String = std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with("loss_factor"))
        .map(|l| format!("{l}\n"))
        .collect();
    let dir = std::path::Path::new(path).parent().unwrap();
    let with =
        |line: &str| text.replace("clamped_edges = 1", &format!("clamped_edges = 1\n{line}"));
    let sc = Scenario3::from_str(&with("loss_factor = 0.3"), "x.toml", dir).unwrap();
    let tau = 0.3 / (2.0 * std::f64::consts::PI * 10.0);
    assert!((sc.damping_time - tau).abs() < 1e-18, "{}", sc.damping_time);
    let sc = Scenario3::from_str(&text, "x.toml", dir).unwrap();
    assert_eq!(sc.damping_time, 0.0);
    let e = Scenario3::from_str(&with("loss_factor = -1"), "x.toml", dir).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("x.toml") && msg.contains("loss_factor") && msg.contains("-1"),
        "{msg}"
    );
}
