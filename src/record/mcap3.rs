//! The MCAP sink of a 3D run (`dimension = 3`): the archival record, on the pattern of the
//! planar [`super::mcap`] but with its own step message.
//!
//! | topic | schema | messages |
//! |---|---|---|
//! | `/sim/meta` | `gripsim.Meta3` (JSON) | one, first: scenario, rods, shapes, units |
//! | `/sim/step` | `gripsim.Step3` (protobuf) | step 0 (the initial state), then one per step: rods (x, y, z, velocity, material angle, twist, m₁, m₂), free bodies' poses, contacts, contact changes |
//! | `/scene/static` | `foxglove.SceneUpdate` (protobuf) | one, before the first step: the fixed obstacles |
//! | `/scene` | `foxglove.SceneUpdate` (protobuf) | one per step and step 0: rods, material frames, free bodies at their pose, contact normals, reactions and friction |
//! | `/sim/event` | `gripsim.Event` (JSON) | one, last: `run_end` (also the metadata record `gripsim.run_end`) |
//!
//! The `gripsim.Step3` schema is a `FileDescriptorSet` built here ([`file_descriptor_set`]), so
//! any protobuf library decodes the file without a `.proto` file. `/scene` draws spheres and
//! ellipsoids as Foxglove sphere primitives (scaled per axis), boxes as cubes, planes and
//! meshes as triangle lists ([`super::shape3`]). Log time: simulated ns. Written as
//! the planar files are ([`super::OutputFile`]: `NAME.partial.mcap`, renamed at
//! [`Mcap3::finish`]; a failed run's file keeps the `.partial` name; a device is written
//! through); zstd with one thread, so the same run gives the same bytes.

use super::shape3::tessellate;
use crate::obstacle3::Shape3;
use crate::rod3d::events::{
    BodyPose3, Contact3, Event3, Observer3, Rod3Info, Rod3StepView, Shape3Info,
};
use prost::Message as _;
use prost_types::{DescriptorProto, FileDescriptorProto, FileDescriptorSet};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// `gripsim.Step3`: the state of a 3D world at the end of a step.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Step3 {
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
    pub rods: Vec<Rod3>,
    #[prost(message, repeated, tag = "7")]
    pub bodies: Vec<Body3>,
    #[prost(message, repeated, tag = "8")]
    pub contacts: Vec<ContactState3>,
    #[prost(message, repeated, tag = "9")]
    pub changes: Vec<Change3>,
}

/// `gripsim.Rod3`: interleaved vectors `[x0, y0, z0, x1, …]`; `theta`, `m1`, `m2` per edge,
/// `twist` per node (0 at the ends).
#[derive(Clone, PartialEq, prost::Message)]
pub struct Rod3 {
    #[prost(double, repeated, tag = "1")]
    pub x: Vec<f64>,
    #[prost(double, repeated, tag = "2")]
    pub v: Vec<f64>,
    #[prost(double, repeated, tag = "3")]
    pub theta: Vec<f64>,
    #[prost(double, repeated, tag = "4")]
    pub twist: Vec<f64>,
    #[prost(double, repeated, tag = "5")]
    pub m1: Vec<f64>,
    #[prost(double, repeated, tag = "6")]
    pub m2: Vec<f64>,
}

/// `gripsim.Body3`: a free body; `shape` indexes the meta's shapes.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Body3 {
    #[prost(uint64, tag = "1")]
    pub shape: u64,
    #[prost(double, repeated, tag = "2")]
    pub position: Vec<f64>,
    /// Unit quaternion x, y, z, w.
    #[prost(double, repeated, tag = "3")]
    pub rotation: Vec<f64>,
    #[prost(double, repeated, tag = "4")]
    pub velocity: Vec<f64>,
    #[prost(double, repeated, tag = "5")]
    pub angular_velocity: Vec<f64>,
}

/// `gripsim.ContactState3`: one contact node (reaction = normal part, friction = tangential).
#[derive(Clone, PartialEq, prost::Message)]
pub struct ContactState3 {
    #[prost(uint64, tag = "1")]
    pub rod: u64,
    #[prost(uint64, tag = "2")]
    pub node: u64,
    #[prost(uint64, tag = "3")]
    pub shape: u64,
    #[prost(double, repeated, tag = "4")]
    pub point: Vec<f64>,
    #[prost(double, repeated, tag = "5")]
    pub normal: Vec<f64>,
    #[prost(double, repeated, tag = "6")]
    pub reaction: Vec<f64>,
    #[prost(double, repeated, tag = "7")]
    pub friction: Vec<f64>,
    #[prost(double, tag = "8")]
    pub gap: f64,
    #[prost(bool, tag = "9")]
    pub stuck: bool,
    #[prost(double, tag = "10")]
    pub normal_force: f64,
    /// 0: a node contact; else an edge contact's weight on the segment from `node`.
    #[prost(double, tag = "11")]
    pub weight: f64,
}

