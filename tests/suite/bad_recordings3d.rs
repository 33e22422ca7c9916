//! Issue 34 items 4–7: the 3D recording reader holds up to damaged and self-contradicting
//! files. Each case runs `replay check`, `diff` and `show` on a short real 3D recording with
//! one thing wrong and asserts exit 2, one error line naming the file and what is wrong where,
//! and that no output was written. The last tests flip 200 random bits of a 3D and of a planar
//! recording and feed ~2 000 mutations of the 3D one to the reader in process.

use crate::common::{gripsim, scenario};
use gripsim::record::mcap3::Step3;
use prost::Message as _;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A short real 3D recording (the two-finger sphere, 20 steps to 2 ms) in `dir`.
fn record3(dir: &Path) -> PathBuf {
    let p = dir.join("good.mcap");
    let out = gripsim()
        .arg("run")
        .arg(scenario("3d-two-finger-sphere"))
        .args(["-q", "--set", "solve.t_end=0.002", "--mcap"])
        .arg(&p)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    p
}

/// One message: topic, schema (name, encoding, data), message encoding, body.
struct Msg {
    topic: String,
    schema: (String, String, Vec<u8>),
    encoding: String,
    data: Vec<u8>,
}

fn messages(path: &Path) -> Vec<Msg> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let s = m.channel.schema.as_ref().expect("a schema");
            Msg {
                topic: m.channel.topic.clone(),
                schema: (s.name.clone(), s.encoding.clone(), s.data.to_vec()),
                encoding: m.channel.message_encoding.clone(),
                data: m.data.to_vec(),
            }
        })
        .collect()
}

/// Write `msgs` as a CRC-valid MCAP file (what another writer, or a bug, could leave).
fn write(path: &Path, msgs: &[Msg]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::Writer::new(file).unwrap();
    let mut ids: BTreeMap<String, u16> = BTreeMap::new();
    for (k, m) in msgs.iter().enumerate() {
        let cid = match ids.get(&m.topic) {
            Some(&c) => c,
            None => {
                let (name, enc, data) = &m.schema;
                let sid = w.add_schema(name, enc, data).unwrap();
                let c = w
                    .add_channel(sid, &m.topic, &m.encoding, &Default::default())
                    .unwrap();
                ids.insert(m.topic.clone(), c);
                c
            }
        };
        let header = mcap::records::MessageHeader {
            channel_id: cid,
            sequence: k as u32,
            log_time: k as u64,
            publish_time: k as u64,
        };
        w.write_to_known_channel(&header, &m.data).unwrap();
    }
    w.finish().unwrap();
}

/// The recording `good` with its `/sim/step` messages edited by `edit` (decoded, in order),
/// written to `dir/name`.
fn edited(good: &Path, name: &str, edit: impl FnOnce(&mut Vec<Step3>)) -> PathBuf {
    let mut msgs = messages(good);
    let first = msgs.iter().position(|m| m.topic == "/sim/step").unwrap();
    let template = Msg {
        data: vec![],
        ..clone_msg(&msgs[first])
    };
    let mut steps: Vec<Step3> = msgs
        .iter()
        .filter(|m| m.topic == "/sim/step")
        .map(|m| Step3::decode(m.data.as_slice()).unwrap())
        .collect();
    edit(&mut steps);
    msgs.retain(|m| m.topic != "/sim/step");
    let at = first.min(msgs.len());
    let new = steps.iter().map(|s| Msg {
        data: s.encode_to_vec(),
        ..clone_msg(&template)
    });
    msgs.splice(at..at, new);
    let p = good.with_file_name(name);
    write(&p, &msgs);
    p
}

fn clone_msg(m: &Msg) -> Msg {
    Msg {
        topic: m.topic.clone(),
        schema: m.schema.clone(),
        encoding: m.encoding.clone(),
        data: m.data.clone(),
    }
}

