//! `gripsim sweep`: the summary table agrees bit for bit with single `gripsim run --summary`
//! calls, shards merge into the unsharded result, a re-run resumes without touching finished
//! cases, and SIGINT stops a sweep without half results.

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant, SystemTime};

const SCENARIO: &str = "scenarios/seed-grasp-r5.toml";
/// Long enough for the prong to touch (first contact at 0.0398 s), short enough to be quick.
const T_END: &str = "solve.t_end=0.045";
const VARY_R: &str = "obstacle.0.radius=0.05,0.048";
const VARY_E: &str = "rod.0.E=1e6,1e9";

fn gripsim(args: &[&str]) -> Output {
    crate::common::gripsim().args(args).output().unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = crate::common::run_ok(crate::common::gripsim().args(args));
    String::from_utf8(out.stdout).unwrap()
}

fn sweep(out: &Path, extra: &[&str]) -> String {
    let o = out.to_str().unwrap();
    let mut args = vec![
        "sweep", SCENARIO, "--vary", VARY_R, "--vary", VARY_E, "--set", T_END, "--out", o,
    ];
    args.extend_from_slice(extra);
    ok(&args)
}

/// summary.csv as (header, rows of cells).
fn table(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r
        .records()
        .map(|x| x.unwrap().iter().map(String::from).collect())
        .collect();
    (header, rows)
}

/// The table without the wall-time column (the only one that differs between two runs).
fn without_wall_time(path: &Path) -> Vec<Vec<String>> {
    let (h, rows) = table(path);
    let w = h
        .iter()
        .position(|c| c == "wall_time_s")
        .expect("wall_time_s column");
    std::iter::once(h)
        .chain(rows)
        .map(|mut r| {
            r.remove(w);
            r
        })
        .collect()
}

fn f(cell: &str) -> f64 {
    cell.parse()
        .unwrap_or_else(|_| panic!("not a number: {cell:?}"))
}

/// The same number, bit for bit (a JSON null is an empty cell).
fn same(cell: &str, v: &Value, what: &str) {
    match v {
        Value::Null => assert_eq!(cell, "", "{what}"),
        Value::Number(n) => {
            let x = n.as_f64().unwrap();
            assert_eq!(
                f(cell).to_bits(),
                x.to_bits(),
                "{what}: csv {cell} vs summary {x}"
            );
        }
        other => panic!("{what}: unexpected {other}"),
    }
}

