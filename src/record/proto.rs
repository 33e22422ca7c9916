//! The protobuf encoding of the high-rate MCAP channels (`/sim/step`, `/sim/iteration`).
//!
//! The messages are `prost` derives; the schema each channel carries is a
//! `google.protobuf.FileDescriptorSet` built here from one table per message ([`MESSAGES`]), so
//! any protobuf library (Foxglove, Python's `protobuf` through `mcap-protobuf-support`) decodes
//! the file without a `.proto` file. Adding a field is two lines: one in the derive, one in its
//! table (a unit test checks the two agree, field by field, on the wire).
//!
//! The fields mirror the JSON encoding of format 1 (docs/recording-format.md) with two
//! differences protobuf forces: an absent index (a free node's obstacle, a body's own contact
//! with no rod) is −1 instead of `null`, and a gap with no obstacle is +∞ instead of `null`.

use crate::events::{BodyView, ContactView, Phase, RodStepView};
use prost::Message as _;
use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet};

/// `gripsim.Step`: the state at the end of a step.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Step {
    #[prost(uint64, tag = "1")]
    pub step: u64,
    #[prost(double, tag = "2")]
    pub t: f64,
    #[prost(double, tag = "3")]
    pub dt: f64,
    #[prost(uint32, tag = "4")]
    pub newton_iterations: u32,
    #[prost(uint32, tag = "5")]
    pub passes: u32,
    #[prost(message, repeated, tag = "6")]
    pub rods: Vec<Rod>,
    #[prost(message, repeated, tag = "7")]
    pub bodies: Vec<Body>,
    #[prost(message, repeated, tag = "8")]
    pub contacts: Vec<Contact>,
}

/// `gripsim.Rod`: one rod of a step (interleaved vectors `[x0, y0, x1, y1, …]`).
#[derive(Clone, PartialEq, prost::Message)]
pub struct Rod {
    #[prost(double, repeated, tag = "1")]
    pub q: Vec<f64>,
    #[prost(double, repeated, tag = "2")]
    pub u: Vec<f64>,
    #[prost(double, repeated, tag = "3")]
    pub reaction: Vec<f64>,
    #[prost(double, repeated, tag = "4")]
    pub reaction_norm: Vec<f64>,
    #[prost(double, repeated, tag = "5")]
    pub impulse: Vec<f64>,
    #[prost(double, repeated, tag = "6")]
    pub drive_force: Vec<f64>,
    #[prost(double, repeated, tag = "7")]
    pub normal: Vec<f64>,
    #[prost(bool, repeated, tag = "8")]
    pub in_contact: Vec<bool>,
    /// −1: free.
    #[prost(sint64, repeated, tag = "9")]
    pub contact_obstacle: Vec<i64>,
    #[prost(double, repeated, tag = "10")]
    pub normal2: Vec<f64>,
    /// −1: none.
    #[prost(sint64, repeated, tag = "11")]
    pub contact_obstacle2: Vec<i64>,
    #[prost(double, repeated, tag = "12")]
    pub bending_stress: Vec<f64>,
    /// +∞: no obstacle.
    #[prost(double, repeated, tag = "13")]
    pub gap: Vec<f64>,
    /// Empty on a step without a corrector pass (then it equals `q`; format 3).
    #[prost(double, repeated, tag = "14")]
    pub q_predictor: Vec<f64>,
}

/// `gripsim.Body`: a free body (fruit) at the end of a step.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Body {
    #[prost(string, tag = "1")]
    pub name: String,
    #[prost(uint64, tag = "2")]
    pub obstacle: u64,
    #[prost(double, repeated, tag = "3")]
    pub position: Vec<f64>,
    #[prost(double, tag = "4")]
    pub angle: f64,
    #[prost(double, repeated, tag = "5")]
    pub velocity: Vec<f64>,
    #[prost(double, tag = "6")]
    pub angular_velocity: f64,
    #[prost(double, repeated, tag = "7")]
    pub contact_force: Vec<f64>,
    #[prost(double, tag = "8")]
    pub contact_torque: f64,
    #[prost(double, tag = "9")]
    pub mass: f64,
}