/// The recording `good` with its `/sim/meta` JSON edited by `edit`, written to `dir/name`.
fn edited_meta(good: &Path, name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let mut msgs = messages(good);
    let m = msgs.iter_mut().find(|m| m.topic == "/sim/meta").unwrap();
    let mut v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
    edit(&mut v);
    m.data = serde_json::to_vec(&v).unwrap();
    let p = good.with_file_name(name);
    write(&p, &msgs);
    p
}

/// `replay check`, `diff` (against the good file, both ways round) and `show` refuse `bad`:
/// exit 2, one `error:` line naming the file and holding every word, no output written.
fn refused3(bad: &Path, good: &Path, words: &[&str]) {
    let dir = bad.parent().unwrap();
    let out = dir.join("out.json");
    let rrd = dir.join("out.rrd");
    let name = bad.display().to_string();
    let runs: [Vec<&std::ffi::OsStr>; 4] = [
        vec![
            "check".as_ref(),
            bad.as_os_str(),
            "--json".as_ref(),
            out.as_os_str(),
        ],
        vec![
            "diff".as_ref(),
            good.as_os_str(),
            bad.as_os_str(),
            "--json".as_ref(),
            out.as_os_str(),
        ],
        vec![
            "diff".as_ref(),
            bad.as_os_str(),
            good.as_os_str(),
            "--rrd".as_ref(),
            rrd.as_os_str(),
        ],
        vec![
            "show".as_ref(),
            bad.as_os_str(),
            "--rrd".as_ref(),
            rrd.as_os_str(),
        ],
    ];
    for args in runs {
        let o = gripsim().arg("replay").args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let lines: Vec<&str> = err.lines().collect();
        assert!(
            lines.len() == 1 && lines[0].starts_with(&format!("error: {name}: ")),
            "{args:?}: one error line naming the file expected:\n{err}"
        );
        for w in words {
            assert!(err.contains(w), "{args:?}: {w:?} missing in {err}");
        }
        assert!(
            !out.exists() && !rrd.exists(),
            "{args:?}: an output was written"
        );
    }
}

/// Flip bit `bit` of byte `at` of `good`, written to `dir/name`.
fn flipped(good: &Path, name: &str, at: usize, bit: u8) -> PathBuf {
    let mut b = std::fs::read(good).unwrap();
    b[at] ^= 1 << bit;
    let p = good.with_file_name(name);
    std::fs::write(&p, b).unwrap();
    p
}

/// The top-level records of an MCAP file: (opcode, offset, length).
fn records(b: &[u8]) -> Vec<(u8, usize, usize)> {
    let mut v = Vec::new();
    let mut pos = 8;
    while pos + 9 <= b.len() {
        let len = u64::from_le_bytes(b[pos + 1..pos + 9].try_into().unwrap()) as usize;
        v.push((b[pos], pos, len));
        if b[pos] == 0x02 {
            break;
        }
        pos += 9 + len;
    }
    v
}

/// Item 4: one flipped bit early in the file (a 3D replay panicked with "capacity
/// overflow"): in the first chunk's length, its uncompressed size and its records: exit 2.
#[test]
fn item4_a_flipped_bit_early_in_a_3d_recording_is_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let b = std::fs::read(&good).unwrap();
    let (op, chunk, _) = records(&b)[1];
    assert_eq!(op, 0x06, "the second record is the first chunk");
    // The chunk record's length (its high byte), the uncompressed size (high byte) and a
    // byte of the compressed records.
    for (k, (at, bit, words)) in [
        (chunk + 8, 6, vec!["not a readable MCAP file"]),
        (chunk + 9 + 23, 7, vec!["chunk 1", "damaged"]),
        (chunk + 9 + 400, 2, vec!["chunk 1", "fails its CRC"]),
    ]
    .into_iter()
    .enumerate()
    {
        let bad = flipped(&good, &format!("flip{k}.mcap"), at, bit);
        refused3(&bad, &good, &words);
    }
}

