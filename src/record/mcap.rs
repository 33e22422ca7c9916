//! The MCAP sink: the archival record of a run. The high-rate channels and the scene are
//! protobuf (their schema, a `FileDescriptorSet`, is in the file: see [`super::proto`] and
//! [`super::foxglove`]), the rest JSON messages with JSON schemas, for a human to read.
//!
//! Channels (each documented field by field in docs/recording-format.md, and by the schemas
//! in `src/record/schemas/` and [`super::proto`], which the file carries):
//!
//! | topic | schema | messages |
//! |---|---|---|
//! | `/sim/meta` | `gripsim.Meta` | one, first: scenario text, rods, obstacles, units |
//! | `/sim/step` | `gripsim.Step` (protobuf; f64: `gripsim.Step64`) | one per step, from step 0 (the initial state) |
//! | `/sim/iteration` | `gripsim.Iteration` (protobuf; f64: `gripsim.Iteration64`) | one per Newton iteration (`--detail iteration`) |
//! | `/sim/contact` | `gripsim.Contact` | one per constraint added or released |
//! | `/sim/event` | `gripsim.Event` | dt changes, Newton failures, warnings, run end |
//! | `/scene` | `foxglove.SceneUpdate` (protobuf) | one per step: the rods and free bodies for Foxglove's 3D panel |
//! | `/scene/static` | `foxglove.SceneUpdate` (protobuf) | one, before the first step: obstacles and legend |
//! | `/scene/nodes` | `foxglove.PointCloud` (protobuf) | one per step: every rod's nodes, coloured |
//!
//! The file is chunked and zstd-compressed (level [`ZSTD_LEVEL`]) with message indexes and a
//! summary (the `mcap` crate writer's records and defaults, written by `src/record/mcap_file.rs`).
//! Log times are simulated time in ns (static runs: step number in s), clamped so they never
//! decrease. Nothing depends on the wall clock or the machine (single threaded compression,
//! fixed header strings), so one scenario gives the same bytes every run.
//!
//! The sink hands batches to one writer thread that encodes, compresses and writes them in
//! order ([`Pipe`]): a copy of each step (the high-rate `/sim/step`, `/scene` and
//! `/scene/nodes` are encoded there, [`StepWriter`]) and the rare messages already encoded
//! (JSON, iterations). The bytes are those of writing inline, and the run waits for the
//! writer only when it is [`BATCHES_QUEUED`] batches or [`FLUSHES_AHEAD`] flushes behind.
//! From the run's end the thread ends the file (summary, footer, `fsync`) while the other
//! sinks end theirs.

use super::foxglove::Wire as _;
use super::{
    error_chain, node_norm, obstacle_outline, Finished, OutputFile, RecordError, RecordOptions,
    Recording, SceneStyle, ViewOptions, BODY_COLOR, DRIVEN_COLOR, NORMAL_COLOR, OBSTACLE_COLOR,
    PREDICTOR_COLOR, REACTION_COLOR, ROD_COLOR,
};
use crate::events::{
    BodyView, ContactChange, Event, Observer, OwnedStepEnd, ReleaseReason, RodInfo, RodStepView,
    RunInfo,
};
use crate::obstacle::Obstacle;
use crate::scenario::Mode;
use crate::world::body::BodySpec;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::BufWriter;
use std::path::Path;

/// Version of the recording format; bumped when a field changes meaning or is removed.
/// Format 2: `/sim/step` and `/sim/iteration` are protobuf (format 1: JSON; still read).
/// Format 3: `/scene` and `/scene/static` are protobuf; a rod's `q_predictor` in `/sim/step` is
/// empty on steps without a corrector pass (it equals `q` then).
/// Format 4: `/sim/step` and `/sim/iteration` store their per-node numbers as protobuf `float`
/// (`gripsim.Step`, `gripsim.Iteration`) or, at `output.precision = "f64"`, `double`
/// (`gripsim.Step64`, `gripsim.Iteration64`); every step carries the 64-bit `fingerprint` of its
/// exact state; the nodes are drawn as one `foxglove.PointCloud` on `/scene/nodes` instead of a
/// sphere per node in `/scene`; `/sim/meta` says `precision`.
pub const FORMAT_VERSION: u32 = 4;

/// The zstd level of the MCAP's chunks: −1, the fastest level's one-step acceleration, with
/// [`ZSTD_MIN_MATCH`] and [`ZSTD_HASH_LOG`]: the bytes of level 1 in 7 % fewer instructions
/// (docs/performance.md, "Recording cost").
pub const ZSTD_LEVEL: i32 = -1;
/// zstd's shortest match in the MCAP's chunks: 4 bytes (the level's 6–7 miss the repeats of
/// protobuf field tags and `float`s; two-prong grasp: 2.7 % fewer bytes at level 1).
pub const ZSTD_MIN_MATCH: u32 = 4;
/// zstd's hash table of 2¹² entries (a chunk of 100 steps is ~300 kB: the level's 2¹⁴ only
/// costs cache misses).
pub const ZSTD_HASH_LOG: u32 = 12;

/// The `library` string in the MCAP header.
pub const LIBRARY: &str = concat!("gripsim ", env!("CARGO_PKG_VERSION"));

/// Every channel: topic, schema name, schema text (JSON schema; empty for the protobuf
/// channels, whose schema is a `FileDescriptorSet`: [`super::proto`], [`super::foxglove`]).
pub const CHANNELS: [(&str, &str, &str); 8] = [
    (
        "/sim/meta",
        "gripsim.Meta",
        include_str!("schemas/gripsim.Meta.json"),
    ),
    (
        "/sim/step",
        "gripsim.Step",
        include_str!("schemas/gripsim.Step.json"),
    ),
    (
        "/sim/iteration",
        "gripsim.Iteration",
        include_str!("schemas/gripsim.Iteration.json"),
    ),
    (
        "/sim/contact",
        "gripsim.Contact",
        include_str!("schemas/gripsim.Contact.json"),
    ),
    (
        "/sim/event",
        "gripsim.Event",
        include_str!("schemas/gripsim.Event.json"),
    ),
    // Foxglove's published foxglove.SceneUpdate, as protobuf (format 3; JSON before).
    ("/scene", super::foxglove::SCHEMA, ""),
    // What never moves (obstacle outlines, the legend): one message before the first step.
    ("/scene/static", super::foxglove::SCHEMA, ""),
    // The nodes of every rod, one point each, coloured as in the .rrd (format 4).
    ("/scene/nodes", super::foxglove::POINT_CLOUD, ""),
];

