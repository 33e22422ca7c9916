//! Rerun views of `replay check --rrd` and `replay diff --rrd` on 3D runs: the run fed to the
//! live 3D sink ([`crate::record::rerun3::Rrd3`], through [`super::three::drive`]) and the
//! findings logged on its stream right after each step, at the time it has just set:
//!
//! | entity | what |
//! |---|---|
//! | `scene/flags/spike/<rod>/node_<i>` | a ball where node i spiked, at its position then, from that step on (colour by kind) |
//! | `scene/flags/sticking/<rod>/node_<i>` | a ball where node i started to stick |
//! | `scene/flags/grasp/<kind>` | a ball at the fruit's centre where it slipped or was dropped |
//! | `scene/run_b/<rod>/centerline` | run B's rods (diff), cyan, interpolated at A's step times |
//! | `scene/largest_difference` | the node of the largest distance (diff): A's node to B's, from its time on |
//! | `diff/position/<rod>` | max over the rod's nodes of \|A − B\| (diff) |
//! | `events/flags` | one WARN row per step with a finding (the findings of that step joined) |
//! | `events/bookmarks` | the largest difference (diff), once, at its time |
//!
//! The 3D layout is the live one ([`crate::record::rerun3::blueprint3`]); a diff adds the
//! difference plot.

use super::diff3::Diff3Report;
use super::three::{self, AtB, Check3Report, Run3};
use super::ReplayError;
use crate::record::rerun::OTHER_COLOR;
use crate::record::rerun3::{blueprint3, blueprint3_with};
use crate::record::series_color;
use ::rerun::blueprint::TimeSeriesView;
use ::rerun::{
    Color, EntityPath, EntityPathPart, LineStrips3D, Points3D, Radius, RecordingStream, Scalars,
    SeriesLines, TextLog,
};
use std::path::Path;

const IMPACT_COLOR: [u8; 3] = [230, 40, 200];
const UNEXPLAINED_COLOR: [u8; 3] = [200, 0, 60];
const STICK_COLOR: [u8; 3] = [255, 150, 0];
const GRASP_COLOR: [u8; 3] = [255, 220, 0];
const DIFFERENCE_COLOR: [u8; 3] = [255, 30, 30];

fn color(c: [u8; 3]) -> Color {
    Color::from_rgb(c[0], c[1], c[2])
}

/// An entity path from parts (names may hold any character).
fn ent(parts: &[&str]) -> EntityPath {
    EntityPath::new(parts.iter().map(|p| EntityPathPart::new(*p)).collect())
}

fn f32s(a: [f64; 3]) -> [f32; 3] {
    a.map(|v| v as f32)
}

/// Where a finding is marked.
enum Place {
    /// Node `node` of rod `rod`.
    Node { rod: usize, node: usize },
    /// The first free body's centre.
    Fruit,
}

/// A finding to mark when the replay reaches its step.
struct Mark {
    step: u64,
    place: Place,
    entity: EntityPath,
    text: String,
    color: [u8; 3],
    /// Ball radius in section half extents.
    scale: f32,
}

/// The marks of a 3D check report, in step order.
fn marks(rep: &Check3Report) -> Vec<Mark> {
    let mut out = Vec::new();
    for s in &rep.spikes {
        out.push(Mark {
            step: s.step,
            place: Place::Node {
                rod: s.rod,
                node: s.node,
            },
            entity: ent(&[
                "scene",
                "flags",
                "spike",
                &s.rod_name,
                &format!("node_{}", s.node),
            ]),
            text: format!(
                "{} spike of rod {:?} node {}, step {} (t = {:.6} s): jump {:.3e} m/s over dt = {:.1e} s ({:.2e} m)",
                s.kind, s.rod_name, s.node, s.step, s.t, s.jump, s.dt, s.displacement
            ),
            color: if s.kind == "impact" {
                IMPACT_COLOR
            } else {
                UNEXPLAINED_COLOR
            },
            scale: 2.0,
        });
    }
    for s in &rep.sticking {
        out.push(Mark {
            step: s.step,
            place: Place::Node {
                rod: s.rod,
                node: s.node,
            },
            entity: ent(&[
                "scene",
                "flags",
                "sticking",
                &s.rod_name,
                &format!("node_{}", s.node),
            ]),
            text: format!(
                "sticking ({}) of rod {:?} node {}, steps {}-{} ({} changes)",
                s.rule, s.rod_name, s.node, s.step, s.last_step, s.count
            ),
            color: STICK_COLOR,
            scale: 2.6,
        });
    }
    for g in &rep.grasp {
        out.push(Mark {
            step: g.step,
            place: Place::Fruit,
            entity: ent(&["scene", "flags", "grasp", g.kind]),
            text: format!(
                "grasp {}: step {} (t = {:.6} s): the fruit moved {:.3e} m in the gripper (tolerance {:.3e} m)",
                g.kind, g.step, g.t, g.slip_m, g.hold_tolerance_m
            ),
            color: GRASP_COLOR,
            scale: 4.0,
        });
    }
    out.sort_by_key(|m| m.step);
    out
}