/// Item 5: a flipped bit in a chunk that still decompresses (Python's `mcap` rejects it; a
/// 3D replay read on, "jump inf m/s … accel ratio NaN"): the chunk CRC finds it, exit 2. In a
/// later chunk of a longer run, the file is read up to the damaged chunk, which is named,
/// exit 3, as for a planar file.
#[test]
fn item5_a_chunk_that_fails_its_crc_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let b = std::fs::read(&good).unwrap();
    let (_, chunk, len) = records(&b)[1];
    let bad = flipped(&good, "crc.mcap", chunk + 9 + len / 2, 0);
    refused3(&bad, &good, &["chunk 1 (at byte 38) fails its CRC"]);

    let long = dir.path().join("long.mcap");
    let out = gripsim()
        .arg("run")
        .arg(scenario("3d-two-finger-sphere"))
        .args(["-q", "--set", "solve.t_end=0.05", "--mcap"])
        .arg(&long)
        .output()
        .unwrap();
    assert!(out.status.success());
    let b = std::fs::read(&long).unwrap();
    let chunks: Vec<_> = records(&b).into_iter().filter(|r| r.0 == 0x06).collect();
    assert!(chunks.len() >= 2, "{} chunk(s)", chunks.len());
    let (_, at, len) = chunks[1];
    let bad = flipped(&long, "crc2.mcap", at + 9 + len / 2, 3);
    let rep = gripsim::replay::three::check(&bad, &Default::default()).unwrap();
    println!(
        "a flip in chunk 2 of {}: {} of the steps read; {:?}",
        chunks.len(),
        rep.steps,
        rep.truncated
    );
    assert!(rep.incomplete && rep.steps > 0);
    let why = rep.truncated.unwrap();
    assert!(
        why.contains("chunk 2") && why.contains("fails its CRC"),
        "{why}"
    );
    let o = gripsim()
        .args(["replay", "check"])
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(3));
}

/// Item 4: a CRC-valid file with one short position or velocity array.
#[test]
fn item4_a_short_position_or_velocity_array_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let bad = edited(&good, "short-x.mcap", |s| {
        s[5].rods[1].x.pop();
    });
    refused3(
        &bad,
        &good,
        &[
            "step 5",
            "rod 1",
            "`x` has 29 numbers, expected 3 x 10 nodes",
        ],
    );
    let bad = edited(&good, "short-v.mcap", |s| {
        s[7].rods[0].v.truncate(3);
    });
    refused3(
        &bad,
        &good,
        &[
            "step 7",
            "rod 0",
            "`v` has 3 numbers, expected 3 x 10 nodes",
        ],
    );
}

/// Item 6: a NaN (or infinite) recorded number is refused, naming step, rod and node.
#[test]
fn item6_a_non_finite_recorded_number_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let bad = edited(&good, "nan.mcap", |s| s[9].rods[1].x[3 * 4 + 2] = f64::NAN);
    refused3(
        &bad,
        &good,
        &["step 9", "rod 1", "non-finite", "`x`[14] = NaN", "node 4"],
    );
    let bad = edited(&good, "inf.mcap", |s| s[3].rods[0].v[3 * 9] = f64::INFINITY);
    refused3(&bad, &good, &["step 3", "rod 0", "`v`[27] = inf", "node 9"]);
    let bad = edited(&good, "nan-theta.mcap", |s| {
        s[4].rods[0].theta[6] = f64::NAN
    });
    refused3(
        &bad,
        &good,
        &["step 4", "rod 0", "`theta`[6] = NaN", "edge 6"],
    );
    let bad = edited(&good, "nan-body.mcap", |s| {
        s[4].bodies[0].position[1] = f64::NAN
    });
    refused3(&bad, &good, &["step 4", "body 0", "`position`[1] = NaN"]);
}

