//! `gripsim replay`: recordings built to contain known spikes and sticking patterns are
//! checked, runs are diffed, stored runs are turned into .rrd files, bad input is refused,
//! and the README's CI example runs against the committed golden recording.

use crate::common::{expect, gripsim, scenario, text, venv, ROOT};
use gripsim::events::{ContactChange, Event, Observer, ReleaseReason, RodStepView, RunInfo};
use gripsim::record::mcap::McapSink;
use gripsim::record::{Detail, RecordOptions, Recording};
use gripsim::{Scenario, Simulation};
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Output};

fn run_to(sc: &Path, mcap: &Path, sets: &[&str]) {
    let mut c = gripsim();
    c.arg("run")
        .arg(sc)
        .arg("-q")
        .args(["--detail", "step"])
        .arg("--mcap")
        .arg(mcap);
    for s in sets {
        c.args(["--set", s]);
    }
    expect(&mut c, 0);
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn rerun_rrd(sub: &str, files: &[&Path]) -> Output {
    Command::new(venv().join("bin/rerun"))
        .arg("rrd")
        .arg(sub)
        .args(files)
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the rerun CLI runs")
}

// ---- recordings built to contain known patterns ----------------------------------------------

/// Rod 0 "beam" (6 nodes) rests above a table; rod 1 "ball" is a particle moving down at
/// 0.5 m/s. No gravity, so any velocity change is something this file put there.
const SYNTHETIC: &str = r#"
name = "synthetic"
description = "Built by tests/replay.rs"

[solve]
mode = "dynamic"
t_end = 0.02
dt = 1e-4
stepping = "fixed"
gravity = [0.0, 0.0]

[[rod]]
name = "beam"
nodes = 6
shape = { kind = "straight", start = [0.0, 0.05], end = [0.1, 0.05] }
E = 1e6
section = { kind = "rect", b = 0.02, h = 0.01 }
density = 1000.0

[[particle]]
name = "ball"
position = [0.2, 0.006]
velocity = [0.0, -0.5]
mass = 0.01

[[obstacle]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"#;

const STEPS: u64 = 200;
const DT: f64 = 1e-4;

/// What to put into a synthetic recording.
#[derive(Clone, Copy, Default)]
struct Inject {
    spikes: bool,
    sticking: bool,
}

/// Per-rod state of one synthetic step.
struct State {
    q: Vec<f64>,
    u: Vec<f64>,
    reaction: Vec<f64>,
    normal: Vec<f64>,
    in_contact: Vec<bool>,
    q_pred: Vec<f64>,
}

impl State {
    fn new(q: &[f64]) -> Self {
        let n = q.len();
        Self {
            q: q.to_vec(),
            u: vec![0.0; n],
            reaction: vec![0.0; n],
            normal: vec![0.0; n],
            in_contact: vec![false; n / 2],
            q_pred: q.to_vec(),
        }
    }

    fn hold(&mut self, i: usize) {
        self.in_contact[i] = true;
        self.normal[2 * i + 1] = 1.0;
    }
}

/// Write a synthetic run through the project's own MCAP sink.
fn synthetic(path: &Path, inject: Inject) {
    let sc = Scenario::from_str(SYNTHETIC, "synthetic", &[]).unwrap();
    let sim = Simulation::new(&sc);
    let infos = sim.rod_infos().to_vec();
    let rest: Vec<Vec<f64>> = (0..2).map(|r| sim.positions(r).to_vec()).collect();
    let mut sink = McapSink::create(
        path,
        RecordOptions {
            detail: Detail::Step,
            flush_every: 50,
        },
    )
    .unwrap();
    sink.on_event(&Event::RunStart(&RunInfo {
        scenario_name: &sc.name,
        scenario_text: &sc.text,
        rods: &infos,
        dimension: 2,
        scene: gripsim::events::Scene::Planar {
            obstacles: &sc.obstacles,
        },
        obstacle_names: &sc.obstacle_names,
        bodies: &sc.bodies,
        mode: sc.solve.mode,
    }));
    let change = |step: u64, rod: usize, node: usize| ContactChange {
        step,
        t: step as f64 * DT,
        pass: 1,
        rod,
        node,
        obstacle: 0,
        normal: [0.0, 1.0, 0.0],
        gap: 0.0,
        reaction: [0.0, 0.0, 0.0],
        z: 0.0,
    };
    let mut ball_y = 0.006;
    let mut ball_landed = false;
    for k in 0..=STEPS {
        let mut beam = State::new(&rest[0]);
        let mut ball = State::new(&[0.2, ball_y]);
        // The ball coasts down at 0.5 m/s; with spikes it lands (an inelastic impact) at step
        // 120, exactly when it reaches the table.
        if k == 0 {
            ball.u[1] = -0.5;
        } else if !ball_landed {
            if inject.spikes && k == 120 {
                ball_y = 0.0;
                ball_landed = true;
                sink.on_event(&Event::ConstraintAdded(change(k, 1, 0)));
            } else {
                ball_y -= 0.5 * DT;
                ball.u[1] = -0.5;
            }
        }
        if inject.spikes {
            // Node 3 of the beam flicks sideways for one step (no force explains it).
            if k == 80 {
                beam.u[6] = 0.3;
            }
            // Node 1 rattles up and down, steps 150-155.
            if (150..=155).contains(&k) {
                beam.u[3] = if k % 2 == 0 { 0.2 } else { -0.2 };
            }
        }
        if ball_landed {
            ball.hold(0);
        }
        ball.q = vec![0.2, ball_y];
        ball.q_pred = ball.q.clone();
        if inject.sticking {
            // Node 4 toggles in and out of contact, steps 60-65 (three times: more than one
            // rebound).
            match k {
                60 | 62 | 64 => {
                    sink.on_event(&Event::ConstraintAdded(change(k, 0, 4)));
                    beam.hold(4);
                }
                61 | 63 | 65 => sink.on_event(&Event::ConstraintReleased(
                    change(k, 0, 4),
                    ReleaseReason::Adhesive,
                )),
                _ => {}
            }
            // Node 5 is held while predictor and corrector disagree, alternately, 100-110.
            if k == 100 {
                sink.on_event(&Event::ConstraintAdded(change(k, 0, 5)));
            }
            if k == 111 {
                sink.on_event(&Event::ConstraintReleased(
                    change(k, 0, 5),
                    ReleaseReason::Adhesive,
                ));
            }
            if (100..=110).contains(&k) {
                beam.hold(5);
                beam.q_pred[11] += if k % 2 == 0 { 1e-6 } else { -1e-6 };
            }
            // Node 0 is held while its reaction pulls it in, 170-172.
            if k == 170 {
                sink.on_event(&Event::ConstraintAdded(change(k, 0, 0)));
            }
            if (170..=172).contains(&k) {
                beam.hold(0);
                beam.reaction[1] = -0.5;
            }
        }
        let states = [beam, ball];
        let obstacles: Vec<Vec<usize>> = states
            .iter()
            .map(|s| {
                s.in_contact
                    .iter()
                    .map(|&c| if c { 0 } else { usize::MAX })
                    .collect()
            })
            .collect();
        let zeros: Vec<Vec<f64>> = states.iter().map(|s| vec![0.0; s.q.len()]).collect();
        let none: Vec<Vec<usize>> = states
            .iter()
            .map(|s| vec![usize::MAX; s.in_contact.len()])
            .collect();
        let impulse: Vec<Vec<f64>> = states
            .iter()
            .map(|s| s.reaction.iter().map(|r| r * DT).collect())
            .collect();
        let gaps: Vec<Vec<f64>> = states
            .iter()
            .map(|s| vec![0.0; s.in_contact.len()])
            .collect();
        let views: Vec<RodStepView> = (0..2)
            .map(|r| RodStepView {
                dim: 2,
                twist_stress: &[],
                frames: None,
                q: &states[r].q,
                u: &states[r].u,
                reaction: &states[r].reaction,
                impulse: &impulse[r],
                drive_force: &zeros[r],
                normal: &states[r].normal,
                contact_obstacle: &obstacles[r],
                normal2: &zeros[r],
                contact_obstacle2: &none[r],
                in_contact: &states[r].in_contact,
                bending_stress: &gaps[r],
                gap: &gaps[r],
                q_predictor: &states[r].q_pred,
            })
            .collect();
        sink.on_event(&Event::StepEnd {
            step: k,
            t: k as f64 * DT,
            dt: if k == 0 { 0.0 } else { DT },
            newton_iterations: 1,
            passes: 0,
            rods: &views,
            bodies: &[],
            contacts: &[],
            joints: &[],
        });
    }
    sink.on_event(&Event::RunEnd {
        steps: STEPS,
        t: STEPS as f64 * DT,
        error: None,
    });
    sink.finish().unwrap();
}

/// `replay check --json` of `path`: (exit status, report).
fn check(path: &Path, extra: &[&str]) -> (i32, Value) {
    let out_json = path.with_extension("check.json");
    let out = gripsim()
        .args(["replay", "check"])
        .arg(path)
        .arg("--json")
        .arg(&out_json)
        .args(extra)
        .output()
        .unwrap();
    let code = out.status.code().unwrap();
    assert!(code == 0 || code == 1 || code == 3, "{}", text(&out));
    (code, json(&out_json))
}

fn spikes(rep: &Value) -> BTreeSet<(String, u64, u64, u64)> {
    rep["spikes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["kind"].as_str().unwrap().to_string(),
                s["rod"].as_u64().unwrap(),
                s["node"].as_u64().unwrap(),
                s["step"].as_u64().unwrap(),
            )
        })
        .collect()
}

