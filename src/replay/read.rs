//! Reading a recorded run back from its MCAP file (docs/recording-format.md).
//!
//! The file is read linearly, record by record, chunks decompressed and their CRCs checked, so
//! a file without a summary or footer (a run killed by SIGKILL, a crash) is read up to its last
//! complete chunk. Every message is checked against what the rest of the code indexes with
//! (array lengths, rod and node numbers), so a damaged or foreign file gives a
//! [`ReplayError`] that names the file, never a panic.

use super::ReplayError;
use crate::events::{ContactChange, Phase, ReleaseReason, RodInfo};
use crate::record::mcap::FORMAT_VERSION;
use crate::record::proto;
use crate::scenario::{Mode, Scenario};
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// The channels a replay needs, with the schema each must have.
pub const REQUIRED: [(&str, &str); 4] = [
    ("/sim/meta", "gripsim.Meta"),
    ("/sim/step", "gripsim.Step"),
    ("/sim/contact", "gripsim.Contact"),
    ("/sim/event", "gripsim.Event"),
];

/// `/sim/meta`, the fields a replay uses.
#[derive(Debug, Clone, Deserialize)]
pub struct Meta {
    pub format_version: u32,
    #[serde(default)]
    pub gripsim_version: String,
    pub scenario_name: String,
    pub scenario_text: String,
    pub mode: String,
    #[serde(default)]
    pub detail: String,
    /// `f32` or `f64`: the per-node numbers of `/sim/step` (format 4; older files: `f64`).
    #[serde(default = "exact")]
    pub precision: String,
    #[serde(default)]
    pub flush_every: u64,
    /// `detail` = auto: every k-th step outside the windows, and the window (steps).
    #[serde(default)]
    pub auto_every: Option<u64>,
    #[serde(default)]
    pub auto_window: Option<u64>,
    pub rods: Vec<RodMeta>,
}

fn exact() -> String {
    "f64".into()
}

impl Meta {
    /// The per-node numbers of `/sim/step` are f32-rounded (format 4 at the default precision).
    pub fn f32(&self) -> bool {
        self.precision == "f32"
    }
}

/// One entry of `/sim/meta` `rods[]`.
#[derive(Debug, Clone, Deserialize)]
pub struct RodMeta {
    pub name: String,
    pub nodes: usize,
    pub mass: Vec<f64>,
    pub clamped: Vec<bool>,
    pub rest_length: Vec<f64>,
    pub rest_curvature: Vec<f64>,
    pub youngs_modulus: f64,
    pub area: f64,
    pub inertia: f64,
    pub half_height: f64,
    #[serde(default)]
    pub particle: bool,
}

impl RodMeta {
    pub fn info(&self) -> RodInfo {
        RodInfo {
            name: self.name.clone(),
            nodes: self.nodes,
            mass: self.mass.clone(),
            clamped: self.clamped.clone(),
            rest_length: self.rest_length.clone(),
            rest_curvature: self.rest_curvature.clone(),
            youngs_modulus: self.youngs_modulus,
            area: self.area,
            inertia: self.inertia,
            half_height: self.half_height,
            particle: self.particle,
        }
    }
}

/// One `/sim/step` message.
#[derive(Debug, Clone, Deserialize)]
pub struct Step {
    pub step: u64,
    pub t: f64,
    pub dt: f64,
    #[serde(default)]
    pub newton_iterations: u32,
    #[serde(default)]
    pub passes: u32,
    pub rods: Vec<RodState>,
    /// Free bodies and active contacts (recordings with a free fruit).
    #[serde(default)]
    pub bodies: Vec<BodyState>,
    #[serde(default)]
    pub contacts: Vec<ContactState>,
    /// The 64-bit fingerprint of the step's exact state (format 4: FNV-1a of the f64 bits of
    /// every rod's q and u and every body's state, `record::proto::Fingerprint`); None in older
    /// files.
    #[serde(default)]
    pub fingerprint: Option<u64>,
}

/// A free body of a `/sim/step` message (what replay uses of it).
#[derive(Debug, Clone, Deserialize)]
pub struct BodyState {
    pub obstacle: usize,
    pub position: [f64; 2],
    #[serde(default)]
    pub velocity: [f64; 2],
}

/// An active contact of a `/sim/step` message (what replay uses of it).
#[derive(Debug, Clone, Deserialize)]
pub struct ContactState {
    pub rod: Option<usize>,
    pub obstacle: usize,
    /// The node, and a compliant fruit's Hertz peak pressure, bruise threshold and the
    /// half-width above it (0 in recordings without them, and at rigid obstacles).
    #[serde(default)]
    pub node: usize,
    #[serde(default)]
    pub peak_pressure: f64,
    #[serde(default)]
    pub bruise_pressure: f64,
    #[serde(default)]
    pub bruise_half_width: f64,
    /// The contact point (m; on the fruit's surface for its own contact).
    #[serde(default)]
    pub point: [f64; 2],
}

impl Step {
    /// Feed the grasp rules of `d` with this step (after `d.step`).
    pub fn grasp(&self, d: &mut super::detect::Detector) {
        if let Some(b) = self.bodies.first() {
            let q: Vec<&[f64]> = self.rods.iter().map(|r| r.q.as_slice()).collect();
            let touching = self
                .contacts
                .iter()
                .any(|c| c.rod.is_some() && c.obstacle == b.obstacle);
            d.grasp(self.step, self.t, &q, Some(b.position), touching);
        }
    }

    /// Feed the bruise rule of `d` with this step's compliant contacts (after `d.step`).
    pub fn pressure(&self, d: &mut super::detect::Detector) {
        let samples: Vec<super::bruise::PressureSample> = self
            .contacts
            .iter()
            .filter(|c| c.peak_pressure > 0.0)
            // A free fruit's own contact (no rod) is a place of its own: node = the body.
            .map(|c| super::bruise::PressureSample {
                rod: c.rod.unwrap_or(usize::MAX),
                node: c.node,
                obstacle: c.obstacle,
                peak_pressure: c.peak_pressure,
                bruise_pressure: c.bruise_pressure,
                bruise_half_width: c.bruise_half_width,
            })
            .collect();
        if !samples.is_empty() {
            d.pressure(self.step, self.t, &samples);
        }
    }
}