/// Log the marks whose step has come (`m` the step just logged).
fn log_marks(
    rec: &RecordingStream,
    marks: &[Mark],
    next: &mut usize,
    m: &crate::record::mcap3::Step3,
    half: f64,
) -> Result<(), ReplayError> {
    let fail = |e: ::rerun::RecordingStreamError| {
        ReplayError::new(format!("cannot log a flag marker: {e}"))
    };
    let mut texts = Vec::new();
    while *next < marks.len() && marks[*next].step <= m.step {
        let k = &marks[*next];
        *next += 1;
        let at = match k.place {
            Place::Node { rod, node } => m
                .rods
                .get(rod)
                .and_then(|r| r.x.get(3 * node..3 * node + 3))
                .map(|x| [x[0], x[1], x[2]]),
            Place::Fruit => m.bodies.first().and_then(|b| match b.position[..] {
                [x, y, z] => Some([x, y, z]),
                _ => None,
            }),
        };
        if let Some(at) = at {
            rec.log(
                k.entity.clone(),
                &Points3D::new([f32s(at)])
                    .with_colors([color(k.color)])
                    .with_radii([Radius::new_scene_units(k.scale * half as f32)]),
            )
            .map_err(fail)?;
        }
        texts.push(k.text.as_str());
    }
    if !texts.is_empty() {
        rec.log(
            "events/flags",
            &TextLog::new(texts.join("; ")).with_level("WARN"),
        )
        .map_err(fail)?;
    }
    Ok(())
}

/// The largest section half extent of a run's prong (m): the size of the markers.
fn half_extent(run: &Run3) -> f64 {
    let h = crate::rod3d::events::half_extents(&run.scenario.prong.section);
    h[0].max(h[1])
}

/// `replay check --rrd` on a 3D run: the run with its findings marked.
pub fn write_check(path: &Path, out: &Path, rep: &Check3Report) -> Result<(), ReplayError> {
    let run = Run3::load(path)?;
    let marks = marks(rep);
    let half = half_extent(&run);
    let mut next = 0;
    three::drive(
        path,
        &run,
        out,
        &format!("{} (check)", run.name),
        blueprint3(),
        |rec, m, _| log_marks(rec, &marks, &mut next, m, half),
    )?;
    Ok(())
}