fn sticking(rep: &Value) -> BTreeSet<(String, u64, u64, u64, u64)> {
    rep["sticking"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["rule"].as_str().unwrap().to_string(),
                s["rod"].as_u64().unwrap(),
                s["node"].as_u64().unwrap(),
                s["step"].as_u64().unwrap(),
                s["last_step"].as_u64().unwrap(),
            )
        })
        .collect()
}

fn set<T: Ord + Clone>(items: &[T]) -> BTreeSet<T> {
    items.iter().cloned().collect()
}

#[test]
fn known_spikes_and_sticking_are_found_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (clean, spiky, sticky) = (
        d.join("clean.mcap"),
        d.join("spiky.mcap"),
        d.join("sticky.mcap"),
    );
    synthetic(&clean, Inject::default());
    synthetic(
        &spiky,
        Inject {
            spikes: true,
            sticking: false,
        },
    );
    synthetic(
        &sticky,
        Inject {
            spikes: false,
            sticking: true,
        },
    );

    let (code, rep) = check(&clean, &[]);
    assert_eq!(code, 0, "{rep:#}");
    assert_eq!(rep["flagged"], false);
    assert_eq!(rep["counts"]["spikes"], 0);
    assert_eq!(rep["counts"]["sticking"], 0);

    let (code, rep) = check(&spiky, &[]);
    assert_eq!(code, 1);
    let s = |k: &str, r, n, st| (k.to_string(), r, n, st);
    let mut want = vec![
        // The ball's landing: the contact removes its 0.5 m/s approach in one 1e-4 s step.
        s("impact", 1, 0, 120),
        // The flick: out at 80, back at 81.
        s("unexplained", 0, 3, 80),
        s("unexplained", 0, 3, 81),
    ];
    // The rattle: every step of it a jump no force explains.
    want.extend((150..=156).map(|k| s("unexplained", 0, 1, k)));
    assert_eq!(spikes(&rep), set(&want), "{:#}", rep["spikes"]);
    assert_eq!(rep["counts"]["sticking"], 0, "{:#}", rep["sticking"]);
    let impact = rep["spikes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["kind"] == "impact")
        .unwrap();
    assert_eq!(impact["rod_name"], "ball");
    assert!((impact["jump"].as_f64().unwrap() - 0.5).abs() < 1e-12);
    assert!((impact["displacement"].as_f64().unwrap() - 0.5e-4).abs() < 1e-15);
    assert!((impact["t"].as_f64().unwrap() - 0.012).abs() < 1e-12);

    let (code, rep) = check(&sticky, &[]);
    assert_eq!(code, 1);
    assert_eq!(rep["counts"]["spikes"], 0, "{:#}", rep["spikes"]);
    let t = |k: &str, r, n, a, b| (k.to_string(), r, n, a, b);
    // The removed rules (oscillating, adhesive hold) find nothing any more.
    assert_eq!(
        sticking(&rep),
        set(&[t("toggling", 0, 4, 60, 65)]),
        "{:#}",
        rep["sticking"]
    );
    assert_eq!(rep["sticking"][0]["count"], 6);

    // Every threshold is a flag.
    let (code, rep) = check(&spiky, &["--spike-displacement", "1e-4"]);
    assert_eq!(code, 1);
    assert_eq!(
        rep["counts"]["impact"], 0,
        "a 5e-5 m impact is under 1e-4 m"
    );
    assert_eq!(rep["counts"]["unexplained"], 9);
    let (code, rep) = check(&spiky, &["--spike-floor", "1"]);
    assert_eq!((code, rep["counts"]["spikes"].as_u64()), (0, Some(0)));
    let (_, rep) = check(&sticky, &["--stick-toggles", "7"]);
    assert_eq!(rep["counts"]["toggling"], 0);
    let (_, rep) = check(&sticky, &["--stick-window", "3.5e-4"]);
    assert_eq!(
        rep["counts"]["toggling"], 0,
        "5 changes over 5 steps of 1e-4 s need a window over 4e-4 s"
    );
    let (_, rep) = check(&sticky, &["--stick-window", "4.5e-4"]);
    assert_eq!(rep["counts"]["toggling"], 1);
    expect(
        gripsim()
            .args(["replay", "check"])
            .arg(&spiky)
            .args(["--spike-floor", "-1"]),
        2,
    );

    // The human table names the rod, node and step.
    let out = expect(gripsim().args(["replay", "check"]).arg(&spiky), 1);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("impact") && stdout.contains("ball") && stdout.contains("120"),
        "{stdout}"
    );
    assert!(stdout.contains("FLAGGED"), "{stdout}");

    // --rrd marks them for the viewer.
    let rrd = d.join("sticky.rrd");
    expect(
        gripsim()
            .args(["replay", "check"])
            .arg(&sticky)
            .arg("--rrd")
            .arg(&rrd),
        1,
    );
    let out = rerun_rrd("verify", &[&rrd]);
    assert!(out.status.success(), "{}", text(&out));
}

