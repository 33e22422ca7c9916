//! Rerun views of stored runs.
//!
//! A stored run is turned back into the events of a live run and fed to the live
//! [`RerunSink`], so `replay show` gives the same entities, timelines and layout as
//! `gripsim run --rrd`. The overlays of `check --rrd` and `diff --rrd` are logged on the sink's
//! stream right after each step, at the time the sink has just set:
//!
//! | entity | what |
//! |---|---|
//! | `scene/run_b/<rod>/nodes`, `…/centerline` | run B, light grey, at A's step times (interpolated) |
//! | `scene/flags/spike/<rod>/node_<i>` | a ring where node i spiked, from that step on (colour by kind) |
//! | `scene/flags/sticking/<rod>/node_<i>` | a ring where node i started to stick |
//! | `scene/flags/run_b/…` | the same for run B's findings (diff), thinner |
//! | `scene/divergence` | the first divergence: a ring at A's node, labelled with the quantity |
//! | `diff/position/<rod>`, `diff/velocity/<rod>` | max over the rod's nodes of \|A − B\| (diff) |
//! | `events` | one WARN line per finding and for the first divergence |

use super::detect::{Findings, Spike, Sticking};
use super::diff::{locate, DiffReport};
use super::read::{read_messages, Message, Meta, Run, Step};
use super::{CheckReport, ReplayError};
use crate::events::{Event, Observer, RodInfo, RodStepView, RunInfo};
use crate::record::rerun::{blueprint, blueprint_with, Look, RerunSink, RodEntities, OTHER_COLOR};
use crate::record::{
    Detail, RecordOptions, Recording, SceneStyle, Survey, SurveyObserver, ViewOptions,
};
use crate::scenario::Scenario;
use ::rerun::blueprint::{Blueprint, TimeSeriesView};
use ::rerun::{
    Color, EntityPath, EntityPathPart, LineStrips2D, Radius, RecordingStream, Scalars, TextLog,
};
use std::path::Path;

/// What `show` wrote.
#[derive(Debug, Clone)]
pub struct Shown {
    pub steps: usize,
    /// Set when the MCAP was read only in part.
    pub warning: Option<String>,
}

/// Owned arrays a [`RodStepView`] borrows that the MCAP stores differently.
struct Views {
    obstacles: Vec<Vec<usize>>,
    obstacles2: Vec<Vec<usize>>,
    normals2: Vec<Vec<f64>>,
}

impl Views {
    fn of(step: &Step) -> Self {
        Self {
            obstacles: step
                .rods
                .iter()
                .map(|r| {
                    r.contact_obstacle
                        .iter()
                        .map(|o| o.unwrap_or(usize::MAX))
                        .collect()
                })
                .collect(),
            obstacles2: step
                .rods
                .iter()
                .map(|r| {
                    let n = r.in_contact.len();
                    (0..n)
                        .map(|i| r.contact_obstacle2.get(i).copied().flatten())
                        .map(|o| o.unwrap_or(usize::MAX))
                        .collect()
                })
                .collect(),
            normals2: step.rods.iter().map(|r| r.normal2_or_zero()).collect(),
        }
    }

    fn views<'a>(&'a self, step: &'a Step) -> Vec<RodStepView<'a>> {
        step.rods
            .iter()
            .zip(&self.obstacles)
            .zip(self.obstacles2.iter().zip(&self.normals2))
            .map(|((v, o), (o2, n2))| RodStepView {
                dim: 2,
                twist_stress: &[],
                frames: None,
                q: &v.q,
                u: &v.u,
                reaction: &v.reaction,
                impulse: &v.impulse,
                drive_force: &v.drive_force,
                normal: &v.normal,
                contact_obstacle: o,
                normal2: n2,
                contact_obstacle2: o2,
                in_contact: &v.in_contact,
                bending_stress: &v.bending_stress,
                gap: &v.gap,
                q_predictor: &v.q_predictor,
            })
            .collect()
    }
}