const META: usize = 0;
const STEP: usize = 1;
const ITERATION: usize = 2;
const CONTACT: usize = 3;
const EVENT: usize = 4;
const SCENE: usize = 5;
const SCENE_STATIC: usize = 6;
const NODES: usize = 7;

/// The channels written as protobuf (the others are JSON).
pub const PROTOBUF: [usize; 5] = [STEP, ITERATION, SCENE, SCENE_STATIC, NODES];

/// What an MCAP file stores besides [`RecordOptions`].
#[derive(Debug, Clone, Copy)]
pub struct McapOptions {
    /// `/sim/step` and `/sim/iteration` in f32 (with a fingerprint) or f64.
    pub precision: super::proto::Precision,
    /// The chunks' zstd level ([`ZSTD_LEVEL`], with [`ZSTD_MIN_MATCH`] and [`ZSTD_HASH_LOG`]).
    pub zstd_level: i32,
}

impl Default for McapOptions {
    fn default() -> Self {
        Self {
            precision: Default::default(),
            zstd_level: ZSTD_LEVEL,
        }
    }
}

type Writer = super::mcap_file::McapFile<BufWriter<std::fs::File>>;

/// Writes an MCAP file.
pub struct McapSink {
    out: OutputFile,
    /// The writer thread (compression and writing happen there); None after an error or the
    /// run's end.
    writer: Option<Pipe>,
    /// The writer thread ending the file, from the run's end on.
    closing: Option<Closing>,
    opts: RecordOptions,
    channels: [u16; 8],
    sequence: [u32; 8],
    buf: Vec<u8>,
    step_encoder: super::proto::StepEncoder,
    static_mode: bool,
    last_time: u64,
    rods: Vec<RodInfo>,
    obstacles: Vec<Obstacle>,
    /// Free bodies: drawn at their pose every step, not with the fixed obstacles.
    bodies: Vec<BodySpec>,
    view: ViewOptions,
    /// Whether the scene's style is fixed (at the first step; the writer thread has it).
    styled: bool,
    /// Simulated time of the current step's start: the log time of its Newton iterations and
    /// contact changes.
    step_start: f64,
    completed: bool,
    end: BTreeMap<String, String>,
    error: Option<RecordError>,
    /// Set with `error`, for [`Recording::failure`].
    failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl McapSink {
    /// Create `path` (as its `.partial` sibling until the run completes) and write the header,
    /// schemas and channels.
    pub fn create(path: &Path, opts: RecordOptions) -> Result<Self, RecordError> {
        Self::create_with(path, opts, McapOptions::default())
    }

    /// [`McapSink::create`] with the MCAP's own options (precision, zstd level).
    pub fn create_with(
        path: &Path,
        opts: RecordOptions,
        mcap: McapOptions,
    ) -> Result<Self, RecordError> {
        let out = OutputFile::new(path);
        let file = out.create()?;
        let writeback = super::Writeback::of(&file);
        // The `mcap` crate's records and options, each chunk compressed whole (one thread:
        // zstd's output then depends on nothing but the input).
        let mut w = Writer::new(
            BufWriter::with_capacity(1 << 16, file),
            "",
            LIBRARY,
            Some(super::mcap_file::Zstd {
                level: mcap.zstd_level,
                min_match: Some(ZSTD_MIN_MATCH),
                hash_log: Some(ZSTD_HASH_LOG),
            }),
        )
        .map_err(|e| RecordError::write(out.writing(), error_chain(&e)))?;
        let mut channels = [0u16; 8];
        let step_encoder = super::proto::StepEncoder::new(mcap.precision);
        let (step_schema, iteration_schema) = step_encoder.schemas();
        let descriptors = super::proto::file_descriptor_set();
        let scene_descriptors = super::foxglove::file_descriptor_set();
        for (k, &(topic, schema, text)) in CHANNELS.iter().enumerate() {
            let schema = match k {
                STEP => step_schema,
                ITERATION => iteration_schema,
                _ => schema,
            };
            let (sid, encoding) = if PROTOBUF.contains(&k) {
                let set = if k == SCENE || k == SCENE_STATIC || k == NODES {
                    &scene_descriptors
                } else {
                    &descriptors
                };
                let sid = w.add_schema(schema, "protobuf", set);
                (sid, "protobuf")
            } else {
                let sid = w.add_schema(schema, "jsonschema", text.as_bytes());
                (sid, "json")
            };
            channels[k] = w.add_channel(sid, topic, encoding, &BTreeMap::new());
        }
        let failed: std::sync::Arc<std::sync::atomic::AtomicBool> = Default::default();
        let steps = StepWriter::new(channels, mcap.precision);
        let pipe = Pipe::start(w, writeback, steps, failed.clone()).map_err(|e| {
            RecordError::write(out.writing(), format!("cannot start a thread: {e}"))
        })?;
        Ok(Self {
            out,
            writer: Some(pipe),
            closing: None,
            opts: RecordOptions {
                flush_every: opts.flush_every.max(1),
                ..opts
            },
            channels,
            sequence: [0; 8],
            buf: Vec::with_capacity(1 << 14),
            step_encoder,
            static_mode: false,
            last_time: 0,
            rods: Vec::new(),
            obstacles: Vec::new(),
            bodies: Vec::new(),
            view: ViewOptions::default(),
            styled: false,
            step_start: 0.0,
            completed: false,
            end: BTreeMap::new(),
            error: None,
            failed,
        })
    }

    /// Draw `/scene` with the run's survey and this arrow scale (call before the run starts).
    pub fn with_view(mut self, view: ViewOptions) -> Self {
        self.view = view;
        self
    }

    /// The log time of an event: simulated ns (static runs: the step number in s), never
    /// smaller than the last one.
    fn time(&mut self, step: u64, t: f64) -> u64 {
        let raw = if self.static_mode {
            step.saturating_mul(1_000_000_000)
        } else if t > 0.0 {
            (t * 1e9).round() as u64
        } else {
            0
        };
        self.last_time = self.last_time.max(raw);
        self.last_time
    }

    /// Serialise `msg` as JSON and write it on channel `k` at `log_time`.
    fn send<T: Serialize>(&mut self, k: usize, log_time: u64, msg: &T) {
        self.buf.clear();
        if let Err(e) = serde_json::to_writer(&mut self.buf, msg) {
            return self.fail(e);
        }
        self.write_buf(k, log_time);
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
        if let Err(e) = w.message(header, &self.buf) {
            self.fail(e);
        }
    }

    /// The `gripsim.run_end` metadata record (empty before the run's end).
    fn run_end_record(&mut self) -> ::mcap::records::Metadata {
        ::mcap::records::Metadata {
            name: "gripsim.run_end".into(),
            metadata: std::mem::take(&mut self.end),
        }
    }

    fn fail(&mut self, e: impl std::fmt::Display) {
        if self.error.is_none() {
            self.error = Some(RecordError::write(self.out.writing(), e));
        }
        // Ending the writer writes what it can of the summary; the file keeps .partial.
        if let Some(pipe) = self.writer.take() {
            let _ = pipe.finish();
        }
        self.failed
            .store(true, std::sync::atomic::Ordering::Relaxed);
    }

    fn run_start(&mut self, info: &RunInfo<'_>) {
        self.static_mode = info.mode == Mode::Static;
        self.rods = info.rods.to_vec();
        self.obstacles = info.planar_obstacles().to_vec();
        self.bodies = info.bodies.to_vec();
        let mode = match info.mode {
            Mode::Dynamic => "dynamic",
            Mode::Static => "static",
        };
        let meta = Meta {
            format_version: FORMAT_VERSION,
            gripsim_version: env!("CARGO_PKG_VERSION"),
            scenario_name: info.scenario_name,
            scenario_text: info.scenario_text,
            mode,
            detail: self.opts.detail.as_str(),
            precision: self.step_encoder.precision.as_str(),
            auto_every: self.opts.detail.auto().map(|a| a.every),
            auto_window: self.opts.detail.auto().map(|a| a.window),
            flush_every: self.opts.flush_every,
            clock: if self.static_mode {
                "load_step"
            } else {
                "sim_time"
            },
            units: UNITS.iter().copied().collect(),
            rods: info.rods.iter().map(RodMeta::from).collect(),
            obstacles: info.planar_obstacles(),
        };
        let record = ::mcap::records::Metadata {
            name: "gripsim".into(),
            metadata: BTreeMap::from([
                ("format_version".into(), FORMAT_VERSION.to_string()),
                ("gripsim_version".into(), env!("CARGO_PKG_VERSION").into()),
                ("scenario_name".into(), info.scenario_name.into()),
                ("mode".into(), mode.into()),
                ("detail".into(), self.opts.detail.as_str().into()),
                (
                    "precision".into(),
                    self.step_encoder.precision.as_str().into(),
                ),
            ]),
        };
        let mut record = record;
        if let Some(a) = self.opts.detail.auto() {
            record
                .metadata
                .insert("auto_every".into(), a.every.to_string());
            record
                .metadata
                .insert("auto_window".into(), a.window.to_string());
        }
        if let Some(w) = self.writer.as_mut() {
            w.metadata(record);
        }
        self.send(META, 0, &meta);
    }

    /// A [`Event::StepEnd`] (`ev`, with its step, time and rods).
    fn step_end(&mut self, ev: &Event<'_>, step: u64, t: f64, rods: &[RodStepView<'_>]) {
        if !self.styled {
            let style = SceneStyle::new(
                &self.rods,
                rods,
                &self.obstacles,
                self.view.survey.as_ref(),
                self.view.arrows,
            );
            // The obstacles and the legend, once: Foxglove keeps an entity until it is
            // replaced, and after a seek it reads the last message of each topic, which for
            // this topic is this one.
            let time = self.time(step, t);
            let msg = super::foxglove::SceneUpdate {
                deletions: Vec::new(),
                entities: static_entities(&self.obstacles, &self.bodies, &style, time),
            };
            self.styled = true;
            self.buf.clear();
            prost::Message::encode(&msg, &mut self.buf).expect("a Vec grows as needed");
            self.write_buf(SCENE_STATIC, time);
            if let Some(w) = self.writer.as_mut() {
                w.setup(Scene::new(
                    self.rods.clone(),
                    self.obstacles.clone(),
                    self.bodies.clone(),
                    style,
                ));
            }
        }
        let time = self.time(step, t);
        let Some(w) = self.writer.as_mut() else {
            return;
        };
        // `/sim/step`, `/scene` and `/scene/nodes` are encoded on the writer thread, from a
        // copy of the step.
        if let Err(e) = w.step(ev, time) {
            return self.fail(e);
        }
        if step.is_multiple_of(self.opts.flush_every) {
            if let Err(e) = w.flush() {
                self.fail(e);
            }
        }
    }

