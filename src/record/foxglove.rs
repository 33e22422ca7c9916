//! `foxglove.SceneUpdate` as protobuf: the MCAP `/scene` and `/scene/static` channels.
//!
//! The messages we write are `prost` derives; the schema the channels carry is a
//! `google.protobuf.FileDescriptorSet` built here from one table per message ([`MESSAGES`],
//! field names and numbers as Foxglove publishes them), with the two well-known types it
//! imports (`google/protobuf/timestamp.proto`, `duration.proto`) in the same set, so Foxglove
//! and any protobuf library decode the file without a `.proto` file. The set describes every
//! message `foxglove.SceneEntity` refers to (cubes, cylinders, triangles, models, metadata),
//! also those gripsim never writes, so a reader sees the complete published type.

use prost::Message as _;
use prost_types::field_descriptor_proto::Type;
use prost_types::{
    DescriptorProto, EnumDescriptorProto, EnumValueDescriptorProto, FieldDescriptorProto,
    FileDescriptorProto, FileDescriptorSet,
};

/// `foxglove.SceneUpdate`.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct SceneUpdate {
    #[prost(message, repeated, tag = "1")]
    pub deletions: Vec<SceneEntityDeletion>,
    #[prost(message, repeated, tag = "2")]
    pub entities: Vec<SceneEntity>,
}

/// `foxglove.SceneEntityDeletion` (never written; here for the wire test and readers).
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct SceneEntityDeletion {
    #[prost(message, optional, tag = "1")]
    pub timestamp: Option<Timestamp>,
    /// 0 = MATCHING_ID, 1 = ALL.
    #[prost(int32, tag = "2")]
    pub r#type: i32,
    #[prost(string, tag = "3")]
    pub id: String,
}

/// `foxglove.SceneEntity` with the primitives gripsim draws (fields 6, 10 and 14 — metadata,
/// cylinders, models — are in the schema, never written; cubes and triangle lists only in 3D).
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct SceneEntity {
    #[prost(message, optional, tag = "1")]
    pub timestamp: Option<Timestamp>,
    #[prost(string, tag = "2")]
    pub frame_id: String,
    #[prost(string, tag = "3")]
    pub id: String,
    /// Zero (or absent): kept until replaced.
    #[prost(message, optional, tag = "4")]
    pub lifetime: Option<Duration>,
    #[prost(bool, tag = "5")]
    pub frame_locked: bool,
    #[prost(message, repeated, tag = "7")]
    pub arrows: Vec<ArrowPrimitive>,
    /// 3D scenes only (boxes); empty in a planar one, so neither on the wire nor in JSON.
    #[prost(message, repeated, tag = "8")]
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub cubes: Vec<CubePrimitive>,
    #[prost(message, repeated, tag = "9")]
    pub spheres: Vec<SpherePrimitive>,
    #[prost(message, repeated, tag = "11")]
    pub lines: Vec<LinePrimitive>,
    /// 3D scenes only (planes and meshes); empty in a planar one.
    #[prost(message, repeated, tag = "12")]
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub triangles: Vec<TriangleListPrimitive>,
    #[prost(message, repeated, tag = "13")]
    pub texts: Vec<TextPrimitive>,
}

/// `foxglove.CubePrimitive`.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct CubePrimitive {
    #[prost(message, optional, tag = "1")]
    pub pose: Option<Pose>,
    #[prost(message, optional, tag = "2")]
    pub size: Option<Vector3>,
    #[prost(message, optional, tag = "3")]
    pub color: Option<Color>,
}

/// `foxglove.TriangleListPrimitive`: every three points (or indices) a triangle.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct TriangleListPrimitive {
    #[prost(message, optional, tag = "1")]
    pub pose: Option<Pose>,
    /// `foxglove.Point3`.
    #[prost(message, repeated, tag = "2")]
    pub points: Vec<Vector3>,
    #[prost(message, optional, tag = "3")]
    pub color: Option<Color>,
    #[prost(message, repeated, tag = "4")]
    pub colors: Vec<Color>,
    #[prost(fixed32, repeated, tag = "5")]
    pub indices: Vec<u32>,
}

/// `foxglove.PointCloud`: points packed in `data`, `point_stride` bytes each, laid out by
/// `fields` (the MCAP's `/scene/nodes`).
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct PointCloud {
    #[prost(message, optional, tag = "1")]
    pub timestamp: Option<Timestamp>,
    #[prost(string, tag = "2")]
    pub frame_id: String,
    #[prost(message, optional, tag = "3")]
    pub pose: Option<Pose>,
    #[prost(fixed32, tag = "4")]
    pub point_stride: u32,
    #[prost(message, repeated, tag = "5")]
    pub fields: Vec<PackedElementField>,
    #[prost(bytes = "vec", tag = "6")]
    pub data: Vec<u8>,
}

/// `foxglove.PackedElementField`: one field of every packed point.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct PackedElementField {
    #[prost(string, tag = "1")]
    pub name: String,
    #[prost(fixed32, tag = "2")]
    pub offset: u32,
    /// `foxglove.PackedElementField.NumericType`: 1 = UINT8, 7 = FLOAT32 (the two used here).
    #[prost(int32, tag = "3")]
    pub r#type: i32,
}