/// `gripsim.Change3`: a node that came into contact (added) or left it.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Change3 {
    #[prost(uint64, tag = "1")]
    pub rod: u64,
    #[prost(uint64, tag = "2")]
    pub node: u64,
    #[prost(bool, tag = "3")]
    pub added: bool,
}

use super::proto::{field_proto, Field, Kind as K};

/// The messages' fields: what the derives above say, for the descriptor.
const MESSAGES: &[(&str, &[Field])] = &[
    (
        "Step3",
        &[
            ("step", 1, K::Uint64, false),
            ("t", 2, K::Double, false),
            ("dt", 3, K::Double, false),
            ("newton_iterations", 4, K::Uint32, false),
            ("passes", 5, K::Uint32, false),
            ("rods", 6, K::Message("Rod3"), true),
            ("bodies", 7, K::Message("Body3"), true),
            ("contacts", 8, K::Message("ContactState3"), true),
            ("changes", 9, K::Message("Change3"), true),
        ],
    ),
    (
        "Rod3",
        &[
            ("x", 1, K::Double, true),
            ("v", 2, K::Double, true),
            ("theta", 3, K::Double, true),
            ("twist", 4, K::Double, true),
            ("m1", 5, K::Double, true),
            ("m2", 6, K::Double, true),
        ],
    ),
    (
        "Body3",
        &[
            ("shape", 1, K::Uint64, false),
            ("position", 2, K::Double, true),
            ("rotation", 3, K::Double, true),
            ("velocity", 4, K::Double, true),
            ("angular_velocity", 5, K::Double, true),
        ],
    ),
    (
        "ContactState3",
        &[
            ("rod", 1, K::Uint64, false),
            ("node", 2, K::Uint64, false),
            ("shape", 3, K::Uint64, false),
            ("point", 4, K::Double, true),
            ("normal", 5, K::Double, true),
            ("reaction", 6, K::Double, true),
            ("friction", 7, K::Double, true),
            ("gap", 8, K::Double, false),
            ("stuck", 9, K::Bool, false),
            ("normal_force", 10, K::Double, false),
            ("weight", 11, K::Double, false),
        ],
    ),
    (
        "Change3",
        &[
            ("rod", 1, K::Uint64, false),
            ("node", 2, K::Uint64, false),
            ("added", 3, K::Bool, false),
        ],
    ),
];

