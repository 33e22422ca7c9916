//! Bad recording input for `gripsim replay`: every case exits with status 2, never panics, and
//! says on stderr which file is wrong and why.
//!
//! tests/replay.rs (`bad_input_is_a_clear_error`, `runs_that_cannot_be_compared_are_an_error`)
//! already covers a text file, the first 300 bytes of a recording, an empty file, the wrong
//! schema on /sim/step, a newer format version (99, in both the metadata record and
//! /sim/meta), a missing /sim/step channel, a /sim/step body that does not match its schema, a
//! missing file, and a diff of a one-rod with a two-rod run. The classes here are the others.

use crate::common::{gripsim, message_json, scenario};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run; expect exit 2, no panic; return stderr.
fn fails(cmd: &mut Command) -> String {
    let out: Output = cmd.output().expect("gripsim starts");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{cmd:?}\nstdout:\n{}\nstderr:\n{stderr}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!stderr.contains("panicked"), "{cmd:?} panicked:\n{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.trim_end().lines().count() == 1,
        "{cmd:?}: one error line expected:\n{stderr}"
    );
    stderr
}

/// `replay check FILE` and `replay show FILE --rrd OUT` both refuse `file`, naming it and
/// saying `why`; no .rrd is left behind.
fn refused(file: &Path, why: &str) {
    let name = file.display().to_string();
    let rrd = file.with_extension("shown.rrd");
    for args in [
        vec!["check".to_string(), name.clone()],
        vec![
            "show".to_string(),
            name.clone(),
            "--rrd".to_string(),
            rrd.display().to_string(),
        ],
    ] {
        let err = fails(gripsim().arg("replay").args(&args));
        assert!(
            err.contains(&name) && err.contains(why),
            "replay {args:?}: expected {why:?} naming the file, got:\n{err}"
        );
    }
    assert!(
        !rrd.exists(),
        "{} written for a refused input",
        rrd.display()
    );
}

fn run_to(sc: &Path, mcap: &Path, sets: &[&str]) {
    let mut c = gripsim();
    c.arg("run")
        .arg(sc)
        .args(["-q", "--detail", "step", "--mcap"])
        .arg(mcap);
    for s in sets {
        c.args(["--set", s]);
    }
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A short real recording: a point mass landing on a plane (30 steps).
fn real(dir: &Path) -> PathBuf {
    let p = dir.join("real.mcap");
    run_to(
        &scenario("point-mass-plane-dt1e-4"),
        &p,
        &["particle.0.position=[0.0, 0.00002]", "solve.t_end=0.003"],
    );
    p
}

/// The messages of a recording: (topic, schema name, schema text, JSON body).
type Messages = Vec<(String, String, Vec<u8>, Value)>;

fn messages(path: &Path) -> Messages {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .map(|m| {
            let schema = m.channel.schema.as_ref().expect("a schema");
            (
                m.channel.topic.clone(),
                schema.name.clone(),
                schema.data.to_vec(),
                message_json(&m),
            )
        })
        .collect()
}

/// Write `msgs` as an MCAP file with the `gripsim` metadata record (`format_version` =
/// `version`, left out when `None`).
fn write(path: &Path, msgs: &Messages, version: Option<&str>) {
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    if let Some(v) = version {
        w.write_metadata(&mcap::records::Metadata {
            name: "gripsim".into(),
            metadata: [("format_version".to_string(), v.to_string())].into(),
        })
        .unwrap();
    }
    let mut ids: BTreeMap<String, u16> = BTreeMap::new();
    for (k, (topic, schema, text, body)) in msgs.iter().enumerate() {
        let cid = match ids.get(topic) {
            Some(&c) => c,
            None => {
                let sid = w.add_schema(schema, "jsonschema", text).unwrap();
                let c = w
                    .add_channel(sid, topic, "json", &Default::default())
                    .unwrap();
                ids.insert(topic.clone(), c);
                c
            }
        };
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: cid,
                sequence: k as u32,
                log_time: k as u64,
                publish_time: k as u64,
            },
            serde_json::to_string(body).unwrap().as_bytes(),
        )
        .unwrap();
    }
    w.finish().unwrap();
}

/// Class 1: a file cut inside the MCAP header (the magic, then the header record).
#[test]
fn a_file_cut_inside_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(real(dir.path())).unwrap();
    for (n, why) in [(5, "not an MCAP file"), (20, "not a readable MCAP file")] {
        let cut = dir.path().join(format!("cut-{n}.mcap"));
        std::fs::write(&cut, &bytes[..n]).unwrap();
        refused(&cut, why);
    }
}

/// Class 2: not an MCAP file at all, but something a user may pass by mistake: random bytes,
/// the run's .rrd or .csv, a directory.
#[test]
fn other_files_than_a_recording() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let noise = d.join("noise.mcap");
    // A fixed pseudo-random byte string (xorshift), so a failure is reproducible.
    let mut x = 0x9e3779b97f4a7c15u64;
    let bytes: Vec<u8> = (0..4096)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    std::fs::write(&noise, bytes).unwrap();
    refused(&noise, "not an MCAP file");

    let (rrd, csv) = (d.join("run.rrd"), d.join("run.csv"));
    let out = gripsim()
        .arg("run")
        .arg(scenario("point-mass-plane-dt1e-4"))
        .args([
            "-q",
            "--detail",
            "step",
            "--set",
            "solve.t_end=0.002",
            "--rrd",
        ])
        .arg(&rrd)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success());
    refused(&rrd, "not an MCAP file");
    refused(&csv, "not an MCAP file");

    let folder = d.join("a-folder.mcap");
    std::fs::create_dir(&folder).unwrap();
    refused(&folder, "cannot read the file");
}