    fn contact(&mut self, c: &ContactChange, released: Option<ReleaseReason>) {
        // Logged at the step's start, like the Newton iterations around it.
        let time = self.time(c.step, self.step_start);
        let msg = ContactMsg {
            change: if released.is_some() {
                "released"
            } else {
                "added"
            },
            reason: released.map(|r| match r {
                ReleaseReason::Adhesive => "adhesive",
                ReleaseReason::HandedOver => "handed_over",
            }),
            step: c.step,
            t: c.t,
            pass: c.pass,
            rod: c.rod,
            node: c.node,
            obstacle: c.obstacle,
            normal: crate::events::xy(c.normal),
            gap: c.gap,
            reaction: crate::events::xy(c.reaction),
            z: c.z,
        };
        self.send(CONTACT, time, &msg);
    }

    fn event(&mut self, msg: EventMsg<'_>) {
        let time = self.time(msg.step, msg.t);
        self.send(EVENT, time, &msg);
    }
}

impl Observer for McapSink {
    fn wants_iterations(&self) -> bool {
        self.opts.detail.iterations()
    }

    fn on_event(&mut self, event: &Event<'_>) {
        if self.writer.is_none() {
            return;
        }
        match *event {
            Event::RunStart(info) => self.run_start(info),
            Event::StepBegin { t, .. } => self.step_start = t,
            Event::Iteration {
                step,
                t,
                phase,
                pass,
                iteration,
                rod,
                residual,
                update,
                q,
            } => {
                if self.opts.detail.iterations() {
                    let time = self.time(step, self.step_start.min(t));
                    self.step_encoder.encode_iteration(
                        step,
                        t,
                        phase,
                        pass,
                        iteration,
                        rod,
                        residual,
                        update,
                        q,
                        &mut self.buf,
                    );
                    self.write_buf(ITERATION, time);
                }
            }
            Event::ConstraintAdded(c) => self.contact(&c, None),
            Event::ConstraintReleased(c, why) => self.contact(&c, Some(why)),
            Event::DtChanged {
                step,
                t,
                old,
                new,
                reason,
            } => self.event(EventMsg {
                kind: "dt_changed",
                step,
                t,
                message: format!("step {step}: dt {old:e} s -> {new:e} s ({reason})"),
                old_dt: Some(old),
                new_dt: Some(new),
                reason: Some(reason),
                ..EventMsg::default()
            }),
            Event::NewtonFailed {
                step,
                t,
                dt,
                rod,
                node,
                residual,
                reason,
            } => self.event(EventMsg {
                kind: "newton_failed",
                step,
                t,
                message: format!(
                    "step {step}: Newton failed on rod {:?} node {node} with dt = {dt:e}: {reason} (residual {residual:e} N)",
                    self.rods.get(rod).map(|r| r.name.as_str()).unwrap_or("?")
                ),
                reason: Some(reason),
                dt: Some(dt),
                rod: Some(rod),
                node: Some(node),
                residual: Some(residual),
                ..EventMsg::default()
            }),
            Event::Warning { step, t, message } => self.event(EventMsg {
                kind: "warning",
                step,
                t,
                message: message.to_string(),
                ..EventMsg::default()
            }),
            Event::FrictionChanged(_)
            | Event::BodyContactChanged { .. }
            | Event::PhaseChanged { .. } => {
                if let Some((step, t, message)) = event.describe() {
                    self.event(EventMsg {
                        kind: "contact_state",
                        step,
                        t,
                        message,
                        ..EventMsg::default()
                    })
                }
            }
            Event::StepEnd { step, t, rods, .. } => self.step_end(event, step, t, rods),
            Event::RunEnd { steps, t, error } => {
                self.completed = error.is_none();
                self.end = BTreeMap::from([
                    ("completed".into(), self.completed.to_string()),
                    ("steps".into(), steps.to_string()),
                    ("t".into(), t.to_string()),
                    ("error".into(), error.unwrap_or("").to_string()),
                ]);
                let message = match error {
                    None => format!("run completed: {steps} steps, t = {t} s"),
                    Some(e) => format!("run stopped after {steps} steps: {e}"),
                };
                self.event(EventMsg {
                    kind: "run_end",
                    step: steps,
                    t,
                    message,
                    completed: Some(error.is_none()),
                    error: Some(error),
                    ..EventMsg::default()
                });
                // Nothing follows the run's end: the writer thread ends the file now, while
                // the other sinks end theirs.
                if let Some(mut w) = self.writer.take() {
                    w.metadata(self.run_end_record());
                    self.closing = Some(w.close());
                }
            }
        }
    }
}