/// `gripsim.ContactState`: an active contact at the end of a step.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Contact {
    /// −1: a free body's own contact with a fixed obstacle (then `node` is the body).
    #[prost(sint64, tag = "1")]
    pub rod: i64,
    #[prost(uint64, tag = "2")]
    pub node: u64,
    #[prost(uint64, tag = "3")]
    pub obstacle: u64,
    /// −1: a fixed obstacle.
    #[prost(sint64, tag = "4")]
    pub body: i64,
    #[prost(double, repeated, tag = "5")]
    pub point: Vec<f64>,
    #[prost(double, repeated, tag = "6")]
    pub normal: Vec<f64>,
    #[prost(double, tag = "7")]
    pub normal_force: f64,
    #[prost(double, tag = "8")]
    pub friction_force: f64,
    #[prost(double, tag = "9")]
    pub slip_velocity: f64,
    #[prost(bool, tag = "10")]
    pub stuck: bool,
    #[prost(double, tag = "11")]
    pub utilisation: f64,
    #[prost(double, tag = "12")]
    pub mu_s: f64,
    /// A compliant fruit's contact (0 at a rigid obstacle): indentation (m), contact
    /// half-width (m), peak pressure (Pa), the fruit's bruise threshold (Pa) and the
    /// half-width above it (m).
    #[prost(double, tag = "13")]
    pub indentation: f64,
    #[prost(double, tag = "14")]
    pub half_width: f64,
    #[prost(double, tag = "15")]
    pub peak_pressure: f64,
    #[prost(double, tag = "16")]
    pub bruise_pressure: f64,
    #[prost(double, tag = "17")]
    pub bruise_half_width: f64,
}

/// `gripsim.Iteration`: one Newton iteration of one rod.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Iteration {
    #[prost(uint64, tag = "1")]
    pub step: u64,
    #[prost(double, tag = "2")]
    pub t: f64,
    /// `predictor`, `corrector` or `static`.
    #[prost(string, tag = "3")]
    pub phase: String,
    #[prost(uint32, tag = "4")]
    pub pass: u32,
    #[prost(uint32, tag = "5")]
    pub iteration: u32,
    #[prost(uint64, tag = "6")]
    pub rod: u64,
    #[prost(double, tag = "7")]
    pub residual: f64,
    #[prost(double, tag = "8")]
    pub update: f64,
    #[prost(double, repeated, tag = "9")]
    pub q: Vec<f64>,
}

/// The type of a field in a descriptor table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Double,
    Bool,
    Uint32,
    Uint64,
    Sint64,
    Str,
    /// A message of this package, by its short name.
    Message(&'static str),
}