/// What a stored run's drive needs to know about the sink it creates.
struct SinkSpec {
    name: String,
    text: String,
    blueprint: Blueprint,
    iterations: bool,
}

/// Read `path` in file order and feed it to a [`RerunSink`] writing `out`, calling
/// `after_step(stream, step, style)` after each step has been logged. Returns the steps read
/// and the read status warning.
fn drive(
    path: &Path,
    out: &Path,
    iterations: bool,
    spec: impl FnOnce(&Meta) -> SinkSpec,
    mut after_step: impl FnMut(&RecordingStream, &Step, &SceneStyle) -> Result<(), ReplayError>,
) -> Result<Shown, ReplayError> {
    let werr = |e: crate::record::RecordError| ReplayError::file(out, e.to_string());
    let survey = survey_stored(path)?;
    let mut spec = Some(spec);
    let mut sink: Option<RerunSink> = None;
    let mut scenario: Option<Scenario> = None;
    let mut infos: Vec<RodInfo> = Vec::new();
    let mut style: Option<SceneStyle> = None;
    let mut steps = 0usize;
    let mut last: Option<(u64, f64)> = None;
    // The stored run has no step-begin messages: send one at the first message of each step,
    // and again after a dt change (a retry): dt is the step's own when its /sim/step comes
    // first, else the last one known (the scenario's, the last step's, the dt change's).
    let mut begun = Begun::default();
    let mut ended = false;
    let status = read_messages(path, iterations, |m| {
        match m {
            Message::Meta(meta) => {
                let sc = super::read::parse_scenario(path, &meta)?;
                let s = (spec.take().expect("one /sim/meta"))(&meta);
                let opts = RecordOptions {
                    detail: match (s.iterations, meta.auto_every) {
                        // A decimated recording keeps its rule (the .rrd's text says it).
                        (true, Some(every)) if meta.detail == "auto" => {
                            Detail::Auto(crate::record::AutoRule {
                                every,
                                window: meta.auto_window.unwrap_or(0),
                            })
                        }
                        (true, _) => Detail::Iteration,
                        _ => Detail::Step,
                    },
                    flush_every: meta.flush_every.max(1),
                };
                let mut k = RerunSink::create_named(out, opts, &s.name, &s.text, s.blueprint)
                    .map_err(werr)?
                    .with_view(ViewOptions {
                        survey: Some(survey),
                        ..ViewOptions::default()
                    });
                infos = meta.rods.iter().map(|r| r.info()).collect();
                let info = RunInfo {
                    dimension: 2,
                    scene: crate::events::Scene::Planar {
                        obstacles: &sc.obstacles,
                    },
                    scenario_name: &meta.scenario_name,
                    scenario_text: &meta.scenario_text,
                    rods: &infos,
                    obstacle_names: &sc.obstacle_names,
                    bodies: &sc.bodies,
                    mode: sc.solve.mode,
                };
                k.on_event(&Event::RunStart(&info));
                begun.dt = sc.solve.dt;
                sink = Some(k);
                scenario = Some(sc);
            }
            Message::Step(st) => {
                let k = sink.as_mut().expect("meta first");
                let owned = Views::of(&st);
                let views = owned.views(&st);
                if st.step > 0 {
                    begun.begin(k, st.step, st.t - st.dt, Some(st.dt));
                }
                k.on_event(&Event::StepEnd {
                    step: st.step,
                    t: st.t,
                    dt: st.dt,
                    newton_iterations: st.newton_iterations,
                    passes: st.passes,
                    rods: &views,
                    bodies: &[],
                    contacts: &[],
                    joints: &[],
                });
                if style.is_none() {
                    style = k.style().cloned();
                }
                steps += 1;
                last = Some((st.step, st.t));
                if let Some(rec) = k.stream() {
                    after_step(rec, &st, style.as_ref().expect("set above"))?;
                }
            }
            Message::Contact(c) => {
                let k = sink.as_mut().expect("meta first");
                begun.begin(k, c.step, c.t, None);
                if c.added() {
                    k.on_event(&Event::ConstraintAdded(c.change()));
                } else {
                    k.on_event(&Event::ConstraintReleased(c.change(), c.release_reason()));
                }
            }
            Message::Iteration(it) => {
                let k = sink.as_mut().expect("meta first");
                begun.begin(k, it.step, it.t, None);
                k.on_event(&Event::Iteration {
                    step: it.step,
                    t: it.t,
                    phase: it.phase,
                    pass: it.pass,
                    iteration: it.iteration,
                    rod: it.rod,
                    residual: it.residual,
                    update: it.update,
                    q: &it.q,
                });
            }
            Message::Event(e) => {
                let Some(k) = sink.as_mut() else {
                    return Ok(());
                };
                let reason = e.reason.as_deref().unwrap_or("");
                match e.kind.as_str() {
                    "dt_changed" => {
                        begun.step = None;
                        begun.dt = e.new_dt.unwrap_or(begun.dt);
                        k.on_event(&Event::DtChanged {
                            step: e.step,
                            t: e.t,
                            old: e.old_dt.unwrap_or(0.0),
                            new: e.new_dt.unwrap_or(0.0),
                            reason,
                        })
                    }
                    "newton_failed" => k.on_event(&Event::NewtonFailed {
                        step: e.step,
                        t: e.t,
                        dt: e.dt.unwrap_or(0.0),
                        rod: e.rod.unwrap_or(0),
                        node: e.node.unwrap_or(0),
                        residual: e.residual.unwrap_or(0.0),
                        reason,
                    }),
                    "run_end" => {
                        ended = true;
                        k.on_event(&Event::RunEnd {
                            steps: e.step,
                            t: e.t,
                            error: e.error.as_deref(),
                        });
                    }
                    // "warning" and kinds of later format versions: shown as warnings.
                    _ => k.on_event(&Event::Warning {
                        step: e.step,
                        t: e.t,
                        message: &e.message,
                    }),
                }
            }
        }
        Ok(())
    });
    let status = match status {
        Ok(s) => s,
        Err(e) => {
            // A refused input leaves no half-written .rrd behind.
            if let Some(k) = sink.take() {
                drop(k);
                let _ = std::fs::remove_file(crate::record::OutputFile::new(out).partial);
            }
            return Err(e);
        }
    };
    let mut k = sink.expect("read_messages checks /sim/meta");
    let warning = status.truncated.as_ref().map(|why| {
        let (s, t) = last.unwrap_or((0, 0.0));
        format!(
            "warning: {} is incomplete ({why}); read {steps} steps up to step {s} (t = {t} s), \
             the last complete chunk",
            path.display()
        )
    });
    if !ended {
        let (s, t) = last.unwrap_or((0, 0.0));
        let why = format!(
            "the recording stops at step {s} without the run's end: {}",
            status
                .truncated
                .as_deref()
                .unwrap_or("the run end event is missing")
        );
        k.on_event(&Event::RunEnd {
            steps: s,
            t,
            error: Some(&why),
        });
    }
    let done = k.finish().map_err(werr)?;
    if done.path != out && !crate::record::plan::holds(out) {
        // An incomplete run keeps the sink's .partial name; the user asked for `out` (a held
        // output is renamed by its plan's commit, with the command's other outputs).
        std::fs::rename(&done.path, out)
            .map_err(|e| ReplayError::file(out, format!("cannot rename the output: {e}")))?;
    }
    Ok(Shown { steps, warning })
}

