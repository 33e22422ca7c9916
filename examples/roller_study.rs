//! The roller study of docs/verification.md ("Roller indentation"): the rigid 20 mm roller of
//! `scenarios/fin-ray-roller.toml` indents the Fin Ray finger at mid-flank, and the same run with
//! the finger replaced by its front flank alone (a single prong clamped at nodes 0 and 1).
//! Prints the table and draws `docs/img/fin-ray-roller.png` and `.svg`:
//!
//! ```sh
//! cargo run --release --example roller_study [OUT_BASE]
//! ```

use gripsim::bench::plot::{panels, Panel, Series};
use gripsim::study::indent::{indentation_run, mean_near, IndentSample};
use gripsim::Scenario;
use std::path::Path;

/// The single prong of the same flank: the Fin Ray's front flank, clamped like it.
const PRONG: [&str; 2] = [
    "rod.0.shape={ kind = \"straight\", start = [0.0, 0.0], end = [0.0, 0.1] }",
    "rod.0.clamped=[0, 1]",
];

fn run(sets: &[&str]) -> Vec<IndentSample> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fin-ray-roller.toml");
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let sc = Scenario::load(&path, &sets).unwrap_or_else(|e| panic!("{e}"));
    indentation_run(&sc, 0, 0, 0).unwrap_or_else(|e| panic!("{e}"))
}

/// The mean of the samples within 0.5 mm of indentation `d`.
fn at(s: &[IndentSample], d: f64) -> IndentSample {
    mean_near(s, d, 0.5e-3).expect("samples near the indentation")
}

fn main() {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "docs/img/fin-ray-roller".to_string());
    let fin = run(&[]);
    let prong = run(&PRONG);
    println!("| indentation (mm) | Fin Ray force (N) | contacts | within 0.5 mm (mm) | prong force (N) | contacts | within 0.5 mm (mm) |");
    println!("|---|---|---|---|---|---|---|");
    for mm in [1.0, 3.0, 5.0, 7.0, 9.0, 11.0, 13.0, 15.0, 17.0, 19.0] {
        let (a, b) = (at(&fin, mm * 1e-3), at(&prong, mm * 1e-3));
        println!(
            "| {:.1} | {:.4} | {} | {:.1} | {:.4} | {} | {:.1} |",
            a.indentation * 1e3,
            a.force,
            a.contacts,
            a.near * 1e3,
            b.force,
            b.contacts,
            b.near * 1e3
        );
    }
    draw(&out, &fin, &prong).unwrap_or_else(|e| panic!("{out}: {e}"));
    println!("wrote {out}.png, {out}.svg");
}

fn draw(out: &str, fin: &[IndentSample], prong: &[IndentSample]) -> Result<(), String> {
    let series = |pick: fn(&IndentSample) -> f64| {
        [
            (fin, "Fin Ray finger"),
            (prong, "single prong (its front flank)"),
        ]
        .iter()
        .map(|(s, name)| Series {
            name: name.to_string(),
            points: s
                .iter()
                .filter(|x| x.contacts > 0)
                .map(|x| (x.indentation * 1e3, pick(x)))
                .collect(),
        })
        .collect::<Vec<_>>()
    };
    let panel = |title: &str, y: &str, series| Panel {
        title: title.to_string(),
        x_label: "indentation (mm)".to_string(),
        y_label: y.to_string(),
        log_x: false,
        log_y: false,
        series,
    };
    panels(
        Path::new(out),
        "20 mm rigid roller at mid-flank (scenarios/fin-ray-roller.toml)",
        &[
            panel(
                "roller force",
                "force on the roller (N)",
                series(|s| s.force),
            ),
            panel(
                "flank within 0.5 mm of the roller",
                "length (mm)",
                series(|s| s.near * 1e3),
            ),
        ],
        2,
    )
}
