//! Figures of a study, drawn with the helpers of [`crate::bench::plot`] (PNG and SVG, font
//! loaded at run time):
//!
//! - per case, `forces`: eq. 2 reaction, impulse-consistent force and bending stress of every
//!   node over time (three panels, one colour per node, the seed report's Fig. 9/14/16/18 style);
//! - per case, `shapes`: prong snapshots with the fruit, nodes coloured by their
//!   impulse-consistent force;
//! - per sweep, `plots/vs-<key>`: every summary metric against each varied key, one line per
//!   value of the other keys.
//!
//! [`Trace`] collects what the per-case figures need while the case runs: the run is cut into
//! [`BUCKETS`] equal spans of time and each span keeps the per-node maximum of each quantity
//! (so a one-step eq. 2 spike is never lost) and the state at its last step.

use super::sweep::{CaseRecord, Manifest, Metrics};
use crate::bench::plot::{color, draw_panel, ensure_font, Panel, Series};
use crate::events::{Event, Observer};
use crate::obstacle::Obstacle;
use crate::record::summary::{Summary, Window};
use crate::scenario::{Mode, Scenario};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Spans of time kept per run for the time-series figures.
pub const BUCKETS: usize = 1000;
/// Window of the impulse-consistent force (s), as in the run summary.
pub const FORCE_WINDOW: f64 = 1e-3;

/// The state at one step, for shape snapshots.
#[derive(Debug, Clone)]
struct Frame {
    t: f64,
    /// Per rod, interleaved positions.
    q: Vec<Vec<f64>>,
    /// Per rod and node, the impulse-consistent force at this step (N).
    ic: Vec<Vec<f64>>,
}

/// Time series of a run, reduced to [`BUCKETS`] spans, plus the warnings it emitted.
#[derive(Debug, Clone)]
pub struct Trace {
    horizon: f64,
    static_mode: bool,
    scenario: String,
    names: Vec<String>,
    nodes: Vec<usize>,
    clamped: Vec<Vec<bool>>,
    obstacles: Vec<Obstacle>,
    /// Time of the last step of each span.
    times: Vec<f64>,
    /// [rod][span × nodes + node]: span maxima.
    reaction: Vec<Vec<f64>>,
    ic: Vec<Vec<f64>>,
    stress: Vec<Vec<f64>>,
    frames: Vec<Frame>,
    initial: Option<Frame>,
    onset: Option<Frame>,
    peak: Option<Frame>,
    peak_ic: f64,
    span: Option<usize>,
    windows: Vec<Vec<Window>>,
    ic_now: Vec<Vec<f64>>,
    /// Warning events of the run, in order.
    pub warnings: Vec<String>,
    /// Constraints released as adhesive.
    pub releases: u64,
    /// Whether the time series are kept (false: only the warnings and releases, for a sweep
    /// that draws no figures).
    series: bool,
    /// The run's dimension: a 3D frame keeps each node's (x, z).
    dim: usize,
}

/// The time a 3D scenario runs to: its `t_end`, or (the hand's moves end it) the sum of the
/// moves' durations with a squeeze's longest (its travel at its speed).
fn horizon3(sc: &crate::scenario::three::Scenario3) -> f64 {
    use crate::rod3d::gripper::Move3;
    if let Some(t) = sc.t_end {
        return t;
    }
    sc.moves
        .iter()
        .map(|m| match *m {
            Move3::Squeeze {
                speed, max_travel, ..
            } if speed > 0.0 => max_travel / speed,
            Move3::Squeeze { .. } => 0.0,
            Move3::Close { duration, .. }
            | Move3::Hold { duration }
            | Move3::Translate { duration, .. }
            | Move3::Lift { duration, .. }
            | Move3::Rotate { duration, .. } => duration,
        })
        .sum()
}

impl Trace {
    /// A trace of a scenario of either dimension. A 3D rod's shape is kept projected onto the
    /// gripper's closing plane (x–z), where the shape figure draws it.
    pub fn of(sc: &crate::run::AnyScenario) -> Self {
        match sc {
            crate::run::AnyScenario::Planar(sc) => Self::new(sc),
            crate::run::AnyScenario::Spatial(sc) => {
                Self::blank(horizon3(sc), false, sc.name.clone(), Vec::new(), 3)
            }
        }
    }

    /// A trace that keeps only the warnings and the releases, of either dimension.
    pub fn counts_of(sc: &crate::run::AnyScenario) -> Self {
        Self {
            series: false,
            ..Self::of(sc)
        }
    }

    pub fn new(sc: &Scenario) -> Self {
        let static_mode = sc.solve.mode == Mode::Static;
        let horizon = if static_mode { 1.0 } else { sc.solve.t_end };
        Self::blank(
            horizon,
            static_mode,
            sc.name.clone(),
            sc.obstacles.clone(),
            2,
        )
    }

    fn blank(
        horizon: f64,
        static_mode: bool,
        scenario: String,
        obstacles: Vec<Obstacle>,
        dim: usize,
    ) -> Self {
        Self {
            dim,
            horizon,
            static_mode,
            scenario,
            names: Vec::new(),
            nodes: Vec::new(),
            clamped: Vec::new(),
            obstacles,
            times: Vec::new(),
            reaction: Vec::new(),
            ic: Vec::new(),
            stress: Vec::new(),
            frames: Vec::new(),
            initial: None,
            onset: None,
            peak: None,
            peak_ic: 0.0,
            span: None,
            windows: Vec::new(),
            ic_now: Vec::new(),
            warnings: Vec::new(),
            releases: 0,
            series: true,
        }
    }