/// One rod of a `/sim/step` message (interleaved vectors `[x0, y0, x1, y1, …]`).
#[derive(Debug, Clone, Deserialize)]
pub struct RodState {
    pub q: Vec<f64>,
    pub u: Vec<f64>,
    pub reaction: Vec<f64>,
    pub impulse: Vec<f64>,
    pub drive_force: Vec<f64>,
    pub normal: Vec<f64>,
    pub in_contact: Vec<bool>,
    pub contact_obstacle: Vec<Option<usize>>,
    pub bending_stress: Vec<f64>,
    /// `null` (no obstacle) is read as +∞.
    #[serde(deserialize_with = "nullable_f64s")]
    pub gap: Vec<f64>,
    pub q_predictor: Vec<f64>,
    /// The second surface of a corner (absent in recordings from before it was recorded).
    #[serde(default)]
    pub normal2: Vec<f64>,
    #[serde(default)]
    pub contact_obstacle2: Vec<Option<usize>>,
}

impl RodState {
    /// `normal2`, zeros when the recording has none.
    pub fn normal2_or_zero(&self) -> Vec<f64> {
        if self.normal2.len() == self.q.len() {
            self.normal2.clone()
        } else {
            vec![0.0; self.q.len()]
        }
    }

    /// What the detector reads of this rod.
    pub fn sample(&self) -> super::detect::RodSample<'_> {
        super::detect::RodSample {
            q: &self.q,
            u: &self.u,
            reaction: &self.reaction,
            normal: &self.normal,
            normal2: &self.normal2,
            in_contact: &self.in_contact,
            q_predictor: &self.q_predictor,
        }
    }
}

fn nullable_f64s<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    let v: Vec<Option<f64>> = Vec::deserialize(d)?;
    Ok(v.into_iter().map(|x| x.unwrap_or(f64::INFINITY)).collect())
}

/// One `/sim/contact` message.
#[derive(Debug, Clone, Deserialize)]
pub struct Contact {
    /// `added` or `released`.
    pub change: String,
    #[serde(default)]
    pub reason: Option<String>,
    pub step: u64,
    pub t: f64,
    #[serde(default)]
    pub pass: u32,
    pub rod: usize,
    pub node: usize,
    pub obstacle: usize,
    pub normal: [f64; 2],
    pub gap: f64,
    pub reaction: [f64; 2],
    pub z: f64,
}

impl Contact {
    pub fn added(&self) -> bool {
        self.change == "added"
    }

    pub fn change(&self) -> ContactChange {
        ContactChange {
            step: self.step,
            t: self.t,
            pass: self.pass,
            rod: self.rod,
            node: self.node,
            obstacle: self.obstacle,
            normal: crate::events::v3(self.normal),
            gap: self.gap,
            reaction: crate::events::v3(self.reaction),
            z: self.z,
        }
    }

    /// Why it was released (`adhesive`, or `handed_over` to an edge contact).
    pub fn release_reason(&self) -> ReleaseReason {
        match self.reason.as_deref() {
            Some("handed_over") => ReleaseReason::HandedOver,
            _ => ReleaseReason::Adhesive,
        }
    }

    /// What the detector reads of this change.
    pub fn sample(&self) -> super::detect::ContactSample {
        super::detect::ContactSample::of(&self.change(), self.added())
    }
}

/// One `/sim/event` message.
#[derive(Debug, Clone, Deserialize)]
pub struct SimEvent {
    pub kind: String,
    pub step: u64,
    pub t: f64,
    pub message: String,
    pub old_dt: Option<f64>,
    pub new_dt: Option<f64>,
    pub reason: Option<String>,
    pub dt: Option<f64>,
    pub rod: Option<usize>,
    pub node: Option<usize>,
    pub residual: Option<f64>,
    pub completed: Option<bool>,
    #[serde(default)]
    pub error: Option<String>,
}

/// One `/sim/iteration` message.
#[derive(Debug, Clone, Deserialize)]
pub struct Iteration {
    pub step: u64,
    pub t: f64,
    pub phase: Phase,
    pub pass: u32,
    pub iteration: u32,
    pub rod: usize,
    pub residual: f64,
    pub update: f64,
    pub q: Vec<f64>,
}

/// An index of the protobuf encoding: −1 is none.
fn pb_index(k: i64) -> Option<usize> {
    usize::try_from(k).ok()
}

/// Two numbers, or why not.
fn pair(what: &str, v: &[f64]) -> Result<[f64; 2], String> {
    <[f64; 2]>::try_from(v).map_err(|_| format!("`{what}` has {} numbers, expected 2", v.len()))
}

/// The f64 values of f32 ones.
fn wide(v: Vec<f32>) -> Vec<f64> {
    v.into_iter().map(f64::from).collect()
}

impl From<proto::Rod> for RodState {
    fn from(r: proto::Rod) -> Self {
        RodState {
            q: wide(r.q),
            u: wide(r.u),
            reaction: wide(r.reaction),
            impulse: wide(r.impulse),
            drive_force: wide(r.drive_force),
            normal: wide(r.normal),
            in_contact: r.in_contact,
            contact_obstacle: r.contact_obstacle.into_iter().map(pb_index).collect(),
            bending_stress: wide(r.bending_stress),
            gap: wide(r.gap),
            q_predictor: wide(r.q_predictor),
            normal2: wide(r.normal2),
            contact_obstacle2: r.contact_obstacle2.into_iter().map(pb_index).collect(),
        }
    }
}

impl From<proto::Rod64> for RodState {
    fn from(r: proto::Rod64) -> Self {
        RodState {
            q: r.q,
            u: r.u,
            reaction: r.reaction,
            impulse: r.impulse,
            drive_force: r.drive_force,
            normal: r.normal,
            in_contact: r.in_contact,
            contact_obstacle: r.contact_obstacle.into_iter().map(pb_index).collect(),
            bending_stress: r.bending_stress,
            gap: r.gap,
            q_predictor: r.q_predictor,
            normal2: r.normal2,
            contact_obstacle2: r.contact_obstacle2.into_iter().map(pb_index).collect(),
        }
    }
}

impl TryFrom<proto::Step> for Step {
    type Error = String;
    fn try_from(s: proto::Step) -> Result<Self, String> {
        let rods = s.rods.into_iter().map(RodState::from).collect();
        let head = (s.step, s.t, s.dt, s.newton_iterations, s.passes);
        let contacts = s.contacts.iter().map(ContactState::from).collect();
        step_from(head, rods, &s.bodies, contacts, Some(s.fingerprint))
    }
}

impl TryFrom<proto::Step64> for Step {
    type Error = String;
    /// Also a format 3 file's `gripsim.Step` (the same layout without the fingerprint).
    fn try_from(s: proto::Step64) -> Result<Self, String> {
        let rods = s.rods.into_iter().map(RodState::from).collect();
        let head = (s.step, s.t, s.dt, s.newton_iterations, s.passes);
        let fingerprint = (s.fingerprint != 0).then_some(s.fingerprint);
        let contacts = s.contacts.iter().map(ContactState::from).collect();
        step_from(head, rods, &s.bodies, contacts, fingerprint)
    }
}

