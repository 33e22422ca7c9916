//! Sinks: each one implementation of [`crate::events::Observer`].
//!
//! - [`summary`]: the run summary (peaks, contact counts, final state).
//! - [`rerun`]: a Rerun `.rrd` recording with a blueprint, for looking at a run.
//! - [`mcap`]: an MCAP file of JSON messages (plus a Foxglove scene), the archival record that
//!   a replay rebuilds a run from.
//! - [`csv`]: one tidy row per step, rod and node, for spreadsheets and data frames.
//!
//! The file sinks share [`OutputFile`] (write under a `.partial` name, rename when the run
//! completed) and the [`Recording`] trait (finish the file and say where it is).

pub mod accepted;
pub mod auto;
pub mod background;
pub mod csv;
pub mod csv3;
pub mod files;
pub mod foxglove;
pub mod grasp;
pub mod mcap;
pub mod mcap3;
mod mcap_file;
pub mod plan;
pub mod pressure;
pub mod proto;
pub mod rerun;
pub mod rerun3;
pub mod shape3;
pub mod summary;
pub mod summary_text;

use crate::events::{Observer, RodStepView};
use crate::obstacle::Obstacle;
pub use plan::{Held, OutputPlan};
use std::path::{Path, PathBuf};

/// Colour of free bodies (fruit) in the scene.
pub const BODY_COLOR: [u8; 3] = [214, 96, 45];
/// Colour of friction force arrows.
pub const FRICTION_COLOR: [u8; 3] = [250, 200, 40];

/// The outline of a free body at its pose in a step (for drawing).
pub fn body_outline(
    shape: &Obstacle,
    specs: &[crate::world::body::BodySpec],
    b: &crate::events::BodyView<'_>,
    style: &SceneStyle,
) -> Vec<[f64; 2]> {
    let c0 = specs
        .iter()
        .find(|s| s.obstacle == b.obstacle)
        .map_or(crate::events::xy(b.position), |s| s.centroid);
    let placed = crate::world::body::Placed {
        shape,
        c0,
        pose: crate::world::body::Pose {
            c: crate::events::xy(b.position),
            theta: b.angle,
        },
    };
    let mut pts: Vec<[f64; 2]> = shape
        .outline(style.lo, style.hi)
        .into_iter()
        .map(|p| placed.to_world(p))
        .collect();
    // A spoke from the centre to the outline shows the body's rotation.
    if let Some(first) = pts.first().copied() {
        pts.push(crate::events::xy(b.position));
        pts.push(first);
    }
    pts
}

/// Write a file atomically: to a temporary sibling, then rename, so a reader never sees half
/// a file. A device or FIFO at `path` (e.g. `/dev/null`) is written through, never replaced; a
/// symlink to a regular file keeps pointing at the new file; a directory is refused before
/// anything is written. On a write error nothing is left behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write as _;
    let out = OutputFile::new(path);
    let plain = |e: RecordError| match e {
        RecordError::Io { source, .. } => source,
        RecordError::Write { message, .. } => std::io::Error::other(message),
    };
    let mut file = out.create().map_err(plain)?;
    let written = file.write_all(bytes).and_then(|_| file.flush());
    drop(file);
    if let Err(e) = written {
        out.discard();
        return Err(e);
    }
    out.settle(true).map(drop).map_err(|e| {
        out.discard();
        plain(e)
    })
}

/// How much a recording holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Detail {
    /// The state at the end of every step, contact changes and solver events.
    #[default]
    Step,
    /// Also every Newton iteration of every predictor and corrector pass.
    Iteration,
    /// What matters ([`auto`]): every step with its Newton iterations in windows around
    /// every event (contact change, stick/slip switch, dt change, Newton trouble, warning,
    /// actuation phase change, a flagged spike), every k-th step elsewhere, the first and the
    /// last step. A sink given this detail records what it is given (iterations included);
    /// the [`auto::AutoDetail`] layer in front of it decides what that is.
    Auto(AutoRule),
}

/// The numbers of `--detail auto`: every `every`-th step outside the windows, windows of
/// `window` steps before and after each event. `every` = 0: not chosen yet (chosen from the
/// scenario by [`auto::AutoRule::for_scenario`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AutoRule {
    pub every: u64,
    pub window: u64,
}

impl Detail {
    pub fn as_str(self) -> &'static str {
        match self {
            Detail::Step => "step",
            Detail::Iteration => "iteration",
            Detail::Auto(_) => "auto",
        }
    }

    /// "step", "iteration", or "auto (every 100th step, windows of 20 steps around events)".
    pub fn describe(self) -> String {
        match self {
            Detail::Auto(a) if a.every <= 1 => format!(
                "auto (every step, windows of {} steps around events)",
                a.window
            ),
            Detail::Auto(a) => format!(
                "auto (every {}{} step, windows of {} steps around events)",
                a.every,
                ordinal_suffix(a.every),
                a.window
            ),
            d => d.as_str().to_string(),
        }
    }

    /// Whether a sink records the Newton iterations it is given.
    pub fn iterations(self) -> bool {
        !matches!(self, Detail::Step)
    }

    /// The rule of `--detail auto`, if that is the detail.
    pub fn auto(self) -> Option<AutoRule> {
        match self {
            Detail::Auto(r) => Some(r),
            _ => None,
        }
    }
}

/// "st", "nd", "rd" or "th" after a number.
pub fn ordinal_suffix(n: u64) -> &'static str {
    match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    }
}

impl std::str::FromStr for Detail {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "step" => Ok(Detail::Step),
            "iteration" => Ok(Detail::Iteration),
            "auto" => Ok(Detail::Auto(AutoRule::default())),
            _ => Err(format!(
                "unknown detail {s:?}: expected auto, step or iteration"
            )),
        }
    }
}