/// The `/sim/step` schema of a 3D run: `gripsim/recording3.proto` (proto3, package `gripsim`).
pub fn file_descriptor_set() -> Vec<u8> {
    let file = FileDescriptorProto {
        name: Some("gripsim/recording3.proto".into()),
        package: Some("gripsim".into()),
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

/// The step message of an [`Event3::Step`].
pub fn step_message(e: &Event3<'_>) -> Option<Step3> {
    let Event3::Step {
        step,
        time,
        dt,
        newton_iterations,
        rods,
        contacts,
        bodies,
        changes,
        passes,
        ..
    } = e
    else {
        return None;
    };
    Some(Step3 {
        step: *step,
        t: *time,
        dt: *dt,
        newton_iterations: *newton_iterations,
        passes: *passes,
        rods: rods.iter().map(rod_message).collect(),
        bodies: bodies.iter().map(body_message).collect(),
        contacts: contacts.iter().map(contact_message).collect(),
        changes: changes
            .iter()
            .map(|c| Change3 {
                rod: c.rod as u64,
                node: c.node as u64,
                added: c.added,
            })
            .collect(),
    })
}

fn rod_message(v: &Rod3StepView<'_>) -> Rod3 {
    let n = v.nodes();
    let mut r = Rod3::default();
    for i in 0..n {
        r.x.extend(v.node(i));
        r.v.extend(v.velocity(i));
        r.twist.push(v.twist(i));
        if i + 1 < n {
            let (m1, m2) = v.material_frame(i);
            r.theta.push(v.theta(i));
            r.m1.extend(m1);
            r.m2.extend(m2);
        }
    }
    r
}

fn body_message(b: &BodyPose3) -> Body3 {
    Body3 {
        shape: b.shape as u64,
        position: b.position.to_vec(),
        rotation: b.rotation.to_vec(),
        velocity: b.velocity.to_vec(),
        angular_velocity: b.angular_velocity.to_vec(),
    }
}

fn contact_message(c: &Contact3) -> ContactState3 {
    ContactState3 {
        rod: c.rod as u64,
        node: c.node as u64,
        shape: c.surface as u64,
        point: c.point.to_vec(),
        normal: c.normal.to_vec(),
        reaction: c.reaction.to_vec(),
        friction: c.friction.to_vec(),
        gap: c.gap,
        stuck: c.stick,
        normal_force: c.normal_force(),
        weight: c.weight,
    }
}

// ---- foxglove.SceneUpdate (protobuf, as the planar /scene: super::foxglove) --------------
// Numbers rounded to f32 (what the 3D panel draws with); the exact values are in /sim/step.

use super::foxglove as fx;

fn v3(p: [f64; 3]) -> fx::Vector3 {
    fx::Vector3 {
        x: p[0] as f32 as f64,
        y: p[1] as f32 as f64,
        z: p[2] as f32 as f64,
    }
}

fn pose(p: [f64; 3], q: [f64; 4]) -> Option<fx::Pose> {
    Some(fx::Pose {
        position: Some(v3(p)),
        orientation: Some(fx::Quaternion {
            x: q[0] as f32 as f64,
            y: q[1] as f32 as f64,
            z: q[2] as f32 as f64,
            w: q[3] as f32 as f64,
        }),
    })
}

const fn rgba(r: f64, g: f64, b: f64, a: f64) -> fx::Color {
    fx::Color { r, g, b, a }
}

const ROD: fx::Color = rgba(0.1, 0.1, 0.1, 1.0);
const M1: fx::Color = rgba(0.86, 0.16, 0.16, 1.0);
const M2: fx::Color = rgba(0.16, 0.67, 0.16, 1.0);
const NORMAL: fx::Color = rgba(0.24, 0.35, 0.9, 1.0);
const REACTION: fx::Color = rgba(0.94, 0.59, 0.12, 1.0);
const FRICTION: fx::Color = rgba(0.63, 0.24, 0.78, 1.0);
const FRUIT: fx::Color = rgba(0.9, 0.47, 0.24, 0.8);
const OBSTACLE: fx::Color = rgba(0.6, 0.6, 0.6, 0.45);

/// A scene entity in frame "world", kept until replaced.
fn entity(id: String, timestamp: fx::Timestamp) -> fx::SceneEntity {
    fx::SceneEntity {
        timestamp: Some(timestamp),
        frame_id: "world".into(),
        id,
        ..Default::default()
    }
}

/// Draw `shape` at `at` in `e`: spheres and ellipsoids as sphere primitives (scaled per
/// axis), boxes as cubes, planes and meshes as triangle lists.
fn draw_shape(
    e: &mut fx::SceneEntity,
    shape: &Shape3,
    at: Option<fx::Pose>,
    plane_half: f64,
    color: fx::Color,
) {
    let solid = |size: [f64; 3]| fx::SpherePrimitive {
        pose: at,
        size: Some(v3(size)),
        color: Some(color),
    };
    match shape {
        Shape3::Sphere { radius } => e.spheres.push(solid([2.0 * radius; 3])),
        Shape3::Ellipsoid { semi_axes } => e.spheres.push(solid(semi_axes.map(|a| 2.0 * a))),
        Shape3::Box { half } => e.cubes.push(fx::CubePrimitive {
            pose: at,
            size: Some(v3(half.map(|a| 2.0 * a))),
            color: Some(color),
        }),
        Shape3::Plane | Shape3::Mesh(_) => {
            let t = tessellate(shape, plane_half);
            e.triangles.push(fx::TriangleListPrimitive {
                pose: at,
                points: t.vertices.iter().map(|p| v3(*p)).collect(),
                color: Some(color),
                colors: vec![],
                indices: t.triangles.iter().flatten().copied().collect(),
            })
        }
    }
}

/// An arrow from `from` along `v` (its length |v|), `d` thick.
fn arrow(from: [f64; 3], v: [f64; 3], d: f64, color: fx::Color) -> Option<fx::ArrowPrimitive> {
    let dir = nalgebra::Vector3::from(v);
    let len = dir.norm();
    if !(len > 0.0) {
        return None;
    }
    let rot = nalgebra::UnitQuaternion::rotation_between(&nalgebra::Vector3::x(), &dir)
        .unwrap_or_else(|| {
            nalgebra::UnitQuaternion::from_axis_angle(
                &nalgebra::Vector3::z_axis(),
                std::f64::consts::PI,
            )
        });
    let head = (2.5 * d).min(0.4 * len);
    let r = |x: f64| x as f32 as f64;
    Some(fx::ArrowPrimitive {
        pose: pose(from, [rot.i, rot.j, rot.k, rot.w]),
        shaft_length: r(len - head),
        shaft_diameter: r(d),
        head_length: r(head),
        head_diameter: r(2.0 * d),
        color: Some(color),
    })
}

/// A line primitive (0 = LINE_STRIP, 2 = LINE_LIST) in world coordinates.
fn line(
    kind: i32,
    points: Vec<fx::Vector3>,
    thickness: f64,
    color: fx::Color,
) -> fx::LinePrimitive {
    fx::LinePrimitive {
        r#type: kind,
        pose: pose([0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        thickness,
        scale_invariant: true,
        points,
        color: Some(color),
        colors: vec![],
        indices: vec![],
    }
}

// ---- /sim/meta -----------------------------------------------------------------------------

/// The JSON schema of `/sim/meta` in a 3D run.
pub const META3_SCHEMA: &str = include_str!("schemas/gripsim.Meta3.json");

#[derive(Serialize)]
struct RodMeta<'a> {
    name: &'a str,
    nodes: usize,
    rest_length: &'a [f64],
    half_extents: [f64; 2],
}

#[derive(Serialize)]
struct ShapeMeta<'a> {
    name: &'a str,
    kind: &'static str,
    free: bool,
    /// Radius, semi-axes or half extents (empty for a plane or a mesh).
    size: Vec<f64>,
    position: [f64; 3],
    rotation: [f64; 4],
    /// A mesh's OBJ text and scale, hashed (`TriMesh::source_hash`, 16 hex digits): a replay
    /// refuses a different mesh at the path the scenario names.
    #[serde(skip_serializing_if = "Option::is_none")]
    mesh_hash: Option<String>,
}

#[derive(Serialize)]
struct Meta3<'a> {
    format_version: u32,
    dimension: u32,
    gripsim_version: &'a str,
    scenario_name: &'a str,
    scenario_text: &'a str,
    sets: &'a [String],
    units: BTreeMap<&'a str, &'a str>,
    rods: Vec<RodMeta<'a>>,
    shapes: Vec<ShapeMeta<'a>>,
}

fn shape_meta(s: &Shape3Info) -> ShapeMeta<'_> {
    let (kind, size) = match &s.shape {
        Shape3::Sphere { radius } => ("sphere", vec![*radius]),
        Shape3::Ellipsoid { semi_axes } => ("ellipsoid", semi_axes.to_vec()),
        Shape3::Plane => ("plane", vec![]),
        Shape3::Box { half } => ("box", half.to_vec()),
        Shape3::Mesh(_) => ("mesh", vec![]),
    };
    ShapeMeta {
        name: &s.name,
        kind,
        free: s.free,
        size,
        position: s.pose.position.into(),
        rotation: quat(&s.pose),
        mesh_hash: match &s.shape {
            Shape3::Mesh(m) if m.source_hash != 0 => Some(format!("{:016x}", m.source_hash)),
            _ => None,
        },
    }
}