impl From<&proto::Contact> for ContactState {
    fn from(c: &proto::Contact) -> Self {
        ContactState {
            rod: pb_index(c.rod),
            obstacle: c.obstacle as usize,
            node: c.node as usize,
            peak_pressure: c.peak_pressure.into(),
            bruise_pressure: c.bruise_pressure.into(),
            bruise_half_width: c.bruise_half_width.into(),
            point: point(&c.point),
        }
    }
}

impl From<&proto::Contact64> for ContactState {
    fn from(c: &proto::Contact64) -> Self {
        ContactState {
            rod: pb_index(c.rod),
            obstacle: c.obstacle as usize,
            node: c.node as usize,
            peak_pressure: c.peak_pressure,
            bruise_pressure: c.bruise_pressure,
            bruise_half_width: c.bruise_half_width,
            point: point(&c.point),
        }
    }
}

/// A recorded point (0 where the message has none).
fn point<T: Copy + Into<f64>>(p: &[T]) -> [f64; 2] {
    let at = |k: usize| p.get(k).map_or(0.0, |&x| x.into());
    [at(0), at(1)]
}

/// A step from its decoded parts (step, t, dt, Newton iterations, passes).
fn step_from(
    (step, t, dt, newton_iterations, passes): (u64, f64, f64, u32, u32),
    rods: Vec<RodState>,
    bodies: &[proto::Body],
    contacts: Vec<ContactState>,
    fingerprint: Option<u64>,
) -> Result<Step, String> {
    let bodies = bodies
        .iter()
        .map(|b| {
            Ok(BodyState {
                obstacle: b.obstacle as usize,
                position: pair("position", &b.position)?,
                velocity: pair("velocity", &b.velocity)?,
            })
        })
        .collect::<Result<_, String>>()?;
    Ok(Step {
        step,
        t,
        dt,
        newton_iterations,
        passes,
        rods,
        bodies,
        contacts,
        fingerprint,
    })
}

impl TryFrom<proto::Iteration> for Iteration {
    type Error = String;
    fn try_from(i: proto::Iteration) -> Result<Self, String> {
        let head = (
            i.step,
            i.t,
            i.pass,
            i.iteration,
            i.rod,
            i.residual,
            i.update,
        );
        iteration_from(head, &i.phase, wide(i.q))
    }
}

impl TryFrom<proto::Iteration64> for Iteration {
    type Error = String;
    /// Also a format 3 file's `gripsim.Iteration` (the same layout).
    fn try_from(i: proto::Iteration64) -> Result<Self, String> {
        let head = (
            i.step,
            i.t,
            i.pass,
            i.iteration,
            i.rod,
            i.residual,
            i.update,
        );
        iteration_from(head, &i.phase, i.q)
    }
}

/// An iteration from its decoded parts (step, t, pass, iteration, rod, residual, update).
fn iteration_from(
    (step, t, pass, iteration, rod, residual, update): (u64, f64, u32, u32, u64, f64, f64),
    phase: &str,
    q: Vec<f64>,
) -> Result<Iteration, String> {
    let phase = match phase {
        "predictor" => Phase::Predictor,
        "corrector" => Phase::Corrector,
        "static" => Phase::Static,
        other => return Err(format!("unknown phase {other:?}")),
    };
    Ok(Iteration {
        step,
        t,
        phase,
        pass,
        iteration,
        rod: usize::try_from(rod).map_err(|_| format!("rod {rod}"))?,
        residual,
        update,
        q,
    })
}

/// A decoded message, in file order.
#[derive(Debug, Clone)]
pub enum Message {
    Meta(Box<Meta>),
    Step(Step),
    Contact(Contact),
    Event(SimEvent),
    Iteration(Iteration),
}

/// What the linear read found besides the messages.
#[derive(Debug, Clone, Default)]
pub struct ReadStatus {
    /// Why reading stopped before the end of a whole file (no summary or footer, a damaged
    /// chunk): the data are complete up to the last complete chunk.
    pub truncated: Option<String>,
    /// The `gripsim.run_end` metadata record (missing after a kill).
    pub run_end: Option<BTreeMap<String, String>>,
}

/// The setting the messages are checked against, known once `/sim/meta` is read.
struct Shape {
    nodes: Vec<usize>,
    obstacles: usize,
}

fn check_step(s: &Step, shape: &Shape) -> Result<(), String> {
    let at = format!("/sim/step step {}", s.step);
    check_rod_count(&at, s.rods.len(), shape.nodes.len())?;
    check_clock(&at, s.t, s.dt, false)?;
    for (r, (v, &n)) in s.rods.iter().zip(&shape.nodes).enumerate() {
        let at = format!("/sim/step step {} rod {r}", s.step);
        if !v.normal2.is_empty() {
            check_len(&at, "normal2", v.normal2.len(), 2, n, "node")?;
        }
        if !v.contact_obstacle2.is_empty() {
            check_len(
                &at,
                "contact_obstacle2",
                v.contact_obstacle2.len(),
                1,
                n,
                "node",
            )?;
        }
        check_finite(&at, "normal2", &v.normal2, 2, "node")?;
        let vectors: [(&str, &[f64]); 7] = [
            ("q", &v.q),
            ("u", &v.u),
            ("reaction", &v.reaction),
            ("impulse", &v.impulse),
            ("drive_force", &v.drive_force),
            ("normal", &v.normal),
            ("q_predictor", &v.q_predictor),
        ];
        let scalars: [(&str, usize); 4] = [
            ("in_contact", v.in_contact.len()),
            ("contact_obstacle", v.contact_obstacle.len()),
            ("bending_stress", v.bending_stress.len()),
            ("gap", v.gap.len()),
        ];
        for (name, x) in vectors {
            check_len(&at, name, x.len(), 2, n, "node")?;
        }
        for (name, len) in scalars {
            check_len(&at, name, len, 1, n, "node")?;
        }
        for (name, x) in vectors.iter().filter(|(name, _)| *name != "impulse") {
            check_finite(&at, name, x, 2, "node")?;
        }
        if let Some(k) = v
            .contact_obstacle
            .iter()
            .chain(&v.contact_obstacle2)
            .flatten()
            .find(|&&k| k >= shape.obstacles)
        {
            return Err(format!(
                "{at}: contact_obstacle {k} but the run has {} obstacle(s)",
                shape.obstacles
            ));
        }
    }
    Ok(())
}

fn check_node(what: &str, step: u64, rod: usize, node: usize, shape: &Shape) -> Result<(), String> {
    match shape.nodes.get(rod) {
        None => Err(format!(
            "{what} at step {step} names rod {rod}, but the run has {} rod(s)",
            shape.nodes.len()
        )),
        Some(&n) if node >= n => Err(format!(
            "{what} at step {step} names node {node} of rod {rod}, which has {n} node(s)"
        )),
        _ => Ok(()),
    }
}

