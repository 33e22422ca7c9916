//! Criterion benchmarks of the solver's kernels on the seed prong (10 nodes) and a 1000-node
//! prong: energy gradient + Hessian assembly, banded factorisation + solve, one contact
//! detection pass, and one whole step in contact.
//!
//!     cargo bench --bench kernels

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use gripsim::bench::SEED_R5;
use gripsim::contact::{self, Surfaces};
use gripsim::events::NullObserver;
use gripsim::solver::newton::assemble;
use gripsim::{Scenario, Simulation};

/// The seed grasp with `nodes` nodes, advanced until the prong is in contact with the fruit.
fn in_contact(nodes: usize) -> Simulation {
    let sets = vec![
        format!("rod.0.nodes={nodes}"),
        format!("rod.0.node_mass={:e}", 0.1 / nodes as f64),
        "solve.t_end=0.045".to_string(),
    ];
    let sc = Scenario::from_str(SEED_R5, "seed-grasp-r5", &sets).unwrap();
    let mut sim = Simulation::new(&sc);
    sim.run(&mut NullObserver).unwrap();
    assert!(
        sim.work[0].contact.iter().any(|c| c.is_some()),
        "the prong must be in contact"
    );
    sim
}

fn kernels(c: &mut Criterion) {
    for nodes in [10usize, 1000] {
        let mut sim = in_contact(nodes);
        let rod = sim.rods[0].clone();
        let q = sim.positions(0).to_vec();
        let mut w = sim.work[0].clone();
        c.bench_function(&format!("assemble gradient+hessian, {nodes} nodes"), |b| {
            b.iter(|| {
                black_box(assemble(
                    &rod,
                    &w.free_index,
                    black_box(&q),
                    &mut w.grad,
                    Some(&mut w.band),
                ))
            })
        });
        let mut band = w.band.clone();
        let mut rhs = vec![1.0; band.dim()];
        // Make it the step's Jacobian: add the mass term to the stiffness.
        assemble(&rod, &w.free_index, &q, &mut w.grad, Some(&mut band));
        for i in 0..band.dim() {
            band.add(i, i, rod.mass[0] / 1e-10);
        }
        c.bench_function(&format!("banded LU factor+solve, {nodes} nodes"), |b| {
            b.iter(|| {
                let mut m = band.clone();
                m.factor().unwrap();
                m.solve(black_box(&mut rhs));
            })
        });
        let obstacles = sim.obstacles.clone();
        c.bench_function(&format!("contact detection pass, {nodes} nodes"), |b| {
            b.iter(|| {
                let mut hits = 0;
                for i in 0..rod.n {
                    if contact::deepest(&Surfaces::fixed(&obstacles), [q[2 * i], q[2 * i + 1]], 0.0)
                        .is_some()
                    {
                        hits += 1;
                    }
                }
                black_box(hits)
            })
        });
        let (q0, u0) = (sim.positions(0).to_vec(), sim.velocities(0).to_vec());
        c.bench_function(
            &format!("one step in contact (dt = 1e-5), {nodes} nodes"),
            |b| {
                b.iter(|| {
                    sim.set_state(0, &q0, &u0);
                    black_box(sim.advance(1e-5, &mut NullObserver).is_ok());
                })
            },
        );
    }
}

criterion_group!(benches, kernels);
criterion_main!(benches);