// ---- shipped scenarios ----------------------------------------------------------------------

#[test]
fn the_point_mass_at_dt_1e4_spikes_and_the_proximity_one_does_not() {
    let dir = tempfile::tempdir().unwrap();
    let (coarse, fine) = (dir.path().join("coarse.mcap"), dir.path().join("fine.mcap"));
    // Contact comes at t = 0.101 s; 0.12 s covers it.
    run_to(
        &scenario("point-mass-plane-dt1e-4"),
        &coarse,
        &["solve.t_end=0.12"],
    );
    run_to(
        &scenario("point-mass-plane-proximity"),
        &fine,
        &["solve.t_end=0.12"],
    );
    let (code, rep) = check(&coarse, &[]);
    assert_eq!(code, 1);
    let want = [
        ("impact".to_string(), 0, 0, 1010),
        ("impact".to_string(), 0, 0, 1011),
    ];
    assert_eq!(spikes(&rep), set(&want), "{:#}", rep["spikes"]);
    // The displacements they stand for, 34 and 65 µm: an impact is judged by that, not by
    // its implied acceleration (351 g and 660 g), which no longer gates it.
    let (_, rep50) = check(&coarse, &["--spike-displacement", "5e-5"]);
    let want50 = [("impact".to_string(), 0, 0, 1011)];
    assert_eq!(spikes(&rep50), set(&want50), "{:#}", rep50["spikes"]);
    let (_, rep_a) = check(&coarse, &["--spike-accel-ratio", "1e6"]);
    assert_eq!(spikes(&rep_a), set(&want), "{:#}", rep_a["spikes"]);
    // A resting contact is support, never a spike: at dt = 2e-3 s gravity alone adds
    // 0.0196 m/s per step that the contact cancels, on each of the ~50 steps after landing.
    // With the gates off (any size, any acceleration) only the two landing steps are jumps.
    let big = dir.path().join("big.mcap");
    run_to(
        &scenario("point-mass-plane-dt1e-4"),
        &big,
        &["solve.dt=2e-3"],
    );
    let (_, rep_big) = check(
        &big,
        &["--spike-accel-ratio", "0", "--spike-displacement", "0"],
    );
    assert_eq!(rep_big["counts"]["impact"], 2, "{:#}", rep_big["spikes"]);
    assert_eq!(rep_big["counts"]["spikes"], 2, "{:#}", rep_big["spikes"]);
    let (code, fine_rep) = check(&fine, &[]);
    assert_eq!(code, 0, "{:#}", fine_rep["spikes"]);
    assert!(fine_rep["counts"]["spikes"].as_u64() < rep["counts"]["spikes"].as_u64());
    // The same impact with a 100x smaller step: the jumps are as large, the displacement they
    // stand for 100x smaller.
    let (_, all) = check(&fine, &["--spike-displacement", "0"]);
    assert_eq!(all["counts"]["impact"], 2, "{:#}", all["spikes"]);
    for x in all["spikes"].as_array().unwrap() {
        assert!(x["displacement"].as_f64().unwrap() < 1e-6);
        assert!(x["jump"].as_f64().unwrap() > 0.2);
    }
}