/// Read `path` message by message in file order and hand each decoded message to `visit`.
/// `/scene` is skipped; `/sim/iteration` is decoded only when `iterations` is true.
///
/// Errors (not an MCAP file, no `/sim/meta` or `/sim/step`, a wrong schema, a newer format,
/// a malformed message) name the file. A file that stops early after at least one
/// `/sim/step` is not an error: [`ReadStatus::truncated`] says why it stopped.
pub fn read_messages(
    path: &Path,
    iterations: bool,
    mut visit: impl FnMut(Message) -> Result<(), ReplayError>,
) -> Result<ReadStatus, ReplayError> {
    let err = |m: String| ReplayError::file(path, m);
    // topics of the channels defined
    let mut topics: Vec<String> = Vec::new();
    // ids of the channels whose messages are protobuf (format 2 /sim/step, /sim/iteration),
    // with whether their schema is the f64 twin (`gripsim.Step64`, `gripsim.Iteration64`)
    let mut protobuf: HashMap<u16, bool> = HashMap::new();
    // `/sim/meta` format_version: format 3 and older wrote the f64 layout as `gripsim.Step`
    let mut format = 0u32;
    let mut status = ReadStatus::default();
    let mut shape: Option<Shape> = None;
    let mut steps = 0u64;
    let mut last_step: Option<(u64, f64)> = None;

    let end = read_raw(path, |raw| {
        let (channel, topic, data) = match raw {
            Raw::Channel {
                id,
                topic,
                encoding,
                schema,
            } => {
                // Format 2 writes these as protobuf, format 1 as JSON: both are read.
                let binary = ["/sim/step", "/sim/iteration"].contains(&topic)
                    && encoding == "protobuf"
                    && schema.is_some_and(|(_, enc)| enc == "protobuf");
                let wide = schema.is_some_and(|(name, _)| name.ends_with("64"));
                if binary {
                    protobuf.insert(id, wide);
                }
                if let Some((_, want)) = REQUIRED.iter().find(|(t, _)| *t == topic) {
                    // Format 4 at precision f64: `gripsim.Step64`.
                    let named = |name: &str| {
                        name == *want || (binary && name.strip_suffix("64") == Some(*want))
                    };
                    let ok = schema
                        .is_some_and(|(name, enc)| named(name) && (enc == "jsonschema" || binary))
                        && (encoding == "json" || binary);
                    if !ok {
                        return Err(wrong_schema(path, topic, want, schema, encoding));
                    }
                }
                topics.push(topic.to_string());
                return Ok(());
            }
            Raw::Metadata(m) => {
                if m.name == "gripsim" {
                    check_format(
                        path,
                        m.metadata.get("format_version").map(|s| s.as_str()),
                        m.metadata.get("gripsim_version").map(|s| s.as_str()),
                        FORMAT_VERSION,
                    )?;
                } else if m.name == "gripsim.run_end" {
                    status.run_end = Some(m.metadata.clone());
                }
                return Ok(());
            }
            Raw::Message {
                channel,
                topic,
                data,
                ..
            } => (channel, topic, data),
        };
        let msg = match topic {
            "/sim/meta" => {
                let raw: serde_json::Value = serde_json::from_slice(data)
                    .map_err(|e| err(format!("/sim/meta is not JSON: {e}")))?;
                check_format(
                    path,
                    raw.get("format_version").map(|v| v.to_string()).as_deref(),
                    raw.get("gripsim_version").and_then(|v| v.as_str()),
                    FORMAT_VERSION,
                )?;
                let meta: Meta = serde_json::from_value(raw).map_err(|e| {
                    err(format!("/sim/meta does not match schema gripsim.Meta: {e}"))
                })?;
                if shape.is_some() {
                    return Err(err("a second /sim/meta message".into()));
                }
                format = meta.format_version;
                for (r, rod) in meta.rods.iter().enumerate() {
                    let n = rod.nodes;
                    let ok = n > 0
                        && rod.mass.len() == n
                        && rod.clamped.len() == n
                        && rod.rest_length.len() == n.saturating_sub(1)
                        && rod.rest_curvature.len() == n
                        && rod.mass.iter().all(|m| m.is_finite() && *m > 0.0);
                    if !ok {
                        return Err(err(format!(
                            "/sim/meta rod {r} ({:?}): its per-node arrays do not match \
                             its {n} nodes, or a mass is not positive",
                            rod.name
                        )));
                    }
                }
                if meta.rods.is_empty() {
                    return Err(err("/sim/meta lists no rods".into()));
                }
                let obstacles = raw_obstacle_count(data);
                shape = Some(Shape {
                    nodes: meta.rods.iter().map(|r| r.nodes).collect(),
                    obstacles,
                });
                Message::Meta(Box::new(meta))
            }
            "/sim/step" => {
                let Some(sh) = shape.as_ref() else {
                    return Err(err("a /sim/step message before /sim/meta".into()));
                };
                let bad = |e: String| {
                    err(format!(
                        "/sim/step message {} does not match schema gripsim.Step: {e}",
                        steps + 1
                    ))
                };
                let mut s: Step = if let Some(&wide) = protobuf.get(&channel) {
                    use prost::Message as _;
                    if wide || format <= 3 {
                        let pb = proto::Step64::decode(data).map_err(|e| bad(e.to_string()))?;
                        Step::try_from(pb).map_err(bad)?
                    } else {
                        let pb = proto::Step::decode(data).map_err(|e| bad(e.to_string()))?;
                        Step::try_from(pb).map_err(bad)?
                    }
                } else {
                    serde_json::from_slice(data).map_err(|e| bad(e.to_string()))?
                };
                // Format 3 leaves `q_predictor` out on steps without a corrector
                // pass, where it is `q`.
                for r in s.rods.iter_mut().filter(|r| r.q_predictor.is_empty()) {
                    r.q_predictor.clone_from(&r.q);
                }
                check_step(&s, sh).map_err(err)?;
                check_order(last_step, s.step, s.t).map_err(err)?;
                last_step = Some((s.step, s.t));
                steps += 1;
                Message::Step(s)
            }
            "/sim/contact" => {
                let Some(sh) = shape.as_ref() else {
                    return Err(err("a /sim/contact message before /sim/meta".into()));
                };
                let c: Contact = serde_json::from_slice(data).map_err(|e| {
                    err(format!(
                        "a /sim/contact message does not match schema gripsim.Contact: {e}"
                    ))
                })?;
                check_node("/sim/contact", c.step, c.rod, c.node, sh).map_err(err)?;
                if c.change != "added" && c.change != "released" {
                    return Err(err(format!(
                        "/sim/contact at step {}: change {:?} is neither added nor released",
                        c.step, c.change
                    )));
                }
                Message::Contact(c)
            }
            "/sim/event" => {
                let e: SimEvent = serde_json::from_slice(data).map_err(|e| {
                    err(format!(
                        "a /sim/event message does not match schema gripsim.Event: {e}"
                    ))
                })?;
                Message::Event(e)
            }
            "/sim/iteration" if iterations => {
                let Some(sh) = shape.as_ref() else {
                    return Err(err("a /sim/iteration message before /sim/meta".into()));
                };
                let bad = |e: String| {
                    err(format!(
                        "a /sim/iteration message does not match schema gripsim.Iteration: {e}"
                    ))
                };
                let it: Iteration = if let Some(&wide) = protobuf.get(&channel) {
                    use prost::Message as _;
                    if wide || format <= 3 {
                        let pb =
                            proto::Iteration64::decode(data).map_err(|e| bad(e.to_string()))?;
                        Iteration::try_from(pb).map_err(bad)?
                    } else {
                        let pb = proto::Iteration::decode(data).map_err(|e| bad(e.to_string()))?;
                        Iteration::try_from(pb).map_err(bad)?
                    }
                } else {
                    serde_json::from_slice(data).map_err(|e| bad(e.to_string()))?
                };
                check_node("/sim/iteration", it.step, it.rod, 0, sh).map_err(err)?;
                if it.q.len() != 2 * sh.nodes[it.rod] {
                    return Err(err(format!(
                        "/sim/iteration at step {}: q has {} numbers for {} nodes",
                        it.step,
                        it.q.len(),
                        sh.nodes[it.rod]
                    )));
                }
                Message::Iteration(it)
            }
            _ => return Ok(()),
        };
        visit(msg)
    })?;
    if let Some(e) = &end.error {
        if steps == 0 {
            return Err(err(unreadable(e)));
        }
    }
    for (topic, schema) in REQUIRED {
        if !topics.iter().any(|t| t == topic) {
            let why = if steps == 0 && end.error.is_none() {
                "the file holds no gripsim run"
            } else {
                "not a gripsim recording, or one cut before the channel was written"
            };
            return Err(err(format!(
                "missing channel {topic} (schema {schema}): {why}"
            )));
        }
    }
    if shape.is_none() {
        return Err(err("no /sim/meta message: not a gripsim recording".into()));
    }
    if steps == 0 {
        return Err(err(NO_STEP.into()));
    }
    status.truncated = end.truncated();
    Ok(status)
}

