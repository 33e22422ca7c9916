//! Reading a 3D run's MCAP (`/sim/meta` `gripsim.Meta3`, `/sim/step` `gripsim.Step3`,
//! src/record/mcap3.rs) through replay's guarded streaming record reader
//! ([`super::read::read_raw`]: chunk CRCs checked, records bounded, one chunk in memory), each
//! step checked with the planar reader's rules ([`super::read`]: format version, step order,
//! clock, rods against `/sim/meta`, array lengths, finite numbers) before anything is reported.
//! Only what is 3D here: the schema names and the arrays of a `gripsim.Step3`.

use super::read::{
    check_clock, check_finite, check_format, check_len, check_order, check_rod_count, read_raw,
    unreadable, wrong_schema, Raw, NO_STEP,
};
use super::ReplayError;
use crate::record::mcap3::{Step3, FORMAT_VERSION3};
use std::path::Path;

/// The channels a 3D replay needs, with the schema each must have.
const REQUIRED3: [(&str, &str); 3] = [
    ("/sim/meta", "gripsim.Meta3"),
    ("/sim/step", "gripsim.Step3"),
    ("/sim/event", "gripsim.Event"),
];

/// `/sim/meta` of a 3D run, the fields a replay uses.
#[derive(Debug, Clone, serde::Deserialize)]
pub struct Meta3In {
    pub scenario_name: String,
    pub scenario_text: String,
    #[serde(default)]
    pub sets: Vec<String>,
    pub rods: Vec<RodIn>,
    #[serde(default)]
    pub shapes: Vec<ShapeIn>,
}

#[derive(Debug, Clone, serde::Deserialize)]
pub struct RodIn {
    pub name: String,
    pub nodes: usize,
}

#[derive(Debug, Clone, serde::Deserialize)]
pub struct ShapeIn {
    pub name: String,
    #[serde(default)]
    pub mesh_hash: Option<String>,
}

#[derive(serde::Deserialize)]
struct EventIn {
    kind: String,
    #[serde(default)]
    completed: Option<bool>,
    #[serde(default)]
    error: Option<String>,
}

/// A decoded, checked message of a 3D recording, in file order.
pub enum Message3 {
    Meta(Box<Meta3In>),
    Step(Box<Step3>),
    /// The run's end: whether it completed, and why not.
    End(Option<bool>, Option<String>),
}

/// Read the 3D recording `path` message by message and hand each checked one to `visit`.
/// Returns why the file was read only in part (None: whole). Errors name the file and what
/// is wrong where (step, rod, node); a file that stops early after at least one step is read
/// up to there.
pub fn read3(
    path: &Path,
    mut visit: impl FnMut(Message3) -> Result<(), ReplayError>,
) -> Result<Option<String>, ReplayError> {
    let err = |m: String| ReplayError::file(path, m);
    let mut topics: Vec<String> = Vec::new();
    let mut meta: Option<(Vec<usize>, usize)> = None;
    let mut last: Option<(u64, f64)> = None;
    let mut steps = 0u64;
    let end = read_raw(path, |raw| match raw {
        Raw::Channel {
            topic,
            encoding,
            schema,
            ..
        } => {
            if let Some((_, want)) = REQUIRED3.iter().find(|(t, _)| *t == topic) {
                if schema.map(|s| s.0) != Some(*want) {
                    return Err(wrong_schema(path, topic, want, schema, encoding));
                }
            }
            topics.push(topic.to_string());
            Ok(())
        }
        Raw::Metadata(m) if m.name == "gripsim" => check_format(
            path,
            m.metadata.get("format_version").map(|s| s.as_str()),
            m.metadata.get("gripsim_version").map(|s| s.as_str()),
            FORMAT_VERSION3,
        ),
        Raw::Metadata(_) => Ok(()),
        Raw::Message { topic, data, .. } => match topic {
            "/sim/meta" => {
                if meta.is_some() {
                    return Err(err("a second /sim/meta message".into()));
                }
                let m = read_meta(path, data)?;
                meta = Some((m.rods.iter().map(|r| r.nodes).collect(), m.shapes.len()));
                visit(Message3::Meta(Box::new(m)))
            }
            "/sim/step" => {
                let Some((nodes, shapes)) = meta.as_ref() else {
                    return Err(err("a /sim/step message before /sim/meta".into()));
                };
                use prost::Message as _;
                let s = Step3::decode(data).map_err(|e| {
                    err(format!(
                        "/sim/step message {} does not match schema gripsim.Step3: {e}",
                        steps + 1
                    ))
                })?;
                check_step3(&s, nodes, *shapes).map_err(err)?;
                check_order(last, s.step, s.t).map_err(err)?;
                last = Some((s.step, s.t));
                steps += 1;
                visit(Message3::Step(Box::new(s)))
            }
            "/sim/event" => {
                let e: EventIn =
                    serde_json::from_slice(data).map_err(|e| err(format!("/sim/event: {e}")))?;
                if e.kind == "run_end" {
                    return visit(Message3::End(e.completed, e.error));
                }
                Ok(())
            }
            _ => Ok(()),
        },
    })?;
    if let Some(e) = &end.error {
        if steps == 0 {
            return Err(err(unreadable(e)));
        }
    }
    if steps == 0 && end.error.is_none() && meta.is_some() {
        return Err(err(NO_STEP.into()));
    }
    for (topic, schema) in REQUIRED3 {
        if !topics.iter().any(|t| t == topic) {
            return Err(err(format!(
                "missing channel {topic} (schema {schema}): not a gripsim 3D recording, or \
                 one cut before the channel was written"
            )));
        }
    }
    if meta.is_none() {
        return Err(err("no /sim/meta message: not a gripsim 3D run".into()));
    }
    if steps == 0 {
        return Err(err(NO_STEP.into()));
    }
    Ok(end.truncated())
}

