//! The study layer on 3D scenarios: `gripsim sweep` over a 3D lift gives the grasp verdict per
//! row (with margins, and empty cells for what a 3D run does not measure), each row's summary
//! is the one `gripsim run --summary` writes, shards merge and a re-run resumes; the replay
//! check's bruise count is real on a compliant 3D fruit; `gripsim window` finds the grasp
//! window of the 3D apple; a bad value of a 3D sweep names the case, key and value.

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;

const LIFT: &str = "scenarios/3d-lift.toml";
const APPLE: &str = "scenarios/3d-apple.toml";

fn gripsim(args: &[&str]) -> Output {
    crate::common::gripsim().args(args).output().unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = crate::common::run_ok(crate::common::gripsim().args(args));
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// summary.csv as one map per row, column name → cell.
fn rows(path: &Path) -> Vec<BTreeMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|x| {
            h.iter()
                .cloned()
                .zip(x.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

fn num(row: &BTreeMap<String, String>, k: &str) -> f64 {
    row[k]
        .parse()
        .unwrap_or_else(|_| panic!("{k} = {:?} is not a number", row[k]))
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The issue's command: three values of μ_s on the 3D lift (μ_k = μ_s). A squeeze of 1 N per
/// prong lifts the 0.51 N sphere only where μ_s · 2 · 0.98 N > 0.51 N with margin: at 0.2 and
/// 0.3 the prongs slide up the sphere, which stays on the table (slipped), at 0.6 it is held.
/// Each row's summary.json is what `gripsim run --summary` writes for its case; a re-run skips
/// the finished cases.
#[test]
fn the_issues_3d_lift_sweep_gives_a_verdict_per_row() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s");
    let o = out.to_str().unwrap();
    let args = [
        "sweep",
        LIFT,
        "--vary",
        "friction.mu_s=0.2,0.3,0.6",
        "--out",
        o,
        "--no-plots",
        "-j",
        "2",
    ];
    ok(&args);
    let r = rows(&out.join("summary.csv"));
    assert_eq!(r.len(), 3);
    let verdicts: Vec<&str> = r.iter().map(|x| x["verdict"].as_str()).collect();
    println!("verdicts {verdicts:?}");
    for x in &r[..2] {
        assert!(
            ["slipped", "dropped"].contains(&x["verdict"].as_str()),
            "{x:?}"
        );
        assert_eq!(x["held"], "false");
        // μ ΣN < m g during the lift.
        assert!(num(x, "min_safety_margin") < 1.0, "{x:?}");
        assert!(num(x, "max_slip_m") > 0.02, "{x:?}");
    }
    assert_eq!(r[2]["verdict"], "held");
    assert_eq!(r[2]["held"], "true");
    assert!(num(&r[2], "min_safety_margin") > 1.5, "{:?}", r[2]);
    assert!(num(&r[2], "max_slip_m") < 0.005, "{:?}", r[2]);
    for x in &r {
        println!(
            "mu_s {}: {} margin {} slip {} peak grip {} N",
            x["friction.mu_s"],
            x["verdict"],
            x["min_safety_margin"],
            x["max_slip_m"],
            x["peak_grip_force_n"]
        );
        assert_eq!(x["completed"], "true");
        assert!(num(x, "peak_grip_force_n") > 0.9, "{x:?}");
        assert!(num(x, "peak_reaction_n") > 0.0);
        assert!(num(x, "contact_onset_s") > 1.0);
        assert!(num(x, "max_tip_deflection_m:finger0") > 0.0);
        // Not measured in 3D: empty, not 0. A rigid sphere has no pressure columns.
        for k in [
            "peak_impulse_consistent_force_n",
            "max_bending_stress_pa",
            "first_slip_s",
            "max_pressure_pa",
            "bruised",
        ] {
            assert_eq!(x[k], "", "{k}: {x:?}");
        }
        // The replay check's counts, found while the case ran.
        assert_eq!(x["spikes"], "0", "{x:?}");
        assert_eq!(x["bruise"], "0", "{x:?}");
    }
    // The held case's summary is `gripsim run --summary`'s, number for number.
    let id = &r[2]["id"];
    let by_hand = d.path().join("hand.json");
    ok(&[
        "run",
        LIFT,
        "--set",
        "friction.mu_s=0.6",
        "--no-record",
        "-q",
        "--summary",
        by_hand.to_str().unwrap(),
    ]);
    let mut a = json(&out.join("cases").join(id).join("summary.json"));
    let mut b = json(&by_hand);
    for v in [&mut a, &mut b] {
        v.as_object_mut().unwrap().remove("wall_time_s");
    }
    assert_eq!(a, b);
    let case = json(&out.join("cases").join(id).join("case.json"));
    assert!(
        case["command"]
            .as_str()
            .unwrap()
            .contains("--set friction.mu_s=0.6"),
        "{case}"
    );
    // Resume: nothing to run again; one folder gone runs that case alone, to the same row.
    let again = ok(&args);
    assert!(again.contains("0 run, 3 skipped"), "{again}");
    std::fs::remove_dir_all(out.join("cases").join(&r[1]["id"])).unwrap();
    let again = ok(&args);
    assert!(again.contains("1 run, 2 skipped"), "{again}");
    let r2 = rows(&out.join("summary.csv"));
    for (x, y) in r.iter().zip(&r2) {
        let strip = |m: &BTreeMap<String, String>| {
            let mut m = m.clone();
            m.remove("wall_time_s");
            m
        };
        assert_eq!(strip(x), strip(y));
    }
}

/// A compliant 3D apple: the pressure columns are filled, and the bruise count is the replay
/// check's, found while the case ran (0 at 2 N, at least one stretch at 5 N: 1.14 × the bruise
/// pressure). Two shards merge into the table of the unsharded sweep.
#[test]
fn a_3d_apple_sweep_counts_bruises_and_its_shards_merge() {
    let d = tempfile::tempdir().unwrap();
    let dir = |n: &str| d.path().join(n).to_str().unwrap().to_string();
    let (all, s1, s2) = (dir("all"), dir("s1"), dir("s2"));
    let base = |out: &str| -> Vec<String> {
        [
            "sweep",
            APPLE,
            "--vary",
            "move.0.force=2,5",
            "--out",
            out,
            "-j",
            "2",
        ]
        .map(String::from)
        .to_vec()
    };
    let run = |extra: &[&str], out: &str| {
        let mut a = base(out);
        a.extend(extra.iter().map(|s| s.to_string()));
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        ok(&a)
    };
    // The unsharded sweep draws every case's figures: the per-node forces, and the shapes
    // projected onto the closing plane.
    run(&["--case-plots", "all"], &all);
    let cases = Path::new(&all).join("cases");
    for e in std::fs::read_dir(&cases).unwrap() {
        let p = e.unwrap().path();
        for f in ["forces.png", "shapes.svg"] {
            let len = std::fs::metadata(p.join(f)).map(|m| m.len()).unwrap_or(0);
            assert!(len > 1000, "{}: {len} bytes", p.join(f).display());
        }
        let case = json(&p.join("case.json"));
        assert!(case["plot_error"].is_null(), "{case}");
    }
    let r = rows(&Path::new(&all).join("summary.csv"));
    println!("{r:?}");
    assert_eq!(r[0]["bruised"], "false");
    assert_eq!(r[0]["bruise"], "0");
    assert_eq!(r[0]["verdict"], "held");
    assert_eq!(r[1]["bruised"], "true");
    assert!(num(&r[1], "bruise") >= 1.0, "{:?}", r[1]);
    assert!(num(&r[1], "bruise_ratio") > 1.1, "{:?}", r[1]);
    assert!(num(&r[1], "max_bruise_width_m") > 0.0);
    assert!(num(&r[0], "max_pressure_pa") > 8e4);
    assert!(num(&r[0], "max_indentation_m") > 2e-4);
    run(&["--shard", "0/2", "--no-plots"], &s1);
    run(&["--shard", "1/2", "--no-plots"], &s2);
    let merged = dir("merged");
    ok(&["sweep", "merge", &s1, &s2, "--out", &merged]);
    let strip = |rows: Vec<BTreeMap<String, String>>| {
        rows.into_iter()
            .map(|mut m| {
                m.remove("wall_time_s");
                m
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(
        strip(rows(&Path::new(&merged).join("summary.csv"))),
        strip(r)
    );
}

/// `gripsim window` on the 3D apple: its knob is the squeeze's force (`move.0.force`); the
/// drop boundary lies between 1 and 1.4 N (held above, slipped below) and the prongs bruise
/// it above 3.4 N (the full search at rtol 1 %: g_hold 1.157 N, g_bruise 3.436 N, in
/// docs/studies.md); here to 5 %.
#[test]
fn the_grasp_window_of_the_3d_apple() {
    let d = tempfile::tempdir().unwrap();
    let j = d.path().join("w.json");
    let text = ok(&[
        "window",
        APPLE,
        "--rtol",
        "0.05",
        "--json",
        j.to_str().unwrap(),
        "-j",
        "2",
    ]);
    println!("{text}");
    let w = json(&j);
    assert_eq!(w["knob"]["knob"], "move.0.force");
    assert_eq!(w["knob"]["unit"], "N");
    let hold = &w["hold"];
    assert_eq!(hold["status"], "found", "{hold}");
    let (g, other) = (
        hold["value"].as_f64().unwrap(),
        hold["other"].as_f64().unwrap(),
    );
    assert!(g > other && g / other <= 1.05 + 1e-9, "{g} {other}");
    assert!((1.0..1.4).contains(&g), "g_hold {g}");
    assert_eq!(hold["at"]["held"], true);
    let bruise = &w["bruise"];
    assert_eq!(bruise["status"], "found", "{bruise}");
    let gb = bruise["value"].as_f64().unwrap();
    assert!((3.2..3.7).contains(&gb), "g_bruise {gb}");
    assert!(w["window_ratio"].as_f64().unwrap() > 2.0);
}

/// A bad value among good ones in a 3D sweep: refused before anything runs, naming the
/// case, the key and the value, exit 2.
#[test]
fn a_bad_value_of_a_3d_sweep_names_its_case() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s");
    let o = gripsim(&[
        "sweep",
        LIFT,
        "--vary",
        "friction.mu_s=0.6,-0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for w in ["case 1", "friction.mu_s=-0.5", "3d-lift.toml"] {
        assert!(err.contains(w), "{w:?} in {err}");
    }
    assert!(!out.join("cases").exists(), "nothing written");
}