    /// A trace that keeps only the warnings and the releases (no figures will be drawn from
    /// it): the step events cost it nothing.
    pub fn counts_only(sc: &Scenario) -> Self {
        Self {
            series: false,
            ..Self::new(sc)
        }
    }
}

impl Observer for Trace {
    fn on_event(&mut self, event: &Event<'_>) {
        match event {
            Event::RunStart(info) => {
                self.names = info.rods.iter().map(|r| r.name.clone()).collect();
                self.nodes = info.rods.iter().map(|r| r.nodes).collect();
                self.clamped = info.rods.iter().map(|r| r.clamped.clone()).collect();
                let k = info.rods.len();
                self.reaction = vec![Vec::new(); k];
                self.ic = vec![Vec::new(); k];
                self.stress = vec![Vec::new(); k];
                // In 3D a node has two windows: (x, y) and (z, 0) (their magnitudes add
                // in quadrature to the 3-vector's).
                let per = if self.dim == 3 { 2 } else { 1 };
                self.windows = info
                    .rods
                    .iter()
                    .map(|r| vec![Window::default(); per * r.nodes])
                    .collect();
                self.ic_now = info.rods.iter().map(|r| vec![0.0; r.nodes]).collect();
            }
            Event::Warning { message, .. } => self.warnings.push(message.to_string()),
            Event::ConstraintReleased(..) => self.releases += 1,
            Event::StepEnd { .. } if !self.series => {}
            Event::StepEnd { t, dt, rods, .. } => {
                let (t, dt) = (*t, *dt);
                let b = if self.horizon > 0.0 {
                    ((t / self.horizon) * BUCKETS as f64)
                        .floor()
                        .clamp(0.0, (BUCKETS - 1) as f64) as usize
                } else {
                    0
                };
                if self.span != Some(b) {
                    self.span = Some(b);
                    self.times.push(t);
                    for (r, n) in self.nodes.iter().enumerate() {
                        self.reaction[r].extend(std::iter::repeat_n(0.0, *n));
                        self.ic[r].extend(std::iter::repeat_n(0.0, *n));
                        self.stress[r].extend(std::iter::repeat_n(0.0, *n));
                    }
                    let dim = self.dim;
                    self.frames.push(Frame {
                        t,
                        q: rods.iter().map(|v| planar(v.q, dim)).collect(),
                        ic: self.ic_now.clone(),
                    });
                }
                let s = self.times.len() - 1;
                self.times[s] = t;
                let mut step_peak = 0.0f64;
                let mut contact = false;
                let d = self.dim;
                for (r, v) in rods.iter().enumerate() {
                    let n = self.nodes[r];
                    for i in 0..n {
                        let k = s * n + i;
                        let reaction = &v.reaction[d * i..d * i + d];
                        let impulse = &v.impulse[d * i..d * i + d];
                        // A node that never had a reaction or an impulse adds nothing
                        // (its window would give exactly 0).
                        let idle = reaction.iter().chain(impulse).all(|x| *x == 0.0)
                            && self.windows[r][i].is_empty();
                        let rm = if idle {
                            0.0
                        } else {
                            reaction.iter().map(|x| x * x).sum::<f64>().sqrt()
                        };
                        let f = if dt > 0.0 && !idle {
                            let w = &mut self.windows[r];
                            let a = w[i].push(t - dt, t, impulse[0], impulse[1], FORCE_WINDOW);
                            if d == 3 {
                                let b = w[n + i].push(t - dt, t, impulse[2], 0.0, FORCE_WINDOW);
                                a.hypot(b)
                            } else {
                                a
                            }
                        } else {
                            0.0
                        };
                        self.ic_now[r][i] = f;
                        step_peak = step_peak.max(f);
                        contact |= v.in_contact[i];
                        self.reaction[r][k] = self.reaction[r][k].max(rm);
                        self.ic[r][k] = self.ic[r][k].max(f);
                        self.stress[r][k] = self.stress[r][k].max(v.bending_stress[i]);
                    }
                }
                let frame = self.frames.last_mut().expect("a span is open");
                frame.t = t;
                for (r, v) in rods.iter().enumerate() {
                    if self.dim == 3 {
                        frame.q[r] = planar(v.q, 3);
                    } else {
                        frame.q[r].copy_from_slice(v.q);
                    }
                    frame.ic[r].copy_from_slice(&self.ic_now[r]);
                }
                // Copied only when it is kept (not in every step).
                if self.initial.is_none() {
                    self.initial = Some(frame.clone());
                }
                if contact && self.onset.is_none() {
                    self.onset = Some(frame.clone());
                }
                if step_peak > self.peak_ic {
                    self.peak_ic = step_peak;
                    self.peak = Some(frame.clone());
                }
            }
            _ => {}
        }
    }
}

/// Interleaved positions of stride `dim` as planar ones: a 3D node's (x, z), its place in
/// the gripper's closing plane.
fn planar(q: &[f64], dim: usize) -> Vec<f64> {
    if dim == 3 {
        q.chunks_exact(3).flat_map(|p| [p[0], p[2]]).collect()
    } else {
        q.to_vec()
    }
}