fn quat(p: &crate::obstacle3::Pose3) -> [f64; 4] {
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(&p.rotation);
    [q.i, q.j, q.k, q.w]
}

// ---- the sink ------------------------------------------------------------------------------

const META: usize = 0;
const STEP: usize = 1;
const SCENE_STATIC: usize = 2;
const SCENE: usize = 3;
const EVENT: usize = 4;

/// The 3D recording format: 2 adds step 0 (the initial state) on `/sim/step` and `/scene`,
/// and the run's end (`/sim/event` `run_end`, metadata `gripsim.run_end`).
/// 3: `/scene` and `/scene/static` are protobuf `foxglove.SceneUpdate` (JSON before), as the
/// planar ones.
pub const FORMAT_VERSION3: u32 = 3;

/// (topic, schema name) of every channel.
pub const CHANNELS3: [(&str, &str); 5] = [
    ("/sim/meta", "gripsim.Meta3"),
    ("/sim/step", "gripsim.Step3"),
    ("/scene/static", "foxglove.SceneUpdate"),
    ("/scene", "foxglove.SceneUpdate"),
    ("/sim/event", "gripsim.Event"),
];

/// The run-end message on `/sim/event` (the planar `gripsim.Event` schema, kind `run_end`).
#[derive(Serialize)]
struct RunEnd3 {
    kind: &'static str,
    step: u64,
    t: f64,
    message: String,
    completed: bool,
    error: Option<String>,
}

