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
pub mod csv;
pub mod grasp;
pub mod mcap;
pub mod rerun;
pub mod summary;

use crate::events::{Observer, RodStepView};
use crate::obstacle::Obstacle;
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
        .map_or(b.position, |s| s.centroid);
    let placed = crate::world::body::Placed {
        shape,
        c0,
        pose: crate::world::body::Pose {
            c: b.position,
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
        pts.push(b.position);
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
}

impl Detail {
    pub fn as_str(self) -> &'static str {
        match self {
            Detail::Step => "step",
            Detail::Iteration => "iteration",
        }
    }
}

impl std::str::FromStr for Detail {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "step" => Ok(Detail::Step),
            "iteration" => Ok(Detail::Iteration),
            _ => Err(format!("unknown detail {s:?}: expected step or iteration")),
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
    /// A device or FIFO (possibly behind symlinks), e.g. `/dev/null`: written through, never
    /// replaced, no `.partial` file and no rename.
    Through,
    /// Something that cannot take a recording (a directory, a socket, a dangling symlink):
    /// refused before anything is written, with this reason.
    Refused(String),
}

/// A recording's path while it is written and after it is complete.
///
/// While the run lasts the file is `DIR/NAME.partial.EXT`; only a run that completed renames
/// it to `DIR/NAME.EXT`. A run that was interrupted, failed or was killed leaves the
/// `.partial` file (closed properly unless the process was killed), so a half run never sits
/// under the name of a whole one. An older file at the final path is removed when the new run
/// starts, so the final path never holds a recording of an earlier run next to this run's
/// partial file.
///
/// Only a regular file (or nothing) at the path is ever removed or renamed onto: a symlink is
/// followed (the new file replaces the file it points at, the link stays), a device or FIFO
/// (`/dev/null`, a named pipe) is written through, and a directory, socket or dangling
/// symlink is refused with a clear error before the run starts ([`OutputFile::check`]).
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
    } else if ft.is_char_device() || ft.is_block_device() || ft.is_fifo() {
        Target::Through
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

    /// Make the directory, remove an older final file, and create the partial file (or open
    /// the device).
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
        match std::fs::remove_file(&self.final_path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(RecordError::Io {
                    path: self.final_path.clone(),
                    source: e,
                })
            }
            _ => {}
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

    /// Remove the partial file of a failed write (nothing for a device).
    pub fn discard(&self) {
        if self.target == Target::File {
            let _ = std::fs::remove_file(&self.partial);
        }
    }

    /// After the file was closed: make it durable, then rename it to its final name when
    /// `complete` (so a crash after the rename cannot leave a whole-looking file whose data
    /// never reached the disk). A device is left as it is.
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

/// The identity of a path for [`check_distinct`]: its device and inode when it exists, and
/// its absolute path with symlinks resolved as far as they exist.
#[derive(Debug, Clone, PartialEq, Eq)]
struct PathId {
    inode: Option<(u64, u64)>,
    char_device: bool,
    canonical: PathBuf,
}

fn path_id(p: &Path) -> PathId {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    let meta = std::fs::metadata(p).ok();
    let canonical = std::fs::canonicalize(p).unwrap_or_else(|_| {
        // Not there yet: resolve the folder, keep the name.
        let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let mut parts: Vec<std::ffi::OsString> = Vec::new();
        let mut dir = abs.as_path();
        loop {
            if let Ok(c) = std::fs::canonicalize(dir) {
                let mut out = c;
                for part in parts.iter().rev() {
                    out.push(part);
                }
                return normalize(&out);
            }
            match (dir.file_name(), dir.parent()) {
                (Some(name), Some(parent)) => {
                    parts.push(name.to_os_string());
                    dir = parent;
                }
                _ => return normalize(&abs),
            }
        }
    });
    PathId {
        inode: meta.as_ref().map(|m| (m.dev(), m.ino())),
        char_device: meta.is_some_and(|m| m.file_type().is_char_device()),
        canonical,
    }
}

/// `a/./b/../c` → `a/c` (lexically; only for paths that do not exist yet).
fn normalize(p: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Check, before a command writes anything, that its outputs are different files from each
/// other (also through symlinks, `./`, `..` and hard links, and counting the `.partial` file
/// each one is written as) and from every input, and that each output path can take a file.
/// `outputs` and `inputs` are (what, path) pairs, e.g. ("--rrd", "out/r.rrd"); the error is
/// one line naming both. The same character device (`/dev/null`) may take several outputs.
pub fn check_distinct(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> Result<(), String> {
    struct Entry<'a> {
        what: &'a str,
        path: &'a Path,
        ids: Vec<PathId>,
        is_output: bool,
    }
    let mut entries: Vec<Entry> = Vec::new();
    for &(what, path) in inputs {
        entries.push(Entry {
            what,
            path,
            ids: vec![path_id(path)],
            is_output: false,
        });
    }
    for &(what, path) in outputs {
        let out = OutputFile::new(path);
        out.check()
            .map_err(|e| format!("{what} {}: {}", path.display(), error_reason(&e)))?;
        let mut ids = vec![path_id(path)];
        if !out.is_through() {
            ids.push(path_id(&out.final_path));
            ids.push(path_id(&out.partial));
        }
        entries.push(Entry {
            what,
            path,
            ids,
            is_output: true,
        });
    }
    for (j, b) in entries.iter().enumerate() {
        for a in &entries[..j] {
            if !(a.is_output || b.is_output) {
                continue;
            }
            let clash = a.ids.iter().any(|x| {
                b.ids.iter().any(|y| {
                    let same =
                        x.canonical == y.canonical || (x.inode.is_some() && x.inode == y.inode);
                    same && !(x.char_device && y.char_device && a.is_output && b.is_output)
                })
            });
            if clash {
                let role = if a.is_output { "" } else { " (an input)" };
                return Err(format!(
                    "{} {} and {} {}{role} are the same file (or one is the other's .partial file): give each output its own path",
                    b.what,
                    b.path.display(),
                    a.what,
                    a.path.display()
                ));
            }
        }
    }
    Ok(())
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
/// ones (planes, sines), with a margin of half its size: where unbounded obstacles are drawn.
pub fn scene_box(rods: &[RodStepView<'_>], obstacles: &[Obstacle]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut add = |p: [f64; 2]| {
        for a in 0..2 {
            if p[a].is_finite() {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
    };
    for o in obstacles {
        let unbounded = matches!(o, Obstacle::Plane(_) | Obstacle::Sine(_));
        if unbounded {
            // The part of the surface the rods face: the closest point to every node.
            for r in rods {
                for p in r.q.chunks_exact(2) {
                    add(o.query([p[0], p[1]]).closest);
                }
            }
        } else {
            for p in o.outline([0.0; 2], [0.0; 2]) {
                add(p);
            }
        }
    }
    for r in rods {
        for p in r.q.chunks_exact(2) {
            add([p[0], p[1]]);
        }
    }
    if !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
        return ([-1.0, -1.0], [1.0, 1.0]);
    }
    let size = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3);
    let m = 0.5 * size;
    ([lo[0] - m, lo[1] - m], [hi[0] + m, hi[1] + m])
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
    v[2 * i].hypot(v[2 * i + 1])
}

/// How the scene is drawn, shared by the Rerun and the Foxglove (MCAP `/scene`) views, fixed at
/// the first step so that every frame uses the same scale.
#[derive(Debug, Clone)]
pub struct SceneStyle {
    /// The drawing box (see [`scene_box`]).
    pub lo: [f64; 2],
    pub hi: [f64; 2],
    pub rods: Vec<RodStyle>,
}

/// Sizes and force scale of one rod's drawing (all lengths in m).
#[derive(Debug, Clone, Copy)]
pub struct RodStyle {
    /// Radius of the node markers.
    pub node_radius: f64,
    /// Length of a contact normal arrow.
    pub normal_length: f64,
    /// Length a reaction arrow tends to for very large forces.
    pub reaction_length: f64,
    /// The rod's weight (N): a reaction of this size is drawn half-way up the colour and
    /// length scales (see [`RodStyle::level`]).
    pub force_ref: f64,
}

impl SceneStyle {
    pub fn new(
        rods: &[crate::events::RodInfo],
        first: &[RodStepView<'_>],
        obstacles: &[Obstacle],
    ) -> Self {
        let (lo, hi) = scene_box(first, obstacles);
        let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let rods = rods
            .iter()
            .map(|r| {
                let length: f64 = r.rest_length.iter().sum();
                let shortest = r.rest_length.iter().copied().fold(f64::INFINITY, f64::min);
                let node_radius = if shortest.is_finite() {
                    (0.25 * shortest).min(0.01 * size)
                } else {
                    0.04 * size // a particle
                };
                let reach = if length > 0.0 { length } else { 0.2 * size };
                RodStyle {
                    node_radius,
                    normal_length: 0.12 * reach,
                    reaction_length: 0.25 * reach,
                    force_ref: (r.mass.iter().sum::<f64>() * 9.81).max(1e-9),
                }
            })
            .collect();
        Self { lo, hi, rods }
    }
}

impl RodStyle {
    /// Where a force of magnitude `f` sits on the colour and arrow-length scales, in [0, 1):
    /// f / (f + weight). Saturating, so a 200 N impact and a 1 N resting contact both read.
    pub fn level(&self, f: f64) -> f64 {
        if f > 0.0 {
            f / (f + self.force_ref)
        } else {
            0.0
        }
    }

    /// Colour of a node carrying a force at `level`: blue (free) to red (large reaction).
    pub fn heat(level: f64) -> [u8; 3] {
        let s = level.clamp(0.0, 1.0);
        let mix = |a: f64, b: f64| (a + (b - a) * s).round() as u8;
        [mix(40.0, 230.0), mix(100.0, 30.0), mix(230.0, 30.0)]
    }
}

/// Colour of the rigid obstacles.
pub const OBSTACLE_COLOR: [u8; 3] = [110, 170, 90];
/// Colour of the rods' centre lines.
pub const ROD_COLOR: [u8; 3] = [120, 130, 150];
/// Colour of the driven (clamped) nodes.
pub const DRIVEN_COLOR: [u8; 3] = [120, 120, 120];
/// Colour of the contact normal arrows.
pub const NORMAL_COLOR: [u8; 3] = [250, 180, 20];