/// One field: name, number, type, repeated.
pub type Field = (&'static str, i32, Kind, bool);

use Kind as K;

/// Every message of the package `gripsim` with its fields, in the order of the derives above.
pub const MESSAGES: [(&str, &[Field]); 5] = [
    (
        "Step",
        &[
            ("step", 1, K::Uint64, false),
            ("t", 2, K::Double, false),
            ("dt", 3, K::Double, false),
            ("newton_iterations", 4, K::Uint32, false),
            ("passes", 5, K::Uint32, false),
            ("rods", 6, K::Message("Rod"), true),
            ("bodies", 7, K::Message("Body"), true),
            ("contacts", 8, K::Message("ContactState"), true),
        ],
    ),
    (
        "Rod",
        &[
            ("q", 1, K::Double, true),
            ("u", 2, K::Double, true),
            ("reaction", 3, K::Double, true),
            ("reaction_norm", 4, K::Double, true),
            ("impulse", 5, K::Double, true),
            ("drive_force", 6, K::Double, true),
            ("normal", 7, K::Double, true),
            ("in_contact", 8, K::Bool, true),
            ("contact_obstacle", 9, K::Sint64, true),
            ("normal2", 10, K::Double, true),
            ("contact_obstacle2", 11, K::Sint64, true),
            ("bending_stress", 12, K::Double, true),
            ("gap", 13, K::Double, true),
            ("q_predictor", 14, K::Double, true),
        ],
    ),
    (
        "Body",
        &[
            ("name", 1, K::Str, false),
            ("obstacle", 2, K::Uint64, false),
            ("position", 3, K::Double, true),
            ("angle", 4, K::Double, false),
            ("velocity", 5, K::Double, true),
            ("angular_velocity", 6, K::Double, false),
            ("contact_force", 7, K::Double, true),
            ("contact_torque", 8, K::Double, false),
            ("mass", 9, K::Double, false),
        ],
    ),
    (
        "ContactState",
        &[
            ("rod", 1, K::Sint64, false),
            ("node", 2, K::Uint64, false),
            ("obstacle", 3, K::Uint64, false),
            ("body", 4, K::Sint64, false),
            ("point", 5, K::Double, true),
            ("normal", 6, K::Double, true),
            ("normal_force", 7, K::Double, false),
            ("friction_force", 8, K::Double, false),
            ("slip_velocity", 9, K::Double, false),
            ("stuck", 10, K::Bool, false),
            ("utilisation", 11, K::Double, false),
            ("mu_s", 12, K::Double, false),
            ("indentation", 13, K::Double, false),
            ("half_width", 14, K::Double, false),
            ("peak_pressure", 15, K::Double, false),
            ("bruise_pressure", 16, K::Double, false),
            ("bruise_half_width", 17, K::Double, false),
        ],
    ),
    (
        "Iteration",
        &[
            ("step", 1, K::Uint64, false),
            ("t", 2, K::Double, false),
            ("phase", 3, K::Str, false),
            ("pass", 4, K::Uint32, false),
            ("iteration", 5, K::Uint32, false),
            ("rod", 6, K::Uint64, false),
            ("residual", 7, K::Double, false),
            ("update", 8, K::Double, false),
            ("q", 9, K::Double, true),
        ],
    ),
];

/// The protobuf package of the messages.
pub const PACKAGE: &str = "gripsim";

/// The descriptor of one field of a `gripsim` message (also the 3D ones, src/record/mcap3.rs).
pub(crate) fn field_proto(&(name, number, kind, repeated): &Field) -> FieldDescriptorProto {
    let (ty, type_name) = match kind {
        K::Double => (Type::Double, None),
        K::Bool => (Type::Bool, None),
        K::Uint32 => (Type::Uint32, None),
        K::Uint64 => (Type::Uint64, None),
        K::Sint64 => (Type::Sint64, None),
        K::Str => (Type::String, None),
        K::Message(m) => (Type::Message, Some(format!(".{PACKAGE}.{m}"))),
    };
    describe_field(name, number, ty, type_name, repeated)
}

/// One field of a descriptor (proto3: a scalar is `optional`-labelled, its JSON name its own).
pub(crate) fn describe_field(
    name: &str,
    number: i32,
    ty: Type,
    type_name: Option<String>,
    repeated: bool,
) -> FieldDescriptorProto {
    let mut f = FieldDescriptorProto {
        name: Some(name.to_string()),
        number: Some(number),
        type_name,
        json_name: Some(name.to_string()),
        ..Default::default()
    };
    f.set_label(if repeated {
        Label::Repeated
    } else {
        Label::Optional
    });
    f.set_type(ty);
    f
}

/// The schema of every channel: a `FileDescriptorSet` holding `gripsim/recording.proto`
/// (proto3, package `gripsim`) with all the messages, serialised. The channel's schema name
/// says which message it carries (`gripsim.Step`, `gripsim.Iteration`).
pub fn file_descriptor_set() -> Vec<u8> {
    let file = FileDescriptorProto {
        name: Some("gripsim/recording.proto".into()),
        package: Some(PACKAGE.into()),
        message_type: MESSAGES
            .iter()
            .map(|(name, fields)| DescriptorProto {
                name: Some(name.to_string()),
                field: fields.iter().map(field_proto).collect(),
                ..Default::default()
            })
            .collect(),
        syntax: Some("proto3".into()),
        ..Default::default()
    };
    FileDescriptorSet { file: vec![file] }.encode_to_vec()
}

/// An index with `usize::MAX` for none as −1.
fn index(k: usize) -> i64 {
    if k == usize::MAX {
        -1
    } else {
        k as i64
    }
}

/// Replace the contents of `dst` by `src` (keeps the allocation).
fn set<T: Copy>(dst: &mut Vec<T>, src: &[T]) {
    dst.clear();
    dst.extend_from_slice(src);
}

impl Rod {
    /// Refill from a step view, reusing the buffers.
    pub fn fill(&mut self, v: &RodStepView<'_>) {
        set(&mut self.q, v.q);
        set(&mut self.u, v.u);
        set(&mut self.reaction, v.reaction);
        self.reaction_norm.clear();
        self.reaction_norm
            .extend((0..v.reaction.len() / 2).map(|i| super::node_norm(v.reaction, i)));
        set(&mut self.impulse, v.impulse);
        set(&mut self.drive_force, v.drive_force);
        set(&mut self.normal, v.normal);
        set(&mut self.in_contact, v.in_contact);
        self.contact_obstacle.clear();
        self.contact_obstacle
            .extend(v.contact_obstacle.iter().map(|&k| index(k)));
        set(&mut self.normal2, v.normal2);
        self.contact_obstacle2.clear();
        self.contact_obstacle2
            .extend(v.contact_obstacle2.iter().map(|&k| index(k)));
        set(&mut self.bending_stress, v.bending_stress);
        set(&mut self.gap, v.gap);
        // Only on steps with a corrector pass: elsewhere it equals q (format 3).
        if v.q_predictor == v.q {
            self.q_predictor.clear();
        } else {
            set(&mut self.q_predictor, v.q_predictor);
        }
    }
}

impl From<&BodyView<'_>> for Body {
    fn from(b: &BodyView<'_>) -> Self {
        Self {
            name: b.name.to_string(),
            obstacle: b.obstacle as u64,
            position: b.position.to_vec(),
            angle: b.angle,
            velocity: b.velocity.to_vec(),
            angular_velocity: b.angular_velocity,
            contact_force: b.contact_force.to_vec(),
            contact_torque: b.contact_torque,
            mass: b.mass,
        }
    }
}