/// Options shared by the file sinks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordOptions {
    pub detail: Detail,
    /// Make the file readable up to here every this many steps (at least 1).
    pub flush_every: u64,
}

impl Default for RecordOptions {
    fn default() -> Self {
        Self {
            detail: Detail::Step,
            flush_every: 100,
        }
    }
}

/// Why a recording could not be written.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
}

impl RecordError {
    pub fn write(path: &Path, message: impl std::fmt::Display) -> Self {
        RecordError::Write {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}

/// A finished recording file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finished {
    /// Where the file is now.
    pub path: PathBuf,
    /// True when the run completed and the file has its final name; false when the run
    /// stopped early (the file is closed properly but keeps its `.partial` name).
    pub complete: bool,
}

/// A sink that writes a file: an observer that can be finished once the run is over.
pub trait Recording: Observer {
    /// A short name of the format ("rerun", "mcap", "csv").
    fn format(&self) -> &'static str;
    /// Close the file (write its footer) and, when the run completed, give it its final name.
    /// Call once, after [`crate::Simulation::run`] returned.
    fn finish(&mut self) -> Result<Finished, RecordError>;
    /// A flag the sink sets when writing failed (disk full, a write error): the caller polls
    /// it to stop the run at once instead of computing steps that cannot be recorded.
    fn failure(&self) -> Option<std::sync::Arc<std::sync::atomic::AtomicBool>> {
        None
    }
}

/// What is at an output path before the run, and so how it is written.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Target {
    /// Nothing, or a regular file (possibly behind symlinks): write a `.partial` sibling of
    /// the file and rename it onto the file when the run completed.
    File,
    /// A character device or FIFO (possibly behind symlinks), e.g. `/dev/null`: written
    /// through, never replaced, no `.partial` file and no rename.
    Through,
    /// Something that cannot take a recording (a directory, a socket, a block device, a
    /// dangling symlink): refused before anything is written, with this reason.
    Refused(String),
}

/// Starts the disk writes of a regular file being recorded at each flush, without waiting
/// for them (Linux: `sync_file_range` with `SYNC_FILE_RANGE_WRITE`; elsewhere nothing), so
/// that the `fsync` at the end ([`OutputFile::settle`]) finds only the last flush's pages
/// left: 0.3 ms instead of 2-4 ms per file of the two-prong grasp on this machine's disk,
/// time in which the cores stood idle (docs/performance.md, "Recording cost"). Durability
/// is the `fsync`'s; this only moves the writing earlier, beside the run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Writeback {
    /// The file's descriptor (regular files only: a device or FIFO is written through).
    fd: Option<i32>,
}

impl Writeback {
    /// For `file`, whose writer keeps it open for as long as [`Writeback::start`] is called.
    pub(crate) fn of(file: &std::fs::File) -> Self {
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsRawFd;
            let regular = file.metadata().is_ok_and(|m| m.is_file());
            Self {
                fd: regular.then(|| file.as_raw_fd()),
            }
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = file;
            Self { fd: None }
        }
    }

    /// Start writing what has reached the file so far (its dirty pages) to the disk. Call
    /// only while the file is open (after its writer's buffer was flushed). A hint: an error
    /// is ignored, the `fsync` at the end reports what matters.
    pub(crate) fn start(self) {
        #[cfg(target_os = "linux")]
        if let Some(fd) = self.fd {
            // SAFETY: `fd` is the descriptor of a file its writer holds open (see `of`); the
            // call only queues the file's dirty pages for writing, offset 0 and length 0
            // meaning the whole file.
            unsafe { libc::sync_file_range(fd, 0, 0, libc::SYNC_FILE_RANGE_WRITE) };
        }
    }
}

/// A recording's path while it is written and after it is complete.
///
/// While the run lasts the file is `DIR/NAME.partial.EXT`; only a run that completed renames
/// it to `DIR/NAME.EXT`. A run that was interrupted, failed or was killed leaves the
/// `.partial` file (closed properly unless the process was killed), so a half run never sits
/// under the name of a whole one. An older file at the final path is left as it is until the
/// rename replaces it: a run that does not complete never destroys the result of an earlier
/// one (the final name then holds the last completed run, the `.partial` file beside it the
/// one that stopped).
///
/// When the path is held by an [`OutputPlan`] ([`Held`]), [`OutputFile::settle`] of a
/// completed file leaves the rename to [`Held::commit`], which renames all the command's
/// outputs together once every one of them was written.
///
/// Only a regular file (or nothing) at the path is ever renamed onto: a symlink is followed
/// (the new file replaces the file it points at, the link stays), a character device or
/// FIFO (`/dev/null`, a named pipe) is written through, and a directory, socket, block device
/// or dangling symlink is refused with a clear error before the run starts
/// ([`OutputFile::check`]).
#[derive(Debug, Clone)]
pub struct OutputFile {
    /// The path as given.
    pub path: PathBuf,
    /// The `.partial` file written while the run lasts (beside the file a symlink points at).
    /// Never created when the path is a device or FIFO.
    pub partial: PathBuf,
    /// The regular file the partial file becomes (`path` with its symlinks resolved).
    final_path: PathBuf,
    target: Target,
}

/// `NAME.EXT` → `NAME.partial.EXT` in the same folder.
fn partial_name(path: &Path) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "recording".into());
    let name = match path.extension() {
        Some(ext) => format!("{stem}.partial.{}", ext.to_string_lossy()),
        None => format!("{stem}.partial"),
    };
    path.with_file_name(name)
}

