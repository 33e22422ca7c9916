//! `--detail auto` (the default of `gripsim run`): every step with its Newton iterations in
//! windows around events, every k-th step elsewhere, the first and the last; and `replay` on
//! the decimated recordings it writes (docs/recording-format.md, docs/replay.md).

use crate::common::{gripsim, message_json, run_ok, scenario, venv, ROOT};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

/// What a recording holds, read with the `mcap` crate (chunk CRCs checked).
#[derive(Default)]
struct Rec {
    meta: Value,
    /// /sim/step by step number, decoded.
    steps: BTreeMap<u64, Value>,
    /// /sim/iteration messages by step number, decoded, in order.
    iterations: BTreeMap<u64, Vec<Value>>,
    contacts: Vec<Value>,
    /// /sim/event messages other than the run's end.
    events: Vec<Value>,
}

fn read(path: &Path) -> Rec {
    let bytes = std::fs::read(path).unwrap();
    let stream = mcap::MessageStream::new_with_options(
        &bytes,
        mcap::read::Options::ValidateChunkCrcs.into(),
    )
    .expect("an MCAP header");
    let mut r = Rec::default();
    for m in stream {
        let m = m.expect("a whole file");
        let json = message_json(&m);
        let step = || json["step"].as_u64().unwrap();
        match m.channel.topic.as_str() {
            "/sim/meta" => r.meta = json,
            "/sim/step" => {
                let k = step();
                assert!(r.steps.insert(k, json).is_none(), "step {k} twice");
            }
            "/sim/iteration" => r.iterations.entry(step()).or_default().push(json),
            "/sim/contact" => r.contacts.push(json),
            "/sim/event" if json["kind"] != "run_end" => r.events.push(json),
            _ => {}
        }
    }
    r
}

fn record(name: &str, mcap: &Path, args: &[&str]) {
    run_ok(
        gripsim()
            .arg("run")
            .arg(scenario(name))
            .arg("-q")
            .args(args)
            .arg("--mcap")
            .arg(mcap),
    );
}

/// `replay check --json` of a recording: (exit status, report).
fn check(mcap: &Path) -> (i32, Value) {
    let json = mcap.with_extension("check.json");
    let out = gripsim()
        .args(["replay", "check", "--json"])
        .arg(&json)
        .arg(mcap)
        .output()
        .unwrap();
    let rep = std::fs::read(&json)
        .map(|b| serde_json::from_slice(&b).unwrap())
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&out.stderr)));
    (out.status.code().unwrap(), rep)
}

/// The steps `--detail auto` records, predicted from the step recording of the same run by
/// the documented rule: windows of `w` steps around every step with a contact change or an
/// event and every step with Newton trouble (more than twice the mean iterations of the
/// steps before it, plus one); every `k`-th step; the first and the last.
fn predicted(s: &Rec, k: u64, w: u64) -> (BTreeSet<u64>, BTreeSet<u64>) {
    let last = *s.steps.keys().last().unwrap();
    let mut eventful: BTreeSet<u64> = s
        .contacts
        .iter()
        .chain(&s.events)
        .map(|e| e["step"].as_u64().unwrap())
        .collect();
    let (mut sum, mut n) = (0u64, 0u64);
    for (&step, v) in s.steps.iter().filter(|(k, _)| **k > 0) {
        let it = v["newton_iterations"].as_u64().unwrap();
        if n > 0 && it * n > 2 * sum + n {
            eventful.insert(step);
        }
        sum += it;
        n += 1;
    }
    let full: BTreeSet<u64> = eventful
        .iter()
        .flat_map(|&e| e.saturating_sub(w)..=(e + w).min(last))
        .collect();
    let mut all = full.clone();
    all.extend((0..=last).filter(|s| s % k == 0));
    all.insert(last);
    (all, full)
}