impl From<&ContactView> for Contact {
    fn from(c: &ContactView) -> Self {
        Self {
            rod: index(c.rod),
            node: c.node as u64,
            obstacle: c.obstacle as u64,
            body: index(c.body),
            point: c.point.to_vec(),
            normal: c.normal.to_vec(),
            normal_force: c.normal_force,
            friction_force: c.friction_force,
            slip_velocity: c.slip_velocity,
            stuck: c.stuck,
            utilisation: c.utilisation,
            mu_s: c.mu_s,
            indentation: c.indentation,
            half_width: c.half_width,
            peak_pressure: c.peak_pressure,
            bruise_pressure: c.bruise_pressure,
            bruise_half_width: c.bruise_half_width,
        }
    }
}

/// A reusable `/sim/step` encoder: one [`Step`] whose buffers live from step to step.
#[derive(Default)]
pub struct StepEncoder {
    msg: Step,
}

/// The fields of a step to encode.
pub struct StepFields<'e, 'a> {
    pub step: u64,
    pub t: f64,
    pub dt: f64,
    pub newton_iterations: u32,
    pub passes: u32,
    pub rods: &'e [RodStepView<'a>],
    pub bodies: &'e [BodyView<'a>],
    pub contacts: &'e [ContactView],
}

impl StepEncoder {
    /// Encode a step into `buf` (cleared first).
    pub fn encode(&mut self, s: &StepFields<'_, '_>, buf: &mut Vec<u8>) {
        let m = &mut self.msg;
        m.step = s.step;
        m.t = s.t;
        m.dt = s.dt;
        m.newton_iterations = s.newton_iterations;
        m.passes = s.passes;
        m.rods.resize_with(s.rods.len(), Rod::default);
        for (dst, v) in m.rods.iter_mut().zip(s.rods) {
            dst.fill(v);
        }
        m.bodies.clear();
        m.bodies.extend(s.bodies.iter().map(Body::from));
        m.contacts.clear();
        m.contacts.extend(s.contacts.iter().map(Contact::from));
        buf.clear();
        m.encode(buf).expect("a Vec grows as needed");
    }
}

/// The iteration message of an [`crate::events::Event::Iteration`].
#[allow(clippy::too_many_arguments)]
pub fn iteration(
    step: u64,
    t: f64,
    phase: Phase,
    pass: u32,
    iteration: u32,
    rod: usize,
    residual: f64,
    update: f64,
    q: &[f64],
) -> Iteration {
    Iteration {
        step,
        t,
        phase: phase.as_str().to_string(),
        pass,
        iteration,
        rod: rod as u64,
        residual,
        update,
        q: q.to_vec(),
    }
}

fn opt_index(k: i64) -> serde_json::Value {
    if k < 0 {
        serde_json::Value::Null
    } else {
        k.into()
    }
}

fn finite_or_null(x: f64) -> serde_json::Value {
    serde_json::Number::from_f64(x).map_or(serde_json::Value::Null, serde_json::Value::Number)
}