/// Item 7: a newer format version, in `/sim/meta` and in the `gripsim` metadata record.
#[test]
fn item7_format_version_99_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let bad = edited_meta(&good, "v99.mcap", |m| m["format_version"] = 99.into());
    refused3(
        &bad,
        &good,
        &[
            "recorded with format version 99",
            "reads format version 3 and older",
        ],
    );
}

/// Item 7: steps swapped, a step recorded twice, dt ≤ 0.
#[test]
fn item7_steps_out_of_order_twice_or_without_time_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let bad = edited(&good, "swapped.mcap", |s| s.swap(5, 6));
    refused3(
        &bad,
        &good,
        &["step 5", "follows step 6", "steps must increase"],
    );
    let bad = edited(&good, "twice.mcap", |s| {
        let again = s[8].clone();
        s.insert(9, again);
    });
    refused3(
        &bad,
        &good,
        &["step 8", "follows step 8", "a step recorded twice"],
    );
    for (name, dt) in [("dt0.mcap", 0.0), ("dtneg.mcap", -1e-4)] {
        let bad = edited(&good, name, |s| s[4].dt = dt);
        refused3(
            &bad,
            &good,
            &["step 4", &format!("dt = {dt}"), "dt must be > 0"],
        );
    }
}

/// Item 7: a step with a rod missing or one too many, a node count unlike `/sim/meta`.
#[test]
fn item7_rods_and_nodes_unlike_the_metadata_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let bad = edited(&good, "missing.mcap", |s| {
        s[6].rods.pop();
    });
    refused3(&bad, &good, &["step 6", "has 1 rods, /sim/meta lists 2"]);
    let bad = edited(&good, "extra.mcap", |s| {
        let again = s[6].rods[0].clone();
        s[6].rods.push(again);
    });
    refused3(&bad, &good, &["step 6", "has 3 rods, /sim/meta lists 2"]);
    // A step whose rod 1 has 11 nodes in every array.
    let bad = edited(&good, "nodes.mcap", |s| {
        let r = &mut s[3].rods[1];
        for x in [&mut r.x, &mut r.v, &mut r.m1, &mut r.m2] {
            x.extend([0.0; 3]);
        }
        r.theta.push(0.0);
        r.twist.push(0.0);
    });
    refused3(
        &bad,
        &good,
        &[
            "step 3",
            "rod 1",
            "`x` has 33 numbers, expected 3 x 10 nodes",
        ],
    );
    // /sim/meta unlike the rods its own scenario builds.
    let bad = edited_meta(&good, "meta-nodes.mcap", |m| {
        m["rods"][1]["nodes"] = 11.into()
    });
    refused3(
        &bad,
        &good,
        &[
            "/sim/meta rods do not match its own scenario_text",
            "[10, 11]",
        ],
    );
    // Every step as /sim/meta says, but not what its own scenario builds.
    let bad = edited_meta(&good, "meta-scenario.mcap", |m| {
        m["scenario_text"] = m["scenario_text"]
            .as_str()
            .unwrap()
            .replace("nodes = 10", "nodes = 12")
            .into();
    });
    refused3(
        &bad,
        &good,
        &["/sim/meta rods do not match its own scenario_text"],
    );
    // A contact on a node the rod does not have.
    let bad = edited(&good, "contact-node.mcap", |s| {
        let mut c = gripsim::record::mcap3::ContactState3 {
            rod: 0,
            node: 99,
            ..Default::default()
        };
        c.point = vec![0.0; 3];
        s[2].contacts.push(c);
    });
    refused3(
        &bad,
        &good,
        &["step 2", "names node 99 of rod 0, which has 10 node(s)"],
    );
}

/// Item 7: a file with no `/sim/step` at all ("0 steps … clean", exit 0, before).
#[test]
fn item7_a_3d_recording_without_steps_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = record3(dir.path());
    let bad = edited(&good, "nosteps.mcap", |s| s.clear());
    refused3(&bad, &good, &["no /sim/step message"]);
}

