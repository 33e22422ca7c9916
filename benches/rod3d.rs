//! Cost of one implicit Euler step of a 3D rod against its node count (100 … 6 400 nodes,
//! doubling): a clamped helical prong swinging under gravity, timed over a fixed number of
//! steps after two warm-up steps, best of two runs, in CPU time of the thread (the machine is shared: wall
//! time would count the other processes). Prints the time
//! per step and per Newton iteration and the ratio per doubling (linear cost: 2.0).
//! Then the bending/twisting kernel alone (hand-derived against dual numbers, per stencil) and
//! the 3D step against the planar seed prong (`gripsim bench` scaling: seed grasp, N nodes per
//! prong, dt = 1e-5 s, before contact) at the same nodes and dt.
//!
//! Last, the shipped 3D two-finger grasp against the shipped planar two-prong grasp at the same
//! nodes (10 per prong) and dt (1e-5 s): the ratio of their costs per step.
//!
//!     cargo bench --bench rod3d [-- --planar | --grasp | --grasp3]
//!
//! (`--grasp3`: the undamped 3D grasp alone, for a profiler; `--grasp3 --once`: one run.)

use gripsim::bench::SEED_R5;
use gripsim::events::NullObserver;
use gripsim::rod3d::energy::{node_derivatives, EdgeFrame, NodeElastic};
use gripsim::rod3d::kernel;
use gripsim::rod3d::run3;
use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3};
use gripsim::scenario::three::Scenario3;
use gripsim::{Scenario, Simulation};
use std::hint::black_box;

/// CPU time consumed by this thread (s).
fn thread_cpu() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn prong(nodes: usize) -> Sim3 {
    // A 0.1 m helical prong, resolution refined at fixed length.
    let points = (0..nodes)
        .map(|i| {
            let s = i as f64 / (nodes - 1) as f64;
            let a = 2.0 * std::f64::consts::PI * 0.5 * s;
            [0.02 * a.cos(), 0.02 * a.sin(), 0.09 * s]
        })
        .collect();
    let spec = Rod3Spec {
        points,
        director: [0.0, 0.0, 1.0],
        rest_theta: vec![],
        section: Section3::Rect { b: 0.004, h: 0.002 },
        youngs_modulus: 1e6,
        shear_modulus: 1e6 / 3.0,
        density: 1000.0,
    };
    let mut sim = Sim3::new(Rod3::new(&spec));
    sim.clamp_edge(0);
    sim.gravity = [0.0, -9.81, 0.0];
    sim
}