/// Both figures of a case into `dir`: `forces.png|svg` and `shapes.png|svg`; `label` (the
/// case's varied values) goes into the titles.
pub fn draw_case(trace: &Trace, summary: &Summary, label: &str, dir: &Path) -> Result<(), String> {
    if trace.times.is_empty() {
        return Ok(());
    }
    draw_forces(trace, label, &dir.join("forces"))?;
    draw_shapes(trace, summary, label, &dir.join("shapes"))
}

fn titled(name: &str, label: &str) -> String {
    if label.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{label}]")
    }
}

/// Reaction (eq. 2), impulse-consistent force and bending stress per node over time: three
/// panels per rod (one column per rod), one colour per node.
pub fn draw_forces(trace: &Trace, label: &str, base: &Path) -> Result<(), String> {
    let x_label = if trace.static_mode {
        "load factor"
    } else {
        "t (s)"
    };
    let multi = trace.names.len() > 1;
    let kinds: [(&str, &str, &Vec<Vec<f64>>); 3] = [
        (
            "eq. 2 reaction |R| per node (0-based; max per 1/1000 of the run)",
            "N",
            &trace.reaction,
        ),
        ("impulse-consistent force (1 ms window)", "N", &trace.ic),
        (
            "bending stress σ = E |κ − κ_rest| / Δl · h/2",
            "Pa",
            &trace.stress,
        ),
    ];
    let mut panels = Vec::new();
    for (title, unit, data) in kinds {
        for (r, name) in trace.names.iter().enumerate() {
            let n = trace.nodes[r];
            let series = (0..n)
                .map(|i| Series {
                    name: String::new(),
                    points: trace
                        .times
                        .iter()
                        .enumerate()
                        .map(|(s, t)| (*t, data[r][s * n + i]))
                        .collect(),
                })
                .collect();
            panels.push(Panel {
                title: if multi {
                    format!("{name}: {title}")
                } else {
                    title.to_string()
                },
                x_label: x_label.into(),
                y_label: unit.into(),
                log_x: false,
                log_y: false,
                series,
            });
        }
    }
    let title = titled(&trace.scenario, label);
    let most = trace.nodes.iter().copied().max().unwrap_or(0);
    let legend: Vec<String> = (0..most).map(|i| format!("node {i}")).collect();
    figure(
        base,
        &title,
        &panels,
        trace.names.len(),
        (900, 290),
        &legend,
    )
}

/// Where each legend entry goes (x, y) in a strip `width` wide, and the strip's height.
fn legend_layout(names: &[String], width: u32) -> (Vec<(i32, i32)>, u32) {
    let mut at = Vec::with_capacity(names.len());
    let (mut x, mut y) = (20i32, 8i32);
    for n in names {
        let w = 50 + (7.2 * n.chars().count() as f64) as i32;
        if x > 20 && x + w > width as i32 - 10 {
            x = 20;
            y += 22;
        }
        at.push((x, y));
        x += w;
    }
    (at, if names.is_empty() { 0 } else { y as u32 + 30 })
}

/// Panels in a grid of `cols` columns (each `panel` pixels) with one legend along the bottom:
/// entry i is coloured as series i of every panel. Written as `<base>.png` and `<base>.svg`.
pub fn figure(
    base: &Path,
    title: &str,
    panels: &[Panel],
    cols: usize,
    panel: (u32, u32),
    legend: &[String],
) -> Result<(), String> {
    ensure_font()?;
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    let width = panel.0 * cols as u32;
    let (at, legend_h) = legend_layout(legend, width);
    let size = (width, panel.1 * rows as u32 + 40 + legend_h);
    if let Some(d) = base.parent() {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        figure_on(&root, title, panels, (rows, cols), legend, &at, legend_h)?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        figure_on(&root, title, panels, (rows, cols), legend, &at, legend_h)?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(())
}

fn figure_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[Panel],
    grid: (usize, usize),
    legend: &[String],
    at: &[(i32, i32)],
    legend_h: u32,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    let h = root.dim_in_pixel().1;
    let (main, strip) = root.split_vertically(h.saturating_sub(legend_h));
    for (a, p) in main.split_evenly(grid).iter().zip(panels) {
        draw_panel(a, p)?;
    }
    for (i, (name, (x, y))) in legend.iter().zip(at).enumerate() {
        let c = color(i);
        strip
            .draw(&PathElement::new(
                vec![(*x, y + 8), (x + 26, y + 8)],
                c.stroke_width(3),
            ))
            .map_err(e)?;
        strip
            .draw(&Text::new(name.clone(), (x + 32, *y), ("sans-serif", 13)))
            .map_err(e)?;
    }
    Ok(())
}

/// Blue (0) → yellow → red (1).
pub fn force_color(f: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 5] = [
        (49, 54, 149),
        (116, 173, 209),
        (254, 224, 144),
        (244, 109, 67),
        (165, 0, 38),
    ];
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = f * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let w = x - i as f64;
    let mix = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * w).round() as u8;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Snapshots: the start, five evenly spaced times, first contact and the peak
