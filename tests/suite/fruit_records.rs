//! Recordings and replay of a compliant free fruit (issue 32): `replay check`'s bruise rule on
//! the fruit's prong contacts and on its own contact with the table, the MCAP and CSV carrying
//! those contacts' pressure and indentation, and the sweep's bruise columns.

use crate::common::{gripsim, message_json, scenario, text};
use gripsim::events::{ContactView, Event, Observer};
use gripsim::{Scenario, Simulation};
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

/// Every step's contact views of a run, by step.
#[derive(Default)]
struct Contacts(std::collections::BTreeMap<u64, Vec<ContactView>>);

impl Observer for Contacts {
    fn on_event(&mut self, e: &Event<'_>) {
        if let Event::StepEnd { step, contacts, .. } = e {
            self.0.insert(*step, contacts.to_vec());
        }
    }
}

fn index(k: usize) -> Value {
    if k == usize::MAX {
        Value::Null
    } else {
        k.into()
    }
}

/// The most pressed compliant contact of rod `r` covering node `i` (its node, or a node of
/// its arc): what the node's CSV row carries.
fn covering(cs: &[ContactView], r: usize, i: usize) -> Option<&ContactView> {
    cs.iter()
        .filter(|c| c.rod == r && c.peak_pressure > 0.0)
        .filter(|c| {
            if c.first == usize::MAX {
                c.node == i
            } else {
                (c.first..=c.last).contains(&i)
            }
        })
        .max_by(|a, b| a.peak_pressure.total_cmp(&b.peak_pressure))
}