/// The error of a file whose data stop (damage, a cut) before its first `/sim/step`.
pub(crate) fn unreadable(e: &str) -> String {
    format!("not a readable MCAP file: its data stop before the first /sim/step message ({e})")
}

/// The error of a whole readable file without a `/sim/step` message (both dimensions).
pub(crate) const NO_STEP: &str =
    "no /sim/step message: the run was cut before its first chunk was written";

/// The error of a required channel with another schema than `want`.
pub(crate) fn wrong_schema(
    path: &Path,
    topic: &str,
    want: &str,
    schema: Option<(&str, &str)>,
    encoding: &str,
) -> ReplayError {
    ReplayError::file(
        path,
        format!(
            "wrong schema on {topic}: expected {want} (jsonschema, json messages; or \
             protobuf), found {} ({encoding} messages); not a gripsim recording of this format",
            schema
                .map(|(n, e)| format!("{n} ({e})"))
                .unwrap_or_else(|| "no schema".into()),
        ),
    )
}

// ---- the rules both dimensions check a recording's steps with --------------------------------

/// Steps in order: each step's number above the last one's (a number recorded twice is a
/// duplicated step), its time not before the last one's.
pub(crate) fn check_order(last: Option<(u64, f64)>, step: u64, t: f64) -> Result<(), String> {
    match last {
        Some((k, t0)) if step <= k || t < t0 => Err(format!(
            "/sim/step step {step} at t = {t} follows step {k} at t = {t0}: steps must \
             increase{}",
            if step == k {
                " (a step recorded twice)"
            } else {
                ""
            }
        )),
        _ => Ok(()),
    }
}

/// A step's clock: t finite, dt finite and not negative (and above 0 where `positive`).
pub(crate) fn check_clock(at: &str, t: f64, dt: f64, positive: bool) -> Result<(), String> {
    if !t.is_finite() || !dt.is_finite() || dt < 0.0 || (positive && dt <= 0.0) {
        let rule = if positive { " (dt must be > 0)" } else { "" };
        return Err(format!("{at} has t = {t}, dt = {dt}{rule}"));
    }
    Ok(())
}

/// A step holds every rod `/sim/meta` lists, and no other.
pub(crate) fn check_rod_count(at: &str, found: usize, listed: usize) -> Result<(), String> {
    if found != listed {
        return Err(format!("{at} has {found} rods, /sim/meta lists {listed}"));
    }
    Ok(())
}

/// An array of `per` numbers per `unit` (node, edge) holds them for `count` of them.
pub(crate) fn check_len(
    at: &str,
    name: &str,
    len: usize,
    per: usize,
    count: usize,
    unit: &str,
) -> Result<(), String> {
    if len == per * count {
        return Ok(());
    }
    Err(if per == 1 {
        format!("{at}: `{name}` has {len} entries, expected {count} (one per {unit})")
    } else {
        format!("{at}: `{name}` has {len} numbers, expected {per} x {count} {unit}s")
    })
}

/// Every recorded number is finite; else where the first one that is not is (its `unit`, the
/// index over `per` numbers each).
pub(crate) fn check_finite(
    at: &str,
    name: &str,
    values: &[f64],
    per: usize,
    unit: &str,
) -> Result<(), String> {
    match values.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(format!(
            "{at} holds a non-finite number: `{name}`[{k}] = {} ({unit} {})",
            values[k],
            k / per.max(1)
        )),
        None => Ok(()),
    }
}

/// One record of a recording as [`read_raw`] hands it over, in file order.
pub(crate) enum Raw<'a> {
    /// A channel, with its schema's name and encoding (None: a schema never defined).
    Channel {
        id: u16,
        topic: &'a str,
        encoding: &'a str,
        schema: Option<(&'a str, &'a str)>,
    },
    Metadata(&'a mcap::records::Metadata),
    /// A message, with its channel's topic.
    Message {
        channel: u16,
        topic: &'a str,
        data: &'a [u8],
    },
}