/// A FIFO nobody writes to (and one a writer feeds) is refused at once, never waited on: a
/// replay reads its recording more than once (it blocked forever in `open`).
#[test]
fn a_fifo_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.mcap");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    for args in [&["check"][..], &["show", "--rrd", "x.rrd"][..]] {
        let mut child = gripsim()
            .current_dir(dir.path())
            .arg("replay")
            .arg(args[0])
            .arg(&fifo)
            .args(&args[1..])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break Some(s);
            }
            if start.elapsed().as_secs() > 60 {
                child.kill().unwrap();
                break None;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        };
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(status.and_then(|s| s.code()), Some(2), "{args:?}: {err}");
        assert!(err.contains("is a FIFO or a socket, not a file"), "{err}");
        assert!(!dir.path().join("x.rrd").exists());
    }
}

/// 3D or planar `replay check` as the CLI runs it, in process: the report as JSON (its
/// `file` left out), or the error (exit 2).
fn check_any(path: &Path) -> Result<serde_json::Value, String> {
    use gripsim::replay::{self, three};
    let th = replay::Thresholds::default();
    let mut v = if three::is_3d_mcap(path) {
        serde_json::to_value(three::check(path, &th).map_err(|e| e.to_string())?)
    } else {
        serde_json::to_value(replay::check(path, &th).map_err(|e| e.to_string())?.0)
    }
    .unwrap();
    v.as_object_mut().unwrap().remove("file");
    Ok(v)
}

/// What one damaged input gave: refused (exit 2), read up to named damage (exit 3), or the
/// undamaged file's report.
#[derive(Default, Debug)]
struct Outcomes {
    refused: usize,
    partial: usize,
    identical: usize,
}

impl Outcomes {
    /// Judge the damaged `bytes` against `pristine` (its report); panics on a different report
    /// that does not say it is incomplete.
    fn judge(&mut self, scratch: &Path, bytes: &[u8], pristine: &serde_json::Value, what: &str) {
        std::fs::write(scratch, bytes).unwrap();
        let got = std::panic::catch_unwind(|| check_any(scratch))
            .unwrap_or_else(|_| panic!("{what}: the reader panicked"));
        match got {
            Err(e) => {
                assert!(e.contains(&scratch.display().to_string()), "{what}: {e}");
                self.refused += 1;
            }
            Ok(v) if &v == pristine => self.identical += 1,
            Ok(v) => {
                assert!(
                    v["incomplete"] == true && v["truncated"].is_string(),
                    "{what}: a different report that does not say it is incomplete:\n{v:#}"
                );
                self.partial += 1;
            }
        }
    }
}

/// A fixed pseudo-random sequence (splitmix64).
struct Mix(u64);

impl Mix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// 200 single-bit flips of a 3D and of a planar recording (seeded): each is refused (exit 2),
/// read up to the damage it names (exit 3), or gives the undamaged file's report; never a
/// different report with exit 0 or 1, never a panic.
#[test]
fn random_bit_flips_are_refused_or_change_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let three = record3(dir.path());
    let planar = dir.path().join("planar.mcap");
    let out = gripsim()
        .arg("run")
        .arg(scenario("point-mass-plane-dt1e-4"))
        .args([
            "-q",
            "--detail",
            "step",
            "--set",
            "particle.0.position=[0.0, 0.00002]",
        ])
        .args(["--set", "solve.t_end=0.003", "--mcap"])
        .arg(&planar)
        .output()
        .unwrap();
    assert!(out.status.success());
    for (name, good, seed) in [("3D", &three, 34u64), ("planar", &planar, 35)] {
        let bytes = std::fs::read(good).unwrap();
        let scratch = dir.path().join(format!("flip-{name}.mcap"));
        std::fs::write(&scratch, &bytes).unwrap();
        let pristine = check_any(&scratch).unwrap();
        let mut rng = Mix(seed);
        let mut o = Outcomes::default();
        for k in 0..200 {
            let (at, bit) = (rng.below(bytes.len()), rng.below(8));
            let mut b = bytes.clone();
            b[at] ^= 1 << bit;
            o.judge(
                &scratch,
                &b,
                &pristine,
                &format!("{name} flip {k}: byte {at} bit {bit}"),
            );
        }
        println!(
            "{name} ({} bytes), 200 single-bit flips: {} refused (exit 2), {} read up to the \
             damage they name (exit 3), {} the undamaged file's report",
            bytes.len(),
            o.refused,
            o.partial,
            o.identical
        );
        assert_eq!(o.refused + o.partial + o.identical, 200);
        assert!(o.refused > 0 && o.identical > 0, "{o:?}");
    }
}