/// `PackedElementField.NumericType` UINT8 and FLOAT32.
pub const UINT8: i32 = 1;
pub const FLOAT32: i32 = 7;

/// The bytes per node of `/scene/nodes`: f32 x, y, z and u8 red, green, blue, alpha.
pub const NODE_POINT_STRIDE: u32 = 16;

/// The fields of a `/scene/nodes` point (Foxglove's 3D panel colours them with its
/// "RGBA (separate fields)" colour mode).
pub fn node_point_fields() -> Vec<PackedElementField> {
    [
        ("x", 0, FLOAT32),
        ("y", 4, FLOAT32),
        ("z", 8, FLOAT32),
        ("red", 12, UINT8),
        ("green", 13, UINT8),
        ("blue", 14, UINT8),
        ("alpha", 15, UINT8),
    ]
    .into_iter()
    .map(|(name, offset, ty)| PackedElementField {
        name: name.into(),
        offset,
        r#type: ty,
    })
    .collect()
}

impl PointCloud {
    /// The points as `[x, y, z, red, green, blue, alpha]` (f64 of the f32 and u8 values), read
    /// through `fields` and `point_stride`; None if a field of those is missing or the data do
    /// not fit.
    pub fn points(&self) -> Option<Vec<[f64; 7]>> {
        let stride = self.point_stride as usize;
        let at = |name: &str, ty: i32| {
            self.fields
                .iter()
                .find(|f| f.name == name && f.r#type == ty)
                .map(|f| f.offset as usize)
        };
        let f32s = [at("x", FLOAT32)?, at("y", FLOAT32)?, at("z", FLOAT32)?];
        let u8s = [
            at("red", UINT8)?,
            at("green", UINT8)?,
            at("blue", UINT8)?,
            at("alpha", UINT8)?,
        ];
        if stride == 0 || !self.data.len().is_multiple_of(stride) {
            return None;
        }
        let mut out = Vec::with_capacity(self.data.len() / stride);
        for p in self.data.chunks_exact(stride) {
            let mut v = [0.0; 7];
            for (k, &o) in f32s.iter().enumerate() {
                v[k] = f32::from_le_bytes(p.get(o..o + 4)?.try_into().ok()?) as f64;
            }
            for (k, &o) in u8s.iter().enumerate() {
                v[3 + k] = *p.get(o)? as f64;
            }
            out.push(v);
        }
        Some(out)
    }

    /// The message as JSON: its fields, with `data` decoded to `points` ([`Self::points`]).
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = serde_json::json!({
            "timestamp": self.timestamp, "frame_id": self.frame_id, "pose": self.pose,
            "point_stride": self.point_stride, "fields": self.fields,
        });
        v["points"] = serde_json::to_value(self.points()).expect("numbers serialise");
        v
    }
}

/// `google.protobuf.Timestamp`.
#[derive(Clone, Copy, PartialEq, prost::Message, serde::Serialize)]
pub struct Timestamp {
    #[prost(int64, tag = "1")]
    pub seconds: i64,
    #[prost(int32, tag = "2")]
    pub nanos: i32,
}

/// `google.protobuf.Duration`.
#[derive(Clone, Copy, PartialEq, prost::Message, serde::Serialize)]
pub struct Duration {
    #[prost(int64, tag = "1")]
    pub seconds: i64,
    #[prost(int32, tag = "2")]
    pub nanos: i32,
}

/// `foxglove.ArrowPrimitive`.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct ArrowPrimitive {
    #[prost(message, optional, tag = "1")]
    pub pose: Option<Pose>,
    #[prost(double, tag = "2")]
    pub shaft_length: f64,
    #[prost(double, tag = "3")]
    pub shaft_diameter: f64,
    #[prost(double, tag = "4")]
    pub head_length: f64,
    #[prost(double, tag = "5")]
    pub head_diameter: f64,
    #[prost(message, optional, tag = "6")]
    pub color: Option<Color>,
}

/// `foxglove.SpherePrimitive`.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct SpherePrimitive {
    #[prost(message, optional, tag = "1")]
    pub pose: Option<Pose>,
    #[prost(message, optional, tag = "2")]
    pub size: Option<Vector3>,
    #[prost(message, optional, tag = "3")]
    pub color: Option<Color>,
}

/// `foxglove.LinePrimitive`.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct LinePrimitive {
    /// 0 = LINE_STRIP, 1 = LINE_LOOP, 2 = LINE_LIST.
    #[prost(int32, tag = "1")]
    pub r#type: i32,
    #[prost(message, optional, tag = "2")]
    pub pose: Option<Pose>,
    #[prost(double, tag = "3")]
    pub thickness: f64,
    #[prost(bool, tag = "4")]
    pub scale_invariant: bool,
    /// `foxglove.Point3` (the same fields as `Vector3`).
    #[prost(message, repeated, tag = "5")]
    pub points: Vec<Vector3>,
    #[prost(message, optional, tag = "6")]
    pub color: Option<Color>,
    #[prost(message, repeated, tag = "7")]
    pub colors: Vec<Color>,
    #[prost(fixed32, repeated, tag = "8")]
    pub indices: Vec<u32>,
}

