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
//! | `scene/obstacles` | LineStrips2D (static) | obstacle outlines, planes and sines clipped to the region the run visits |
//! | `scene/legend/scale`, `…/colors` | Arrows2D, Points2D (static) | the force scale bar and colour bar, labelled |
//! | `scene/<rod>/nodes` | Points2D + LineStrips2D | nodes coloured by \|R\| (viridis over the run's range); grey = driven; and the rod's centre line (in one chunk with the positions: LZ4 finds it as their copy) |
//! | `scene/<rod>/reactions` | Arrows2D | eq. 2 reactions, length ∝ \|R\| (one scale per recording), labels in N |
//! | `scene/<rod>/normals` | Arrows2D | outward obstacle normals at constrained nodes, beside the reaction |
//! | `scene/<rod>/predictor` | Points2D | predictor positions (orange rings), on steps with corrector passes |
//! | `scene/<rod>/iterate` | LineStrips2D + `phase`, `pass`, `newton_iteration` | each Newton iterate (`--detail iteration`), orange = predictor, magenta = corrector |
//! | `magnified/<rod>/…` | | (own 2D view) each step's departure from free flight magnified ×K: `iterate`, `iterate_nodes`, `surface` (the obstacle surface), `predictor`, `step`, `correction` |
//! | `scene/pressure` | LineStrips2D | a compliant fruit's contacts, coloured by pressure along the face (src/record/pressure.rs) |
//! | `zoom/contact/…` | | the most pressed contact at true scale in mm: fruit surface, face, indentation, pressure profile, threshold, scale bar |
//! | `plots/reaction/<rod>` | Scalars, one per node | \|reaction\| (N), eq. 2 |
//! | `plots/force_ic/<rod>` | Scalars, one per node | impulse-consistent force (N): contact impulse over the last 1 ms / 1 ms |
//! | `plots/impulse/<rod>` | Scalars, one per node | \|impulse\| (N s) |
//! | `plots/bending_stress/<rod>` | Scalars, one per node | bending stress (Pa) |
//! | `solver/<rod>/log10_residual`, `solver/<rod>/pass` | Scalars | per Newton iteration (`--detail iteration`) |
//! | `solver/newton_iterations`, `solver/corrector_passes`, `solver/dt` | Scalars | per step |
//! | `events` | TextLog | contacts added/released, dt changes, Newton failures, warnings, run end |
//! | `events/bookmarks` | TextLog (level BOOKMARK) | first contact, each contact change, the peak forces, dt changes, Newton trouble |
//!
//! Every series has a static SeriesLines with its own colour and a short name (per node for
//! the per-node plots: one entity per kind and rod, a row holds all its nodes' values). Whatever changes
//! every step (the scalar series, node positions, centre lines, the magnified step) is buffered
//! and sent as columns at every 10th flush or at 1 MiB ([`RRD_FLUSH_POINTS`], [`RRD_CHUNK_BYTES`]),
//! built as Arrow arrays straight from the buffers (the rows logged one by one close their
//! chunks there too, where the stream is flushed); a scalar series skips the
//! inside of runs of equal values (the per-node plots at f32's precision), node colours are sent only when they change, and what never
//! changes (radii, line colours, draw orders) is static. The normals and reactions go out as
//! columns too (a row per step in contact, and an empty one after); the sparse entities
//! (predictor, magnified correction) are logged as rows on the steps that show them.

use super::summary::Window;
use super::{
    node_norm, obstacle_outline, phase_color, series_color, Finished, OutputFile, RecordError,
    RecordOptions, Recording, RodStyle, SceneStyle, ViewOptions, CORRECTOR_COLOR, DRIVEN_COLOR,
    NORMAL_COLOR, OBSTACLE_COLOR, PREDICTOR_COLOR, REACTION_COLOR, ROD_COLOR,
};
use crate::events::{
    BodyView, ContactChange, ContactView, Event, Observer, Phase, ReleaseReason, RodInfo,
    RodStepView,
};
use crate::obstacle::Obstacle;
use crate::scenario::Scenario;
use ::rerun::blueprint::components::PanelState;
use ::rerun::blueprint::{
    Blueprint, BlueprintPanel, ContainerLike, Horizontal, SelectionPanel, Spatial2DView, Tabs,
    TextLogView, TimePanel, TimeSeriesView, Vertical,
};
use ::rerun::external::arrow::array::{ArrayRef, Float32Array, Float64Array};
use ::rerun::log::ChunkBatcherConfig;
use ::rerun::{
    AnyValues, Arrows2D, AsComponents, Color, EntityPath, EntityPathPart, LineStrips2D, Points2D,
    Radius, RecordingStream, RecordingStreamBuilder, Scalars, SeriesLines, TextLog, TimeColumn,
    Transform3D,
};
use std::path::Path;

/// Application id of the recordings.
pub const APPLICATION_ID: &str = "gripsim";

/// Writes a Rerun `.rrd` file.
pub struct RerunSink {
    out: OutputFile,
    rec: Option<RecordingStream>,
    opts: RecordOptions,
    view: ViewOptions,
    rods: Vec<RodEntities>,
    obstacles: Vec<Obstacle>,
    obstacle_names: Vec<String>,
    bodies: Vec<crate::world::body::BodySpec>,
    style: Option<SceneStyle>,
    /// The `iteration` timeline's next value.
    iteration: i64,
    per_step: Series,
    /// Scratch: one series row.
    row: Vec<f64>,
    /// Per rod: its scene rows of the steps since the last flush.
    scene: Vec<SceneColumns>,
    /// Per rod: log10 residual and pass of each of its Newton iterations.
    per_iteration: Vec<Series>,
    /// Per rod and node: the impulse-consistent force's window.
    windows: Vec<Vec<Window>>,
    last_t: f64,
    /// The last recorded step (a later one that is not its successor follows a gap).
    last_step: Option<u64>,
    marks: Bookmarks,
    completed: bool,
    error: Option<RecordError>,
    /// Set with `error`, for [`Recording::failure`].
    failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
    /// The file the stream writes to.
    file: RrdFile,
    /// Whether the last step drew a compliant contact's pressure (then the next one without
    /// clears it).
    pressure_shown: bool,
    /// Flush points since the columns were last sent.
    flush_points: u32,
    /// `step`, `sim_time`, `iteration`.
    timelines: [::rerun::TimelineName; 3],
}

/// Time points worth a bookmark, found while the run is logged and written at its end.
#[derive(Debug, Default, Clone)]
struct Bookmarks {
    first_contact: bool,
    /// (|R|, step, t, iteration, rod, node) of the largest eq. 2 reaction.
    peak: Option<(f64, u64, f64, i64, usize, usize)>,
    /// The same for a compliant fruit's peak contact pressure (Pa), and where it was
    /// (`rod "left" node 7`, or `"apple" on "table"`).
    peak_pressure: Option<(f64, u64, f64, i64, usize, usize)>,
    peak_pressure_place: String,
    /// The same for the impulse-consistent force.
    peak_ic: Option<(f64, u64, f64, i64, usize, usize)>,
}

/// The window of the impulse-consistent force (s), as in the run summary.
pub const FORCE_WINDOW: f64 = 1e-3;

/// Entity paths of one rod, and what its transient entities showed at the last step.
pub struct RodEntities {
    info: RodInfo,
    nodes: EntityPath,
    centerline: EntityPath,
    normals: EntityPath,
    reactions: EntityPath,
    predictor: EntityPath,
    iterate: EntityPath,
    mag_iterate: EntityPath,
    mag_iterate_nodes: EntityPath,
    mag_surface: EntityPath,
    mag_predictor: EntityPath,
    mag_step: EntityPath,
    mag_correction: EntityPath,
    /// Positions and velocities at the start of the current step (the end of the last one),
    /// and the free-flight positions start + dt u that the magnified view is drawn about.
    start: Vec<f64>,
    start_u: Vec<f64>,
    reference: Vec<f64>,
    /// Step whose magnified surface is drawn (its iterates share it).
    surface_step: Option<u64>,
    had_contacts: bool,
    had_predictor: bool,
    had_iterate: bool,
    had_mag_correction: bool,
}

/// How a rod is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Look {
    /// A run as recorded: nodes coloured by reaction, centre line, normals, reactions and the
    /// predictor's positions.
    Live,
    /// A second run drawn for comparison (`replay diff --rrd`): its own colour, nodes as rings
    /// around A's dots, its reactions as thinner arrows.
    Other,
}

/// The three timelines of one row: step, sim_time (s), iteration.
type Now = (i64, f64, i64);

/// Time points of buffered rows, sent as the three time columns of `send_columns`.
#[derive(Default)]
struct Times {
    step: Vec<i64>,
    sim_time: Vec<f64>,
    iteration: Vec<i64>,
}

impl Times {
    fn push(&mut self, (step, t, it): Now) {
        self.step.push(step);
        self.sim_time.push(t);
        self.iteration.push(it);
    }

    fn is_empty(&self) -> bool {
        self.step.is_empty()
    }

    fn columns(&self) -> [TimeColumn; 3] {
        [
            TimeColumn::new_sequence("step", self.step.iter().copied()),
            TimeColumn::new_duration_secs("sim_time", self.sim_time.iter().copied()),
            TimeColumn::new_sequence("iteration", self.iteration.iter().copied()),
        ]
    }

    fn clear(&mut self) {
        self.step.clear();
        self.sim_time.clear();
        self.iteration.clear();
    }
}

/// One buffered scalar series of `width` values per row (one entity, one line per value:
/// per kind and rod, a row holds every node's value). A row equal to the last one buffered is
/// held back: a run of equal rows is sent as its first and last rows (the plot is the same,
/// flat between them), so a force that stays 0 costs two rows per flush instead of one per
/// step.
#[derive(Default)]
struct Column {
    times: Times,
    values: Vec<f64>,
    width: usize,
    /// The last row buffered, and the time of the latest equal row not sent yet.
    last: Vec<f64>,
    held: Option<Now>,
}

impl Column {
    fn push(&mut self, now: Now, xs: &[f64]) {
        self.width = xs.len();
        let same = |(a, b): (&f64, &f64)| a.to_bits() == b.to_bits();
        if self.last.len() == xs.len() && self.last.iter().zip(xs).all(same) {
            self.held = Some(now);
            return;
        }
        self.release();
        self.times.push(now);
        self.values.extend_from_slice(xs);
        self.last.clear();
        self.last.extend_from_slice(xs);
    }