/// What is at `path`: its kind, and the regular file path it stands for.
fn classify(path: &Path) -> (Target, PathBuf) {
    use std::os::unix::fs::FileTypeExt;
    let Ok(link) = std::fs::symlink_metadata(path) else {
        return (Target::File, path.to_path_buf());
    };
    let resolved = if link.file_type().is_symlink() {
        match std::fs::canonicalize(path) {
            Ok(p) => p,
            Err(e) => {
                // A link to a file not made yet, in a folder that exists: the new file is made
                // there (as writing through the link would). Else refused.
                let target = std::fs::read_link(path).ok().map(|t| {
                    path.parent()
                        .filter(|_| t.is_relative())
                        .map_or(t.clone(), |dir| dir.join(&t))
                });
                let in_a_folder = target.as_ref().and_then(|t| {
                    let dir = std::fs::canonicalize(t.parent()?).ok()?;
                    Some(dir.join(t.file_name()?))
                });
                return match in_a_folder {
                    Some(t) if std::fs::symlink_metadata(&t).is_err() => (Target::File, t),
                    _ => (
                        Target::Refused(format!(
                            "is a symlink that leads nowhere ({e}); remove it or point it at a file"
                        )),
                        path.to_path_buf(),
                    ),
                };
            }
        }
    } else {
        path.to_path_buf()
    };
    let Ok(meta) = std::fs::metadata(&resolved) else {
        return (Target::File, resolved);
    };
    let ft = meta.file_type();
    let target = if ft.is_file() {
        Target::File
    } else if ft.is_dir() {
        Target::Refused("is a directory; give a file name".into())
    } else if ft.is_char_device() || ft.is_fifo() {
        Target::Through
    } else if ft.is_block_device() {
        Target::Refused(
            "is a block device (a disk); recordings go to a file, or to a character device \
             such as /dev/null"
                .into(),
        )
    } else {
        Target::Refused("is a socket; give a file name".into())
    };
    (target, resolved)
}

impl OutputFile {
    pub fn new(path: &Path) -> Self {
        let (target, final_path) = classify(path);
        let partial = match target {
            Target::File => partial_name(&final_path),
            // Never created; named for callers that clean up after a failed run.
            _ => partial_name(path),
        };
        Self {
            path: path.to_path_buf(),
            partial,
            final_path,
            target,
        }
    }

    /// Where the bytes go while the run lasts: the partial file, or the device itself.
    pub fn writing(&self) -> &Path {
        match self.target {
            Target::Through => &self.path,
            _ => &self.partial,
        }
    }

    /// True when the path is a device or FIFO that is written through.
    pub fn is_through(&self) -> bool {
        self.target == Target::Through
    }

    /// The error for a path that cannot take the file (a directory, a socket, a dangling
    /// symlink), before anything is written.
    pub fn check(&self) -> Result<(), RecordError> {
        match &self.target {
            Target::Refused(why) => Err(RecordError::write(&self.path, why)),
            _ => Ok(()),
        }
    }

    /// Make the directory and create the partial file (or open the device). An older final
    /// file stays until the partial file is renamed onto it.
    pub fn create(&self) -> Result<std::fs::File, RecordError> {
        self.check()?;
        if self.target == Target::Through {
            return open_through(&self.path);
        }
        let io = |source| RecordError::Io {
            path: self.partial.clone(),
            source,
        };
        if let Some(dir) = self
            .final_path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
        {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        // A leftover partial file of an earlier run goes; whatever else sits under that name
        // (a symlink planted there) is not followed: the new file is created exclusively.
        if std::fs::symlink_metadata(&self.partial).is_ok_and(|m| !m.is_dir()) {
            std::fs::remove_file(&self.partial).map_err(io)?;
        }
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&self.partial)
            .map_err(io)
    }

    /// After a sink closed its file: on the sink's `error` remove the partial file and report
    /// the error naming the path; else [`OutputFile::settle`]. Returns where the file is.
    pub fn conclude(&self, error: Option<String>, complete: bool) -> Result<PathBuf, String> {
        if let Some(e) = error {
            self.discard();
            return Err(format!("{}: {e}", self.path.display()));
        }
        self.settle(complete)
            .map(|f| f.path)
            .map_err(|e| e.to_string())
    }

    /// Remove the partial file of a failed write (nothing for a device).
    pub fn discard(&self) {
        if self.target == Target::File {
            let _ = std::fs::remove_file(&self.partial);
        }
    }

    /// After the file was closed: make it durable, then rename it to its final name when
    /// `complete` (so a crash after the rename cannot leave a whole-looking file whose data
    /// never reached the disk). A device is left as it is. A file held by an [`OutputPlan`]
    /// stays under its partial name, for [`Held::commit`] to rename with the command's other
    /// outputs.
    pub fn settle(&self, complete: bool) -> Result<Finished, RecordError> {
        if self.target == Target::Through {
            return Ok(Finished {
                path: self.path.clone(),
                complete,
            });
        }
        std::fs::File::open(&self.partial)
            .and_then(|f| f.sync_all())
            .map_err(|source| RecordError::Io {
                path: self.partial.clone(),
                source,
            })?;
        if complete && plan::is_held(&self.partial) {
            return Ok(Finished {
                path: self.path.clone(),
                complete: true,
            });
        }
        if complete {
            std::fs::rename(&self.partial, &self.final_path).map_err(|source| RecordError::Io {
                path: self.final_path.clone(),
                source,
            })?;
            Ok(Finished {
                path: self.path.clone(),
                complete: true,
            })
        } else {
            Ok(Finished {
                path: self.partial.clone(),
                complete: false,
            })
        }
    }
}

/// Open a device or FIFO for writing without creating, truncating or replacing it. A FIFO
/// nobody reads is refused at once instead of blocking the run forever.
fn open_through(path: &Path) -> Result<std::fs::File, RecordError> {
    use std::os::unix::fs::OpenOptionsExt;
    use std::os::unix::io::AsRawFd;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| {
            if e.raw_os_error() == Some(libc::ENXIO) {
                RecordError::write(path, "is a FIFO that nobody reads")
            } else {
                RecordError::Io {
                    path: path.to_path_buf(),
                    source: e,
                }
            }
        })?;
    // Blocking writes from here on (the flag was only for the open).
    // SAFETY: fcntl on a file descriptor we own, with flags read from it.
    unsafe {
        let fd = file.as_raw_fd();
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
        }
    }
    Ok(file)
}