/// `replay diff --rrd` on two 3D runs: A as recorded, B's rods in cyan at A's times, the
/// largest per-rod node distance plotted, and the node of the largest distance marked from its
/// time on (a line from A's node to B's), bookmarked once.
pub fn write_diff(a: &Path, b: &Path, out: &Path, rep: &Diff3Report) -> Result<(), ReplayError> {
    let (ra, rb) = (Run3::load(a)?, Run3::load(b)?);
    let names: Vec<String> = crate::rod3d::run3::build(&ra.scenario)
        .map(|(w, _)| w.rod_names)
        .map_err(|e| ReplayError::file(a, e))?;
    let extra = vec![
        TimeSeriesView::new("Node distance |A - B| (m), max per rod")
            .with_origin("/diff/position")
            .into(),
    ];
    let fail = |what: &str, e: ::rerun::RecordingStreamError| {
        ReplayError::new(format!("cannot log {what}: {e}"))
    };
    let half = half_extent(&ra);
    let mut j = 0;
    let mut told = false;
    let mut first = true;
    three::drive(
        a,
        &ra,
        out,
        &format!("{} vs {}", ra.name, rb.name),
        blueprint3_with(extra),
        |rec, m, _| {
            if first {
                first = false;
                for (r, name) in names.iter().enumerate() {
                    rec.log_static(
                        ent(&["diff", "position", name]),
                        &SeriesLines::new()
                            .with_colors([color(series_color(r))])
                            .with_names([name.as_str()]),
                    )
                    .map_err(|e| fail("a series style", e))?;
                }
            }
            let (b0, b1, w) = match three::locate_b(&rb, &mut j, m.t) {
                AtB::Between(k0, k1, w) => (&rb.steps[k0], &rb.steps[k1], w),
                _ => return Ok(()),
            };
            let mut b_nodes: Vec<Vec<[f64; 3]>> = Vec::new();
            for (r, ra_rod) in m.rods.iter().enumerate().take(b0.rods.len()) {
                let n = ra_rod.x.len() / 3;
                let nodes: Vec<[f64; 3]> = (0..n)
                    .map(|i| three::node_between(b0, b1, w, r, i))
                    .collect();
                let name = names.get(r).map_or("rod", String::as_str);
                rec.log(
                    ent(&["scene", "run_b", name, "centerline"]),
                    &LineStrips3D::new([nodes.iter().map(|p| f32s(*p)).collect::<Vec<_>>()])
                        .with_colors([color(OTHER_COLOR)]),
                )
                .map_err(|e| fail("run B", e))?;
                let d = (0..n)
                    .map(|i| {
                        let x = &ra_rod.x[3 * i..3 * i + 3];
                        let p = nodes[i];
                        ((x[0] - p[0]).powi(2) + (x[1] - p[1]).powi(2) + (x[2] - p[2]).powi(2))
                            .sqrt()
                    })
                    .fold(0.0f64, f64::max);
                rec.log(ent(&["diff", "position", name]), &Scalars::single(d))
                    .map_err(|e| fail("a difference", e))?;
                b_nodes.push(nodes);
            }
            if m.t >= rep.t && rep.max_distance > 0.0 {
                let pa = m
                    .rods
                    .get(rep.rod)
                    .and_then(|r| r.x.get(3 * rep.node..3 * rep.node + 3))
                    .map(|x| [x[0], x[1], x[2]]);
                let pb = b_nodes.get(rep.rod).and_then(|v| v.get(rep.node)).copied();
                if let (Some(pa), Some(pb)) = (pa, pb) {
                    let label = format!(
                        "largest difference: {} node {}, {:.3e} m at t = {:.6} s",
                        rep.rod_name, rep.node, rep.max_distance, rep.t
                    );
                    rec.log(
                        ent(&["scene", "largest_difference"]),
                        &LineStrips3D::new([[f32s(pa), f32s(pb)]])
                            .with_colors([color(DIFFERENCE_COLOR)])
                            .with_radii([Radius::new_ui_points(3.0)])
                            .with_labels([label.clone()]),
                    )
                    .map_err(|e| fail("the difference marker", e))?;
                    rec.log(
                        ent(&["scene", "largest_difference", "node"]),
                        &Points3D::new([f32s(pa)])
                            .with_colors([color(DIFFERENCE_COLOR)])
                            .with_radii([Radius::new_scene_units(2.0 * half as f32)]),
                    )
                    .map_err(|e| fail("the difference marker", e))?;
                    if !told {
                        told = true;
                        rec.log(
                            ent(&["events", "bookmarks"]),
                            &TextLog::new(format!(
                                "★ {label} (A step {}; tolerance {:e} m)",
                                m.step, rep.tol_position
                            ))
                            .with_level("BOOKMARK"),
                        )
                        .map_err(|e| fail("an event", e))?;
                    }
                }
            }
            Ok(())
        },
    )?;
    Ok(())
}