#[test]
fn summary_rows_match_single_runs_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    // Every case's figures (by default only flagged cases get them).
    let stdout = sweep(&out, &["--jobs", "2", "--case-plots", "all"]);
    assert!(stdout.contains("4 cases: 4 run, 0 skipped"), "{stdout}");
    let (h, rows) = table(&out.join("summary.csv"));
    let col = |name: &str| {
        h.iter()
            .position(|c| c == name)
            .unwrap_or_else(|| panic!("no column {name}: {h:?}"))
    };
    assert_eq!(rows.len(), 4);
    // Grid order: the first --vary varies slowest.
    let params: Vec<(&str, &str)> = rows
        .iter()
        .map(|r| {
            (
                r[col("obstacle.0.radius")].as_str(),
                r[col("rod.0.E")].as_str(),
            )
        })
        .collect();
    assert_eq!(
        params,
        [
            ("0.05", "1e6"),
            ("0.05", "1e9"),
            ("0.048", "1e6"),
            ("0.048", "1e9")
        ]
    );
    let mut contacts = 0;
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[col("case")], k.to_string());
        let json = dir.path().join(format!("run{k}.json"));
        let set_r = format!("obstacle.0.radius={}", r[col("obstacle.0.radius")]);
        let set_e = format!("rod.0.E={}", r[col("rod.0.E")]);
        ok(&[
            "run",
            SCENARIO,
            "--set",
            T_END,
            "--set",
            &set_r,
            "--set",
            &set_e,
            "--summary",
            json.to_str().unwrap(),
            "--no-record",
            "-q",
        ]);
        let s: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let what = |c: &str| format!("case {k} {c}");
        assert_eq!(r[col("completed")], s["completed"].to_string());
        assert_eq!(r[col("steps")], s["steps"].to_string());
        same(
            &r[col("simulated_time_s")],
            &s["simulated_time_s"],
            &what("time"),
        );
        same(
            &r[col("peak_reaction_n")],
            &s["peak_reaction_force_n"],
            &what("peak reaction"),
        );
        same(
            &r[col("peak_reaction_node")],
            &s["peak_reaction_node"]["node"],
            &what("peak reaction node"),
        );
        same(
            &r[col("peak_reaction_time_s")],
            &s["peak_reaction_time_s"],
            &what("peak reaction time"),
        );
        same(
            &r[col("peak_impulse_consistent_force_n")],
            &s["peak_impulse_consistent_force_n"],
            &what("ic force"),
        );
        same(
            &r[col("peak_impulse_consistent_node")],
            &s["peak_impulse_consistent_node"]["node"],
            &what("ic node"),
        );
        same(
            &r[col("contact_onset_s")],
            &s["contact_onset_time_s"],
            &what("onset"),
        );
        // The node that touched first, at the onset time.
        match s["contact_onset_time_s"].as_f64() {
            Some(t0) => {
                let first = s["rods"][0]["first_contact_time_s"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .position(|v| v.as_f64() == Some(t0))
                    .unwrap();
                assert_eq!(
                    r[col("first_contact_node")],
                    first.to_string(),
                    "{}",
                    what("first contact node")
                );
            }
            None => assert_eq!(r[col("first_contact_node")], ""),
        }
        same(
            &r[col("max_bending_stress_pa")],
            &s["max_bending_stress_pa"],
            &what("stress"),
        );
        same(
            &r[col("max_bending_stress_node")],
            &s["max_bending_stress_node"]["node"],
            &what("stress node"),
        );
        same(
            &r[col("max_penetration_m")],
            &s["max_penetration_m"],
            &what("penetration"),
        );
        let rod = &s["rods"][0];
        same(
            &r[col("max_tip_deflection_m:prong")],
            &rod["max_tip_deflection_m"],
            &what("tip deflection"),
        );
        // Total impulse of the prong: the per-node totals summed in node order.
        let total: f64 = rod["total_impulse_per_node_ns"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .sum();
        assert_eq!(
            f(&r[col("total_impulse_ns:prong")]).to_bits(),
            total.to_bits(),
            "{}",
            what("impulse")
        );
        // The node with the most contact steps (ties: the lowest node).
        let steps: Vec<u64> = rod["contact_steps_per_node"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        let most = steps.iter().copied().max().unwrap();
        if most == 0 {
            assert_eq!(r[col("most_contact_steps_node")], "");
        } else {
            contacts += 1;
            let node = steps.iter().position(|c| *c == most).unwrap();
            assert_eq!(r[col("most_contact_steps_node")], node.to_string());
            assert_eq!(r[col("most_contact_steps")], most.to_string());
        }
        // The case's own summary.json is the run's, but for the wall time.
        let id = &r[col("id")];
        let case = out.join("cases").join(id);
        let mut a: Value =
            serde_json::from_slice(&std::fs::read(case.join("summary.json")).unwrap()).unwrap();
        let mut b = s.clone();
        a["wall_time_s"] = Value::Null;
        b["wall_time_s"] = Value::Null;
        assert_eq!(
            a, b,
            "case {k}: summary.json differs from gripsim run --summary"
        );
        let rec: Value =
            serde_json::from_slice(&std::fs::read(case.join("case.json")).unwrap()).unwrap();
        assert_eq!(rec["id"], Value::String(id.clone()));
        for fig in ["forces.png", "forces.svg", "shapes.png", "shapes.svg"] {
            let m = std::fs::metadata(case.join(fig))
                .unwrap_or_else(|_| panic!("case {k}: {fig} missing"));
            assert!(m.len() > 5_000, "case {k}: {fig} is too small");
        }
    }
    assert!(contacts >= 3, "the grid should mostly touch the fruit");
    for fig in [
        "vs-obstacle-0-radius.png",
        "vs-obstacle-0-radius.svg",
        "vs-rod-0-E.png",
        "vs-rod-0-E.svg",
    ] {
        assert!(out.join("plots").join(fig).exists(), "{fig} missing");
    }
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert_eq!(md.lines().count(), 2 + 4, "{md}");
}

#[test]
fn two_shards_merged_equal_the_unsharded_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole");
    sweep(&whole, &["--no-plots"]);

    // One folder per shard (separate machines), merged into a third.
    let (a, b, merged) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("merged"),
    );
    let s0 = sweep(&a, &["--no-plots", "--shard", "0/2"]);
    assert!(
        s0.contains("(shard 0/2: 2 of them): 2 run, 0 skipped"),
        "{s0}"
    );
    sweep(&b, &["--no-plots", "--shard", "1/2"]);
    assert!(
        !a.join("summary.csv").exists(),
        "a shard writes no sweep summary"
    );
    assert_eq!(table(&a.join("summary.shard-0-of-2.csv")).1.len(), 2);
    let m = ok(&[
        "sweep",
        "merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(m.contains("merged 4 cases"), "{m}");
    assert_eq!(
        without_wall_time(&merged.join("summary.csv")),
        without_wall_time(&whole.join("summary.csv"))
    );

    // Shards sharing one folder (a shared file system), merged in place.
    let shared = dir.path().join("shared");
    sweep(&shared, &["--no-plots", "--shard", "1/2"]);
    sweep(&shared, &["--no-plots", "--shard", "0/2"]);
    ok(&["sweep", "merge", shared.to_str().unwrap(), "--no-plots"]);
    assert_eq!(
        without_wall_time(&shared.join("summary.csv")),
        without_wall_time(&whole.join("summary.csv"))
    );

    // A merge with a shard missing says which cases are missing and fails.
    let out = gripsim(&[
        "sweep",
        "merge",
        a.to_str().unwrap(),
        "--out",
        dir.path().join("half").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("2 of 4 cases are not finished"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every file under `dir` with its modification time and content.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (SystemTime, Vec<u8>)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let m = std::fs::metadata(&p).unwrap().modified().unwrap();
                out.insert(p.clone(), (m, std::fs::read(&p).unwrap()));
            }
        }
    }
    out
}

#[test]
fn a_second_sweep_runs_nothing_and_touches_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    sweep(&out, &[]);
    let before = snapshot(&out);
    std::thread::sleep(Duration::from_millis(20));
    let again = sweep(&out, &[]);
    assert!(again.contains("4 cases: 0 run, 4 skipped"), "{again}");
    assert_eq!(
        snapshot(&out),
        before,
        "a resumed sweep with nothing to do changed files"
    );

    // A lost case is recomputed, identically, and only it.
    let (h, rows) = table(&out.join("summary.csv"));
    let id = &rows[1][h.iter().position(|c| c == "id").unwrap()];
    std::fs::remove_dir_all(out.join("cases").join(id)).unwrap();
    let third = sweep(&out, &[]);
    assert!(third.contains("4 cases: 1 run, 3 skipped"), "{third}");
    assert_eq!(without_wall_time(&out.join("summary.csv")), {
        let mut t = vec![h.clone()];
        t.extend(rows.clone());
        let w = h.iter().position(|c| c == "wall_time_s").unwrap();
        t.into_iter()
            .map(|mut r| {
                r.remove(w);
                r
            })
            .collect::<Vec<_>>()
    });

    // Another base scenario in the same folder is refused, not mixed in.
    let o = out.to_str().unwrap();
    let bad = gripsim(&[
        "sweep",
        SCENARIO,
        "--vary",
        VARY_R,
        "--vary",
        VARY_E,
        "--set",
        "solve.t_end=0.04",
        "--out",
        o,
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("different scenario"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}

#[cfg(unix)]
#[test]
fn sigint_leaves_only_finished_cases_and_a_rerun_completes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    // Six cases of 60 000 steps each, one at a time.
    let args = [
        "sweep",
        SCENARIO,
        "--vary",
        "obstacle.0.radius=0.05,0.049,0.048",
        "--vary",
        VARY_E,
        "--set",
        "solve.dt=1e-6",
        "--set",
        "solve.t_end=0.06",
        "--jobs",
        "1",
        "--no-plots",
        "--out",
        out.to_str().unwrap(),
    ];
    let child = Command::new(env!("CARGO_BIN_EXE_gripsim"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let cases = out.join("cases");
    let finished = |d: &Path| -> Vec<PathBuf> {
        std::fs::read_dir(d)
            .map(|rd| {
                rd.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| !p.file_name().unwrap().to_string_lossy().starts_with('.'))
                    .collect()
            })
            .unwrap_or_default()
    };
    let start = Instant::now();
    while finished(&cases).is_empty() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let result = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted by SIGINT"), "{stderr}");
    let done = finished(&cases);
    assert!(
        !done.is_empty() && done.len() < 6,
        "{} cases finished",
        done.len()
    );
    for d in &done {
        assert!(
            d.join("case.json").exists() && d.join("summary.json").exists(),
            "{} is incomplete",
            d.display()
        );
    }
    let leftovers: Vec<_> = std::fs::read_dir(&cases)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "half results left: {leftovers:?}");
    assert!(
        !out.join("summary.csv").exists(),
        "no summary of an unfinished sweep"
    );

    let again = ok(&args);
    assert!(
        again.contains(&format!(
            "6 cases: {} run, {} skipped",
            6 - done.len(),
            done.len()
        )),
        "{again}"
    );
    assert_eq!(table(&out.join("summary.csv")).1.len(), 6);
}

#[test]
fn bad_arguments_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("x");
    let o = o.to_str().unwrap();
    for (args, says) in [
        (
            vec!["sweep", SCENARIO, "--vary", "rod.0.E", "--out", o],
            "expected KEY=V1,V2",
        ),
        (
            vec![
                "sweep", SCENARIO, "--vary", VARY_E, "--shard", "2/2", "--out", o,
            ],
            "0 <= I < N",
        ),
        (
            vec!["sweep", SCENARIO, "--vary", "rod.0.youngs=1,2", "--out", o],
            "rod.0.youngs",
        ),
        (
            vec![
                "sweep",
                SCENARIO,
                "--vary",
                VARY_E,
                "--vary",
                "rod.0.E=3e6",
                "--out",
                o,
            ],
            "given twice",
        ),
        (vec!["sweep", "merge", o], "sweep.json"),
    ] {
        let out = gripsim(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

/// A sweep that draws no figures keeps no time series (its trace only counts warnings and
/// releases, and idle nodes skip the summary's windows): every column but the wall time is
/// the same as with the figures.
#[test]
fn no_plots_gives_the_same_table_as_with_plots() {
    let dir = tempfile::tempdir().unwrap();
    let (with, without) = (dir.path().join("with"), dir.path().join("without"));
    sweep(&with, &[]);
    sweep(&without, &["--no-plots"]);
    assert!(with.join("plots").exists() && !without.join("plots").exists());
    let (a, b) = (
        without_wall_time(&with.join("summary.csv")),
        without_wall_time(&without.join("summary.csv")),
    );
    assert_eq!(a.len(), 5);
    assert_eq!(a, b);
}