// ---- diff -----------------------------------------------------------------------------------

/// A tilted rod falling flat onto a table: it moves rigidly (E plays no part) until it touches.
const FALLING_ROD: &str = r#"
name = "falling-rod"
description = "A tilted soft rod falling onto a table"

[solve]
mode = "dynamic"
t_end = 0.07
dt = 1e-4
stepping = "fixed"
gravity = [0.0, -9.81]

[[rod]]
name = "rod"
nodes = 8
shape = { kind = "straight", start = [0.0, 0.02], end = [0.1, 0.03] }
E = 1e6
section = { kind = "rect", b = 0.02, h = 0.01 }
density = 1000.0

[[obstacle]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"#;

fn diff(a: &Path, b: &Path, extra: &[&str], code: i32) -> Value {
    let out_json = a.with_extension("diff.json");
    expect(
        gripsim()
            .args(["replay", "diff"])
            .arg(a)
            .arg(b)
            .arg("--json")
            .arg(&out_json)
            .args(extra),
        code,
    );
    json(&out_json)
}

#[test]
fn two_runs_of_one_scenario_diff_empty() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    run_to(&scenario("seed-grasp-r5"), &a, &[]);
    run_to(&scenario("seed-grasp-r5"), &b, &[]);
    let rep = diff(&a, &b, &[], 0);
    assert_eq!(rep["within_tolerance"], true);
    assert_eq!(rep["parameters"], Value::Array(vec![]));
    assert_eq!(rep["first_divergence"], Value::Null);
    assert_eq!(rep["span"]["differs"], false);
    assert_eq!(rep["samples"], 6001);
    assert_eq!(rep["contact_events"], Value::Array(vec![]));
    let c = &rep["contact_event_counts"];
    assert_eq!(c["a"], c["matched"]);
    assert!(c["a"].as_u64().unwrap() >= 3);
    for n in rep["nodes"].as_array().unwrap() {
        assert_eq!(n["position"]["max"], 0.0);
        assert_eq!(n["exceeds"], Value::Array(vec![]));
    }
}

