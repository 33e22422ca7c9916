//! The run summary's JSON Schema (docs/summary.schema.json, generated from the types' doc
//! comments by schemars) is current, and every shipped scenario's `--summary`, planar and 3D,
//! validates against it: every vector has `dimension` components, and every lift ends in the
//! verdict its `[expect]` names (held unless it says otherwise), printed as HELD, SLIPPED or
//! DROPPED.

use crate::common::{gripsim, ROOT};
use gripsim::record::summary::Summary;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The schema as the types give it, as the file holds it (pretty, ending in a newline).
fn schema_text() -> String {
    let schema = schemars::schema_for!(Summary);
    let mut text = serde_json::to_string_pretty(&schema).unwrap();
    text.push('\n');
    text
}

#[test]
fn summary_schema_is_current() {
    let file = Path::new(ROOT).join("docs/summary.schema.json");
    let now = schema_text();
    if std::env::var("GRIPSIM_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&file, &now).unwrap();
        return;
    }
    let then = std::fs::read_to_string(&file).unwrap_or_default();
    assert!(
        then == now,
        "{} is not the schema of record::summary::Summary (rewrite it: GRIPSIM_BLESS=1 cargo \
         test --release --test suite summary_schema_is_current)",
        file.display()
    );
    // What the schema says about a key comes from its doc comment.
    let v: Value = serde_json::from_str(&now).unwrap();
    let dim = &v["properties"]["dimension"]["description"];
    assert!(
        dim.as_str().is_some_and(|d| d.contains("2 (planar) or 3")),
        "{dim}"
    );
}

/// The vectors of a summary: (where, value).
fn vectors(s: &Value) -> Vec<(String, &Value)> {
    let mut out = Vec::new();
    for (r, rod) in s["rods"].as_array().unwrap().iter().enumerate() {
        for key in ["final_positions", "final_velocities"] {
            for (i, v) in rod[key].as_array().unwrap().iter().enumerate() {
                out.push((format!("rods[{r}].{key}[{i}]"), v));
            }
        }
        out.push((
            format!("rods[{r}].final_drive_force_n"),
            &rod["final_drive_force_n"],
        ));
    }
    for key in [
        "initial_position_m",
        "final_position_m",
        "final_velocity_m_s",
    ] {
        if !s["grasp"].is_null() {
            out.push((format!("grasp.{key}"), &s["grasp"][key]));
        }
    }
    if !s["contact_pressure"].is_null() {
        out.push((
            "contact_pressure.max_pressure_point".to_string(),
            &s["contact_pressure"]["max_pressure_point"],
        ));
    }
    out
}

/// Whether the scenario lifts the fruit (a phase named `lift`, or a 3D `lift` move), and the
/// verdict its `[expect]` names.
fn lift_and_expectation(path: &Path) -> (bool, String) {
    let doc: toml::Table = std::fs::read_to_string(path).unwrap().parse().unwrap();
    let arr = |v: Option<&toml::Value>| v.and_then(toml::Value::as_array).cloned();
    let mut lift = false;
    for a in arr(doc.get("actuator")).unwrap_or_default() {
        for p in arr(a.get("phase")).unwrap_or_default() {
            lift |= p.get("name").and_then(toml::Value::as_str) == Some("lift");
        }
    }
    for m in arr(doc.get("move")).unwrap_or_default() {
        lift |= m.get("kind").and_then(toml::Value::as_str) == Some("lift");
    }
    let expect = doc
        .get("expect")
        .and_then(|e| e.get("grasp"))
        .and_then(toml::Value::as_str)
        .unwrap_or("held")
        .to_string();
    (lift, expect)
}

/// Run `gripsim run FILE --no-record --summary JSON`: its summary and printed text.
fn run(path: &Path, dir: &Path) -> (Value, String) {
    let json = dir.join(format!(
        "{}.json",
        path.file_stem().unwrap().to_string_lossy()
    ));
    let out = gripsim()
        .arg("run")
        .arg(path)
        .args(["--no-record", "--summary"])
        .arg(&json)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{}: {text}{}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let s = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (s, text)
}