/// A first pass over a stored run's steps: the force range and the region it visits, so the
/// `.rrd` is drawn with one scale, as a live run's is.
fn survey_stored(path: &Path) -> Result<Survey, ReplayError> {
    let mut obs = SurveyObserver::default();
    read_messages(path, false, |m| {
        match m {
            Message::Meta(meta) => {
                let infos: Vec<RodInfo> = meta.rods.iter().map(|r| r.info()).collect();
                let sc = super::read::parse_scenario(path, &meta)?;
                obs.on_event(&Event::RunStart(&RunInfo {
                    dimension: 2,
                    scene: crate::events::Scene::Planar {
                        obstacles: &sc.obstacles,
                    },
                    scenario_name: &meta.scenario_name,
                    scenario_text: &meta.scenario_text,
                    rods: &infos,
                    obstacle_names: &sc.obstacle_names,
                    bodies: &sc.bodies,
                    mode: sc.solve.mode,
                }));
            }
            Message::Step(st) => {
                let owned = Views::of(&st);
                obs.step(st.dt, &owned.views(&st));
            }
            _ => {}
        }
        Ok(())
    })?;
    Ok(obs.survey)
}

/// Which step the sink was told began, and the dt to tell it.
#[derive(Default)]
struct Begun {
    step: Option<u64>,
    dt: f64,
}