/// `foxglove.TextPrimitive`.
#[derive(Clone, PartialEq, prost::Message, serde::Serialize)]
pub struct TextPrimitive {
    #[prost(message, optional, tag = "1")]
    pub pose: Option<Pose>,
    #[prost(bool, tag = "2")]
    pub billboard: bool,
    #[prost(double, tag = "3")]
    pub font_size: f64,
    #[prost(bool, tag = "4")]
    pub scale_invariant: bool,
    #[prost(message, optional, tag = "5")]
    pub color: Option<Color>,
    #[prost(string, tag = "6")]
    pub text: String,
}

/// `foxglove.Pose`.
#[derive(Clone, Copy, PartialEq, prost::Message, serde::Serialize)]
pub struct Pose {
    #[prost(message, optional, tag = "1")]
    pub position: Option<Vector3>,
    #[prost(message, optional, tag = "2")]
    pub orientation: Option<Quaternion>,
}

/// `foxglove.Vector3` and `foxglove.Point3`.
#[derive(Clone, Copy, PartialEq, prost::Message, serde::Serialize)]
pub struct Vector3 {
    #[prost(double, tag = "1")]
    pub x: f64,
    #[prost(double, tag = "2")]
    pub y: f64,
    #[prost(double, tag = "3")]
    pub z: f64,
}

/// `foxglove.Quaternion`.
#[derive(Clone, Copy, PartialEq, prost::Message, serde::Serialize)]
pub struct Quaternion {
    #[prost(double, tag = "1")]
    pub x: f64,
    #[prost(double, tag = "2")]
    pub y: f64,
    #[prost(double, tag = "3")]
    pub z: f64,
    #[prost(double, tag = "4")]
    pub w: f64,
}

/// `foxglove.Color` (components 0 … 1).
#[derive(Clone, Copy, PartialEq, prost::Message, serde::Serialize)]
pub struct Color {
    #[prost(double, tag = "1")]
    pub r: f64,
    #[prost(double, tag = "2")]
    pub g: f64,
    #[prost(double, tag = "3")]
    pub b: f64,
    #[prost(double, tag = "4")]
    pub a: f64,
}