/// The first 0.35 s of apple-squeeze-bruise (the close, the squeeze to 50 N, the start of the
/// lift: the apple leaves the table at 0.314 s), recorded at every step in f64: every step's
/// contacts in `/sim/step` are the run's contact views number for number — the prongs' arcs
/// on the free apple (body 0, their first and last node) and the apple's own contact with the
/// table (no rod, node = the body) with their pressure and indentation — and the Python
/// protobuf reader agrees; the CSV carries an arc's numbers on each of its nodes and the
/// table contact on a row of its own (`rod` empty, `obstacle` "table").
#[test]
fn the_free_fruits_contacts_reach_the_mcap_and_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let file = scenario("apple-squeeze-bruise");
    let sets = vec!["solve.t_end=0.35".to_string()];
    let sc = Scenario::load(&file, &sets).unwrap();
    let mut run = Contacts::default();
    Simulation::new(&sc).run(&mut run).unwrap();
    let (mcap, csv) = (dir.path().join("a.mcap"), dir.path().join("a.csv"));
    let out = gripsim()
        .arg("run")
        .arg(&file)
        .args([
            "-q",
            "--detail",
            "step",
            "--precision",
            "f64",
            "--set",
            &sets[0],
        ])
        .arg("--mcap")
        .arg(&mcap)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    // The MCAP, as gripsim's decoder reads it.
    let bytes = std::fs::read(&mcap).unwrap();
    let mut steps = std::collections::BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == "/sim/step" {
            let j = message_json(&m);
            steps.insert(j["step"].as_u64().unwrap(), j);
        }
    }
    assert_eq!(steps.len(), run.0.len());
    let (mut table, mut arcs, mut spread) = (0, 0, 0);
    for (step, cs) in &run.0 {
        let rec = steps[step]["contacts"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        assert_eq!(rec.len(), cs.len(), "contacts at step {step}");
        for (c, j) in cs.iter().zip(&rec) {
            let ctx = format!("step {step}: {j}");
            assert_eq!(j["rod"], index(c.rod), "{ctx}");
            assert_eq!(j["body"], index(c.body), "{ctx}");
            assert_eq!(j["first"], index(c.first), "{ctx}");
            assert_eq!(j["last"], index(c.last), "{ctx}");
            assert_eq!(
                (j["node"].as_u64(), j["obstacle"].as_u64()),
                (Some(c.node as u64), Some(c.obstacle as u64)),
                "{ctx}"
            );
            let f = |k: &str| j[k].as_f64().unwrap();
            let xy = |k: &str| [j[k][0].as_f64().unwrap(), j[k][1].as_f64().unwrap()];
            assert_eq!(
                (xy("point"), xy("normal")),
                (gripsim::events::xy(c.point), gripsim::events::xy(c.normal)),
                "{ctx}"
            );
            assert_eq!(
                (f("normal_force"), f("friction_force")),
                (c.normal_force, c.friction_force),
                "{ctx}"
            );
            assert_eq!(
                [
                    f("indentation"),
                    f("half_width"),
                    f("peak_pressure"),
                    f("bruise_pressure"),
                    f("bruise_half_width")
                ],
                [
                    c.indentation,
                    c.half_width,
                    c.peak_pressure,
                    c.bruise_pressure,
                    c.bruise_half_width
                ],
                "{ctx}"
            );
            if c.rod == usize::MAX && c.peak_pressure > 0.0 {
                // The apple (body 0) on the table (obstacle 0).
                assert_eq!((c.node, c.obstacle), (0, 0), "{ctx}");
                table += 1;
            }
            if c.rod != usize::MAX && c.peak_pressure > 0.0 {
                assert_eq!((c.body, c.obstacle), (0, 1), "the free apple: {ctx}");
                assert!(
                    c.first < c.last && (c.first..=c.last).contains(&c.node),
                    "{ctx}"
                );
                arcs += 1;
            }
        }
    }
    println!("{table} table contacts, {arcs} arcs recorded");
    assert!(
        table > 1000 && arcs > 1000,
        "{table} table contacts, {arcs} arcs"
    );
    // The Python protobuf library reads the same contacts (−1 for no index).
    let py = crate::recordings::read_mcap_py(&mcap);
    assert_eq!(py["error"], Value::Null, "{py}");
    for s in py["step_samples"].as_array().unwrap() {
        let cs = &run.0[&s["step"].as_u64().unwrap()];
        let theirs = s["contacts"].as_array().unwrap();
        assert_eq!(theirs.len(), cs.len());
        for (c, j) in cs.iter().zip(theirs) {
            let i = |k: usize| if k == usize::MAX { -1 } else { k as i64 };
            assert_eq!(
                [
                    &j["rod"],
                    &j["node"],
                    &j["obstacle"],
                    &j["body"],
                    &j["first"],
                    &j["last"]
                ]
                .map(|v| v.as_i64().unwrap()),
                [
                    i(c.rod),
                    i(c.node),
                    i(c.obstacle),
                    i(c.body),
                    i(c.first),
                    i(c.last)
                ],
                "{j}"
            );
            assert_eq!(j["peak_pressure"].as_f64().unwrap(), c.peak_pressure);
            assert_eq!(j["indentation"].as_f64().unwrap(), c.indentation);
        }
    }
    // The CSV: exact doubles.
    let mut rdr = csv::Reader::from_path(&csv).unwrap();
    let h: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    let col = |k: &str| h.iter().position(|x| x == k).unwrap();
    let mut table_rows = 0;
    for row in rdr.records() {
        let row = row.unwrap();
        let num = |k: &str| -> f64 { row[col(k)].parse().unwrap() };
        let step: u64 = row[col("step")].parse().unwrap();
        let node: usize = row[col("node")].parse().unwrap();
        let cs = &run.0[&step];
        let pressure = |c: Option<&ContactView>| {
            c.map_or([0.0; 4], |c| {
                [
                    c.indentation,
                    c.half_width,
                    c.peak_pressure,
                    c.bruise_half_width,
                ]
            })
        };
        let got = [
            num("indentation"),
            num("half_width"),
            num("peak_pressure"),
            num("bruise_half_width"),
        ];
        if row[col("rod")].is_empty() {
            let c = cs
                .iter()
                .find(|c| c.rod == usize::MAX && c.node == node)
                .expect("the body's contact");
            assert_eq!(got, pressure(Some(c)), "step {step}");
            assert_eq!(
                [num("x"), num("y"), num("nx"), num("ny")],
                [c.point[0], c.point[1], c.normal[0], c.normal[1]]
            );
            assert_eq!(num("reaction"), c.normal_force.hypot(c.friction_force));
            assert_eq!(&row[col("obstacle")], "table");
            table_rows += 1;
            continue;
        }
        let r = usize::from(&row[col("rod")] == "left");
        let c = covering(cs, r, node);
        assert_eq!(got, pressure(c), "step {step} rod {r} node {node}");
        if let Some(c) = c {
            assert_eq!(&row[col("obstacle")], "apple");
            spread += usize::from(c.node != node);
        }
    }
    let own = run
        .0
        .values()
        .flatten()
        .filter(|c| c.rod == usize::MAX)
        .count();
    println!("{table_rows} table rows, {spread} arc rows off the force's node");
    assert_eq!(table_rows, own, "a row per table contact");
    assert!(spread > 1000, "{spread}");
}