/// An error with its causes: "I/O error from writing…: No space left on device (os error 28)".
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !s.contains(&text) {
            s.push_str(": ");
            s.push_str(&text);
        }
        cause = c.source();
    }
    s
}

fn error_reason(e: &RecordError) -> String {
    match e {
        RecordError::Io { source, .. } => source.to_string(),
        RecordError::Write { message, .. } => message.clone(),
    }
}

/// A box around the rods' shape, the bounded obstacles and the nearest points of the unbounded
/// ones (planes, sines), with a margin of half its size: where unbounded obstacles are drawn
/// when nothing is known of the run beyond its first state (see [`Survey`] for the box of
/// the whole run).
pub fn scene_box(rods: &[RodStepView<'_>], obstacles: &[Obstacle]) -> ([f64; 2], [f64; 2]) {
    let mut b = BoxAcc::default();
    for o in obstacles {
        let unbounded = matches!(o, Obstacle::Plane(_) | Obstacle::Sine(_));
        if unbounded {
            // The part of the surface the rods face: the closest point to every node.
            for r in rods {
                for p in r.q.chunks_exact(2) {
                    b.add(o.query([p[0], p[1]]).closest);
                }
            }
        } else {
            for p in o.outline([0.0; 2], [0.0; 2]) {
                b.add(p);
            }
        }
    }
    for r in rods {
        b.add_all(r.q);
    }
    b.with_margin(0.5)
}

/// A growing axis-aligned box.
#[derive(Debug, Clone, Copy)]
pub struct BoxAcc {
    pub lo: [f64; 2],
    pub hi: [f64; 2],
}

impl Default for BoxAcc {
    fn default() -> Self {
        Self {
            lo: [f64::INFINITY; 2],
            hi: [f64::NEG_INFINITY; 2],
        }
    }
}

impl BoxAcc {
    pub fn add(&mut self, p: [f64; 2]) {
        for a in 0..2 {
            if p[a].is_finite() {
                self.lo[a] = self.lo[a].min(p[a]);
                self.hi[a] = self.hi[a].max(p[a]);
            }
        }
    }

    /// Add every point of an interleaved `[x0, y0, x1, y1, …]` array.
    pub fn add_all(&mut self, q: &[f64]) {
        for p in q.chunks_exact(2) {
            self.add([p[0], p[1]]);
        }
    }

    pub fn is_empty(&self) -> bool {
        !(self.lo[0] <= self.hi[0] && self.lo[1] <= self.hi[1])
    }

    /// The box grown on every side by `margin` × its larger size (at least 1 mm);
    /// ±1 m when empty.
    pub fn with_margin(&self, margin: f64) -> ([f64; 2], [f64; 2]) {
        if self.is_empty() {
            return ([-1.0, -1.0], [1.0, 1.0]);
        }
        let size = (self.hi[0] - self.lo[0])
            .max(self.hi[1] - self.lo[1])
            .max(1e-3);
        let m = margin * size;
        (
            [self.lo[0] - m, self.lo[1] - m],
            [self.hi[0] + m, self.hi[1] + m],
        )
    }
}

/// What a whole run does, known before it is recorded: the sinks draw with it so that every
/// frame of a recording shares one force scale and one drawing box chosen from the run itself.
///
/// `gripsim run` makes it with a first, unrecorded run of the scenario ([`Survey::of`]: the
/// physics alone, deterministic, so the recorded run does exactly the same); `gripsim replay`
/// with a first pass over the stored steps. Feed it [`Event::StepEnd`]s through its
/// [`Observer`] implementation.
#[derive(Debug, Clone, Copy)]
pub struct Survey {
    /// Every node position (and predictor position) of every step.
    pub visited: BoxAcc,
    /// The largest eq. 2 reaction |R| of any node at any step (N).
    pub force_max: f64,
    /// The largest corrector correction |q − q_predictor| of any node at any step (m).
    pub correction_max: f64,
    /// The largest departure of a free node from free flight in one step,
    /// |q − (q_previous + dt u_previous)| (m).
    pub motion_max: f64,
    /// Steps seen.
    pub steps: u64,
    prev_valid: bool,
}

impl Default for Survey {
    fn default() -> Self {
        Self {
            visited: BoxAcc::default(),
            force_max: 0.0,
            correction_max: 0.0,
            motion_max: 0.0,
            steps: 0,
            prev_valid: false,
        }
    }
}

/// [`Survey`] with the previous step's positions (for the per-step motion).
#[derive(Debug, Default)]
pub struct SurveyObserver {
    pub survey: Survey,
    clamped: Vec<Vec<bool>>,
    prev: Vec<Vec<f64>>,
    prev_u: Vec<Vec<f64>>,
}

/// The survey looks at most this many steps (the first ones): a long run starts recording
/// after a bounded delay, and the scales stay deterministic.
pub const SURVEY_MAX_STEPS: u64 = 200_000;

impl Survey {
    /// Run `scenario` unrecorded and survey it (its first [`SURVEY_MAX_STEPS`] steps). The
    /// run's error, if any, is ignored here: the recorded run that follows meets it again and
    /// reports it.
    pub fn of(
        scenario: &crate::Scenario,
        interrupt: Option<Box<dyn Fn() -> bool + Send>>,
    ) -> Survey {
        let mut sim = crate::Simulation::new(scenario);
        let steps = std::sync::atomic::AtomicU64::new(0);
        sim.interrupt = Some(Box::new(move || {
            let n = steps.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            n >= SURVEY_MAX_STEPS || interrupt.as_ref().is_some_and(|f| f())
        }));
        let mut obs = SurveyObserver::default();
        let _ = sim.run(&mut obs);
        obs.survey
    }
}

impl SurveyObserver {
    /// Take in one accepted step of size `dt`.
    pub fn step(&mut self, dt: f64, rods: &[RodStepView<'_>]) {
        let s = &mut self.survey;
        s.steps += 1;
        if self.prev.len() != rods.len() {
            self.prev = rods.iter().map(|v| v.q.to_vec()).collect();
            self.prev_u = rods.iter().map(|v| v.u.to_vec()).collect();
            s.prev_valid = false;
        }
        for (r, v) in rods.iter().enumerate() {
            s.visited.add_all(v.q);
            let n = v.in_contact.len();
            let corrected = v.q_predictor.len() == v.q.len();
            if corrected {
                s.visited.add_all(v.q_predictor);
            }
            for i in 0..n {
                s.force_max = s.force_max.max(node_norm(v.reaction, i));
                if corrected {
                    let d = (v.q[2 * i] - v.q_predictor[2 * i])
                        .hypot(v.q[2 * i + 1] - v.q_predictor[2 * i + 1]);
                    s.correction_max = s.correction_max.max(d);
                }
                let clamped = self
                    .clamped
                    .get(r)
                    .and_then(|c| c.get(i))
                    .copied()
                    .unwrap_or(false);
                if s.prev_valid && !clamped {
                    let (p, u) = (&self.prev[r], &self.prev_u[r]);
                    let d = (v.q[2 * i] - p[2 * i] - dt * u[2 * i])
                        .hypot(v.q[2 * i + 1] - p[2 * i + 1] - dt * u[2 * i + 1]);
                    if d.is_finite() {
                        s.motion_max = s.motion_max.max(d);
                    }
                }
            }
            self.prev[r].copy_from_slice(v.q);
            self.prev_u[r].copy_from_slice(v.u);
        }
        s.prev_valid = true;
    }
}

impl Observer for SurveyObserver {
    fn on_event(&mut self, event: &crate::events::Event<'_>) {
        match event {
            crate::events::Event::RunStart(info) => {
                self.clamped = info.rods.iter().map(|r| r.clamped.clone()).collect();
            }
            crate::events::Event::StepEnd {
                dt, rods, bodies, ..
            } => {
                self.step(*dt, rods);
                // Free bodies (fruit): their centroids; the margin covers their size.
                for b in bodies.iter() {
                    self.survey.visited.add(crate::events::xy(b.position));
                }
            }
            _ => {}
        }
    }
}

/// The part of the segment a–b inside the box `[lo, hi]` (Liang–Barsky), if any.
pub fn clip_segment(
    a: [f64; 2],
    b: [f64; 2],
    lo: [f64; 2],
    hi: [f64; 2],
) -> Option<([f64; 2], [f64; 2])> {
    let d = [b[0] - a[0], b[1] - a[1]];
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..2 {
        for (p, q) in [(-d[k], a[k] - lo[k]), (d[k], hi[k] - a[k])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
    }
    (t0 <= t1).then(|| {
        (
            [a[0] + t0 * d[0], a[1] + t0 * d[1]],
            [a[0] + t1 * d[0], a[1] + t1 * d[1]],
        )
    })
}

/// An obstacle's outline for drawing: bounded obstacles whole, planes and sines clipped to the
/// box `[lo, hi]` (one polyline per piece inside the box).
pub fn obstacle_outline(o: &Obstacle, lo: [f64; 2], hi: [f64; 2]) -> Vec<Vec<[f64; 2]>> {
    let line = o.outline(lo, hi);
    if !matches!(o, Obstacle::Plane(_) | Obstacle::Sine(_)) {
        return vec![line];
    }
    let mut pieces: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut open = false;
    for w in line.windows(2) {
        match clip_segment(w[0], w[1], lo, hi) {
            Some((a, b)) => {
                if !open {
                    pieces.push(vec![a]);
                    open = true;
                }
                let piece = pieces.last_mut().expect("opened above");
                piece.push(b);
                // Leaving the box: close this piece.
                if b != w[1] {
                    open = false;
                }
            }
            None => open = false,
        }
    }
    pieces
}

/// 64-bit FNV-1a: a hash that is the same on every machine and every build (for recording ids).
pub fn stable_hash(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// |(v[2i], v[2i+1])|, the magnitude of node i's vector in an interleaved array.
#[inline]
pub fn node_norm(v: &[f64], i: usize) -> f64 {
    let (x, y) = (v[2 * i], v[2 * i + 1]);
    // Most nodes carry no reaction: skip libm's `hypot` there (hypot(±0, ±0) = +0 too).
    if x == 0.0 && y == 0.0 {
        0.0
    } else {
        x.hypot(y)
    }
}

/// How force arrows are scaled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ArrowScale {
    /// Length proportional to the force: one scale for the whole recording.
    #[default]
    Linear,
    /// Length proportional to log10(1 + f/f0), f0 = a thousandth of the run's largest force:
    /// three decades of force on one picture (the scale bar gives two points of the curve).
    Log,
}

impl ArrowScale {
    pub fn as_str(self) -> &'static str {
        match self {
            ArrowScale::Linear => "linear",
            ArrowScale::Log => "log",
        }
    }
}

impl std::str::FromStr for ArrowScale {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "linear" => Ok(ArrowScale::Linear),
            "log" => Ok(ArrowScale::Log),
            _ => Err(format!("unknown arrow scale {s:?}: expected linear or log")),
        }
    }
}