type Writer = ::mcap::Writer<BufWriter<std::fs::File>>;

/// Writes the MCAP file of a 3D run.
pub struct Mcap3 {
    out: super::OutputFile,
    writer: Option<Writer>,
    channels: [u16; 5],
    sequence: [u32; 5],
    /// The `gripsim.run_end` metadata, written at [`Mcap3::finish`] (empty: no run end seen).
    end: BTreeMap<String, String>,
    buf: Vec<u8>,
    name: String,
    text: String,
    sets: Vec<String>,
    rods: Vec<Rod3Info>,
    shapes: Vec<Shape3Info>,
    last_time: u64,
    /// Half size of a drawn plane (m).
    pub plane_half: f64,
    /// Force arrows: metres per newton.
    pub force_scale: f64,
    error: Option<String>,
}

impl Mcap3 {
    /// Create `path` for the scenario `name` with text `text` and the `--set` overrides
    /// `sets` (both stored in `/sim/meta`). Written as the planar files are
    /// ([`super::OutputFile`]): under a `.partial` name renamed at the end of a completed run;
    /// a device or FIFO written through; a symlink followed.
    pub fn create(path: &Path, name: &str, text: &str, sets: &[String]) -> Result<Mcap3, String> {
        let out = super::OutputFile::new(path);
        let file = out.create().map_err(|e| e.to_string())?;
        let shown = out.writing().display().to_string();
        let fail = |e: &dyn std::fmt::Display| {
            out.discard();
            format!("{shown}: {e}")
        };
        let mut w = ::mcap::WriteOptions::new()
            .profile("")
            .library(super::mcap::LIBRARY)
            .compression_threads(0)
            .create(BufWriter::with_capacity(1 << 16, file))
            .map_err(|e| fail(&e))?;
        let mut channels = [0u16; 5];
        let scene = fx::file_descriptor_set();
        for (k, (topic, schema)) in CHANNELS3.iter().enumerate() {
            let (sid, enc) = match k {
                STEP => (
                    w.add_schema(schema, "protobuf", &file_descriptor_set()),
                    "protobuf",
                ),
                META => (
                    w.add_schema(schema, "jsonschema", META3_SCHEMA.as_bytes()),
                    "json",
                ),
                EVENT => (
                    w.add_schema(
                        schema,
                        "jsonschema",
                        include_str!("schemas/gripsim.Event.json").as_bytes(),
                    ),
                    "json",
                ),
                _ => (w.add_schema(schema, "protobuf", &scene), "protobuf"),
            };
            let sid = sid.map_err(|e| fail(&e))?;
            channels[k] = w
                .add_channel(sid, topic, enc, &BTreeMap::new())
                .map_err(|e| fail(&e))?;
        }
        Ok(Mcap3 {
            out,
            writer: Some(w),
            channels,
            sequence: [0; 5],
            end: BTreeMap::new(),
            buf: Vec::with_capacity(1 << 14),
            name: name.to_string(),
            text: text.to_string(),
            sets: sets.to_vec(),
            rods: vec![],
            shapes: vec![],
            last_time: 0,
            plane_half: 0.1,
            force_scale: 0.04,
            error: None,
        })
    }

    fn write_buf(&mut self, k: usize, log_time: u64) {
        let Some(w) = self.writer.as_mut() else {
            return;
        };
        let header = ::mcap::records::MessageHeader {
            channel_id: self.channels[k],
            sequence: self.sequence[k],
            log_time,
            publish_time: log_time,
        };
        self.sequence[k] = self.sequence[k].wrapping_add(1);
        if let Err(e) = w.write_to_known_channel(&header, &self.buf) {
            self.fail(e);
        }
    }