/// impulse-consistent force.
fn snapshots(trace: &Trace) -> Vec<(String, Frame)> {
    let mut picks: Vec<(String, Frame)> = Vec::new();
    if let Some(f) = &trace.initial {
        picks.push(("start".into(), f.clone()));
    }
    for k in 1..=5 {
        let target = trace.horizon * k as f64 / 5.0;
        if let Some(f) = trace
            .frames
            .iter()
            .min_by(|a, b| (a.t - target).abs().total_cmp(&(b.t - target).abs()))
        {
            picks.push((String::new(), f.clone()));
        }
    }
    if let Some(f) = &trace.onset {
        picks.push(("first contact".into(), f.clone()));
    }
    if let Some(f) = &trace.peak {
        picks.push(("peak force".into(), f.clone()));
    }
    picks.sort_by(|a, b| a.1.t.total_cmp(&b.1.t));
    // Drop unlabelled snapshots close to a labelled one, and exact repeats.
    let close = trace.horizon / 100.0;
    let mut out: Vec<(String, Frame)> = Vec::new();
    for p in picks {
        if let Some(last) = out.last_mut() {
            if (last.1.t - p.1.t).abs() <= close {
                if last.0.is_empty() {
                    *last = p;
                } else if !p.0.is_empty() && (last.1.t - p.1.t).abs() > 0.0 {
                    out.push(p);
                }
                continue;
            }
        }
        out.push(p);
    }
    out
}

/// Prong snapshots with the obstacles; nodes coloured by impulse-consistent force (grey: no
/// contact force), driven nodes boxed, node numbers 0-based.
pub fn draw_shapes(
    trace: &Trace,
    summary: &Summary,
    label: &str,
    base: &Path,
) -> Result<(), String> {
    ensure_font()?;
    let snaps = snapshots(trace);
    if snaps.is_empty() {
        return Ok(());
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (_, f) in &snaps {
        for q in &f.q {
            for p in q.chunks(2) {
                for d in 0..2 {
                    if p[d].is_finite() {
                        lo[d] = lo[d].min(p[d]);
                        hi[d] = hi[d].max(p[d]);
                    }
                }
            }
        }
    }
    if !lo[0].is_finite() {
        return Ok(());
    }
    let half = ((hi[0] - lo[0]).max(hi[1] - lo[1]) / 2.0).max(1e-6) * 1.2;
    let c = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let bounds = ([c[0] - half, c[1] - half], [c[0] + half, c[1] + half]);
    let cols = snaps.len().min(4);
    let rows = snaps.len().div_ceil(cols);
    let size = (340 * cols as u32, 340 * rows as u32 + 110);
    let title = format!(
        "{}: nodes coloured by impulse-consistent force{}",
        titled(&summary.scenario, label),
        if trace.dim == 3 {
            " (3D: x–z projection, fruit not drawn)"
        } else {
            ""
        }
    );
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        shapes_on(&root, trace, &snaps, bounds, &title, (rows, cols))?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        shapes_on(&root, trace, &snaps, bounds, &title, (rows, cols))?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(())
}

type Bounds = ([f64; 2], [f64; 2]);

fn shapes_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    trace: &Trace,
    snaps: &[(String, Frame)],
    bounds: Bounds,
    title: &str,
    (rows, cols): (usize, usize),
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 18)).map_err(e)?;
    let h = root.dim_in_pixel().1;
    let (main, bar) = root.split_vertically(h.saturating_sub(70));
    let (lo, hi) = bounds;
    let scale = trace.peak_ic;
    for (area, (label, f)) in main.split_evenly((rows, cols)).iter().zip(snaps) {
        let caption = if label.is_empty() {
            format!("t = {:.5} s", f.t)
        } else {
            format!("t = {:.5} s ({label})", f.t)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(44)
            .build_cartesian_2d(lo[0]..hi[0], lo[1]..hi[1])
            .map_err(e)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .bold_line_style(RGBColor(235, 235, 235))
            .x_labels(5)
            .y_labels(5)
            .x_label_formatter(&|v| format!("{v:.2}"))
            .y_label_formatter(&|v| format!("{v:.2}"))
            .label_style(("sans-serif", 10))
            .draw()
            .map_err(e)?;
        for o in &trace.obstacles {
            let line = o.outline(lo, hi);
            let closed = line.len() > 2 && {
                let (a, b) = (line[0], line[line.len() - 1]);
                (a[0] - b[0]).hypot(a[1] - b[1]) <= 1e-9 * (1.0 + a[0].abs() + a[1].abs())
            };
            if closed {
                let poly = clip_polygon(&line, lo, hi);
                if poly.len() > 2 {
                    chart
                        .draw_series(std::iter::once(Polygon::new(
                            poly.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>(),
                            RGBColor(255, 200, 120).mix(0.35).filled(),
                        )))
                        .map_err(e)?;
                }
            }
            for seg in clip_polyline(&line, lo, hi) {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        seg.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>(),
                        RGBColor(230, 120, 20).stroke_width(2),
                    )))
                    .map_err(e)?;
            }
        }
        for (r, q) in f.q.iter().enumerate() {
            let pts: Vec<(f64, f64)> = q.chunks(2).map(|p| (p[0], p[1])).collect();
            chart
                .draw_series(std::iter::once(PathElement::new(
                    pts.clone(),
                    RGBColor(60, 60, 60).stroke_width(2),
                )))
                .map_err(e)?;
            for (i, p) in pts.iter().enumerate() {
                let force = f.ic[r][i];
                let fill = if force > 0.0 && scale > 0.0 {
                    force_color(force / scale)
                } else {
                    RGBColor(200, 200, 200)
                };
                let marker = EmptyElement::at(*p)
                    + plotters::element::Circle::new((0, 0), 5, fill.filled())
                    + plotters::element::Circle::new((0, 0), 5, BLACK.stroke_width(1))
                    + Text::new(format!("{i}"), (7, -12), ("sans-serif", 10));
                chart.draw_series(std::iter::once(marker)).map_err(e)?;
                if trace.clamped[r].get(i).copied().unwrap_or(false) {
                    let bx = EmptyElement::at(*p)
                        + Rectangle::new([(-8, -8), (8, 8)], BLACK.stroke_width(1));
                    chart.draw_series(std::iter::once(bx)).map_err(e)?;
                }
            }
        }
    }
    // Colour bar.
    let (w, _) = bar.dim_in_pixel();
    let (x0, x1) = (60i32, w as i32 - 160);
    let steps = 200;
    for k in 0..steps {
        let a = x0 + (x1 - x0) * k / steps;
        let b = x0 + (x1 - x0) * (k + 1) / steps;
        let col = force_color(k as f64 / (steps - 1) as f64);
        bar.draw(&Rectangle::new([(a, 12), (b + 1, 32)], col.filled()))
            .map_err(e)?;
    }
    bar.draw(&Rectangle::new([(x0, 12), (x1, 32)], BLACK.stroke_width(1)))
        .map_err(e)?;
    bar.draw(&Text::new("0 N", (x0 - 40, 14), ("sans-serif", 13)))
        .map_err(e)?;
    bar.draw(&Text::new(
        format!("{scale:.4} N"),
        (x1 + 6, 14),
        ("sans-serif", 13),
    ))
    .map_err(e)?;
    bar.draw(&Text::new(
        "impulse-consistent force of the node at that step (grey: none); boxed nodes are driven",
        (x0, 40),
        ("sans-serif", 13),
    ))
    .map_err(e)?;
    Ok(())
}