/// What the drawing sinks (Rerun, MCAP `/scene`) draw with beyond the record options: the
/// run's [`Survey`] (its force range, the region it visits, its corrections) and the arrow
/// scale.
#[derive(Debug, Clone, Copy, Default)]
pub struct ViewOptions {
    pub survey: Option<Survey>,
    pub arrows: ArrowScale,
}

/// How the scene is drawn, shared by the Rerun and the Foxglove (MCAP `/scene`) views, fixed
/// before the first step so that every frame uses the same scales.
#[derive(Debug, Clone)]
pub struct SceneStyle {
    /// The drawing box: the region the run visits plus a margin (see [`Survey`]), or around
    /// the first state when there is no survey. Planes and sines are clipped to it.
    pub lo: [f64; 2],
    pub hi: [f64; 2],
    pub rods: Vec<RodStyle>,
    pub forces: ForceScale,
    /// Magnification of the step motion and of the corrector's correction (1 = none), see
    /// [`SceneStyle::magnification`].
    pub magnify: f64,
}

/// The one force scale of a recording: arrow length and node colour from |R|.
#[derive(Debug, Clone, Copy)]
pub struct ForceScale {
    pub mode: ArrowScale,
    /// The largest force of the run (N): the top of the colour scale.
    pub force_max: f64,
    /// A round length (m) and the force (N) an arrow of that length shows: the scale bar.
    pub unit_length: f64,
    pub unit_force: f64,
    /// Log mode: f0 (N).
    pub f0: f64,
}