    /// Buffer the held end of a run of equal rows.
    fn release(&mut self) {
        if let Some(at) = self.held.take() {
            self.times.push(at);
            self.values.extend_from_slice(&self.last);
        }
    }
}

/// Scalar time series buffered until the next flush and sent as columns.
#[derive(Default)]
struct Series {
    paths: Vec<EntityPath>,
    columns: Vec<Column>,
    now: Now,
}

impl Series {
    fn add(&mut self, path: EntityPath) -> usize {
        self.paths.push(path);
        self.columns.push(Column::default());
        self.paths.len() - 1
    }

    /// The time point of the values pushed next.
    fn at(&mut self, step: u64, t: f64, iteration: i64) {
        self.now = (step as i64, t, iteration);
    }

    fn push(&mut self, k: usize, xs: &[f64]) {
        let now = self.now;
        self.columns[k].push(now, xs);
    }

    /// Send what is buffered, including the held end of a run of equal rows (so the file
    /// read up to this flush shows every series up to its last point).
    fn send(&mut self, rec: &RecordingStream) -> ::rerun::RecordingStreamResult<()> {
        for (path, c) in self.paths.iter().zip(&mut self.columns) {
            c.release();
            if c.times.is_empty() {
                continue;
            }
            let rows = c.times.step.len();
            let values = std::mem::take(&mut c.values);
            let column = arrow_column(
                std::sync::Arc::new(Float64Array::from(values)),
                Scalars::descriptor_scalars(),
                std::iter::repeat_n(c.width, rows),
            )?;
            rec.send_columns(path.clone(), c.times.columns(), [column])?;
            c.times.clear();
        }
        Ok(())
    }
}

/// The normal and reaction arrows of one rod at one step.
#[derive(Default)]
struct ForceArrows {
    n_orig: Vec<[f32; 2]>,
    n_vec: Vec<[f32; 2]>,
    r_orig: Vec<[f32; 2]>,
    r_vec: Vec<[f32; 2]>,
    labels: Vec<String>,
}

/// One rod's per-step scene rows, buffered until the next flush and sent as columns: node
/// positions and the centre line every step, node colours only when they changed, the
/// magnified step when drawn. Radii, line colours and draw orders are static (logged once).
#[derive(Default)]
struct SceneColumns {
    times: Times,
    /// x, y of every node of every buffered row.
    points: Vec<f32>,
    nodes: usize,
    color_times: Times,
    colors: Vec<Color>,
    last_colors: Vec<Color>,
    /// Scratch: this step's colours.
    new_colors: Vec<Color>,
    mag_times: Times,
    /// x, y of every point of the buffered rows' strips, and each strip's length.
    mag: Vec<f32>,
    mag_lengths: Vec<usize>,
    /// The normals and reactions of the rows that show them (and the empty row after).
    force_times: Times,
    forces: ForceArrows,
    force_counts: Vec<usize>,
}

impl SceneColumns {
    /// A step's positions `q` (x, y per node) and node colours (`colors` fills the buffer it
    /// is given; they are buffered only when they changed).
    fn push(&mut self, now: Now, q: &[f64], colors: impl FnOnce(&mut Vec<Color>)) {
        self.times.push(now);
        self.nodes = q.len() / 2;
        self.points.extend(q.iter().map(|&x| x as f32));
        colors(&mut self.new_colors);
        if self.new_colors != self.last_colors {
            self.color_times.push(now);
            self.colors.extend_from_slice(&self.new_colors);
            std::mem::swap(&mut self.last_colors, &mut self.new_colors);
        }
    }

    fn push_forces(&mut self, now: Now, a: ForceArrows) {
        self.force_times.push(now);
        self.force_counts.push(a.n_orig.len());
        let f = &mut self.forces;
        f.n_orig.extend(a.n_orig);
        f.n_vec.extend(a.n_vec);
        f.r_orig.extend(a.r_orig);
        f.r_vec.extend(a.r_vec);
        f.labels.extend(a.labels);
    }

    fn send_forces(
        &mut self,
        rec: &RecordingStream,
        e: &RodEntities,
    ) -> ::rerun::RecordingStreamResult<()> {
        if self.force_times.is_empty() {
            return Ok(());
        }
        let f = std::mem::take(&mut self.forces);
        let counts = std::mem::take(&mut self.force_counts);
        let normals = Arrows2D::update_fields()
            .with_origins(f.n_orig)
            .with_vectors(f.n_vec)
            .columns(counts.iter().copied())?;
        rec.send_columns(e.normals.clone(), self.force_times.columns(), normals)?;
        let reactions = Arrows2D::update_fields()
            .with_origins(f.r_orig)
            .with_vectors(f.r_vec)
            .with_labels(f.labels)
            .columns(counts.iter().copied())?;
        rec.send_columns(e.reactions.clone(), self.force_times.columns(), reactions)?;
        self.force_times.clear();
        Ok(())
    }

    fn send(
        &mut self,
        rec: &RecordingStream,
        e: &RodEntities,
    ) -> ::rerun::RecordingStreamResult<()> {
        self.send_forces(rec, e)?;
        if !self.times.is_empty() {
            let n = self.nodes;
            let rows = self.times.step.len();
            // The same points as the nodes' positions (n per row) and as one strip per row.
            let points = vec2_array(std::mem::take(&mut self.points));
            let nodes = arrow_column(
                points.clone(),
                Points2D::descriptor_positions(),
                std::iter::repeat_n(n, rows),
            )?;
            // The centre line on the nodes' entity: one chunk holds both columns, so LZ4
            // finds the line's points as a copy of the positions (within its 64 KiB window:
            // [`RRD_LINE_WINDOW`]) instead of storing them twice.
            let line = arrow_column(
                strips_array(points, std::iter::repeat_n(n, rows)),
                LineStrips2D::descriptor_strips(),
                std::iter::repeat_n(1, rows),
            )?;
            rec.send_columns(e.nodes.clone(), self.times.columns(), [nodes, line])?;
            self.times.clear();
        }
        if !self.color_times.is_empty() {
            let rows = self.color_times.step.len();
            let colors = Points2D::update_fields()
                .with_colors(self.colors.drain(..))
                .columns(std::iter::repeat_n(self.nodes, rows))?;
            rec.send_columns(e.nodes.clone(), self.color_times.columns(), colors)?;
            self.color_times.clear();
        }
        if !self.mag_times.is_empty() {
            // One strip per row.
            let rows = self.mag_lengths.len();
            let points = vec2_array(std::mem::take(&mut self.mag));
            let strips = arrow_column(
                strips_array(points, self.mag_lengths.drain(..)),
                LineStrips2D::descriptor_strips(),
                std::iter::repeat_n(1, rows),
            )?;
            rec.send_columns(e.mag_step.clone(), self.mag_times.columns(), [strips])?;
            self.mag_times.clear();
        }
        Ok(())
    }
}

fn path(parts: &[&str]) -> EntityPath {
    EntityPath::new(parts.iter().map(|p| EntityPathPart::new(*p)).collect())
}

/// The layout the file opens with, for rods named `rods`: the scene on the left; per rod the
/// eq. 2 reaction beside the impulse-consistent force, solver plots and the event log on the
/// right.
pub fn blueprint(rods: &[String]) -> Blueprint {
    blueprint_with(rods, Vec::new())
}

/// [`blueprint`] with `extra` views as the first tabs of the plot tabs (replay overlays add
/// their difference plots there).
pub fn blueprint_with(rods: &[String], extra: Vec<ContainerLike>) -> Blueprint {
    layout(rods, extra, false)
}

