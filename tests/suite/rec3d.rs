//! 3D runs recorded (.rrd, MCAP) and replayed (`replay check|diff|show`, `run --check`), and
//! `--set` on 3D scenarios (issue 16 item 5).

use crate::common::{expect, gripsim, run_ok, scenario, venv};
use std::path::{Path, PathBuf};

fn tmp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gripsim-rec3d-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap()
}

fn verify_rrd(p: &Path) {
    let out = std::process::Command::new(venv().join("bin/rerun"))
        .args(["rrd", "verify"])
        .arg(p)
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the rerun CLI runs");
    assert!(
        out.status.success(),
        "rerun rrd verify {}:\n{}{}",
        p.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The two-finger grasp at 10× the scenario's step (≈ 700 steps) with every output: the .rrd
/// verifies; the MCAP read by the independent Python reader (protobuf from the file's own
/// descriptor) gives the summary's finger forces and fruit position and the CSV's node
/// positions bit for bit; recording changes nothing (the summary of an unrecorded run is the
/// same file).
#[test]
fn a_3d_grasp_recorded_as_rrd_and_mcap_agrees_with_csv_and_summary() {
    let d = tmp("rec");
    let sc = scenario("3d-two-finger-sphere");
    run_ok(
        gripsim()
            .arg("run")
            .arg(&sc)
            .args(["--set", "solve.dt=1e-3", "-q"])
            .arg("--rrd")
            .arg(d.join("g.rrd"))
            .arg("--mcap")
            .arg(d.join("g.mcap"))
            .arg("--csv")
            .arg(d.join("g.csv"))
            .arg("--summary")
            .arg(d.join("g.json")),
    );
    run_ok(
        gripsim()
            .arg("run")
            .arg(&sc)
            .args(["--set", "solve.dt=1e-3", "-q", "--summary"])
            .arg(d.join("plain.json")),
    );
    let without_wall = |p: &Path| {
        let mut v = json(p);
        v.as_object_mut().unwrap().remove("wall_time_s");
        v
    };
    assert_eq!(
        without_wall(&d.join("g.json")),
        without_wall(&d.join("plain.json")),
        "recording changed the run"
    );
    verify_rrd(&d.join("g.rrd"));
    let out = std::process::Command::new(venv().join("bin/python"))
        .arg(Path::new(crate::common::ROOT).join("tests/py/read_mcap.py"))
        .arg(d.join("g.mcap"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(r["error"].is_null(), "{}", r["error"]);
    let s = json(&d.join("g.json"));
    let steps = s["steps"].as_u64().unwrap();
    // The squeeze ends on the sensed force: the step count follows the physics (709 when
    // this was written, 752 after main's 3D changes), the recording must follow the summary.
    assert!(steps > 500, "{steps}");
    assert_eq!(r["topics"]["/sim/step"]["schema"], "gripsim.Step3");
    // Step 0 (the initial state) and every step after it, then the run's end.
    assert_eq!(
        r["topics"]["/sim/step"]["messages"].as_u64(),
        Some(steps + 1)
    );
    assert_eq!(r["topics"]["/scene"]["messages"].as_u64(), Some(steps + 1));
    assert_eq!(r["topics"]["/scene/static"]["messages"].as_u64(), Some(1));
    let numbers: Vec<u64> = r["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(numbers, (0..=steps).collect::<Vec<_>>());
    let first = &r["step_samples"][0];
    assert_eq!(
        (first["step"].as_u64(), f(&first["t"]), f(&first["dt"])),
        (Some(0), 0.0, 0.0)
    );
    assert_eq!(
        first["bodies"][0]["position"],
        s["grasp"]["initial_position_m"]
    );
    assert_eq!(r["topics"]["/sim/event"]["messages"].as_u64(), Some(1));
    let end = &r["last_event"];
    assert_eq!(end["kind"], "run_end");
    assert_eq!(end["step"].as_u64(), Some(steps));
    assert_eq!(f(&end["t"]), f(&s["simulated_time_s"]));
    assert_eq!(end["completed"], true);
    // /scene is protobuf foxglove.SceneUpdate (3D format 3), decoded by Google's library from
    // the file's descriptor: each sampled step's centre lines are its /sim/step positions in
    // f32, the fruit's sphere is at its body's position (f32), the table a triangle list.
    assert_eq!(r["meta3"]["format_version"].as_u64(), Some(3));
    for topic in ["/scene", "/scene/static"] {
        assert_eq!(r["topics"][topic]["schema_encoding"], "protobuf", "{topic}");
        assert_eq!(
            r["topics"][topic]["message_encoding"], "protobuf",
            "{topic}"
        );
    }
    assert_eq!(r["scene_static"][0]["triangles"], serde_json::json!([4]));
    let f32s = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| f(x) as f32 as f64)
            .collect()
    };
    let samples = r["step_samples"].as_array().unwrap();
    let mut checked = 0;
    for sc in r["scene_samples"].as_array().unwrap() {
        let n = sc["index"].as_u64().unwrap();
        let st = samples
            .iter()
            .find(|s| s["step"].as_u64() == Some(n))
            .expect("the step of each scene sample is sampled");
        let ents = sc["entities"].as_array().unwrap();
        for (k, rod) in ["finger0", "finger1"].iter().enumerate() {
            let e = ents
                .iter()
                .find(|e| e["id"] == format!("rod/{rod}"))
                .unwrap();
            let line: Vec<f64> = e["line_points"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|p| p.as_array().unwrap().iter().map(f))
                .collect();
            assert_eq!(line, f32s(&st["rods"][k]["x"]), "step {n} {rod}");
        }
        let body = ents.iter().find(|e| e["id"] == "body/fruit").unwrap();
        let centre: Vec<f64> = body["spheres"][0]
            .as_array()
            .unwrap()
            .iter()
            .map(f)
            .collect();
        assert_eq!(centre, f32s(&st["bodies"][0]["position"]), "step {n}");
        checked += 1;
    }
    assert!(checked >= 20, "{checked}");
    let meta_end = &r["metadata"]["gripsim.run_end"];
    assert_eq!(meta_end["completed"], "true");
    assert_eq!(meta_end["steps"], steps.to_string());
    assert_eq!(
        r["meta3"]["rods"],
        serde_json::json!(["finger0", "finger1"])
    );
    let last = &r["last_step3"];
    assert_eq!(last["step"].as_u64(), Some(steps));
    assert_eq!(f(&last["t"]), f(&s["simulated_time_s"]));
    // Finger forces: the summed normal reactions per rod, as the summary has them.
    let mut forces = [0.0f64; 2];
    for c in last["contacts"].as_array().unwrap() {
        forces[c["rod"].as_u64().unwrap() as usize] += f(&c["normal_force"]);
    }
    let want: Vec<f64> = s["rods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| f(&r["final_contact_force_n"]))
        .collect();
    println!("3D MCAP: {steps} steps, finger forces {forces:?} N (summary {want:?})");
    assert_eq!(forces.to_vec(), want);
    assert!(forces[0] > 0.3, "the fingers press: {forces:?}");
    let fruit: Vec<f64> = last["bodies"][0]["position"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    let fruit_end: Vec<f64> = s["grasp"]["final_position_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    assert_eq!(fruit, fruit_end);
    // The CSV's last step: every node of every finger where /sim/step has it.
    let csv = std::fs::read_to_string(d.join("g.csv")).unwrap();
    let mut compared = 0;
    for line in csv.lines().skip(1) {
        let c: Vec<&str> = line.split(',').collect();
        if c[0] != steps.to_string() || !c[2].starts_with("finger") {
            continue;
        }
        let r_ix: usize = c[2]["finger".len()..].parse().unwrap();
        let i: usize = c[3].parse().unwrap();
        let x = &last["rods"][r_ix]["x"];
        for k in 0..3 {
            assert_eq!(c[4 + k].parse::<f64>().unwrap(), f(&x[3 * i + k]), "{line}");
        }
        compared += 1;
    }
    assert_eq!(compared, 20);
    std::fs::remove_dir_all(&d).unwrap();
}

/// `run --check` on a shipped 3D grasp finds nothing; the same grasp at 10× its step is
/// flagged (impact spikes where the fingers land), live and from its MCAP alike; `replay diff`
/// reports the largest node distance between the two; `replay show` writes a .rrd that
/// verifies.
#[test]
fn replay_check_diff_and_show_on_3d_runs() {
    let d = tmp("replay");
    let sc = scenario("3d-two-finger-sphere");
    let out = expect(
        gripsim()
            .arg("run")
            .arg(&sc)
            .args(["-q", "--check", "--check-json"])
            .arg(d.join("fine.check.json"))
            .arg("--mcap")
            .arg(d.join("fine.mcap")),
        0,
    );
    let fine = json(&d.join("fine.check.json"));
    println!("{}", String::from_utf8_lossy(&out.stdout));
    assert_eq!(fine["flagged"], false);
    assert_eq!(fine["spikes"].as_array().unwrap().len(), 0);
    assert_eq!(fine["sticking"].as_array().unwrap().len(), 0);
    assert!(fine["steps"].as_u64().unwrap() > 5000, "{}", fine["steps"]);
    expect(
        gripsim()
            .arg("run")
            .arg(&sc)
            .args(["-q", "--set", "solve.dt=1e-3", "--check", "--check-json"])
            .arg(d.join("coarse.live.json"))
            .arg("--mcap")
            .arg(d.join("coarse.mcap")),
        1,
    );
    expect(
        gripsim()
            .args(["replay", "check"])
            .arg(d.join("coarse.mcap"))
            .arg("--json")
            .arg(d.join("coarse.check.json")),
        1,
    );
    let live = json(&d.join("coarse.live.json"));
    let offline = json(&d.join("coarse.check.json"));
    assert_eq!(
        live["spikes"], offline["spikes"],
        "live and replayed checks differ"
    );
    let spikes = offline["spikes"].as_array().unwrap();
    println!(
        "10x coarser dt: {} spikes, first {} at t = {} s, jump {} m/s",
        spikes.len(),
        spikes[0]["kind"],
        spikes[0]["t"],
        spikes[0]["jump"]
    );
    assert!(!spikes.is_empty());
    assert!(spikes.iter().all(|s| s["kind"] == "impact"));
    expect(
        gripsim().args(["replay", "check"]).arg(d.join("fine.mcap")),
        0,
    );
    expect(
        gripsim()
            .args(["replay", "diff"])
            .arg(d.join("fine.mcap"))
            .arg(d.join("coarse.mcap"))
            .arg("--json")
            .arg(d.join("diff.json")),
        1,
    );
    let diff = json(&d.join("diff.json"));
    let dist = f(&diff["max_distance"]);
    println!(
        "diff fine vs 10x coarse: largest node distance {dist:.6e} m ({} node {} at t = {} s)",
        diff["rod_name"], diff["node"], diff["t"]
    );
    assert!(dist > 1e-6 && dist < 1e-2, "{dist}");
    // What the planar diff reports, in 3D: the differing scenario value, the velocity
    // difference and first divergence, contact events paired across the runs, and the
    // coarse run's impact spikes as found in run B only (the fine run has none).
    let params = diff["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 1, "{params:?}");
    assert_eq!(params[0]["key"], "solve.dt");
    assert_eq!(f(&params[0]["b"]), 1e-3);
    assert!(f(&diff["velocity"]["max"]) > 1e-3);
    assert!(diff["first_divergence"].is_object());
    let ev = &diff["contact_event_counts"];
    println!("contact events: {ev}");
    assert!(ev["a"].as_u64().unwrap() > 0);
    assert_eq!(ev["a"], ev["b"]);
    assert_eq!(ev["only_a"], 0);
    assert_eq!(ev["only_b"], 0);
    let found = diff["findings"].as_array().unwrap();
    assert_eq!(found.len(), spikes.len(), "{found:?}");
    assert!(found
        .iter()
        .all(|x| x["status"] == "only_b" && x["category"] == "spike" && x["kind"] == "impact"));
    assert_eq!(diff["counts_a"]["spikes"], 0);
    assert_eq!(
        diff["counts_b"]["spikes"].as_u64().unwrap() as usize,
        spikes.len()
    );
    assert_eq!(diff["within_tolerance"], false);
    expect(
        gripsim()
            .args(["replay", "diff"])
            .arg(d.join("coarse.mcap"))
            .arg(d.join("coarse.mcap"))
            .arg("--json")
            .arg(d.join("same.json")),
        0,
    );
    let same = json(&d.join("same.json"));
    assert_eq!(f(&same["max_distance"]), 0.0);
    assert_eq!(f(&same["velocity"]["max"]), 0.0);
    assert!(same["first_divergence"].is_null());
    assert_eq!(same["parameters"].as_array().unwrap().len(), 0);
    assert_eq!(same["findings"].as_array().unwrap().len(), 0);
    assert_eq!(same["contact_event_counts"]["shifted"], 0);
    assert_eq!(same["within_tolerance"], true);
    expect(
        gripsim()
            .args(["replay", "show"])
            .arg(d.join("coarse.mcap"))
            .arg("--rrd")
            .arg(d.join("coarse.rrd")),
        0,
    );
    verify_rrd(&d.join("coarse.rrd"));
    std::fs::remove_dir_all(&d).unwrap();
}

/// `--set` on a 3D scenario: an override reaches the run (t_end), a bad key, index or value is
/// refused with exit 2 on one line naming the file, the key and the value, and nothing is
/// written.
#[test]
fn set_overrides_a_3d_scenario_with_the_planar_rules() {
    let d = tmp("set");
    let sc = scenario("3d-two-finger-sphere");
    run_ok(
        gripsim()
            .arg("run")
            .arg(&sc)
            .args([
                "-q",
                "--no-record",
                "--set",
                "solve.t_end=0.01",
                "--summary",
            ])
            .arg(d.join("s.json")),
    );
    assert_eq!(json(&d.join("s.json"))["steps"].as_u64(), Some(100));
    for (set, key, value) in [
        ("solve.tend=0.01", "solve.tend", "0.01"),
        ("move.7.speed=1", "move.7", "1"),
        ("solve.dt=-1", "solve.dt", "-1"),
        ("gripper.kind=tripod", "gripper.kind", "tripod"),
    ] {
        let out = expect(
            gripsim()
                .arg("run")
                .arg(&sc)
                .args(["--set", set, "--csv"])
                .arg(d.join("x.csv"))
                .arg("--mcap")
                .arg(d.join("x.mcap")),
            2,
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(
            err.contains("3d-two-finger-sphere.toml")
                && err.contains(&format!("--set {set}"))
                && err.contains(key)
                && err.contains(value),
            "{err}"
        );
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n != "s.json")
            .collect();
        assert!(left.is_empty(), "{set}: left {left:?}");
    }
    expect(
        gripsim()
            .arg("validate")
            .arg(&sc)
            .args(["--set", "gripper.radius=0.07"]),
        0,
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// The report of tests/py/read_rrd.py (the Rerun SDK reading the file back).
fn read_rrd(p: &Path) -> serde_json::Value {
    let out = std::process::Command::new(venv().join("bin/python"))
        .arg(Path::new(crate::common::ROOT).join("tests/py/read_rrd.py"))
        .arg(p)
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the venv's python runs");
    assert!(
        out.status.success(),
        "read_rrd.py {}:\n{}",
        p.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `replay check --rrd` and `replay diff --rrd` on 3D runs: the two-finger grasp at 10× its
/// step is flagged; the overlay read back by the Rerun SDK marks exactly the report's
/// findings (one ball per spike, on the spiking node's entity, at the spike's step) and lists
/// them in `events/flags`; the diff against the same grasp at 5× its step draws run B's rods at
/// every compared step, plots the per-rod distance whose largest value is the report's, marks
/// the largest difference from its step on and bookmarks it once. Both files verify.
#[test]
fn check_and_diff_rrd_overlays_on_3d_runs() {
    let d = tmp("overlay");
    let sc = scenario("3d-two-finger-sphere");
    for (dt, name) in [("1e-3", "a.mcap"), ("5e-4", "b.mcap")] {
        run_ok(
            gripsim()
                .arg("run")
                .arg(&sc)
                .args(["-q", "--set", &format!("solve.dt={dt}"), "--mcap"])
                .arg(d.join(name)),
        );
    }
    expect(
        gripsim()
            .args(["replay", "check"])
            .arg(d.join("a.mcap"))
            .arg("--json")
            .arg(d.join("check.json"))
            .arg("--rrd")
            .arg(d.join("check.rrd")),
        1,
    );
    verify_rrd(&d.join("check.rrd"));
    let rep = json(&d.join("check.json"));
    let spikes = rep["spikes"].as_array().unwrap();
    let sticking = rep["sticking"].as_array().unwrap();
    assert!(!spikes.is_empty());
    let view = read_rrd(&d.join("check.rrd"));
    let overlay = view["overlay"].as_object().unwrap();
    let rows = |e: &str| -> Vec<u64> {
        overlay
            .get(e)
            .map(|v| {
                v.as_array()
                    .unwrap()
                    .iter()
                    .map(|s| s.as_u64().unwrap())
                    .collect()
            })
            .unwrap_or_default()
    };
    let mut want: std::collections::BTreeMap<String, Vec<u64>> = Default::default();
    for (kind, list) in [("spike", spikes), ("sticking", sticking)] {
        for s in list {
            want.entry(format!(
                "/scene/flags/{kind}/{}/node_{}",
                s["rod_name"].as_str().unwrap(),
                s["node"]
            ))
            .or_default()
            .push(s["step"].as_u64().unwrap());
        }
    }
    let flagged: Vec<&String> = overlay
        .keys()
        .filter(|k| k.starts_with("/scene/flags/"))
        .collect();
    assert_eq!(flagged.len(), want.len(), "{overlay:?} vs {want:?}");
    for (e, steps) in &want {
        let mut steps = steps.clone();
        steps.sort();
        assert_eq!(rows(e), steps, "{e}");
    }
    let texts: Vec<String> = view["flag_events"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| {
            r["text"]
                .as_str()
                .unwrap()
                .split("; ")
                .map(String::from)
                .collect::<Vec<_>>()
        })
        .collect();
    assert_eq!(texts.len(), spikes.len() + sticking.len(), "{texts:?}");
    assert!(texts
        .iter()
        .all(|t| t.contains("spike") || t.contains("sticking")));
    println!(
        "3D check --rrd: {} spikes, {} sticking; {} flag entities, {} flag rows in events/flags",
        spikes.len(),
        sticking.len(),
        flagged.len(),
        texts.len()
    );

    expect(
        gripsim()
            .args(["replay", "diff"])
            .arg(d.join("a.mcap"))
            .arg(d.join("b.mcap"))
            .arg("--json")
            .arg(d.join("diff.json"))
            .arg("--rrd")
            .arg(d.join("diff.rrd")),
        1,
    );
    verify_rrd(&d.join("diff.rrd"));
    let rep = json(&d.join("diff.json"));
    let view = read_rrd(&d.join("diff.rrd"));
    let overlay = view["overlay"].as_object().unwrap();
    let compared = rep["compared_steps"].as_u64().unwrap();
    for r in ["finger0", "finger1"] {
        for e in [
            format!("/scene/run_b/{r}/centerline"),
            format!("/diff/position/{r}"),
        ] {
            let n = overlay.get(&e).map_or(0, |v| v.as_array().unwrap().len());
            assert_eq!(n as u64, compared, "{e}");
        }
    }
    let marked: Vec<u64> = overlay["/scene/largest_difference"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_u64().unwrap())
        .collect();
    let bookmarks = view["bookmarks"].as_array().unwrap();
    assert_eq!(bookmarks.len(), 1, "{bookmarks:?}");
    let text = bookmarks[0]["text"].as_str().unwrap();
    let dist = f(&rep["max_distance"]);
    assert!(
        text.contains(&format!("{:.3e} m", dist))
            && text.contains(&format!(
                "{} node {}",
                rep["rod_name"].as_str().unwrap(),
                rep["node"]
            )),
        "{text}"
    );
    // Marked from the step of the largest difference to A's last step.
    let first = bookmarks[0]["step"].as_u64().unwrap();
    assert_eq!(marked[0], first);
    let t_ns = bookmarks[0]["sim_time_ns"].as_f64().unwrap();
    assert!(
        (t_ns * 1e-9 - f(&rep["t"])).abs() < 1e-9,
        "{t_ns} vs {}",
        rep["t"]
    );
    println!(
        "3D diff --rrd: {compared} steps, largest distance {dist:.6e} m at step {first}; marked on {} steps",
        marked.len()
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A check report without its `file` (live and replayed reports name different files).
fn without_file(mut v: serde_json::Value) -> serde_json::Value {
    v.as_object_mut().unwrap().remove("file");
    v
}

/// The grasp rules on 3D runs (the planar rule: the gripper is the centroid of the driven
/// nodes, slip beyond the fruit's hold tolerance during the lift, drop when no prong touches
/// it): the shipped lift holds its sphere (no flag, live and replayed); with a tenth of its
/// friction the sphere stays on the table while the hand rises and is flagged as slipping
/// during the lift, at the same step live and replayed; a scenario that expects the slip
/// (`[expect] grasp = "slipped"`) reports it unflagged, and a wider `[fruit] hold_tolerance`
/// flags it later. A copy cut short has no run end:
/// `replay check` says so and exits 3, or reads what is there with `--allow-partial`.
#[test]
fn grasp_rules_on_3d_lifts_live_and_replayed() {
    let d = tmp("grasp");
    let sc = scenario("3d-lift");
    let mut reports = vec![];
    for (tag, sets, code) in [
        ("held", vec![], 0),
        (
            "slip",
            vec!["--set", "friction.mu_s=0.1", "--set", "friction.mu_k=0.08"],
            1,
        ),
        (
            "expected",
            vec![
                "--set",
                "friction.mu_s=0.1",
                "--set",
                "friction.mu_k=0.08",
                "--set",
                "expect.grasp=slipped",
            ],
            0,
        ),
        (
            "wider",
            vec![
                "--set",
                "friction.mu_s=0.1",
                "--set",
                "friction.mu_k=0.08",
                "--set",
                "fruit.hold_tolerance=0.01",
            ],
            1,
        ),
    ] {
        let out = expect(
            gripsim()
                .arg("run")
                .arg(&sc)
                .arg("-q")
                .args(&sets)
                .arg("--check")
                .arg("--check-json")
                .arg(d.join(format!("{tag}.live.json")))
                .arg("--mcap")
                .arg(d.join(format!("{tag}.mcap")))
                .arg("--summary")
                .arg(d.join(format!("{tag}.json"))),
            code,
        );
        println!("{}", String::from_utf8_lossy(&out.stdout));
        expect(
            gripsim()
                .args(["replay", "check"])
                .arg(d.join(format!("{tag}.mcap")))
                .arg("--json")
                .arg(d.join(format!("{tag}.check.json"))),
            code,
        );
        let live = json(&d.join(format!("{tag}.live.json")));
        let offline = json(&d.join(format!("{tag}.check.json")));
        assert_eq!(without_file(live.clone()), without_file(offline), "{tag}");
        reports.push((live, json(&d.join(format!("{tag}.json")))));
    }
    let (held, held_sum) = &reports[0];
    assert_eq!(held["flagged"], false, "{held:#}");
    assert!(held.get("grasp").is_none(), "{held:#}");
    let rise = |s: &serde_json::Value| {
        f(&s["grasp"]["final_position_m"][2]) - f(&s["grasp"]["initial_position_m"][2])
    };
    assert!(
        rise(held_sum) > 0.025,
        "held: the fruit rises {}",
        rise(held_sum)
    );
    let (slip, slip_sum) = &reports[1];
    let flags = slip["grasp"].as_array().unwrap();
    assert_eq!(flags[0]["kind"], "slip", "{flags:?}");
    let (step, t) = (flags[0]["step"].as_u64().unwrap(), f(&flags[0]["t"]));
    let tol = f(&flags[0]["hold_tolerance_m"]);
    assert_eq!(tol, 0.1 * 0.05, "0.1 × the sphere's radius");
    assert!(f(&flags[0]["slip_m"]) > tol);
    // The lift starts after the squeeze and its 0.05 s hold and lasts 0.5 s: the slip is
    // flagged within it, at the step of its time.
    let squeeze = slip_sum["phases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "squeeze")
        .unwrap();
    assert_eq!(squeeze["reason"], "grip_force", "{squeeze}");
    let lift = f(&squeeze["end_s"]) + 0.05;
    assert!(
        t > lift && t < lift + 0.5,
        "slip at t = {t}, lift from {lift}"
    );
    assert!((t - step as f64 * 2e-4).abs() < 1e-9, "{step} {t}");
    assert!(
        rise(slip_sum) < tol,
        "slip: the fruit rises {}",
        rise(slip_sum)
    );
    println!(
        "3d-lift held: fruit rises {:.4} m, no grasp flag; mu_s = 0.1: {} at step {step} (t = {t} s, lift from {lift} s), slip {:.3e} m > {tol} m, fruit rises {:.2e} m; {} flag(s)",
        rise(held_sum),
        flags[0]["kind"],
        f(&flags[0]["slip_m"]),
        rise(slip_sum),
        flags.len()
    );
    // `[expect] grasp = "slipped"`: the same slip is reported as expected, not flagged.
    let (expected, _) = &reports[2];
    assert_eq!(expected["flagged"], false, "{expected:#}");
    assert!(expected.get("grasp").is_none(), "{expected:#}");
    assert_eq!(expected["grasp_expected"][0], flags[0]);
    // `[fruit] hold_tolerance` sets the slip allowed: twice the default flags the same slip
    // later, where the fruit has fallen behind the hand by the larger distance.
    let wider = reports[3].0["grasp"].as_array().unwrap();
    assert_eq!(wider[0]["kind"], "slip", "{wider:?}");
    assert_eq!(f(&wider[0]["hold_tolerance_m"]), 0.01);
    assert!(f(&wider[0]["slip_m"]) > 0.01);
    assert!(
        f(&wider[0]["t"]) > t,
        "hold_tolerance 0.01: slip at {} s, default at {t} s",
        f(&wider[0]["t"])
    );
    // A copy cut short: no run end, exit 3; --allow-partial reads the steps before the cut.
    let bytes = std::fs::read(d.join("held.mcap")).unwrap();
    std::fs::write(d.join("cut.mcap"), &bytes[..bytes.len() * 6 / 10]).unwrap();
    let out = expect(
        gripsim()
            .args(["replay", "check"])
            .arg(d.join("cut.mcap"))
            .arg("--json")
            .arg(d.join("cut.json")),
        3,
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("INCOMPLETE"),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let cut = json(&d.join("cut.json"));
    assert_eq!(cut["incomplete"], true);
    assert!(cut["completed"].is_null());
    let cut_steps = cut["steps"].as_u64().unwrap();
    assert!(cut_steps > 0 && cut_steps < held["steps"].as_u64().unwrap());
    expect(
        gripsim()
            .args(["replay", "check", "--allow-partial"])
            .arg(d.join("cut.mcap")),
        0,
    );
    std::fs::remove_dir_all(&d).unwrap();
}