impl ForceScale {
    /// A scale for forces up to `force_max` whose longest arrow is at most `target` long:
    /// `unit_length` is a power of ten below `target`, `unit_force` the 1-2-5 number of N it
    /// stands for (linear), or the run's largest force drawn `target` long (log).
    pub fn new(mode: ArrowScale, force_max: f64, target: f64) -> Self {
        let force_max = if force_max.is_finite() && force_max > 0.0 {
            force_max
        } else {
            1.0
        };
        let unit_length = 10f64.powi(target.log10().floor() as i32);
        let unit_force = match mode {
            ArrowScale::Linear => nice_up(force_max * unit_length / target),
            ArrowScale::Log => force_max,
        };
        let unit_length = match mode {
            ArrowScale::Linear => unit_length,
            ArrowScale::Log => target,
        };
        Self {
            mode,
            force_max,
            unit_length,
            unit_force,
            f0: 1e-3 * force_max,
        }
    }

    /// Arrow length (m) of a force of magnitude `f` (N).
    pub fn length(&self, f: f64) -> f64 {
        if !(f > 0.0) {
            return 0.0;
        }
        match self.mode {
            ArrowScale::Linear => f * self.unit_length / self.unit_force,
            ArrowScale::Log => {
                self.unit_length * (1.0 + f / self.f0).log10()
                    / (1.0 + self.unit_force / self.f0).log10()
            }
        }
    }

    /// Node colour of a force `f`: the colour map over 0 … `force_max`.
    pub fn color(&self, f: f64) -> [u8; 3] {
        colormap((f / self.force_max).clamp(0.0, 1.0))
    }

    /// What the scale bar says: "1 cm = 5 N" (linear) or "log: 3 cm = 194.4 N".
    pub fn bar_label(&self) -> String {
        let tag = match self.mode {
            ArrowScale::Linear => "",
            ArrowScale::Log => "log: ",
        };
        format!(
            "{tag}{} = {} N",
            fmt_length(self.unit_length),
            fmt_force(self.unit_force)
        )
    }

    /// What the legend says.
    pub fn describe(&self) -> String {
        let bar = match self.mode {
            ArrowScale::Linear => format!(
                "arrows linear: {} = {} N",
                fmt_length(self.unit_length),
                fmt_force(self.unit_force)
            ),
            ArrowScale::Log => format!(
                "arrows log10(1 + f/{} N): {} = {} N",
                fmt_force(self.f0),
                fmt_length(self.unit_length),
                fmt_force(self.unit_force)
            ),
        };
        format!("{bar}; colour 0 … {} N", fmt_force(self.force_max))
    }
}

/// The smallest 1, 2, 5 × 10^k at or above `x` (> 0).
pub fn nice_up(x: f64) -> f64 {
    if !(x > 0.0) || !x.is_finite() {
        return 1.0;
    }
    let e = 10f64.powi(x.log10().floor() as i32);
    for m in [1.0, 2.0, 5.0, 10.0] {
        if m * e >= x * (1.0 - 1e-12) {
            return m * e;
        }
    }
    10.0 * e
}

/// The largest 1, 2, 5 × 10^k at or below `x` (> 0).
pub fn nice_down(x: f64) -> f64 {
    if !(x > 0.0) || !x.is_finite() {
        return 1.0;
    }
    let e = 10f64.powi(x.log10().floor() as i32);
    for m in [10.0, 5.0, 2.0, 1.0] {
        if m * e <= x * (1.0 + 1e-12) {
            return m * e;
        }
    }
    e
}

/// A length for a label: "1 cm", "0.1 mm", "2 µm" …
pub fn fmt_length(m: f64) -> String {
    let (v, unit) = if m >= 1.0 {
        (m, "m")
    } else if m >= 1e-2 {
        (m * 100.0, "cm")
    } else if m >= 1e-3 {
        (m * 1e3, "mm")
    } else {
        (m * 1e6, "µm")
    };
    format!("{} {unit}", fmt_g(v))
}

/// A force for a label, with 4 significant digits and no trailing zeros.
pub fn fmt_force(f: f64) -> String {
    fmt_g(f)
}

fn fmt_g(v: f64) -> String {
    let mut s = String::new();
    push_g(&mut s, v);
    s
}

/// Append `v` with four significant digits, trailing zeros dropped (`3.451`, `120`, `0`), to
/// `out`: the force labels of every step, written in place (no string of their own).
pub fn push_g(out: &mut String, v: f64) {
    use std::fmt::Write as _;
    if v == 0.0 {
        out.push('0');
        return;
    }
    let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let start = out.len();
    let _ = write!(out, "{v:.digits$}");
    if out[start..].contains('.') {
        let kept = out[start..]
            .trim_end_matches('0')
            .trim_end_matches('.')
            .len();
        out.truncate(start + kept);
    }
}