impl Step {
    /// The same message in the JSON form of format 1 (`null` for absent indices and gaps), for
    /// tools and tests that read both encodings alike.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let rods: Vec<serde_json::Value> = self
            .rods
            .iter()
            .map(|r| {
                json!({
                    "q": r.q, "u": r.u, "reaction": r.reaction, "reaction_norm": r.reaction_norm,
                    "impulse": r.impulse, "drive_force": r.drive_force, "normal": r.normal,
                    "in_contact": r.in_contact,
                    "contact_obstacle": r.contact_obstacle.iter().map(|&k| opt_index(k)).collect::<Vec<_>>(),
                    "normal2": r.normal2,
                    "contact_obstacle2": r.contact_obstacle2.iter().map(|&k| opt_index(k)).collect::<Vec<_>>(),
                    "bending_stress": r.bending_stress,
                    "gap": r.gap.iter().map(|&g| finite_or_null(g)).collect::<Vec<_>>(),
                    "q_predictor": r.q_predictor,
                })
            })
            .collect();
        let mut v = json!({
            "step": self.step, "t": self.t, "dt": self.dt,
            "newton_iterations": self.newton_iterations, "passes": self.passes, "rods": rods,
        });
        if !self.bodies.is_empty() {
            v["bodies"] = self
                .bodies
                .iter()
                .map(|b| {
                    json!({
                        "name": b.name, "obstacle": b.obstacle, "position": b.position,
                        "angle": b.angle, "velocity": b.velocity,
                        "angular_velocity": b.angular_velocity, "contact_force": b.contact_force,
                        "contact_torque": b.contact_torque, "mass": b.mass,
                    })
                })
                .collect();
        }
        if !self.contacts.is_empty() {
            v["contacts"] = self
                .contacts
                .iter()
                .map(|c| {
                    json!({
                        "rod": opt_index(c.rod), "node": c.node, "obstacle": c.obstacle,
                        "body": opt_index(c.body), "point": c.point, "normal": c.normal,
                        "normal_force": c.normal_force, "friction_force": c.friction_force,
                        "slip_velocity": c.slip_velocity, "stuck": c.stuck,
                        "utilisation": c.utilisation, "mu_s": c.mu_s,
                        "indentation": c.indentation, "half_width": c.half_width,
                        "peak_pressure": c.peak_pressure, "bruise_pressure": c.bruise_pressure,
                        "bruise_half_width": c.bruise_half_width,
                    })
                })
                .collect();
        }
        v
    }
}

impl Iteration {
    /// The JSON form of format 1.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "step": self.step, "t": self.t, "phase": self.phase, "pass": self.pass,
            "iteration": self.iteration, "rod": self.rod, "residual": self.residual,
            "update": self.update, "q": self.q,
        })
    }
}