/// Format 4: every step's fingerprint of the exact state finds the first step where two runs
/// differ bit for bit, also when their f32 values agree; an f32 and an f64 recording of one
/// run are the same run; a format 3 file (no fingerprints) is compared on values alone.
#[test]
fn diff_finds_the_first_bitwise_divergence_from_the_fingerprints() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scenario("seed-grasp-r5");
    let (a, a64, b) = (d.join("a.mcap"), d.join("a64.mcap"), d.join("b.mcap"));
    run_to(&sc, &a, &["solve.t_end=0.002"]);
    run_to(&sc, &a64, &["solve.t_end=0.002", "output.precision=f64"]);
    // Gravity one double ulp stronger: different bits from step 1, far below f32.
    run_to(
        &sc,
        &b,
        &[
            "solve.t_end=0.002",
            "solve.gravity=[0.0,-9.800000000000002]",
        ],
    );
    let rep = diff(&a, &a64, &[], 0);
    assert_eq!(rep["fingerprints"], true);
    assert_eq!(rep["first_bitwise_divergence"], Value::Null, "{rep:#}");
    assert_eq!(rep["first_divergence"], Value::Null);
    // The f32 rounding of A is within its resolution: no node over tolerance.
    assert!(rep["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .all(|n| n["exceeds"] == Value::Array(vec![])));
    let rep = diff(&a, &b, &[], 0);
    assert_eq!(rep["within_tolerance"], true);
    let first = &rep["first_bitwise_divergence"];
    assert_eq!(first["step"], 1, "{first:#}");
    assert_eq!(first["what"], "state");
    assert_eq!(first["below_f32_resolution"], true);
    let out = gripsim()
        .args(["replay", "diff"])
        .arg(&a)
        .arg(&b)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stdout)
        .contains("first bitwise    step 1 (t = 1.000e-5 s): the exact states differ (fingerprints), below the recording's f32 resolution"));
    // A golden file of format 3 has no fingerprints.
    let golden = Path::new(ROOT).join("recordings/golden/point-mass-plane-dt1e-4.mcap");
    let now = d.join("plane.mcap");
    run_to(
        &Path::new(ROOT).join("recordings/golden/point-mass-plane-dt1e-4.toml"),
        &now,
        &["solve.t_end=0.12"],
    );
    // (The report is written beside the first file: the new one, not the golden.)
    let rep = diff(&now, &golden, &[], 0);
    assert_eq!(rep["fingerprints"], false);
    assert_eq!(rep["first_bitwise_divergence"], Value::Null);
    assert_eq!(rep["within_tolerance"], true, "{rep:#}");
}