/// Sizes of one rod's drawing (all lengths in m).
#[derive(Debug, Clone, Copy)]
pub struct RodStyle {
    /// Radius of the node markers.
    pub node_radius: f64,
    /// Length of a contact normal arrow.
    pub normal_length: f64,
    /// The rod's length (a particle: a fifth of the drawing box).
    pub reach: f64,
}

impl SceneStyle {
    /// The style of a run: from `survey` when there is one (the box the run visits, its force
    /// range, its corrections), else from the first state alone.
    pub fn new(
        rods: &[crate::events::RodInfo],
        first: &[RodStepView<'_>],
        obstacles: &[Obstacle],
        survey: Option<&Survey>,
        arrows: ArrowScale,
    ) -> Self {
        let (lo, hi) = match survey {
            Some(s) if !s.visited.is_empty() => s.visited.with_margin(0.15),
            _ => scene_box(first, obstacles),
        };
        let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let rods: Vec<RodStyle> = rods
            .iter()
            .map(|r| {
                let length: f64 = r.rest_length.iter().sum();
                let shortest = r.rest_length.iter().copied().fold(f64::INFINITY, f64::min);
                let node_radius = if shortest.is_finite() {
                    (0.25 * shortest).min(0.01 * size)
                } else {
                    0.02 * size // a particle
                };
                let reach = if length > 0.0 { length } else { 0.2 * size };
                RodStyle {
                    node_radius,
                    normal_length: 0.12 * reach,
                    reach,
                }
            })
            .collect();
        let reach = rods.iter().map(|r| r.reach).fold(0.0, f64::max).max(1e-6);
        let weight: f64 = rods_weight(first.len(), survey);
        let force_max = survey.map(|s| s.force_max).filter(|f| *f > 0.0);
        let forces = ForceScale::new(arrows, force_max.unwrap_or(weight), 0.3 * reach);
        let magnify = survey.map(|s| Self::magnification(s, reach)).unwrap_or(1.0);
        Self {
            lo,
            hi,
            rods,
            forces,
            magnify,
        }
    }

    /// A round magnification (1, 2, 5 × 10^k) that draws the run's largest corrector correction
    /// a tenth of the rod long, but its largest one-step departure from free flight at most
    /// half the rod long; 1 when that would not magnify.
    pub fn magnification(s: &Survey, reach: f64) -> f64 {
        let mut k = f64::INFINITY;
        if s.correction_max > 0.0 {
            k = k.min(0.1 * reach / s.correction_max);
        }
        if s.motion_max > 0.0 {
            k = k.min(0.5 * reach / s.motion_max);
        }
        if !k.is_finite() || k < 2.0 {
            return 1.0;
        }
        nice_down(k)
    }

    /// What the magnified view says.
    pub fn describe_magnify(&self) -> String {
        format!(
            "departure from free flight ×{} (1 mm = {})",
            fmt_g(self.magnify),
            fmt_length(1e-3 / self.magnify)
        )
    }
}

/// A stand-in force range before anything is known: 1 N per rod.
fn rods_weight(rods: usize, _survey: Option<&Survey>) -> f64 {
    rods.max(1) as f64
}

/// Viridis (a perceptually uniform colour map), from its 0.25 point (a blue that reads on the
/// viewer's dark background) at `x` = 0 to yellow at `x` = 1.
pub fn colormap(x: f64) -> [u8; 3] {
    // Viridis at 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.
    const STOPS: [[f64; 3]; 7] = [
        [59.0, 82.0, 139.0],
        [44.0, 114.0, 142.0],
        [33.0, 145.0, 140.0],
        [39.0, 173.0, 129.0],
        [94.0, 201.0, 98.0],
        [170.0, 220.0, 50.0],
        [253.0, 231.0, 37.0],
    ];
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let f = x * (STOPS.len() - 1) as f64;
    let k = (f.floor() as usize).min(STOPS.len() - 2);
    let u = f - k as f64;
    let c = |a: usize| (STOPS[k][a] + u * (STOPS[k + 1][a] - STOPS[k][a])).round() as u8;
    [c(0), c(1), c(2)]
}

/// Distinct series colours: 20 qualitative colours, then golden-angle hues at alternating
/// lightness, so any number of series get different colours, the same ones in every recording.
pub fn series_color(i: usize) -> [u8; 3] {
    const BASE: [[u8; 3]; 20] = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
        [227, 119, 194],
        [188, 189, 34],
        [23, 190, 207],
        [250, 250, 250],
        [174, 199, 232],
        [255, 187, 120],
        [152, 223, 138],
        [255, 152, 150],
        [197, 176, 213],
        [196, 156, 148],
        [247, 182, 210],
        [219, 219, 141],
        [158, 218, 229],
        [160, 160, 160],
    ];
    if i < BASE.len() {
        return BASE[i];
    }
    let k = i - BASE.len();
    let h = (k as f64 * 137.507_764) % 360.0;
    let l = [0.55, 0.7, 0.4][k % 3];
    hsl(h, 0.75, l)
}