/// The type of a field in a descriptor table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Double,
    Bool,
    Int32,
    Int64,
    Fixed32,
    Str,
    Bytes,
    /// A message or enum by its full name (`.foxglove.Pose`).
    Message(&'static str),
    Enum(&'static str),
}

/// One field: name, number, type, repeated.
pub type Field = (&'static str, i32, Kind, bool);

use Kind as K;

const POSE: Kind = K::Message(".foxglove.Pose");
const COLOR: Kind = K::Message(".foxglove.Color");
const VECTOR3: Kind = K::Message(".foxglove.Vector3");
const POINT3: Kind = K::Message(".foxglove.Point3");
const TIMESTAMP: Kind = K::Message(".google.protobuf.Timestamp");

const XYZ: &[Field] = &[
    ("x", 1, K::Double, false),
    ("y", 2, K::Double, false),
    ("z", 3, K::Double, false),
];
const SECONDS_NANOS: &[Field] = &[
    ("seconds", 1, K::Int64, false),
    ("nanos", 2, K::Int32, false),
];

/// A nested enum: its name and values.
type EnumDef = (&'static str, &'static [(&'static str, i32)]);

/// Every message of the package `foxglove` that `SceneUpdate` reaches, with its fields and
/// nested enums.
pub const MESSAGES: [(&str, &[Field], Option<EnumDef>); 19] = [
    (
        "SceneUpdate",
        &[
            (
                "deletions",
                1,
                K::Message(".foxglove.SceneEntityDeletion"),
                true,
            ),
            ("entities", 2, K::Message(".foxglove.SceneEntity"), true),
        ],
        None,
    ),
    (
        "SceneEntityDeletion",
        &[
            ("timestamp", 1, TIMESTAMP, false),
            (
                "type",
                2,
                K::Enum(".foxglove.SceneEntityDeletion.Type"),
                false,
            ),
            ("id", 3, K::Str, false),
        ],
        Some(("Type", &[("MATCHING_ID", 0), ("ALL", 1)])),
    ),
    (
        "SceneEntity",
        &[
            ("timestamp", 1, TIMESTAMP, false),
            ("frame_id", 2, K::Str, false),
            ("id", 3, K::Str, false),
            (
                "lifetime",
                4,
                K::Message(".google.protobuf.Duration"),
                false,
            ),
            ("frame_locked", 5, K::Bool, false),
            ("metadata", 6, K::Message(".foxglove.KeyValuePair"), true),
            ("arrows", 7, K::Message(".foxglove.ArrowPrimitive"), true),
            ("cubes", 8, K::Message(".foxglove.CubePrimitive"), true),
            ("spheres", 9, K::Message(".foxglove.SpherePrimitive"), true),
            (
                "cylinders",
                10,
                K::Message(".foxglove.CylinderPrimitive"),
                true,
            ),
            ("lines", 11, K::Message(".foxglove.LinePrimitive"), true),
            (
                "triangles",
                12,
                K::Message(".foxglove.TriangleListPrimitive"),
                true,
            ),
            ("texts", 13, K::Message(".foxglove.TextPrimitive"), true),
            ("models", 14, K::Message(".foxglove.ModelPrimitive"), true),
        ],
        None,
    ),
    (
        "KeyValuePair",
        &[("key", 1, K::Str, false), ("value", 2, K::Str, false)],
        None,
    ),
    (
        "ArrowPrimitive",
        &[
            ("pose", 1, POSE, false),
            ("shaft_length", 2, K::Double, false),
            ("shaft_diameter", 3, K::Double, false),
            ("head_length", 4, K::Double, false),
            ("head_diameter", 5, K::Double, false),
            ("color", 6, COLOR, false),
        ],
        None,
    ),
    (
        "CubePrimitive",
        &[
            ("pose", 1, POSE, false),
            ("size", 2, VECTOR3, false),
            ("color", 3, COLOR, false),
        ],
        None,
    ),
    (
        "SpherePrimitive",
        &[
            ("pose", 1, POSE, false),
            ("size", 2, VECTOR3, false),
            ("color", 3, COLOR, false),
        ],
        None,
    ),
    (
        "CylinderPrimitive",
        &[
            ("pose", 1, POSE, false),
            ("size", 2, VECTOR3, false),
            ("bottom_scale", 3, K::Double, false),
            ("top_scale", 4, K::Double, false),
            ("color", 5, COLOR, false),
        ],
        None,
    ),
    (
        "LinePrimitive",
        &[
            ("type", 1, K::Enum(".foxglove.LinePrimitive.Type"), false),
            ("pose", 2, POSE, false),
            ("thickness", 3, K::Double, false),
            ("scale_invariant", 4, K::Bool, false),
            ("points", 5, POINT3, true),
            ("color", 6, COLOR, false),
            ("colors", 7, COLOR, true),
            ("indices", 8, K::Fixed32, true),
        ],
        Some((
            "Type",
            &[("LINE_STRIP", 0), ("LINE_LOOP", 1), ("LINE_LIST", 2)],
        )),
    ),
    (
        "TriangleListPrimitive",
        &[
            ("pose", 1, POSE, false),
            ("points", 2, POINT3, true),
            ("color", 3, COLOR, false),
            ("colors", 4, COLOR, true),
            ("indices", 5, K::Fixed32, true),
        ],
        None,
    ),
    (
        "TextPrimitive",
        &[
            ("pose", 1, POSE, false),
            ("billboard", 2, K::Bool, false),
            ("font_size", 3, K::Double, false),
            ("scale_invariant", 4, K::Bool, false),
            ("color", 5, COLOR, false),
            ("text", 6, K::Str, false),
        ],
        None,
    ),
    (
        "ModelPrimitive",
        &[
            ("pose", 1, POSE, false),
            ("scale", 2, VECTOR3, false),
            ("color", 3, COLOR, false),
            ("override_color", 4, K::Bool, false),
            ("url", 5, K::Str, false),
            ("media_type", 6, K::Str, false),
            ("data", 7, K::Bytes, false),
        ],
        None,
    ),
    (
        "Pose",
        &[
            ("position", 1, VECTOR3, false),
            ("orientation", 2, K::Message(".foxglove.Quaternion"), false),
        ],
        None,
    ),
    ("Vector3", XYZ, None),
    ("Point3", XYZ, None),
    (
        "Quaternion",
        &[
            ("x", 1, K::Double, false),
            ("y", 2, K::Double, false),
            ("z", 3, K::Double, false),
            ("w", 4, K::Double, false),
        ],
        None,
    ),
    (
        "Color",
        &[
            ("r", 1, K::Double, false),
            ("g", 2, K::Double, false),
            ("b", 3, K::Double, false),
            ("a", 4, K::Double, false),
        ],
        None,
    ),
    (
        "PointCloud",
        &[
            ("timestamp", 1, TIMESTAMP, false),
            ("frame_id", 2, K::Str, false),
            ("pose", 3, POSE, false),
            ("point_stride", 4, K::Fixed32, false),
            (
                "fields",
                5,
                K::Message(".foxglove.PackedElementField"),
                true,
            ),
            ("data", 6, K::Bytes, false),
        ],
        None,
    ),
    (
        "PackedElementField",
        &[
            ("name", 1, K::Str, false),
            ("offset", 2, K::Fixed32, false),
            (
                "type",
                3,
                K::Enum(".foxglove.PackedElementField.NumericType"),
                false,
            ),
        ],
        Some((
            "NumericType",
            &[
                ("UNKNOWN", 0),
                ("UINT8", 1),
                ("INT8", 2),
                ("UINT16", 3),
                ("INT16", 4),
                ("UINT32", 5),
                ("INT32", 6),
                ("FLOAT32", 7),
                ("FLOAT64", 8),
            ],
        )),
    ),
];

/// The schema name of the scene channels.
pub const SCHEMA: &str = "foxglove.SceneUpdate";

/// The schema name of `/scene/nodes` (its schema data the same set as [`SCHEMA`]'s).
pub const POINT_CLOUD: &str = "foxglove.PointCloud";

impl SceneUpdate {
    /// The message as JSON with the protobuf field names (absent sub-messages `null`), for
    /// tools and tests.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a scene update serialises")
    }
}

/// The protobuf wire form written straight from the messages: the bytes
/// `prost::Message::encode` writes (fields in number order, proto3 scalars at their default
/// left out, a set optional message present even when empty), checked by the tests below,
/// in one pass: prost works out the length of every nested message before writing it, for
/// each level it sits in (a rod's line points twice, the arrows' poses three times). `/scene`
/// and `/scene/nodes` are encoded this way every step.
pub trait Wire {
    /// Append the message's fields (without a length: a top-level message).
    fn wire(&self, buf: &mut Vec<u8>);
}

use super::proto::wire as w;

/// A set optional message as the field `tag`.
#[inline]
fn opt<M: Wire>(buf: &mut Vec<u8>, tag: u32, m: &Option<M>) {
    if let Some(m) = m {
        w::message(buf, tag, |b| m.wire(b));
    }
}

/// A repeated message as the field `tag`.
#[inline]
fn each<M: Wire>(buf: &mut Vec<u8>, tag: u32, ms: &[M]) {
    for m in ms {
        w::message(buf, tag, |b| m.wire(b));
    }
}

impl Wire for SceneUpdate {
    fn wire(&self, buf: &mut Vec<u8>) {
        each(buf, 1, &self.deletions);
        each(buf, 2, &self.entities);
    }
}

impl Wire for SceneEntityDeletion {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.timestamp);
        w::int(buf, 2, self.r#type as i64);
        w::bytes(buf, 3, self.id.as_bytes());
    }
}

impl Wire for SceneEntity {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.timestamp);
        w::bytes(buf, 2, self.frame_id.as_bytes());
        w::bytes(buf, 3, self.id.as_bytes());
        opt(buf, 4, &self.lifetime);
        w::boolean(buf, 5, self.frame_locked);
        each(buf, 7, &self.arrows);
        each(buf, 8, &self.cubes);
        each(buf, 9, &self.spheres);
        each(buf, 11, &self.lines);
        each(buf, 12, &self.triangles);
        each(buf, 13, &self.texts);
    }
}

/// Cubes and spheres: the same fields (pose, size, colour).
macro_rules! pose_size_color {
    ($($t:ty),*) => {$(
        impl Wire for $t {
            fn wire(&self, buf: &mut Vec<u8>) {
                opt(buf, 1, &self.pose);
                opt(buf, 2, &self.size);
                opt(buf, 3, &self.color);
            }
        }
    )*};
}
pose_size_color!(CubePrimitive, SpherePrimitive);

impl Wire for TriangleListPrimitive {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.pose);
        each(buf, 2, &self.points);
        opt(buf, 3, &self.color);
        each(buf, 4, &self.colors);
        w::packed_fixed32(buf, 5, &self.indices);
    }
}