#[test]
fn a_stiffer_rod_diverges_at_the_first_contact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = d.join("falling-rod.toml");
    std::fs::write(&sc, FALLING_ROD).unwrap();
    let (a, b) = (d.join("a.mcap"), d.join("b.mcap"));
    let summary = d.join("a.json");
    expect(
        gripsim()
            .arg("run")
            .arg(&sc)
            .args(["-q", "--detail", "step", "--mcap"])
            .arg(&a)
            .arg("--summary")
            .arg(&summary),
        0,
    );
    run_to(&sc, &b, &["rod.0.E=2e6"]);
    let rep = diff(&a, &b, &[], 1);
    assert_eq!(rep["within_tolerance"], false);
    // Scenario differences come first, by dotted path.
    assert_eq!(
        rep["parameters"],
        serde_json::json!([{"key": "rod.0.E", "a": 1e6, "b": 2e6}])
    );
    let onset = json(&summary)["contact_onset_time_s"].as_f64().unwrap();
    let first = &rep["first_divergence"];
    let t = first["t"].as_f64().unwrap();
    assert!(
        (t - onset).abs() <= 1e-4 + 1e-12,
        "first divergence at {t} s, first contact at {onset} s: {first:#}"
    );
    assert_eq!(first["rod_name"], "rod");
    assert!(["position", "velocity", "reaction"].contains(&first["quantity"].as_str().unwrap()));
    // Before the contact nothing differs: no node's largest difference is earlier.
    for n in rep["nodes"].as_array().unwrap() {
        for q in ["position", "velocity", "reaction"] {
            if n[q]["max"].as_f64().unwrap() > 0.0 {
                assert!(n[q]["t"].as_f64().unwrap() >= onset - 1e-12, "{n:#}");
            }
        }
    }
    // The human report lists the parameter first.
    let out = expect(gripsim().args(["replay", "diff"]).arg(&a).arg(&b), 1);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let p = stdout.find("rod.0.E").expect("parameter listed");
    let f = stdout.find("first divergence").expect("divergence listed");
    assert!(p < f, "{stdout}");
    assert!(stdout.contains("DIFFERENT"));

    // The overlay: A and B on one set of timelines, B ghosted, the divergence marked.
    let rrd = d.join("diff.rrd");
    expect(
        gripsim()
            .args(["replay", "diff"])
            .arg(&a)
            .arg(&b)
            .arg("--rrd")
            .arg(&rrd),
        1,
    );
    let out = rerun_rrd("verify", &[&rrd]);
    assert!(out.status.success(), "{}", text(&out));
    let out = rerun_rrd("stats", &[&rrd]);
    let stats = String::from_utf8_lossy(&out.stdout);
    for entity in [
        "/scene/rod/nodes",
        "/scene/run_b/rod/nodes",
        "/scene/run_b/rod/centerline",
        "/scene/divergence",
        "/diff/position/rod",
    ] {
        assert!(stats.contains(entity), "{entity} missing:\n{stats}");
    }
}

#[test]
fn runs_with_different_steps_are_compared_at_the_same_times() {
    // A particle coasting at constant velocity: exact at any step, so two step sizes whose
    // step times interleave agree once interpolated.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = d.join("coast.toml");
    std::fs::write(
        &sc,
        r#"
name = "coast"
[solve]
mode = "dynamic"
t_end = 0.021
dt = 1e-3
stepping = "fixed"
gravity = [0.0, 0.0]
[[particle]]
name = "puck"
position = [0.0, 0.0]
velocity = [0.5, 0.25]
mass = 0.01
"#,
    )
    .unwrap();
    let (a, b) = (d.join("a.mcap"), d.join("b.mcap"));
    // Exact doubles: the interpolation is checked to 1e-12 below (f32 would round at ~1e-9).
    run_to(&sc, &a, &["output.precision=f64"]);
    run_to(&sc, &b, &["solve.dt=7e-4", "output.precision=f64"]);
    let rep = diff(&a, &b, &[], 0);
    assert_eq!(
        rep["parameters"],
        serde_json::json!([{"key": "solve.dt", "a": 1e-3, "b": 7e-4}])
    );
    // The union of A's 22 step times and B's 31 (a few coincide).
    let samples = rep["samples"].as_u64().unwrap();
    assert!((32..=53).contains(&samples), "{samples} samples");
    assert!(rep["nodes"][0]["position"]["max"].as_f64().unwrap() < 1e-12);
    assert!(rep["nodes"][0]["velocity"]["max"].as_f64().unwrap() < 1e-12);
    // A puck that is 1 mm/s faster in B: out of tolerance from the first step on.
    let c = d.join("c.mcap");
    run_to(
        &sc,
        &c,
        &[
            "solve.dt=7e-4",
            "particle.0.velocity=[0.501, 0.25]",
            "output.precision=f64",
        ],
    );
    let rep = diff(&a, &c, &[], 1);
    let first = &rep["first_divergence"];
    assert_eq!(first["quantity"], "velocity", "{first:#}");
    assert!(first["t"].as_f64().unwrap() <= 7e-4 + 1e-15, "{first:#}");
    let du = rep["nodes"][0]["velocity"]["max"].as_f64().unwrap();
    assert!((du - 1e-3).abs() < 1e-9, "{du}");
}

#[test]
fn runs_that_cannot_be_compared_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two) = (dir.path().join("one.mcap"), dir.path().join("two.mcap"));
    run_to(&scenario("seed-grasp-r5"), &one, &["solve.t_end=0.001"]);
    run_to(&scenario("two-prong-grasp"), &two, &["solve.t_end=0.001"]);
    let out = expect(gripsim().args(["replay", "diff"]).arg(&one).arg(&two), 2);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cannot compare"), "{err}");
    assert!(
        err.contains("1 rod(s)") && err.contains("2 rod(s)"),
        "{err}"
    );
    assert!(err.contains("10 node(s)"), "{err}");
}

