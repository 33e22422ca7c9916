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
    assert_eq!(
        std::fs::read(d.join("g.json")).unwrap(),
        std::fs::read(d.join("plain.json")).unwrap(),
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
    assert_eq!(r["topics"]["/sim/step"]["messages"].as_u64(), Some(steps));
    assert_eq!(r["topics"]["/scene"]["messages"].as_u64(), Some(steps));
    assert_eq!(r["topics"]["/scene/static"]["messages"].as_u64(), Some(1));
    assert_eq!(
        r["meta3"]["rods"],
        serde_json::json!(["finger0", "finger1"])
    );
    let last = &r["last_step3"];
    assert_eq!(last["step"].as_u64(), Some(steps));
    assert_eq!(f(&last["t"]), f(&s["t_end"]));
    // Finger forces: the summed normal reactions per rod, as the summary has them.
    let mut forces = [0.0f64; 2];
    for c in last["contacts"].as_array().unwrap() {
        forces[c["rod"].as_u64().unwrap() as usize] += f(&c["normal_force"]);
    }
    let want: Vec<f64> = s["finger_forces"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
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
    let fruit_end: Vec<f64> = s["fruit_end"].as_array().unwrap().iter().map(f).collect();
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
    expect(
        gripsim()
            .args(["replay", "diff"])
            .arg(d.join("coarse.mcap"))
            .arg(d.join("coarse.mcap"))
            .arg("--json")
            .arg(d.join("same.json")),
        0,
    );
    assert_eq!(f(&json(&d.join("same.json"))["max_distance"]), 0.0);
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
            .args(["-q", "--set", "solve.t_end=0.01", "--summary"])
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