/// [`blueprint_with`], with the contact zoom under the magnified view when the scene has a
/// compliant fruit.
fn layout(rods: &[String], extra: Vec<ContainerLike>, compliant: bool) -> Blueprint {
    let scene = Spatial2DView::new("Scene")
        .with_origin("/")
        .with_contents(["+ /scene/**"]);
    let magnified = Spatial2DView::new("Departure from free flight, magnified")
        .with_origin("/")
        .with_contents(["+ /magnified/**"]);
    // Forces: per rod, eq. 2 beside the impulse-consistent force (one tab per rod).
    let forces: Vec<ContainerLike> = rods
        .iter()
        .map(|r| {
            let label = if rods.len() > 1 {
                format!("{r}: ")
            } else {
                String::new()
            };
            Horizontal::new([
                TimeSeriesView::new(format!("{label}|R| eq. 2 (N)"))
                    .with_origin(format!("/plots/reaction/{r}"))
                    .into(),
                TimeSeriesView::new(format!("{label}impulse-consistent, 1 ms (N)"))
                    .with_origin(format!("/plots/force_ic/{r}"))
                    .into(),
            ])
            .into()
        })
        .collect();
    let forces: ContainerLike = if forces.len() == 1 {
        forces.into_iter().next().expect("one")
    } else {
        Tabs::new(forces).into()
    };
    let mut tabs: Vec<ContainerLike> = extra;
    tabs.push(
        TimeSeriesView::new("log10 residual (N), per rod")
            .with_origin("/solver")
            .with_contents(["+ /solver/*/log10_residual"])
            .into(),
    );
    tabs.push(
        TimeSeriesView::new("Newton its, passes")
            .with_origin("/solver")
            .with_contents(["+ /solver/newton_iterations", "+ /solver/corrector_passes"])
            .into(),
    );
    tabs.push(
        TimeSeriesView::new("dt (s)")
            .with_origin("/solver/dt")
            .into(),
    );
    tabs.push(
        TimeSeriesView::new("Grip force (N), safety margin")
            .with_origin("/plots/grasp")
            .into(),
    );
    tabs.push(
        TimeSeriesView::new("Fruit height (m)")
            .with_origin("/plots/fruit")
            .into(),
    );
    for r in rods {
        let tag = if rods.len() > 1 {
            format!(" {r}")
        } else {
            String::new()
        };
        tabs.push(
            TimeSeriesView::new(format!("Impulse{tag} (N s)"))
                .with_origin(format!("/plots/impulse/{r}"))
                .into(),
        );
        tabs.push(
            TimeSeriesView::new(format!("Stress{tag} (Pa)"))
                .with_origin(format!("/plots/bending_stress/{r}"))
                .into(),
        );
    }
    let events = TextLogView::new("Events and bookmarks").with_origin("/events");
    let middle: ContainerLike = if compliant {
        let zoom = Spatial2DView::new("Most pressed contact, to scale (mm)")
            .with_origin("/")
            .with_contents(["+ /zoom/**"]);
        Vertical::new([magnified.into(), zoom.into()]).into()
    } else {
        magnified.into()
    };
    Blueprint::new(
        Horizontal::new([
            scene.into(),
            middle,
            Vertical::new([forces, Tabs::new(tabs).into(), events.into()])
                .with_row_shares([0.4, 0.3, 0.3])
                .into(),
        ])
        .with_column_shares([0.3, 0.25, 0.45]),
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
        let rods: Vec<String> = scenario.rods.iter().map(|r| r.name.clone()).collect();
        let compliant = scenario.materials.iter().any(Option::is_some);
        let layout = layout(&rods, Vec::new(), compliant);
        Self::create_named(path, opts, &scenario.name, &scenario.text, layout)
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
        // Creates the directory and the partial file (a device is only opened);
        // the SDK opens the file.
        drop(out.create()?);
        let id = format!("{}-{:016x}", name, super::stable_hash(text.as_bytes()));
        // Chunks of rows close only when we flush, never on a timer, nor at the batcher's
        // byte threshold (its 2 MiB default is reached at a different row by `replay show`,
        // which logs the same rows from a stored run: its chunks would differ from the live
        // run's); [`RRD_BATCHER_BYTES`] bounds the memory a pathological flush interval holds.
        let batching = ChunkBatcherConfig {
            flush_tick: std::time::Duration::MAX,
            flush_num_bytes: RRD_BATCHER_BYTES,
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
            view: ViewOptions::default(),
            rods: Vec::new(),
            obstacles: Vec::new(),
            obstacle_names: Vec::new(),
            bodies: Vec::new(),
            style: None,
            iteration: 0,
            per_step: Series::default(),
            row: Vec::new(),
            scene: Vec::new(),
            per_iteration: Vec::new(),
            windows: Vec::new(),
            last_t: 0.0,
            last_step: None,
            marks: Bookmarks::default(),
            completed: false,
            error: None,
            failed: Default::default(),
            file,
            pressure_shown: false,
            flush_points: 0,
            timelines: ["step", "sim_time", "iteration"].map(::rerun::TimelineName::from),
        })
    }

    /// Draw with the run's survey and this arrow scale (call before the run starts).
    pub fn with_view(mut self, view: ViewOptions) -> Self {
        self.view = view;
        self
    }

    /// The scene style, once the first step is known.
    pub fn style(&self) -> Option<&SceneStyle> {
        self.style.as_ref()
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
        // The names interned once (a string is interned at every call).
        let [s, time, it] = self.timelines;
        rec.set_time_sequence(s, step as i64);
        rec.set_duration_secs(time, t.max(0.0));
        rec.set_time_sequence(it, iteration);
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
        self.obstacles = info.planar_obstacles().to_vec();
        self.bodies = info.bodies.to_vec();
        self.obstacle_names = info.obstacle_names.to_vec();
        for r in info.rods {
            self.rods.push(RodEntities::new(&["scene"], r.clone()));
            self.scene.push(SceneColumns::default());
        }
        // Per-node series, each with its colour and name (static, so every time point has them).
        // One entity per kind and rod, a line per node (the row holds every node's value).
        let mut lines: Vec<(EntityPath, Vec<[u8; 3]>, Vec<String>)> = Vec::new();
        for kind in ["reaction", "force_ic", "impulse", "bending_stress"] {
            for r in info.rods {
                let p = path(&["plots", kind, &r.name]);
                self.per_step.add(p.clone());
                lines.push((
                    p,
                    (0..r.nodes).map(series_color).collect(),
                    (0..r.nodes).map(|i| format!("node {i}")).collect(),
                ));
            }
        }
        for (k, s) in ["newton_iterations", "corrector_passes", "dt"]
            .into_iter()
            .enumerate()
        {
            let p = path(&["solver", s]);
            self.per_step.add(p.clone());
            lines.push((p, vec![series_color(k)], vec![s.replace('_', " ")]));
        }
        for (r, rod) in info.rods.iter().enumerate() {
            let mut series = Series::default();
            for s in ["log10_residual", "pass"] {
                let p = path(&["solver", &rod.name, s]);
                series.add(p.clone());
                lines.push((
                    p,
                    vec![series_color(r)],
                    vec![format!("{} {}", rod.name, s.replace('_', " "))],
                ));
            }
            self.per_iteration.push(series);
        }
        self.windows = info
            .rods
            .iter()
            .map(|r| vec![Window::default(); r.nodes])
            .collect();
        if let Some(rec) = self.rec.clone() {
            for (p, c, name) in lines {
                let r = rec.log_static(
                    p,
                    &SeriesLines::new()
                        .with_colors(c.into_iter().map(rgb))
                        .with_names(name)
                        .with_widths([1.5]),
                );
                self.check(r);
            }
        }
        self.text(
            0,
            0.0,
            TextLogLevelName::INFO,
            format!(
                "run of {:?}: {} rod(s), {} obstacle(s), {} mode, detail {}",
                info.scenario_name,
                info.rods.len(),
                info.planar_obstacles().len(),
                format!("{:?}", info.mode).to_lowercase(),
                self.opts.detail.describe()
            ),
        );
    }

    /// Static data once the first state is known: the y-up flip, the obstacle outlines and the
    /// legend (force scale bar, colour bar, magnification).
    fn first_step(&mut self, rods: &[RodStepView<'_>]) {
        let infos: Vec<RodInfo> = self.rods.iter().map(|r| r.info.clone()).collect();
        let style = SceneStyle::new(
            &infos,
            rods,
            &self.obstacles,
            self.view.survey.as_ref(),
            self.view.arrows,
        );
        for (e, v) in self.rods.iter_mut().zip(rods) {
            e.start = v.q.to_vec();
            e.start_u = v.u.to_vec();
            e.reference = v.q.to_vec();
        }
        if let Some(rec) = self.rec.clone() {
            let outlines: Vec<Vec<[f32; 2]>> = self
                .obstacles
                .iter()
                .enumerate()
                .filter(|(k, _)| !self.bodies.iter().any(|b| b.obstacle == *k))
                .flat_map(|(_, o)| obstacle_outline(o, style.lo, style.hi))
                .map(|line| line.into_iter().map(f32x2).collect())
                .collect();
            let r = rec
                .log_static("scene", &Transform3D::from_scale((1.0, -1.0, 1.0)))
                .and_then(|_| {
                    rec.log_static("magnified", &Transform3D::from_scale((1.0, -1.0, 1.0)))
                })
                .and_then(|_| {
                    rec.log_static(
                        "scene/obstacles",
                        &LineStrips2D::new(outlines)
                            .with_colors([rgb(OBSTACLE_COLOR)])
                            .with_radii([Radius::new_ui_points(1.5)])
                            .with_draw_order(DRAW_OBSTACLES),
                    )
                })
                .and_then(|_| log_legend(&rec, &style));
            self.check(r);
            let mut r = Ok(());
            for (e, rs) in self.rods.iter().zip(&style.rods) {
                r = r.and_then(|_| e.log_static_style(&rec, rs));
            }
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
        // Taken out for the step (put back below): no copy of the style per step.
        let style = self.style.take().expect("set above");
        let now = (step as i64, t.max(0.0), it);
        for (r, v) in rods.iter().enumerate() {
            // Nodes and centre line (every step) go out as columns at the next flush; the
            // normals and reactions as columns too; the predictor is logged as rows when shown.
            let e = &mut self.rods[r];
            self.scene[r].push(now, v.q, |colors| e.node_colors(&style, v, colors));
            if let Some(a) = e.force_arrows(&style, r, v, Look::Live) {
                self.scene[r].push_forces(now, a);
            }
            let res = e.draw_predictor(&rec, &style.rods[r], v, passes > 0);
            self.check(res);
            let res = self.rods[r].draw_magnified(&rec, &style, r, v, passes > 0, step);
            match res {
                Ok(Some(strip)) => {
                    let c = &mut self.scene[r];
                    c.mag_times.push(now);
                    c.mag_lengths.push(strip.len());
                    c.mag.extend(strip.iter().flatten());
                }
                Ok(None) => {}
                Err(e) => self.check(Err(e)),
            }
        }
        // Scalars: per rod and node, then the solver's.
        let t0 = if step == 0 { t } else { self.last_t };
        self.last_t = t;
        // After a gap (`--detail auto`), the steps left out are taken to have had this step's
        // impulse rate: the impulse-consistent force of a held contact stays its force.
        let gap_scale = match self.last_step.replace(step) {
            Some(s) if s + 1 != step && dt > 0.0 => (t - t0) / dt,
            _ => 1.0,
        };
        self.per_step.at(step, t, it);
        let mut k = 0;
        for pick in 0..4 {
            for (r, v) in rods.iter().enumerate() {
                let mut row = std::mem::take(&mut self.row);
                row.clear();
                for i in 0..v.in_contact.len() {
                    let x = match pick {
                        0 => node_norm(v.reaction, i),
                        1 => {
                            let f = self.windows[r][i].push(
                                t0,
                                t,
                                gap_scale * v.impulse[2 * i],
                                gap_scale * v.impulse[2 * i + 1],
                                FORCE_WINDOW,
                            );
                            if step > 0 {
                                note_peak(&mut self.marks.peak_ic, f, step, t, it, r, i);
                            }
                            f
                        }
                        2 => node_norm(v.impulse, i),
                        _ => v.bending_stress[i],
                    };
                    if pick == 0 {
                        note_peak(&mut self.marks.peak, x, step, t, it, r, i);
                    }
                    // Plotted at f32's precision (7 digits, as the positions are drawn): the
                    // low half of an f64 mantissa is noise to LZ4 (the bending stress, which
                    // changes every step, takes 26 % fewer bytes); the peaks above are exact.
                    row.push(x as f32 as f64);
                }
                self.per_step.push(k, &row);
                self.row = row;
                k += 1;
            }
        }
        for x in [iterations as f64, passes as f64, dt] {
            self.per_step.push(k, &[x]);
            k += 1;
        }
        self.style = Some(style);
        // Every RRD_FLUSH_POINTS-th flush point, or an earlier one once the buffered columns
        // hold RRD_CHUNK_BYTES, sends them and flushes the stream: one chunk per entity and
        // send, and a chunk carries its schema and per-row time columns. A rod whose
        // positions fit RRD_LINE_WINDOW sends its scene columns on its own schedule instead.
        if step.is_multiple_of(self.opts.flush_every) {
            self.flush_points += 1;
            let all =
                self.flush_points >= RRD_FLUSH_POINTS || self.pending_bytes() >= RRD_CHUNK_BYTES;
            if all {
                self.flush_points = 0;
            }
            // The rows logged one by one close their chunks, and the file is flushed, only
            // where the series go out: each flush is a round trip through the SDK's batcher
            // thread that the run waits for (60 of them took the two-prong grasp 12–22 ms).
            // A windowed rod's scene columns in between need none (a chunk passes the
            // batcher straight to the writer thread).
            self.send_due(&rec, all);
            if all {
                self.flush_stream_async(&rec);
            }
        }
    }

    /// Whether rod `r`'s scene columns go out on their own schedule: a flush interval of its
    /// positions fits [`RRD_LINE_WINDOW`].
    fn windowed(&self, r: usize) -> bool {
        let c = &self.scene[r];
        8 * c.nodes * self.opts.flush_every as usize <= RRD_LINE_WINDOW
    }

    /// At a flush point: send the series and the scene columns of the rods that are not
    /// [`Self::windowed`] when `all`, and the scene columns of each windowed rod whose
    /// positions would pass [`RRD_LINE_WINDOW`] within the next flush interval.
    fn send_due(&mut self, rec: &RecordingStream, all: bool) {
        let every = self.opts.flush_every as usize;
        let mut r = Ok(());
        if all {
            r = self.per_step.send(rec);
            for s in &mut self.per_iteration {
                r = r.and_then(|_| s.send(rec));
            }
        }
        for k in 0..self.scene.len() {
            let c = &self.scene[k];
            let due = if self.windowed(k) {
                !c.times.is_empty() && 4 * c.points.len() + 8 * c.nodes * every > RRD_LINE_WINDOW
            } else {
                all
            };
            if due {
                r = r.and_then(|_| self.scene[k].send(rec, &self.rods[k]));
            }
        }
        self.check(r);
    }

    /// Bytes of column data buffered since the last send (values and time columns).
    fn pending_bytes(&self) -> usize {
        let rows = |t: &Times| t.step.len() * 24;
        let series = |s: &Series| {
            s.columns
                .iter()
                .map(|c| rows(&c.times) + c.values.len() * 8)
                .sum::<usize>()
        };
        let scene: usize = self
            .scene
            .iter()
            .map(|c| {
                2 * rows(&c.times)
                    + 8 * c.points.len()
                    + rows(&c.color_times)
                    + 4 * c.colors.len()
                    + rows(&c.mag_times)
                    + 4 * c.mag.len()
                    + 2 * rows(&c.force_times)
                    + 16 * (c.forces.n_orig.len() + c.forces.r_orig.len())
            })
            .sum();
        series(&self.per_step) + self.per_iteration.iter().map(series).sum::<usize>() + scene
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

    /// The zoom of pressed contact `c` where the fruit is at the step (a free fruit at its pose
    /// in `bodies`), and what its label says: a prong's contact, or a free fruit's own contact
    /// with a fixed obstacle (no rod), seen from the fruit with the obstacle's surface as the
    /// face.
    fn pressure_zoom(
        &self,
        c: &ContactView,
        rods: &[RodStepView<'_>],
        bodies: &[BodyView<'_>],
    ) -> (super::pressure::Zoom, String) {
        use super::pressure as pr;
        let own = c.rod == usize::MAX;
        let body = if own { c.node } else { c.body };
        let placed = bodies.get(body).map(|b| crate::world::body::Placed {
            shape: &self.obstacles[b.obstacle],
            c0: self
                .bodies
                .iter()
                .find(|s| s.obstacle == b.obstacle)
                .map_or(crate::events::xy(b.position), |s| s.centroid),
            pose: crate::world::body::Pose {
                c: crate::events::xy(b.position),
                theta: b.angle,
            },
        });
        let fixed = (!own && c.body == usize::MAX)
            .then(|| self.obstacles.get(c.obstacle))
            .flatten();
        let on_body = placed.map(|p| move |x: [f64; 2]| p.query(x).closest);
        let on_fixed = fixed.map(|o| move |x: [f64; 2]| o.query(x).closest);
        let fruit: Option<pr::Surface<'_>> = match (&on_body, &on_fixed) {
            (Some(f), _) => Some(f),
            (None, Some(f)) => Some(f),
            _ => None,
        };
        if !own {
            let place = format!("rod {:?} node {}", self.rod_name(c.rod), c.node);
            return (pr::zoom(c, pr::Face::Rod(rods[c.rod].q), fruit), place);
        }
        let table = &self.obstacles[c.obstacle];
        let name = self
            .obstacle_names
            .get(c.obstacle)
            .cloned()
            .unwrap_or_default();
        let fruit_name = self.bodies.get(body).map_or("fruit", |b| b.name.as_str());
        let surface = |x: [f64; 2]| table.query(x).closest;
        let v = pr::from_the_fruit(c, surface(crate::events::xy(c.point)));
        let z = pr::zoom(&v, pr::Face::Surface(&surface, &name), fruit);
        (z, format!("{fruit_name:?} on {name:?}"))
    }

    /// A compliant fruit's contacts: the pressure as a colour along each contact on the prong's
    /// face, or for a free fruit's own contact with a fixed obstacle (a fruit on the table) at
    /// the fruit's pressed point (`scene/pressure`), and the most pressed one zoomed in its own
    /// frame, to scale, in millimetres (`zoom/contact/…`, src/record/pressure.rs), all where
    /// the fruit is at the step. Cleared on the first step without one.
    fn draw_pressure(
        &mut self,
        step: u64,
        t: f64,
        rods: &[RodStepView<'_>],
        bodies: &[BodyView<'_>],
        contacts: &[ContactView],
    ) {
        use super::pressure as pr;
        let Some(rec) = self.rec.clone() else {
            return;
        };
        let zoomable = |c: &&ContactView| c.rod < rods.len() || c.rod == usize::MAX;
        let Some(c) = pr::most_pressed(contacts).filter(zoomable) else {
            if std::mem::take(&mut self.pressure_shown) {
                let r = rec
                    .log("scene/pressure", &::rerun::Clear::flat())
                    .and_then(|_| rec.log("zoom/contact", &::rerun::Clear::recursive()));
                self.check(r);
            }
            return;
        };
        if !self.pressure_shown {
            self.pressure_shown = true;
            let r = rec.log_static("zoom", &Transform3D::from_scale((1.0, -1.0, 1.0)));
            self.check(r);
        }
        let it = self.iteration - 1;
        let (z, place) = self.pressure_zoom(c, rods, bodies);
        if c.peak_pressure > self.marks.peak_pressure.map_or(0.0, |p| p.0) {
            self.marks.peak_pressure_place = place.clone();
        }
        note_peak(
            &mut self.marks.peak_pressure,
            c.peak_pressure,
            step,
            t,
            it,
            c.rod,
            c.node,
        );
        let (mut strips, mut colors) = (Vec::new(), Vec::new());
        for (seg, col) in contacts
            .iter()
            .filter(|c| pr::is_pressed(c))
            .flat_map(pr::patch)
        {
            strips.push(seg.map(f32x2).to_vec());
            colors.push(rgb(col));
        }
        let strip = |p: &[[f64; 2]]| p.iter().copied().map(f32x2).collect::<Vec<_>>();
        let (prof, prof_colors): (Vec<_>, Vec<_>) = z
            .profile
            .iter()
            .map(|(s, col)| (strip(s), rgb(*col)))
            .unzip();
        let label = pr::describe(c, &place);
        let scale_label = format!("{} mm", z.scale.1);
        let threshold = z.threshold.map(|l| vec![strip(&l)]).unwrap_or_default();
        let ui = Radius::new_ui_points;
        let r = rec
            .log(
                "scene/pressure",
                &LineStrips2D::new(strips)
                    .with_colors(colors)
                    .with_radii([ui(4.0)])
                    .with_draw_order(DRAW_OBSTACLES + 3.0),
            )
            .and_then(|_| {
                rec.log(
                    "zoom/contact/surfaces",
                    &LineStrips2D::new([strip(&z.fruit), strip(&z.face), strip(&z.centerline)])
                        .with_colors([rgb(OBSTACLE_COLOR), rgb(ROD_COLOR), rgb(DRIVEN_COLOR)])
                        .with_radii([ui(2.0), ui(2.5), ui(1.0)]),
                )
            })
            .and_then(|_| {
                rec.log(
                    "zoom/contact/pressure",
                    &LineStrips2D::new(prof)
                        .with_colors(prof_colors)
                        .with_radii([ui(3.0)]),
                )
            })
            .and_then(|_| {
                rec.log(
                    "zoom/contact/threshold",
                    &LineStrips2D::new(threshold)
                        .with_colors([rgb(pr::BRUISE_COLOR)])
                        .with_radii([ui(1.0)]),
                )
            })
            .and_then(|_| {
                rec.log(
                    "zoom/contact/indentation",
                    &Arrows2D::from_vectors([f32x2(z.indentation)])
                        .with_origins([[0.0f32, 0.0]])
                        .with_colors([rgb(REACTION_COLOR)])
                        .with_labels([format!("δ = {}", pr::mm(c.indentation))])
                        .with_show_labels(true),
                )
            })
            .and_then(|_| {
                rec.log(
                    "zoom/contact/scale",
                    &LineStrips2D::new([strip(&z.scale.0)])
                        .with_colors([rgb([80, 80, 80])])
                        .with_radii([ui(1.5)])
                        .with_labels([scale_label])
                        .with_show_labels(true),
                )
            })
            .and_then(|_| {
                let (pos, text): (Vec<_>, Vec<_>) = z
                    .labels(label)
                    .into_iter()
                    .map(|(p, t)| (f32x2(p), t))
                    .unzip();
                rec.log(
                    "zoom/contact/labels",
                    &Points2D::new(pos)
                        .with_colors([rgb([80, 80, 80])])
                        .with_radii([ui(0.1)])
                        .with_labels(text)
                        .with_show_labels(true),
                )
            });
        self.check(r);
    }

    fn iteration(&mut self, ev: IterationEvent<'_>) {
        let Some(rec) = self.rec.clone() else {
            return;
        };
        let it = self.iteration;
        self.iteration += 1;
        self.set_time(&rec, ev.step, ev.t, it);
        if let Some(s) = self.per_iteration.get_mut(ev.rod) {
            s.at(ev.step, ev.t, it);
            s.push(0, &[ev.residual.max(1e-300).log10()]);
            s.push(1, &[ev.pass as f64]);
        }
        let Some(style) = self.style.clone() else {
            return;
        };
        if let Some(e) = self.rods.get_mut(ev.rod) {
            let r = e.draw_iterate(&rec, &style, ev.rod, &ev, &self.obstacles);
            self.check(r);
        }
    }

    fn contact(&mut self, c: &ContactChange, released: Option<ReleaseReason>) {
        let rod = self.rod_name(c.rod);
        let at = format!(
            "t = {:.6} s, step {}, iteration {}",
            c.t, c.step, self.iteration
        );
        let text = match released {
            None => format!(
                "contact added: rod {rod:?} node {} on obstacle {} before corrector pass {} ({at}); normal ({:.4}, {:.4}), predictor gap {:.3e} m, z {:.3e} m/s",
                c.node, c.obstacle, c.pass, c.normal[0], c.normal[1], c.gap, c.z
            ),
            Some(ReleaseReason::Adhesive) => format!(
                "contact released (adhesive R = ({:.4}, {:.4}) N): rod {rod:?} node {} from obstacle {} before corrector pass {} ({at}); normal ({:.4}, {:.4}), gap {:.3e} m",
                c.reaction[0], c.reaction[1], c.node, c.obstacle, c.pass, c.normal[0], c.normal[1], c.gap
            ),
            Some(ReleaseReason::HandedOver) => format!(
                "contact handed to the segment beside it (R = ({:.4}, {:.4}) N): rod {rod:?} node {} on obstacle {} before corrector pass {} ({at}); normal ({:.4}, {:.4}), gap {:.3e} m",
                c.reaction[0], c.reaction[1], c.node, c.obstacle, c.pass, c.normal[0], c.normal[1], c.gap
            ),
        };
        if released.is_none() && !self.marks.first_contact {
            self.marks.first_contact = true;
            self.bookmark(
                c.step,
                c.t,
                self.iteration,
                format!("first contact: rod {rod:?} node {} ({at})", c.node),
            );
        }
        self.bookmark(c.step, c.t, self.iteration, text);
    }

    /// A line in `events/bookmarks` at (step, t, iteration).
    fn bookmark(&mut self, step: u64, t: f64, iteration: i64, text: String) {
        let Some(rec) = self.rec.clone() else {
            return;
        };
        self.set_time(&rec, step, t, iteration);
        let r = rec.log(
            "events/bookmarks",
            &TextLog::new(format!("★ {text}")).with_level(TextLogLevelName::BOOKMARK),
        );
        self.check(r);
    }

    /// The bookmarks known only at the end: the peak forces, at their own time points.
    fn end_bookmarks(&mut self) {
        if let Some((p, step, t, it, _, _)) = self.marks.peak_pressure {
            let place = std::mem::take(&mut self.marks.peak_pressure_place);
            self.bookmark(
                step,
                t,
                it,
                format!(
                    "peak contact pressure {}: {place} (t = {t:.6} s, step {step}, iteration {it})",
                    super::pressure::pressure(p)
                ),
            );
        }
        let peaks = [
            ("peak eq. 2 reaction", self.marks.peak),
            (
                "peak impulse-consistent force (1 ms window)",
                self.marks.peak_ic,
            ),
        ];
        for (what, p) in peaks {
            if let Some((f, step, t, it, r, i)) = p.filter(|p| p.0 > 0.0) {
                let rod = self.rod_name(r);
                self.bookmark(
                    step,
                    t,
                    it,
                    format!(
                        "{what} {f:.4} N: rod {rod:?} node {i} (t = {t:.6} s, step {step}, iteration {it})"
                    ),
                );
            }
        }
    }

    fn rod_name(&self, r: usize) -> String {
        self.rods
            .get(r)
            .map(|e| e.info.name.clone())
            .unwrap_or_else(|| r.to_string())
    }

    /// Send the buffered columns and make the file readable up to here. The rows logged one by
    /// one (events, iterates, the sparse entities) close their chunks here and where the
    /// series are sent ([`Self::flush_stream_async`]; or at the batcher's 1 MiB per entity),
    /// so the chunking of those is the same in every run of the same data (`replay show` and
    /// the live run agree chunk for chunk). The wait for the SDK's writer thread is bounded: a
    /// writer that died (disk full) or hangs fails the recording instead of the run waiting
    /// forever.
    fn flush(&mut self, rec: &RecordingStream) {
        let mut r = self.per_step.send(rec);
        for s in &mut self.per_iteration {
            r = r.and_then(|_| s.send(rec));
        }
        for (c, e) in self.scene.iter_mut().zip(&self.rods) {
            r = r.and_then(|_| c.send(rec, e));
        }
        self.check(r);
        self.flush_stream(rec);
    }

    /// Close the chunks of what the stream holds here (the SDK's batcher does that before this
    /// returns, so the chunking is the same in every run) and let its threads encode and write
    /// them while the run goes on: the wait of [`Self::flush_stream`] at every flush point made
    /// the simulation thread idle while the SDK encoded (the two-prong grasp's `.rrd` at step
    /// detail took its CPU time as wall time). A failure of the writer seen by now (a full
    /// disk) fails the recording here; a later one at the next flush point or the end, which
    /// waits.
    fn flush_stream_async(&mut self, rec: &RecordingStream) {
        if let Err(e) = rec.flush_async() {
            return self.fail(e.to_string());
        }
        if let Some(e) = self.file.error() {
            self.fail(e);
        }
    }

    /// Make the file readable up to here (what the stream holds is written).
    fn flush_stream(&mut self, rec: &RecordingStream) {
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

/// The `.rrd` sink sends its buffered per-step columns at every this many-th flush point (a
/// step that is a multiple of `flush_every`: every 1 000 steps by default; the rows logged
/// one by one close their chunks there too, and the file is flushed)...
pub const RRD_FLUSH_POINTS: u32 = 10;

/// ... or at an earlier flush point once they hold this many bytes of column data (values and
/// time columns, as Arrow holds them; ~1 000 steps of the two-prong grasp). Per entity and
/// send the file gets one chunk with its own schema (~1.7 KiB) and time columns, so fewer,
/// larger chunks make a smaller file and less work for the SDK's encoder (two-prong grasp at
/// step detail: 1 266 chunks, 46.6 B/node-step in the bench when every flush sent them; 254,
/// 36.4 now).
/// A run killed by SIGKILL loses the `.rrd`'s last send interval; a stop by a signal, an
/// error or the run's end sends everything.
pub const RRD_CHUNK_BYTES: usize = 1 << 20;

/// ... or at an earlier flush point once one more flush interval would take a rod's buffered
/// node positions (f32 x, y: 8 bytes per node and step) past this many bytes. A rod's chunk
/// holds its positions and its centre line (the same points again) one after the other, and
/// the `.rrd`'s LZ4 (one block per chunk) finds the second copy only within 64 KiB of the
/// first: the budget leaves room for the columns' offsets. The two-prong grasp (10 nodes per
/// rod) sends every 700 steps; a rod of more than ~76 nodes at `flush_every` 100 gets no
/// copy found (its line costs its bytes again, as before). Such a rod's scene columns go out
/// with the series; a rod within the budget sends its own on its own schedule.
pub const RRD_LINE_WINDOW: usize = 60 * 1024;

/// An entity's rows logged one by one between two `.rrd` flushes close a chunk at this many
/// bytes (the SDK's batcher's own threshold): far above what a flush interval holds (the
/// rows' per-step size goes with the columns', which send at 1 MiB), a bound on memory only.
const RRD_BATCHER_BYTES: u64 = 64 << 20;

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

/// Most chunks whose index (the `.rrd` footer) is kept: a few kB of memory each (more for
/// wide chunks: the per-node plots hold a column per node), so at most ~10 MB. Since the
/// columnar logging a step detail run logs ~0.1 chunk per step and rod, so a footer is kept
/// for ~20 000 steps of the seed grasp (8 192 before, when each step made ~1 chunk per
/// entity). The SDK builds the footer in memory for the whole run (a dense table of every
/// chunk by every column), which made a long run's memory grow like its file (442 MB at
/// 300 000 steps of the seed grasp). A run that logs more chunks drops the index at that
/// point, freeing it: its `.rrd` is the same stream without a footer (`rerun rrd
/// stats/print` and the viewer read it; `rerun rrd verify` asks for the footer, which
/// `rerun rrd optimize` adds).
pub const FOOTER_CHUNKS: u64 = 2048;

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
    /// The file's disk writes, started at each flush.
    writeback: super::Writeback,
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
        let writeback = super::Writeback::of(&file);
        let encoder = Encoder::new_eager(
            CrateVersion::LOCAL,
            EncodingOptions::PROTOBUF_COMPRESSED,
            std::io::BufWriter::with_capacity(1 << 16, file),
        )
        .map_err(|e| RecordError::write(path, e))?;
        Ok(Self {
            state: std::sync::Arc::new(std::sync::Mutex::new(RrdState {
                encoder: Some(encoder),
                writeback,
                chunks: 0,
                footer: true,
                error: None,
            })),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, RrdState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The writer's failure so far, if any (the stream's threads write while the run goes on).
    fn error(&self) -> Option<String> {
        self.lock().error.clone()
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
            match enc.flush_blocking() {
                // In the file: its pages start for the disk now.
                Ok(()) => s.writeback.start(),
                Err(e) => s.fail(super::error_chain(&e)),
            }
        }
        match &s.error {
            Some(e) => Err(::rerun::sink::SinkFlushError::Failed { message: e.clone() }),
            None => Ok(()),
        }
    }
}

/// Keep the largest `f` with where and when it happened.
fn note_peak(
    peak: &mut Option<(f64, u64, f64, i64, usize, usize)>,
    f: f64,
    step: u64,
    t: f64,
    it: i64,
    r: usize,
    i: usize,
) {
    if f > peak.map(|p| p.0).unwrap_or(0.0) {
        *peak = Some((f, step, t, it, r, i));
    }
}

// The magnified view's rows, data and clearing rows alike (the same columns).
fn mag_step_strip(strips: Vec<Vec<[f32; 2]>>) -> LineStrips2D {
    LineStrips2D::new(strips)
        .with_colors([rgb(ROD_COLOR)])
        .with_radii([Radius::new_ui_points(1.0)])
        .with_draw_order(DRAW_MAGNIFIED)
}

fn mag_predictor_points(points: Vec<[f32; 2]>, rad: f64) -> Points2D {
    Points2D::new(points)
        .with_colors([rgb(PREDICTOR_COLOR)])
        .with_radii([1.2 * rad as f32])
        .with_draw_order(DRAW_MAGNIFIED)
}

fn mag_correction_arrows(
    origins: Vec<[f32; 2]>,
    vectors: Vec<[f32; 2]>,
    labels: Vec<String>,
    rad: f64,
) -> Arrows2D {
    Arrows2D::from_vectors(vectors)
        .with_origins(origins)
        .with_labels(labels)
        .with_colors([rgb(CORRECTOR_COLOR)])
        .with_radii([0.35 * rad as f32])
        .with_draw_order(DRAW_MAGNIFIED + 1.0)
}

fn mag_iterate_strip(
    strips: Vec<Vec<[f32; 2]>>,
    color: Color,
    labels: Vec<String>,
) -> LineStrips2D {
    LineStrips2D::new(strips)
        .with_colors([color])
        .with_labels(labels)
        .with_show_labels(true)
        .with_radii([Radius::new_ui_points(2.0)])
        .with_draw_order(DRAW_MAGNIFIED)
}

fn mag_iterate_points(points: Vec<[f32; 2]>, color: Color, rad: f64) -> Points2D {
    Points2D::new(points)
        .with_colors([color])
        .with_radii([0.8 * rad as f32])
        .with_draw_order(DRAW_MAGNIFIED)
}

/// One row of `…/iterate`: the strip (none: a clearing row) with its phase, pass, Newton
/// iteration and label as components.
fn iterate_row(
    strip: Option<Vec<[f32; 2]>>,
    color: Color,
    phase: &[&str],
    pass: &[u32],
    newton: &[u32],
    label: &[&str],
) -> Vec<::rerun::SerializedComponentBatch> {
    use ::rerun::external::arrow::array::{ArrayRef, UInt32Array};
    let pass: ArrayRef = std::sync::Arc::new(UInt32Array::from(pass.to_vec()));
    let newton: ArrayRef = std::sync::Arc::new(UInt32Array::from(newton.to_vec()));
    let mut row = LineStrips2D::new(strip)
        .with_colors([color])
        .with_radii([Radius::new_ui_points(2.5)])
        .with_draw_order(DRAW_ITERATE)
        .as_serialized_batches();
    row.extend(
        AnyValues::default()
            .with_component::<::rerun::components::Text>("phase", phase.iter().copied())
            .with_component_from_data("pass", pass)
            .with_component_from_data("newton_iteration", newton)
            .with_component::<::rerun::components::Text>("label", label.iter().copied())
            .as_serialized_batches(),
    );
    row
}

fn f32x2(p: [f64; 2]) -> [f32; 2] {
    [p[0] as f32, p[1] as f32]
}

/// `xy` (x, y, x, y, …) as the Arrow array of Rerun's 2D positions and vectors (a fixed-size
/// list of two f32), built straight from the buffer: the archetypes' builders convert point
/// by point.
fn vec2_array(xy: Vec<f32>) -> ArrayRef {
    use ::rerun::external::arrow::array::FixedSizeListArray;
    use ::rerun::external::arrow::datatypes::DataType;
    use ::rerun::Loggable;
    let DataType::FixedSizeList(item, 2) = ::rerun::components::Position2D::arrow_datatype() else {
        unreachable!("a Position2D is two f32")
    };
    std::sync::Arc::new(FixedSizeListArray::new(
        item,
        2,
        std::sync::Arc::new(Float32Array::from(xy)),
        None,
    ))
}

/// `points` cut into line strips of `lengths` points (Rerun's LineStrip2D).
fn strips_array(points: ArrayRef, lengths: impl IntoIterator<Item = usize>) -> ArrayRef {
    use ::rerun::external::arrow::array::ListArray;
    use ::rerun::external::arrow::buffer::OffsetBuffer;
    use ::rerun::external::arrow::datatypes::DataType;
    use ::rerun::Loggable;
    let DataType::List(item) = ::rerun::components::LineStrip2D::arrow_datatype() else {
        unreachable!("a LineStrip2D is a list of points")
    };
    std::sync::Arc::new(ListArray::new(
        item,
        OffsetBuffer::from_lengths(lengths),
        points,
        None,
    ))
}

/// A `send_columns` column of `descriptor` from the values `array`, `lengths` of them per row.
fn arrow_column(
    array: ArrayRef,
    descriptor: ::rerun::ComponentDescriptor,
    lengths: impl IntoIterator<Item = usize>,
) -> Result<::rerun::SerializedComponentColumn, ::rerun::SerializationError> {
    ::rerun::SerializedComponentBatch::new(array, descriptor).partitioned(lengths)
}

/// The legend, static, in a band above the drawing box (the 2D view fits it in): the force
/// scale bar (an arrow of the scale's round length, labelled with it), the colour bar
/// (labelled with its range), and the magnification with the colour key of the magnified view.
fn log_legend(rec: &RecordingStream, style: &SceneStyle) -> ::rerun::RecordingStreamResult<()> {
    let fs = &style.forces;
    let w = style.hi[0] - style.lo[0];
    let h = style.hi[1] - style.lo[1];
    let cx = 0.5 * (style.lo[0] + style.hi[0]);
    let row = |k: f64| style.hi[1] + 0.07 * k * h;
    rec.log_static(
        "scene/legend/scale",
        &Arrows2D::from_vectors([[fs.unit_length as f32, 0.0]])
            .with_origins([f32x2([cx - 0.5 * fs.unit_length, row(1.0)])])
            .with_colors([rgb(REACTION_COLOR)])
            .with_labels([fs.bar_label()])
            .with_show_labels(true)
            .with_radii([Radius::new_ui_points(2.0)])
            .with_draw_order(DRAW_LEGEND),
    )?;
    let n = 11;
    let span = 0.3 * w;
    let pts: Vec<[f32; 2]> = (0..n)
        .map(|k| f32x2([cx - 0.5 * span + span * k as f64 / (n - 1) as f64, row(2.0)]))
        .collect();
    let colors: Vec<Color> = (0..n)
        .map(|k| rgb(super::colormap(k as f64 / (n - 1) as f64)))
        .collect();
    let mut labels = vec![String::new(); n];
    labels[0] = "0 N".into();
    labels[n - 1] = format!("{} N", super::fmt_force(fs.force_max));
    rec.log_static(
        "scene/legend/colors",
        &Points2D::new(pts)
            .with_colors(colors)
            .with_radii([Radius::new_ui_points(5.0)])
            .with_labels(labels)
            .with_show_labels(true)
            .with_draw_order(DRAW_LEGEND),
    )?;
    if style.magnify > 1.0 {
        rec.log_static(
            "magnified/legend",
            &Points2D::new([f32x2([cx, row(1.0)])])
                .with_colors([rgb(CORRECTOR_COLOR)])
                .with_radii([Radius::new_ui_points(3.0)])
                .with_labels([format!(
                    "{}\norange predictor, magenta corrector,\ngreen: obstacle surface, grey: step end",
                    style.describe_magnify()
                )])
                .with_show_labels(true)
                .with_draw_order(DRAW_LEGEND),
        )?;
    }
    Ok(())
}

impl RodEntities {
    /// The entities of rod `info` under `root`: `root/<rod>/nodes`, `…/centerline`,
    /// `…/normals`, `…/reactions`, `…/predictor`, `…/iterate` (a live run uses `["scene"]`),
    /// and `magnified/<rod>/…`.
    pub fn new(root: &[&str], info: RodInfo) -> Self {
        let rod = |kind: &[&str]| {
            let mut parts: Vec<&str> = root.to_vec();
            parts.push(info.name.as_str());
            parts.extend(kind);
            path(&parts)
        };
        // The magnified view is its own 2D view: entities under `magnified/<rod>/`.
        let mag = |kind: &str| path(&["magnified", info.name.as_str(), kind]);
        Self {
            nodes: rod(&["nodes"]),
            centerline: rod(&["centerline"]),
            normals: rod(&["normals"]),
            reactions: rod(&["reactions"]),
            predictor: rod(&["predictor"]),
            iterate: rod(&["iterate"]),
            mag_iterate: mag("iterate"),
            mag_iterate_nodes: mag("iterate_nodes"),
            mag_surface: mag("surface"),
            mag_predictor: mag("predictor"),
            mag_step: mag("step"),
            mag_correction: mag("correction"),
            start: Vec::new(),
            start_u: Vec::new(),
            reference: Vec::new(),
            surface_step: None,
            had_contacts: true,
            had_predictor: true,
            had_iterate: false,
            had_mag_correction: true,
            info,
        }
    }

    fn clamped(&self, i: usize) -> bool {
        self.info.clamped.get(i).copied().unwrap_or(false)
    }

    /// The live look's node colours: |R| on the recording's colour map, grey when driven
    /// (into `out`, cleared first).
    fn node_colors(&self, style: &SceneStyle, v: &RodStepView<'_>, out: &mut Vec<Color>) {
        out.clear();
        // A node without a reaction (most of them, most of the time) has the map's first colour.
        let zero = rgb(style.forces.color(0.0));
        out.extend((0..v.in_contact.len()).map(|i| {
            if self.clamped(i) {
                rgb(DRIVEN_COLOR)
            } else {
                let (x, y) = (v.reaction[2 * i], v.reaction[2 * i + 1]);
                if x == 0.0 && y == 0.0 {
                    zero
                } else {
                    rgb(style.forces.color(x.hypot(y)))
                }
            }
        }));
    }

    /// What never changes in a live run's nodes, centre line and magnified step: logged once,
    /// static, so the per-step columns carry positions (and changed colours) only.
    fn log_static_style(
        &self,
        rec: &RecordingStream,
        rs: &RodStyle,
    ) -> ::rerun::RecordingStreamResult<()> {
        // The centre line is drawn from the same entity (its strips go out with the
        // positions): one row holds both styles.
        let points = Points2D::update_fields()
            .with_radii([rs.node_radius as f32])
            .with_draw_order(DRAW_NODES);
        let line = LineStrips2D::update_fields()
            .with_colors([rgb(ROD_COLOR)])
            .with_radii([Radius::new_ui_points(1.5)])
            .with_draw_order(DRAW_ROD);
        rec.log_static(self.nodes.clone(), &[&points as &dyn AsComponents, &line])?;
        let rad = rs.node_radius;
        rec.log_static(
            self.normals.clone(),
            &Arrows2D::update_fields()
                .with_colors([rgb(NORMAL_COLOR)])
                .with_radii([0.2 * rad as f32])
                .with_draw_order(DRAW_NORMALS),
        )?;
        rec.log_static(
            self.reactions.clone(),
            &Arrows2D::update_fields()
                .with_colors([rgb(REACTION_COLOR)])
                .with_radii([0.45 * rad as f32])
                .with_draw_order(DRAW_REACTIONS),
        )?;
        rec.log_static(
            self.mag_step.clone(),
            &LineStrips2D::update_fields()
                .with_colors([rgb(ROD_COLOR)])
                .with_radii([Radius::new_ui_points(1.0)])
                .with_draw_order(DRAW_MAGNIFIED),
        )
    }

    /// Log the rod's state `v` (rod number `r` of `style`) at the stream's current time.
    /// `corrected`: a corrector pass moved the rod this step (its predictor positions are
    /// shown).
    pub fn draw(
        &mut self,
        rec: &RecordingStream,
        style: &SceneStyle,
        r: usize,
        v: &RodStepView<'_>,
        corrected: bool,
        look: Look,
    ) -> ::rerun::RecordingStreamResult<()> {
        let rs = style.rods[r];
        let n = v.in_contact.len();
        let radius = rs.node_radius as f32;
        let points: Vec<[f32; 2]> = v.q.chunks_exact(2).map(|c| f32x2([c[0], c[1]])).collect();
        let (node_colors, node_radius, line, line_width, draw_nodes, draw_line): (
            Vec<Color>,
            f32,
            [u8; 3],
            f32,
            f32,
            f32,
        ) = match look {
            Look::Live => (
                (0..n)
                    .map(|i| {
                        if self.clamped(i) {
                            rgb(DRIVEN_COLOR)
                        } else {
                            rgb(style.forces.color(node_norm(v.reaction, i)))
                        }
                    })
                    .collect(),
                radius,
                ROD_COLOR,
                1.5,
                DRAW_NODES,
                DRAW_ROD,
            ),
            // Run B: larger dots under A's, so a node where both runs agree shows as A's dot
            // in a B-coloured ring, and a thicker line under A's.
            Look::Other => (
                vec![rgb(OTHER_COLOR)],
                1.7 * radius,
                OTHER_COLOR,
                4.0,
                DRAW_OTHER_NODES,
                DRAW_OTHER_ROD,
            ),
        };
        rec.log(
            self.nodes.clone(),
            &Points2D::new(points.iter().copied())
                .with_radii([node_radius])
                .with_colors(node_colors)
                .with_draw_order(draw_nodes),
        )?;
        rec.log(
            self.centerline.clone(),
            &LineStrips2D::new([points])
                .with_colors([rgb(line)])
                .with_radii([Radius::new_ui_points(line_width)])
                .with_draw_order(draw_line),
        )?;
        self.draw_forces(rec, style, r, v, look)?;
        if look == Look::Live {
            self.draw_predictor(rec, &rs, v, corrected)?;
        }
        Ok(())
    }

    /// Normals and reactions at constrained nodes; logged empty once when contact ends.
    /// Reactions start at the edge of the node marker, length by the recording's force scale;
    /// normals start beside them (offset along the surface) so the two never overlap.
    fn draw_forces(
        &mut self,
        rec: &RecordingStream,
        style: &SceneStyle,
        r: usize,
        v: &RodStepView<'_>,
        look: Look,
    ) -> ::rerun::RecordingStreamResult<()> {
        let Some(a) = self.force_arrows(style, r, v, look) else {
            return Ok(());
        };
        let rad = style.rods[r].node_radius;
        let (color, width, order) = match look {
            Look::Live => (REACTION_COLOR, 0.45 * rad, DRAW_REACTIONS),
            Look::Other => (OTHER_COLOR, 0.8 * rad, DRAW_OTHER_REACTIONS),
        };
        if look == Look::Live {
            rec.log(
                self.normals.clone(),
                &Arrows2D::from_vectors(a.n_vec)
                    .with_origins(a.n_orig)
                    .with_colors([rgb(NORMAL_COLOR)])
                    .with_radii([0.2 * rad as f32])
                    .with_draw_order(DRAW_NORMALS),
            )?;
        }
        rec.log(
            self.reactions.clone(),
            &Arrows2D::from_vectors(a.r_vec)
                .with_origins(a.r_orig)
                .with_labels(a.labels)
                .with_colors([rgb(color)])
                .with_radii([width as f32])
                .with_draw_order(order),
        )
    }

    /// The arrows of [`Self::draw_forces`]; `None` when there are none now and there were
    /// none at the last call either (nothing to log).
    fn force_arrows(
        &mut self,
        style: &SceneStyle,
        r: usize,
        v: &RodStepView<'_>,
        look: Look,
    ) -> Option<ForceArrows> {
        let rs = style.rods[r];
        let n = v.in_contact.len();
        let any = v.in_contact.iter().any(|&c| c);
        if !any && !self.had_contacts {
            return None;
        }
        self.had_contacts = any;
        let rad = rs.node_radius;
        let mut a = ForceArrows::default();
        for i in (0..n).filter(|&i| v.in_contact[i]) {
            let p = [v.q[2 * i], v.q[2 * i + 1]];
            let nv = [v.normal[2 * i], v.normal[2 * i + 1]];
            let tangent = [-nv[1], nv[0]];
            let side = 2.2 * rad;
            a.n_orig
                .push(f32x2([p[0] + side * tangent[0], p[1] + side * tangent[1]]));
            a.n_vec
                .push(f32x2([rs.normal_length * nv[0], rs.normal_length * nv[1]]));
            let f = node_norm(v.reaction, i);
            let dir = if f > 0.0 {
                [v.reaction[2 * i] / f, v.reaction[2 * i + 1] / f]
            } else {
                nv
            };
            let len = style.forces.length(f);
            a.r_orig
                .push(f32x2([p[0] + rad * dir[0], p[1] + rad * dir[1]]));
            a.r_vec.push(f32x2([len * dir[0], len * dir[1]]));
            let mut label = String::with_capacity(16);
            if let Look::Other = look {
                label.push_str("B ");
            }
            super::push_g(&mut label, f);
            label.push_str(" N");
            a.labels.push(label);
        }
        Some(a)
    }

    /// The predictor's positions where a corrector pass moved the rod: orange rings around the
    /// nodes (a larger dot under the node), over everything else.
    fn draw_predictor(
        &mut self,
        rec: &RecordingStream,
        rs: &RodStyle,
        v: &RodStepView<'_>,
        corrected: bool,
    ) -> ::rerun::RecordingStreamResult<()> {
        if corrected || self.had_predictor {
            let ghost: Vec<[f32; 2]> = if corrected {
                v.q_predictor
                    .chunks_exact(2)
                    .map(|c| f32x2([c[0], c[1]]))
                    .collect()
            } else {
                Vec::new()
            };
            rec.log(
                self.predictor.clone(),
                &Points2D::new(ghost)
                    .with_radii([1.6 * rs.node_radius as f32])
                    .with_colors([rgb(PREDICTOR_COLOR)])
                    .with_draw_order(DRAW_PREDICTOR),
            )?;
        }
        self.had_predictor = corrected;
        Ok(())
    }

    /// The step of size `dt` begins: its free-flight positions, start + dt u.
    pub fn step_begin(&mut self, dt: f64) {
        self.reference.clear();
        self.reference.extend(
            self.start
                .iter()
                .zip(&self.start_u)
                .map(|(q, u)| q + dt * u),
        );
        self.surface_step = None;
    }

    /// `p` magnified ×`k` about node `i`'s free-flight position of this step.
    fn magnified(&self, k: f64, i: usize, p: [f64; 2]) -> [f32; 2] {
        let s = [self.reference[2 * i], self.reference[2 * i + 1]];
        f32x2([s[0] + k * (p[0] - s[0]), s[1] + k * (p[1] - s[1])])
    }

    /// The obstacle surface near each free node, magnified about the node's position at the
    /// step's start: a short tick across the nearest obstacle's normal, where the node would
    /// touch after moving ×k less. Nodes whose magnified surface is far off get none.
    fn log_surface(
        &mut self,
        rec: &RecordingStream,
        style: &SceneStyle,
        r: usize,
        obstacles: &[Obstacle],
        step: u64,
    ) -> ::rerun::RecordingStreamResult<()> {
        if self.surface_step == Some(step) {
            return Ok(());
        }
        self.surface_step = Some(step);
        let rs = style.rods[r];
        let k = style.magnify;
        let w = 2.5 * rs.node_radius;
        let mut ticks = Vec::new();
        for i in 0..self.reference.len() / 2 {
            if self.clamped(i) {
                continue;
            }
            let p = [self.reference[2 * i], self.reference[2 * i + 1]];
            let near = obstacles
                .iter()
                .map(|o| o.query(p))
                .min_by(|a, b| a.distance.total_cmp(&b.distance));
            let Some(q) = near else { continue };
            if !(k * q.distance.abs() < 0.5 * rs.reach) {
                continue;
            }
            let c = [
                p[0] - k * q.distance * q.normal[0],
                p[1] - k * q.distance * q.normal[1],
            ];
            let t = [-q.normal[1], q.normal[0]];
            ticks.push(vec![
                f32x2([c[0] - w * t[0], c[1] - w * t[1]]),
                f32x2([c[0] + w * t[0], c[1] + w * t[1]]),
            ]);
        }
        rec.log(
            self.mag_surface.clone(),
            &LineStrips2D::new(ticks)
                .with_colors([rgb(OBSTACLE_COLOR)])
                .with_radii([Radius::new_ui_points(2.5)])
                .with_draw_order(DRAW_MAGNIFIED),
        )
    }

    /// One Newton iterate: at true scale over the rod (phase colour, with phase, pass and
    /// iteration as data), and magnified about the step's start.
    fn draw_iterate(
        &mut self,
        rec: &RecordingStream,
        style: &SceneStyle,
        r: usize,
        ev: &IterationEvent<'_>,
        obstacles: &[Obstacle],
    ) -> ::rerun::RecordingStreamResult<()> {
        let color = rgb(phase_color(ev.phase));
        let what = format!(
            "{} pass {} Newton iteration {}",
            ev.phase.as_str(),
            ev.pass,
            ev.iteration
        );
        let strip: Vec<[f32; 2]> = ev.q.chunks_exact(2).map(|c| f32x2([c[0], c[1]])).collect();
        let row = iterate_row(
            Some(strip),
            color,
            &[ev.phase.as_str()],
            &[ev.pass],
            &[ev.iteration],
            &[what.as_str()],
        );
        rec.log_serialized_batches(self.iterate.clone(), false, row)?;
        self.had_iterate = true;
        let k = style.magnify;
        if k <= 1.0 || self.reference.len() != ev.q.len() {
            return Ok(());
        }
        // The step-end drawings of the last step make way for the iterates (with the columns
        // of their own rows, so that clearing rows share their chunks).
        if self.surface_step != Some(ev.step) {
            let rad = style.rods[r].node_radius;
            rec.log(
                self.mag_predictor.clone(),
                &mag_predictor_points(Vec::new(), rad),
            )?;
            rec.log(self.mag_step.clone(), &mag_step_strip(Vec::new()))?;
            rec.log(
                self.mag_correction.clone(),
                &mag_correction_arrows(Vec::new(), Vec::new(), Vec::new(), rad),
            )?;
        }
        self.log_surface(rec, style, r, obstacles, ev.step)?;
        let n = ev.q.len() / 2;
        let mag: Vec<[f32; 2]> = (0..n)
            .map(|i| self.magnified(k, i, [ev.q[2 * i], ev.q[2 * i + 1]]))
            .collect();
        rec.log(
            self.mag_iterate.clone(),
            &mag_iterate_strip(
                vec![mag.clone()],
                color,
                vec![format!("{what}, motion ×{}", super::fmt_force(k))],
            ),
        )?;
        rec.log(
            self.mag_iterate_nodes.clone(),
            &mag_iterate_points(mag, color, style.rods[r].node_radius),
        )
    }

    /// At the step's end: the accepted positions and, on a corrected step, the predictor's
    /// and the correction, all magnified about the step's start; the iterates are cleared.
    fn draw_magnified(
        &mut self,
        rec: &RecordingStream,
        style: &SceneStyle,
        r: usize,
        v: &RodStepView<'_>,
        corrected: bool,
        _step: u64,
    ) -> ::rerun::RecordingStreamResult<Option<Vec<[f32; 2]>>> {
        let k = style.magnify;
        let mut strip = None;
        if self.had_iterate {
            // The same columns as an iterate's row (so both kinds of row share their chunks),
            // all empty.
            let row = iterate_row(None, rgb(ROD_COLOR), &[], &[], &[], &[]);
            rec.log_serialized_batches(self.iterate.clone(), false, row)?;
            let rad = style.rods[r].node_radius;
            rec.log(
                self.mag_iterate.clone(),
                &mag_iterate_strip(Vec::new(), rgb(ROD_COLOR), Vec::new()),
            )?;
            rec.log(
                self.mag_iterate_nodes.clone(),
                &mag_iterate_points(Vec::new(), rgb(ROD_COLOR), rad),
            )?;
            self.had_iterate = false;
        }
        if k > 1.0 && self.reference.len() == v.q.len() {
            let rad = style.rods[r].node_radius;
            let n = v.q.len() / 2;
            let at = |q: &[f64], i: usize| self.magnified(k, i, [q[2 * i], q[2 * i + 1]]);
            let end: Vec<[f32; 2]> = (0..n).map(|i| at(v.q, i)).collect();
            let corrected = corrected && v.q_predictor.len() == v.q.len();
            let (mut pred, mut orig, mut vecs, mut labels) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            if corrected {
                let dmax = (0..n)
                    .map(|i| {
                        (v.q[2 * i] - v.q_predictor[2 * i])
                            .hypot(v.q[2 * i + 1] - v.q_predictor[2 * i + 1])
                    })
                    .fold(0.0, f64::max);
                for i in 0..n {
                    let a = at(v.q_predictor, i);
                    pred.push(a);
                    let d = (v.q[2 * i] - v.q_predictor[2 * i])
                        .hypot(v.q[2 * i + 1] - v.q_predictor[2 * i + 1]);
                    if d > 0.05 * dmax && d > 0.0 {
                        orig.push(a);
                        vecs.push([end[i][0] - a[0], end[i][1] - a[1]]);
                        labels.push(format!(
                            "correction {} (×{})",
                            super::fmt_length(d),
                            super::fmt_force(k)
                        ));
                    }
                }
            }
            // Logged when there is a correction, and once (empty) after the last one.
            if corrected || self.had_mag_correction {
                rec.log(self.mag_predictor.clone(), &mag_predictor_points(pred, rad))?;
                rec.log(
                    self.mag_correction.clone(),
                    &mag_correction_arrows(orig, vecs, labels, rad),
                )?;
            }
            self.had_mag_correction = corrected;
            strip = Some(end);
        }
        self.surface_step = None;
        self.start.clear();
        self.start.extend_from_slice(v.q);
        self.start_u.clear();
        self.start_u.extend_from_slice(v.u);
        Ok(strip)
    }
}

// Draw order in the 2D view (higher on top).
const DRAW_OBSTACLES: f32 = 5.0;
/// Colour of a second run drawn for comparison ([`Look::Other`]).
pub const OTHER_COLOR: [u8; 3] = [80, 200, 255];
const DRAW_OTHER_ROD: f32 = 12.0;
const DRAW_OTHER_REACTIONS: f32 = 14.0;
const DRAW_OTHER_NODES: f32 = 16.0;
const DRAW_ROD: f32 = 20.0;
const DRAW_REACTIONS: f32 = 30.0;
const DRAW_NORMALS: f32 = 35.0;
const DRAW_NODES: f32 = 40.0;
const DRAW_PREDICTOR: f32 = 38.0;
const DRAW_MAGNIFIED: f32 = 45.0;
const DRAW_ITERATE: f32 = 50.0;
const DRAW_LEGEND: f32 = 60.0;

/// Text log levels.
struct TextLogLevelName;

impl TextLogLevelName {
    const INFO: &'static str = "INFO";
    const WARN: &'static str = "WARN";
    const ERROR: &'static str = "ERROR";
    const BOOKMARK: &'static str = "BOOKMARK";
}

fn rgb(c: [u8; 3]) -> Color {
    Color::from_rgb(c[0], c[1], c[2])
}

/// The fields of [`Event::Iteration`] that the recording uses.
struct IterationEvent<'a> {
    step: u64,
    t: f64,
    phase: Phase,
    pass: u32,
    iteration: u32,
    rod: usize,
    residual: f64,
    q: &'a [f64],
}

impl Observer for RerunSink {
    fn wants_iterations(&self) -> bool {
        self.opts.detail.iterations()
    }

    fn on_event(&mut self, event: &Event<'_>) {
        if self.rec.is_none() {
            return;
        }
        match *event {
            Event::RunStart(info) => self.run_start(info),
            Event::StepBegin { step, dt, .. } => {
                // After a gap (`--detail auto` left steps out) the last recorded state is not
                // this step's start: no free-flight reference, so no magnified view.
                let gap = self.last_step.is_some_and(|s| s + 1 != step);
                for e in &mut self.rods {
                    e.step_begin(dt);
                    if gap {
                        e.reference.clear();
                    }
                }
            }
            Event::Iteration {
                step,
                t,
                phase,
                pass,
                iteration,
                rod,
                residual,
                q,
                ..
            } => {
                if self.opts.detail.iterations() {
                    self.iteration(IterationEvent {
                        step,
                        t,
                        phase,
                        pass,
                        iteration,
                        rod,
                        residual,
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
            } => {
                let at = self.iteration;
                self.bookmark(
                    step,
                    t,
                    at,
                    format!("dt {old:e} s -> {new:e} s ({reason}) (t = {t:.6} s, step {step}, iteration {at})"),
                )
            }
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
                let at = self.iteration;
                self.text(
                    step,
                    t,
                    TextLogLevelName::WARN,
                    format!("step {step}: Newton failed on rod {name:?} node {node} with dt = {dt:e} s: {reason} (residual {residual:.3e} N)"),
                );
                self.bookmark(
                    step,
                    t,
                    at,
                    format!("Newton failed on rod {name:?} node {node}, retried with a smaller dt (t = {t:.6} s, step {step}, iteration {at})"),
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
                joints: _,
            } => {
                self.step_end(step, t, dt, newton_iterations, passes, rods);
                self.draw_pressure(step, t, rods, bodies, contacts);
                if !bodies.is_empty() {
                    self.draw_bodies(bodies, contacts);
                }
            }
            Event::RunEnd { steps, t, error } => {
                self.completed = error.is_none();
                self.end_bookmarks();
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of equal values is sent as its first and last points; the plot (linear between
    /// points) is the same as with every point.
    #[test]
    fn a_series_sends_the_ends_of_runs_of_equal_values() {
        let mut c = Column::default();
        let xs = [0.0, 0.0, 0.0, 0.0, 3.0, 3.0, 5.0, 0.0, 0.0, 0.0];
        for (k, x) in xs.iter().enumerate() {
            c.push((k as i64, k as f64 * 0.1, k as i64), &[*x]);
        }
        // Steps 0 and 3 (ends of the zeros), 4 and 5 (the threes), 6, 7 (then 8, 9 held).
        assert_eq!(c.times.step, [0, 3, 4, 5, 6, 7]);
        assert_eq!(c.values, [0.0, 0.0, 3.0, 3.0, 5.0, 0.0]);
        assert_eq!(c.held, Some((9, 0.9, 9)));
        c.release();
        assert_eq!(c.times.step, [0, 3, 4, 5, 6, 7, 9]);
        assert_eq!(c.values, [0.0, 0.0, 3.0, 3.0, 5.0, 0.0, 0.0]);
        // Linear interpolation between the sent points gives every value back.
        for (k, x) in xs.iter().enumerate().take(8) {
            let k = k as i64;
            let j = c.times.step.iter().rposition(|&s| s <= k).unwrap();
            let y = if c.times.step[j] == k {
                c.values[j]
            } else {
                let (s0, s1) = (c.times.step[j], c.times.step[j + 1]);
                let (y0, y1) = (c.values[j], c.values[j + 1]);
                y0 + (y1 - y0) * (k - s0) as f64 / (s1 - s0) as f64
            };
            assert_eq!(y, *x, "step {k}");
        }
    }

    /// A row of several values (one per node) is held back only when all of them repeat.
    #[test]
    fn a_row_is_held_only_when_every_value_repeats() {
        let mut c = Column::default();
        let rows = [[0.0, 1.0], [0.0, 1.0], [0.0, 2.0], [0.0, 2.0], [0.0, 2.0]];
        for (k, r) in rows.iter().enumerate() {
            c.push((k as i64, k as f64, k as i64), r);
        }
        assert_eq!(c.times.step, [0, 1, 2]);
        assert_eq!(c.values, [0.0, 1.0, 0.0, 1.0, 0.0, 2.0]);
        c.release();
        assert_eq!(c.times.step, [0, 1, 2, 4]);
        assert_eq!(c.values[6..], [0.0, 2.0]);
    }
}