impl Wire for ArrowPrimitive {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.pose);
        w::double(buf, 2, self.shaft_length);
        w::double(buf, 3, self.shaft_diameter);
        w::double(buf, 4, self.head_length);
        w::double(buf, 5, self.head_diameter);
        opt(buf, 6, &self.color);
    }
}

impl Wire for LinePrimitive {
    fn wire(&self, buf: &mut Vec<u8>) {
        w::int(buf, 1, self.r#type as i64);
        opt(buf, 2, &self.pose);
        w::double(buf, 3, self.thickness);
        w::boolean(buf, 4, self.scale_invariant);
        each(buf, 5, &self.points);
        opt(buf, 6, &self.color);
        each(buf, 7, &self.colors);
        w::packed_fixed32(buf, 8, &self.indices);
    }
}

impl Wire for TextPrimitive {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.pose);
        w::boolean(buf, 2, self.billboard);
        w::double(buf, 3, self.font_size);
        w::boolean(buf, 4, self.scale_invariant);
        opt(buf, 5, &self.color);
        w::bytes(buf, 6, self.text.as_bytes());
    }
}

impl Wire for PointCloud {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.timestamp);
        w::bytes(buf, 2, self.frame_id.as_bytes());
        opt(buf, 3, &self.pose);
        w::fixed32(buf, 4, self.point_stride);
        each(buf, 5, &self.fields);
        w::bytes(buf, 6, &self.data);
    }
}