/// CPU µs per call of the dual-number and the hand-derived stencil derivatives.
fn kernels() -> (f64, f64) {
    let e = [0.01, 0.002, 0.001];
    let f = [0.009, 0.004, -0.002];
    let norm = |a: [f64; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let old = [
        EdgeFrame {
            t: norm([1.0, 0.1, 0.0]),
            a1: norm([-0.1, 1.0, 0.0]),
        },
        EdgeFrame {
            t: norm([1.0, 0.3, -0.1]),
            a1: norm([-0.3, 1.0, 0.0]),
        },
    ];
    let x = [
        0.0,
        0.0,
        0.0,
        0.1,
        e[0],
        e[1],
        e[2],
        0.2,
        e[0] + f[0],
        e[1] + f[1],
        e[2] + f[2],
    ];
    let p = NodeElastic {
        ei1: 1.0,
        ei2: 2.0,
        gj: 0.7,
        kappa_bar: [0.1, -0.2],
        twist_bar: 0.05,
    };
    let (mut g, mut h) = ([0.0; 11], [[0.0; 11]; 11]);
    let reps = 20_000;
    let mut best = [f64::INFINITY; 2];
    for _ in 0..3 {
        let t = thread_cpu();
        for _ in 0..reps {
            node_derivatives(black_box(&x), [&old[0], &old[1]], 0.0, &p, &mut g, &mut h);
        }
        best[0] = best[0].min((thread_cpu() - t) / reps as f64 * 1e6);
        let t = thread_cpu();
        for _ in 0..reps {
            kernel::node_derivatives(black_box(&x), [&old[0], &old[1]], 0.0, &p, &mut g, &mut h);
        }
        best[1] = best[1].min((thread_cpu() - t) / reps as f64 * 1e6);
    }
    black_box(&h);
    (best[0], best[1])
}

/// CPU µs per step and Newton iterations per step of the planar seed prong with `n` nodes.
fn planar(n: usize, steps: usize) -> (f64, f64) {
    let sets = vec![
        format!("rod.0.nodes={n}"),
        format!("rod.0.node_mass={:e}", 0.1 / n as f64),
        format!("solve.t_end={:e}", steps as f64 * 1e-5),
    ];
    let sc = Scenario::from_str(SEED_R5, "seed-grasp-r5", &sets).expect("seed scenario");
    let mut best = (f64::INFINITY, 0.0);
    for _ in 0..2 {
        let mut sim = Simulation::new(&sc);
        let t = thread_cpu();
        let st = sim.run(&mut NullObserver).expect("planar run");
        let us = (thread_cpu() - t) * 1e6 / st.steps as f64;
        if us < best.0 {
            best = (us, st.newton_iterations as f64 / st.steps as f64);
        }
    }
    best
}

/// CPU µs per step and Newton iterations per step of the 3D prong with `n` nodes.
fn spatial(n: usize, steps: usize, dt: f64) -> (f64, f64) {
    let mut best = (f64::INFINITY, 0.0);
    for _ in 0..2 {
        let mut sim = prong(n);
        sim.step(dt).expect("warm-up step");
        let it0 = sim.newton_iterations;
        let t = thread_cpu();
        for _ in 0..steps {
            sim.step(dt).expect("step");
        }
        let us = (thread_cpu() - t) * 1e6 / steps as f64;
        if us < best.0 {
            best = (us, (sim.newton_iterations - it0) as f64 / steps as f64);
        }
    }
    best
}

fn against_planar() {
    let (dual, hand) = kernels();
    println!(
        "\nbending/twisting stencil derivatives: dual numbers {dual:.3} µs, hand-derived {hand:.3} µs ({:.1}× faster)",
        dual / hand
    );
    println!("\n3D prong against the planar seed prong, dt = 1e-5 s, CPU µs:");
    println!("| nodes | 3D µs/step | 3D it/step | planar µs/step | planar it/step | × per step | × per iteration | 3D µs/node/iteration |");
    println!("|---|---|---|---|---|---|---|---|");
    for n in [10usize, 100, 1000, 10000] {
        let steps = (400_000 / n).clamp(20, 400);
        let (s3, i3) = spatial(n, steps, 1e-5);
        let (s2, i2) = planar(n, steps);
        println!(
            "| {n} | {s3:.2} | {i3:.2} | {s2:.2} | {i2:.2} | {:.2} | {:.2} | {:.3} |",
            s3 / s2,
            (s3 / i3) / (s2 / i2),
            s3 / i3 / n as f64
        );
    }
}

/// The shipped 3D two-finger grasp (scenarios/3d-two-finger-sphere.toml) run at `dt`, whole:
/// CPU µs per step, steps, Newton iterations and contact passes per step. Best of `runs`.
fn grasp3(dt: f64, damped: bool, runs: usize) -> (f64, u64, f64, f64) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/3d-two-finger-sphere.toml"
    );
    let mut sc = Scenario3::load(std::path::Path::new(path)).expect("3D grasp scenario");
    sc.dt = dt;
    if !damped {
        sc.damping_time = 0.0;
    }
    let mut best = (f64::INFINITY, 0, 0.0, 0.0);
    for _ in 0..runs {
        let t = thread_cpu();
        let s = run3::run(&sc, None).expect("3D grasp run");
        let us = (thread_cpu() - t) * 1e6 / s.steps as f64;
        if us < best.0 {
            let n = s.steps as f64;
            let (it, passes) = (s.newton_iterations as f64, s.contact_passes as f64);
            best = (us, s.steps, it / n, passes / n);
        }
    }
    best
}

/// The shipped planar two-prong grasp (scenarios/two-prong-grasp.toml), whole, unrecorded:
/// CPU µs per step, steps, Newton iterations per step. Best of `runs`.
fn grasp2(runs: usize) -> (f64, u64, f64) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/two-prong-grasp.toml"
    );
    let sc = Scenario::load(std::path::Path::new(path), &[]).expect("planar grasp scenario");
    let mut best = (f64::INFINITY, 0, 0.0);
    for _ in 0..runs {
        let mut sim = Simulation::new(&sc);
        let t = thread_cpu();
        let st = sim.run(&mut NullObserver).expect("planar grasp run");
        let us = (thread_cpu() - t) * 1e6 / st.steps as f64;
        if us < best.0 {
            best = (us, st.steps, st.newton_iterations as f64 / st.steps as f64);
        }
    }
    best
}