    fn send<T: Serialize>(&mut self, k: usize, log_time: u64, msg: &T) {
        self.buf.clear();
        if let Err(e) = serde_json::to_writer(&mut self.buf, msg) {
            return self.fail(e);
        }
        self.write_buf(k, log_time);
    }

    fn fail(&mut self, e: impl std::fmt::Display) {
        self.error.get_or_insert(e.to_string());
        self.writer = None;
    }

    /// Close the file and move it into place.
    pub fn finish(self) -> Result<(), String> {
        self.close(true).map(drop)
    }

    /// Close the file of a run that failed (its run end says why): it keeps its `.partial`
    /// name, as a planar run's. Returns where it is.
    pub fn finish_failed(self) -> Result<PathBuf, String> {
        self.close(false)
    }

    fn close(mut self, complete: bool) -> Result<PathBuf, String> {
        if let Some(mut w) = self.writer.take() {
            let mut closed = Ok(());
            if !self.end.is_empty() {
                let record = ::mcap::records::Metadata {
                    name: "gripsim.run_end".into(),
                    metadata: std::mem::take(&mut self.end),
                };
                closed = w.write_metadata(&record).map_err(|e| e.to_string());
            }
            let closed = closed
                .and_then(|_| w.finish().map_err(|e| e.to_string()))
                .and_then(|_| {
                    w.into_inner()
                        .into_inner()
                        .map(drop)
                        .map_err(|e| e.error().to_string())
                });
            if let Err(e) = closed {
                self.error.get_or_insert(e);
            }
        }
        self.out.conclude(self.error.take(), complete)
    }

    /// Close and remove the unfinished file (a run that never started leaves nothing).
    pub fn abandon(mut self) {
        self.writer = None;
        self.out.discard();
    }

    fn meta(&mut self) {
        let units = [
            ("length", "m"),
            ("time", "s"),
            ("velocity", "m/s"),
            ("angle", "rad"),
            ("force", "N"),
            ("log_time", "ns"),
        ];
        let meta = Meta3 {
            format_version: FORMAT_VERSION3,
            dimension: 3,
            gripsim_version: env!("CARGO_PKG_VERSION"),
            scenario_name: &self.name,
            scenario_text: &self.text,
            sets: &self.sets,
            units: units.into_iter().collect(),
            rods: self
                .rods
                .iter()
                .map(|r| RodMeta {
                    name: &r.name,
                    nodes: r.nodes,
                    rest_length: &r.rest_length,
                    half_extents: r.half_extents,
                })
                .collect(),
            shapes: self.shapes.iter().map(shape_meta).collect(),
        };
        self.buf.clear();
        match serde_json::to_writer(&mut self.buf, &meta) {
            Ok(()) => self.write_buf(META, 0),
            Err(e) => self.fail(e),
        }
        let mut fixed = entity("obstacles".into(), fx::Timestamp::default());
        for s in self.shapes.iter().filter(|s| !s.free) {
            draw_shape(
                &mut fixed,
                &s.shape,
                pose(s.pose.position.into(), quat(&s.pose)),
                self.plane_half,
                OBSTACLE,
            );
        }
        let msg = fx::SceneUpdate {
            deletions: vec![],
            entities: vec![fixed],
        };
        self.send_proto(SCENE_STATIC, 0, &msg);
    }