/// A sweep's summary.csv as rows of (column, value).
fn sweep(
    scenario: &Path,
    args: &[&str],
    out: &Path,
) -> Vec<std::collections::HashMap<String, String>> {
    let o = gripsim()
        .arg("sweep")
        .arg(scenario)
        .args(args)
        .args(["--no-plots", "-q", "-j", "2", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let mut rdr = csv::Reader::from_path(out.join("summary.csv")).unwrap();
    let h: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    rdr.records()
        .map(|r| {
            h.iter()
                .cloned()
                .zip(r.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

/// The sweep's bruise columns for a free compliant fruit: apple-pick-and-place squeezed to
/// 10 N and 50 N (0.61x and 1.13x the apple's 0.1 MPa at the prongs: not bruised, bruised, and
/// the 50 N case's two stretches flagged since this scenario does not expect them), and the
/// drop of the compliant disc from 1 cm and 10 cm (the table's pressure: 0.88x, 1.65x).
#[test]
fn sweeps_fill_the_bruise_columns_for_a_free_fruit_at_the_prongs_and_on_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let rows = sweep(
        &scenario("apple-pick-and-place"),
        &["--vary", "actuator.0.phase.0.end.grip_force=10,50"],
        &dir.path().join("grip"),
    );
    let col = |r: &std::collections::HashMap<String, String>, k: &str| r[k].clone();
    let num =
        |r: &std::collections::HashMap<String, String>, k: &str| -> f64 { r[k].parse().unwrap() };
    assert_eq!(rows.len(), 2);
    for r in &rows {
        println!(
            "grip {}: bruised {}, ratio {}, max {} Pa, width {} m, flagged {}",
            col(r, "actuator.0.phase.0.end.grip_force"),
            col(r, "bruised"),
            col(r, "bruise_ratio"),
            col(r, "max_pressure_pa"),
            col(r, "max_bruise_width_m"),
            col(r, "bruise")
        );
    }
    let (soft, hard) = (&rows[0], &rows[1]);
    assert_eq!(col(soft, "actuator.0.phase.0.end.grip_force"), "10");
    assert_eq!(
        (col(soft, "bruised").as_str(), col(soft, "bruise").as_str()),
        ("false", "0")
    );
    assert_eq!(
        (col(hard, "bruised").as_str(), col(hard, "bruise").as_str()),
        ("true", "2")
    );
    assert!((num(soft, "bruise_ratio") - 0.6051).abs() < 1e-3);
    assert!((num(hard, "bruise_ratio") - 1.1322).abs() < 1e-3);
    assert_eq!(num(soft, "max_bruise_width_m"), 0.0);
    assert!(num(hard, "max_bruise_width_m") > 4e-3);
    assert!(num(hard, "max_indentation_m") > num(soft, "max_indentation_m"));
    // The table's contact: the drop.
    let file = dir.path().join("drop.toml");
    std::fs::write(&file, DROP).unwrap();
    let rows = sweep(
        &file,
        &[
            "--set",
            "solve.t_end=0.16",
            "--vary",
            "obstacle.1.center=[0.0,0.05],[0.0,0.14]",
        ],
        &dir.path().join("drop"),
    );
    assert_eq!(rows.len(), 2);
    for r in &rows {
        println!(
            "drop: bruised {}, ratio {}, flagged {}",
            col(r, "bruised"),
            col(r, "bruise_ratio"),
            col(r, "bruise")
        );
    }
    assert_eq!(
        (
            col(&rows[0], "bruised").as_str(),
            col(&rows[0], "bruise").as_str()
        ),
        ("false", "0")
    );
    assert_eq!(
        (
            col(&rows[1], "bruised").as_str(),
            col(&rows[1], "bruise").as_str()
        ),
        ("true", "1")
    );
    assert!((num(&rows[0], "bruise_ratio") - 0.882).abs() < 2e-3);
    assert!((num(&rows[1], "bruise_ratio") - 1.6466).abs() < 1e-3);
}