impl Begun {
    fn begin(&mut self, k: &mut RerunSink, step: u64, t: f64, dt: Option<f64>) {
        if self.step != Some(step) {
            self.step = Some(step);
            k.on_event(&Event::StepBegin {
                step,
                t,
                dt: dt.unwrap_or(self.dt),
            });
        }
        if let Some(dt) = dt {
            self.dt = dt;
        }
    }
}

/// `replay show`: the stored run as a `.rrd`, as a live run would have written it.
pub fn show(path: &Path, out: &Path) -> Result<Shown, ReplayError> {
    drive(
        path,
        out,
        true,
        |meta| SinkSpec {
            name: meta.scenario_name.clone(),
            text: meta.scenario_text.clone(),
            blueprint: blueprint(&rod_names(meta)),
            iterations: meta.detail == "iteration" || meta.detail == "auto",
        },
        |_, _, _| Ok(()),
    )
}

// Ring colours; run B's findings are drawn with thinner rings.
const IMPACT_COLOR: [u8; 3] = [230, 40, 200];
const UNEXPLAINED_COLOR: [u8; 3] = [200, 0, 60];
const ALTERNATING_COLOR: [u8; 3] = [130, 60, 255];
const STICK_COLOR: [u8; 3] = [255, 150, 0];
const BRUISE_COLOR: [u8; 3] = [150, 60, 200];
const DIVERGENCE_COLOR: [u8; 3] = [255, 30, 30];
/// Rings sit over the nodes (they are outlines and hide nothing).
const DRAW_HALO: f32 = 45.0;

fn rod_names(meta: &Meta) -> Vec<String> {
    meta.rods.iter().map(|r| r.name.clone()).collect()
}

fn color(c: [u8; 3]) -> Color {
    Color::from_rgb(c[0], c[1], c[2])
}

/// A finding to mark when the replay reaches its step.
struct Mark {
    /// Marked when the replayed run reaches this time.
    t: f64,
    rod: usize,
    /// Where (m): the node's position in the run the finding belongs to.
    at: [f64; 2],
    entity: EntityPath,
    /// The ring's label (shown only with `show_label`) and the events log line.
    label: String,
    text: String,
    color: [u8; 3],
    /// Ring radius relative to the node radius, and its line width (UI points).
    scale: f32,
    width: f32,
    /// Show the label in the scene (the events log always has it): only the first
    /// divergence, so that rings of neighbouring nodes do not stack their texts.
    show_label: bool,
}

/// An entity path from parts (names may hold any character).
fn ent(parts: &[&str]) -> EntityPath {
    EntityPath::new(parts.iter().map(|p| EntityPathPart::new(*p)).collect())
}

