//! The Rerun sink: a `.rrd` recording that opens laid out (`rerun FILE.rrd`).
//!
//! Timelines: `step` (sequence), `sim_time` (simulated seconds; the load factor in static
//! runs) and `iteration` (a sequence advanced once per logged Newton iteration and once per
//! step, so every predictor and corrector iteration is its own point in time). There is no
//! wall-clock timeline, and the recording id is derived from the scenario, so two runs of one
//! scenario hold the same data.
//!
//! Entities (one per kind of thing, many instances each):
//!
//! | entity | archetype | what |
//! |---|---|---|
//! | `scene` | Transform3D (static) | flips y so the scene is drawn y-up |
//! | `scene/obstacles` | LineStrips2D (static) | obstacle outlines |
//! | `scene/<rod>/nodes` | Points2D | nodes, blue (free) to red (large reaction); grey = driven |
//! | `scene/<rod>/centerline` | LineStrips2D | the rod |
//! | `scene/<rod>/normals` | Arrows2D | outward obstacle normals at constrained nodes |
//! | `scene/<rod>/reactions` | Arrows2D | eq. 2 reactions, length f/(f+W) (W = rod weight), labels in N |
//! | `scene/<rod>/predictor` | Points2D | predictor positions, on steps with corrector passes |
//! | `scene/<rod>/iterate` | LineStrips2D | each Newton iterate (`--detail iteration`) |
//! | `plots/reaction/<rod>/node_<i>` | Scalars | \|reaction\| (N) |
//! | `plots/impulse/<rod>/node_<i>` | Scalars | \|impulse\| (N s) |
//! | `plots/bending_stress/<rod>/node_<i>` | Scalars | bending stress (Pa) |
//! | `solver/residual`, `solver/update` | Scalars | per Newton iteration (`--detail iteration`) |
//! | `solver/newton_iterations`, `solver/corrector_passes`, `solver/dt` | Scalars | per step |
//! | `events` | TextLog | contacts added/released, dt changes, Newton failures, warnings, run end |
//!
//! Scene entities are logged row by row; the many scalar series are buffered and sent as
//! columns at every flush (every `flush_every` steps), which is much cheaper.

use super::{
    node_norm, Detail, Finished, OutputFile, RecordError, RecordOptions, Recording, RodStyle,
    SceneStyle, DRIVEN_COLOR, NORMAL_COLOR, OBSTACLE_COLOR, ROD_COLOR,
};
use crate::events::{
    BodyView, ContactChange, ContactView, Event, Observer, ReleaseReason, RodInfo, RodStepView,
};
use crate::obstacle::Obstacle;
use crate::scenario::Scenario;
use ::rerun::blueprint::components::PanelState;
use ::rerun::blueprint::{
    Blueprint, BlueprintPanel, ContainerLike, Horizontal, SelectionPanel, Spatial2DView, Tabs,
    TextLogView, TimePanel, TimeSeriesView, Vertical,
};
use ::rerun::log::ChunkBatcherConfig;
use ::rerun::{
    Arrows2D, AsComponents, Color, EntityPath, EntityPathPart, LineStrips2D, Points2D, Radius,
    RecordingStream, RecordingStreamBuilder, Scalars, TextLog, TimeColumn, Transform3D,
};
use std::path::Path;

/// Application id of the recordings.
pub const APPLICATION_ID: &str = "gripsim";

/// Writes a Rerun `.rrd` file.
pub struct RerunSink {
    out: OutputFile,
    rec: Option<RecordingStream>,
    opts: RecordOptions,
    rods: Vec<RodEntities>,
    obstacles: Vec<Obstacle>,
    bodies: Vec<crate::world::body::BodySpec>,
    style: Option<SceneStyle>,
    /// The `iteration` timeline's next value.
    iteration: i64,
    per_step: Series,
    per_iteration: Series,
    completed: bool,
    error: Option<RecordError>,
    /// Set with `error`, for [`Recording::failure`].
    failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
    /// The file the stream writes to.
    file: RrdFile,
}

/// Entity paths of one rod, and what its transient entities showed at the last step.
pub struct RodEntities {
    info: RodInfo,
    nodes: EntityPath,
    centerline: EntityPath,
    normals: EntityPath,
    reactions: EntityPath,
    predictor: EntityPath,
    iterate: EntityPath,
    had_contacts: bool,
    had_predictor: bool,
}

/// How a rod is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Look {
    /// A run as recorded: nodes coloured by reaction, centre line, normals, reactions and the
    /// predictor's positions.
    Live,
    /// A second run drawn for comparison (`replay diff --rrd`): grey, translucent nodes and
    /// centre line only, under the live run.
    Ghost,
}