/// Issue 16's "3D two-finger grasp within 5× the planar step cost at the planar scenario's
/// resolution": both shipped grasps have 10-node prongs; the 3D one is run at the planar
/// one's dt = 1e-5 s without material damping (the planar grasp has none), then as shipped
/// (loss factor 0.3) and at its own dt = 1e-4 s for reference.
///
/// The planar figure is bimodal on a shared machine (the same binary measures 6.3 or 10 µs
/// in runs minutes apart), so the two sides are measured in interleaved rounds, each a planar
/// run (best of 3) right before a 3D run: the ratio is reported best against best and as the
/// median of the rounds' ratios. Both sides run the same work in every round.
fn grasp_ratio() {
    const ROUNDS: usize = 5;
    let (mut planar, mut undamped) = ((f64::INFINITY, 0, 0.0), (f64::INFINITY, 0, 0.0, 0.0));
    let mut ratios = Vec::with_capacity(ROUNDS);
    println!("\nInterleaved rounds (planar best of 3, then the 3D grasp undamped at dt 1e-5), CPU µs per step:");
    for round in 1..=ROUNDS {
        let p = grasp2(3);
        let u = grasp3(1e-5, false, 1);
        println!(
            "round {round}: planar {:.2}, 3D {:.2}, × {:.2}",
            p.0,
            u.0,
            u.0 / p.0
        );
        ratios.push(u.0 / p.0);
        if p.0 < planar.0 {
            planar = p;
        }
        if u.0 < undamped.0 {
            undamped = u;
        }
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ROUNDS / 2];
    let (us2, n2, it2) = planar;
    println!(
        "\nTwo-finger grasps, 10 nodes per prong, whole scenarios, CPU µs per step (best of runs):"
    );
    println!("| run | dt (s) | steps | µs/step | Newton it/step | passes/step | × planar |");
    println!("|---|---|---|---|---|---|---|");
    println!("| planar two-prong-grasp | 1e-5 | {n2} | {us2:.2} | {it2:.2} | | 1 |");
    let row = |label: &str, dt: f64, (us3, n3, it3, p3): (f64, u64, f64, f64)| {
        println!(
            "| {label} | {dt:e} | {n3} | {us3:.2} | {it3:.2} | {p3:.3} | {:.2} |",
            us3 / us2
        );
    };
    row("3d-two-finger-sphere, undamped", 1e-5, undamped);
    row(
        "3d-two-finger-sphere, as shipped",
        1e-5,
        grasp3(1e-5, true, 2),
    );
    row(
        "3d-two-finger-sphere, as shipped",
        1e-4,
        grasp3(1e-4, true, 2),
    );
    println!(
        "3D undamped against planar: {:.2}× best against best, {median:.2}× median of {ROUNDS} interleaved rounds",
        undamped.0 / us2
    );
}

fn main() {
    if std::env::args().any(|a| a == "--planar") {
        against_planar();
        return;
    }
    if std::env::args().any(|a| a == "--grasp") {
        grasp_ratio();
        return;
    }
    if std::env::args().any(|a| a == "--grasp3") {
        // The undamped 3D grasp at dt = 1e-5 alone (for a profiler; `--once`: one run, for
        // an instruction counter).
        let runs = if std::env::args().any(|a| a == "--once") {
            1
        } else {
            3
        };
        let (us, n, it, passes) = grasp3(1e-5, false, runs);
        println!("3d-two-finger-sphere, undamped, dt 1e-5: {n} steps, {us:.2} µs/step, {it:.2} it/step, {passes:.3} passes/step");
        return;
    }
    let dt = 1e-4;
    let mut last: Option<f64> = None;
    println!("| nodes | steps | CPU ms/step | Newton it/step | ms/iteration | ×/doubling (step) |");
    println!("|---|---|---|---|---|---|");
    let mut fit = vec![];
    let mut n = 100;
    while n <= 6400 {
        let steps = (60_000 / n).clamp(8, 600);
        let (mut ms, mut its) = (f64::INFINITY, 0.0);
        for _ in 0..2 {
            let mut sim = prong(n);
            for _ in 0..2 {
                sim.step(dt).expect("warm-up step");
            }
            let it0 = sim.newton_iterations;
            let t = thread_cpu();
            for _ in 0..steps {
                sim.step(dt).expect("step");
            }
            let run = (thread_cpu() - t) * 1e3 / steps as f64;
            if run < ms {
                ms = run;
                its = (sim.newton_iterations - it0) as f64 / steps as f64;
            }
        }
        let ratio = last.map(|l| format!("{:.2}", ms / l)).unwrap_or_default();
        println!(
            "| {n} | {steps} | {ms:.3} | {its:.2} | {:.3} | {ratio} |",
            ms / its
        );
        last = Some(ms);
        fit.push(((n as f64).ln(), ms.ln()));
        n *= 2;
    }
    // Least-squares slope of log(cost) against log(nodes): 1 for linear cost.
    let k = fit.len() as f64;
    let (sx, sy) = fit.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let (mx, my) = (sx / k, sy / k);
    let num: f64 = fit.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let den: f64 = fit.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let total = (fit[fit.len() - 1].1 - fit[0].1).exp();
    println!(
        "cost ∝ nodes^{:.3}; 6 400 / 100 nodes: {total:.1}× (linear: 64×, {:.2}× per doubling)",
        num / den,
        total.powf(1.0 / 6.0)
    );
    against_planar();
    grasp_ratio();
}