fn spike_label(s: &Spike, tag: &str) -> String {
    let steps = if s.last_step != s.step {
        format!("steps {}-{}", s.step, s.last_step)
    } else {
        format!("step {}", s.step)
    };
    format!(
        "{tag}{} spike of rod {:?} node {}, {steps}: jump {:.3e} m/s over dt = {:.1e} s ({:.2e} m)",
        s.kind, s.rod_name, s.node, s.jump, s.dt, s.displacement
    )
}

fn stick_label(s: &Sticking, tag: &str) -> String {
    format!(
        "{tag}sticking ({}) of rod {:?} node {}, steps {}-{}",
        s.rule.replace('_', " "),
        s.rod_name,
        s.node,
        s.step,
        s.last_step
    )
}

/// The position of node `i` of rod `r` in `run` at the step numbered `step`.
fn node_at(run: &Run, r: usize, i: usize, step: u64) -> [f64; 2] {
    let k = run
        .steps
        .partition_point(|s| s.step < step)
        .min(run.steps.len() - 1);
    let q = &run.steps[k].rods[r].q;
    [q[2 * i], q[2 * i + 1]]
}

/// Where a bruise is marked: its node, or for a free fruit's own contact (no rod: `node` is
/// the body) that contact's point at the recorded step nearest the peak (the body's centroid
/// if the step has it not).
fn bruise_at(run: &Run, f: &super::bruise::BruiseFlag) -> [f64; 2] {
    if f.rod != usize::MAX {
        return node_at(run, f.rod, f.node, f.step);
    }
    let k = run
        .steps
        .partition_point(|s| s.t < f.max_pressure_t)
        .min(run.steps.len() - 1);
    let s = &run.steps[k];
    s.contacts
        .iter()
        .find(|c| c.rod.is_none() && c.node == f.node && c.obstacle == f.obstacle)
        .map(|c| c.point)
        .or_else(|| s.bodies.get(f.node).map(|b| b.position))
        .unwrap_or_default()
}

fn marks(run: &Run, f: &Findings, b: bool) -> Vec<Mark> {
    let (root, tag, width): (&[&str], _, _) = if b {
        (&["scene", "flags", "run_b"], "B: ", 1.0)
    } else {
        (&["scene", "flags"], "", 2.5)
    };
    let entity = |kind: &str, rod: &str, node: usize| {
        let node = format!("node_{node}");
        let mut parts = root.to_vec();
        parts.extend([kind, rod, node.as_str()]);
        ent(&parts)
    };
    let mut out = Vec::new();
    for s in &f.spikes {
        out.push(Mark {
            t: s.t,
            rod: s.rod,
            at: node_at(run, s.rod, s.node, s.step),
            entity: entity("spike", &s.rod_name, s.node),
            label: String::new(),
            text: spike_label(s, tag),
            color: match s.kind {
                "impact" => IMPACT_COLOR,
                "unexplained" => UNEXPLAINED_COLOR,
                _ => ALTERNATING_COLOR,
            },
            scale: if b { 1.6 } else { 1.9 },
            width,
            show_label: false,
        });
    }
    for s in &f.sticking {
        out.push(Mark {
            t: s.t,
            rod: s.rod,
            at: node_at(run, s.rod, s.node, s.step),
            entity: entity("sticking", &s.rod_name, s.node),
            label: String::new(),
            text: stick_label(s, tag),
            color: STICK_COLOR,
            scale: if b { 2.3 } else { 2.6 },
            width,
            show_label: false,
        });
    }
    for s in &f.bruise {
        out.push(Mark {
            t: s.max_pressure_t,
            rod: s.rod,
            at: bruise_at(run, s),
            entity: entity("bruise", &s.rod_name, s.node),
            label: String::new(),
            text: format!(
                "{tag}bruise at {}: peak pressure {:.3e} Pa, {:.2}x the threshold, steps {}-{}",
                s.place(),
                s.max_pressure_pa,
                s.ratio,
                s.step,
                s.last_step
            ),
            color: BRUISE_COLOR,
            scale: if b { 3.0 } else { 3.3 },
            width,
            show_label: false,
        });
    }
    out.sort_by(|p, q| p.t.total_cmp(&q.t));
    out
}