/// The sink's end of the writer thread. The sink encodes each message (protobuf or JSON) and
/// appends it to a batch; full batches (and every flush) go over a bounded channel to one
/// thread that compresses and writes them in order with the `mcap` writer, so the file holds
/// the same bytes as when the sink wrote it itself. Emptied batches come back for reuse. A
/// flush waits until the writer has done all but the last [`FLUSHES_AHEAD`] flushes before
/// it, so the file on disk is never more than that many flush intervals and one behind the
/// run. The thread's first write error sets the sink's failure flag (which stops the run) and
/// is returned by [`Pipe::finish`].
struct Pipe {
    batch: Batch,
    to_writer: std::sync::mpsc::SyncSender<Batch>,
    spent: std::sync::mpsc::Receiver<Batch>,
    free: Vec<Batch>,
    /// Flushes sent to the writer, and those it has done.
    flushes_sent: u64,
    flushes_done: u64,
    thread: std::thread::JoinHandle<Result<(), String>>,
}

/// Encoded messages and records for the writer thread, in order.
#[derive(Default)]
struct Batch {
    data: Vec<u8>,
    items: Vec<Item>,
    /// Copies of steps, the first `steps_used` of them this batch's (the others are slots
    /// kept for reuse).
    steps: Vec<StepCopy>,
    steps_used: usize,
    /// Whether the batch ended with a flush (kept when the writer empties it).
    flushed: bool,
}

enum Item {
    /// A message whose bytes end at this offset of the batch's data (and start where the
    /// previous message's end).
    Message(::mcap::records::MessageHeader, usize),
    Metadata(::mcap::records::Metadata),
    /// End the current chunk and hand the bytes to the operating system.
    Flush,
    /// The scene's fixed parts, for the steps that follow.
    Setup(Box<Scene>),
    /// A step (this slot of the batch's copies): `/sim/step`, `/scene` and `/scene/nodes`.
    Step(usize),
}

/// A batch is sent when it holds this many bytes (or at a flush).
const BATCH_BYTES: usize = 1 << 18;
/// ... or this many steps.
const BATCH_STEPS: usize = 64;
/// Batches queued for the writer thread at most (then the simulation waits for it).
const BATCHES_QUEUED: usize = 16;
/// Flushes the run may be ahead of the writer thread (then it waits for it at a flush). Slack
/// lets the writer thread and the others even out on two cores: with one flush ahead (and 4
/// batches) the run waited at most of the flush points while a core stood idle (two-prong grasp,
/// both files at step detail: wall time 7 % longer, the same CPU time; docs/performance.md);
/// with eight, the writer's backlog at the run's end (which it works off alone) grew to
/// ~18 ms, two and four did as well as eight in the middle. With `flush_every` 100 the
/// `.mcap` on disk lags the run by at most ~500 steps (the `.rrd`'s columns, sent every
/// 700-1 000 steps, more).
const FLUSHES_AHEAD: u64 = 4;

