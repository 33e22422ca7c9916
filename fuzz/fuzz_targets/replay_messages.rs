//! Fuzz what `gripsim replay` does with the *messages* of a well-formed MCAP file.
//!
//! Raw-byte mutations of a recording mostly die at the container (chunk CRCs, zstd); this
//! target builds a valid MCAP around fuzzed message bodies, so the JSON decoding, the checks
//! against `/sim/meta` and everything downstream (spike and sticking detection, diff) see
//! arbitrary content.
//!
//! Input: UTF-8 text (other bytes replaced), one record per line, `<kind> <body>`:
//! `meta`, `step`, `contact`, `event`, `iteration`, `scene` put the body as a message on
//! `/sim/meta`, `/sim/step`, `/sim/contact`, `/sim/event`, `/sim/iteration`, `/scene`;
//! `version <v>` writes the `gripsim` metadata record with `format_version = v`;
//! `end <k=v,k=v>` writes a `gripsim.run_end` metadata record. Other lines are ignored.
//! The channels carry the schemas a real recording has (`record::mcap::CHANNELS`).
//! The seeds (fuzz/seeds/replay_messages/) are real recordings in this form
//! (fuzz/make_seeds.py).
//!
//! Any `Err` is fine; a panic is a finding, and so is a run that reads but does not diff
//! clean against itself.

#![no_main]

use gripsim::record::mcap::CHANNELS;
use gripsim::replay::{self, diff, Thresholds, Tolerances};
use libfuzzer_sys::fuzz_target;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        dir.join(format!("gripsim-fuzz-msg-{}.mcap", std::process::id()))
    })
}

fn build(text: &str) -> Vec<u8> {
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::WriteOptions::new()
            .compression(None)
            .create(&mut buf)
            .expect("writer");
        let mut ids = BTreeMap::new();
        for (topic, schema, body) in CHANNELS {
            let sid = w
                .add_schema(schema, "jsonschema", body.as_bytes())
                .expect("schema");
            let cid = w
                .add_channel(sid, topic, "json", &BTreeMap::new())
                .expect("channel");
            ids.insert(topic, cid);
        }
        let mut seq = 0u32;
        for line in text.lines() {
            let (kind, body) = line.split_once(' ').unwrap_or((line, ""));
            let topic = match kind {
                "meta" => "/sim/meta",
                "step" => "/sim/step",
                "contact" => "/sim/contact",
                "event" => "/sim/event",
                "iteration" => "/sim/iteration",
                "scene" => "/scene",
                "version" | "end" => {
                    let (name, metadata) = if kind == "version" {
                        let m = [("format_version".to_string(), body.to_string())];
                        ("gripsim", m.into_iter().collect())
                    } else {
                        let m = body
                            .split(',')
                            .filter_map(|kv| kv.split_once('='))
                            .map(|(k, v)| (k.to_string(), v.to_string()))
                            .collect();
                        ("gripsim.run_end", m)
                    };
                    w.write_metadata(&mcap::records::Metadata {
                        name: name.into(),
                        metadata,
                    })
                    .expect("metadata");
                    continue;
                }
                _ => continue,
            };
            let Some(&cid) = ids.get(&topic) else {
                continue;
            };
            seq += 1;
            w.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: cid,
                    sequence: seq,
                    log_time: seq as u64,
                    publish_time: seq as u64,
                },
                body.as_bytes(),
            )
            .expect("message");
        }
        w.finish().expect("finish");
    }
    buf.into_inner()
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let bytes = build(&text);
    let path = scratch();
    std::fs::write(path, &bytes).expect("write the scratch file");
    let th = Thresholds::default();
    let Ok((report, _warning)) = replay::check(path, &th) else {
        return;
    };
    let _ = replay::format_check(&report);
    let rep = diff::diff_files(path, path, &Tolerances::default(), &th)
        .expect("a run that reads is comparable with itself");
    let _ = diff::format_diff(&rep);
    assert!(rep.within_tolerance, "a run differs from itself");
});