    fn scene(
        &self,
        stamp: fx::Timestamp,
        rods: &[Rod3StepView<'_>],
        bodies: &[BodyPose3],
    ) -> fx::SceneUpdate {
        let mut entities = Vec::new();
        for (r, v) in rods.iter().enumerate() {
            let (name, half) = self
                .rods
                .get(r)
                .map_or((format!("rod{r}"), [1e-3; 2]), |i| {
                    (i.name.clone(), i.half_extents)
                });
            let mut e = entity(format!("rod/{name}"), stamp);
            let n = v.nodes();
            e.lines
                .push(line(0, (0..n).map(|i| v3(v.node(i))).collect(), 3.0, ROD));
            let (mut l1, mut l2) = (vec![], vec![]);
            for i in 0..n - 1 {
                let (a, b) = (v.node(i), v.node(i + 1));
                let mid = [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]));
                let (m1, m2) = v.material_frame(i);
                for (m, h, l) in [(m1, half[0], &mut l1), (m2, half[1], &mut l2)] {
                    l.push(v3(mid));
                    l.push(v3([0, 1, 2].map(|k| mid[k] + 3.0 * h * m[k])));
                }
            }
            e.lines.push(line(2, l1, 1.5, M1));
            e.lines.push(line(2, l2, 1.5, M2));
            entities.push(e);
        }
        for b in bodies {
            let Some(s) = self.shapes.get(b.shape) else {
                continue;
            };
            let mut e = entity(format!("body/{}", s.name), stamp);
            draw_shape(
                &mut e,
                &s.shape,
                pose(b.position, b.rotation),
                self.plane_half,
                FRUIT,
            );
            entities.push(e);
        }
        fx::SceneUpdate {
            deletions: vec![],
            entities,
        }
    }

    fn contacts_entity(&self, stamp: fx::Timestamp, contacts: &[Contact3]) -> fx::SceneEntity {
        let d = 0.3
            * self
                .rods
                .iter()
                .map(|r| r.half_extents[0])
                .fold(1e-3, f64::max);
        let mut e = entity("contacts".into(), stamp);
        for c in contacts {
            let k = self.force_scale;
            e.arrows.extend(
                [
                    arrow(c.point, c.normal.map(|x| 10.0 * d * x), 0.5 * d, NORMAL),
                    arrow(c.point, c.reaction.map(|x| k * x), d, REACTION),
                    arrow(c.point, c.friction.map(|x| k * x), d, FRICTION),
                ]
                .into_iter()
                .flatten(),
            );
        }
        e
    }

    fn send_proto(&mut self, k: usize, log_time: u64, msg: &impl prost::Message) {
        self.buf.clear();
        msg.encode(&mut self.buf)
            .expect("a Vec grows to take any message");
        self.write_buf(k, log_time);
    }
}

impl Observer3 for Mcap3 {
    fn on_event(&mut self, e: &Event3<'_>) {
        match e {
            Event3::Start { rods } => self.rods = rods.to_vec(),
            Event3::Scene { shapes } => {
                self.shapes = shapes.to_vec();
                self.meta();
            }
            Event3::Step {
                time,
                rods,
                bodies,
                contacts,
                ..
            } => {
                let t = ((time * 1e9).round() as u64).max(self.last_time);
                self.last_time = t;
                if let Some(msg) = step_message(e) {
                    self.buf.clear();
                    msg.encode(&mut self.buf)
                        .expect("a Vec grows to take any message");
                    self.write_buf(STEP, t);
                }
                let stamp = fx::Timestamp {
                    seconds: (t / 1_000_000_000) as i64,
                    nanos: (t % 1_000_000_000) as i32,
                };
                let mut scene = self.scene(stamp, rods, bodies);
                scene.entities.push(self.contacts_entity(stamp, contacts));
                self.send_proto(SCENE, t, &scene);
            }
            Event3::End { steps, time, error } => {
                // A failed run's file keeps its `.partial` name, with the error as its end.
                self.end = BTreeMap::from([
                    ("completed".into(), error.is_none().to_string()),
                    ("steps".into(), steps.to_string()),
                    ("t".into(), time.to_string()),
                    ("error".into(), error.unwrap_or_default().to_string()),
                ]);
                let t = ((time * 1e9).round() as u64).max(self.last_time);
                let message = match error {
                    None => format!("run completed: {steps} steps, t = {time} s"),
                    Some(e) => format!("run failed after {steps} steps, t = {time} s: {e}"),
                };
                let msg = RunEnd3 {
                    kind: "run_end",
                    step: *steps,
                    t: *time,
                    message,
                    completed: error.is_none(),
                    error: error.map(str::to_string),
                };
                self.send(EVENT, t, &msg);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The descriptor tables say what the derives write: a message with every field set
    /// decodes through the descriptor-driven reading of its tags (field numbers agree).
    #[test]
    fn descriptor_names_every_message_and_field() {
        let set = FileDescriptorSet::decode(&*file_descriptor_set()).unwrap();
        let names: Vec<&str> = set.file[0].message_type.iter().map(|m| m.name()).collect();
        assert_eq!(
            names,
            ["Step3", "Rod3", "Body3", "ContactState3", "Change3"]
        );
        let step = Step3 {
            step: 3,
            t: 0.5,
            dt: 0.1,
            newton_iterations: 2,
            passes: 1,
            rods: vec![Rod3 {
                x: vec![1.0, 2.0, 3.0],
                ..Default::default()
            }],
            ..Default::default()
        };
        let back = Step3::decode(&*step.encode_to_vec()).unwrap();
        assert_eq!(back, step);
    }
}