fn inside(p: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> bool {
    p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1]
}

// Liang–Barsky clipping is the recordings' (record::clip_segment).
use crate::record::clip_segment;

/// The pieces of a polyline inside the box.
fn clip_polyline(line: &[[f64; 2]], lo: [f64; 2], hi: [f64; 2]) -> Vec<Vec<[f64; 2]>> {
    let mut out: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut cur: Vec<[f64; 2]> = Vec::new();
    for w in line.windows(2) {
        match clip_segment(w[0], w[1], lo, hi) {
            Some((a, b)) => {
                if cur.is_empty() {
                    cur.push(a);
                }
                cur.push(b);
                if !inside(w[1], lo, hi) || b != w[1] {
                    out.push(std::mem::take(&mut cur));
                }
            }
            None => {
                if !cur.is_empty() {
                    out.push(std::mem::take(&mut cur));
                }
            }
        }
    }
    if cur.len() > 1 {
        out.push(cur);
    }
    out.retain(|s| s.len() > 1);
    out
}

/// Sutherland–Hodgman: a closed outline clipped to the box.
fn clip_polygon(poly: &[[f64; 2]], lo: [f64; 2], hi: [f64; 2]) -> Vec<[f64; 2]> {
    let mut pts = poly.to_vec();
    for (k, bound, keep_above) in [
        (0, lo[0], true),
        (0, hi[0], false),
        (1, lo[1], true),
        (1, hi[1], false),
    ] {
        if pts.is_empty() {
            break;
        }
        let ins = |p: &[f64; 2]| {
            if keep_above {
                p[k] >= bound
            } else {
                p[k] <= bound
            }
        };
        let mut next = Vec::with_capacity(pts.len() + 4);
        for i in 0..pts.len() {
            let a = pts[i];
            let b = pts[(i + 1) % pts.len()];
            let (ia, ib) = (ins(&a), ins(&b));
            if ia {
                next.push(a);
            }
            if ia != ib {
                let t = (bound - a[k]) / (b[k] - a[k]);
                next.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        pts = next;
    }
    pts
}

/// File stem of the sweep figure for a varied key.
pub fn sweep_plot_name(key: &str) -> String {
    let k: String = key
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    format!("vs-{k}")
}

type Metric = (&'static str, &'static str, fn(&Metrics) -> Option<f64>);

const METRICS: [Metric; 8] = [
    ("peak eq. 2 reaction", "N", |m| Some(m.peak_reaction_n)),
    ("peak impulse-consistent force", "N", |m| {
        Some(m.peak_impulse_consistent_force_n)
    }),
    (
        "critical node (peak impulse-consistent force)",
        "node (0-based)",
        |m| m.peak_impulse_consistent_node.map(|n| n as f64),
    ),
    ("total contact impulse, all prongs", "N s", |m| {
        Some(m.total_impulse_per_rod_ns.iter().sum())
    }),
    ("contact onset", "s", |m| m.contact_onset_s),
    ("max bending stress", "Pa", |m| {
        Some(m.max_bending_stress_pa)
    }),
    ("max tip deflection", "m", |m| {
        m.max_tip_deflection_per_rod_m
            .iter()
            .cloned()
            .reduce(f64::max)
    }),
    ("max penetration", "m", |m| Some(m.max_penetration_m)),
];

/// The most lines of one colour each in a `vs-<key>` figure: a key whose other keys make
/// more combinations than this gets no line figure when a heat map shows the grid.
const MAX_LINES: usize = 10;

/// Whether the grid of a two-key sweep is drawn as heat maps (`map-<key1>-<key2>`).
fn has_map(manifest: &Manifest) -> bool {
    manifest.vary.len() == 2
}

/// Whether key `k` gets a `vs-<key>` line figure: always, but in a two-key sweep only when
/// the other key has few enough values that its lines can be told apart (the heat map shows
/// the rest).
fn has_lines(manifest: &Manifest, k: usize) -> bool {
    !has_map(manifest) || manifest.vary[1 - k].values.len() <= MAX_LINES
}

/// File stem of the heat-map figure of a two-key sweep.
pub fn sweep_map_name(manifest: &Manifest) -> String {
    let part = |k: &str| -> String {
        k.chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect()
    };
    let keys: Vec<String> = manifest.vary.iter().map(|v| part(&v.key)).collect();
    format!("map-{}", keys.join("-"))
}

/// The stems of every figure `draw_sweep` writes into `plots/`.
pub fn sweep_figures(manifest: &Manifest) -> Vec<String> {
    let mut out: Vec<String> = (0..manifest.vary.len())
        .filter(|&k| has_lines(manifest, k))
        .map(|k| sweep_plot_name(&manifest.vary[k].key))
        .collect();
    if has_map(manifest) {
        out.push(sweep_map_name(manifest));
    }
    out
}

/// The metrics of a case for the heat maps: the line figures' and, where any case has them,
/// the grasp's and the compliant contact's.
const MAP_METRICS: [Metric; 5] = [
    ("held (1) / not held (0)", "", |m| {
        m.held.map(|h| if h { 1.0 } else { 0.0 })
    }),
    ("min safety margin over the lift", "μ_s ΣN/(m g)", |m| {
        m.min_safety_margin
    }),
    ("peak grip force of one prong", "N", |m| m.peak_grip_force_n),
    ("max Hertz pressure p₀", "Pa", |m| m.max_pressure_pa),
    ("max p₀ / bruise pressure", "", |m| m.bruise_ratio),
];

/// Heat maps of every metric over a two-key grid (x: the first key, y: the second).
fn draw_sweep_map(manifest: &Manifest, records: &[&CaseRecord], dir: &Path) -> Result<(), String> {
    let (kx, ky) = (&manifest.vary[0], &manifest.vary[1]);
    let (nx, ny) = (kx.values.len(), ky.values.len());
    let mut maps = Vec::new();
    for (title, unit, f) in METRICS.iter().chain(MAP_METRICS.iter()) {
        let mut cells = vec![vec![None; nx]; ny];
        for (k, rec) in records.iter().enumerate() {
            // Grid order: the first key varies slowest.
            let (ix, iy) = (k / ny, k % ny);
            if ix < nx {
                cells[iy][ix] = f(rec.run_metrics()).filter(|v| v.is_finite());
            }
        }
        if cells.iter().flatten().all(Option::is_none) {
            continue;
        }
        maps.push(ValueMap {
            title: title.to_string(),
            x_label: kx.key.clone(),
            y_label: ky.key.clone(),
            x_ticks: kx.values.clone(),
            y_ticks: ky.values.clone(),
            cells,
            unit: unit.to_string(),
            colors: MapColors::Sequential,
        });
    }
    let title = format!(
        "sweep over {} × {}: {} cases, one cell per case",
        kx.key,
        ky.key,
        records.len()
    );
    value_maps(
        &dir.join(sweep_map_name(manifest)),
        &title,
        &maps,
        3,
        (520, 400),
    )
}

/// How a [`ValueMap`] colours its cells.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MapColors {
    /// Blue (the smallest value) → yellow → red (the largest).
    Sequential,
    /// A ratio around 1 on a log scale: red below 1, white at 1, green above.
    Ratio,
}

/// A heat map of numbers: `cells[y][x]`, None drawn grey.
#[derive(Debug, Clone)]
pub struct ValueMap {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x_ticks: Vec<String>,
    pub y_ticks: Vec<String>,
    pub cells: Vec<Vec<Option<f64>>>,
    pub unit: String,
    pub colors: MapColors,
}

impl ValueMap {
    fn span(&self) -> (f64, f64) {
        let vals = self.cells.iter().flatten().flatten();
        let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        (lo, hi)
    }

    /// The colour of a value, and where it sits on the colour bar (0..1).
    fn color(&self, v: f64, (lo, hi): (f64, f64)) -> (RGBColor, f64) {
        match self.colors {
            MapColors::Sequential => {
                let f = if hi > lo { (v - lo) / (hi - lo) } else { 0.5 };
                (force_color(f), f)
            }
            MapColors::Ratio => {
                // log2 ratio, ±3 (×8) at the ends of the scale.
                let f = ((v.max(1e-12).log2() / 3.0).clamp(-1.0, 1.0) + 1.0) / 2.0;
                (ratio_color(f), f)
            }
        }
    }
}

/// Red (0) → white (0.5) → green (1).
pub fn ratio_color(f: f64) -> RGBColor {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.5
    };
    let lerp = |a: (f64, f64, f64), b: (f64, f64, f64), t: f64| {
        RGBColor(
            (a.0 + (b.0 - a.0) * t).round() as u8,
            (a.1 + (b.1 - a.1) * t).round() as u8,
            (a.2 + (b.2 - a.2) * t).round() as u8,
        )
    };
    if f < 0.5 {
        lerp((200.0, 30.0, 40.0), (250.0, 250.0, 245.0), f / 0.5)
    } else {
        lerp((250.0, 250.0, 245.0), (30.0, 150.0, 60.0), (f - 0.5) / 0.5)
    }
}