impl Pipe {
    fn start(
        w: Writer,
        writeback: super::Writeback,
        steps: StepWriter,
        failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
    ) -> std::io::Result<Self> {
        let (to_writer, batches) = std::sync::mpsc::sync_channel(BATCHES_QUEUED);
        let (back, spent) = std::sync::mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || write_batches(w, writeback, steps, batches, back, failed))?;
        Ok(Self {
            batch: Batch::default(),
            to_writer,
            spent,
            free: Vec::new(),
            flushes_sent: 0,
            flushes_done: 0,
            thread,
        })
    }

    fn message(
        &mut self,
        header: ::mcap::records::MessageHeader,
        data: &[u8],
    ) -> Result<(), String> {
        self.batch.data.extend_from_slice(data);
        self.batch
            .items
            .push(Item::Message(header, self.batch.data.len()));
        if self.batch.data.len() >= BATCH_BYTES {
            self.send()
        } else {
            Ok(())
        }
    }

    fn metadata(&mut self, record: ::mcap::records::Metadata) {
        self.batch.items.push(Item::Metadata(record));
    }

    fn setup(&mut self, scene: Scene) {
        self.batch.items.push(Item::Setup(Box::new(scene)));
    }

    /// Copy a step (logged at `time`) for the writer thread to encode.
    fn step(&mut self, ev: &Event<'_>, time: u64) -> Result<(), String> {
        let b = &mut self.batch;
        if b.steps_used == b.steps.len() {
            b.steps.push(StepCopy::default());
        }
        b.steps[b.steps_used].set(ev, time);
        b.items.push(Item::Step(b.steps_used));
        b.steps_used += 1;
        if b.steps_used >= BATCH_STEPS {
            self.send()
        } else {
            Ok(())
        }
    }

    /// Send a flush, and wait until the writer has done all but [`FLUSHES_AHEAD`] of those
    /// before.
    fn flush(&mut self) -> Result<(), String> {
        self.batch.items.push(Item::Flush);
        self.batch.flushed = true;
        self.flushes_sent += 1;
        self.send()?;
        while self.flushes_done + FLUSHES_AHEAD < self.flushes_sent {
            let b = self
                .spent
                .recv()
                .map_err(|_| "the .mcap writer thread stopped".to_string())?;
            self.take_back(b);
        }
        Ok(())
    }

    fn take_back(&mut self, mut b: Batch) {
        if std::mem::take(&mut b.flushed) {
            self.flushes_done += 1;
        }
        self.free.push(b);
    }

    fn send(&mut self) -> Result<(), String> {
        if self.batch.items.is_empty() {
            return Ok(());
        }
        while let Ok(b) = self.spent.try_recv() {
            self.take_back(b);
        }
        let next = self.free.pop().unwrap_or_default();
        let full = std::mem::replace(&mut self.batch, next);
        self.to_writer
            .send(full)
            .map_err(|_| "the .mcap writer thread stopped".to_string())
    }

    /// Send what is left and wait for the thread to end the file (summary, footer) and close
    /// it.
    fn finish(self) -> Result<(), String> {
        self.close().wait()
    }

    /// Send what is left and let the thread end the file (summary, footer, `fsync`) while the
    /// caller goes on; [`Closing::wait`] waits for it.
    fn close(mut self) -> Closing {
        let sent = self.send();
        let Pipe {
            to_writer, thread, ..
        } = self;
        drop(to_writer);
        Closing { sent, thread }
    }
}

/// A writer thread ending the file.
struct Closing {
    sent: Result<(), String>,
    thread: std::thread::JoinHandle<Result<(), String>>,
}

impl Closing {
    fn wait(self) -> Result<(), String> {
        let written = self
            .thread
            .join()
            .unwrap_or_else(|_| Err("the .mcap writer thread panicked".to_string()));
        written.and(self.sent)
    }
}

