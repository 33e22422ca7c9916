//! Issue 36: the roller study. A rigid 20 mm roller indents the shipped Fin Ray finger at
//! mid-flank (scenarios/fin-ray-roller.toml); the same run with the finger replaced by its front
//! flank alone (a single prong clamped at nodes 0 and 1) is the comparison. The numbers are the
//! table of docs/verification.md ("Roller indentation"), made by
//! `cargo run --release --example roller_study`.

use gripsim::study::indent::{indentation_run, mean_near, IndentSample};
use gripsim::Scenario;

fn run(sets: &[&str]) -> Vec<IndentSample> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fin-ray-roller.toml");
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let sc = Scenario::load(&path, &sets).unwrap_or_else(|e| panic!("{e}"));
    indentation_run(&sc, 0, 0, 0).unwrap_or_else(|e| panic!("{e}"))
}

/// Force (N) and length within 0.5 mm of the roller (m), averaged over ±0.5 mm of
/// indentation, at 1, 3, … 19 mm.
fn curve(s: &[IndentSample]) -> Vec<(f64, f64, usize)> {
    (0..10)
        .map(|k| {
            let d = (1.0 + 2.0 * k as f64) * 1e-3;
            let m = mean_near(s, d, 0.5e-3).unwrap_or_else(|| panic!("no sample near {d}"));
            (m.force, m.near, m.contacts)
        })
        .collect()
}

/// The force rises monotonically with the indentation for both; the Fin Ray is 7.3 × as stiff
/// as its flank alone at 19 mm (0.0513 N against 0.0070 N); the roller touches either at one
/// or two points, and from 13 mm on more of the Fin Ray's flank hugs the roller (within
/// 0.5 mm of it) than the prong's: 7.5 mm against 5.6 mm at 19 mm.
#[test]
fn a_roller_indents_the_fin_ray_stiffer_and_hugged_longer_than_a_single_prong() {
    let fin = curve(&run(&[]));
    let prong = curve(&run(&[
        "rod.0.shape={ kind = \"straight\", start = [0.0, 0.0], end = [0.0, 0.1] }",
        "rod.0.clamped=[0, 1]",
    ]));
    for (k, (f, p)) in fin.iter().zip(&prong).enumerate() {
        println!(
            "{:>2} mm: fin ray {:.4} N, {} contact(s), {:.1} mm near; prong {:.4} N, {} contact(s), {:.1} mm near",
            1 + 2 * k,
            f.0,
            f.2,
            f.1 * 1e3,
            p.0,
            p.2,
            p.1 * 1e3
        );
    }
    for c in [&fin, &prong] {
        for w in c.windows(2) {
            assert!(w[1].0 > w[0].0, "force not rising: {:?}", c);
        }
        assert!(c.iter().all(|x| (1..=2).contains(&x.2)), "{c:?}");
    }
    let (f19, p19) = (fin[9], prong[9]);
    assert!(
        (f19.0 - 0.0513).abs() < 0.0005,
        "fin ray at 19 mm: {}",
        f19.0
    );
    assert!((p19.0 - 0.0070).abs() < 0.0003, "prong at 19 mm: {}", p19.0);
    assert!(f19.0 / p19.0 > 6.5, "{} / {}", f19.0, p19.0);
    // The closed form of the prong: a cantilever pushed at a = 50 mm, F = 3 EI δ / a³.
    let ei = 1e6 * 0.02 * 0.002f64.powi(3) / 12.0;
    let linear = 3.0 * ei * 5e-3 / 0.05f64.powi(3);
    assert!(
        (prong[2].0 / linear - 1.0).abs() < 0.1,
        "prong at 5 mm: {} vs {linear}",
        prong[2].0
    );
    for k in 6..10 {
        assert!(
            fin[k].1 > prong[k].1 + 0.5e-3,
            "{} mm: {:?} {:?}",
            1 + 2 * k,
            fin[k],
            prong[k]
        );
    }
    assert!((f19.1 - 7.5e-3).abs() < 0.3e-3 && (p19.1 - 5.6e-3).abs() < 0.3e-3);
}