/// `/sim/meta`: its format version known, its rods named with at least 2 nodes each.
fn read_meta(path: &Path, data: &[u8]) -> Result<Meta3In, ReplayError> {
    let err = |m: String| ReplayError::file(path, m);
    let raw: serde_json::Value =
        serde_json::from_slice(data).map_err(|e| err(format!("/sim/meta is not JSON: {e}")))?;
    check_format(
        path,
        raw.get("format_version").map(|v| v.to_string()).as_deref(),
        raw.get("gripsim_version").and_then(|v| v.as_str()),
        FORMAT_VERSION3,
    )?;
    let m: Meta3In = serde_json::from_value(raw).map_err(|e| {
        err(format!(
            "/sim/meta does not match schema gripsim.Meta3: {e}"
        ))
    })?;
    if m.rods.is_empty() {
        return Err(err("/sim/meta lists no rods".into()));
    }
    if let Some((r, rod)) = m.rods.iter().enumerate().find(|(_, r)| r.nodes < 2) {
        return Err(err(format!(
            "/sim/meta rod {r} ({:?}) has {} node(s), at least 2 expected",
            rod.name, rod.nodes
        )));
    }
    Ok(m)
}

/// A `gripsim.Step3` against `/sim/meta` (`nodes` per rod, `shapes`): the planar rules on its
/// clock, rods, array lengths and numbers; contacts, changes and bodies name rods, nodes and
/// shapes that exist.
fn check_step3(s: &Step3, nodes: &[usize], shapes: usize) -> Result<(), String> {
    let at = format!("/sim/step step {} (t = {} s)", s.step, s.t);
    check_clock(&at, s.t, s.dt, s.step > 0)?;
    check_rod_count(&at, s.rods.len(), nodes.len())?;
    for (r, (rod, &n)) in s.rods.iter().zip(nodes).enumerate() {
        let at = format!("{at} rod {r}");
        let arrays: [(&str, &[f64], usize, usize, &str); 6] = [
            ("x", &rod.x, 3, n, "node"),
            ("v", &rod.v, 3, n, "node"),
            ("theta", &rod.theta, 1, n - 1, "edge"),
            ("twist", &rod.twist, 1, n, "node"),
            ("m1", &rod.m1, 3, n - 1, "edge"),
            ("m2", &rod.m2, 3, n - 1, "edge"),
        ];
        for (name, x, per, count, unit) in arrays {
            check_len(&at, name, x.len(), per, count, unit)?;
            check_finite(&at, name, x, per, unit)?;
        }
    }
    for (k, c) in s.contacts.iter().enumerate() {
        let at = format!("{at} contact {k}");
        check_place(&at, c.rod, c.node, nodes)?;
        check_shape(&at, c.shape, shapes)?;
        for (name, x) in [
            ("point", &c.point),
            ("normal", &c.normal),
            ("reaction", &c.reaction),
            ("friction", &c.friction),
        ] {
            check_len(&at, name, x.len(), 3, 1, "point")?;
            check_finite(&at, name, x, 3, "point")?;
        }
        check_finite(
            &at,
            "gap, normal_force, weight",
            &[c.gap, c.normal_force, c.weight],
            3,
            "contact",
        )?;
    }
    for c in &s.changes {
        check_place(&format!("{at} contact change"), c.rod, c.node, nodes)?;
    }
    for (k, b) in s.bodies.iter().enumerate() {
        let at = format!("{at} body {k}");
        check_shape(&at, b.shape, shapes)?;
        for (name, x, per) in [
            ("position", &b.position, 3),
            ("rotation", &b.rotation, 4),
            ("velocity", &b.velocity, 3),
            ("angular_velocity", &b.angular_velocity, 3),
        ] {
            check_len(&at, name, x.len(), per, 1, "body")?;
            check_finite(&at, name, x, per, "body")?;
        }
    }
    Ok(())
}

/// A rod and node of the run.
fn check_place(at: &str, rod: u64, node: u64, nodes: &[usize]) -> Result<(), String> {
    match usize::try_from(rod).ok().and_then(|r| nodes.get(r)) {
        None => Err(format!(
            "{at} names rod {rod}, but the run has {} rod(s)",
            nodes.len()
        )),
        Some(&n) if node >= n as u64 => Err(format!(
            "{at} names node {node} of rod {rod}, which has {n} node(s)"
        )),
        _ => Ok(()),
    }
}

/// A shape `/sim/meta` lists.
fn check_shape(at: &str, shape: u64, shapes: usize) -> Result<(), String> {
    if shape >= shapes as u64 {
        return Err(format!(
            "{at} names shape {shape}, but /sim/meta lists {shapes} shape(s)"
        ));
    }
    Ok(())
}