/// Scalar time series that share their time points, buffered until the next flush.
#[derive(Default)]
struct Series {
    step: Vec<i64>,
    sim_time: Vec<f64>,
    iteration: Vec<i64>,
    paths: Vec<EntityPath>,
    values: Vec<Vec<f64>>,
}

impl Series {
    fn add(&mut self, path: EntityPath) -> usize {
        self.paths.push(path);
        self.values.push(Vec::new());
        self.paths.len() - 1
    }

    fn at(&mut self, step: u64, t: f64, iteration: i64) {
        self.step.push(step as i64);
        self.sim_time.push(t);
        self.iteration.push(iteration);
    }

    fn send(&mut self, rec: &RecordingStream) -> ::rerun::RecordingStreamResult<()> {
        if self.step.is_empty() {
            return Ok(());
        }
        for (path, values) in self.paths.iter().zip(&mut self.values) {
            let times = [
                TimeColumn::new_sequence("step", self.step.iter().copied()),
                TimeColumn::new_duration_secs("sim_time", self.sim_time.iter().copied()),
                TimeColumn::new_sequence("iteration", self.iteration.iter().copied()),
            ];
            let columns = Scalars::new(values.drain(..)).columns_of_unit_batches()?;
            rec.send_columns(path.clone(), times, columns)?;
        }
        self.step.clear();
        self.sim_time.clear();
        self.iteration.clear();
        Ok(())
    }
}

fn path(parts: &[&str]) -> EntityPath {
    EntityPath::new(parts.iter().map(|p| EntityPathPart::new(*p)).collect())
}

/// The layout the file opens with: the scene on the left; reaction forces, solver plots and
/// the event log on the right.
pub fn blueprint() -> Blueprint {
    blueprint_with(Vec::new())
}

/// [`blueprint`] with `extra` views as the first tabs of the plot tabs (replay overlays add
/// their difference plots there).
pub fn blueprint_with(extra: Vec<ContainerLike>) -> Blueprint {
    let scene = Spatial2DView::new("Scene")
        .with_origin("/")
        .with_contents(["+ /scene/**"]);
    let reactions = TimeSeriesView::new("Reaction force |R| (N)").with_origin("/plots/reaction");
    let solver = Tabs::new(
        extra.into_iter().chain([
            TimeSeriesView::new("Solver: residual (N) and Newton iterations")
                .with_origin("/solver")
                .with_contents(["+ /solver/**", "- /solver/dt", "- /solver/update"])
                .into(),
            TimeSeriesView::new("Step size dt (s)")
                .with_origin("/solver/dt")
                .into(),
            TimeSeriesView::new("Contact impulse (N s)")
                .with_origin("/plots/impulse")
                .into(),
            TimeSeriesView::new("Bending stress (Pa)")
                .with_origin("/plots/bending_stress")
                .into(),
        ]),
    );
    let events = TextLogView::new("Events").with_origin("/events");
    Blueprint::new(
        Horizontal::new([
            scene.into(),
            Vertical::new([reactions.into(), solver.into(), events.into()])
                .with_row_shares([0.4, 0.35, 0.25])
                .into(),
        ])
        .with_column_shares([0.55, 0.45]),
    )
    // Side panels folded away so the views get the window; the time panel shows its
    // playback bar only.
    .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Collapsed))
    .with_selection_panel(SelectionPanel::new().with_state(PanelState::Collapsed))
    .with_time_panel(
        TimePanel::new()
            .with_timeline("sim_time")
            .with_state(PanelState::Collapsed),
    )
}

impl RerunSink {
    /// Create `path` (as its `.partial` sibling until the run completes) for a run of
    /// `scenario`.
    pub fn create(
        path: &Path,
        opts: RecordOptions,
        scenario: &Scenario,
    ) -> Result<Self, RecordError> {
        Self::create_named(path, opts, &scenario.name, &scenario.text, blueprint())
    }

