//! `gripsim window`: the drop boundary of the jaw grasp (checked against single runs and
//! against μ_s ΣN = m (g + a)), the bruise boundary of a fixed compliant fruit, bad input,
//! a range with no boundary, the map over design parameters (one row per design, resumed,
//! sharded and merged), and what a sweep writes by default (figures only for flagged cases, a
//! heat map for two keys).

use serde_json::Value;
use std::path::Path;
use std::process::Output;

const JAW: &str = "scenarios/jaw-grasp-hold.toml";
const BRUISE: &str = "tests/data/window-bruise.toml";
const GRIP: &str = "actuator.0.phase.0.end.grip_force";
const APPLE: &str = "scenarios/apple-pick-and-place.toml";

fn gripsim(args: &[&str]) -> Output {
    crate::common::gripsim().args(args).output().unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = crate::common::run_ok(crate::common::gripsim().args(args));
    String::from_utf8(out.stdout).unwrap()
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// One run of `scenario` with the knob at `value`: its summary.
fn run_at(dir: &Path, scenario: &str, value: f64, name: &str) -> Value {
    let path = dir.join(format!("{name}.json"));
    let set = format!("{GRIP}={value:?}");
    ok(&[
        "run",
        scenario,
        "--set",
        &set,
        "--summary",
        path.to_str().unwrap(),
        "--no-record",
        "-q",
    ]);
    json(&path)
}

#[test]
fn the_jaw_grasp_drop_boundary_is_found_in_few_runs_and_holds_up() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("window.json");
    let stdout = ok(&[
        "window",
        JAW,
        "--json",
        out.to_str().unwrap(),
        "--jobs",
        "2",
        "-q",
    ]);
    assert!(stdout.contains("drop boundary  : g_hold = "), "{stdout}");
    assert!(
        stdout.contains("no compliant material in the scenario: no bruise boundary"),
        "{stdout}"
    );
    let w = json(&out);
    // The knob is the squeeze's grip target, 1.8 N in the scenario; the range 1.8/8 to 1.8*8.
    assert_eq!(w["knob"]["knob"], GRIP);
    assert_eq!(num(&w["knob"]["scenario_value"]), 1.8);
    assert_eq!(
        (num(&w["knob"]["lo"]), num(&w["knob"]["hi"])),
        (0.225, 14.4)
    );
    let hold = &w["hold"];
    assert_eq!(hold["status"], "found");
    assert_eq!(w["bruise"]["status"], "not_applicable");
    let (g, other) = (num(&hold["value"]), num(&hold["other"]));
    assert!(other < g && g / other <= 1.01 + 1e-12, "{g} {other}");
    let runs = w["runs"].as_array().unwrap().len();
    assert!(runs <= 14, "{runs} runs");
    // Every value is run once.
    let mut values: Vec<f64> = w["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| num(&r["value"]))
        .collect();
    values.sort_by(f64::total_cmp);
    values.dedup();
    assert_eq!(values.len(), runs);

    // Physics: friction holds the fruit through the lift iff μ_s ΣN ≥ m (g + a), i.e. a
    // safety margin μ_s ΣN / (m g) of 1 + a/g; the S-curve lift (4 cm in 0.6 s) peaks at
    // a = 10√3/3 · D/T² = 0.6415 m/s², so 1.0654. The boundary's runs straddle it.
    let needed = num(&w["margin_needed"]);
    assert!((needed - (1.0 + 0.6415 / 9.81)).abs() < 1e-4, "{needed}");
    let m_hold = num(&hold["at"]["safety_margin_at_lift"]);
    assert!(
        m_hold >= needed * 0.995 && m_hold <= needed * 1.02,
        "margin {m_hold} at g_hold against {needed}"
    );
    let below = w["runs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| num(&r["value"]) == other)
        .unwrap();
    assert!(num(&below["safety_margin_at_lift"]) < needed * 1.005);

    // Single runs 2 % either side flip as the search says.
    let up = run_at(dir.path(), JAW, g * 1.02, "up");
    let down = run_at(dir.path(), JAW, g * 0.98, "down");
    assert_eq!(up["grasp"]["held"], true, "{}", up["grasp"]);
    assert_eq!(down["grasp"]["held"], false, "{}", down["grasp"]);
    // The search's own run at g_hold is a normal run: the same margin as `gripsim run`.
    let at = run_at(dir.path(), JAW, g, "at");
    assert_eq!(
        num(&at["grasp"]["safety_margin_at_lift"]).to_bits(),
        m_hold.to_bits()
    );
}

#[test]
fn the_shipped_apple_has_a_grip_window_whose_boundaries_hold_up() {
    // The compliant free apple between curved prongs (the face, at segments, the conforming
    // law, friction per arc): the least grip that lifts it and the least that bruises it.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("window.json");
    let stdout = ok(&["window", APPLE, "--json", out.to_str().unwrap(), "-q"]);
    println!("{stdout}");
    let w = json(&out);
    let (hold, bruise) = (&w["hold"], &w["bruise"]);
    assert_eq!(hold["status"], "found");
    assert_eq!(bruise["status"], "found");
    let (gh, gb) = (num(&hold["value"]), num(&bruise["value"]));
    let runs = w["runs"].as_array().unwrap().len();
    println!(
        "g_hold {gh} N, g_bruise {gb} N, ratio {}, {runs} runs",
        gb / gh
    );
    assert!(runs <= 14, "{runs} runs");
    assert!(gb / gh > 1.0, "a safe window: {gh} .. {gb}");
    assert!((num(&w["window_ratio"]) - gb / gh).abs() < 1e-12);
    // The margin at the hold boundary sits at the Coulomb limit of the lift, μ_s ΣN = m (g + a)
    // with the gripper's peak acceleration (measured: +2.2 %; the curved prongs' own dynamics
    // during the lift, which the margin at its start does not see).
    let needed = num(&w["margin_needed"]);
    let m = num(&hold["at"]["safety_margin_at_lift"]);
    assert!(
        (m / needed - 1.0).abs() < 0.03,
        "margin {m} at g_hold against {needed}"
    );
    // Single runs 2 % either side of each boundary flip as the search says.
    let up = run_at(dir.path(), APPLE, gh * 1.02, "hold-up");
    let down = run_at(dir.path(), APPLE, gh * 0.98, "hold-down");
    assert_eq!(up["grasp"]["held"], true, "{}", up["grasp"]);
    assert_eq!(down["grasp"]["held"], false, "{}", down["grasp"]);
    let up = run_at(dir.path(), APPLE, gb * 1.02, "bruise-up");
    let down = run_at(dir.path(), APPLE, gb * 0.98, "bruise-down");
    assert_eq!(up["contact_pressure"]["bruised"], true);
    assert_eq!(down["contact_pressure"]["bruised"], false);
    assert_eq!(up["grasp"]["held"], true);
}

#[test]
fn a_fixed_compliant_fruit_has_a_bruise_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("window.json");
    let stdout = ok(&["window", BRUISE, "--json", out.to_str().unwrap(), "-q"]);
    assert!(
        stdout.contains("no free body in the scenario: no grasp verdict, no drop boundary"),
        "{stdout}"
    );
    let w = json(&out);
    assert_eq!(w["hold"]["status"], "not_applicable");
    let b = &w["bruise"];
    assert_eq!(b["status"], "found");
    let (g, other) = (num(&b["value"]), num(&b["other"]));
    assert!(other < g && g / other <= 1.01 + 1e-12, "{g} {other}");
    assert!(w["runs"].as_array().unwrap().len() <= 14);
    // At the boundary the peak pressure is just above the fruit's 30 kPa.
    let ratio = num(&b["at"]["bruise_ratio"]);
    assert!(ratio > 1.0 && ratio < 1.02, "{ratio}");
    assert_eq!(num(&b["at"]["bruise_pressure_pa"]), 3e4);
    let up = run_at(dir.path(), BRUISE, g * 1.02, "up");
    let down = run_at(dir.path(), BRUISE, g * 0.98, "down");
    assert_eq!(up["contact_pressure"]["bruised"], true);
    assert_eq!(down["contact_pressure"]["bruised"], false);
}

#[test]
fn bad_window_input_is_a_located_error() {
    for (args, says) in [
        (
            vec!["window", JAW, "--knob", "name"],
            "--knob name = \"jaw-grasp-hold\": not a number",
        ),
        (
            vec!["window", JAW, "--knob", "rod.0.nodez"],
            "--knob rod.0.nodez: not in the scenario",
        ),
        (
            vec!["window", JAW, "--range", "5:1"],
            "LO = 5 is not below HI = 1",
        ),
        (vec!["window", JAW, "--range", "0:2"], "LO must be > 0"),
        (
            vec!["window", JAW, "--rtol", "0"],
            "--rtol \"0\": 0 is not in (0, 1)",
        ),
        (vec!["window", JAW, "--rtol=-0.1"], "is not in (0, 1)"),
        (
            vec!["window", JAW, "--rtol", "abc"],
            "--rtol \"abc\": not a number",
        ),
        (
            vec!["window", "scenarios/two-prong-grasp.toml"],
            "no grip target to vary: name the knob with --knob KEY",
        ),
        (
            vec!["window", JAW, "--out", "/tmp/x"],
            "--out and --shard go with --vary",
        ),
        (
            vec!["window", JAW, "--vary", "obstacle.1.mass=0.1,0.2"],
            "window --vary needs --out DIR",
        ),
        (
            vec![
                "window",
                JAW,
                "--vary",
                "rod.0.E=5e7,6e7",
                "--vary",
                "obstacle.1.mass=1,2",
            ],
            "needs --out",
        ),
    ] {
        let out = gripsim(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // The knob varied as a design parameter too.
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("m");
    let out = gripsim(&[
        "window",
        JAW,
        "--vary",
        &format!("{GRIP}=1,2"),
        "--out",
        o.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("that is the window's knob"));
    // Nothing half written.
    assert!(!o.join("window.csv").exists());
}

#[test]
fn a_range_without_a_boundary_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("w.json");
    let stdout = ok(&[
        "window",
        JAW,
        "--range",
        "3:14",
        "--json",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert!(
        stdout.contains("held at both ends of 3–14 N: g_hold < 3 N"),
        "{stdout}"
    );
    let w = json(&out);
    assert_eq!(w["hold"]["status"], "everywhere");
    assert!(w["hold"]["value"].is_null());
    // Only the coarse grid ran: 3 points over a factor 4.7.
    assert_eq!(w["runs"].as_array().unwrap().len(), 3);
    let stdout = ok(&["window", JAW, "--range", "0.1:0.5", "-q"]);
    assert!(
        stdout.contains("dropped at both ends of 0.1–0.5 N"),
        "{stdout}"
    );
    let stdout = ok(&["window", BRUISE, "--range", "0.1:0.5", "-q"]);
    assert!(stdout.contains("no bruise up to 0.5 N"), "{stdout}");
}

fn rows(path: &Path) -> Vec<csv::StringRecord> {
    csv::Reader::from_path(path)
        .unwrap()
        .records()
        .map(|r| r.unwrap())
        .collect()
}

#[test]
fn a_window_map_has_one_row_per_design_resumes_and_merges() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("map");
    let o = d.to_str().unwrap();
    let vary = "obstacle.0.material.bruise_pressure=3e4,4e4";
    let first = ok(&["window", BRUISE, "--vary", vary, "--out", o, "-q"]);
    assert!(
        first.contains("2 designs: 2 searched, 0 skipped"),
        "{first}"
    );
    let r = rows(&d.join("window.csv"));
    assert_eq!(r.len(), 2);
    let h = csv::Reader::from_path(d.join("window.csv"))
        .unwrap()
        .headers()
        .unwrap()
        .clone();
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    // A tougher skin bruises at a higher grip (p₀ ∝ √F roughly: more than twice the grip).
    let g: Vec<f64> = r
        .iter()
        .map(|x| x[col("g_bruise")].parse().unwrap())
        .collect();
    assert!(g[1] > 2.0 * g[0], "{g:?}");
    assert_eq!(&r[0][col("bruise_status")], "found");
    let runs: usize = r
        .iter()
        .map(|x| x[col("runs")].parse::<usize>().unwrap())
        .sum();
    for f in ["window.json", "window.png", "window.svg"] {
        assert!(d.join(f).exists(), "{f}");
    }
    let j = json(&d.join("window.json"));
    assert_eq!(j["designs"].as_array().unwrap().len(), 2);
    assert_eq!(
        j["designs"][1]["window"]["runs"].as_array().unwrap().len()
            + j["designs"][0]["window"]["runs"].as_array().unwrap().len(),
        runs
    );

    // A third design: the two finished ones are skipped.
    let vary3 = "obstacle.0.material.bruise_pressure=3e4,3.5e4,4e4";
    let again = ok(&["window", BRUISE, "--vary", vary3, "--out", o, "-q"]);
    assert!(
        again.contains("3 designs: 1 searched, 2 skipped"),
        "{again}"
    );
    let r3 = rows(&d.join("window.csv"));
    assert_eq!(r3.len(), 3);
    assert_eq!(r3[0], r[0]);
    assert_eq!(r3[2][col("g_bruise")], r[1][col("g_bruise")]);

    // Two shards in one folder, merged: the same table.
    let s = dir.path().join("shards");
    let so = s.to_str().unwrap();
    for shard in ["0/2", "1/2"] {
        let out = ok(&[
            "window", BRUISE, "--vary", vary3, "--out", so, "--shard", shard, "-q",
        ]);
        assert!(out.contains("gripsim sweep merge"), "{out}");
    }
    assert!(!s.join("window.csv").exists());
    assert!(s.join("window.shard-0-of-2.csv").exists());
    ok(&["sweep", "merge", so]);
    assert_eq!(
        std::fs::read_to_string(s.join("window.csv")).unwrap(),
        std::fs::read_to_string(d.join("window.csv")).unwrap()
    );

    // A sweep does not write into a window map's folder.
    let bad = gripsim(&["sweep", BRUISE, "--vary", vary, "--out", o]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("holds a window map"));
}

#[test]
fn a_two_key_window_map_draws_the_ratio_as_a_heat_map() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("map2");
    ok(&[
        "window",
        BRUISE,
        "--vary",
        "obstacle.0.material.bruise_pressure=3e4,4e4",
        "--vary",
        "obstacle.0.material.E=1.5e6,2e6",
        "--range",
        "0.5:8",
        "--out",
        d.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(rows(&d.join("window.csv")).len(), 4);
    for f in ["window.png", "window.svg"] {
        let n = std::fs::metadata(d.join(f)).unwrap().len();
        assert!(n > 5_000, "{f}: {n} bytes");
    }
}

/// Bytes of the files under `dir` whose name ends with one of `ext`.
fn bytes_of(dir: &Path, ext: &[&str]) -> u64 {
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            n += bytes_of(&p, ext);
        } else if ext.iter().any(|x| p.to_string_lossy().ends_with(x)) {
            n += std::fs::metadata(&p).unwrap().len();
        }
    }
    n
}

/// By default a sweep draws the figures of flagged cases only (the bruised 1 GPa prong), a
/// two-key grid gets its heat maps, and a flagged case's figures are those `--case-plots all`
/// draws (its second run is the same run).
#[test]
fn a_sweep_draws_case_figures_only_for_flagged_cases() {
    let dir = tempfile::tempdir().unwrap();
    let args = |out: &Path, extra: &[&str]| {
        let mut a: Vec<String> = [
            "sweep",
            "scenarios/seed-grasp-r5.toml",
            "--vary",
            "rod.0.E=1e6,1e9",
            "--vary",
            "obstacle.0.radius=0.05,0.049",
            "--set",
            "contact.surface=face",
            "--set",
            "obstacle.0.center=[-0.055,-0.05]",
            "--set",
            "obstacle.0.material=apple",
            "--set",
            "solve.t_end=0.045",
            "--out",
            out.to_str().unwrap(),
            "-q",
        ]
        .map(String::from)
        .to_vec();
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let (def, all, none) = (
        dir.path().join("default"),
        dir.path().join("all"),
        dir.path().join("none"),
    );
    let run = |a: Vec<String>| ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    run(args(&def, &[]));
    run(args(&all, &["--case-plots", "all"]));
    run(args(&none, &["--no-plots"]));
    let figs = [".png", ".svg"];
    let mut flagged = 0;
    for e in std::fs::read_dir(def.join("cases")).unwrap() {
        let case = e.unwrap().path();
        let rec = json(&case.join("case.json"));
        let m = &rec["metrics"];
        let flag = m["bruise"].as_u64().unwrap() > 0
            || m["spikes"].as_u64().unwrap() > 0
            || m["sticking"].as_u64().unwrap() > 0
            || m["warnings"].as_u64().unwrap() > 0
            || m["completed"] == false;
        let n = bytes_of(&case, &figs);
        if flag {
            flagged += 1;
            assert!(
                n > 20_000,
                "{}: flagged, {n} bytes of figures",
                case.display()
            );
            let same = all.join("cases").join(case.file_name().unwrap());
            for f in ["forces.png", "shapes.png"] {
                assert_eq!(
                    std::fs::read(case.join(f)).unwrap(),
                    std::fs::read(same.join(f)).unwrap(),
                    "{f}"
                );
            }
        } else {
            assert_eq!(n, 0, "{}: not flagged, yet figures", case.display());
        }
    }
    // The 1 GPa prong bruises the apple (both radii); the 1 MPa one does not.
    assert_eq!(flagged, 2);
    assert!(bytes_of(&all.join("cases"), &figs) > bytes_of(&def.join("cases"), &figs));
    assert_eq!(bytes_of(&none, &figs), 0);
    let map = def.join("plots/map-rod-0-E-obstacle-0-radius.png");
    assert!(std::fs::metadata(&map).unwrap().len() > 20_000);
    assert!(def.join("plots/map-rod-0-E-obstacle-0-radius.svg").exists());
    // The same table either way.
    assert_eq!(
        std::fs::read_to_string(def.join("summary.md")).unwrap(),
        std::fs::read_to_string(none.join("summary.md")).unwrap()
    );
}