/// Heat maps in a grid of `cols` columns, each with its colour bar, to `<base>.png|svg`.
pub fn value_maps(
    base: &Path,
    title: &str,
    maps: &[ValueMap],
    cols: usize,
    panel: (u32, u32),
) -> Result<(), String> {
    ensure_font()?;
    let cols = cols.clamp(1, maps.len().max(1));
    let rows = maps.len().div_ceil(cols).max(1);
    let size = (panel.0 * cols as u32, panel.1 * rows as u32 + 40);
    if let Some(d) = base.parent() {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        maps_on(&root, title, maps, (rows, cols))?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        maps_on(&root, title, maps, (rows, cols))?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(())
}

fn maps_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    maps: &[ValueMap],
    grid: (usize, usize),
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    for (area, m) in root.split_evenly(grid).iter().zip(maps) {
        value_map_on(area, m)?;
    }
    Ok(())
}

/// Every k-th tick label, so that about `room` of them show; numbers with four significant
/// digits (0.03364, 1e9), other text cut to 12 characters.
fn thin(labels: &[String], room: usize) -> Vec<String> {
    let step = labels.len().div_ceil(room.max(1)).max(1);
    labels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            if i % step != 0 {
                return String::new();
            }
            match l.trim().parse::<f64>() {
                Ok(v) if v != 0.0 && (v.abs() >= 1e5 || v.abs() < 1e-3) => {
                    format!("{v:.2e}").replace(".00e", "e").replace("0e", "e")
                }
                Ok(v) => super::window::fmt_g(v),
                Err(_) => l.chars().take(12).collect(),
            }
        })
        .collect()
}