/// The writer thread: write every batch in order, then end the file. After the first error
/// nothing more is written (the batches are still taken, so the sink never waits).
fn write_batches(
    w: Writer,
    writeback: super::Writeback,
    mut steps: StepWriter,
    batches: std::sync::mpsc::Receiver<Batch>,
    back: std::sync::mpsc::Sender<Batch>,
    failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> Result<(), String> {
    super::background::as_writer_thread();
    let mut w = Some(w);
    let mut error = None;
    for mut b in batches {
        if let Some(writer) = w.as_mut() {
            if let Err(e) = write_batch(writer, writeback, &mut steps, &mut b) {
                error = Some(error_chain(&e));
                failed.store(true, std::sync::atomic::Ordering::Relaxed);
                // Nothing more is written; the error is the run's.
                w = None;
            }
        }
        b.data.clear();
        b.items.clear();
        b.steps_used = 0;
        let _ = back.send(b);
    }
    match (w, error) {
        (_, Some(e)) => Err(e),
        (None, None) => Ok(()),
        // A regular file's data reach the disk here, beside whatever the caller does
        // meanwhile (the sink's own `fsync` at the end then finds nothing left to write); a
        // device written through (`/dev/null`) is not synced, as in `OutputFile::settle`.
        (Some(mut w), None) => w
            .finish()
            .map_err(|e| error_chain(&e))
            .and_then(|_| {
                w.into_inner()
                    .into_inner()
                    .map_err(|e| error_chain(e.error()))
            })
            .and_then(|f| match f.metadata() {
                Ok(m) if m.is_file() => f.sync_all().map_err(|e| error_chain(&e)),
                _ => Ok(()),
            }),
    }
}

fn write_batch(
    w: &mut Writer,
    writeback: super::Writeback,
    steps: &mut StepWriter,
    b: &mut Batch,
) -> Result<(), ::mcap::McapError> {
    fingerprint_steps(&mut b.steps[..b.steps_used]);
    let mut start = 0;
    for item in b.items.drain(..) {
        match item {
            Item::Message(header, end) => {
                w.write_to_known_channel(&header, &b.data[start..end])?;
                start = end;
            }
            Item::Metadata(record) => w.write_metadata(&record)?,
            Item::Flush => {
                // The chunk is ended and in the file: its pages start for the disk now.
                w.flush()?;
                writeback.start();
            }
            Item::Setup(scene) => steps.scene = Some(*scene),
            Item::Step(k) => steps.write(w, &b.steps[k])?,
        }
    }
    Ok(())
}

/// Work out the steps' fingerprints [`proto::LANES`](super::proto::LANES) at a time (the
/// same values, side by side: [`super::proto::fingerprints`]); the rest, or steps of
/// differing shapes, are left to the encoder.
fn fingerprint_steps(copies: &mut [StepCopy]) {
    use super::proto::LANES;
    for group in copies.chunks_exact_mut(LANES) {
        let views: [_; LANES] = std::array::from_fn(|k| group[k].end.views());
        let prints = super::proto::fingerprints(views.each_ref().map(|(r, b)| (&r[..], &b[..])));
        for (c, p) in group
            .iter_mut()
            .zip(prints.map(|p| p.map(Some)).unwrap_or_default())
        {
            c.fingerprint = p;
        }
    }
}

/// The writer thread's encoder of the per-step messages: `/sim/step`, and once the scene is
/// set up, `/scene` and `/scene/nodes` (each message's buffers reused from step to step).
struct StepWriter {
    channels: [u16; 8],
    /// The next sequence number of `/sim/step`, `/scene`, `/scene/nodes`.
    sequence: [u32; 3],
    encoder: super::proto::StepEncoder,
    buf: Vec<u8>,
    scene: Option<Scene>,
}

impl StepWriter {
    fn new(channels: [u16; 8], precision: super::proto::Precision) -> Self {
        Self {
            channels,
            sequence: [0; 3],
            encoder: super::proto::StepEncoder::new(precision),
            buf: Vec::with_capacity(1 << 14),
            scene: None,
        }
    }

    fn message(&mut self, w: &mut Writer, k: usize, time: u64) -> Result<(), ::mcap::McapError> {
        let slot = match k {
            STEP => 0,
            SCENE => 1,
            _ => 2,
        };
        let header = ::mcap::records::MessageHeader {
            channel_id: self.channels[k],
            sequence: self.sequence[slot],
            log_time: time,
            publish_time: time,
        };
        self.sequence[slot] = self.sequence[slot].wrapping_add(1);
        Ok(w.write_to_known_channel(&header, &self.buf)?)
    }

    fn write(&mut self, w: &mut Writer, c: &StepCopy) -> Result<(), ::mcap::McapError> {
        let s = &c.end;
        let (rods, bodies) = s.views();
        let fields = super::proto::StepFields {
            step: s.step,
            t: s.t,
            dt: s.dt,
            newton_iterations: s.newton_iterations,
            passes: s.passes,
            rods: &rods,
            bodies: &bodies,
            contacts: &s.contacts,
            fingerprint: c.fingerprint,
        };
        self.encoder.encode(&fields, &mut self.buf);
        self.message(w, STEP, c.time)?;
        let Some(mut scene) = self.scene.take() else {
            return Ok(());
        };
        scene.update(c.time, &rods, &bodies);
        self.buf.clear();
        scene.scene.wire(&mut self.buf);
        let sent = self.message(w, SCENE, c.time);
        self.buf.clear();
        scene.nodes.wire(&mut self.buf);
        self.scene = Some(scene);
        sent.and_then(|_| self.message(w, NODES, c.time))
    }
}

/// What `/scene` and `/scene/nodes` are drawn from (fixed at the first step), and the two
/// messages, refilled in place every step.
struct Scene {
    rods: Vec<RodInfo>,
    obstacles: Vec<Obstacle>,
    /// Free bodies: drawn at their pose every step, not with the fixed obstacles.
    bodies: Vec<BodySpec>,
    style: SceneStyle,
    /// Per free body (by obstacle index): its outline in its own frame, made at its first
    /// step.
    body_points: BTreeMap<usize, Vec<super::foxglove::Vector3>>,
    scene: super::foxglove::SceneUpdate,
    nodes: super::foxglove::PointCloud,
}

impl Scene {
    fn new(
        rods: Vec<RodInfo>,
        obstacles: Vec<Obstacle>,
        bodies: Vec<BodySpec>,
        style: SceneStyle,
    ) -> Self {
        Self {
            rods,
            obstacles,
            bodies,
            style,
            body_points: BTreeMap::new(),
            scene: Default::default(),
            nodes: Default::default(),
        }
    }

    /// The `/scene` message: one entity per rod and per free body (the obstacles are on
    /// `/scene/static`), and the `/scene/nodes` point cloud.
    fn update(&mut self, time: u64, rods: &[RodStepView<'_>], bodies: &[BodyView<'_>]) {
        let style = &self.style;
        let msg = &mut self.scene;
        msg.entities
            .resize_with(rods.len() + bodies.len(), Default::default);
        let (rod_entities, body_entities) = msg.entities.split_at_mut(rods.len());
        for (r, (e, v)) in rod_entities.iter_mut().zip(rods).enumerate() {
            rod_entity(e, &self.rods[r], style, r, v, time);
        }
        for (e, b) in body_entities.iter_mut().zip(bodies) {
            // The outline in the body's frame is the same every step (made once); the line's
            // pose places it.
            let points = self.body_points.entry(b.obstacle).or_insert_with(|| {
                body_points(&self.obstacles[b.obstacle], &self.bodies, b, style)
            });
            reset_entity(e, time, |id| {
                let _ = write!(id, "body/{}", b.name);
            });
            e.lines.resize_with(1, Default::default);
            let line = &mut e.lines[0];
            line_style(line, 2.0, rgb(BODY_COLOR));
            line.pose = Some(pose(b.position[0], b.position[1], b.angle));
            line.points.clone_from(points);
        }
        node_cloud(&mut self.nodes, &self.rods, style, rods, time);
    }
}

/// An owned copy of a step's event, for the writer thread; its vectors are reused.
#[derive(Default)]
struct StepCopy {
    /// The log time.
    time: u64,
    end: OwnedStepEnd,
    /// Its fingerprint, once worked out on the writer thread ([`fingerprint_steps`]).
    fingerprint: Option<u64>,
}

impl StepCopy {
    fn set(&mut self, ev: &Event<'_>, time: u64) {
        self.time = time;
        self.end.set(ev);
        self.fingerprint = None;
    }
}

impl Recording for McapSink {
    fn format(&self) -> &'static str {
        "mcap"
    }

    fn finish(&mut self) -> Result<Finished, RecordError> {
        if let Some(mut w) = self.writer.take() {
            w.metadata(self.run_end_record());
            self.closing = Some(w.close());
        }
        if let Some(c) = self.closing.take() {
            if let Err(e) = c.wait() {
                self.fail(e);
            }
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.settle(self.completed)
    }

    fn failure(&self) -> Option<std::sync::Arc<std::sync::atomic::AtomicBool>> {
        Some(self.failed.clone())
    }
}

const UNITS: [(&str, &str); 9] = [
    ("length", "m"),
    ("time", "s"),
    ("velocity", "m/s"),
    ("mass", "kg"),
    ("force", "N"),
    ("impulse", "N s"),
    ("stress", "Pa"),
    ("log_time", "ns"),
    ("angle", "rad"),
];

#[derive(Serialize)]
struct Meta<'a> {
    format_version: u32,
    gripsim_version: &'a str,
    scenario_name: &'a str,
    scenario_text: &'a str,
    mode: &'a str,
    detail: &'a str,
    /// `f32` or `f64`: the per-node numbers of `/sim/step` and `/sim/iteration` (format 4).
    precision: &'a str,
    /// `--detail auto`: every k-th step outside the windows, and the window (steps).
    #[serde(skip_serializing_if = "Option::is_none")]
    auto_every: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    auto_window: Option<u64>,
    flush_every: u64,
    clock: &'a str,
    units: BTreeMap<&'a str, &'a str>,
    rods: Vec<RodMeta<'a>>,
    obstacles: &'a [Obstacle],
}