impl Wire for PackedElementField {
    fn wire(&self, buf: &mut Vec<u8>) {
        w::bytes(buf, 1, self.name.as_bytes());
        w::fixed32(buf, 2, self.offset);
        w::int(buf, 3, self.r#type as i64);
    }
}

/// `google.protobuf.Timestamp` and `Duration`: the same fields (seconds, nanos).
macro_rules! seconds_nanos {
    ($($t:ty),*) => {$(
        impl Wire for $t {
            fn wire(&self, buf: &mut Vec<u8>) {
                w::int(buf, 1, self.seconds);
                w::int(buf, 2, self.nanos as i64);
            }
        }
    )*};
}
seconds_nanos!(Timestamp, Duration);

impl Wire for Pose {
    fn wire(&self, buf: &mut Vec<u8>) {
        opt(buf, 1, &self.position);
        opt(buf, 2, &self.orientation);
    }
}

impl Wire for Vector3 {
    fn wire(&self, buf: &mut Vec<u8>) {
        w::double(buf, 1, self.x);
        w::double(buf, 2, self.y);
        w::double(buf, 3, self.z);
    }
}

impl Wire for Quaternion {
    fn wire(&self, buf: &mut Vec<u8>) {
        w::double(buf, 1, self.x);
        w::double(buf, 2, self.y);
        w::double(buf, 3, self.z);
        w::double(buf, 4, self.w);
    }
}

impl Wire for Color {
    fn wire(&self, buf: &mut Vec<u8>) {
        w::double(buf, 1, self.r);
        w::double(buf, 2, self.g);
        w::double(buf, 3, self.b);
        w::double(buf, 4, self.a);
    }
}

fn field_proto(&(name, number, kind, repeated): &Field) -> FieldDescriptorProto {
    let (ty, type_name) = match kind {
        K::Double => (Type::Double, None),
        K::Bool => (Type::Bool, None),
        K::Int32 => (Type::Int32, None),
        K::Int64 => (Type::Int64, None),
        K::Fixed32 => (Type::Fixed32, None),
        K::Str => (Type::String, None),
        K::Bytes => (Type::Bytes, None),
        K::Message(m) => (Type::Message, Some(m.to_string())),
        K::Enum(e) => (Type::Enum, Some(e.to_string())),
    };
    super::proto::describe_field(name, number, ty, type_name, repeated)
}

fn message_proto(name: &str, fields: &[Field], nested: Option<EnumDef>) -> DescriptorProto {
    DescriptorProto {
        name: Some(name.to_string()),
        field: fields.iter().map(field_proto).collect(),
        enum_type: nested
            .map(|(name, values)| EnumDescriptorProto {
                name: Some(name.to_string()),
                value: values
                    .iter()
                    .map(|&(v, n)| EnumValueDescriptorProto {
                        name: Some(v.to_string()),
                        number: Some(n),
                        ..Default::default()
                    })
                    .collect(),
                ..Default::default()
            })
            .into_iter()
            .collect(),
        ..Default::default()
    }
}

/// A `google/protobuf/<file>.proto` with one message of `seconds` and `nanos`.
fn well_known(file: &str, message: &str) -> FileDescriptorProto {
    FileDescriptorProto {
        name: Some(format!("google/protobuf/{file}.proto")),
        package: Some("google.protobuf".into()),
        message_type: vec![message_proto(message, SECONDS_NANOS, None)],
        syntax: Some("proto3".into()),
        ..Default::default()
    }
}

/// The schema of the scene channels, serialised: a `FileDescriptorSet` of
/// `google/protobuf/timestamp.proto`, `google/protobuf/duration.proto` and
/// `foxglove/SceneUpdate.proto` (package `foxglove`, every message of [`MESSAGES`]).
pub fn file_descriptor_set() -> Vec<u8> {
    let scene = FileDescriptorProto {
        name: Some("foxglove/SceneUpdate.proto".into()),
        package: Some("foxglove".into()),
        dependency: vec![
            "google/protobuf/duration.proto".into(),
            "google/protobuf/timestamp.proto".into(),
        ],
        message_type: MESSAGES
            .iter()
            .map(|&(name, fields, nested)| message_proto(name, fields, nested))
            .collect(),
        syntax: Some("proto3".into()),
        ..Default::default()
    };
    FileDescriptorSet {
        file: vec![
            well_known("timestamp", "Timestamp"),
            well_known("duration", "Duration"),
            scene,
        ],
    }
    .encode_to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::encoding::WireType;

    use crate::record::proto::tests::wire_fields;

    fn expected_wire(kind: Kind, repeated: bool) -> WireType {
        match (kind, repeated) {
            (_, true) | (K::Str | K::Bytes | K::Message(_), false) => WireType::LengthDelimited,
            (K::Double, false) => WireType::SixtyFourBit,
            (K::Fixed32, false) => WireType::ThirtyTwoBit,
            _ => WireType::Varint,
        }
    }

    /// The fields `bytes` holds agree with the table of `name` (numbers and wire types), for
    /// the table fields whose numbers are in `written`.
    fn check(name: &str, bytes: &[u8], written: &[i32]) {
        let fields = MESSAGES
            .iter()
            .find(|(n, _, _)| *n == name)
            .map(|m| m.1)
            .unwrap_or(SECONDS_NANOS);
        let got = wire_fields(bytes);
        let want: Vec<(u32, WireType)> = fields
            .iter()
            .filter(|f| written.contains(&f.1))
            .map(|&(_, n, k, r)| (n as u32, expected_wire(k, r)))
            .collect();
        assert_eq!(
            got, want,
            "{name}: the derive and the descriptor table differ"
        );
    }

    #[test]
    fn derives_and_descriptor_tables_agree_on_the_wire() {
        let v = Vector3 {
            x: 1.0,
            y: 1.0,
            z: 1.0,
        };
        let q = Quaternion {
            x: 1.0,
            y: 1.0,
            z: 1.0,
            w: 1.0,
        };
        let c = Color {
            r: 1.0,
            g: 1.0,
            b: 1.0,
            a: 1.0,
        };
        let pose = Pose {
            position: Some(v),
            orientation: Some(q),
        };
        let ts = Timestamp {
            seconds: 1,
            nanos: 1,
        };
        let arrow = ArrowPrimitive {
            pose: Some(pose),
            shaft_length: 1.0,
            shaft_diameter: 1.0,
            head_length: 1.0,
            head_diameter: 1.0,
            color: Some(c),
        };
        let sphere = SpherePrimitive {
            pose: Some(pose),
            size: Some(v),
            color: Some(c),
        };
        let line = LinePrimitive {
            r#type: 2,
            pose: Some(pose),
            thickness: 1.0,
            scale_invariant: true,
            points: vec![v],
            color: Some(c),
            colors: vec![c],
            indices: vec![1],
        };
        let text = TextPrimitive {
            pose: Some(pose),
            billboard: true,
            font_size: 1.0,
            scale_invariant: true,
            color: Some(c),
            text: "a".into(),
        };
        let entity = SceneEntity {
            timestamp: Some(ts),
            frame_id: "world".into(),
            id: "a".into(),
            lifetime: Some(Duration {
                seconds: 1,
                nanos: 1,
            }),
            frame_locked: true,
            arrows: vec![arrow.clone()],
            spheres: vec![sphere.clone()],
            lines: vec![line.clone()],
            texts: vec![text.clone()],
            ..Default::default()
        };
        let deletion = SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: 1,
            id: "a".into(),
        };
        let update = SceneUpdate {
            deletions: vec![deletion.clone()],
            entities: vec![entity.clone()],
        };
        check("SceneUpdate", &update.encode_to_vec(), &[1, 2]);
        check("SceneEntityDeletion", &deletion.encode_to_vec(), &[1, 2, 3]);
        check(
            "SceneEntity",
            &entity.encode_to_vec(),
            &[1, 2, 3, 4, 5, 7, 9, 11, 13],
        );
        check(
            "ArrowPrimitive",
            &arrow.encode_to_vec(),
            &[1, 2, 3, 4, 5, 6],
        );
        check("SpherePrimitive", &sphere.encode_to_vec(), &[1, 2, 3]);
        check(
            "LinePrimitive",
            &line.encode_to_vec(),
            &[1, 2, 3, 4, 5, 6, 7, 8],
        );
        check("TextPrimitive", &text.encode_to_vec(), &[1, 2, 3, 4, 5, 6]);
        check("Pose", &pose.encode_to_vec(), &[1, 2]);
        check("Vector3", &v.encode_to_vec(), &[1, 2, 3]);
        check("Quaternion", &q.encode_to_vec(), &[1, 2, 3, 4]);
        check("Color", &c.encode_to_vec(), &[1, 2, 3, 4]);
        check("Timestamp", &ts.encode_to_vec(), &[1, 2]);
        assert_eq!(
            SceneUpdate::decode(update.encode_to_vec().as_slice()).unwrap(),
            update
        );
        let cloud = PointCloud {
            timestamp: Some(ts),
            frame_id: "world".into(),
            pose: Some(pose),
            point_stride: NODE_POINT_STRIDE,
            fields: node_point_fields(),
            data: [1.5f32, -2.0, 0.25]
                .iter()
                .flat_map(|x| x.to_le_bytes())
                .chain([10, 20, 30, 255])
                .collect(),
        };
        let one_field = PointCloud {
            fields: cloud.fields[..1].to_vec(),
            ..cloud.clone()
        };
        check(
            "PointCloud",
            &one_field.encode_to_vec(),
            &[1, 2, 3, 4, 5, 6],
        );
        check(
            "PackedElementField",
            &cloud.fields[1].encode_to_vec(),
            &[1, 2, 3],
        );
        assert_eq!(
            cloud.points().unwrap(),
            [[1.5, -2.0, 0.25, 10.0, 20.0, 30.0, 255.0]]
        );
    }

