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
//!
//! Format 4: each message with per-node numbers comes twice, `Step`/`Rod`/`ContactState`/
//! `Iteration` with protobuf `float` (the default precision) and their `…64` twins with
//! `double` (`output.precision = "f64"`), the same field names and numbers; every step carries
//! the [`Fingerprint`] of its exact f64 state.

use crate::events::{BodyView, ContactView, Phase, RodStepView};
use prost::Message as _;
use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet};

/// Defines a `/sim/step` message family (`Step`, `Rod`, `Iteration`) with its per-node arrays
/// of one float type: protobuf `float` (f32, the default precision) or `double` (f64,
/// `output.precision = "f64"`). The per-step scalars (`t`, `dt`, a residual) are `double` in
/// both; the field names and numbers are the same, so a Foxglove plot path
/// (`/sim/step.rods[0].q[4]`) reads either.
macro_rules! step_messages {
    ($step:ident, $rod:ident, $contact:ident, $iteration:ident, $pty:ident, $t:ty, $schema:literal) => {
        #[doc = concat!("`gripsim.", $schema, "`: the state at the end of a step.")]
        #[derive(Clone, PartialEq, prost::Message)]
        pub struct $step {
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
            pub rods: Vec<$rod>,
            #[prost(message, repeated, tag = "7")]
            pub bodies: Vec<Body>,
            #[prost(message, repeated, tag = "8")]
            pub contacts: Vec<$contact>,
            /// FNV-1a 64 of the exact f64 bits of every rod's q and u and every body's state
            /// ([`Fingerprint`]); 0 in files of format 3 and older (format 4).
            #[prost(fixed64, tag = "9")]
            pub fingerprint: u64,
        }

        /// One rod of a step (interleaved vectors `[x0, y0, x1, y1, …]`).
        #[derive(Clone, PartialEq, prost::Message)]
        pub struct $rod {
            #[prost($pty, repeated, tag = "1")]
            pub q: Vec<$t>,
            #[prost($pty, repeated, tag = "2")]
            pub u: Vec<$t>,
            #[prost($pty, repeated, tag = "3")]
            pub reaction: Vec<$t>,
            #[prost($pty, repeated, tag = "4")]
            pub reaction_norm: Vec<$t>,
            #[prost($pty, repeated, tag = "5")]
            pub impulse: Vec<$t>,
            #[prost($pty, repeated, tag = "6")]
            pub drive_force: Vec<$t>,
            #[prost($pty, repeated, tag = "7")]
            pub normal: Vec<$t>,
            #[prost(bool, repeated, tag = "8")]
            pub in_contact: Vec<bool>,
            /// −1: free.
            #[prost(sint64, repeated, tag = "9")]
            pub contact_obstacle: Vec<i64>,
            #[prost($pty, repeated, tag = "10")]
            pub normal2: Vec<$t>,
            /// −1: none.
            #[prost(sint64, repeated, tag = "11")]
            pub contact_obstacle2: Vec<i64>,
            #[prost($pty, repeated, tag = "12")]
            pub bending_stress: Vec<$t>,
            /// +∞: no obstacle.
            #[prost($pty, repeated, tag = "13")]
            pub gap: Vec<$t>,
            /// Empty on a step without a corrector pass (then it equals `q`; format 3).
            #[prost($pty, repeated, tag = "14")]
            pub q_predictor: Vec<$t>,
        }

        /// `gripsim.ContactState`: an active contact at the end of a step.
        #[derive(Clone, PartialEq, prost::Message)]
        pub struct $contact {
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
            #[prost($pty, repeated, tag = "5")]
            pub point: Vec<$t>,
            #[prost($pty, repeated, tag = "6")]
            pub normal: Vec<$t>,
            #[prost($pty, tag = "7")]
            pub normal_force: $t,
            #[prost($pty, tag = "8")]
            pub friction_force: $t,
            #[prost($pty, tag = "9")]
            pub slip_velocity: $t,
            #[prost(bool, tag = "10")]
            pub stuck: bool,
            #[prost($pty, tag = "11")]
            pub utilisation: $t,
            #[prost($pty, tag = "12")]
            pub mu_s: $t,
            /// A compliant fruit's contact (0 at a rigid obstacle): indentation (m), contact
            /// half-width (m), peak pressure (Pa), the fruit's bruise threshold (Pa) and the
            /// half-width above it (m).
            #[prost($pty, tag = "13")]
            pub indentation: $t,
            #[prost($pty, tag = "14")]
            pub half_width: $t,
            #[prost($pty, tag = "15")]
            pub peak_pressure: $t,
            #[prost($pty, tag = "16")]
            pub bruise_pressure: $t,
            #[prost($pty, tag = "17")]
            pub bruise_half_width: $t,
            /// A contact arc's first and last node (edge mode, a compliant fruit); −1 for
            /// any other contact.
            #[prost(sint64, tag = "18")]
            pub first: i64,
            #[prost(sint64, tag = "19")]
            pub last: i64,
        }

        impl $contact {
            /// Refill from a contact view, reusing the buffers.
            pub fn fill(&mut self, c: &ContactView) {
                self.rod = index(c.rod);
                self.node = c.node as u64;
                self.obstacle = c.obstacle as u64;
                self.body = index(c.body);
                // The run's components only (`dim`: 2 writes x, y as before).
                let d = if c.dim == 3 { 3 } else { 2 };
                self.point.clear();
                self.point.extend(c.point[..d].iter().map(|&x| x as $t));
                self.normal.clear();
                self.normal.extend(c.normal[..d].iter().map(|&x| x as $t));
                self.normal_force = c.normal_force as $t;
                self.friction_force = c.friction_force as $t;
                self.slip_velocity = c.slip_velocity as $t;
                self.stuck = c.stuck;
                self.utilisation = c.utilisation as $t;
                self.mu_s = c.mu_s as $t;
                self.indentation = c.indentation as $t;
                self.half_width = c.half_width as $t;
                self.peak_pressure = c.peak_pressure as $t;
                self.bruise_pressure = c.bruise_pressure as $t;
                self.bruise_half_width = c.bruise_half_width as $t;
                self.first = index(c.first);
                self.last = index(c.last);
            }

            /// The JSON form of format 1 (f64 values).
            pub fn to_json(&self) -> serde_json::Value {
                let w = |x: $t| x as f64;
                serde_json::json!({
                    "rod": opt_index(self.rod), "node": self.node, "obstacle": self.obstacle,
                    "body": opt_index(self.body),
                    "point": self.point.iter().map(|&x| w(x)).collect::<Vec<f64>>(),
                    "normal": self.normal.iter().map(|&x| w(x)).collect::<Vec<f64>>(),
                    "normal_force": w(self.normal_force),
                    "friction_force": w(self.friction_force),
                    "slip_velocity": w(self.slip_velocity), "stuck": self.stuck,
                    "utilisation": w(self.utilisation), "mu_s": w(self.mu_s),
                    "indentation": w(self.indentation), "half_width": w(self.half_width),
                    "peak_pressure": w(self.peak_pressure),
                    "bruise_pressure": w(self.bruise_pressure),
                    "bruise_half_width": w(self.bruise_half_width),
                    "first": opt_index(self.first), "last": opt_index(self.last),
                })
            }
        }

        /// One Newton iteration of one rod.
        #[derive(Clone, PartialEq, prost::Message)]
        pub struct $iteration {
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
            #[prost($pty, repeated, tag = "9")]
            pub q: Vec<$t>,
        }

        impl $rod {
            /// Refill from a step view, reusing the buffers (f64 values rounded to the
            /// message's float type).
            pub fn fill(&mut self, v: &RodStepView<'_>) {
                fn set(dst: &mut Vec<$t>, src: &[f64]) {
                    dst.clear();
                    dst.extend(src.iter().map(|&x| x as $t));
                }
                set(&mut self.q, v.q);
                set(&mut self.u, v.u);
                set(&mut self.reaction, v.reaction);
                self.reaction_norm.clear();
                self.reaction_norm.extend(
                    (0..v.reaction.len() / 2).map(|i| super::node_norm(v.reaction, i) as $t),
                );
                set(&mut self.impulse, v.impulse);
                set(&mut self.drive_force, v.drive_force);
                set(&mut self.normal, v.normal);
                self.in_contact.clear();
                self.in_contact.extend_from_slice(v.in_contact);
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

        impl $step {
            /// Refill from a step's fields, reusing every buffer.
            pub fn fill(&mut self, s: &StepFields<'_, '_>) {
                self.step = s.step;
                self.t = s.t;
                self.dt = s.dt;
                self.newton_iterations = s.newton_iterations;
                self.passes = s.passes;
                self.rods.resize_with(s.rods.len(), $rod::default);
                for (dst, v) in self.rods.iter_mut().zip(s.rods) {
                    dst.fill(v);
                }
                self.bodies.resize_with(s.bodies.len(), Body::default);
                for (dst, b) in self.bodies.iter_mut().zip(s.bodies) {
                    dst.fill(b);
                }
                self.contacts.resize_with(s.contacts.len(), $contact::default);
                for (dst, c) in self.contacts.iter_mut().zip(s.contacts) {
                    dst.fill(c);
                }
                self.fingerprint = s.fingerprint.unwrap_or_else(|| fingerprint(s.rods, s.bodies));
            }

            /// Append the message [`Self::fill`] and `encode` would give, written straight
            /// from the views: the per-node arrays go from f64 to the wire in one pass, with
            /// no copy in between (the bodies and contacts, few, still pass through their
            /// messages, whose buffers `self` keeps).
            pub fn encode_direct(&mut self, s: &StepFields<'_, '_>, buf: &mut Vec<u8>) {
                use wire::*;
                uint(buf, 1, s.step);
                double(buf, 2, s.t);
                double(buf, 3, s.dt);
                uint(buf, 4, s.newton_iterations as u64);
                uint(buf, 5, s.passes as u64);
                for v in s.rods {
                    rod::<$t>(buf, 6, v);
                }
                self.bodies.resize_with(s.bodies.len(), Body::default);
                for (dst, b) in self.bodies.iter_mut().zip(s.bodies) {
                    dst.fill(b);
                    prost::encoding::message::encode(7, dst, buf);
                }
                self.contacts.resize_with(s.contacts.len(), $contact::default);
                for (dst, c) in self.contacts.iter_mut().zip(s.contacts) {
                    dst.fill(c);
                    prost::encoding::message::encode(8, dst, buf);
                }
                let print = s.fingerprint.unwrap_or_else(|| fingerprint(s.rods, s.bodies));
                fixed64(buf, 9, print);
            }

            /// The same message in the JSON form of format 1 (`null` for absent indices and
            /// gaps; each number the f64 value of the recorded one), for tools and tests that
            /// read both encodings alike.
            pub fn to_json(&self) -> serde_json::Value {
                use serde_json::json;
                fn w(v: &[$t]) -> Vec<f64> {
                    v.iter().map(|&x| x as f64).collect()
                }
                let rods: Vec<serde_json::Value> = self
                    .rods
                    .iter()
                    .map(|r| {
                        json!({
                            "q": w(&r.q), "u": w(&r.u), "reaction": w(&r.reaction),
                            "reaction_norm": w(&r.reaction_norm),
                            "impulse": w(&r.impulse), "drive_force": w(&r.drive_force),
                            "normal": w(&r.normal),
                            "in_contact": r.in_contact,
                            "contact_obstacle": r.contact_obstacle.iter().map(|&k| opt_index(k)).collect::<Vec<_>>(),
                            "normal2": w(&r.normal2),
                            "contact_obstacle2": r.contact_obstacle2.iter().map(|&k| opt_index(k)).collect::<Vec<_>>(),
                            "bending_stress": w(&r.bending_stress),
                            "gap": r.gap.iter().map(|&g| finite_or_null(g as f64)).collect::<Vec<_>>(),
                            "q_predictor": w(&r.q_predictor),
                        })
                    })
                    .collect();
                let mut v = json!({
                    "step": self.step, "t": self.t, "dt": self.dt,
                    "newton_iterations": self.newton_iterations, "passes": self.passes,
                    "rods": rods, "fingerprint": self.fingerprint,
                });
                bodies_json(&mut v, &self.bodies);
                if !self.contacts.is_empty() {
                    v["contacts"] = self.contacts.iter().map(|c| c.to_json()).collect();
                }
                v
            }
        }

        impl $iteration {
            /// Refill, reusing the buffers.
            #[allow(clippy::too_many_arguments)]
            pub fn fill(
                &mut self,
                step: u64,
                t: f64,
                phase: Phase,
                pass: u32,
                iteration: u32,
                rod: usize,
                residual: f64,
                update: f64,
                q: &[f64],
            ) {
                self.step = step;
                self.t = t;
                self.phase.clear();
                self.phase.push_str(phase.as_str());
                self.pass = pass;
                self.iteration = iteration;
                self.rod = rod as u64;
                self.residual = residual;
                self.update = update;
                self.q.clear();
                self.q.extend(q.iter().map(|&x| x as $t));
            }

            /// The JSON form of format 1.
            pub fn to_json(&self) -> serde_json::Value {
                serde_json::json!({
                    "step": self.step, "t": self.t, "phase": self.phase, "pass": self.pass,
                    "iteration": self.iteration, "rod": self.rod, "residual": self.residual,
                    "update": self.update,
                    "q": self.q.iter().map(|&x| x as f64).collect::<Vec<f64>>(),
                })
            }
        }
    };
}

step_messages!(Step, Rod, Contact, Iteration, float, f32, "Step");
step_messages!(Step64, Rod64, Contact64, Iteration64, double, f64, "Step64");

/// `gripsim.Body`: a free body (fruit) at the end of a step (`double` in both precisions).
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

/// The 64-bit fingerprint of a step's exact state: FNV-1a (64-bit: offset basis
/// 0xcbf29ce484222325, prime 0x100000001b3) over the little-endian bytes of the f64 bits of,
/// in order, every rod's `q` then its `u` (rods in `/sim/meta` order), then every free body's
/// position x, y, angle, velocity x, y and angular velocity. Two runs whose fingerprints
/// differ at a step differ there bit for bit, however close their f32 values are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fingerprint(pub u64);

impl Default for Fingerprint {
    fn default() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }
}

impl Fingerprint {
    /// Add one number's exact bits.
    #[inline]
    pub fn add(&mut self, x: f64) {
        for b in x.to_bits().to_le_bytes() {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Add every number of `xs`.
    pub fn add_all(&mut self, xs: &[f64]) {
        for &x in xs {
            self.add(x);
        }
    }
}

/// The fingerprint of a step (see [`Fingerprint`]).
pub fn fingerprint(rods: &[RodStepView<'_>], bodies: &[BodyView<'_>]) -> u64 {
    let mut h = Fingerprint::default();
    for r in rods {
        h.add_all(r.q);
        h.add_all(r.u);
    }
    for b in bodies {
        h.add_all(&body_numbers(b));
    }
    h.0
}

/// A free body's numbers in a fingerprint, in order.
fn body_numbers(b: &BodyView<'_>) -> [f64; 6] {
    [
        b.position[0],
        b.position[1],
        b.angle,
        b.velocity[0],
        b.velocity[1],
        b.angular_velocity[2],
    ]
}

/// Steps fingerprinted side by side by [`fingerprints`].
pub const LANES: usize = 4;

/// The fingerprints of [`LANES`] steps of the same shape (rods of the same node counts, as
/// many bodies): the values [`fingerprint`] gives each, with the steps' multiply chains
/// interleaved. One step's chain is serial (eight dependent multiplies per number, most of
/// its time in the MCAP writer) and the core runs independent chains side by side. None
/// when the shapes differ.
pub fn fingerprints(steps: [(&[RodStepView<'_>], &[BodyView<'_>]); LANES]) -> Option<[u64; LANES]> {
    let (rods, bodies) = steps[0];
    let same = steps.iter().all(|(r, b)| {
        r.len() == rods.len()
            && b.len() == bodies.len()
            && r.iter()
                .zip(rods)
                .all(|(x, y)| x.q.len() == y.q.len() && x.u.len() == y.u.len())
    });
    if !same {
        return None;
    }
    let mut h = [Fingerprint::default(); LANES];
    let mut side_by_side = |xs: [&[f64]; LANES]| {
        for i in 0..xs[0].len() {
            for (h, x) in h.iter_mut().zip(&xs) {
                h.add(x[i]);
            }
        }
    };
    for k in 0..rods.len() {
        side_by_side(steps.map(|(r, _)| r[k].q));
        side_by_side(steps.map(|(r, _)| r[k].u));
    }
    for k in 0..bodies.len() {
        let numbers = steps.map(|(_, b)| body_numbers(&b[k]));
        side_by_side(numbers.each_ref().map(|n| n.as_slice()));
    }
    Some(h.map(|h| h.0))
}

/// How `/sim/step` and `/sim/iteration` store their per-node arrays (`[output] precision`,
/// `--precision`): `f32` (protobuf `float`, the default) or `f64` (`double`, exact).
pub use crate::scenario::Precision;

/// The type of a field in a descriptor table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Double,
    /// `float` in the f32 messages (`Step`, `Rod`, `Iteration`), `double` in their f64 twins.
    Float,
    Fixed64,
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
            ("fingerprint", 9, K::Fixed64, false),
        ],
    ),
    (
        "Rod",
        &[
            ("q", 1, K::Float, true),
            ("u", 2, K::Float, true),
            ("reaction", 3, K::Float, true),
            ("reaction_norm", 4, K::Float, true),
            ("impulse", 5, K::Float, true),
            ("drive_force", 6, K::Float, true),
            ("normal", 7, K::Float, true),
            ("in_contact", 8, K::Bool, true),
            ("contact_obstacle", 9, K::Sint64, true),
            ("normal2", 10, K::Float, true),
            ("contact_obstacle2", 11, K::Sint64, true),
            ("bending_stress", 12, K::Float, true),
            ("gap", 13, K::Float, true),
            ("q_predictor", 14, K::Float, true),
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
            ("point", 5, K::Float, true),
            ("normal", 6, K::Float, true),
            ("normal_force", 7, K::Float, false),
            ("friction_force", 8, K::Float, false),
            ("slip_velocity", 9, K::Float, false),
            ("stuck", 10, K::Bool, false),
            ("utilisation", 11, K::Float, false),
            ("mu_s", 12, K::Float, false),
            ("indentation", 13, K::Float, false),
            ("half_width", 14, K::Float, false),
            ("peak_pressure", 15, K::Float, false),
            ("bruise_pressure", 16, K::Float, false),
            ("bruise_half_width", 17, K::Float, false),
            ("first", 18, K::Sint64, false),
            ("last", 19, K::Sint64, false),
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
            ("q", 9, K::Float, true),
        ],
    ),
];