#[derive(Serialize)]
struct RodMeta<'a> {
    name: &'a str,
    nodes: usize,
    mass: &'a [f64],
    clamped: &'a [bool],
    rest_length: &'a [f64],
    rest_curvature: &'a [f64],
    youngs_modulus: f64,
    area: f64,
    inertia: f64,
    half_height: f64,
    particle: bool,
}

impl<'a> From<&'a RodInfo> for RodMeta<'a> {
    fn from(r: &'a RodInfo) -> Self {
        Self {
            name: &r.name,
            nodes: r.nodes,
            mass: &r.mass,
            clamped: &r.clamped,
            rest_length: &r.rest_length,
            rest_curvature: &r.rest_curvature,
            youngs_modulus: r.youngs_modulus,
            area: r.area,
            inertia: r.inertia,
            half_height: r.half_height,
            particle: r.particle,
        }
    }
}

#[derive(Serialize)]
struct ContactMsg {
    change: &'static str,
    reason: Option<&'static str>,
    step: u64,
    t: f64,
    pass: u32,
    rod: usize,
    node: usize,
    obstacle: usize,
    normal: [f64; 2],
    gap: f64,
    reaction: [f64; 2],
    z: f64,
}

#[derive(Serialize, Default)]
struct EventMsg<'a> {
    kind: &'static str,
    step: u64,
    t: f64,
    message: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    old_dt: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    new_dt: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    dt: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rod: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    node: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    residual: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    completed: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<Option<&'a str>>,
}

// ---- foxglove.SceneUpdate ------------------------------------------------------------------
// Protobuf with Foxglove's published field names and numbers (super::foxglove). The scene is
// the xy plane (z = 0) in frame "world". Its numbers are rounded to f32 (what the 3D panel
// draws with; zstd then finds the zeroed low mantissa bits): the exact values are in /sim/step.
// Fields at their proto3 default (z = 0, an empty deletion list) are not on the wire.

use super::foxglove as fx;

const FRAME: &str = "world";

/// `x` rounded to f32.
fn r32(x: f64) -> f64 {
    x as f32 as f64
}

fn stamp(ns: u64) -> fx::Timestamp {
    fx::Timestamp {
        seconds: (ns / 1_000_000_000) as i64,
        nanos: (ns % 1_000_000_000) as i32,
    }
}

fn xy(x: f64, y: f64) -> fx::Vector3 {
    fx::Vector3 {
        x: r32(x),
        y: r32(y),
        z: 0.0,
    }
}

/// At (x, y), turned by `angle` about z (identity points along +x).
fn pose(x: f64, y: f64, angle: f64) -> fx::Pose {
    let (s, c) = (0.5 * angle).sin_cos();
    fx::Pose {
        position: Some(xy(x, y)),
        orientation: Some(fx::Quaternion {
            x: 0.0,
            y: 0.0,
            z: r32(s),
            w: r32(c),
        }),
    }
}

fn rgb(c: [u8; 3]) -> fx::Color {
    rgba(c, 1.0)
}

fn rgba(c: [u8; 3], a: f32) -> fx::Color {
    fx::Color {
        r: r32(c[0] as f64 / 255.0),
        g: r32(c[1] as f64 / 255.0),
        b: r32(c[2] as f64 / 255.0),
        a: a as f64,
    }
}

/// An arrow from (x, y) along `v`, drawn `length` long, with a head sized by `r`.
fn arrow(x: f64, y: f64, v: [f64; 2], length: f64, r: f64, color: fx::Color) -> fx::ArrowPrimitive {
    let head = (2.5 * r).min(0.4 * length);
    fx::ArrowPrimitive {
        pose: Some(pose(x, y, v[1].atan2(v[0]))),
        shaft_length: r32(length - head),
        shaft_diameter: r32(0.6 * r),
        head_length: r32(head),
        head_diameter: r32(1.8 * r),
        color: Some(color),
    }
}

/// A LINE_STRIP through `points`, `thickness_px` screen pixels wide.
fn strip(
    points: impl Iterator<Item = [f64; 2]>,
    thickness_px: f64,
    color: fx::Color,
) -> fx::LinePrimitive {
    fx::LinePrimitive {
        r#type: 0,
        pose: Some(pose(0.0, 0.0, 0.0)),
        thickness: thickness_px,
        scale_invariant: true,
        points: points.map(|p| xy(p[0], p[1])).collect(),
        color: Some(color),
        colors: Vec::new(),
        indices: Vec::new(),
    }
}

/// A white label at (x, y), facing the camera, 14 px high.
fn label(x: f64, y: f64, text: String) -> fx::TextPrimitive {
    fx::TextPrimitive {
        pose: Some(pose(x, y, 0.0)),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(rgb([255, 255, 255])),
        text,
    }
}

/// An entity with nothing in it yet, kept until replaced (lifetime 0).
fn entity(id: String, ns: u64) -> fx::SceneEntity {
    fx::SceneEntity {
        timestamp: Some(stamp(ns)),
        frame_id: FRAME.into(),
        id,
        lifetime: Some(fx::Duration::default()),
        frame_locked: false,
        ..Default::default()
    }
}

/// The obstacles as one entity of outlines (planes and sines clipped to the region the run
/// visits; free bodies are drawn at their pose every step) and the legend (force scale bar and
/// its text).
fn static_entities(
    obstacles: &[Obstacle],
    bodies: &[BodySpec],
    style: &SceneStyle,
    ns: u64,
) -> Vec<fx::SceneEntity> {
    let mut e = entity("obstacles".into(), ns);
    for (k, o) in obstacles.iter().enumerate() {
        if bodies.iter().any(|b| b.obstacle == k) {
            continue;
        }
        for line in obstacle_outline(o, style.lo, style.hi) {
            e.lines
                .push(strip(line.into_iter(), 2.0, rgb(OBSTACLE_COLOR)));
        }
    }
    let mut legend = entity("legend".into(), ns);
    let fs = &style.forces;
    let h = style.hi[1] - style.lo[1];
    let (x0, y0) = (
        0.5 * (style.lo[0] + style.hi[0]) - 0.5 * fs.unit_length,
        style.hi[1] + 0.07 * h,
    );
    let r = style.rods.first().map(|r| r.node_radius).unwrap_or(1e-3);
    legend.arrows.push(arrow(
        x0,
        y0,
        [1.0, 0.0],
        fs.unit_length,
        0.5 * r,
        rgb(REACTION_COLOR),
    ));
    legend.texts.push(label(x0, y0 + 0.03 * h, fs.describe()));
    vec![e, legend]
}