    /// Create `path` for a run of the scenario named `name` with TOML `text` (the recording id
    /// derives from both), laid out by `blueprint`. `gripsim replay` drives the sink from a
    /// stored run this way.
    pub fn create_named(
        path: &Path,
        opts: RecordOptions,
        name: &str,
        text: &str,
        blueprint: Blueprint,
    ) -> Result<Self, RecordError> {
        let out = OutputFile::new(path);
        // Creates the directory and removes an older final file (a device is only opened);
        // the SDK opens the file.
        drop(out.create()?);
        let id = format!("{}-{:016x}", name, super::stable_hash(text.as_bytes()));
        // Chunks close only when we flush (or at 2 MiB), never on a timer.
        let batching = ChunkBatcherConfig {
            flush_tick: std::time::Duration::MAX,
            ..ChunkBatcherConfig::DEFAULT
        };
        let file = RrdFile::create(out.writing())?;
        let rec = RecordingStreamBuilder::new(APPLICATION_ID)
            .recording_id(id)
            .enabled(true)
            .batcher_config(batching)
            .with_blueprint(blueprint)
            .buffered()
            .map_err(|e| RecordError::write(out.writing(), e))?;
        // What was buffered (the store info, the blueprint) goes to the file first.
        rec.set_sink(Box::new(file.clone()));
        rec.set_log_time_enabled(false);
        rec.set_log_tick_enabled(false);
        // The name only: the builder's recording properties would carry the wall-clock start.
        rec.send_recording_name(name.to_string())
            .map_err(|e| RecordError::write(out.writing(), e))?;
        Ok(Self {
            out,
            rec: Some(rec),
            opts: RecordOptions {
                flush_every: opts.flush_every.max(1),
                ..opts
            },
            rods: Vec::new(),
            obstacles: Vec::new(),
            bodies: Vec::new(),
            style: None,
            iteration: 0,
            per_step: Series::default(),
            per_iteration: Series::default(),
            completed: false,
            error: None,
            failed: Default::default(),
            file,
        })
    }

    /// The recording stream (None once finished), for replay overlays that log their own
    /// entities at the times the sink has set.
    pub fn stream(&self) -> Option<&RecordingStream> {
        self.rec.as_ref()
    }

    fn fail(&mut self, e: impl std::fmt::Display) {
        if self.error.is_none() {
            self.error = Some(RecordError::write(self.out.writing(), e));
        }
        self.failed
            .store(true, std::sync::atomic::Ordering::Relaxed);
    }

    fn check(&mut self, r: ::rerun::RecordingStreamResult<()>) {
        if let Err(e) = r {
            self.fail(e);
        }
    }

    fn set_time(&self, rec: &RecordingStream, step: u64, t: f64, iteration: i64) {
        rec.set_time_sequence("step", step as i64);
        rec.set_duration_secs("sim_time", t.max(0.0));
        rec.set_time_sequence("iteration", iteration);
    }

    fn log(&mut self, path: &EntityPath, what: &dyn AsComponents) {
        if let Some(rec) = &self.rec {
            let r = rec.log(path.clone(), what);
            self.check(r);
        }
    }

    fn text(&mut self, step: u64, t: f64, level: &str, text: String) {
        let Some(rec) = self.rec.clone() else {
            return;
        };
        self.set_time(&rec, step, t, self.iteration);
        let r = rec.log("events", &TextLog::new(text).with_level(level));
        self.check(r);
    }

    fn run_start(&mut self, info: &crate::events::RunInfo<'_>) {
        self.obstacles = info.obstacles.to_vec();
        self.bodies = info.bodies.to_vec();
        for r in info.rods {
            self.rods.push(RodEntities::new(&["scene"], r.clone()));
        }
        for kind in ["reaction", "impulse", "bending_stress"] {
            for r in info.rods {
                for i in 0..r.nodes {
                    self.per_step
                        .add(path(&["plots", kind, &r.name, &format!("node_{i}")]));
                }
            }
        }
        for s in ["newton_iterations", "corrector_passes", "dt"] {
            self.per_step.add(path(&["solver", s]));
        }
        for s in ["residual", "update"] {
            self.per_iteration.add(path(&["solver", s]));
        }
        self.text(
            0,
            0.0,
            TextLogLevelName::INFO,
            format!(
                "run of {:?}: {} rod(s), {} obstacle(s), {} mode, detail {}",
                info.scenario_name,
                info.rods.len(),
                info.obstacles.len(),
                format!("{:?}", info.mode).to_lowercase(),
                self.opts.detail.as_str()
            ),
        );
    }

