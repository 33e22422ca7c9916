//! Cost of one implicit Euler step of a 3D rod against its node count (100 … 6 400 nodes,
//! doubling): a clamped helical prong swinging under gravity, timed over a fixed number of
//! steps after two warm-up steps, best of two runs, in CPU time of the thread (the machine is shared: wall
//! time would count the other processes). Prints the time
//! per step and per Newton iteration and the ratio per doubling (linear cost: 2.0).
//!
//!     cargo bench --bench rod3d

use gripsim::rod3d::{Rod3, Rod3Spec, Section3, Sim3};

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

fn main() {
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
}