/// One deterministic mutation of `bytes`: a bit flip, a byte overwritten, a truncation, a
/// piece of the file copied over another place, or a byte repeated.
fn mutate(bytes: &[u8], kind: usize, rng: &mut Mix) -> Vec<u8> {
    let n = bytes.len();
    let mut b = bytes.to_vec();
    match kind {
        0 => b[rng.below(n)] ^= 1 << rng.below(8),
        1 => b[rng.below(n)] = rng.next() as u8,
        2 => b.truncate(rng.below(n)),
        3 => {
            let (from, to, len) = (rng.below(n), rng.below(n), 1 + rng.below(64));
            let piece = bytes[from..(from + len).min(n)].to_vec();
            let end = (to + piece.len()).min(n);
            b[to..end].copy_from_slice(&piece[..end - to]);
        }
        _ => {
            let (at, len) = (rng.below(n), 1 + rng.below(32));
            b.splice(at..at, std::iter::repeat_n(bytes[at], len));
        }
    }
    b
}

/// The bounded in-suite fuzz of the 3D reader (what CI runs; fuzz/fuzz_targets/replay_mcap3d.rs
/// runs it unbounded): 1 000 deterministic mutations of each 3D fuzz seed. The seed as gripsim
/// writes it (zstd chunks with CRCs): each mutation is refused, read up to the damage it
/// names, or read as the seed. The plain seed (no chunks, no CRC: a changed number there is
/// undetectable): never a panic, an error names the file.
#[test]
fn bounded_fuzz_of_the_3d_reader() {
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/replay_mcap3d");
    let dir = tempfile::tempdir().unwrap();
    let scratch = dir.path().join("fuzz3d.mcap");
    for (k, name) in ["two-finger.mcap", "two-finger-plain.mcap"]
        .iter()
        .enumerate()
    {
        let bytes = std::fs::read(seeds.join(name)).unwrap();
        std::fs::write(&scratch, &bytes).unwrap();
        let pristine = check_any(&scratch).unwrap();
        let mut rng = Mix(0x3d + k as u64);
        let mut o = Outcomes::default();
        let mut changed = 0;
        for m in 0..1000 {
            let b = mutate(&bytes, m % 5, &mut rng);
            let what = format!("{name} mutation {m} (kind {})", m % 5);
            if k == 0 {
                o.judge(&scratch, &b, &pristine, &what);
                continue;
            }
            std::fs::write(&scratch, &b).unwrap();
            match std::panic::catch_unwind(|| check_any(&scratch)) {
                Err(_) => panic!("{what}: the reader panicked"),
                Ok(Err(e)) => {
                    assert!(e.contains(&scratch.display().to_string()), "{what}: {e}");
                    o.refused += 1;
                }
                Ok(Ok(v)) if v == pristine => o.identical += 1,
                Ok(Ok(_)) => changed += 1,
            }
        }
        println!(
            "3D reader, 1000 mutations of {name} ({} bytes): {} refused, {} read up to the \
             damage, {} as the seed, {changed} read with other numbers (no CRC to find them)",
            bytes.len(),
            o.refused,
            o.partial,
            o.identical
        );
        assert_eq!(o.refused + o.partial + o.identical + changed, 1000);
    }
}