    /// The direct encoder ([`Wire`]) writes the bytes prost writes: every field set (negative
    /// enums in ten bytes, ±0 and empty strings left out, empty optional messages kept),
    /// and lengths of one, two and three bytes at every level.
    #[test]
    fn the_direct_encoder_writes_the_bytes_prost_writes() {
        let v = |k: usize| Vector3 {
            x: 0.1 * k as f64 - 0.3,
            y: if k.is_multiple_of(3) {
                -0.0
            } else {
                1e-3 * k as f64
            },
            z: if k.is_multiple_of(2) { 0.0 } else { f64::NAN },
        };
        let c = |k: usize| Color {
            r: 0.5,
            g: k as f64 / 10.0,
            b: 0.0,
            a: 1.0,
        };
        let pose = |k: usize| Pose {
            position: (k % 4 != 1).then(|| v(k)),
            orientation: (k % 4 != 2).then(|| Quaternion {
                x: 0.0,
                y: 0.0,
                z: (k as f64).sin(),
                w: (k as f64).cos(),
            }),
        };
        let ts = |k: usize| Timestamp {
            seconds: k as i64 - 2,
            nanos: (k as i32 * 123_456_789) % 1_000_000_000,
        };
        let text = |n: usize| "N".repeat(n);
        let entity = |k: usize, points: usize| SceneEntity {
            timestamp: (k != 1).then(|| ts(k)),
            frame_id: if k == 2 {
                String::new()
            } else {
                "world".into()
            },
            id: text(k * 70),
            lifetime: Some(Duration {
                seconds: 0,
                nanos: if k == 0 { 0 } else { 5 },
            }),
            frame_locked: k % 2 == 1,
            arrows: (0..k)
                .map(|i| ArrowPrimitive {
                    pose: Some(pose(i)),
                    shaft_length: i as f64,
                    shaft_diameter: 0.01,
                    head_length: -0.0,
                    head_diameter: 0.02,
                    color: Some(c(i)),
                })
                .collect(),
            cubes: vec![
                CubePrimitive {
                    pose: Some(pose(k)),
                    size: Some(Vector3::default()),
                    color: None,
                };
                k % 3
            ],
            spheres: (0..2 * k)
                .map(|i| SpherePrimitive {
                    pose: Some(pose(i)),
                    size: Some(v(i)),
                    color: Some(c(i)),
                })
                .collect(),
            lines: vec![LinePrimitive {
                r#type: if k == 3 { -1 } else { k as i32 },
                pose: Some(pose(k)),
                thickness: 2.0,
                scale_invariant: k != 2,
                points: (0..points).map(v).collect(),
                color: Some(c(k)),
                colors: (0..points % 7).map(c).collect(),
                indices: (0..points as u32 % 5).collect(),
            }],
            triangles: vec![TriangleListPrimitive {
                pose: None,
                points: (0..3 * k).map(v).collect(),
                color: Some(Color::default()),
                colors: vec![c(k)],
                indices: vec![0, 1, u32::MAX],
            }],
            texts: (0..k)
                .map(|i| TextPrimitive {
                    pose: Some(pose(i)),
                    billboard: i % 2 == 0,
                    font_size: 12.0,
                    scale_invariant: true,
                    color: Some(c(i)),
                    text: format!("{} N", 0.5 * i as f64),
                })
                .collect(),
        };
        let updates = [
            SceneUpdate::default(),
            SceneUpdate {
                deletions: vec![SceneEntityDeletion {
                    timestamp: Some(ts(3)),
                    r#type: -7,
                    id: text(200),
                }],
                entities: vec![SceneEntity::default()],
            },
            SceneUpdate {
                deletions: Vec::new(),
                entities: vec![entity(0, 0), entity(1, 5), entity(2, 6)],
            },
            SceneUpdate {
                deletions: Vec::new(),
                entities: vec![entity(3, 1_000), entity(4, 7)],
            },
        ];
        for (k, u) in updates.iter().enumerate() {
            let mut direct = Vec::new();
            u.wire(&mut direct);
            assert_eq!(direct, u.encode_to_vec(), "update {k}");
        }
        for points in [0, 1, 8, 100, 5_000] {
            let cloud = PointCloud {
                timestamp: Some(ts(points)),
                frame_id: "world".into(),
                pose: Some(pose(points)),
                point_stride: NODE_POINT_STRIDE,
                fields: node_point_fields(),
                data: (0..points * 16).map(|i| (i * 7) as u8).collect(),
            };
            let mut direct = Vec::new();
            cloud.wire(&mut direct);
            assert_eq!(direct, cloud.encode_to_vec(), "{points} points");
        }
        let mut direct = Vec::new();
        PointCloud::default().wire(&mut direct);
        assert!(direct.is_empty());
    }