/// One heat map with its colour bar on the right.
pub fn value_map_on<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    m: &ValueMap,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let (w, h) = area.dim_in_pixel();
    let (plot, bar) = area.split_horizontally(w.saturating_sub(90));
    let (nx, ny) = (m.x_ticks.len().max(1), m.y_ticks.len().max(1));
    let mut chart = ChartBuilder::on(&plot)
        .caption(&m.title, ("sans-serif", 15))
        .margin(8)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..nx as f64, 0f64..ny as f64)
        .map_err(e)?;
    let (xl, yl) = (
        thin(&m.x_ticks, (w as usize / 64).max(2)),
        thin(&m.y_ticks, (h as usize / 26).max(2)),
    );
    let at = |labels: &[String], v: f64| -> String {
        let i = v.floor();
        if (v - i - 0.5).abs() < 1e-6 && i >= 0.0 {
            labels.get(i as usize).cloned().unwrap_or_default()
        } else {
            String::new()
        }
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(nx * 2 + 1)
        .y_labels(ny * 2 + 1)
        .x_label_formatter(&|v| at(&xl, *v))
        .y_label_formatter(&|v| at(&yl, *v))
        .x_desc(m.x_label.as_str())
        .y_desc(m.y_label.as_str())
        .label_style(("sans-serif", 11))
        .draw()
        .map_err(e)?;
    let span = m.span();
    // Values in the cells where they fit.
    let text =
        (w as usize).saturating_sub(170) / nx >= 48 && (h as usize).saturating_sub(90) / ny >= 18;
    for (iy, row) in m.cells.iter().enumerate() {
        for (ix, cell) in row.iter().enumerate() {
            let (x0, y0) = (ix as f64, iy as f64);
            let fill = cell.map_or(RGBColor(215, 215, 215), |v| m.color(v, span).0);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x0, y0), (x0 + 1.0, y0 + 1.0)],
                    fill.filled(),
                )))
                .map_err(e)?;
            if text {
                let label = cell.map_or("–".to_string(), super::window::fmt_g);
                chart
                    .draw_series(std::iter::once(Text::new(
                        label,
                        (x0 + 0.5, y0 + 0.5),
                        ("sans-serif", 11).into_font().color(&BLACK).pos(
                            plotters::style::text_anchor::Pos::new(
                                plotters::style::text_anchor::HPos::Center,
                                plotters::style::text_anchor::VPos::Center,
                            ),
                        ),
                    )))
                    .map_err(e)?;
            }
        }
    }
    // Colour bar.
    let (top, bottom) = (40i32, h as i32 - 60);
    let steps = 100;
    for k in 0..steps {
        let f = 1.0 - k as f64 / steps as f64;
        let col = match m.colors {
            MapColors::Sequential => force_color(f),
            MapColors::Ratio => ratio_color(f),
        };
        let a = top + (bottom - top) * k / steps;
        let b = top + (bottom - top) * (k + 1) / steps;
        bar.draw(&Rectangle::new([(8, a), (24, b + 1)], col.filled()))
            .map_err(e)?;
    }
    bar.draw(&Rectangle::new(
        [(8, top), (24, bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(e)?;
    let (hi_label, lo_label) = match m.colors {
        MapColors::Sequential => (super::window::fmt_g(span.1), super::window::fmt_g(span.0)),
        MapColors::Ratio => ("≥ 8".to_string(), "≤ 1/8".to_string()),
    };
    let style = ("sans-serif", 11);
    bar.draw(&Text::new(hi_label, (28, top - 4), style))
        .map_err(e)?;
    bar.draw(&Text::new(lo_label, (28, bottom - 8), style))
        .map_err(e)?;
    if m.colors == MapColors::Ratio {
        bar.draw(&Text::new("1", (28, (top + bottom) / 2 - 6), style))
            .map_err(e)?;
    }
    if !m.unit.is_empty() {
        bar.draw(&Text::new(m.unit.clone(), (4, bottom + 8), style))
            .map_err(e)?;
    }
    Ok(())
}

/// Every metric against each varied key (one figure per key, one panel per metric, one line
/// per combination of the other keys' values) into `dir/vs-<key>.png|svg`; a two-key grid
/// also as heat maps (`dir/map-<key1>-<key2>.png|svg`), which replace the line figure of a
/// key whose other key has more than [`MAX_LINES`] values.
pub fn draw_sweep(manifest: &Manifest, records: &[&CaseRecord], dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    if has_map(manifest) {
        draw_sweep_map(manifest, records, dir)?;
    }
    for (k, v) in manifest.vary.iter().enumerate() {
        if !has_lines(manifest, k) {
            continue;
        }
        let nums: Option<Vec<f64>> = v
            .values
            .iter()
            .map(|s| s.trim().parse::<f64>().ok())
            .collect();
        let (xs, x_label, log_x) = match nums {
            Some(x) => {
                let pos = x.iter().all(|a| *a > 0.0);
                let (mn, mx) = x
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| {
                        (a.min(*c), b.max(*c))
                    });
                // Two points make the same line on either axis; a linear one labels both ends.
                let log = pos && x.len() > 2 && mx / mn >= 10.0;
                (x, v.key.clone(), log)
            }
            None => {
                let names: Vec<String> = v
                    .values
                    .iter()
                    .enumerate()
                    .map(|(i, s)| format!("{i} = {s}"))
                    .collect();
                (
                    (0..v.values.len()).map(|i| i as f64).collect(),
                    format!("{} ({})", v.key, names.join(", ")),
                    false,
                )
            }
        };
        // Group the cases by the values of the other keys, in grid order.
        let mut groups: Vec<(String, Vec<(f64, &Metrics)>)> = Vec::new();
        for (c, rec) in manifest.cases.iter().zip(records) {
            let others: Vec<String> = manifest
                .vary
                .iter()
                .zip(&c.values)
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, (w, val))| format!("{}={val}", w.key))
                .collect();
            let name = if others.is_empty() {
                "all cases".to_string()
            } else {
                others.join(", ")
            };
            let x = v
                .values
                .iter()
                .position(|s| *s == c.values[k])
                .map(|i| xs[i])
                .unwrap_or(f64::NAN);
            match groups.iter_mut().find(|g| g.0 == name) {
                Some(g) => g.1.push((x, rec.run_metrics())),
                None => groups.push((name, vec![(x, rec.run_metrics())])),
            }
        }
        let panels: Vec<Panel> = METRICS
            .iter()
            .map(|(title, unit, f)| Panel {
                title: title.to_string(),
                x_label: x_label.clone(),
                y_label: unit.to_string(),
                log_x,
                log_y: false,
                series: groups
                    .iter()
                    .map(|(_, pts)| {
                        let mut p: Vec<(f64, f64)> = pts
                            .iter()
                            .filter_map(|(x, m)| f(m).map(|y| (*x, y)))
                            .collect();
                        p.sort_by(|a, b| a.0.total_cmp(&b.0));
                        Series {
                            name: String::new(),
                            points: p,
                        }
                    })
                    .collect(),
            })
            .collect();
        let title = format!("sweep over {}: {} cases", v.key, records.len());
        let legend: Vec<String> = groups.iter().map(|g| g.0.clone()).collect();
        figure(
            &dir.join(sweep_plot_name(&v.key)),
            &title,
            &panels,
            4,
            (440, 330),
            &legend,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_inside_parts() {
        let lo = [0.0, 0.0];
        let hi = [1.0, 1.0];
        let segs = clip_polyline(&[[-1.0, 0.5], [0.5, 0.5], [2.0, 0.5]], lo, hi);
        assert_eq!(segs, vec![vec![[0.0, 0.5], [0.5, 0.5], [1.0, 0.5]]]);
        let poly = clip_polygon(
            &[[-1.0, -1.0], [2.0, -1.0], [2.0, 2.0], [-1.0, 2.0]],
            lo,
            hi,
        );
        assert_eq!(poly.len(), 4);
        assert!(poly.iter().all(|p| inside(*p, lo, hi)));
        assert!(clip_segment([2.0, 2.0], [3.0, 3.0], lo, hi).is_none());
    }

    #[test]
    fn colour_map_ends() {
        assert_eq!(force_color(0.0), RGBColor(49, 54, 149));
        assert_eq!(force_color(1.0), RGBColor(165, 0, 38));
        assert_eq!(force_color(f64::NAN), RGBColor(49, 54, 149));
    }
}