/// How [`read_raw`] ended.
pub(crate) struct RawEnd {
    /// The reader's error where reading stopped (damage, a cut), naming the chunk.
    pub error: Option<String>,
    /// Why the records stopped before the end of the file without a reader error.
    pub stopped: Option<String>,
    /// A data end or footer record was read.
    pub ended: bool,
}

impl RawEnd {
    /// Why the file was read only in part (None: whole).
    pub fn truncated(&self) -> Option<String> {
        if let Some(e) = &self.error {
            return Some(format!("reading stopped early: {e}"));
        }
        if let Some(s) = &self.stopped {
            return Some(s.clone());
        }
        (!self.ended).then(|| "the file ends without a summary or footer".into())
    }
}

/// Read `path` with the guarded, streaming record reader ([`Records`]: one chunk in memory at
/// a time, chunk CRCs checked before any of its records is handed out, record lengths bounded)
/// and hand `visit` its channels, metadata and messages in file order. The reader of both
/// dimensions: [`read_messages`] (planar) and [`super::read3`] (3D) decode the messages. A
/// reader error ends the reading ([`RawEnd::error`]); what `visit` returns as an error is
/// returned.
pub(crate) fn read_raw(
    path: &Path,
    mut visit: impl FnMut(Raw<'_>) -> Result<(), ReplayError>,
) -> Result<RawEnd, ReplayError> {
    use mcap::records::Record;
    let err = |m: String| ReplayError::file(path, m);
    let mut records = Records::open(path).map_err(err)?;
    // id -> (name, encoding)
    let mut schemas: HashMap<u16, (String, String)> = HashMap::new();
    // id -> topic
    let mut channels: HashMap<u16, String> = HashMap::new();
    let mut end = RawEnd {
        error: None,
        stopped: None,
        ended: false,
    };
    while let Some(record) = records.next() {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                end.error = Some(records.explain(e));
                break;
            }
        };
        match record {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, (header.name.clone(), header.encoding.clone()));
            }
            Record::Channel(c) => {
                let schema = schemas.get(&c.schema_id);
                visit(Raw::Channel {
                    id: c.id,
                    topic: &c.topic,
                    encoding: &c.message_encoding,
                    schema: schema.map(|(n, e)| (n.as_str(), e.as_str())),
                })?;
                channels.insert(c.id, c.topic.clone());
            }
            Record::Metadata(m) => visit(Raw::Metadata(&m))?,
            Record::DataEnd(_) | Record::Footer(_) => end.ended = true,
            Record::Message { header, data } => {
                let Some(topic) = channels.get(&header.channel_id) else {
                    return Err(err(format!(
                        "a message on channel {} that was never defined",
                        header.channel_id
                    )));
                };
                visit(Raw::Message {
                    channel: header.channel_id,
                    topic,
                    data: &data,
                })?;
            }
            _ => {}
        }
    }
    end.stopped = records.stopped.take();
    Ok(end)
}

/// Every record of an MCAP file in file order, read from the file record by record (memory:
/// one chunk at a time), chunks decompressed and their CRCs checked before any of their
/// records is handed out: what `mcap::read::ChunkFlattener` does, but streaming, with a record
/// length limit and a check of uncompressed chunks. Without the limit, a damaged length field
/// inside a chunk made the reader allocate that many bytes (8e18) and abort the process (found
/// by fuzz/fuzz_targets/replay_mcap.rs; tests/suite/regressions.rs replays it).
struct Records {
    src: std::io::BufReader<std::fs::File>,
    /// Bytes of the current top-level record (or the leading magic), fed to `reader`.
    queue: Vec<u8>,
    pos: usize,
    /// Bytes left in the file (a regular file), else unknown.
    remaining: Option<u64>,
    after_footer: bool,
    eof: bool,
    /// Chunk records handed to `reader` so far (the last one is the one being read).
    chunks: u64,
    chunk_offset: u64,
    offset: u64,
    /// Why feeding stopped before the end of the file, if it did.
    stopped: Option<String>,
    reader: mcap::sans_io::LinearReader,
}

impl Records {
    /// Open `path` and check its first 8 bytes (the MCAP magic) before anything else is read.
    fn open(path: &Path) -> Result<Records, String> {
        use std::io::Read;
        not_a_pipe(path)?;
        let file = std::fs::File::open(path).map_err(|e| format!("cannot read the file: {e}"))?;
        let meta = file
            .metadata()
            .map_err(|e| format!("cannot read the file: {e}"))?;
        let size = meta.is_file().then_some(meta.len());
        let mut src = std::io::BufReader::with_capacity(1 << 16, file);
        let mut magic = Vec::with_capacity(8);
        (&mut src)
            .take(8)
            .read_to_end(&mut magic)
            .map_err(|e| format!("cannot read the file: {e}"))?;
        if magic != mcap::MAGIC {
            return Err(
                "not an MCAP file (it does not start with the MCAP magic bytes); replay reads \
                 the .mcap that `gripsim run --mcap` writes"
                    .into(),
            );
        }
        // A record is a chunk (at most the file) or a message in one: no gripsim message is
        // 64 times larger than its whole file compressed, nor larger than 64 MiB in a small one.
        let limit = size.unwrap_or(1 << 30).saturating_mul(64).max(64 << 20);
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(usize::try_from(limit).unwrap_or(usize::MAX));
        Ok(Records {
            src,
            queue: magic,
            pos: 0,
            remaining: size.map(|s| s.saturating_sub(8)),
            after_footer: false,
            eof: false,
            chunks: 0,
            chunk_offset: 0,
            offset: 8,
            stopped: None,
            reader: mcap::sans_io::LinearReader::new_with_options(options),
        })
    }

    /// Put the next top-level record in `queue`; false at the end (or where reading stops).
    fn fill(&mut self) -> bool {
        use std::io::Read;
        self.queue.clear();
        self.pos = 0;
        if self.eof {
            return false;
        }
        let at = self.offset;
        let mut head = Vec::with_capacity(9);
        let want = if self.after_footer { 8 } else { 9 };
        if (&mut self.src).take(want).read_to_end(&mut head).is_err() || head.is_empty() {
            self.eof = true;
            return false;
        }
        self.offset += head.len() as u64;
        if self.after_footer || head.len() < 9 {
            self.queue = head;
            self.eof = true;
            return true;
        }
        let len = u64::from_le_bytes(head[1..9].try_into().expect("9 bytes"));
        let left = self.remaining.map(|r| r.saturating_sub(9));
        self.queue = head;
        if left.is_some_and(|l| len > l) {
            // The record runs past the end of the file: the file was cut (or the length is
            // damaged). Hand over the header only; the reader says where it stops.
            self.eof = true;
            return true;
        }
        if (&mut self.src)
            .take(len)
            .read_to_end(&mut self.queue)
            .is_err()
        {
            self.eof = true;
        }
        let got = (self.queue.len() - 9) as u64;
        self.offset += got;
        self.remaining = self.remaining.map(|r| r.saturating_sub(9 + got));
        match self.queue[0] {
            mcap::records::op::CHUNK => {
                if !chunk_records_fit(&self.queue[9..]) {
                    // The mcap crate (0.26) subtracts such a record's length from what is left
                    // of the chunk unchecked (a panic in a debug build, found by fuzzing).
                    self.stopped = Some(format!(
                        "reading stopped early: chunk {} (at byte {at}) holds a record that runs \
                         past the chunk's end: the file is damaged there",
                        self.chunks + 1
                    ));
                    self.queue.clear();
                    self.eof = true;
                    return false;
                }
                self.chunks += 1;
                self.chunk_offset = at;
            }
            mcap::records::op::FOOTER => self.after_footer = true,
            _ => {}
        }
        true
    }