/// Class 3: a valid MCAP without /sim/meta — another program's file (no gripsim channel at
/// all), or a gripsim file whose /sim/meta channel or message is missing.
#[test]
fn no_sim_meta() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let msgs = messages(&real(d));

    let foreign = d.join("foreign.mcap");
    write(
        &foreign,
        &vec![(
            "/camera/info".to_string(),
            "foxglove.CameraCalibration".to_string(),
            b"{}".to_vec(),
            serde_json::json!({"width": 640, "height": 480}),
        )],
        None,
    );
    refused(&foreign, "missing channel /sim/meta");

    let no_channel = d.join("no-meta-channel.mcap");
    let without: Messages = msgs
        .iter()
        .filter(|m| m.0 != "/sim/meta")
        .cloned()
        .collect();
    write(&no_channel, &without, Some("1"));
    refused(&no_channel, "/sim/meta");
}

/// Class 4: a run from a newer format: `/sim/meta` says format_version = 999 and the file
/// has no `gripsim` metadata record (another writer), so only the message says so.
#[test]
fn a_newer_format_version_in_sim_meta() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut msgs = messages(&real(d));
    for m in msgs.iter_mut().filter(|m| m.0 == "/sim/meta") {
        m.3["format_version"] = 999.into();
    }
    let newer = d.join("newer.mcap");
    write(&newer, &msgs, None);
    refused(&newer, "format version 999");
    let err = fails(gripsim().args(["replay", "check"]).arg(&newer));
    assert!(err.contains("newer gripsim"), "{err}");
}

/// Class 5: messages that contradict /sim/meta or each other: a step with the wrong number of
/// positions, steps out of order, a contact on a node the rod does not have, a recorded
/// scenario that no longer reads.
#[test]
fn messages_that_contradict_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let msgs = messages(&real(d));
    let edit = |name: &str, f: &dyn Fn(&mut Messages)| {
        let mut m = msgs.clone();
        f(&mut m);
        let p = d.join(name);
        write(&p, &m, Some("1"));
        p
    };
    let step = |m: &mut Messages, k: usize| -> usize {
        m.iter()
            .enumerate()
            .filter(|(_, x)| x.0 == "/sim/step")
            .nth(k)
            .unwrap()
            .0
    };

    let short = edit("short-q.mcap", &|m| {
        let i = step(m, 3);
        m[i].3["rods"][0]["q"] = serde_json::json!([0.0]);
    });
    refused(&short, "`q` has 1 numbers");

    let order = edit("out-of-order.mcap", &|m| {
        let (i, j) = (step(m, 3), step(m, 4));
        m.swap(i, j);
    });
    refused(&order, "steps must increase");

    let contact = edit("contact-node.mcap", &|m| {
        let i = m.iter().position(|x| x.0 == "/sim/contact").unwrap();
        m[i].3["node"] = 7.into();
    });
    refused(&contact, "names node 7");

    let scenario = edit("bad-scenario.mcap", &|m| {
        let i = m.iter().position(|x| x.0 == "/sim/meta").unwrap();
        m[i].3["scenario_text"] = "name = \"x\"\n[solve]\n".into();
    });
    refused(&scenario, "recorded scenario does not read back");
}

/// Class 6: `replay diff` of runs that cannot be compared node by node: the same rods with
/// other node counts, and a dynamic with a static run. The message names both files and
/// says what differs and why that blocks a diff.
#[test]
fn diff_of_runs_that_cannot_be_compared() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (a, b) = (d.join("ten.mcap"), d.join("twelve.mcap"));
    run_to(&scenario("seed-grasp-r5"), &a, &["solve.t_end=0.0005"]);
    run_to(
        &scenario("seed-grasp-r5"),
        &b,
        &["solve.t_end=0.0005", "rod.0.nodes=12"],
    );
    let err = fails(gripsim().args(["replay", "diff"]).arg(&a).arg(&b));
    assert!(
        err.contains(&a.display().to_string())
            && err.contains(&b.display().to_string())
            && err.contains("10 node(s)")
            && err.contains("12 node(s)")
            && err.contains("same node counts"),
        "{err}"
    );

    let s = d.join("static.mcap");
    run_to(&scenario("cantilever-tip-load"), &s, &[]);
    let c = d.join("cantilever-dynamic.mcap");
    run_to(
        &scenario("cantilever-tip-load"),
        &c,
        &["solve.mode=dynamic", "solve.t_end=0.001", "solve.dt=1e-4"],
    );
    let err = fails(gripsim().args(["replay", "diff"]).arg(&c).arg(&s));
    assert!(
        err.contains("cannot compare a dynamic run")
            && err.contains(&s.display().to_string())
            && err.contains("load factor"),
        "{err}"
    );
}
