//! The planar identity harness: every planar scenario of scenarios/ (each file without
//! `dimension = 3`) run in-process as `gripsim run` runs it, and compared with its digest in
//! tests/golden/planar/<scenario>.json:
//!
//! - `summary`: every field of the `--summary` JSON but `wall_time_s`, flattened to
//!   `path → value` (numbers in their shortest exact form, so equal text means equal bits);
//!   every field of the golden digest is compared, and a field the summary gained since is
//!   not (adding a key does not move a number);
//! - `fingerprints`: FNV-1a 64 ([`Fingerprint`]) over the exact f64 bits of every step's end
//!   (`StepEnd`), in three strands: `state` (step, t, dt, every rod's q and u, every free
//!   body's position, angle and velocities), `reactions` (every rod's eq. 2 reaction and drive
//!   force, every body's contact force and torque) and `contacts` (every active contact's rod,
//!   node, obstacle, body, segment, stick flag, normal and friction force and slip velocity);
//! - `checkpoints`: the `state` strand as it stood after steps 1, 2, 4, 8, …, so a difference
//!   names the first power of two by which the runs parted.
//!
//! Bit for bit: a change that means to move planar numbers re-blesses
//! (`GRIPSIM_BLESS=1 cargo test --release --test suite planar_identity`) and says why in its
//! commit (docs/verification.md). All 16 scenarios run to their own `t_end` (≈ 5 s together).

use gripsim::events::{Event, Fanout, Observer};
use gripsim::record::accepted::AcceptedContacts;
use gripsim::record::proto::Fingerprint;
use gripsim::record::summary::SummaryCollector;
use gripsim::{Scenario, Simulation};
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};

/// The step-end digests of a run.
#[derive(Default)]
struct Digest {
    steps: u64,
    state: Fingerprint,
    reactions: Fingerprint,
    contacts: Fingerprint,
    checkpoints: Vec<(u64, u64)>,
}

impl Observer for Digest {
    fn on_event(&mut self, event: &Event<'_>) {
        let Event::StepEnd {
            step,
            t,
            dt,
            rods,
            bodies,
            contacts,
            ..
        } = *event
        else {
            return;
        };
        self.steps += 1;
        let (s, r, c) = (&mut self.state, &mut self.reactions, &mut self.contacts);
        s.add_all(&[step as f64, t, dt]);
        for rod in rods {
            s.add_all(rod.q);
            s.add_all(rod.u);
            r.add_all(rod.reaction);
            r.add_all(rod.drive_force);
        }
        for b in bodies {
            s.add_all(&b.position[..2]);
            s.add_all(&[b.angle, b.velocity[0], b.velocity[1], b.angular_velocity[2]]);
            r.add_all(&b.contact_force[..2]);
            r.add(b.contact_torque[2]);
        }
        for k in contacts {
            let index = |i: usize| if i == usize::MAX { -1.0 } else { i as f64 };
            c.add_all(&[
                index(k.rod),
                index(k.node),
                index(k.obstacle),
                index(k.body),
                index(k.segment),
                f64::from(u8::from(k.stuck)),
                k.normal_force,
                k.friction_force,
                k.slip_velocity,
            ]);
        }
        if self.steps.is_power_of_two() {
            self.checkpoints.push((self.steps, self.state.0));
        }
    }
}

/// Every leaf of `v` under its path (`rods[0].final_positions[3][1]`), as JSON text.
fn flatten(v: &Value, path: String, out: &mut Map<String, Value>) {
    match v {
        Value::Object(o) => {
            for (k, x) in o {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                flatten(x, p, out);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                flatten(x, format!("{path}[{i}]"), out);
            }
        }
        leaf => {
            out.insert(path, leaf.clone());
        }
    }
}

fn hex(x: u64) -> Value {
    Value::String(format!("{x:#018x}"))
}