    /// Static data once the first state is known: the y-up flip and the obstacle outlines.
    fn first_step(&mut self, rods: &[RodStepView<'_>]) {
        let infos: Vec<RodInfo> = self.rods.iter().map(|r| r.info.clone()).collect();
        let style = SceneStyle::new(&infos, rods, &self.obstacles);
        if let Some(rec) = &self.rec {
            let outlines: Vec<Vec<[f32; 2]>> = self
                .obstacles
                .iter()
                .enumerate()
                .filter(|(k, _)| !self.bodies.iter().any(|b| b.obstacle == *k))
                .map(|(_, o)| {
                    o.outline(style.lo, style.hi)
                        .into_iter()
                        .map(|p| [p[0] as f32, p[1] as f32])
                        .collect()
                })
                .collect();
            let r = rec
                .log_static("scene", &Transform3D::from_scale((1.0, -1.0, 1.0)))
                .and_then(|_| {
                    rec.log_static(
                        "scene/obstacles",
                        &LineStrips2D::new(outlines)
                            .with_colors([rgb(OBSTACLE_COLOR)])
                            .with_radii([Radius::new_ui_points(1.5)])
                            .with_draw_order(DRAW_OBSTACLES),
                    )
                });
            self.check(r);
        }
        self.style = Some(style);
    }

    fn step_end(
        &mut self,
        step: u64,
        t: f64,
        dt: f64,
        iterations: u32,
        passes: u32,
        rods: &[RodStepView<'_>],
    ) {
        if self.style.is_none() {
            self.first_step(rods);
        }
        let Some(rec) = self.rec.clone() else {
            return;
        };
        let it = self.iteration;
        self.iteration += 1;
        self.set_time(&rec, step, t, it);
        for (r, v) in rods.iter().enumerate() {
            let style = self.style.as_ref().expect("set above").rods[r];
            self.draw_rod(r, &style, v, passes > 0);
        }
        // Scalars: per rod and node, then the solver's.
        self.per_step.at(step, t, it);
        let mut k = 0;
        for pick in [0, 1, 2] {
            for v in rods {
                for i in 0..v.in_contact.len() {
                    let x = match pick {
                        0 => node_norm(v.reaction, i),
                        1 => node_norm(v.impulse, i),
                        _ => v.bending_stress[i],
                    };
                    self.per_step.values[k].push(x);
                    k += 1;
                }
            }
        }
        for x in [iterations as f64, passes as f64, dt] {
            self.per_step.values[k].push(x);
            k += 1;
        }
        if step.is_multiple_of(self.opts.flush_every) {
            self.flush(&rec);
        }
    }

    /// The free bodies at their pose (with a spoke that shows the rotation), the friction
    /// force at every contact (yellow arrows, 1 body radius per body weight), and the grasp
    /// plots: each prong's grip force (Σ normal force on the body) and the safety margin
    /// μ_s Σ N / (m g).
    fn draw_bodies(&mut self, bodies: &[BodyView<'_>], contacts: &[ContactView]) {
        let (Some(rec), Some(style)) = (self.rec.clone(), self.style.as_ref()) else {
            return;
        };
        let strips: Vec<Vec<[f32; 2]>> = bodies
            .iter()
            .map(|b| {
                super::body_outline(&self.obstacles[b.obstacle], &self.bodies, b, style)
                    .into_iter()
                    .map(|p| [p[0] as f32, p[1] as f32])
                    .collect()
            })
            .collect();
        let mut r = rec.log(
            "scene/bodies",
            &LineStrips2D::new(strips)
                .with_colors([rgb(super::BODY_COLOR)])
                .with_radii([Radius::new_ui_points(2.0)])
                .with_draw_order(DRAW_OBSTACLES + 1.0),
        );
        let fruit = &self.bodies[0];
        let scale = fruit.radius / fruit.weight[0].hypot(fruit.weight[1]).max(1e-300);
        let (mut origins, mut vectors) = (Vec::new(), Vec::new());
        for c in contacts.iter().filter(|c| c.friction_force != 0.0) {
            let t = [-c.normal[1], c.normal[0]];
            origins.push([c.point[0] as f32, c.point[1] as f32]);
            vectors.push([
                (c.friction_force * t[0] * scale) as f32,
                (c.friction_force * t[1] * scale) as f32,
            ]);
        }
        r = r.and_then(|_| {
            rec.log(
                "scene/friction",
                &Arrows2D::from_vectors(vectors)
                    .with_origins(origins)
                    .with_colors([rgb(super::FRICTION_COLOR)])
                    .with_draw_order(DRAW_OBSTACLES + 2.0),
            )
        });
        let mut per_rod = vec![0.0f64; self.rods.len()];
        let mut mu_n = 0.0;
        let nrods = per_rod.len();
        for c in contacts.iter().filter(|c| c.rod < nrods && c.body == 0) {
            per_rod[c.rod] += c.normal_force.max(0.0);
            mu_n += c.mu_s * c.normal_force.max(0.0);
        }
        for (k, f) in per_rod.iter().enumerate() {
            let name = self.rods[k].info.name.clone();
            r = r.and_then(|_| {
                rec.log(
                    path(&["plots", "grasp", "grip_force", &name]),
                    &Scalars::single(*f),
                )
            });
        }
        let w = fruit.weight[0].hypot(fruit.weight[1]);
        if w > 0.0 {
            r = r.and_then(|_| rec.log("plots/grasp/safety_margin", &Scalars::single(mu_n / w)));
        }
        for b in bodies {
            r = r.and_then(|_| {
                rec.log(
                    path(&["plots", "fruit", b.name, "height"]),
                    &Scalars::single(b.position[1]),
                )
            });
        }
        self.check(r);
    }

    fn draw_rod(&mut self, r: usize, style: &RodStyle, v: &RodStepView<'_>, corrected: bool) {
        let Some(rec) = self.rec.clone() else {
            return;
        };
        let res = self.rods[r].draw(&rec, style, v, corrected, Look::Live);
        self.check(res);
    }

    fn iteration(&mut self, ev: IterationEvent<'_>) {
        let Some(rec) = self.rec.clone() else {
            return;
        };
        let it = self.iteration;
        self.iteration += 1;
        self.set_time(&rec, ev.step, ev.t, it);
        self.per_iteration.at(ev.step, ev.t, it);
        self.per_iteration.values[0].push(ev.residual);
        self.per_iteration.values[1].push(ev.update);
        if let Some(e) = self.rods.get(ev.rod) {
            let iterate = e.iterate.clone();
            let strip: Vec<[f32; 2]> =
                ev.q.chunks_exact(2)
                    .map(|c| [c[0] as f32, c[1] as f32])
                    .collect();
            self.log(
                &iterate,
                &LineStrips2D::new([strip])
                    .with_colors([Color::from_unmultiplied_rgba(120, 200, 255, 160)])
                    .with_radii([Radius::new_ui_points(1.0)])
                    .with_draw_order(DRAW_GHOSTS),
            );
        }
    }

    fn contact(&mut self, c: &ContactChange, released: Option<ReleaseReason>) {
        let rod = self.rod_name(c.rod);
        let text = match released {
            None => format!(
                "step {}: constraint added: rod {rod:?} node {} on obstacle {} (pass {}), normal ({:.6}, {:.6}), gap {:.3e} m, z {:.3e} m/s",
                c.step, c.node, c.obstacle, c.pass, c.normal[0], c.normal[1], c.gap, c.z
            ),
            Some(ReleaseReason::Adhesive) => format!(
                "step {}: constraint released (adhesive reaction, R = ({:.4}, {:.4}) N): rod {rod:?} node {} from obstacle {} (pass {}), normal ({:.6}, {:.6}), gap {:.3e} m",
                c.step, c.reaction[0], c.reaction[1], c.node, c.obstacle, c.pass, c.normal[0], c.normal[1], c.gap
            ),
        };
        self.text(c.step, c.t, TextLogLevelName::INFO, text);
    }

    fn rod_name(&self, r: usize) -> String {
        self.rods
            .get(r)
            .map(|e| e.info.name.clone())
            .unwrap_or_else(|| r.to_string())
    }

    /// Send the buffered series and make the file readable up to here. The wait for the
    /// SDK's writer thread is bounded: a writer that died (disk full) or hangs fails the
    /// recording instead of the run waiting forever.
    fn flush(&mut self, rec: &RecordingStream) {
        let r = self
            .per_step
            .send(rec)
            .and_then(|_| self.per_iteration.send(rec));
        self.check(r);
        if let Err(e) = rec.flush_with_timeout(WRITER_TIMEOUT) {
            let e = match e {
                ::rerun::sink::SinkFlushError::Timeout => format!(
                    "the .rrd writer did not answer within {} s (is the disk hanging?)",
                    WRITER_TIMEOUT.as_secs()
                ),
                e => e.to_string(),
            };
            self.fail(e);
        }
    }
}

/// How long the sink waits for the SDK's writer thread to flush or close the file.
const WRITER_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);

/// End the stream (dropping the last handle makes the SDK send what it still holds to the
/// sink), on a helper thread so that a pipeline that never returns costs at most
/// [`WRITER_TIMEOUT`], then an error.
fn close_stream(rec: RecordingStream) -> Result<(), String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let spawned = std::thread::Builder::new()
        .name("rrd-close".into())
        .spawn(move || {
            drop(rec);
            let _ = tx.send(());
        });
    if spawned.is_err() {
        return Err("cannot start a thread to close the file".into());
    }
    rx.recv_timeout(WRITER_TIMEOUT).map_err(|_| {
        format!(
            "the .rrd writer did not close the file within {} s (is the disk hanging?)",
            WRITER_TIMEOUT.as_secs()
        )
    })
}

/// Most chunks whose index (the `.rrd` footer) is kept: about 4 kB of memory each, so at most
/// ~32 MB. The SDK builds the footer in memory for the whole run (a dense table of every
/// chunk by every column), which made a long run's memory grow like its file (442 MB at
/// 300 000 steps of the seed grasp). A run that logs more chunks drops the index at that
/// point, freeing it: its `.rrd` is the same stream without a footer (`rerun rrd
/// stats/print` and the viewer read it; `rerun rrd verify` asks for the footer, which
/// `rerun rrd optimize` adds).
pub const FOOTER_CHUNKS: u64 = 8192;

/// The `.rrd` file: the SDK's encoder writing straight to the file on the stream's own
/// thread (no further queue), a write error kept and reported at the next flush, and the
/// footer index bounded by [`FOOTER_CHUNKS`]. Shared between the stream (as its sink) and
/// the [`RerunSink`], which ends the file itself once the stream is closed.
#[derive(Clone)]
struct RrdFile {
    state: std::sync::Arc<std::sync::Mutex<RrdState>>,
}

struct RrdState {
    encoder: Option<Encoder<std::io::BufWriter<std::fs::File>>>,
    chunks: u64,
    footer: bool,
    error: Option<String>,
}

type Encoder<W> = ::rerun::external::re_log_encoding::Encoder<W>;

impl RrdFile {
    fn create(path: &Path) -> Result<Self, RecordError> {
        use ::rerun::external::re_log_encoding::{CrateVersion, EncodingOptions};
        // Opened without truncating anything but a regular file (OutputFile::create has made
        // the partial file, or checked the device).
        let file = std::fs::OpenOptions::new()
            .write(true)
            .truncate(std::fs::metadata(path).is_ok_and(|m| m.is_file()))
            .open(path)
            .map_err(|source| RecordError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let encoder = Encoder::new_eager(
            CrateVersion::LOCAL,
            EncodingOptions::PROTOBUF_COMPRESSED,
            std::io::BufWriter::with_capacity(1 << 16, file),
        )
        .map_err(|e| RecordError::write(path, e))?;
        Ok(Self {
            state: std::sync::Arc::new(std::sync::Mutex::new(RrdState {
                encoder: Some(encoder),
                chunks: 0,
                footer: true,
                error: None,
            })),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, RrdState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Write the end of the stream (and the footer, when it was kept) and close the file.
    fn finish(&self) -> Result<(), String> {
        let mut s = self.lock();
        if let Some(e) = s.error.take() {
            return Err(e);
        }
        let Some(mut enc) = s.encoder.take() else {
            return Ok(());
        };
        enc.finish()
            .map_err(|e| super::error_chain(&e))
            .and_then(|_| enc.into_inner().map_err(|e| super::error_chain(&e)))
            .and_then(|w| w.into_inner().map_err(|e| super::error_chain(e.error())))
            .map(drop)
    }
}

impl RrdState {
    fn fail(&mut self, e: String) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        // Nothing more is written (not even the end of the stream).
        if let Some(enc) = self.encoder.take() {
            let _ = enc.into_inner();
        }
    }
}

impl ::rerun::sink::LogSink for RrdFile {
    fn send(&self, msg: ::rerun::external::re_log_types::LogMsg) {
        let mut s = self.lock();
        let Some(enc) = s.encoder.as_mut() else {
            return;
        };
        if let Err(e) = enc.append(&msg) {
            return s.fail(super::error_chain(&e));
        }
        if matches!(msg, ::rerun::external::re_log_types::LogMsg::ArrowMsg(..)) {
            s.chunks += 1;
            if s.footer && s.chunks > FOOTER_CHUNKS {
                if let Some(enc) = s.encoder.as_mut() {
                    enc.do_not_emit_footer();
                }
                s.footer = false;
            }
        }
    }

    fn flush_blocking(
        &self,
        _timeout: std::time::Duration,
    ) -> Result<(), ::rerun::sink::SinkFlushError> {
        let mut s = self.lock();
        if let Some(enc) = s.encoder.as_mut() {
            if let Err(e) = enc.flush_blocking() {
                s.fail(super::error_chain(&e));
            }
        }
        match &s.error {
            Some(e) => Err(::rerun::sink::SinkFlushError::Failed { message: e.clone() }),
            None => Ok(()),
        }
    }
}

impl RodEntities {
    /// The entities of rod `info` under `root`: `root/<rod>/nodes`, `…/centerline`,
    /// `…/normals`, `…/reactions`, `…/predictor`, `…/iterate` (a live run uses `["scene"]`).
    pub fn new(root: &[&str], info: RodInfo) -> Self {
        let rod = |kind: &str| {
            let mut parts: Vec<&str> = root.to_vec();
            parts.extend([info.name.as_str(), kind]);
            path(&parts)
        };
        Self {
            nodes: rod("nodes"),
            centerline: rod("centerline"),
            normals: rod("normals"),
            reactions: rod("reactions"),
            predictor: rod("predictor"),
            iterate: rod("iterate"),
            had_contacts: true,
            had_predictor: true,
            info,
        }
    }

    /// Log the rod's state `v` at the stream's current time. `corrected`: a corrector pass
    /// moved the rod this step (its predictor positions are shown).
    pub fn draw(
        &mut self,
        rec: &RecordingStream,
        style: &RodStyle,
        v: &RodStepView<'_>,
        corrected: bool,
        look: Look,
    ) -> ::rerun::RecordingStreamResult<()> {
        let n = v.in_contact.len();
        let p = |i: usize| [v.q[2 * i] as f32, v.q[2 * i + 1] as f32];
        let radius = style.node_radius as f32;
        let points: Vec<[f32; 2]> = (0..n).map(p).collect();
        if look == Look::Ghost {
            // Opaque light grey: translucent points render dark in some viewers.
            rec.log(
                self.nodes.clone(),
                &Points2D::new(points.iter().copied())
                    .with_radii([0.8 * radius])
                    .with_colors([rgb(GHOST_COLOR)])
                    .with_draw_order(DRAW_GHOSTS),
            )?;
            return rec.log(
                self.centerline.clone(),
                &LineStrips2D::new([points])
                    .with_colors([rgb(GHOST_COLOR)])
                    .with_radii([Radius::new_ui_points(1.5)])
                    .with_draw_order(DRAW_GHOSTS),
            );
        }
        let colors: Vec<Color> = (0..n)
            .map(|i| {
                if self.info.clamped.get(i).copied().unwrap_or(false) {
                    rgb(DRIVEN_COLOR)
                } else {
                    rgb(RodStyle::heat(style.level(node_norm(v.reaction, i))))
                }
            })
            .collect();
        rec.log(
            self.nodes.clone(),
            &Points2D::new(points.iter().copied())
                .with_radii([radius])
                .with_colors(colors)
                .with_draw_order(DRAW_NODES),
        )?;
        rec.log(
            self.centerline.clone(),
            &LineStrips2D::new([points])
                .with_colors([rgb(ROD_COLOR)])
                .with_radii([Radius::new_ui_points(1.5)])
                .with_draw_order(DRAW_ROD),
        )?;

        // Normals and reactions at constrained nodes; logged empty once when contact ends.
        let contacts: Vec<usize> = (0..n).filter(|&i| v.in_contact[i]).collect();
        if !contacts.is_empty() || self.had_contacts {
            let origins: Vec<[f32; 2]> = contacts.iter().map(|&i| p(i)).collect();
            let nl = style.normal_length;
            let nvec = contacts.iter().map(|&i| {
                [
                    (nl * v.normal[2 * i]) as f32,
                    (nl * v.normal[2 * i + 1]) as f32,
                ]
            });
            rec.log(
                self.normals.clone(),
                &Arrows2D::from_vectors(nvec)
                    .with_origins(origins.iter().copied())
                    .with_colors([rgb(NORMAL_COLOR)])
                    .with_radii([0.25 * radius])
                    .with_draw_order(DRAW_NORMALS),
            )?;
            let mut rvec = Vec::with_capacity(contacts.len());
            let mut labels = Vec::with_capacity(contacts.len());
            for &i in &contacts {
                let f = node_norm(v.reaction, i);
                let s = if f > 0.0 {
                    style.reaction_length * style.level(f) / f
                } else {
                    0.0
                };
                rvec.push([
                    (s * v.reaction[2 * i]) as f32,
                    (s * v.reaction[2 * i + 1]) as f32,
                ]);
                labels.push(format!("{f:.3} N"));
            }
            rec.log(
                self.reactions.clone(),
                &Arrows2D::from_vectors(rvec)
                    .with_origins(origins)
                    .with_labels(labels)
                    .with_colors([rgb(RodStyle::heat(1.0))])
                    .with_radii([0.5 * radius])
                    .with_draw_order(DRAW_REACTIONS),
            )?;
        }
        self.had_contacts = !contacts.is_empty();

        // The predictor's positions where a corrector pass moved the rod.
        if corrected || self.had_predictor {
            let ghost: Vec<[f32; 2]> = if corrected {
                v.q_predictor
                    .chunks_exact(2)
                    .map(|c| [c[0] as f32, c[1] as f32])
                    .collect()
            } else {
                Vec::new()
            };
            rec.log(
                self.predictor.clone(),
                &Points2D::new(ghost)
                    .with_radii([0.8 * radius])
                    .with_colors([Color::from_unmultiplied_rgba(150, 150, 150, 110)])
                    .with_draw_order(DRAW_GHOSTS),
            )?;
        }
        self.had_predictor = corrected;
        Ok(())
    }
}

// Draw order in the 2D view (higher on top): a normal shares its direction with the
// node's reaction, so the thin normal is drawn over the thick reaction arrow.
const DRAW_OBSTACLES: f32 = 5.0;
/// Colour of a second run drawn for comparison ([`Look::Ghost`]).
const GHOST_COLOR: [u8; 3] = [185, 190, 200];
const DRAW_GHOSTS: f32 = 10.0;
const DRAW_ROD: f32 = 20.0;
const DRAW_REACTIONS: f32 = 30.0;
const DRAW_NORMALS: f32 = 35.0;
const DRAW_NODES: f32 = 40.0;

/// Text log levels.
struct TextLogLevelName;

impl TextLogLevelName {
    const INFO: &'static str = "INFO";
    const WARN: &'static str = "WARN";
    const ERROR: &'static str = "ERROR";
}

fn rgb(c: [u8; 3]) -> Color {
    Color::from_rgb(c[0], c[1], c[2])
}

/// The fields of [`Event::Iteration`] that the recording uses.
struct IterationEvent<'a> {
    step: u64,
    t: f64,
    rod: usize,
    residual: f64,
    update: f64,
    q: &'a [f64],
}

impl Observer for RerunSink {
    fn wants_iterations(&self) -> bool {
        self.opts.detail == Detail::Iteration
    }

    fn on_event(&mut self, event: &Event<'_>) {
        if self.rec.is_none() {
            return;
        }
        match *event {
            Event::RunStart(info) => self.run_start(info),
            Event::StepBegin { .. } => {}
            Event::Iteration {
                step,
                t,
                rod,
                residual,
                update,
                q,
                ..
            } => {
                if self.opts.detail == Detail::Iteration {
                    self.iteration(IterationEvent {
                        step,
                        t,
                        rod,
                        residual,
                        update,
                        q,
                    });
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
            } => self.text(
                step,
                t,
                TextLogLevelName::INFO,
                format!("step {step}: dt {old:e} s -> {new:e} s ({reason})"),
            ),
            Event::NewtonFailed {
                step,
                t,
                dt,
                rod,
                node,
                residual,
                reason,
            } => {
                let name = self.rod_name(rod);
                self.text(
                    step,
                    t,
                    TextLogLevelName::WARN,
                    format!("step {step}: Newton failed on rod {name:?} node {node} with dt = {dt:e} s: {reason} (residual {residual:.3e} N)"),
                )
            }
            Event::Warning { step, t, message } => {
                self.text(step, t, TextLogLevelName::WARN, message.to_string())
            }
            Event::FrictionChanged(_)
            | Event::BodyContactChanged { .. }
            | Event::PhaseChanged { .. } => {
                if let Some((step, t, text)) = event.describe() {
                    self.text(step, t, TextLogLevelName::INFO, text)
                }
            }
            Event::StepEnd {
                step,
                t,
                dt,
                newton_iterations,
                passes,
                rods,
                bodies,
                contacts,
            } => {
                self.step_end(step, t, dt, newton_iterations, passes, rods);
                if !bodies.is_empty() {
                    self.draw_bodies(bodies, contacts);
                }
            }
            Event::RunEnd { steps, t, error } => {
                self.completed = error.is_none();
                match error {
                    None => self.text(
                        steps,
                        t,
                        TextLogLevelName::INFO,
                        format!("run completed: {steps} steps, t = {t} s"),
                    ),
                    Some(e) => self.text(
                        steps,
                        t,
                        TextLogLevelName::ERROR,
                        format!("run stopped after {steps} steps: {e}"),
                    ),
                }
            }
        }
    }
}

impl Recording for RerunSink {
    fn format(&self) -> &'static str {
        "rerun"
    }

    fn finish(&mut self) -> Result<Finished, RecordError> {
        if let Some(rec) = self.rec.take() {
            if self.error.is_none() {
                self.flush(&rec);
            }
            // The stream sends what it still holds, then the file is ended here.
            match close_stream(rec) {
                Ok(()) => {
                    if let Err(e) = self.file.finish() {
                        self.fail(e);
                    }
                }
                Err(e) => self.fail(e),
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