/// Log every mark whose time has come (`t` of the step just logged).
fn log_marks(
    rec: &RecordingStream,
    marks: &[Mark],
    next: &mut usize,
    t: f64,
    style: &SceneStyle,
) -> Result<(), ReplayError> {
    while *next < marks.len() && marks[*next].t <= t {
        let m = &marks[*next];
        *next += 1;
        let radius = style.rods.get(m.rod).map(|s| s.node_radius).unwrap_or(1e-3) as f32;
        let rr = m.scale * radius;
        let circle: Vec<[f32; 2]> = (0..=32)
            .map(|j| {
                let a = j as f32 * std::f32::consts::TAU / 32.0;
                [m.at[0] as f32 + rr * a.cos(), m.at[1] as f32 + rr * a.sin()]
            })
            .collect();
        let mut ring = LineStrips2D::new([circle])
            .with_colors([color(m.color)])
            .with_radii([Radius::new_ui_points(m.width)])
            .with_draw_order(DRAW_HALO);
        if m.show_label {
            ring = ring.with_labels([m.label.as_str()]);
        }
        rec.log(m.entity.clone(), &ring)
            .map_err(|e| ReplayError::new(format!("cannot log a marker: {e}")))?;
        rec.log("events", &TextLog::new(m.text.as_str()).with_level("WARN"))
            .map_err(|e| ReplayError::new(format!("cannot log an event: {e}")))?;
    }
    Ok(())
}

/// `replay check --rrd`: the run with its spikes and sticking nodes marked.
pub fn write_check(out: &Path, run: &Run, rep: &CheckReport) -> Result<(), ReplayError> {
    let found = Findings {
        spikes: rep.spikes.clone(),
        sticking: rep.sticking.clone(),
        grasp: rep.grasp.clone(),
        grasp_expected: rep.grasp_expected.clone(),
        bruise: rep.bruise.clone(),
        bruise_expected: rep.bruise_expected.clone(),
        bruise_missing: rep.bruise_missing,
    };
    let marks = marks(run, &found, false);
    let mut next = 0;
    drive(
        &run.path,
        out,
        false,
        |meta| SinkSpec {
            name: format!("{} (check)", meta.scenario_name),
            text: meta.scenario_text.clone(),
            blueprint: blueprint(&rod_names(meta)),
            iterations: false,
        },
        |rec, st, style| log_marks(rec, &marks, &mut next, st.t, style),
    )?;
    Ok(())
}

/// A contact event that differs between the runs, for the events log at its (earlier) time.
fn event_lines(rep: &DiffReport) -> Vec<(f64, String)> {
    let mut out: Vec<(f64, String)> = rep
        .contact_events
        .iter()
        .map(|e| {
            let when = |t: Option<f64>, s: Option<u64>| match (t, s) {
                (Some(t), Some(s)) => format!("t = {t:.6} s (step {s})"),
                _ => "never".to_string(),
            };
            let what = match e.status {
                "shifted" => format!("shifted by {:+.3e} s", e.shift.unwrap_or(0.0)),
                "only_a" => "in A only".to_string(),
                _ => "in B only".to_string(),
            };
            let t = e.t_a.into_iter().chain(e.t_b).fold(f64::INFINITY, f64::min);
            (
                t,
                format!(
                    "contact {} of rod {:?} node {} on obstacle {} {what}: A {}, B {}",
                    e.change,
                    e.rod_name,
                    e.node,
                    e.obstacle,
                    when(e.t_a, e.step_a),
                    when(e.t_b, e.step_b)
                ),
            )
        })
        .collect();
    out.sort_by(|p, q| p.0.total_cmp(&q.0));
    out
}

