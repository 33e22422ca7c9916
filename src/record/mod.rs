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
/// a file.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    std::fs::create_dir_all(dir)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.partial"));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
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
}

/// A recording's path while it is written and after it is complete.
///
/// While the run lasts the file is `DIR/NAME.partial.EXT`; only a run that completed renames
/// it to `DIR/NAME.EXT`. A run that was interrupted, failed or was killed leaves the
/// `.partial` file (closed properly unless the process was killed), so a half run never sits
/// under the name of a whole one. An older file at the final path is removed when the new run
/// starts, so the final path never holds a recording of an earlier run next to this run's
/// partial file.
#[derive(Debug, Clone)]
pub struct OutputFile {
    pub path: PathBuf,
    pub partial: PathBuf,
}

impl OutputFile {
    pub fn new(path: &Path) -> Self {
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "recording".into());
        let name = match path.extension() {
            Some(ext) => format!("{stem}.partial.{}", ext.to_string_lossy()),
            None => format!("{stem}.partial"),
        };
        Self {
            path: path.to_path_buf(),
            partial: path.with_file_name(name),
        }
    }

    /// Make the directory, remove an older final file, and create the partial file.
    pub fn create(&self) -> Result<std::fs::File, RecordError> {
        let io = |source| RecordError::Io {
            path: self.partial.clone(),
            source,
        };
        if let Some(dir) = self.path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        match std::fs::remove_file(&self.path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(RecordError::Io {
                    path: self.path.clone(),
                    source: e,
                })
            }
            _ => {}
        }
        std::fs::File::create(&self.partial).map_err(io)
    }

    /// After the file was closed: make it durable, then rename it to its final name when
    /// `complete` (so a crash after the rename cannot leave a whole-looking file whose data
    /// never reached the disk).
    pub fn settle(&self, complete: bool) -> Result<Finished, RecordError> {
        std::fs::File::open(&self.partial)
            .and_then(|f| f.sync_all())
            .map_err(|source| RecordError::Io {
                path: self.partial.clone(),
                source,
            })?;
        if complete {
            std::fs::rename(&self.partial, &self.path).map_err(|source| RecordError::Io {
                path: self.path.clone(),
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