    #[test]
    fn the_descriptor_set_resolves_every_type_it_names() {
        let set = FileDescriptorSet::decode(file_descriptor_set().as_slice()).unwrap();
        let names: Vec<&str> = set.file.iter().map(|f| f.name()).collect();
        assert_eq!(
            names,
            [
                "google/protobuf/timestamp.proto",
                "google/protobuf/duration.proto",
                "foxglove/SceneUpdate.proto"
            ]
        );
        // Every full name a field refers to is a message (or a nested enum) of the set.
        let mut known = Vec::new();
        for f in &set.file {
            for m in &f.message_type {
                let full = format!(".{}.{}", f.package(), m.name());
                for e in &m.enum_type {
                    known.push(format!("{full}.{}", e.name()));
                }
                known.push(full);
            }
        }
        let mut refs = 0;
        for f in &set.file {
            for m in &f.message_type {
                for fd in &m.field {
                    if let Some(t) = &fd.type_name {
                        assert!(known.contains(t), "{}.{}: {t} unknown", m.name(), fd.name());
                        refs += 1;
                    }
                }
            }
        }
        assert_eq!(refs, 46);
        let scene = &set.file[2];
        assert_eq!(scene.package(), "foxglove");
        assert_eq!(scene.message_type[0].name(), "SceneUpdate");
    }
}