/// Run one scenario as `gripsim run` does (summary collector behind the accepted-steps
/// filter) and give its digest file's contents.
fn digest(path: &Path) -> Value {
    let sc = Scenario::load(path, &[]).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut sim = Simulation::new(&sc);
    let mut collector = SummaryCollector::new();
    let mut d = Digest::default();
    {
        let mut fan = Fanout::new();
        fan.push(&mut collector as &mut dyn Observer);
        fan.push(&mut d as &mut dyn Observer);
        let mut accepted = AcceptedContacts::new(fan);
        sim.run(&mut accepted)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
    let mut summary = serde_json::to_value(collector.finish(&sim.stats, 0.0)).unwrap();
    summary.as_object_mut().unwrap().remove("wall_time_s");
    let mut flat = Map::new();
    flatten(&summary, String::new(), &mut flat);
    let checkpoints = d
        .checkpoints
        .iter()
        .map(|&(s, h)| Value::String(format!("step {s}: {h:#018x}")))
        .collect();
    serde_json::json!({
        "scenario": sc.name,
        "step_ends": d.steps,
        "fingerprints": {
            "state": hex(d.state.0),
            "reactions": hex(d.reactions.0),
            "contacts": hex(d.contacts.0),
        },
        "checkpoints": Value::Array(checkpoints),
        "summary": Value::Object(flat),
    })
}

/// The planar scenarios of scenarios/ (no `dimension = 3`), by name.
fn planar_scenarios(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let text = std::fs::read_to_string(&p).unwrap();
        let doc: toml::Table = text
            .parse()
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        if doc.get("dimension").and_then(toml::Value::as_integer) == Some(3) {
            continue;
        }
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        out.push((name, p));
    }
    out.sort();
    out
}

/// What differs between the golden digest and this run's, one line each (at most 12 summary
/// fields).
fn differences(then: &Value, now: &Value) -> Vec<String> {
    let mut out = Vec::new();
    if then["step_ends"] != now["step_ends"] {
        out.push(format!(
            "step_ends: {} then, {} now",
            then["step_ends"], now["step_ends"]
        ));
    }
    for k in ["state", "reactions", "contacts"] {
        let (a, b) = (&then["fingerprints"][k], &now["fingerprints"][k]);
        if a != b {
            out.push(format!("fingerprint {k}: {a} then, {b} now"));
        }
    }
    let (a, b) = (
        then["checkpoints"].as_array(),
        now["checkpoints"].as_array(),
    );
    if let (Some(a), Some(b)) = (a, b) {
        if let Some((x, _)) = a.iter().zip(b).find(|(x, y)| x != y) {
            let at = x.as_str().and_then(|s| s.split(':').next()).unwrap_or("?");
            out.push(format!("the state first differs by {at}"));
        }
    }
    let empty = Map::new();
    let (a, b) = (
        then["summary"].as_object().unwrap_or(&empty),
        now["summary"].as_object().unwrap_or(&empty),
    );
    // The golden digest's fields (a new summary key is not a moved number).
    let keys: std::collections::BTreeSet<&String> = a.keys().collect();
    let mut fields = keys
        .into_iter()
        .filter(|k| a.get(*k).map(Value::to_string) != b.get(*k).map(Value::to_string));
    for k in fields.by_ref().take(12) {
        let show = |v: Option<&Value>| v.map_or("(absent)".to_string(), Value::to_string);
        out.push(format!(
            "summary {k}: {} then, {} now",
            show(a.get(k)),
            show(b.get(k))
        ));
    }
    let more = fields.count();
    if more > 0 {
        out.push(format!("… and {more} more summary fields"));
    }
    out
}

#[test]
fn planar_identity() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let golden = root.join("tests/golden/planar");
    let bless = std::env::var("GRIPSIM_BLESS").is_ok_and(|v| v == "1");
    let scenarios = planar_scenarios(&root.join("scenarios"));
    assert!(
        scenarios.len() >= 16,
        "{} planar scenarios",
        scenarios.len()
    );
    let mut failures = Vec::new();
    for (name, path) in &scenarios {
        let now = digest(path);
        let file = golden.join(format!("{name}.json"));
        if bless {
            std::fs::create_dir_all(&golden).unwrap();
            let mut text = serde_json::to_string_pretty(&now).unwrap();
            text.push('\n');
            std::fs::write(&file, text).unwrap();
            println!("{name}: blessed ({} step ends)", now["step_ends"]);
            continue;
        }
        let Ok(text) = std::fs::read_to_string(&file) else {
            failures.push(format!(
                "{name}: no {} (bless with GRIPSIM_BLESS=1)",
                file.display()
            ));
            continue;
        };
        let then: Value = serde_json::from_str(&text).unwrap();
        let diff = differences(&then, &now);
        if diff.is_empty() {
            println!("{name}: identical ({} step ends)", now["step_ends"]);
        } else {
            failures.push(format!("{name}:\n  {}", diff.join("\n  ")));
        }
    }
    for e in std::fs::read_dir(&golden).into_iter().flatten() {
        let p = e.unwrap().path();
        let stem = p
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        if !scenarios.iter().any(|(n, _)| *n == stem) {
            failures.push(format!("{}: no planar scenario of that name", p.display()));
        }
    }
    assert!(
        failures.is_empty(),
        "planar numbers moved (re-bless only for a change meant to move them, saying why in \
         the commit: GRIPSIM_BLESS=1 cargo test --release --test suite planar_identity):\n{}",
        failures.join("\n")
    );
}