// ---- show -----------------------------------------------------------------------------------

#[test]
fn show_gives_the_rrd_of_a_live_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (live, mcap, shown) = (d.join("live.rrd"), d.join("run.mcap"), d.join("shown.rrd"));
    expect(
        gripsim()
            .arg("run")
            .arg(scenario("seed-grasp-r5"))
            .args([
                "-q",
                "--set",
                "solve.t_end=0.042",
                "--detail",
                "iteration",
                // The MCAP with exact doubles: `rerun rrd compare` below wants the same data
                // (an f32 recording shows f32-rounded values).
                "--precision",
                "f64",
                "--rrd",
            ])
            .arg(&live)
            .arg("--mcap")
            .arg(&mcap),
        0,
    );
    let out = expect(
        gripsim()
            .args(["replay", "show"])
            .arg(&mcap)
            .arg("--rrd")
            .arg(&shown),
        0,
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("4201 steps"));
    let out = rerun_rrd("verify", &[&shown]);
    assert!(out.status.success(), "{}", text(&out));
    // Same entities, timelines, data and chunks as the live recording. Unordered: chunks
    // closed at the same flush may reach the file in either order (the SDK's batcher splits
    // an entity's rows of several schemas into chunks, and which goes out first varies).
    let out = rerun_rrd("compare", &[&live, &shown, Path::new("--unordered")]);
    assert!(out.status.success(), "rerun rrd compare: {}", text(&out));
}

// ---- bad and cut-short input ----------------------------------------------------------------

/// An MCAP written with the mcap crate: `channels` as (topic, schema), one message each.
fn handmade(path: &Path, channels: &[(&str, &str)], meta: &str, version: &str) {
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    w.write_metadata(&mcap::records::Metadata {
        name: "gripsim".into(),
        metadata: [("format_version".to_string(), version.to_string())].into(),
    })
    .unwrap();
    for (topic, schema) in channels {
        let sid = w.add_schema(schema, "jsonschema", b"{}").unwrap();
        let cid = w
            .add_channel(sid, topic, "json", &Default::default())
            .unwrap();
        let body: &[u8] = if *topic == "/sim/meta" {
            meta.as_bytes()
        } else {
            b"{}"
        };
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: cid,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
            },
            body,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = d.join("good.mcap");
    run_to(
        &scenario("point-mass-plane-dt1e-4"),
        &good,
        &["solve.t_end=0.01"],
    );
    let meta = {
        // The real /sim/meta text, for files that are wrong elsewhere.
        let bytes = std::fs::read(&good).unwrap();
        let m = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .find(|m| m.channel.topic == "/sim/meta")
            .unwrap();
        String::from_utf8(m.data.to_vec()).unwrap()
    };

    let text_file = d.join("notes.mcap");
    std::fs::write(&text_file, "these are my notes, not a recording\n").unwrap();
    let garbage = d.join("garbage.mcap");
    std::fs::write(&garbage, &std::fs::read(&good).unwrap()[..300]).unwrap();
    let empty = d.join("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    let wrong_schema = d.join("wrong-schema.mcap");
    handmade(
        &wrong_schema,
        &[
            ("/sim/meta", "gripsim.Meta"),
            ("/sim/step", "foxglove.PointCloud"),
        ],
        &meta,
        "1",
    );
    let newer = d.join("newer.mcap");
    let version = format!(
        "\"format_version\":{}",
        gripsim::record::mcap::FORMAT_VERSION
    );
    let newer_meta = meta.replacen(&version, "\"format_version\":99", 1);
    assert_ne!(newer_meta, meta);
    handmade(&newer, &[("/sim/meta", "gripsim.Meta")], &newer_meta, "99");
    let missing = d.join("missing.mcap");
    handmade(&missing, &[("/sim/meta", "gripsim.Meta")], &meta, "1");
    let bad_step = d.join("bad-step.mcap");
    handmade(
        &bad_step,
        &[
            ("/sim/meta", "gripsim.Meta"),
            ("/sim/step", "gripsim.Step"),
            ("/sim/contact", "gripsim.Contact"),
            ("/sim/event", "gripsim.Event"),
        ],
        &meta,
        "1",
    );
    let absent = d.join("no-such-file.mcap");

    let cases: [(&Path, &str); 8] = [
        (&text_file, "not an MCAP file"),
        (&garbage, "stop before the first /sim/step"),
        (&empty, "not an MCAP file"),
        (&wrong_schema, "wrong schema on /sim/step"),
        (&newer, "format version 99"),
        (&missing, "missing channel /sim/step"),
        (&bad_step, "does not match schema gripsim.Step"),
        (&absent, "cannot read the file"),
    ];
    for (file, why) in cases {
        let name = file.display().to_string();
        for args in [
            vec!["check".to_string(), name.clone()],
            vec!["diff".to_string(), good.display().to_string(), name.clone()],
            vec![
                "show".to_string(),
                name.clone(),
                "--rrd".to_string(),
                d.join("out.rrd").display().to_string(),
            ],
        ] {
            let out = expect(gripsim().arg("replay").args(&args), 2);
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(
                err.contains(&name) && err.contains(why),
                "replay {args:?}: expected {why:?} naming the file, got:\n{err}"
            );
            // No .rrd, whole or half written, is left for a refused input.
            for left in ["out.rrd", "out.partial.rrd"] {
                assert!(!d.join(left).exists(), "replay {args:?} left {left}");
            }
        }
    }
}

#[test]
fn a_file_cut_short_is_read_to_its_last_complete_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.mcap");
    expect(
        gripsim()
            .arg("run")
            .arg(scenario("point-mass-plane-dt1e-4"))
            .args([
                "-q",
                "--detail",
                "step",
                "--set",
                "solve.t_end=0.12",
                "--flush-every",
                "50",
                "--mcap",
            ])
            .arg(&whole),
        0,
    );
    // What SIGKILL leaves: no summary, no footer, the last chunk half written.
    let bytes = std::fs::read(&whole).unwrap();
    let cut = d.join("cut.partial.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();

    // An incomplete recording is no pass: its own exit status, unless asked.
    let (code, rep) = check(&cut, &[]);
    assert_eq!(code, 3, "{rep:#}");
    assert_eq!(rep["incomplete"], true);
    let (code, _) = check(&cut, &["--allow-partial"]);
    assert_eq!(code, 0, "cut before the drop lands");
    assert!(rep["truncated"].is_string(), "{rep:#}");
    let steps = rep["steps"].as_u64().unwrap();
    assert!(steps > 300 && steps < 1201, "{steps} steps read");
    assert_eq!(steps % 50, 1, "whole chunks of 50 steps (plus step 0)");
    assert_eq!(rep["completed"], Value::Null);
    let out = gripsim()
        .args(["replay", "check"])
        .arg(&cut)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning")
            && err.contains("incomplete")
            && err.contains(&cut.display().to_string()),
        "{err}"
    );

    // Against the whole run: the same up to the cut, but it ends early.
    diff(&whole, &cut, &[], 3);
    let rep = diff(&whole, &cut, &["--allow-partial"], 1);
    assert_eq!(rep["span"]["differs"], true);
    assert_eq!(rep["first_divergence"], Value::Null);

    // show writes a complete .rrd of what is there.
    let rrd = d.join("cut.rrd");
    let out = expect(
        gripsim()
            .args(["replay", "show"])
            .arg(&cut)
            .arg("--rrd")
            .arg(&rrd),
        0,
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("incomplete"));
    let out = rerun_rrd("verify", &[&rrd]);
    assert!(out.status.success(), "{}", text(&out));
}

