//! Issue 36: joints between rods (`[[joint]]`), exact in the implicit step. An L-frame with a
//! rigid corner against Castigliano, a pin-jointed two-bar truss against statics, a
//! clamped–jointed–free beam against the same beam as one rod, and the energy and momentum
//! balances of jointed frames.

use gripsim::events::NullObserver;
use gripsim::{Scenario, Simulation};

const E: f64 = 1e6;
/// A thin, wide section: EA / EI = 12 / h² = 1.2e7 m⁻², so the members' stretch is far below
/// their bending (Castigliano's closed form neglects it).
const SECTION: &str = "section = { kind = \"rect\", b = 20.0, h = 0.001 }";
const EI: f64 = E * 20.0 * 0.001 * 0.001 * 0.001 / 12.0;
const EA: f64 = E * 20.0 * 0.001;
const L: f64 = 0.1;

pub(crate) fn run(text: &str) -> Simulation {
    let sc = Scenario::from_str(text, "test.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&sc);
    sim.run(&mut NullObserver).unwrap_or_else(|e| panic!("{e}"));
    sim
}

pub(crate) fn node(sim: &Simulation, r: usize, i: usize) -> [f64; 2] {
    let q = sim.positions(r);
    [q[2 * i], q[2 * i + 1]]
}

/// An L-frame: a column clamped at its foot (the clamp's midpoint at y = 0, so its free
/// length is L) rising to (0, L), a rigid corner, a beam to (L, L) with load `p` at its tip.
fn l_frame(nodes: usize, p: [f64; 2], kind: &str, solve: &str) -> String {
    let h = L / (nodes as f64 - 1.5);
    format!(
        r#"
name = "l-frame"
[solve]
{solve}
gravity = [0.0, 0.0]
force_tol = 1e-13

[[rod]]
name = "column"
nodes = {nodes}
shape = {{ kind = "straight", start = [0.0, {y0:e}], end = [0.0, {L}] }}
E = {E:e}
{SECTION}
density = 1000.0
clamped = [0, 1]

[[rod]]
name = "beam"
nodes = {nodes}
shape = {{ kind = "straight", start = [0.0, {L}], end = [{L}, {L}] }}
E = {E:e}
{SECTION}
density = 1000.0
loads = [{{ node = {last}, force = [{px:e}, {py:e}] }}]

[[joint]]
rods = ["column", "beam"]
nodes = [{last}, 0]
kind = "{kind}"
"#,
        y0 = -h / 2.0,
        last = nodes - 1,
        px = p[0],
        py = p[1],
    )
}

/// Tip deflection of the static L-frame under a small downward tip load, relative to
/// Castigliano's along P (4 P L³ / 3 EI) and across it (P L³ / 2 EI, toward +x: the corner's
/// moment P L bends the column clockwise); and the corner's moment relative to P L.
fn l_frame_errors(nodes: usize) -> (f64, f64, f64) {
    let p = 1e-6 * EI / (L * L);
    let sim = run(&l_frame(nodes, [0.0, -p], "rigid", "mode = \"static\""));
    let tip = node(&sim, 1, nodes - 1);
    let along = L - tip[1];
    let across = tip[0] - L;
    // Castigliano with the column's axial energy (its force is P): + P L / EA, 6e-6 of the
    // bending part with this section, which the second-order check would otherwise see.
    let want_along = 4.0 * p * L.powi(3) / (3.0 * EI) + p * L / EA;
    let want_across = p * L.powi(3) / (2.0 * EI);
    let j = &sim.joints.joints[0];
    println!(
        "L-frame {nodes} nodes/member: along P {along:.6e} m (Castigliano {want_along:.6e}, err {:.3e}), \
         across {across:.6e} m (Castigliano {want_across:.6e}, err {:.3e}); joint force ({:.4e}, {:.4e}) N, \
         moment {:.4e} N·m (P L = {:.4e})",
        along / want_along - 1.0,
        across / want_across - 1.0,
        j.force[0],
        j.force[1],
        j.moment,
        p * L
    );
    // The column holds the beam up: the corner passes (0, P) to it.
    let f = (j.force[0].hypot(j.force[1] - p)) / p;
    assert!(f < 1e-4, "joint force {:?} against (0, {p:e})", j.force);
    (
        along / want_along - 1.0,
        across / want_across - 1.0,
        j.moment / (p * L),
    )
}

#[test]
fn l_frame_with_a_rigid_corner_matches_castigliano_at_second_order() {
    let mut errs = Vec::new();
    for n in [25usize, 50, 100] {
        let (a, c, m) = l_frame_errors(n);
        if n == 50 {
            assert!(a.abs() < 0.005, "along P: {a}");
            assert!(c.abs() < 0.005, "across P: {c}");
        }
        // The corner carries the beam's moment P L (the beam's joint spring turns it).
        assert!((m.abs() - 1.0).abs() < 0.02, "joint moment / P L = {m}");
        errs.push((a.abs(), c.abs()));
    }
    for k in 0..2 {
        let r = errs[k].0 / errs[k + 1].0;
        assert!(r > 3.5 && r < 4.6, "along-P error ratio {r}: {errs:?}");
        let r = errs[k].1 / errs[k + 1].1;
        assert!(r > 3.5 && r < 4.6, "across-P error ratio {r}: {errs:?}");
    }
}

/// Two bars from pinned supports A and B to a pin C, a load P at C: the bars carry axial
/// forces only, N_a u_a + N_b u_b + P = 0 (u from the support to C, compression > 0), solved
/// in the deformed geometry.
#[test]
fn pin_jointed_truss_carries_the_statically_determinate_member_forces() {
    let (a, b, c) = ([-0.1, 0.0], [0.05, 0.0], [0.0, 0.08]);
    let p = [0.3, -1.0];
    let text = format!(
        r#"
name = "truss"
[solve]
mode = "static"
gravity = [0.0, 0.0]
force_tol = 1e-13

[[rod]]
name = "left"
nodes = 21
shape = {{ kind = "straight", start = [{},{}], end = [{}, {}] }}
E = 1e9
section = {{ kind = "rect", b = 0.01, h = 0.01 }}
density = 1000.0
clamped = [0]
loads = [{{ node = 20, force = [{}, {}] }}]

[[rod]]
name = "right"
nodes = 15
shape = {{ kind = "straight", start = [{}, {}], end = [{}, {}] }}
E = 1e9
section = {{ kind = "rect", b = 0.01, h = 0.01 }}
density = 1000.0
clamped = [0]

[[joint]]
rods = ["left", "right"]
nodes = [20, 14]
kind = "pin"
"#,
        a[0], a[1], c[0], c[1], p[0], p[1], b[0], b[1], c[0], c[1]
    );
    let sim = run(&text);
    let cf = node(&sim, 0, 20);
    let unit = |s: [f64; 2]| {
        let d = [cf[0] - s[0], cf[1] - s[1]];
        let l = d[0].hypot(d[1]);
        [d[0] / l, d[1] / l]
    };
    let (ua, ub) = (unit(a), unit(b));
    // N_a ua + N_b ub = −P.
    let det = ua[0] * ub[1] - ua[1] * ub[0];
    let na = (-p[0] * ub[1] + p[1] * ub[0]) / det;
    let nb = (-ua[0] * p[1] + ua[1] * p[0]) / det;
    // The joint's force on the right bar pushes it toward B: −N_b u_b.
    let f = sim.joints.joints[0].force;
    let want = [-nb * ub[0], -nb * ub[1]];
    let err = (f[0] - want[0]).hypot(f[1] - want[1]) / nb.abs();
    // The left bar's support reaction (its clamp's force on the bar, r) is N_a u_a toward C.
    let r = &sim.work[0].r;
    let ra = [r[0], r[1]];
    let want_a = [na * ua[0], na * ua[1]];
    let err_a = (ra[0] - want_a[0]).hypot(ra[1] - want_a[1]) / na.abs();
    let rb = [sim.work[1].r[0], sim.work[1].r[1]];
    let err_b = (rb[0] - nb * ub[0]).hypot(rb[1] - nb * ub[1]) / nb.abs();
    println!(
        "truss: N_a = {na:.9} N, N_b = {nb:.9} N; joint force ({:.9}, {:.9}) N, rel err {err:.2e}; \
         support reactions rel err {err_a:.2e}, {err_b:.2e}; moment {}",
        f[0], f[1], sim.joints.joints[0].moment
    );
    assert!(err < 1e-6, "joint force {f:?} against {want:?}");
    assert!(err_a < 1e-6, "support A {ra:?} against {want_a:?}");
    assert!(err_b < 1e-6, "support B {rb:?}");
    assert_eq!(sim.joints.joints[0].moment, 0.0);
}

/// A beam of `na + nb − 1` nodes along +x, clamped at its start (nodes 0, 1), under gravity
/// and a tip load: as one rod, or as two rods rigidly joined at node na − 1.
fn beam(na: usize, nb: usize, joined: bool, solve: &str) -> String {
    let n = na + nb - 1;
    let h = L / (n as f64 - 1.5);
    let x0 = -h / 2.0;
    let xj = x0 + (na - 1) as f64 * h;
    let common = format!(
        "E = {E:e}\nsection = {{ kind = \"rect\", b = 0.02, h = 0.002 }}\ndensity = 1000.0"
    );
    let head =
        format!("name = \"beam\"\n[solve]\n{solve}\ngravity = [0.0, -9.81]\nforce_tol = 1e-13\n");
    if !joined {
        return format!(
            "{head}\n[[rod]]\nname = \"one\"\nnodes = {n}\nshape = {{ kind = \"straight\", start = [{x0:e}, 0.0], end = [{L}, 0.0] }}\n{common}\nclamped = [0, 1]\nloads = [{{ node = {}, force = [0.0, -0.002] }}]\n",
            n - 1
        );
    }
    format!(
        "{head}\n[[rod]]\nname = \"a\"\nnodes = {na}\nshape = {{ kind = \"straight\", start = [{x0:e}, 0.0], end = [{xj:e}, 0.0] }}\n{common}\nclamped = [0, 1]\n\n\
         [[rod]]\nname = \"b\"\nnodes = {nb}\nshape = {{ kind = \"straight\", start = [{xj:e}, 0.0], end = [{L}, 0.0] }}\n{common}\nloads = [{{ node = {}, force = [0.0, -0.002] }}]\n\n\
         [[joint]]\nrods = [\"a\", \"b\"]\nnodes = [{}, 0]\nkind = \"rigid\"\n",
        nb - 1,
        na - 1
    )
}

/// The joined beam's positions (and velocities) against the one rod's, node by node.
fn beam_difference(solve: &str) -> (f64, f64, f64) {
    let (na, nb) = (13usize, 19usize);
    let one = run(&beam(na, nb, false, solve));
    let two = run(&beam(na, nb, true, solve));
    let (mut dq, mut du, mut scale) = (0.0f64, 0.0f64, 0.0f64);
    let (mut umax, mut qref) = (0.0f64, [0.0; 2]);
    for k in 0..na + nb - 1 {
        let (r, i) = if k < na { (0, k) } else { (1, k - na + 1) };
        let (p1, p2) = (node(&one, 0, k), node(&two, r, i));
        let (u1, u2) = (one.velocities(0), two.velocities(r));
        let dq0 = [one.rods[0].q0[2 * k], one.rods[0].q0[2 * k + 1]];
        for a in 0..2 {
            dq = dq.max((p1[a] - p2[a]).abs());
            scale = scale.max((p1[a] - dq0[a]).abs());
            du = du.max((u1[2 * k + a] - u2[2 * i + a]).abs());
            umax = umax.max(u1[2 * k + a].abs());
        }
        qref = p1;
    }
    println!(
        "one rod against joined ({solve:?}): max |Δq| {dq:.3e} m of max displacement {scale:.3e} m \
         (tip {qref:?}), max |Δu| {du:.3e} of {umax:.3e} m/s; joint moment {:.6e} N·m",
        two.joints.joints[0].moment
    );
    (dq / scale, if umax > 0.0 { du / umax } else { 0.0 }, scale)
}

#[test]
fn a_rigid_joint_transmits_the_moment_as_one_rod_static() {
    let (rq, _, scale) = beam_difference("mode = \"static\"");
    assert!(scale > 1e-3, "the beam should bend visibly: {scale}");
    assert!(rq < 1e-9, "static: relative position difference {rq:e}");
}

#[test]
fn a_rigid_joint_transmits_the_moment_as_one_rod_dynamic() {
    let (rq, ru, scale) =
        beam_difference("mode = \"dynamic\"\nt_end = 0.02\ndt = 1e-4\nstepping = \"fixed\"");
    assert!(scale > 1e-4, "the beam should swing visibly: {scale}");
    assert!(rq < 1e-9, "dynamic: relative position difference {rq:e}");
    assert!(ru < 1e-9, "dynamic: relative velocity difference {ru:e}");
}

/// The energy balance of a swinging L-frame (clamped column, rigid corner) closes as tightly
/// as the one rod's; a free L-frame thrown in zero gravity keeps its momentum.
#[test]
fn energy_and_momentum_balances_close_with_joints() {
    let dynamic = "mode = \"dynamic\"\nt_end = 0.05\ndt = 1e-4\nstepping = \"fixed\"";
    let text = l_frame(20, [0.0, -0.01], "rigid", dynamic)
        .replace("gravity = [0.0, 0.0]", "gravity = [0.0, -9.81]");
    let sim = run(&text);
    let jointed = sim.stats.energy.closure_rel();
    let one = run(&beam(13, 19, false, dynamic));
    let single = one.stats.energy.closure_rel();
    let e = &sim.stats.energy;
    println!("energy closure: L-frame {jointed:.3e}, one rod {single:.3e}; L-frame terms {e:?}");
    assert!(jointed.abs() < 1e-8, "L-frame closure {jointed:e}");
    assert!(
        jointed.abs() <= 10.0 * single.abs().max(1e-10),
        "{jointed:e} against {single:e}"
    );
    for kind in ["rigid", "pin"] {
        let free = l_frame(20, [0.0, 0.0], kind, dynamic)
            .replace("clamped = [0, 1]", "velocity = [0.3, 0.5]");
        let sim = run(&free);
        let (mut p0, mut p1) = ([0.0; 2], [0.0; 2]);
        for r in 0..2 {
            let rod = &sim.rods[r];
            let u = sim.velocities(r);
            for i in 0..rod.n {
                for a in 0..2 {
                    p0[a] += rod.mass[i] * rod.velocity[a];
                    p1[a] += rod.mass[i] * u[2 * i + a];
                }
            }
        }
        let err = (p1[0] - p0[0]).hypot(p1[1] - p0[1]) / p0[0].hypot(p0[1]);
        let closure = sim.stats.energy.closure_rel();
        println!("free L-frame ({kind}): momentum {p0:?} → {p1:?} (rel {err:.2e}), energy closure {closure:.3e}");
        assert!(err < 1e-10, "{kind}: momentum {p0:?} → {p1:?}");
        assert!(closure.abs() < 1e-8, "{kind}: closure {closure:e}");
    }
}

/// The joints' force and moment reach every step's end and the run's summary.
#[test]
fn joint_force_and_moment_reach_the_step_end_and_the_summary() {
    use gripsim::events::{Event, Observer};
    use gripsim::record::summary::SummaryCollector;
    struct Both(SummaryCollector, Vec<gripsim::events::JointView>);
    impl Observer for Both {
        fn on_event(&mut self, e: &Event<'_>) {
            self.0.on_event(e);
            if let Event::StepEnd { joints, .. } = e {
                self.1 = joints.to_vec();
            }
        }
    }
    let p = 1e-6 * EI / (L * L);
    let sc = Scenario::from_str(
        &l_frame(30, [0.0, -p], "rigid", "mode = \"static\""),
        "t.toml",
        &[],
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&sc);
    let mut obs = Both(SummaryCollector::new(), Vec::new());
    sim.run(&mut obs).unwrap_or_else(|e| panic!("{e}"));
    let s = obs.0.finish(&sim.stats, 0.0);
    let last = obs.1[0];
    assert_eq!((last.rods, last.nodes), ([0, 1], [29, 0]));
    assert!((last.force[1] / p - 1.0).abs() < 1e-4, "{last:?}");
    assert!((last.moment.abs() / (p * L) - 1.0).abs() < 1e-3, "{last:?}");
    let js = &s.joints[0];
    println!("summary joint: {js:?}");
    assert_eq!(js.rods, ["column".to_string(), "beam".to_string()]);
    assert_eq!(js.final_force_n, last.force);
    assert!((js.peak_force_n / p - 1.0).abs() < 1e-4);
    assert!((js.peak_moment_nm / (p * L) - 1.0).abs() < 1e-3);
}

/// A Fin Ray finger built by hand: front flank from (0, 0) up to the tip (0, H), back flank
/// from (W, 0) to the tip, `ribs` horizontal ribs between them at equal spacing, joined
/// `kind` at both ends, the flanks rigidly joined at the tip, both clamped at the base
/// (nodes 0, 1). With `ribs = 0` and no back flank: the front flank alone, a single prong.
/// A static load `p` (N, +x: pressing into the finger) at the front flank's mid node.
fn fin_ray(ribs: usize, kind: &str, p: f64, single: bool) -> String {
    fin_ray_with(ribs, kind, p, single, 0.04, 0.002)
}

/// [`fin_ray`] with base width `w` (m) and rib thickness `rib_h` (m).
pub(crate) fn fin_ray_with(
    ribs: usize,
    kind: &str,
    p: f64,
    single: bool,
    w: f64,
    rib_h: f64,
) -> String {
    const H: f64 = 0.1;
    let per = 6; // front-flank edges between ribs
    let nf = (ribs + 1) * per + 1;
    let mid = (nf - 1) / 2;
    let rod = |name: &str, n: usize, a: [f64; 2], b: [f64; 2], extra: &str| {
        let h = if name.starts_with("rib") {
            rib_h
        } else {
            0.002
        };
        format!(
            "[[rod]]\nname = \"{name}\"\nnodes = {n}\nshape = {{ kind = \"straight\", start = [{:e}, {:e}], end = [{:e}, {:e}] }}\n\
             E = 1e6\nsection = {{ kind = \"rect\", b = 0.02, h = {h:e} }}\ndensity = 1000.0\n{extra}\n\n",
            a[0], a[1], b[0], b[1]
        )
    };
    let mut t = String::from(
        "name = \"fin-ray\"\n[solve]\nmode = \"static\"\ngravity = [0.0, 0.0]\nforce_tol = 1e-12\n\n",
    );
    let load = format!("clamped = [0, 1]\nloads = [{{ node = {mid}, force = [{p:e}, 0.0] }}]");
    t += &rod("front", nf, [0.0, 0.0], [0.0, H], &load);
    if single {
        return t;
    }
    t += &rod("back", nf, [w, 0.0], [0.0, H], "clamped = [0, 1]");
    t += &format!(
        "[[joint]]\nrods = [\"front\", \"back\"]\nnodes = [{}, {}]\nkind = \"rigid\"\n\n",
        nf - 1,
        nf - 1
    );
    for k in 1..=ribs {
        let i = k * per;
        let y = H * i as f64 / (nf - 1) as f64;
        let xb = w * (1.0 - y / H);
        // The back flank's node i at height y: its straight shape puts node i at w (1 − i/(nf−1)).
        t += &rod(&format!("rib{k}"), 7, [0.0, y], [xb, y], "");
        t += &format!(
            "[[joint]]\nrods = [\"front\", \"rib{k}\"]\nnodes = [{i}, 0]\nkind = \"{kind}\"\n\n"
        );
        t += &format!(
            "[[joint]]\nrods = [\"back\", \"rib{k}\"]\nnodes = [{i}, 6]\nkind = \"{kind}\"\n\n"
        );
    }
    t
}

/// The Fin Ray effect of a hand-built finger (front flank, back flank, ribs; W = 0.04 m,
/// H = 0.1 m, flanks and ribs 2 mm thick): pushed at the front flank's mid node, a small push
/// leaves the tip nearly still (it follows the push by ~1 % of a single prong's tip motion);
/// a large push (P = 0.2 N, the front flank pushed in by a third of its length) with pinned
/// ribs turns the tip toward the load (−x), where the front flank alone swings away (+x).
#[test]
fn fin_ray_finger_with_pinned_ribs_wraps_toward_a_large_mid_flank_push() {
    let tip = |text: &str| {
        let sim = run(text);
        let n = sim.rods[0].n;
        (node(&sim, 0, n - 1)[0], node(&sim, 0, (n - 1) / 2)[0])
    };
    let (small_single, _) = tip(&fin_ray(0, "pin", 1e-3, true));
    let (small, small_mid) = tip(&fin_ray(5, "pin", 1e-3, false));
    println!(
        "P = 1e-3 N: single prong tip dx {small_single:.4e} m; fin ray (5 pinned ribs) tip dx \
         {small:.4e} m, mid dx {small_mid:.4e} m"
    );
    assert!(small_single > 0.0 && small_mid > 0.0);
    assert!(
        small.abs() < 0.01 * small_single,
        "{small} against {small_single}"
    );
    let (single, single_mid) = tip(&fin_ray(0, "pin", 0.2, true));
    println!("P = 0.2 N: single prong tip dx {single:.4e} m, mid dx {single_mid:.4e} m");
    assert!(single > 0.05, "the single prong swings away: {single}");
    for ribs in [4usize, 5] {
        let (t, m) = tip(&fin_ray(ribs, "pin", 0.2, false));
        println!("P = 0.2 N: fin ray ({ribs} pinned ribs) tip dx {t:.4e} m, mid dx {m:.4e} m");
        assert!(m > 0.03, "the flank is pushed in: {m}");
        assert!(t < -2e-3, "{ribs} ribs: the tip turns toward the load: {t}");
    }
}