#[test]
fn auto_is_the_default_and_keeps_every_step_of_each_window_and_every_kth_elsewhere() {
    let d = tempfile::tempdir().unwrap();
    let (a, s, i) = (
        d.path().join("a.mcap"),
        d.path().join("s.mcap"),
        d.path().join("i.mcap"),
    );
    record("two-prong-grasp", &a, &[]);
    record("two-prong-grasp", &s, &["--detail", "step"]);
    record("two-prong-grasp", &i, &["--detail", "iteration"]);
    let (a, s, i) = (read(&a), read(&s), read(&i));
    // 6 000 steps x 20 nodes / 20 000 node-steps = 6, rounded up to 1, 2, 5 x 10^n: 10.
    assert_eq!(a.meta["detail"], "auto");
    assert_eq!(a.meta["auto_every"], 10);
    assert_eq!(a.meta["auto_window"], 20);
    // Made readable every 100 sampled steps (100 x k), as many recorded steps as at step detail.
    assert_eq!(a.meta["flush_every"], 1000);
    assert_eq!(s.meta["flush_every"], 100);
    assert_eq!(s.meta["detail"], "step");
    assert_eq!(s.meta.get("auto_every"), None);
    assert_eq!(s.steps.len(), 6001);

    let (want, full) = predicted(&s, 10, 20);
    assert!(!s.contacts.is_empty(), "the grasp touches");
    let got: BTreeSet<u64> = a.steps.keys().copied().collect();
    assert_eq!(got, want, "recorded steps");
    assert!(got.contains(&0) && got.contains(&6000));
    // 601 sampled steps and the windows: far fewer than all 6 001.
    assert!(
        got.len() < 900 && full.len() >= 41,
        "{} recorded",
        got.len()
    );
    // The same numbers as the step recording for every step it holds, and every contact
    // change and event.
    for (k, v) in &a.steps {
        assert_eq!(v, &s.steps[k], "step {k}");
    }
    assert_eq!(a.contacts, s.contacts);
    assert_eq!(a.events, s.events);
    // Every Newton iteration of the steps in a window (as --detail iteration has them), none
    // of the others.
    let with_iterations: BTreeSet<u64> = a.iterations.keys().copied().collect();
    let expected: BTreeSet<u64> = full
        .iter()
        .copied()
        .filter(|k| i.iterations.contains_key(k))
        .collect();
    assert_eq!(with_iterations, expected);
    for (k, its) in &a.iterations {
        assert_eq!(its, &i.iterations[k], "iterations of step {k}");
    }
}

#[test]
fn a_spike_is_flagged_alike_on_the_auto_and_the_step_recording() {
    // At dt = 1e-4 both prongs hit the fruit in one step each: impact spikes.
    let d = tempfile::tempdir().unwrap();
    let (a, s) = (d.path().join("a.mcap"), d.path().join("s.mcap"));
    let dt = ["--set", "solve.dt=1e-4"];
    record(
        "two-prong-grasp",
        &a,
        &[&dt[..], &["--auto-every", "20"]].concat(),
    );
    record(
        "two-prong-grasp",
        &s,
        &[&dt[..], &["--detail", "step"]].concat(),
    );
    let ((ca, ra), (cs, rs)) = (check(&a), check(&s));
    assert_eq!((ca, cs), (1, 1), "both flagged");
    let key = |r: &Value| -> Vec<(String, u64, u64, u64, String)> {
        r["spikes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| {
                (
                    x["kind"].as_str().unwrap().to_string(),
                    x["rod"].as_u64().unwrap(),
                    x["node"].as_u64().unwrap(),
                    x["step"].as_u64().unwrap(),
                    x["jump"].to_string(),
                )
            })
            .collect()
    };
    assert_eq!(key(&ra).len(), 4, "{ra}");
    assert_eq!(key(&ra), key(&rs));
    assert_eq!(ra["sticking"], rs["sticking"]);
    // The auto recording says which stretches hold only some steps; the step one has none.
    let dec = ra["decimated"].as_array().unwrap();
    assert!(!dec.is_empty());
    assert!(
        dec.iter().all(|x| x["every"].as_u64().unwrap() <= 20),
        "{ra}"
    );
    assert_eq!(rs.get("decimated"), None);
    assert!(ra["steps"].as_u64().unwrap() < rs["steps"].as_u64().unwrap());
}