    /// The reader's error in words that name the chunk where it concerns one.
    fn explain(&self, e: mcap::McapError) -> String {
        match e {
            mcap::McapError::BadChunkCrc { saved, calculated } => format!(
                "chunk {} (at byte {}) fails its CRC (stored {saved:#010x}, computed \
                 {calculated:#010x}): the file is damaged there",
                self.chunks, self.chunk_offset
            ),
            // Damage that the decompressor or the record parser finds first.
            other if self.queue.first() == Some(&mcap::records::op::CHUNK) => format!(
                "chunk {} (at byte {}) is damaged ({other})",
                self.chunks, self.chunk_offset
            ),
            other => other.to_string(),
        }
    }
}

impl Iterator for Records {
    type Item = mcap::McapResult<mcap::records::Record<'static>>;

    fn next(&mut self) -> Option<Self::Item> {
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(mcap::sans_io::LinearReadEvent::ReadRequest(need)) => {
                    if self.pos == self.queue.len() && !self.fill() {
                        self.reader.notify_read(0);
                        continue;
                    }
                    let len = need.min(self.queue.len() - self.pos);
                    self.reader
                        .insert(len)
                        .copy_from_slice(&self.queue[self.pos..self.pos + len]);
                    self.reader.notify_read(len);
                    self.pos += len;
                }
                // Attachments are skipped unparsed: a replay has no use for them, and the mcap
                // crate (0.26) slices a too-short attachment record unchecked, a panic (found by
                // fuzz/fuzz_targets/replay_mcap.rs).
                Ok(mcap::sans_io::LinearReadEvent::Record { opcode, .. })
                    if opcode == mcap::records::op::ATTACHMENT => {}
                Ok(mcap::sans_io::LinearReadEvent::Record { data, opcode }) => {
                    return Some(mcap::read::parse_record(opcode, data).map(|r| r.into_owned()));
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }
}

/// The schema name of the file's first message, read with the same guarded record reader as
/// [`read_messages`] (damaged or hostile files give `None`, never a panic); used to tell a 3D
/// recording cut short (no summary section) from a planar one.
pub fn first_message_schema(path: &Path) -> Option<String> {
    use mcap::records::Record;
    let records = Records::open(path).ok()?;
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: HashMap<u16, u16> = HashMap::new();
    for record in records {
        match record.ok()? {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name.clone());
            }
            Record::Channel(c) => {
                channels.insert(c.id, c.schema_id);
            }
            Record::Message { header, .. } => {
                let schema = channels.get(&header.channel_id)?;
                return schemas.get(schema).cloned();
            }
            _ => {}
        }
    }
    None
}

/// The scenario a recording holds (`/sim/meta` `scenario_text`, and `sets` when it has them),
/// read with the same guarded record reader as [`read_messages`], looking no further than the
/// first few messages (`/sim/meta` is the first); `None` for a file that is not one.
pub fn recorded_scenario(path: &Path) -> Option<(String, Vec<String>)> {
    use mcap::records::Record;
    let records = Records::open(path).ok()?;
    let mut channels: HashMap<u16, String> = HashMap::new();
    let mut messages = 0;
    for record in records {
        match record.ok()? {
            Record::Channel(c) => {
                channels.insert(c.id, c.topic.clone());
            }
            Record::Message { header, data } => {
                if channels.get(&header.channel_id).map(String::as_str) == Some("/sim/meta") {
                    let v: serde_json::Value = serde_json::from_slice(&data).ok()?;
                    let text = v.get("scenario_text")?.as_str()?.to_string();
                    let sets = v
                        .get("sets")
                        .and_then(|s| s.as_array())
                        .map(|a| {
                            a.iter()
                                .filter_map(|x| x.as_str().map(str::to_string))
                                .collect()
                        })
                        .unwrap_or_default();
                    return Some((text, sets));
                }
                messages += 1;
                if messages >= 16 {
                    return None;
                }
            }
            _ => {}
        }
    }
    None
}

/// The files a recording's scenario names (meshes, profile tables), where a replay looks them
/// up: beside the recording. Empty for a file that is not a recording, or not a regular file
/// (a pipe is not read ahead of the replay).
pub fn recorded_files(path: &Path) -> Vec<std::path::PathBuf> {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return Vec::new();
    }
    match recorded_scenario(path) {
        Some((text, sets)) => crate::scenario::input::referenced_files(
            &text,
            &sets,
            crate::scenario::input::scenario_dir(path),
        ),
        None => Vec::new(),
    }
}

/// A recording is read more than once (which reader, then the data; `diff` and `show` again):
/// a FIFO or a socket is refused before it is opened (opening a FIFO without a writer blocks).
pub(crate) fn not_a_pipe(path: &Path) -> Result<(), String> {
    use std::os::unix::fs::FileTypeExt;
    let kind = std::fs::metadata(path)
        .map_err(|e| format!("cannot read the file: {e}"))?
        .file_type();
    if kind.is_fifo() || kind.is_socket() {
        return Err(
            "is a FIFO or a socket, not a file: replay reads a recording more than \
                    once; save it to a file first"
                .into(),
        );
    }
    Ok(())
}

/// Whether every record of an uncompressed chunk ends within the chunk's records length, as far
/// as `body` (the chunk record's body, perhaps cut short) shows. True for a compressed chunk.
fn chunk_records_fit(body: &[u8]) -> bool {
    // Start and end time, uncompressed size (8 bytes each), CRC (4), compression (4-byte
    // length + text), records (8-byte length + bytes).
    let Some(clen) = body.get(28..32) else {
        return true;
    };
    if clen != [0; 4] {
        return true;
    }
    let Some(records_len) = u64_at(body, 32) else {
        return true;
    };
    let records = body.get(40..).unwrap_or(&[]);
    let mut i = 0u64;
    while i < records_len {
        let Some(head_end) = i.checked_add(9).filter(|&h| h <= records_len) else {
            return false;
        };
        let Some(len) = usize::try_from(i + 1).ok().and_then(|k| u64_at(records, k)) else {
            // The file stops inside the chunk: a cut-short file, read up to there.
            return true;
        };
        match head_end.checked_add(len) {
            Some(next) if next <= records_len => i = next,
            _ => return false,
        }
    }
    true
}