#[test]
fn every_shipped_scenario_summary_validates() {
    let schema: Value = serde_json::from_str(
        &std::fs::read_to_string(Path::new(ROOT).join("docs/summary.schema.json")).unwrap(),
    )
    .unwrap();
    let validator = jsonschema::validator_for(&schema).expect("the schema compiles");
    let mut files: Vec<PathBuf> = std::fs::read_dir(Path::new(ROOT).join("scenarios"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 21, "{} scenarios", files.len());
    let dir = tempfile::tempdir().unwrap();
    // Two runs at a time (the scenarios are independent processes).
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..2 {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(p) = files.get(k) else { break };
                let r = run(p, dir.path());
                results.lock().unwrap().push((p.clone(), r));
            });
        }
    });
    let mut results = results.into_inner().unwrap();
    results.sort_by(|a, b| a.0.cmp(&b.0));
    assert_eq!(results.len(), files.len());
    let (mut dims, mut lifts) = ([0; 2], 0);
    for (path, (s, text)) in &results {
        let name = path.file_name().unwrap().to_string_lossy();
        let errors: Vec<String> = validator
            .iter_errors(s)
            .map(|e| format!("{} at {}", e, e.instance_path()))
            .collect();
        assert!(errors.is_empty(), "{name}: {}", errors.join("\n"));
        let d = s["dimension"].as_u64().unwrap();
        assert!(d == 2 || d == 3, "{name}: dimension {d}");
        dims[usize::from(d == 3)] += 1;
        for (at, v) in vectors(s) {
            let n = v.as_array().map_or(0, Vec::len) as u64;
            assert_eq!(
                n, d,
                "{name}: {at} = {v} has {n} components in dimension {d}"
            );
        }
        assert!(
            !text.contains("Some(") && !text.contains("None"),
            "{name}: {text}"
        );
        let (lift, expect) = lift_and_expectation(path);
        if lift {
            lifts += 1;
            let g = &s["grasp"];
            assert!(!g["lift_start_time_s"].is_null(), "{name}: no lift: {g}");
            assert_eq!(g["verdict"], expect.as_str(), "{name}: {g}");
            let word = expect.to_uppercase();
            assert!(
                text.contains(&format!("): {word}")),
                "{name}: {word} not printed:\n{text}"
            );
        }
        println!(
            "{name}: dimension {d}, {} steps, verdict {}",
            s["steps"], s["grasp"]["verdict"]
        );
    }
    assert!(dims[0] >= 16 && dims[1] >= 5, "planar, 3D: {dims:?}");
    assert!(lifts >= 5, "{lifts} lifts");
}

/// A 3D run's one summary carries the 3D run's own figures: the squeeze's end, the finger
/// forces, the fruit's start and end, the penetration and twist, with 3-component vectors.
#[test]
fn the_3d_summary_carries_the_3d_run() {
    let sc =
        gripsim::scenario::three::Scenario3::load(&crate::common::scenario("3d-two-finger-sphere"))
            .unwrap();
    let s3 = gripsim::rod3d::run3::run(&sc, None).unwrap();
    let s = s3.to_summary(0.0);
    assert_eq!((s.dimension, s.steps), (3, s3.steps));
    assert_eq!(s.simulated_time_s, s3.t_end);
    let forces: Vec<f64> = s.rods.iter().map(|r| r.final_contact_force_n).collect();
    assert_eq!(forces, s3.finger_forces);
    assert_eq!(s.max_penetration_m, s3.worst_penetration.max(0.0));
    assert_eq!(s.max_twist_rad, Some(s3.max_twist));
    assert!(s.rods.iter().all(|r| r
        .final_positions
        .iter()
        .chain(&r.final_velocities)
        .all(|v| v.len() == 3)));
    // The squeeze ended on its force when the 3D run says it did, then the hold ran out.
    let squeeze = &s.phases[0];
    assert_eq!(squeeze.name.as_deref(), Some("squeeze"));
    assert_eq!(squeeze.reason.as_deref(), Some("grip_force"));
    assert_eq!(squeeze.end_s, s3.squeezed_at);
    let hold = &s.phases[1];
    assert_eq!(
        (hold.name.as_deref(), hold.start_s),
        (Some("hold"), squeeze.end_s.unwrap())
    );
    let g = s.grasp.as_ref().expect("a free fruit");
    assert_eq!(g.verdict, gripsim::record::grasp::Verdict::NoLift);
    assert_eq!(g.initial_position_m, s3.fruit_start.unwrap().to_vec());
    assert_eq!(g.final_position_m, s3.fruit_end.unwrap().to_vec());
    // The peak node reaction is a node's, at or after the first contact.
    let at = s.peak_reaction_time_s.unwrap();
    assert!(s.peak_reaction_force_n > 0.0 && at >= s.contact_onset_time_s.unwrap());
    println!(
        "3d-two-finger-sphere: {} steps, squeeze ends at {:?} s, finger forces {forces:?} N, peak reaction {} N at t = {at} s",
        s.steps, squeeze.end_s, s.peak_reaction_force_n
    );
}