/// A free body's outline (with a spoke from its centre that shows the rotation) in its own
/// frame: centroid at the origin, unrotated.
fn body_points(
    shape: &Obstacle,
    specs: &[BodySpec],
    b: &BodyView<'_>,
    style: &SceneStyle,
) -> Vec<fx::Vector3> {
    let at_rest = BodyView {
        position: [0.0; 3],
        angle: 0.0,
        ..*b
    };
    super::body_outline(shape, specs, &at_rest, style)
        .into_iter()
        .map(|p| xy(p[0], p[1]))
        .collect()
}

/// An entity kept until replaced (lifetime 0), emptied for refilling: its id is written by
/// `id` the first time (a slot of the scene message always holds the same rod or body).
fn reset_entity(e: &mut fx::SceneEntity, ns: u64, id: impl FnOnce(&mut String)) {
    e.timestamp = Some(stamp(ns));
    if e.frame_id.is_empty() {
        e.frame_id.push_str(FRAME);
    }
    if e.id.is_empty() {
        id(&mut e.id);
    }
    e.lifetime = Some(fx::Duration::default());
    e.frame_locked = false;
    e.arrows.clear();
    e.spheres.clear();
}

/// A LINE_STRIP's style (its points are set by the caller).
fn line_style(line: &mut fx::LinePrimitive, thickness_px: f64, color: fx::Color) {
    line.r#type = 0;
    line.pose = Some(pose(0.0, 0.0, 0.0));
    line.thickness = thickness_px;
    line.scale_invariant = true;
    line.color = Some(color);
}

/// The `/scene/nodes` point cloud: every rod's nodes as packed f32 x, y, z (z = 0) and u8
/// red, green, blue, alpha (the node colours of the scene: driven nodes, or the reaction's
/// colour), 16 bytes per point, in frame `world`.
fn node_cloud(
    pc: &mut fx::PointCloud,
    infos: &[RodInfo],
    style: &SceneStyle,
    rods: &[RodStepView<'_>],
    ns: u64,
) {
    pc.timestamp = Some(stamp(ns));
    if pc.frame_id.is_empty() {
        pc.frame_id.push_str(FRAME);
    }
    pc.pose = Some(pose(0.0, 0.0, 0.0));
    pc.point_stride = fx::NODE_POINT_STRIDE;
    if pc.fields.is_empty() {
        pc.fields = fx::node_point_fields();
    }
    pc.data.clear();
    for (info, v) in infos.iter().zip(rods) {
        for i in 0..v.in_contact.len() {
            let color = if info.clamped.get(i).copied().unwrap_or(false) {
                DRIVEN_COLOR
            } else {
                style.forces.color(node_norm(v.reaction, i))
            };
            for x in [v.q[2 * i] as f32, v.q[2 * i + 1] as f32, 0.0] {
                pc.data.extend_from_slice(&x.to_le_bytes());
            }
            pc.data
                .extend_from_slice(&[color[0], color[1], color[2], 255]);
        }
    }
}

/// One rod, refilled in place: centre line, reactions (length by the recording's force scale,
/// from the node's edge) with their magnitudes as text, normals beside them, and the
/// predictor's positions on corrected steps. The nodes themselves are on `/scene/nodes`.
fn rod_entity(
    e: &mut fx::SceneEntity,
    info: &RodInfo,
    style: &SceneStyle,
    r: usize,
    v: &RodStepView<'_>,
    ns: u64,
) {
    let rs = &style.rods[r];
    reset_entity(e, ns, |id| {
        let _ = write!(id, "rod/{}", info.name);
    });
    let n = v.in_contact.len();
    let p = |i: usize| [v.q[2 * i], v.q[2 * i + 1]];
    e.lines.resize_with(1, Default::default);
    line_style(&mut e.lines[0], 2.0, rgb(ROD_COLOR));
    e.lines[0].points.clear();
    e.lines[0]
        .points
        .extend((0..n).map(|i| xy(p(i)[0], p(i)[1])));
    let rad = rs.node_radius;
    let corrected = v.q_predictor.len() == v.q.len() && v.q_predictor != v.q;
    let mut texts = 0;
    for i in 0..n {
        let [x, y] = p(i);
        let f = node_norm(v.reaction, i);
        if corrected {
            let (px, py) = (v.q_predictor[2 * i], v.q_predictor[2 * i + 1]);
            let d = r32(3.2 * rad);
            e.spheres.push(fx::SpherePrimitive {
                pose: Some(pose(px, py, 0.0)),
                size: Some(fx::Vector3 { x: d, y: d, z: d }),
                color: Some(rgba(PREDICTOR_COLOR, 0.45)),
            });
        }
        if v.in_contact[i] {
            let nrm = [v.normal[2 * i], v.normal[2 * i + 1]];
            let side = 2.2 * rad;
            e.arrows.push(arrow(
                x - side * nrm[1],
                y + side * nrm[0],
                nrm,
                rs.normal_length,
                0.4 * rad,
                rgb(NORMAL_COLOR),
            ));
        }
        if f > 0.0 {
            let dir = [v.reaction[2 * i] / f, v.reaction[2 * i + 1] / f];
            let len = style.forces.length(f);
            let (ox, oy) = (x + rad * dir[0], y + rad * dir[1]);
            e.arrows
                .push(arrow(ox, oy, dir, len, 0.9 * rad, rgb(REACTION_COLOR)));
            // The labels' strings are reused from step to step.
            if texts == e.texts.len() {
                e.texts.push(label(0.0, 0.0, String::new()));
            }
            let t = &mut e.texts[texts];
            t.pose = Some(pose(ox + len * dir[0], oy + len * dir[1], 0.0));
            t.text.clear();
            super::push_g(&mut t.text, f);
            t.text.push_str(" N");
            texts += 1;
        }
    }
    e.texts.truncate(texts);
}