/// Decode a message of `schema` in `encoding` (`json` or `protobuf`) to its JSON form: what
/// tests and tools that compare recordings of either encoding read. `None` for a schema or
/// encoding this does not know, or bytes that do not decode.
pub fn decode_json(schema: &str, encoding: &str, data: &[u8]) -> Option<serde_json::Value> {
    match (encoding, schema) {
        ("json", _) => serde_json::from_slice(data).ok(),
        ("protobuf", "gripsim.Step") => Step::decode(data).ok().map(|s| s.to_json()),
        ("protobuf", "gripsim.Iteration") => Iteration::decode(data).ok().map(|s| s.to_json()),
        ("protobuf", super::foxglove::SCHEMA) => super::foxglove::SceneUpdate::decode(data)
            .ok()
            .map(|s| s.to_json()),
        _ => None,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use prost::encoding::{decode_key, WireType};

    /// Every field of `bytes` (one message) as (number, wire type), in order.
    pub(crate) fn wire_fields(mut bytes: &[u8]) -> Vec<(u32, WireType)> {
        let mut out = Vec::new();
        while !bytes.is_empty() {
            let (tag, wt) = decode_key(&mut bytes).unwrap();
            out.push((tag, wt));
            match wt {
                WireType::Varint => {
                    prost::encoding::decode_varint(&mut bytes).unwrap();
                }
                WireType::SixtyFourBit => bytes = &bytes[8..],
                WireType::ThirtyTwoBit => bytes = &bytes[4..],
                WireType::LengthDelimited => {
                    let n = prost::encoding::decode_varint(&mut bytes).unwrap() as usize;
                    bytes = &bytes[n..];
                }
                _ => panic!("group wire type"),
            }
        }
        out
    }

    /// The wire type a table field must be written with (repeated scalars packed).
    fn expected_wire(kind: Kind, repeated: bool) -> WireType {
        match (kind, repeated) {
            (_, true) | (K::Str | K::Message(_), false) => WireType::LengthDelimited,
            (K::Double, false) => WireType::SixtyFourBit,
            _ => WireType::Varint,
        }
    }

    fn check(name: &str, bytes: &[u8]) {
        let fields = MESSAGES.iter().find(|(n, _)| *n == name).unwrap().1;
        let got = wire_fields(bytes);
        let want: Vec<(u32, WireType)> = fields
            .iter()
            .map(|&(_, n, k, r)| (n as u32, expected_wire(k, r)))
            .collect();
        assert_eq!(
            got, want,
            "{name}: the derive and the descriptor table differ"
        );
    }

    #[test]
    fn derives_and_descriptor_tables_agree_on_the_wire() {
        let rod = Rod {
            q: vec![1.0],
            u: vec![1.0],
            reaction: vec![1.0],
            reaction_norm: vec![1.0],
            impulse: vec![1.0],
            drive_force: vec![1.0],
            normal: vec![1.0],
            in_contact: vec![true],
            contact_obstacle: vec![-1],
            normal2: vec![1.0],
            contact_obstacle2: vec![2],
            bending_stress: vec![1.0],
            gap: vec![f64::INFINITY],
            q_predictor: vec![1.0],
        };
        let body = Body {
            name: "apple".into(),
            obstacle: 1,
            position: vec![1.0],
            angle: 1.0,
            velocity: vec![1.0],
            angular_velocity: 1.0,
            contact_force: vec![1.0],
            contact_torque: 1.0,
            mass: 1.0,
        };
        let contact = Contact {
            rod: -1,
            node: 1,
            obstacle: 1,
            body: 1,
            point: vec![1.0],
            normal: vec![1.0],
            normal_force: 1.0,
            friction_force: 1.0,
            slip_velocity: 1.0,
            stuck: true,
            utilisation: 1.0,
            mu_s: 1.0,
            indentation: 1.0,
            half_width: 1.0,
            peak_pressure: 1.0,
            bruise_pressure: 1.0,
            bruise_half_width: 1.0,
        };
        let step = Step {
            step: 1,
            t: 1.0,
            dt: 1.0,
            newton_iterations: 1,
            passes: 1,
            rods: vec![rod.clone()],
            bodies: vec![body.clone()],
            contacts: vec![contact.clone()],
        };
        let it = Iteration {
            step: 1,
            t: 1.0,
            phase: "predictor".into(),
            pass: 1,
            iteration: 1,
            rod: 1,
            residual: 1.0,
            update: 1.0,
            q: vec![1.0],
        };
        check("Step", &step.encode_to_vec());
        check("Rod", &rod.encode_to_vec());
        check("Body", &body.encode_to_vec());
        check("ContactState", &contact.encode_to_vec());
        check("Iteration", &it.encode_to_vec());
        // Round trip, with the JSON form of format 1.
        let back = Step::decode(step.encode_to_vec().as_slice()).unwrap();
        assert_eq!(back, step);
        let j = back.to_json();
        assert_eq!(j["rods"][0]["gap"][0], serde_json::Value::Null);
        assert_eq!(j["rods"][0]["contact_obstacle"][0], serde_json::Value::Null);
        assert_eq!(j["rods"][0]["contact_obstacle2"][0], 2);
        assert_eq!(j["contacts"][0]["rod"], serde_json::Value::Null);
    }

    #[test]
    fn the_descriptor_set_names_every_message() {
        let set = FileDescriptorSet::decode(file_descriptor_set().as_slice()).unwrap();
        assert_eq!(set.file.len(), 1);
        let f = &set.file[0];
        assert_eq!(f.package(), "gripsim");
        assert_eq!(f.syntax(), "proto3");
        let names: Vec<&str> = f.message_type.iter().map(|m| m.name()).collect();
        assert_eq!(names, ["Step", "Rod", "Body", "ContactState", "Iteration"]);
        let rod = &f.message_type[1];
        assert_eq!(rod.field.len(), 14);
        assert_eq!(rod.field[8].name(), "contact_obstacle");
        assert_eq!(rod.field[8].r#type(), Type::Sint64);
        assert_eq!(rod.field[8].label(), Label::Repeated);
        assert_eq!(f.message_type[0].field[5].type_name(), ".gripsim.Rod");
    }
}