// ---- the README's CI example ----------------------------------------------------------------

const GOLDEN: &str = "recordings/golden/point-mass-plane-dt1e-4.mcap";
const REGENERATE: &str = "the commands under \"regenerate the golden files\" in README.md";

#[test]
fn the_readme_ci_example_passes_against_the_golden_recording() {
    let golden = Path::new(ROOT).join(GOLDEN);
    assert!(
        golden.exists(),
        "{GOLDEN} is missing; make it with:\n  {REGENERATE}"
    );
    let size = std::fs::metadata(&golden).unwrap().len();
    assert!(size < 1_000_000, "{GOLDEN} is {size} bytes: keep it small");
    // The example as README.md shows it (its commands, run from the repository root).
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let section = readme
        .split("## Guarding CI against spike regressions")
        .nth(1)
        .expect("README has the CI section");
    let block = section
        .split("```sh")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("the section has a sh block");
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().display().to_string();
    let commands: Vec<String> = block
        .lines()
        .map(|l| l.split(" #").next().unwrap().trim())
        .filter(|l| l.starts_with("gripsim "))
        .map(|l| l.replace("out/ci", &out_dir))
        .collect();
    assert_eq!(commands.len(), 16, "{block}");
    for c in &commands {
        let args: Vec<&str> = c.split_whitespace().skip(1).collect();
        let out = gripsim().args(&args).output().unwrap();
        let code = out.status.code();
        if c.contains("replay diff") && code == Some(1) {
            panic!(
                "the run differs from the golden recording {GOLDEN}:\n{}\n\nIf the change in \
                 the physics is intended, regenerate the golden file (from the repository root):\n  \
                 {REGENERATE}\nand commit it.",
                String::from_utf8_lossy(&out.stdout)
            );
        }
        assert_eq!(code, Some(0), "`{c}` failed:\n{}", text(&out));
    }
}
