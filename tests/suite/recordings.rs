//! Recordings: the `.rrd`, `.mcap` and `.csv` that `gripsim run` writes, read back by
//! independent readers (the Rerun CLI and the `mcap` Python package, installed into `.venv`
//! by tests/py/setup_venv.py) and by the `mcap` crate.

use crate::common::{gripsim, message_json, run_ok, scenario, venv, ROOT};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `rerun rrd <args>` from the test venv.
fn rerun_rrd(args: &[&Path], sub: &str) -> Output {
    Command::new(venv().join("bin/rerun"))
        .arg("rrd")
        .arg(sub)
        .args(args)
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the rerun CLI runs")
}

fn assert_rrd_verifies(path: &Path) {
    let out = rerun_rrd(&[path], "verify");
    assert!(
        out.status.success(),
        "rerun rrd verify {} failed:\n{}{}",
        path.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The report of tests/py/read_mcap.py (the `mcap` Python package, CRCs validated).
pub(crate) fn read_mcap_py(path: &Path) -> Value {
    let out = Command::new(venv().join("bin/python"))
        .arg(Path::new(ROOT).join("tests/py/read_mcap.py"))
        .arg(path)
        .output()
        .expect("the venv's python runs");
    assert!(
        out.status.success(),
        "read_mcap.py {} failed:\n{}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("read_mcap.py prints JSON")
}

/// One decoded message.
struct Msg {
    topic: String,
    log_time: u64,
    json: Value,
}

/// Every message the `mcap` crate reads (with chunk CRCs checked) up to the end, or up to
/// where a file cut short stops; the error is returned alongside.
fn read_mcap_rust(path: &Path) -> (Vec<Msg>, Option<String>) {
    let bytes = std::fs::read(path).unwrap();
    let stream = mcap::MessageStream::new_with_options(
        &bytes,
        mcap::read::Options::ValidateChunkCrcs.into(),
    )
    .expect("an MCAP header");
    let mut msgs = Vec::new();
    for m in stream {
        match m {
            Ok(m) => msgs.push(Msg {
                topic: m.channel.topic.clone(),
                log_time: m.log_time,
                json: message_json(&m),
            }),
            Err(e) => return (msgs, Some(e.to_string())),
        }
    }
    (msgs, None)
}

const CHANNELS: [(&str, &str); 7] = [
    ("/sim/meta", "gripsim.Meta"),
    ("/sim/step", "gripsim.Step"),
    ("/sim/iteration", "gripsim.Iteration"),
    ("/sim/contact", "gripsim.Contact"),
    ("/sim/event", "gripsim.Event"),
    ("/scene", "foxglove.SceneUpdate"),
    ("/scene/nodes", "foxglove.PointCloud"),
];

/// The channels and their schemas; `f64`: a run at `--precision f64` (`gripsim.Step64`,
/// `gripsim.Iteration64`).
fn assert_channels(report: &Value, f64: bool) {
    for (topic, schema) in CHANNELS {
        let t = &report["topics"][topic];
        let schema = match (topic, f64) {
            ("/sim/step" | "/sim/iteration", true) => format!("{schema}64"),
            _ => schema.to_string(),
        };
        if topic == "/sim/iteration" && t.is_null() {
            continue; // step detail: the channel is declared, its messages absent
        }
        assert_eq!(t["schema"], schema.as_str(), "{topic}: {t}");
        // The high-rate channels and the scene are protobuf with the schema in the file, the
        // rest JSON.
        let binary = ["/sim/step", "/sim/iteration", "/scene", "/scene/nodes"].contains(&topic);
        let (schema_encoding, message_encoding) = if binary {
            ("protobuf", "protobuf")
        } else {
            ("jsonschema", "json")
        };
        assert_eq!(t["schema_encoding"], schema_encoding, "{topic}");
        assert_eq!(t["message_encoding"], message_encoding, "{topic}");
    }
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// A scenario that runs as long as we like: a soft cantilever drooping onto a table.
fn long_scenario(dir: &Path) -> PathBuf {
    let p = dir.join("long-droop.toml");
    std::fs::write(
        &p,
        r#"name = "long-droop"
description = "A soft cantilever drooping onto a table, for runs that are stopped"

[solve]
mode = "dynamic"
t_end = 1000.0
dt = 1e-3
stepping = "fixed"
gravity = [0.0, -9.81]

[[rod]]
name = "beam"
nodes = 12
shape = { kind = "straight", start = [0.0, 0.0], end = [0.1, 0.0] }
E = 1e6
section = { kind = "rect", b = 0.02, h = 0.01 }
density = 1000.0
clamped = [0, 1]

[[obstacle]]
kind = "plane"
point = [0.0, -0.02]
normal = [0.0, 1.0]
"#,
    )
    .unwrap();
    p
}

/// Wait until `path` holds at least `bytes` bytes.
fn wait_for_size(path: &Path, bytes: u64, child: &mut std::process::Child) {
    let start = Instant::now();
    loop {
        if std::fs::metadata(path).map(|m| m.len()).unwrap_or(0) >= bytes {
            return;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before {} grew", path.display());
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{} did not grow",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn seed_grasp_recordings_agree_with_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (rrd, mcap, csv, summary) = (
        d.join("r5.rrd"),
        d.join("r5.mcap"),
        d.join("r5.csv"),
        d.join("r5.json"),
    );
    let out = run_ok(
        gripsim()
            .arg("run")
            .arg(scenario("seed-grasp-r5"))
            // Exact doubles in /sim/step: the numbers below are compared bit for bit with the
            // summary and the CSV (the default f32 file: f32_recording_* below).
            .args(["--precision", "f64", "--detail", "iteration", "--rrd"])
            .arg(&rrd)
            .arg("--mcap")
            .arg(&mcap)
            .arg("--csv")
            .arg(&csv)
            .arg("--summary")
            .arg(&summary),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(&format!("rerun {}", rrd.display())),
        "the run says how to open the .rrd:\n{stdout}"
    );
    assert!(stdout.contains(&mcap.display().to_string()) && stdout.contains("Foxglove"));
    for p in [&rrd, &mcap, &csv] {
        assert!(p.exists(), "{} is there", p.display());
    }
    let summary: Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    let steps = summary["steps"].as_u64().unwrap();
    let newton = summary["newton_iterations"].as_u64().unwrap();
    let peak = f64s(&summary["rods"][0]["peak_reaction_per_node_n"]);
    assert!(peak.iter().any(|&f| f > 100.0), "the grasp has an impact");

    // Independent readers.
    assert_rrd_verifies(&rrd);
    let report = read_mcap_py(&mcap);
    assert_eq!(report["error"], Value::Null, "{report}");
    assert_channels(&report, true);
    // Every step's fingerprint, recomputed in Python from the exact doubles, matches.
    assert_eq!(report["fingerprints"]["steps"], steps + 1);
    assert_eq!(report["fingerprints"]["matched"], steps + 1);
    assert_eq!(report["summary"]["footer"], true);
    assert_eq!(report["summary"]["statistics"], true);
    assert_eq!(
        report["summary"]["indexed_messages"],
        report["summary"]["message_count"]
    );
    assert_eq!(report["log_time_monotone"], true);
    assert!(report["validated"].as_u64().unwrap() > 100);
    assert_eq!(report["topics"]["/sim/step"]["messages"], steps + 1);
    assert_eq!(report["topics"]["/scene"]["messages"], steps + 1);
    assert_eq!(report["topics"]["/scene/nodes"]["messages"], steps + 1);
    // Obstacles and legend once, not in every /scene message.
    assert_eq!(report["topics"]["/scene/static"]["messages"], 1);
    assert_eq!(
        report["topics"]["/scene/static"]["schema"],
        "foxglove.SceneUpdate"
    );
    assert_eq!(report["topics"]["/sim/iteration"]["messages"], newton);
    assert_eq!(report["topics"]["/sim/meta"]["messages"], 1);
    assert_eq!(report["last_event"]["kind"], "run_end");
    assert_eq!(report["last_event"]["completed"], true);
    assert_eq!(report["metadata"]["gripsim.run_end"]["completed"], "true");

    // The mcap crate: every message, in order.
    let (msgs, err) = read_mcap_rust(&mcap);
    assert_eq!(err, None);
    let summary_rec = mcap::Summary::read(&std::fs::read(&mcap).unwrap())
        .unwrap()
        .expect("a summary section");
    assert_eq!(summary_rec.stats.unwrap().message_count, msgs.len() as u64);
    assert!(msgs.windows(2).all(|w| w[0].log_time <= w[1].log_time));
    let count = |topic: &str| msgs.iter().filter(|m| m.topic == topic).count() as u64;
    assert_eq!(count("/sim/iteration"), newton);

    let mut mcap_peak = vec![0.0f64; peak.len()];
    let mut contacts_seen = 0;
    for m in &msgs {
        match m.topic.as_str() {
            "/sim/step" => {
                let rod = &m.json["rods"][0];
                let (r, n) = (f64s(&rod["reaction"]), f64s(&rod["normal"]));
                let norm = f64s(&rod["reaction_norm"]);
                for (i, c) in rod["in_contact"].as_array().unwrap().iter().enumerate() {
                    let f = r[2 * i].hypot(r[2 * i + 1]);
                    assert_eq!(norm[i], f);
                    mcap_peak[i] = mcap_peak[i].max(f);
                    if c.as_bool().unwrap() {
                        contacts_seen += 1;
                        let len = n[2 * i].hypot(n[2 * i + 1]);
                        assert!((len - 1.0).abs() < 1e-12, "normal of length {len}");
                    }
                }
            }
            "/sim/contact" => {
                let n = f64s(&m.json["normal"]);
                assert!((n[0].hypot(n[1]) - 1.0).abs() < 1e-12, "{}", m.json);
            }
            "/sim/iteration" => {
                assert!(["predictor", "corrector"].contains(&m.json["phase"].as_str().unwrap()));
            }
            _ => {}
        }
    }
    assert!(contacts_seen > 100);
    assert_eq!(mcap_peak, peak, "peak reaction per node: MCAP vs --summary");

    // Google's protobuf library (Python), from the schema in the file, reads the same numbers
    // as gripsim's own decoder, bit for bit.
    let samples = report["step_samples"].as_array().unwrap();
    assert!(samples.len() > 20, "{} samples", samples.len());
    let steps_json: BTreeMap<u64, &Value> = msgs
        .iter()
        .filter(|m| m.topic == "/sim/step")
        .map(|m| (m.json["step"].as_u64().unwrap(), &m.json))
        .collect();
    let mut contact_samples = 0;
    for s in samples {
        let ours = steps_json[&s["step"].as_u64().unwrap()];
        for key in ["t", "dt"] {
            assert_eq!(
                s[key].as_f64(),
                ours[key].as_f64(),
                "{key} of {}",
                s["step"]
            );
        }
        let (theirs, ours) = (&s["rods"][0], &ours["rods"][0]);
        for key in ["q", "reaction_norm", "in_contact", "gap"] {
            assert_eq!(theirs[key], ours[key], "{key} at step {}", s["step"]);
        }
        contact_samples += theirs["in_contact"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c == true) as usize;
    }
    assert!(contact_samples > 0, "a sample in contact");

    // The protobuf /scene, as Google's library decodes it: the prong's centre line at the
    // step's positions (rounded to f32), the predictor's spheres on corrected steps, a red and
    // a white arrow and a label per pressed node on steps in contact, the obstacles and
    // legend once on /scene/static; the nodes as the /scene/nodes point cloud.
    let statics = report["scene_static"].as_array().unwrap();
    let ids: Vec<&str> = statics.iter().map(|e| e["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["obstacles", "legend"]);
    assert!(statics[0]["lines"].as_u64().unwrap() >= 1);
    let scenes = report["scene_samples"].as_array().unwrap();
    assert_eq!(scenes.len(), samples.len());
    let nodes_at: BTreeMap<u64, &Value> = report["node_samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| (n["index"].as_u64().unwrap(), n))
        .collect();
    assert_eq!(nodes_at.len(), samples.len());
    let mut labelled = 0;
    for sc in scenes {
        let step = sc["index"].as_u64().unwrap();
        let rod = &steps_json[&step]["rods"][0];
        let q = f64s(&rod["q"]);
        let want: Vec<Vec<f64>> = q
            .chunks(2)
            .map(|p| vec![p[0] as f32 as f64, p[1] as f32 as f64, 0.0])
            .collect();
        let e = &sc["entities"][0];
        assert_eq!(e["id"], "rod/prong");
        let line: Vec<Vec<f64>> = e["line_points"]
            .as_array()
            .unwrap()
            .iter()
            .map(f64s)
            .collect();
        assert_eq!(line, want, "centre line at step {step}");
        let spheres = e["spheres"].as_array().unwrap().len();
        let corrected = !steps_json[&step]["rods"][0]["q_predictor"]
            .as_array()
            .unwrap()
            .is_empty();
        assert_eq!(spheres, if corrected { want.len() } else { 0 }, "{step}");
        let cloud = nodes_at
            .get(&step)
            .expect("a /scene/nodes sample per /scene one");
        assert_eq!(cloud["frame_id"], "world");
        assert_eq!(cloud["stride"], 16);
        let points: Vec<Vec<f64>> = cloud["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                vec![
                    p["x"].as_f64().unwrap(),
                    p["y"].as_f64().unwrap(),
                    p["z"].as_f64().unwrap(),
                ]
            })
            .collect();
        assert_eq!(points, want, "node points at step {step}");
        assert!(cloud["points"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| p["alpha"] == 255));
        let pressed = f64s(&rod["reaction_norm"])
            .iter()
            .filter(|&&f| f > 0.0)
            .count();
        let touching = rod["in_contact"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|c| *c == true)
            .count();
        assert_eq!(e["arrows"].as_u64().unwrap() as usize, pressed + touching);
        let texts = e["texts"].as_array().unwrap();
        assert_eq!(texts.len(), pressed);
        assert!(texts.iter().all(|t| t.as_str().unwrap().ends_with(" N")));
        labelled += texts.len();
    }
    assert!(labelled > 0, "a sampled scene with reaction labels");

    // The CSV: header, one row per step and node, the same peaks.
    let mut rdr = csv::Reader::from_path(&csv).unwrap();
    let header: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(
        header,
        [
            "step",
            "t",
            "rod",
            "node",
            "x",
            "y",
            "vx",
            "vy",
            "rx",
            "ry",
            "reaction",
            "impulse",
            "in_contact",
            "bending_stress",
            "nx",
            "ny",
            "gap",
            "dt",
            "passes",
            "indentation",
            "half_width",
            "peak_pressure",
            "bruise_half_width",
            "obstacle"
        ]
    );
    let mut csv_peak = vec![0.0f64; peak.len()];
    let mut rows = 0u64;
    for rec in rdr.records() {
        let rec = rec.unwrap();
        let node: usize = rec[3].parse().unwrap();
        let f: f64 = rec[10].parse().unwrap();
        let (rx, ry): (f64, f64) = (rec[8].parse().unwrap(), rec[9].parse().unwrap());
        assert_eq!(f, rx.hypot(ry));
        csv_peak[node] = csv_peak[node].max(f);
        rows += 1;
    }
    assert_eq!(rows, (steps + 1) * peak.len() as u64);
    assert_eq!(csv_peak, peak, "peak reaction per node: CSV vs --summary");

    // The MCAP alone rebuilds the run: its scenario text runs to the same summary.
    let meta = &msgs.iter().find(|m| m.topic == "/sim/meta").unwrap().json;
    assert_eq!(meta["format_version"], 4);
    assert_eq!(meta["precision"], "f64");
    let replay = d.join("replay.toml");
    std::fs::write(&replay, meta["scenario_text"].as_str().unwrap()).unwrap();
    let again = d.join("again.json");
    run_ok(
        gripsim()
            .arg("run")
            .arg(&replay)
            .args(["--no-record", "-q", "--summary"])
            .arg(&again),
    );
    let again: Value = serde_json::from_slice(&std::fs::read(&again).unwrap()).unwrap();
    assert_eq!(f64s(&again["rods"][0]["peak_reaction_per_node_n"]), peak);
    assert_eq!(
        again["rods"][0]["final_positions"],
        summary["rods"][0]["final_positions"]
    );
}

#[test]
fn two_runs_give_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |tag: &str| {
        run_ok(
            gripsim()
                .arg("run")
                .arg(scenario("seed-grasp-r5"))
                .args([
                    "--set",
                    "solve.t_end=0.045",
                    "--flush-every",
                    "250",
                    "-q",
                    "--detail",
                    "step",
                ])
                .arg("--mcap")
                .arg(d.join(format!("{tag}.mcap")))
                .arg("--csv")
                .arg(d.join(format!("{tag}.csv")))
                .arg("--rrd")
                .arg(d.join(format!("{tag}.rrd"))),
        );
    };
    run("a");
    run("b");
    for ext in ["mcap", "csv"] {
        let a = std::fs::read(d.join(format!("a.{ext}"))).unwrap();
        let b = std::fs::read(d.join(format!("b.{ext}"))).unwrap();
        assert!(a.len() > 10_000);
        assert!(a == b, "the two .{ext} files differ");
    }
    // Rerun row ids and the blueprint's ids are random, but the data are the same (in chunks
    // that may reach the file in another order within a flush: compared unordered).
    let out = rerun_rrd(
        &[&d.join("a.rrd"), &d.join("b.rrd"), Path::new("--unordered")],
        "compare",
    );
    assert!(
        out.status.success(),
        "rerun rrd compare: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn default_recordings_and_no_record() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = run_ok(
        gripsim()
            .current_dir(d)
            .arg("run")
            .arg(scenario("seed-grasp-r5"))
            .args(["--set", "solve.t_end=0.002"]),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let rec = d.join("recordings");
    let mut names: Vec<String> = std::fs::read_dir(&rec)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    names.sort();
    assert_eq!(names, ["seed-grasp-r5.mcap", "seed-grasp-r5.rrd"]);
    assert!(
        stdout.contains("rerun recordings/seed-grasp-r5.rrd"),
        "{stdout}"
    );
    assert!(stdout.contains("recordings/seed-grasp-r5.mcap"), "{stdout}");

    // --no-record writes nothing; it cannot be combined with an output.
    let d2 = d.join("quiet");
    std::fs::create_dir(&d2).unwrap();
    run_ok(
        gripsim()
            .current_dir(&d2)
            .arg("run")
            .arg(scenario("seed-grasp-r5"))
            .args(["--set", "solve.t_end=0.002", "--no-record"]),
    );
    assert_eq!(std::fs::read_dir(&d2).unwrap().count(), 0);
    let clash = gripsim()
        .arg("run")
        .arg(scenario("seed-grasp-r5"))
        .args(["--no-record", "--csv", "x.csv"])
        .output()
        .unwrap();
    assert!(!clash.status.success());
}

#[test]
fn static_runs_log_time_by_load_step() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("static.mcap");
    run_ok(
        gripsim()
            .arg("run")
            .arg(scenario("cantilever-tip-load"))
            .args(["-q", "--detail", "iteration", "--mcap"])
            .arg(&mcap),
    );
    let (msgs, err) = read_mcap_rust(&mcap);
    assert_eq!(err, None);
    let meta = &msgs[0].json;
    assert_eq!(meta["mode"], "static");
    assert_eq!(meta["clock"], "load_step");
    assert!(msgs.windows(2).all(|w| w[0].log_time <= w[1].log_time));
    let steps: Vec<&Msg> = msgs.iter().filter(|m| m.topic == "/sim/step").collect();
    assert!(steps.len() > 2);
    for m in &steps {
        assert_eq!(m.log_time, m.json["step"].as_u64().unwrap() * 1_000_000_000);
    }
    let phases: BTreeMap<String, usize> =
        msgs.iter()
            .filter(|m| m.topic == "/sim/iteration")
            .fold(BTreeMap::new(), |mut acc, m| {
                *acc.entry(m.json["phase"].as_str().unwrap().to_string())
                    .or_default() += 1;
                acc
            });
    assert!(phases.contains_key("static"), "{phases:?}");
}

#[test]
fn sigkill_leaves_files_readable_up_to_the_last_flush() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = long_scenario(d);
    let (mcap, rrd) = (d.join("long.mcap"), d.join("long.rrd"));
    let partial = d.join("long.partial.mcap");
    let mut child = gripsim()
        .arg("run")
        .arg(&sc)
        .args(["-q", "--detail", "step", "--flush-every", "40", "--mcap"])
        .arg(&mcap)
        .arg("--rrd")
        .arg(&rrd)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_size(&partial, 3_000_000, &mut child);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(!mcap.exists() && !rrd.exists(), "no file looks whole");

    // The mcap crate and the Python reader both read up to the last complete chunk.
    let (msgs, err) = read_mcap_rust(&partial);
    assert!(err.is_some(), "a killed file has no summary");
    let steps: Vec<u64> = msgs
        .iter()
        .filter(|m| m.topic == "/sim/step")
        .map(|m| m.json["step"].as_u64().unwrap())
        .collect();
    assert!(steps.len() > 200, "{} steps read", steps.len());
    assert!(steps.iter().enumerate().all(|(i, &s)| s == i as u64));
    let last = *steps.last().unwrap();
    let report = read_mcap_py(&partial);
    assert!(report["error"].is_string(), "{}", report["error"]);
    assert_eq!(report["summary"]["footer"], false);
    assert_eq!(report["steps"].as_array().unwrap().len() as u64, last + 1);
    assert_channels(&report, false);

    // The .rrd decodes up to its last flush (it has no footer, so `verify` would refuse it).
    let out = rerun_rrd(&[&d.join("long.partial.rrd")], "stats");
    assert!(
        out.status.success(),
        "rerun rrd stats: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stats = String::from_utf8_lossy(&out.stdout);
    assert!(stats.contains("/scene/beam/nodes"), "{stats}");
}

#[test]
fn sigint_and_sigterm_close_the_recordings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = long_scenario(d);
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let (mcap, rrd) = (
            d.join(format!("{signal}.mcap")),
            d.join(format!("{signal}.rrd")),
        );
        let mut child = gripsim()
            .arg("run")
            .arg(&sc)
            .args(["-q", "--detail", "step", "--flush-every", "50", "--mcap"])
            .arg(&mcap)
            .arg("--rrd")
            .arg(&rrd)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let partial_mcap = d.join(format!("{signal}.partial.mcap"));
        wait_for_size(&partial_mcap, 500_000, &mut child);
        let sent = Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(child.id().to_string())
            .status()
            .unwrap();
        assert!(sent.success());
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(code), "SIG{signal}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("interrupted"), "{stderr}");

        assert!(
            !mcap.exists() && !rrd.exists(),
            "an interrupted run keeps .partial"
        );
        assert_rrd_verifies(&d.join(format!("{signal}.partial.rrd")));
        let report = read_mcap_py(&partial_mcap);
        assert_eq!(report["error"], Value::Null, "{report}");
        assert_eq!(report["summary"]["footer"], true);
        assert_eq!(report["summary"]["statistics"], true);
        assert_eq!(report["last_event"]["kind"], "run_end");
        assert_eq!(report["last_event"]["completed"], false);
        let why = report["last_event"]["error"].as_str().unwrap();
        assert!(why.contains("interrupted"), "{why}");
        assert_eq!(report["metadata"]["gripsim.run_end"]["completed"], "false");
    }
}

/// A run that diverges (one Newton iteration allowed, no dt back-off, a stiff prong) stops
/// with exit status 2 and a message naming the step, time, rod, node and residual; its
/// recordings are closed properly up to the last accepted step (footer, summary), keep their
/// .partial names, and end with the reason (the last /sim/event and the run_end metadata).
#[test]
fn a_diverged_run_exits_2_and_its_recordings_say_why() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mcap, rrd, csv) = (d.join("div.mcap"), d.join("div.rrd"), d.join("div.csv"));
    let out = gripsim()
        .arg("run")
        .arg(scenario("seed-grasp-r5"))
        .args([
            "-q",
            "--detail",
            "step",
            "--set",
            "rod.0.E=1e11",
            "--set",
            "solve.max_newton_iterations=1",
            "--set",
            "solve.max_backoff=0",
            "--mcap",
        ])
        .arg(&mcap)
        .arg("--rrd")
        .arg(&rrd)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    // error: diverged at step N, t = T s: rod "prong" node I: <reason> (residual R N) ...
    let first = stderr.lines().next().unwrap_or("");
    let step: u64 = first
        .strip_prefix("error: diverged at step ")
        .and_then(|s| s.split(',').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no step in {stderr}"));
    assert!(step > 100, "diverged at step {step}: expected mid-run");
    for part in [", t = ", " s: rod \"prong\" node ", "(residual ", "hint:"] {
        assert!(stderr.contains(part), "{part:?} missing from:\n{stderr}");
    }

    // MCAP: complete file, steps 0 .. N-1, then the reason.
    assert!(
        !mcap.exists() && !rrd.exists() && !csv.exists(),
        "a failed run keeps .partial"
    );
    let partial = d.join("div.partial.mcap");
    let report = read_mcap_py(&partial);
    assert_eq!(report["error"], Value::Null, "{report}");
    assert_eq!(report["summary"]["footer"], true);
    assert_eq!(report["summary"]["statistics"], true);
    let steps = report["steps"].as_array().unwrap();
    assert_eq!(steps.len() as u64, step, "steps 0 .. {}", step - 1);
    assert_eq!(steps.last().unwrap().as_u64(), Some(step - 1));
    let last = &report["last_event"];
    assert_eq!(last["kind"], "run_end");
    assert_eq!(last["completed"], false);
    let why = last["error"].as_str().unwrap();
    assert!(
        why.starts_with(&format!("diverged at step {step}, t = ")),
        "{why}"
    );
    assert!(first.contains(why), "stderr and recording agree: {why}");
    let end = &report["metadata"]["gripsim.run_end"];
    assert_eq!(end["completed"], "false");
    assert_eq!(end["error"], why);
    assert_eq!(end["steps"], (step - 1).to_string());
    // The failed attempt itself is an event just before the end.
    let (msgs, err) = read_mcap_rust(&partial);
    assert_eq!(err, None);
    let kinds: Vec<&str> = msgs
        .iter()
        .filter(|m| m.topic == "/sim/event")
        .filter_map(|m| m.json["kind"].as_str())
        .collect();
    assert_eq!(kinds[kinds.len() - 2..], ["newton_failed", "run_end"]);

    // Rerun: a whole, valid file.
    assert_rrd_verifies(&d.join("div.partial.rrd"));

    // CSV: rows up to the last accepted step.
    let text = std::fs::read_to_string(d.join("div.partial.csv")).unwrap();
    let last_row = text.lines().last().unwrap();
    assert!(
        last_row.starts_with(&format!("{},", step - 1)),
        "{last_row}"
    );
}

/// The compliant contact's fields (issue 11: indentation, half-width, peak pressure, bruise
/// threshold, bruise half-width) reach `/sim/step`, and Google's protobuf library (Python,
/// from the schema in the file) reads the same numbers as gripsim's own decoder, bit for bit;
/// the CSV has them on the node's row.
#[test]
fn contact_pressure_reaches_the_mcap() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("apple.mcap");
    let csv = dir.path().join("apple.csv");
    run_ok(
        gripsim()
            .arg("run")
            .arg(scenario("seed-grasp-r5"))
            .args([
                "-q",
                "--detail",
                "step",
                "--set",
                "contact.surface=face",
                "--set",
                "obstacle.0.center=[-0.055,-0.05]",
                "--set",
                "obstacle.0.material=apple",
                "--mcap",
            ])
            .arg(&mcap)
            .arg("--csv")
            .arg(&csv),
    );
    let (msgs, err) = read_mcap_rust(&mcap);
    assert_eq!(err, None);
    let steps: BTreeMap<u64, &Value> = msgs
        .iter()
        .filter(|m| m.topic == "/sim/step")
        .map(|m| (m.json["step"].as_u64().unwrap(), &m.json))
        .collect();
    // gripsim's decode: a pressed compliant contact has all five fields, consistently.
    let mut pressed = 0;
    for s in steps.values() {
        for c in s["contacts"].as_array().into_iter().flatten() {
            let f = |k: &str| c[k].as_f64().unwrap_or_else(|| panic!("{k} in {c}"));
            if f("normal_force") > 0.0 {
                pressed += 1;
                assert!(f("indentation") > 0.0 && f("half_width") > 0.0, "{c}");
                assert!(f("peak_pressure") > 0.0, "{c}");
                assert_eq!(f("bruise_pressure"), 1e5, "the apple's threshold: {c}");
                let above = f("peak_pressure") > f("bruise_pressure");
                assert_eq!(f("bruise_half_width") > 0.0, above, "{c}");
                assert!(f("bruise_half_width") <= f("half_width"), "{c}");
            }
        }
    }
    assert!(pressed > 100, "{pressed} pressed contacts");
    // The independent reader.
    let report = read_mcap_py(&mcap);
    assert_eq!(report["error"], Value::Null, "{report}");
    let mut sampled = 0;
    for s in report["step_samples"].as_array().unwrap() {
        let ours = steps[&s["step"].as_u64().unwrap()];
        let theirs = s["contacts"].as_array().unwrap();
        let ours_c = ours["contacts"].as_array().cloned().unwrap_or_default();
        assert_eq!(theirs.len(), ours_c.len(), "contacts at step {}", s["step"]);
        for (a, b) in theirs.iter().zip(&ours_c) {
            for key in [
                "node",
                "normal_force",
                "indentation",
                "half_width",
                "peak_pressure",
                "bruise_pressure",
                "bruise_half_width",
            ] {
                assert_eq!(a[key], b[key], "{key} at step {}", s["step"]);
            }
            sampled += (b["peak_pressure"].as_f64().unwrap() > 0.0) as usize;
        }
    }
    assert!(sampled > 0, "a sampled step with a pressed contact");
    // The CSV: the same numbers on the node's row (0 on rows without a pressed contact).
    let mut rdr = csv::Reader::from_path(&csv).unwrap();
    let h: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    let col = |k: &str| h.iter().position(|x| x == k).unwrap();
    let mut rows_pressed = 0;
    for rec in rdr.records() {
        let rec = rec.unwrap();
        let step: u64 = rec[col("step")].parse().unwrap();
        let node: u64 = rec[col("node")].parse().unwrap();
        let c = steps[&step]["contacts"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|c| c["node"] == node && c["peak_pressure"].as_f64().unwrap() > 0.0);
        for key in [
            "indentation",
            "half_width",
            "peak_pressure",
            "bruise_half_width",
        ] {
            // The CSV's exact double, rounded to the MCAP's f32 (format 4's default).
            let x: f64 = rec[col(key)].parse().unwrap();
            let want = c.map_or(0.0, |c| c[key].as_f64().unwrap());
            assert_eq!(x as f32 as f64, want, "{key} at step {step} node {node}");
        }
        rows_pressed += c.is_some() as usize;
    }
    assert_eq!(rows_pressed, pressed, "a CSV row per pressed contact");
}

/// Format 4's default precision: `/sim/step` is the f64 recording's numbers rounded to f32,
/// with the same fingerprint of the exact state on every step; Google's protobuf library reads
/// it from the file's schema (`gripsim.Step`, `float` fields) and the `/scene/nodes` cloud.
#[test]
fn the_default_f32_recording_is_the_exact_one_rounded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (f32_file, f64_file) = (d.join("f32.mcap"), d.join("f64.mcap"));
    for (file, precision) in [(&f32_file, "f32"), (&f64_file, "f64")] {
        run_ok(
            gripsim()
                .arg("run")
                .arg(scenario("two-prong-grasp"))
                .args(["-q", "--detail", "step"])
                .args(["--precision", precision, "--mcap"])
                .arg(file),
        );
    }
    let steps = |p: &Path| {
        let mut out = Vec::new();
        gripsim::replay::read::read_messages(p, false, |m| {
            if let gripsim::replay::read::Message::Step(s) = m {
                out.push(s);
            }
            Ok(())
        })
        .unwrap();
        out
    };
    let (short, exact) = (steps(&f32_file), steps(&f64_file));
    assert_eq!(short.len(), 6001);
    assert_eq!(short.len(), exact.len());
    let round = |v: &[f64]| v.iter().map(|&x| x as f32 as f64).collect::<Vec<f64>>();
    let mut contacts = 0;
    for (s, e) in short.iter().zip(&exact) {
        assert_eq!((s.step, s.t, s.dt), (e.step, e.t, e.dt));
        assert!(s.fingerprint.is_some());
        assert_eq!(s.fingerprint, e.fingerprint, "step {}", s.step);
        for (r, x) in s.rods.iter().zip(&e.rods) {
            assert_eq!(r.q, round(&x.q), "q at step {}", s.step);
            assert_eq!(r.u, round(&x.u), "u at step {}", s.step);
            assert_eq!(r.reaction, round(&x.reaction));
            assert_eq!(r.bending_stress, round(&x.bending_stress));
            assert_eq!(r.in_contact, x.in_contact);
            contacts += r.in_contact.iter().filter(|&&c| c).count();
        }
        assert_eq!(s.contacts.len(), e.contacts.len());
    }
    assert!(contacts > 100, "{contacts} node-steps in contact");
    let (a, b) = (
        std::fs::metadata(&f32_file).unwrap().len(),
        std::fs::metadata(&f64_file).unwrap().len(),
    );
    assert!(a < b, "f32 {a} bytes, f64 {b} bytes");
    // The independent reader.
    let report = read_mcap_py(&f32_file);
    assert_eq!(report["error"], Value::Null, "{report}");
    assert_channels(&report, false);
    assert_eq!(report["fingerprints"]["steps"], 6001);
    assert_eq!(report["fingerprints"]["checked"], 0);
    let samples = report["step_samples"].as_array().unwrap();
    for s in samples {
        let k = s["step"].as_u64().unwrap() as usize;
        assert_eq!(f64s(&s["rods"][0]["q"]), round(&exact[k].rods[0].q));
        assert_eq!(s["fingerprint"].as_u64(), exact[k].fingerprint);
    }
    // /scene/nodes: every node of both prongs at its f32 position.
    for n in report["node_samples"].as_array().unwrap() {
        let k = n["index"].as_u64().unwrap() as usize;
        let want: Vec<f64> = exact[k].rods.iter().flat_map(|r| round(&r.q)).collect();
        let got: Vec<f64> = n["points"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|p| [p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap()])
            .collect();
        assert_eq!(got, want, "/scene/nodes at step {k}");
    }
    // The f64 file's fingerprints, recomputed in Python from its doubles, all match.
    let report = read_mcap_py(&f64_file);
    assert_eq!(report["fingerprints"]["checked"], 6001);
    assert_eq!(report["fingerprints"]["matched"], 6001);
}