#[test]
fn a_gap_over_a_large_velocity_change_is_no_spike() {
    // The cantilever swings down under its own weight: no contact, no event; every 50th step
    // recorded, so a gap spans 50 steps of gravity and bending.
    let d = tempfile::tempdir().unwrap();
    let (a, s) = (d.path().join("a.mcap"), d.path().join("s.mcap"));
    record("cantilever-gravity", &a, &["--auto-every", "50"]);
    record("cantilever-gravity", &s, &["--detail", "step"]);
    let ((ca, ra), (cs, rs)) = (check(&a), check(&s));
    assert_eq!((cs, rs["counts"]["spikes"].as_u64()), (0, Some(0)), "{rs}");
    assert_eq!((ca, ra["counts"]["spikes"].as_u64()), (0, Some(0)), "{ra}");
    let dec = &ra["decimated"];
    assert_eq!(dec[0]["from"], 0, "{dec}");
    assert_eq!(dec[0]["every"], 50, "{dec}");
    let text = String::from_utf8_lossy(
        &gripsim()
            .args(["replay", "check"])
            .arg(&a)
            .output()
            .unwrap()
            .stdout,
    )
    .to_string();
    assert!(text.contains("recorded at most every 50th step"), "{text}");

    // Read as if the recorded steps were consecutive, the same detector flags the gaps: the
    // velocity change over 50 steps is far more than one step's forces explain.
    let mut run = gripsim::replay::read::Run::load(&a).unwrap();
    let th = gripsim::replay::Thresholds::DEFAULT;
    assert!(gripsim::replay::detect::detect(&run, &th).spikes.is_empty());
    for (k, st) in run.steps.iter_mut().enumerate() {
        st.step = k as u64;
    }
    let invented = gripsim::replay::detect::detect(&run, &th).spikes;
    assert!(invented.len() > 10, "{} spikes", invented.len());
}

#[test]
fn auto_files_are_smaller_and_read_by_the_independent_readers() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let mut size = BTreeMap::new();
    for detail in ["auto", "step"] {
        let (rrd, mcap) = (p(&format!("{detail}.rrd")), p(&format!("{detail}.mcap")));
        run_ok(
            gripsim()
                .arg("run")
                .arg(scenario("two-prong-grasp"))
                .args(["-q", "--detail", detail, "--rrd"])
                .arg(&rrd)
                .arg("--mcap")
                .arg(&mcap),
        );
        let len = |f: &Path| std::fs::metadata(f).unwrap().len() as f64;
        size.insert(detail, (len(&rrd), len(&mcap)));
    }
    // Measured (docs/performance.md): .mcap 6.8x, .rrd 4.4x, both 5.2x smaller at auto
    // (750 of 6 001 steps, 166 of them with their iterations).
    let (a, s) = (size["auto"], size["step"]);
    assert!(s.1 / a.1 > 4.0, "mcap {s:?} / {a:?}");
    assert!(s.0 / a.0 > 2.5, "rrd {s:?} / {a:?}");
    assert!((s.0 + s.1) / (a.0 + a.1) > 3.0, "rrd + mcap {s:?} / {a:?}");

    let out = Command::new(venv().join("bin/rerun"))
        .args(["rrd", "verify"])
        .arg(p("auto.rrd"))
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the rerun CLI runs");
    assert!(out.status.success(), "rerun rrd verify: {out:?}");
    let out = Command::new(venv().join("bin/python"))
        .arg(Path::new(ROOT).join("tests/py/read_mcap.py"))
        .arg(p("auto.mcap"))
        .output()
        .expect("the venv's python runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["error"], Value::Null, "{report}");
    assert_eq!(report["metadata"]["gripsim"]["detail"], "auto");
    assert_eq!(report["metadata"]["gripsim"]["auto_every"], "10");
    let ours: Vec<u64> = read(&p("auto.mcap")).steps.keys().copied().collect();
    let theirs: Vec<u64> = report["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_u64().unwrap())
        .collect();
    assert_eq!(theirs, ours);
    assert!(report["validated"].as_u64().unwrap() as usize > ours.len());

    // diff compares the steps both recordings hold: the auto run is the step run there.
    let out = gripsim()
        .args(["replay", "diff", "--json"])
        .arg(p("diff.json"))
        .arg(p("step.mcap"))
        .arg(p("auto.mcap"))
        .output()
        .unwrap();
    let rep: Value = serde_json::from_slice(&std::fs::read(p("diff.json")).unwrap()).unwrap();
    assert_eq!(out.status.code(), Some(0), "{rep}");
    assert_eq!(rep["within_tolerance"], true);
    assert_eq!(rep["samples"].as_u64().unwrap() as usize, ours.len());
    assert_eq!(
        rep["samples"].as_u64().unwrap() + rep["skipped_in_gaps"].as_u64().unwrap(),
        6001
    );
}

#[test]
fn auto_every_is_for_auto_only() {
    let out = gripsim()
        .arg("run")
        .arg(scenario("two-prong-grasp"))
        .args([
            "-q",
            "--no-record",
            "--detail",
            "step",
            "--auto-every",
            "10",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("--auto-every applies to --detail auto only"),
        "{e}"
    );
}