fn hsl(h: f64, s: f64, l: f64) -> [u8; 3] {
    let c = (1.0 - (2.0 * l - 1.0).abs()) * s;
    let hp = h / 60.0;
    let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = l - c / 2.0;
    let v = |a: f64| ((a + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    [v(r), v(g), v(b)]
}

/// Colour of the rigid obstacles.
pub const OBSTACLE_COLOR: [u8; 3] = [110, 170, 90];
/// Colour of the rods' centre lines.
pub const ROD_COLOR: [u8; 3] = [150, 160, 180];
/// Colour of the driven (clamped) nodes.
pub const DRIVEN_COLOR: [u8; 3] = [120, 120, 120];
/// Colour of the contact normal arrows (drawn beside the reaction, not over it).
pub const NORMAL_COLOR: [u8; 3] = [235, 235, 235];
/// Colour of the eq. 2 reaction arrows.
pub const REACTION_COLOR: [u8; 3] = [240, 50, 50];
/// Colour of predictor iterates and positions.
pub const PREDICTOR_COLOR: [u8; 3] = [255, 160, 0];
/// Colour of corrector iterates.
pub const CORRECTOR_COLOR: [u8; 3] = [235, 70, 235];
/// Colour of static load-step iterates.
pub const STATIC_COLOR: [u8; 3] = [120, 200, 255];

/// The colour of an iterate of `phase`.
pub fn phase_color(phase: crate::events::Phase) -> [u8; 3] {
    match phase {
        crate::events::Phase::Predictor => PREDICTOR_COLOR,
        crate::events::Phase::Corrector => CORRECTOR_COLOR,
        crate::events::Phase::Static => STATIC_COLOR,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_numbers_round_to_1_2_5() {
        assert_eq!(nice_up(64.8), 100.0);
        assert_eq!(nice_up(1.5), 2.0);
        assert_eq!(nice_up(5.0), 5.0);
        assert_eq!(nice_down(1282.0), 1000.0);
        assert_eq!(nice_down(475.0), 200.0);
        assert_eq!(nice_down(0.03), 0.02);
    }

    #[test]
    fn linear_arrows_are_proportional_and_within_the_target() {
        // The seed grasp: 194.4471 N largest, rod 0.1 m long, target 0.03 m.
        let s = ForceScale::new(ArrowScale::Linear, 194.4471, 0.03);
        assert!((s.unit_length - 0.01).abs() < 1e-15 && s.unit_force == 100.0);
        assert_eq!(s.bar_label(), "1 cm = 100 N");
        let (a, b) = (s.length(194.4471), s.length(3.9));
        assert!((a / b - 194.4471 / 3.9).abs() < 1e-12);
        assert!(a <= 0.03 && (a - 0.01944471).abs() < 1e-12);
        assert_eq!(s.length(0.0), 0.0);
        // Log: the largest force is drawn at the target length, smaller ones longer than linear.
        let l = ForceScale::new(ArrowScale::Log, 194.4471, 0.03);
        assert!((l.length(194.4471) - 0.03).abs() < 1e-12);
        assert!(l.length(3.9) > 0.3 * l.length(194.4471));
    }

    #[test]
    fn segments_are_clipped_to_the_box() {
        let (lo, hi) = ([0.0, 0.0], [1.0, 1.0]);
        let (a, b) = clip_segment([-1.0, 0.5], [2.0, 0.5], lo, hi).unwrap();
        assert_eq!((a, b), ([0.0, 0.5], [1.0, 0.5]));
        assert!(clip_segment([-1.0, 2.0], [2.0, 2.0], lo, hi).is_none());
        // A plane through the box is drawn only inside it.
        let plane = Obstacle::Plane(crate::obstacle::Plane::new([0.0, 0.0], [1.0, 0.0]));
        let lines = obstacle_outline(&plane, [-0.01, -0.12], [0.02, 0.01]);
        assert_eq!(lines.len(), 1);
        for p in &lines[0] {
            assert!(p[1] >= -0.12 - 1e-12 && p[1] <= 0.01 + 1e-12, "{p:?}");
        }
    }

    #[test]
    fn series_colours_differ() {
        let c: std::collections::BTreeSet<[u8; 3]> = (0..60).map(series_color).collect();
        assert_eq!(c.len(), 60);
    }

    /// A regular file's pages are started for the disk and its bytes stay its own; a FIFO
    /// (made here, in a temporary folder) is written through and never synced.
    #[test]
    fn writeback_starts_for_regular_files_only() {
        use std::io::Write as _;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        let mut file = std::fs::File::create(&path).unwrap();
        let bytes: Vec<u8> = (0..100_000u32).map(|i| (i % 251) as u8).collect();
        file.write_all(&bytes).unwrap();
        let wb = Writeback::of(&file);
        assert_eq!(wb.fd.is_some(), cfg!(target_os = "linux"));
        wb.start();
        file.write_all(&bytes[..10]).unwrap();
        wb.start();
        file.sync_all().unwrap();
        drop(file);
        let back = std::fs::read(&path).unwrap();
        assert_eq!(back.len(), 100_010);
        assert!(back[..100_000] == bytes[..] && back[100_000..] == bytes[..10]);
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::ffi::OsStrExt as _;
            let fifo = dir.path().join("fifo");
            let c = std::ffi::CString::new(fifo.as_os_str().as_bytes()).unwrap();
            // SAFETY: a valid C string; creates a FIFO in the temporary folder.
            assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
            // Read and write: opening a FIFO so does not wait for a reader.
            let f = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(&fifo)
                .unwrap();
            let wb = Writeback::of(&f);
            assert!(wb.fd.is_none());
            wb.start();
        }
    }

    /// Labels are written in place after what the string holds: four significant digits,
    /// trailing zeros dropped, as `fmt_force` gives them.
    #[test]
    fn push_g_appends_four_significant_digits() {
        for (v, text) in [
            (3.4512, "3.451"),
            (120.0, "120"),
            (0.0, "0"),
            (1e-5, "0.00001"),
            (-2.5, "-2.5"),
            (194.4471, "194.4"),
            (12345.6, "12346"),
        ] {
            let mut s = String::from("B ");
            push_g(&mut s, v);
            assert_eq!(s, format!("B {text}"));
            assert_eq!(fmt_force(v), text);
        }
    }
}