/// `replay diff --rrd`: A as recorded, B in its own colour at A's times (nodes as rings around
/// A's, its reactions as wider arrows under A's), both runs' findings, the first divergence
/// marked at its node from its time on (A's node, B's node and the gap between them), the
/// contact events that differ in the events log, and the rod-wise largest differences plotted.
pub fn write_diff(out: &Path, a: &Run, b: &Run, rep: &DiffReport) -> Result<(), ReplayError> {
    let mut all = marks(a, &rep.findings_a, false);
    all.extend(marks(b, &rep.findings_b, true));
    all.sort_by(|p, q| p.t.total_cmp(&q.t));
    let mut next = 0;
    let lines = event_lines(rep);
    let mut next_line = 0;
    let divergence = rep.first_divergence.clone();
    let mut divergence_told = false;
    let mut ghosts: Vec<RodEntities> = b
        .meta
        .rods
        .iter()
        .map(|r| RodEntities::new(&["scene", "run_b"], r.info()))
        .collect();
    let b_end = b.t_end();
    let names: Vec<String> = a.meta.rods.iter().map(|r| r.name.clone()).collect();
    let extra = vec![
        TimeSeriesView::new("Position |A - B| (m), max per rod")
            .with_origin("/diff/position")
            .into(),
        TimeSeriesView::new("Velocity |A - B| (m/s), max per rod")
            .with_origin("/diff/velocity")
            .into(),
    ];
    let text = format!("{}\n{}", a.meta.scenario_text, b.meta.scenario_text);
    let title = format!("{} vs {}", a.meta.scenario_name, b.meta.scenario_name);
    let fail = |what: &str, e: ::rerun::RecordingStreamError| {
        ReplayError::new(format!("cannot log {what}: {e}"))
    };
    drive(
        &a.path,
        out,
        false,
        |_| SinkSpec {
            name: title,
            text,
            blueprint: blueprint_with(&names, extra),
            iterations: false,
        },
        |rec, st, style| {
            let t = st.t;
            if st.step == 0 {
                for (r, name) in names.iter().enumerate() {
                    for (kind, c) in [("position", r), ("velocity", r)] {
                        rec.log_static(
                            ent(&["diff", kind, name]),
                            &::rerun::SeriesLines::new()
                                .with_colors([color(crate::record::series_color(c))])
                                .with_names([name.as_str()]),
                        )
                        .map_err(|e| fail("a series style", e))?;
                    }
                }
                rec.log_static(
                    ent(&["scene", "run_b", "legend"]),
                    &::rerun::Points2D::new([[
                        (style.lo[0] + 0.04 * (style.hi[0] - style.lo[0])) as f32,
                        (style.lo[1] + 0.16 * (style.hi[1] - style.lo[1])) as f32,
                    ]])
                    .with_colors([color(OTHER_COLOR)])
                    .with_radii([Radius::new_ui_points(5.0)])
                    .with_labels([format!(
                        "run B ({}): cyan rings, line and arrows under run A's",
                        b.meta.scenario_name
                    )])
                    .with_show_labels(true),
                )
                .map_err(|e| fail("the legend", e))?;
            }
            let mut b_q: Vec<Vec<f64>> = Vec::new();
            if t <= b_end {
                let at = locate(b, t);
                let kb = at.k0;
                for (r, g) in ghosts.iter_mut().enumerate() {
                    let bs = &b.steps[kb].rods[r];
                    let n = bs.in_contact.len();
                    let q: Vec<f64> = (0..n)
                        .flat_map(|i| at.vec2(b, r, i, super::diff::pos))
                        .collect();
                    let obst = vec![usize::MAX; n];
                    let zeros = vec![0.0; 2 * n];
                    let view = RodStepView {
                        dim: 2,
                        twist_stress: &[],
                        frames: None,
                        q: &q,
                        u: &bs.u,
                        reaction: &bs.reaction,
                        impulse: &bs.impulse,
                        drive_force: &bs.drive_force,
                        normal: &bs.normal,
                        contact_obstacle: &obst,
                        normal2: &zeros,
                        contact_obstacle2: &obst,
                        in_contact: &bs.in_contact,
                        bending_stress: &bs.bending_stress,
                        gap: &bs.gap,
                        q_predictor: &bs.q_predictor,
                    };
                    g.draw(rec, style, r, &view, false, Look::Other)
                        .map_err(|e| fail("run B", e))?;
                    // Largest differences over the rod's nodes.
                    let (mut dq, mut du) = (0.0f64, 0.0f64);
                    let va = &st.rods[r];
                    for i in 0..n {
                        let qb = [q[2 * i], q[2 * i + 1]];
                        let ub = at.vec2(b, r, i, super::diff::vel);
                        dq = dq.max((va.q[2 * i] - qb[0]).hypot(va.q[2 * i + 1] - qb[1]));
                        du = du.max((va.u[2 * i] - ub[0]).hypot(va.u[2 * i + 1] - ub[1]));
                    }
                    for (kind, v) in [("position", dq), ("velocity", du)] {
                        rec.log(ent(&["diff", kind, &names[r]]), &Scalars::single(v))
                            .map_err(|e| fail("a difference", e))?;
                    }
                    b_q.push(q);
                }
            }
            if let Some(d) = divergence.as_ref().filter(|d| t >= d.t) {
                let qa = &st.rods[d.rod].q;
                let pa = [qa[2 * d.node], qa[2 * d.node + 1]];
                let pb = b_q
                    .get(d.rod)
                    .map(|q| [q[2 * d.node], q[2 * d.node + 1]])
                    .unwrap_or(pa);
                let rr = 3.2 * style.rods.get(d.rod).map(|s| s.node_radius).unwrap_or(1e-3);
                let ring = |c: [f64; 2]| -> Vec<[f32; 2]> {
                    (0..=32)
                        .map(|j| {
                            let a = j as f64 * std::f64::consts::TAU / 32.0;
                            [(c[0] + rr * a.cos()) as f32, (c[1] + rr * a.sin()) as f32]
                        })
                        .collect()
                };
                let label = format!(
                    "first divergence: {} of rod {:?} node {} at t = {:.6} s",
                    d.quantity, d.rod_name, d.node, d.t
                );
                rec.log(
                    ent(&["scene", "divergence"]),
                    &LineStrips2D::new([
                        ring(pa),
                        vec![[pa[0] as f32, pa[1] as f32], [pb[0] as f32, pb[1] as f32]],
                    ])
                    .with_colors([color(DIVERGENCE_COLOR)])
                    .with_radii([Radius::new_ui_points(3.0)])
                    .with_labels([label.clone(), String::new()])
                    .with_draw_order(DRAW_HALO),
                )
                .map_err(|e| fail("the divergence marker", e))?;
                if !divergence_told {
                    divergence_told = true;
                    rec.log(
                        ent(&["events", "bookmarks"]),
                        &TextLog::new(format!(
                            "★ first divergence: {} of rod {:?} node {}, |A - B| = {:.3e} > {:.3e} at t = {} s (A step {}, B step {})",
                            d.quantity, d.rod_name, d.node, d.difference, d.tolerance, d.t, d.step_a, d.step_b
                        ))
                        .with_level("BOOKMARK"),
                    )
                    .map_err(|e| fail("an event", e))?;
                }
            }
            while next_line < lines.len() && lines[next_line].0 <= t {
                rec.log(
                    "events",
                    &TextLog::new(lines[next_line].1.as_str()).with_level("WARN"),
                )
                .map_err(|e| fail("an event", e))?;
                next_line += 1;
            }
            log_marks(rec, &all, &mut next, t, style)
        },
    )?;
    Ok(())
}