fn u64_at(b: &[u8], i: usize) -> Option<u64> {
    let bytes = b.get(i..i.checked_add(8)?)?;
    Some(u64::from_le_bytes(bytes.try_into().ok()?))
}

/// How many obstacles `/sim/meta` lists (only the count is needed to check indices).
fn raw_obstacle_count(data: &[u8]) -> usize {
    #[derive(Deserialize)]
    struct Obstacles {
        #[serde(default)]
        obstacles: Vec<serde::de::IgnoredAny>,
    }
    serde_json::from_slice::<Obstacles>(data)
        .map(|o| o.obstacles.len())
        .unwrap_or(0)
}

/// The rule of the format version (both dimensions): a recording of a format newer than
/// `newest` (what this gripsim reads) is refused, naming the writer.
pub(crate) fn check_format(
    path: &Path,
    version: Option<&str>,
    writer: Option<&str>,
    newest: u32,
) -> Result<(), ReplayError> {
    let Some(v) = version else { return Ok(()) };
    let v: u64 = v
        .trim_matches('"')
        .parse()
        .map_err(|_| ReplayError::file(path, format!("format_version {v:?} is not a number")))?;
    if v > newest as u64 {
        return Err(ReplayError::file(
            path,
            format!(
                "recorded with format version {v} by gripsim {}; this gripsim ({}) reads format \
                 version {newest} and older: replay it with a newer gripsim",
                writer.unwrap_or("(unknown)"),
                env!("CARGO_PKG_VERSION")
            ),
        ));
    }
    Ok(())
}

/// A whole recorded run in memory (without `/sim/iteration` and `/scene`).
#[derive(Debug, Clone)]
pub struct Run {
    pub path: PathBuf,
    pub meta: Meta,
    /// The scenario parsed from `/sim/meta` `scenario_text`.
    pub scenario: Scenario,
    pub steps: Vec<Step>,
    pub contacts: Vec<Contact>,
    pub events: Vec<SimEvent>,
    pub status: ReadStatus,
}

impl Run {
    /// Read a run, printing nothing: a cut-short file is read up to its last complete chunk
    /// and [`Run::warning`] says so.
    pub fn load(path: &Path) -> Result<Run, ReplayError> {
        let mut meta = None;
        let mut steps = Vec::new();
        let mut contacts = Vec::new();
        let mut events = Vec::new();
        let status = read_messages(path, false, |m| {
            match m {
                Message::Meta(x) => meta = Some(*x),
                Message::Step(s) => steps.push(s),
                Message::Contact(c) => contacts.push(c),
                Message::Event(e) => events.push(e),
                Message::Iteration(_) => {}
            }
            Ok(())
        })?;
        let meta = meta.expect("read_messages checks /sim/meta");
        let scenario = parse_scenario(path, &meta)?;
        // Only the changes of accepted steps: a change of an attempt the solver threw away
        // (a rejected adaptive step, a back-off, a time-of-impact split; recordings before
        // they were filtered at the source) has its step's number but another time.
        let dynamic = scenario.solve.mode == Mode::Dynamic;
        contacts.retain(|c| {
            let k = steps.partition_point(|s| s.step < c.step);
            steps
                .get(k)
                .is_some_and(|s| s.step == c.step && (!dynamic || s.t == c.t))
        });
        Ok(Run {
            path: path.to_path_buf(),
            meta,
            scenario,
            steps,
            contacts,
            events,
            status,
        })
    }

    /// The stderr warning for a run read only in part, if it was.
    pub fn warning(&self) -> Option<String> {
        self.status.truncated.as_ref().map(|why| {
            let last = self.steps.last().expect("a run has a step");
            format!(
                "warning: {} is incomplete ({why}); read {} steps up to step {} (t = {} s), \
                 the last complete chunk",
                self.path.display(),
                self.steps.len(),
                last.step,
                last.t
            )
        })
    }

    pub fn dynamic(&self) -> bool {
        self.scenario.solve.mode == Mode::Dynamic
    }

    /// Whether the run says it completed: `Some(true/false)` from its run end, `None` when the
    /// file stops before the run end.
    pub fn completed(&self) -> Option<bool> {
        if let Some(e) = self.events.iter().rev().find(|e| e.kind == "run_end") {
            return e.completed;
        }
        self.status
            .run_end
            .as_ref()
            .and_then(|m| m.get("completed"))
            .map(|c| c == "true")
    }

    /// Why the run stopped early, from its run end event.
    pub fn end_error(&self) -> Option<String> {
        self.events
            .iter()
            .rev()
            .find(|e| e.kind == "run_end")
            .and_then(|e| e.error.clone())
    }

    pub fn t_end(&self) -> f64 {
        self.steps.last().map(|s| s.t).unwrap_or(0.0)
    }

    pub fn rod_name(&self, r: usize) -> &str {
        &self.meta.rods[r].name
    }
}

/// The scenario of a recording, from `/sim/meta` `scenario_text`.
/// The recorded scenario of a run, checked against the rods `/sim/meta` lists.
pub fn parse_scenario(path: &Path, meta: &Meta) -> Result<Scenario, ReplayError> {
    let file = format!("{} (/sim/meta scenario_text)", path.display());
    // A recording made before the contact defaults changed says no [contact]: it ran with the
    // seed's model.
    let text = match meta.scenario_text.parse::<toml::Table>() {
        Ok(mut root) if !root.contains_key("contact") => {
            crate::scenario::contact::recorded_defaults(&mut root);
            toml::to_string(&root).unwrap_or_else(|_| meta.scenario_text.clone())
        }
        _ => meta.scenario_text.clone(),
    };
    let sc = Scenario::from_str(&text, &file, &[]).map_err(|e| {
        ReplayError::file(
            path,
            format!("its recorded scenario does not read back: {e}"),
        )
    })?;
    if sc.rods.len() != meta.rods.len()
        || sc
            .rods
            .iter()
            .zip(&meta.rods)
            .any(|(s, m)| s.nodes != m.nodes)
    {
        return Err(ReplayError::file(
            path,
            "/sim/meta rods do not match its own scenario_text".into(),
        ));
    }
    Ok(sc)
}
