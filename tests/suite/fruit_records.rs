//! Recordings and replay of a compliant free fruit (issue 32): `replay check`'s bruise rule on
//! the fruit's prong contacts and on its own contact with the table, the MCAP and CSV carrying
//! those contacts' pressure and indentation, and the sweep's bruise columns.

use crate::common::{gripsim, scenario, text};
use serde_json::Value;
use std::path::Path;

/// tests/suite/fruit.rs's compliant disc on a table (a 4 cm apple disc of 0.15 kg), with a
/// short stiff cantilever standing beside it, out of its way: a recording has a rod.
const DROP: &str = r#"
name = "compliant-disc-drop"
[solve]
mode = "dynamic"
t_end = 0.2
dt = 1e-5
stepping = "fixed"
gravity = [0.0, -9.81]
force_tol = 1e-11

[[rod]]
name = "post"
nodes = 4
shape = { kind = "straight", start = [0.2, 0.1], end = [0.2, 0.15] }
E = 5e7
section = { kind = "rect", b = 0.02, h = 0.01 }
density = 1000.0
clamped = [0, 1]

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

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `gripsim run` of `scenario` with `sets` to an MCAP of every step and a summary in `dir`.
fn record(scenario: &Path, sets: &[String], dir: &Path, tag: &str) -> (Value, std::path::PathBuf) {
    let mcap = dir.join(format!("{tag}.mcap"));
    let summary = dir.join(format!("{tag}.json"));
    let mut cmd = gripsim();
    cmd.arg("run")
        .arg(scenario)
        .args(["-q", "--detail", "step"]);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let out = cmd
        .arg("--mcap")
        .arg(&mcap)
        .arg("--summary")
        .arg(&summary)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    (json(&summary), mcap)
}

/// `gripsim replay check` of `mcap`: its exit code, stdout and JSON report.
fn check(mcap: &Path) -> (i32, String, Value) {
    let report = mcap.with_extension("check.json");
    let out = gripsim()
        .args(["replay", "check"])
        .arg(mcap)
        .arg("--json")
        .arg(&report)
        .output()
        .unwrap();
    let code = out.status.code().unwrap();
    assert!(code == 0 || code == 1, "{}", text(&out));
    (code, String::from_utf8(out.stdout).unwrap(), json(&report))
}

/// The drop tests of tests/suite/fruit.rs, recorded: from 10 cm the table bruises the fruit
/// (1.65x the apple's 0.1 MPa), `replay check` flags it and names the place "fruit on table"
/// (no rod: the fruit's own contact), with the summary's peak pressure; from 1 cm (0.88x) the
/// recording is clean.
#[test]
fn replay_check_names_a_bruise_from_a_drop_on_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("drop.toml");
    std::fs::write(&file, DROP).unwrap();
    for (h, bruised) in [(0.10, true), (0.01, false)] {
        let t_end = (2.0 * h / 9.81f64).sqrt() + 0.01;
        let sets = [
            format!("obstacle.1.center=[0.0,{}]", 0.04 + h),
            format!("solve.t_end={t_end}"),
        ];
        let (summary, mcap) = record(&file, &sets, dir.path(), &format!("drop{h}"));
        let p = &summary["contact_pressure"];
        assert_eq!(p["bruised"], bruised, "{p}");
        assert_eq!(p["max_pressure_node"]["rod"], "table");
        let (code, out, rep) = check(&mcap);
        let flags = rep["bruise"].as_array().cloned().unwrap_or_default();
        println!("drop {h} m: exit {code}\n{out}");
        if !bruised {
            assert_eq!(code, 0, "{out}");
            assert!(flags.is_empty(), "{rep}");
            assert_eq!(rep["counts"]["bruise"], 0);
            continue;
        }
        assert_eq!(code, 1, "{out}");
        assert_eq!(flags.len(), 1, "{rep}");
        let f = &flags[0];
        assert_eq!(f["rod"], Value::Null, "{f}");
        assert_eq!(f["rod_name"], "fruit on table", "{f}");
        assert_eq!(
            (f["node"].as_u64(), f["obstacle"].as_u64()),
            (Some(0), Some(0))
        );
        // The recorded f32 of the run's peak.
        let peak = p["max_pressure_pa"].as_f64().unwrap();
        assert_eq!(f["max_pressure_pa"].as_f64().unwrap(), peak as f32 as f64);
        assert_eq!(f["max_pressure_t"], p["max_pressure_time_s"]);
        assert!((f["ratio"].as_f64().unwrap() - 1.6466).abs() < 1e-3, "{f}");
        assert!(out.contains("  fruit on table steps "), "{out}");
    }
}

/// apple-squeeze-bruise recorded: the prongs bruise the moving apple as its `[expect]` says,
/// so `replay check` reports the bruise (the summary's peak, at its node) and is clean; the
/// same scenario squeezed to 10 N does not bruise and is flagged "bruise missing".
#[test]
fn replay_check_reports_the_squeezed_apples_expected_bruise_and_a_missing_one() {
    let dir = tempfile::tempdir().unwrap();
    let file = scenario("apple-squeeze-bruise");
    let (summary, mcap) = record(&file, &[], dir.path(), "squeeze");
    let p = &summary["contact_pressure"];
    assert_eq!(p["bruised"], true);
    let (code, out, rep) = check(&mcap);
    assert_eq!(code, 0, "{out}");
    assert_eq!(rep["counts"]["bruise"], 0);
    assert_ne!(rep["bruise_missing"], true, "absent when false");
    let expected = rep["bruise_expected"].as_array().unwrap();
    assert!(!expected.is_empty(), "{rep}");
    let top = expected
        .iter()
        .max_by(|a, b| {
            a["ratio"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["ratio"].as_f64().unwrap())
        })
        .unwrap();
    let peak = p["max_pressure_pa"].as_f64().unwrap();
    println!("expected: {top}\nsummary: {p}");
    // Every step recorded: the same number, as f32.
    assert_eq!(top["max_pressure_pa"].as_f64().unwrap(), peak as f32 as f64);
    assert_eq!(top["node"], p["max_pressure_node"]["node"]);
    assert!(
        expected.iter().all(|f| f["rod"].is_u64()),
        "prong contacts: {rep}"
    );
    assert!(
        out.contains("expected  bruised as the scenario expects"),
        "{out}"
    );
    let soft = ["actuator.0.phase.0.end.grip_force=10".to_string()];
    let (summary, mcap) = record(&file, &soft, dir.path(), "soft");
    assert_eq!(summary["contact_pressure"]["bruised"], false);
    let (code, out, rep) = check(&mcap);
    assert_eq!(code, 1, "{out}");
    assert_eq!(rep["bruise_missing"], true);
    assert_eq!(rep["counts"]["bruise"], 1);
    assert!(out.contains("bruise    missing"), "{out}");
}