/// The protobuf package of the messages.
pub const PACKAGE: &str = "gripsim";

/// The descriptor of one field of a `gripsim` message (also the 3D ones, src/record/mcap3.rs).
pub(crate) fn field_proto(&(name, number, kind, repeated): &Field) -> FieldDescriptorProto {
    let (ty, type_name) = match kind {
        K::Double => (Type::Double, None),
        K::Float => (Type::Float, None),
        K::Fixed64 => (Type::Fixed64, None),
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

/// The name of a message's f64 twin (`Step` → `Step64`); the others are shared.
fn twin(name: &'static str) -> &'static str {
    match name {
        "Step" => "Step64",
        "Rod" => "Rod64",
        "Iteration" => "Iteration64",
        "ContactState" => "ContactState64",
        other => other,
    }
}

/// Every message of the package with its fields: [`MESSAGES`] and the f64 twins of `Step`,
/// `Rod` and `Iteration` (`Step64`, `Rod64`, `Iteration64`: the same fields, `double` where the
/// f32 ones are `float`).
pub fn all_messages() -> Vec<(&'static str, Vec<Field>)> {
    let mut out: Vec<(&'static str, Vec<Field>)> =
        MESSAGES.iter().map(|(n, f)| (*n, f.to_vec())).collect();
    for (name, fields) in MESSAGES {
        if twin(name) == name {
            continue;
        }
        let wide = fields
            .iter()
            .map(|&(f, n, k, r)| {
                let k = match k {
                    K::Float => K::Double,
                    K::Message(m) => K::Message(twin(m)),
                    k => k,
                };
                (f, n, k, r)
            })
            .collect();
        out.push((twin(name), wide));
    }
    out
}

/// The schema of every channel: a `FileDescriptorSet` holding `gripsim/recording.proto`
/// (proto3, package `gripsim`) with all the messages, serialised. The channel's schema name
/// says which message it carries (`gripsim.Step` or `gripsim.Step64`, `gripsim.Iteration` or
/// `gripsim.Iteration64`).
pub fn file_descriptor_set() -> Vec<u8> {
    let file = FileDescriptorProto {
        name: Some("gripsim/recording.proto".into()),
        package: Some(PACKAGE.into()),
        message_type: all_messages()
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

/// The protobuf wire format written by hand for `/sim/step`'s rods (the bytes prost writes
/// for the same message: proto3 scalars at their default left out, repeated scalars packed,
/// fields in number order), straight from the f64 views; its scalar writers serve the
/// Foxglove scene's encoder too (`super::foxglove`).
pub(crate) mod wire {
    use super::index;
    use crate::events::RodStepView;

    const VARINT: u64 = 0;
    const I64: u64 = 1;
    const LEN: u64 = 2;
    const I32: u64 = 5;

    /// A per-node number's wire form: protobuf `float` (f32) or `double` (f64).
    pub trait Float: Copy {
        const SIZE: usize;
        fn put(dst: &mut [u8], x: f64);
    }

    impl Float for f32 {
        const SIZE: usize = 4;
        #[inline]
        fn put(dst: &mut [u8], x: f64) {
            dst.copy_from_slice(&(x as f32).to_le_bytes());
        }
    }

    impl Float for f64 {
        const SIZE: usize = 8;
        #[inline]
        fn put(dst: &mut [u8], x: f64) {
            dst.copy_from_slice(&x.to_le_bytes());
        }
    }

    #[inline]
    pub fn varint(buf: &mut Vec<u8>, mut v: u64) {
        while v >= 0x80 {
            buf.push(v as u8 | 0x80);
            v >>= 7;
        }
        buf.push(v as u8);
    }

    #[inline]
    fn varint_len(v: u64) -> usize {
        (64 - (v | 1).leading_zeros() as usize).div_ceil(7)
    }

    #[inline]
    fn key(buf: &mut Vec<u8>, tag: u32, wire_type: u64) {
        varint(buf, (tag as u64) << 3 | wire_type);
    }

    /// A nested message as the field `tag`, written by `body` (present even when empty, as
    /// prost writes an optional message that is set). Its length is known only once it is
    /// written: one byte is kept for it and the body moved on when the length needs more
    /// (the varint is the shortest, as prost's).
    #[inline]
    pub fn message(buf: &mut Vec<u8>, tag: u32, body: impl FnOnce(&mut Vec<u8>)) {
        key(buf, tag, LEN);
        let at = buf.len();
        buf.push(0);
        body(buf);
        let len = buf.len() - at - 1;
        if len < 0x80 {
            buf[at] = len as u8;
            return;
        }
        let n = varint_len(len as u64);
        let end = buf.len();
        buf.resize(end + n - 1, 0);
        buf.copy_within(at + 1..end, at + n);
        let mut v = len as u64;
        for b in &mut buf[at..at + n] {
            *b = v as u8 | 0x80;
            v >>= 7;
        }
        buf[at + n - 1] &= 0x7f;
    }

    /// A `bool` scalar (left out when false).
    #[inline]
    pub fn boolean(buf: &mut Vec<u8>, tag: u32, v: bool) {
        if v {
            key(buf, tag, VARINT);
            buf.push(1);
        }
    }

    /// An `int32`/`int64` scalar (left out at 0; negative ones take ten bytes, as the
    /// protobuf encoding sign-extends them).
    #[inline]
    pub fn int(buf: &mut Vec<u8>, tag: u32, v: i64) {
        if v != 0 {
            key(buf, tag, VARINT);
            varint(buf, v as u64);
        }
    }

    /// A `fixed32` scalar (left out at 0).
    #[inline]
    pub fn fixed32(buf: &mut Vec<u8>, tag: u32, v: u32) {
        if v != 0 {
            key(buf, tag, I32);
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `string` or `bytes` field (left out when empty).
    #[inline]
    pub fn bytes(buf: &mut Vec<u8>, tag: u32, v: &[u8]) {
        if !v.is_empty() {
            key(buf, tag, LEN);
            varint(buf, v.len() as u64);
            buf.extend_from_slice(v);
        }
    }

    /// A packed repeated `fixed32` (left out when empty).
    pub fn packed_fixed32(buf: &mut Vec<u8>, tag: u32, vs: &[u32]) {
        if !vs.is_empty() {
            key(buf, tag, LEN);
            varint(buf, 4 * vs.len() as u64);
            for v in vs {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
    }

    /// A `uint64`/`uint32` scalar (left out at 0).
    pub fn uint(buf: &mut Vec<u8>, tag: u32, v: u64) {
        if v != 0 {
            key(buf, tag, VARINT);
            varint(buf, v);
        }
    }

    /// A `double` scalar (left out at ±0).
    #[inline]
    pub fn double(buf: &mut Vec<u8>, tag: u32, x: f64) {
        if x != 0.0 {
            key(buf, tag, I64);
            buf.extend_from_slice(&x.to_le_bytes());
        }
    }

    /// A `fixed64` scalar (left out at 0).
    pub fn fixed64(buf: &mut Vec<u8>, tag: u32, v: u64) {
        if v != 0 {
            key(buf, tag, I64);
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// The bytes of a packed field of `bytes` bytes of data (tag below 16: a one-byte key).
    fn packed_len(bytes: usize) -> usize {
        if bytes == 0 {
            0
        } else {
            1 + varint_len(bytes as u64) + bytes
        }
    }

    fn zigzag(k: usize) -> u64 {
        let v = index(k);
        ((v << 1) ^ (v >> 63)) as u64
    }

    fn indices_len(ks: &[usize]) -> usize {
        ks.iter().map(|&k| varint_len(zigzag(k))).sum()
    }

    /// A packed repeated float of `n` values, the i-th `x(i)`.
    #[inline]
    fn floats_with<T: Float>(buf: &mut Vec<u8>, tag: u32, n: usize, x: impl Fn(usize) -> f64) {
        if n == 0 {
            return;
        }
        key(buf, tag, LEN);
        varint(buf, (n * T::SIZE) as u64);
        let at = buf.len();
        buf.resize(at + n * T::SIZE, 0);
        for (i, dst) in buf[at..].chunks_exact_mut(T::SIZE).enumerate() {
            T::put(dst, x(i));
        }
    }

    #[inline]
    fn floats<T: Float>(buf: &mut Vec<u8>, tag: u32, xs: &[f64]) {
        floats_with::<T>(buf, tag, xs.len(), |i| xs[i]);
    }

    /// A packed repeated `sint64` of indices (−1 for `usize::MAX`).
    fn indices(buf: &mut Vec<u8>, tag: u32, ks: &[usize]) {
        if ks.is_empty() {
            return;
        }
        key(buf, tag, LEN);
        varint(buf, indices_len(ks) as u64);
        for &k in ks {
            varint(buf, zigzag(k));
        }
    }

    /// One `Rod` (`Rod64`) as the field `tag` of its step.
    pub fn rod<T: Float>(buf: &mut Vec<u8>, tag: u32, v: &RodStepView<'_>) {
        let nodes = v.reaction.len() / 2;
        // Only on steps with a corrector pass: elsewhere it equals q (format 3).
        let predictor = v.q_predictor != v.q;
        let f = |n: usize| packed_len(n * T::SIZE);
        let len = f(v.q.len())
            + f(v.u.len())
            + f(v.reaction.len())
            + f(nodes)
            + f(v.impulse.len())
            + f(v.drive_force.len())
            + f(v.normal.len())
            + packed_len(v.in_contact.len())
            + packed_len(indices_len(v.contact_obstacle))
            + f(v.normal2.len())
            + packed_len(indices_len(v.contact_obstacle2))
            + f(v.bending_stress.len())
            + f(v.gap.len())
            + if predictor { f(v.q_predictor.len()) } else { 0 };
        key(buf, tag, LEN);
        varint(buf, len as u64);
        let start = buf.len();
        floats::<T>(buf, 1, v.q);
        floats::<T>(buf, 2, v.u);
        floats::<T>(buf, 3, v.reaction);
        floats_with::<T>(buf, 4, nodes, |i| super::super::node_norm(v.reaction, i));
        floats::<T>(buf, 5, v.impulse);
        floats::<T>(buf, 6, v.drive_force);
        floats::<T>(buf, 7, v.normal);
        if !v.in_contact.is_empty() {
            key(buf, 8, LEN);
            varint(buf, v.in_contact.len() as u64);
            buf.extend(v.in_contact.iter().map(|&b| b as u8));
        }
        indices(buf, 9, v.contact_obstacle);
        floats::<T>(buf, 10, v.normal2);
        indices(buf, 11, v.contact_obstacle2);
        floats::<T>(buf, 12, v.bending_stress);
        floats::<T>(buf, 13, v.gap);
        if predictor {
            floats::<T>(buf, 14, v.q_predictor);
        }
        debug_assert_eq!(
            buf.len() - start,
            len,
            "Rod: the length and the bytes differ"
        );
    }
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

impl Body {
    /// Refill from a body view, reusing the buffers.
    pub fn fill(&mut self, b: &BodyView<'_>) {
        if self.name != b.name {
            self.name.clear();
            self.name.push_str(b.name);
        }
        self.obstacle = b.obstacle as u64;
        // The planar message: x, y and the rates about z.
        set(&mut self.position, &b.position[..2]);
        self.angle = b.angle;
        set(&mut self.velocity, &b.velocity[..2]);
        self.angular_velocity = b.angular_velocity[2];
        set(&mut self.contact_force, &b.contact_force[..2]);
        self.contact_torque = b.contact_torque[2];
        self.mass = b.mass;
    }
}

/// A reusable `/sim/step` and `/sim/iteration` encoder: one message of each precision whose
/// buffers live from step to step (nothing is allocated per message once they have grown).
#[derive(Default)]
pub struct StepEncoder {
    pub precision: Precision,
    step: Step,
    step64: Step64,
    iteration: Iteration,
    iteration64: Iteration64,
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
    /// The step's [`fingerprint`] when already worked out ([`fingerprints`]); else it is
    /// here.
    pub fingerprint: Option<u64>,
}

impl StepEncoder {
    pub fn new(precision: Precision) -> Self {
        Self {
            precision,
            ..Default::default()
        }
    }

    /// The schema names of `/sim/step` and `/sim/iteration` at this precision.
    pub fn schemas(&self) -> (&'static str, &'static str) {
        match self.precision {
            Precision::F32 => ("gripsim.Step", "gripsim.Iteration"),
            Precision::F64 => ("gripsim.Step64", "gripsim.Iteration64"),
        }
    }

    /// Encode a step into `buf` (cleared first).
    pub fn encode(&mut self, s: &StepFields<'_, '_>, buf: &mut Vec<u8>) {
        buf.clear();
        match self.precision {
            Precision::F32 => self.step.encode_direct(s, buf),
            Precision::F64 => self.step64.encode_direct(s, buf),
        }
    }

    /// Encode an iteration (an [`crate::events::Event::Iteration`]) into `buf` (cleared first).
    #[allow(clippy::too_many_arguments)]
    pub fn encode_iteration(
        &mut self,
        step: u64,
        t: f64,
        phase: Phase,
        pass: u32,
        iteration: u32,
        rod: usize,
        residual: f64,
        update: f64,
        q: &[f64],
        buf: &mut Vec<u8>,
    ) {
        buf.clear();
        match self.precision {
            Precision::F32 => {
                let m = &mut self.iteration;
                m.fill(step, t, phase, pass, iteration, rod, residual, update, q);
                m.encode(buf)
            }
            Precision::F64 => {
                let m = &mut self.iteration64;
                m.fill(step, t, phase, pass, iteration, rod, residual, update, q);
                m.encode(buf)
            }
        }
        .expect("a Vec grows as needed");
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

/// Add a step's bodies (when there are any) to its JSON form.
fn bodies_json(v: &mut serde_json::Value, bodies: &[Body]) {
    use serde_json::json;
    if !bodies.is_empty() {
        v["bodies"] = bodies
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
}

/// Decode a message of `schema` in `encoding` (`json` or `protobuf`) to its JSON form: what
/// tests and tools that compare recordings of either encoding read (format 4's `gripsim.Step`
/// is the f32 message; a format 3 file's `gripsim.Step` was the f64 layout, `Step64` here).
/// `None` for a schema or encoding this does not know, or bytes that do not decode.
pub fn decode_json(schema: &str, encoding: &str, data: &[u8]) -> Option<serde_json::Value> {
    match (encoding, schema) {
        ("json", _) => serde_json::from_slice(data).ok(),
        ("protobuf", "gripsim.Step") => Step::decode(data).ok().map(|s| s.to_json()),
        ("protobuf", "gripsim.Step64") => Step64::decode(data).ok().map(|s| s.to_json()),
        ("protobuf", "gripsim.Iteration") => Iteration::decode(data).ok().map(|s| s.to_json()),
        ("protobuf", "gripsim.Iteration64") => Iteration64::decode(data).ok().map(|s| s.to_json()),
        ("protobuf", super::foxglove::SCHEMA) => super::foxglove::SceneUpdate::decode(data)
            .ok()
            .map(|s| s.to_json()),
        ("protobuf", super::foxglove::POINT_CLOUD) => super::foxglove::PointCloud::decode(data)
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
            (K::Double | K::Fixed64, false) => WireType::SixtyFourBit,
            (K::Float, false) => WireType::ThirtyTwoBit,
            _ => WireType::Varint,
        }
    }

    fn check(name: &str, bytes: &[u8]) {
        let all = all_messages();
        let fields = &all.iter().find(|(n, _)| *n == name).unwrap().1;
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

    /// Steps fingerprinted side by side get the fingerprint each gets alone (real runs: two
    /// rods; a rod and a free body), and steps of different shapes are refused.
    #[test]
    fn fingerprints_side_by_side_are_each_steps_own() {
        struct Keep(Vec<crate::events::OwnedStepEnd>);
        impl crate::events::Observer for Keep {
            fn on_event(&mut self, ev: &crate::events::Event<'_>) {
                let mut s = crate::events::OwnedStepEnd::default();
                if s.set(ev) {
                    self.0.push(s);
                }
            }
        }
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        let mut runs = Vec::new();
        for (name, t_end) in [("two-prong-grasp", "0.0004"), ("pick-and-place", "0.002")] {
            let sc = crate::Scenario::load(
                &root.join(format!("{name}.toml")),
                &[format!("solve.t_end={t_end}")],
            )
            .unwrap();
            let mut keep = Keep(Vec::new());
            crate::Simulation::new(&sc).run(&mut keep).unwrap();
            assert!(keep.0.len() >= 2 * LANES, "{name}: {} steps", keep.0.len());
            runs.push(keep.0);
        }
        assert!(runs[1].iter().any(|s| !s.bodies.is_empty()));
        for steps in &runs {
            for group in steps.chunks_exact(LANES) {
                let views: [_; LANES] = std::array::from_fn(|k| group[k].views());
                let alone = views.each_ref().map(|(r, b)| fingerprint(r, b));
                let side = fingerprints(views.each_ref().map(|(r, b)| (&r[..], &b[..])));
                assert_eq!(side, Some(alone));
            }
        }
        let mixed: [_; LANES] = std::array::from_fn(|k| {
            if k == 2 {
                runs[1][0].views()
            } else {
                runs[0][k].views()
            }
        });
        assert_eq!(
            fingerprints(mixed.each_ref().map(|(r, b)| (&r[..], &b[..]))),
            None
        );
    }

    /// A step's views: two rods (one with a corrector pass, contacts, a corner, a far node
    /// and 200 nodes so that the lengths take two-byte varints), a body and a contact.
    fn direct_case(step: u64, t: f64, check: impl Fn(&StepFields<'_, '_>)) {
        let n = 200;
        let wave = |k: usize, s: f64| {
            (0..2 * n)
                .map(|i| s * ((i * k) as f64).sin())
                .collect::<Vec<f64>>()
        };
        let (q, u, reaction) = (wave(1, 0.1), wave(2, -3.0), wave(3, 0.0));
        let mut react = wave(3, 7.0);
        for x in react.iter_mut().skip(8) {
            *x = 0.0;
        }
        let pred = wave(5, 0.1);
        let mut obst = vec![usize::MAX; n];
        obst[1] = 0;
        obst[2] = 70;
        let mut obst2 = vec![usize::MAX; n];
        obst2[2] = 1;
        let inside: Vec<bool> = obst.iter().map(|&k| k != usize::MAX).collect();
        let mut gap = wave(7, 0.01);
        gap[3] = f64::INFINITY;
        gap[4] = f64::NAN;
        gap[5] = -0.0;
        let views = [
            RodStepView {
                dim: 2,
                twist_stress: &[],
                frames: None,
                q: &q,
                u: &u,
                reaction: &react,
                impulse: &react,
                drive_force: &u,
                normal: &react,
                contact_obstacle: &obst,
                normal2: &react,
                contact_obstacle2: &obst2,
                in_contact: &inside,
                bending_stress: &q[..n],
                gap: &gap,
                q_predictor: &pred,
            },
            RodStepView {
                dim: 2,
                twist_stress: &[],
                frames: None,
                q: &u,
                u: &q,
                reaction: &reaction,
                impulse: &reaction,
                drive_force: &reaction,
                normal: &reaction,
                contact_obstacle: &vec![usize::MAX; n],
                normal2: &reaction,
                contact_obstacle2: &vec![usize::MAX; n],
                in_contact: &vec![false; n],
                bending_stress: &u[..n],
                gap: &gap,
                q_predictor: &u,
            },
        ];
        let bodies = [BodyView {
            name: "apple",
            obstacle: 2,
            position: [0.1, -0.2, 0.0],
            angle: 0.3,
            rotation: crate::events::about_z(0.3),
            velocity: [0.0, -1.0, 0.0],
            angular_velocity: [0.0; 3],
            contact_force: [2.0, 9.8, 0.0],
            contact_torque: [0.0, 0.0, -0.01],
            mass: 0.1,
        }];
        let contacts = [ContactView {
            rod: usize::MAX,
            node: 0,
            obstacle: 1,
            body: 0,
            point: [0.1, 0.2, 0.0],
            normal: [0.0, 1.0, 0.0],
            tangent: [-1.0, 0.0, 0.0],
            normal_force: 1.5,
            friction_force: -0.5,
            slip_velocity: 0.0,
            stuck: true,
            utilisation: 0.3,
            mu_s: 0.5,
            indentation: 1e-4,
            half_width: 2e-3,
            half_width_minor: 2e-3,
            peak_pressure: 1e5,
            bruise_pressure: 2e5,
            bruise_half_width: 0.0,
            segment: usize::MAX,
            weight: 0.0,
            first: usize::MAX,
            last: usize::MAX,
            dim: 2,
        }];
        check(&StepFields {
            step,
            t,
            dt: 1e-5,
            newton_iterations: 2,
            passes: (step % 2) as u32,
            rods: &views,
            bodies: &bodies,
            contacts: &contacts,
            fingerprint: None,
        });
        check(&StepFields {
            step,
            t,
            dt: 0.0,
            newton_iterations: 0,
            passes: 0,
            rods: &views[1..],
            bodies: &[],
            contacts: &[],
            fingerprint: None,
        });
    }

    #[test]
    fn the_direct_step_encoder_writes_the_bytes_prost_writes() {
        for (step, t) in [(0, 0.0), (1, 1e-5), (300, -0.0), (1 << 40, 12.5)] {
            direct_case(step, t, |s| {
                let mut direct = Vec::new();
                let mut prost32 = Step::default();
                prost32.fill(s);
                Step::default().encode_direct(s, &mut direct);
                assert_eq!(direct, prost32.encode_to_vec(), "f32, step {step}");
                let mut prost64 = Step64::default();
                prost64.fill(s);
                direct.clear();
                Step64::default().encode_direct(s, &mut direct);
                assert_eq!(direct, prost64.encode_to_vec(), "f64, step {step}");
                // And through the reusable encoder, twice (its buffers reused).
                let mut enc = StepEncoder::new(Precision::F32);
                enc.encode(s, &mut direct);
                enc.encode(s, &mut direct);
                assert_eq!(direct, prost32.encode_to_vec());
            });
        }
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
            gap: vec![f32::INFINITY],
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
            first: 1,
            last: 1,
        };
        let contact64 = Contact64 {
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
            first: 1,
            last: 1,
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
            fingerprint: 1,
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
        // The f64 twins: the same fields, `double` for `float`.
        let wide = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<f64>>();
        let rod64 = Rod64 {
            q: wide(&rod.q),
            u: wide(&rod.u),
            reaction: wide(&rod.reaction),
            reaction_norm: wide(&rod.reaction_norm),
            impulse: wide(&rod.impulse),
            drive_force: wide(&rod.drive_force),
            normal: wide(&rod.normal),
            in_contact: rod.in_contact.clone(),
            contact_obstacle: rod.contact_obstacle.clone(),
            normal2: wide(&rod.normal2),
            contact_obstacle2: rod.contact_obstacle2.clone(),
            bending_stress: wide(&rod.bending_stress),
            gap: wide(&rod.gap),
            q_predictor: wide(&rod.q_predictor),
        };
        let step64 = Step64 {
            step: 1,
            t: 1.0,
            dt: 1.0,
            newton_iterations: 1,
            passes: 1,
            rods: vec![rod64.clone()],
            bodies: vec![body.clone()],
            contacts: vec![contact64.clone()],
            fingerprint: 1,
        };
        let it64 = Iteration64 {
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
        check("Step64", &step64.encode_to_vec());
        check("Rod64", &rod64.encode_to_vec());
        check("Iteration64", &it64.encode_to_vec());
        check("ContactState64", &contact64.encode_to_vec());
        // The f32 and f64 forms of one message give the same JSON (values exact in f32).
        assert_eq!(step.to_json(), step64.to_json());
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
        assert_eq!(
            names,
            [
                "Step",
                "Rod",
                "Body",
                "ContactState",
                "Iteration",
                "Step64",
                "Rod64",
                "ContactState64",
                "Iteration64"
            ]
        );
        let rod = &f.message_type[1];
        assert_eq!(rod.field.len(), 14);
        assert_eq!(rod.field[8].name(), "contact_obstacle");
        assert_eq!(rod.field[8].r#type(), Type::Sint64);
        assert_eq!(rod.field[8].label(), Label::Repeated);
        assert_eq!(f.message_type[0].field[5].type_name(), ".gripsim.Rod");
        assert_eq!(rod.field[0].r#type(), Type::Float);
        assert_eq!(f.message_type[0].field[8].r#type(), Type::Fixed64);
        let rod64 = &f.message_type[6];
        assert_eq!(rod64.field[0].r#type(), Type::Double);
        assert_eq!(f.message_type[5].field[5].type_name(), ".gripsim.Rod64");
    }

    #[test]
    fn the_fingerprint_is_fnv1a_over_the_f64_bytes() {
        // FNV-1a 64 of the bytes "abcdefgh" (the reference algorithm gives 0x25da8c1836a8d66d;
        // of "foobar", the published test vector, 0x85944171f73967e8).
        let mut h = Fingerprint::default();
        h.add(f64::from_bits(u64::from_le_bytes(*b"abcdefgh")));
        assert_eq!(h.0, 0x25da_8c18_36a8_d66d);
        // One bit of one number changes it.
        let mut g = Fingerprint::default();
        g.add(f64::from_bits(u64::from_le_bytes(*b"abcdefgh") ^ 1));
        assert_ne!(g.0, h.0);
    }
}
