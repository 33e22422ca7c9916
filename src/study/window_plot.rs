//! The picture of a window map (`DIR/window.png|svg`): for one varied key, x = the design
//! value, y = the knob (log), regions filled — dropped below g_hold, the safe window between,
//! bruised above g_bruise — with the designs' boundaries as points; for two keys, a heat map
//! of the window ratio g_bruise / g_hold.

use super::plots::{value_maps, MapColors, ValueMap};
use super::sweep::{CaseRecord, Manifest};
use super::window::{fmt_g, Boundary, Resolved, Status, Which, WindowResult};
use crate::bench::plot::ensure_font;
use plotters::coord::combinators::BindKeyPoints;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

const DROPPED: RGBColor = RGBColor(120, 140, 175);
const SAFE: RGBColor = RGBColor(120, 200, 120);
const BRUISED: RGBColor = RGBColor(220, 70, 60);

/// Draw the map's picture to `<base>.png` and `<base>.svg`.
pub fn draw_map(manifest: &Manifest, records: &[&CaseRecord], base: &Path) -> Result<(), String> {
    ensure_font()?;
    let w = manifest
        .window
        .as_ref()
        .ok_or_else(|| "not a window map".to_string())?;
    if manifest.vary.len() == 2 {
        return ratio_map(manifest, records, w, base);
    }
    let size = (1000u32, 640u32);
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        bands_on(&root, manifest, records, w)?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        bands_on(&root, manifest, records, w)?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(())
}

/// Where a design's drop region ends (the bottom of its safe window) on the knob axis.
fn hold_edge(b: &Boundary, w: &Resolved) -> Option<f64> {
    match b.status {
        Status::Found if b.rising => b.value,
        Status::Everywhere | Status::NotApplicable => Some(w.lo),
        Status::Nowhere => Some(w.hi),
        _ => None,
    }
}

/// Where a design's bruised region begins.
fn bruise_edge(b: &Boundary, w: &Resolved) -> Option<f64> {
    match b.status {
        Status::Found if b.rising => b.value,
        Status::Nowhere | Status::NotApplicable => Some(w.hi),
        Status::Everywhere => Some(w.lo),
        _ => None,
    }
}

/// The first key's value of each design as a number (its index when the key is not numeric),
/// and the axis label.
fn design_x(manifest: &Manifest, records: &[&CaseRecord]) -> (Vec<f64>, String, bool) {
    let key = &manifest.vary[0];
    let nums: Option<Vec<f64>> = key.values.iter().map(|s| s.trim().parse().ok()).collect();
    let pos = |r: &CaseRecord| {
        key.values
            .iter()
            .position(|v| Some(v) == r.parameters.first().map(|p| &p.1))
            .unwrap_or(0)
    };
    match nums {
        Some(n) => {
            let xs: Vec<f64> = records.iter().map(|r| n[pos(r)]).collect();
            let (lo, hi) = xs
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            let log = lo > 0.0 && hi / lo >= 10.0 && xs.len() > 2;
            let unit = super::window::unit_of(&key.key);
            let label = if unit.is_empty() {
                key.key.clone()
            } else {
                format!("{} ({unit})", key.key)
            };
            (xs, label, log)
        }
        None => {
            let names: Vec<String> = key
                .values
                .iter()
                .enumerate()
                .map(|(i, s)| format!("{i} = {s}"))
                .collect();
            (
                records.iter().map(|r| pos(r) as f64).collect(),
                format!("{} ({})", key.key, names.join(", ")),
                false,
            )
        }
    }
}

/// One design: x, the two edges (None where not monotone), the boundaries found.
type Design<'a> = (f64, Option<f64>, Option<f64>, &'a WindowResult);

fn bands_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    manifest: &Manifest,
    records: &[&CaseRecord],
    w: &Resolved,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (xs, x_label, log_x) = design_x(manifest, records);
    let mut designs: Vec<Design> = records
        .iter()
        .zip(&xs)
        .filter_map(|(r, x)| {
            let res = r.window.as_deref()?;
            Some((
                *x,
                hold_edge(&res.hold, w),
                bruise_edge(&res.bruise, w),
                res,
            ))
        })
        .collect();
    designs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let title = format!(
        "grasp window of {} over {} ({} designs, rtol {} %)",
        manifest.scenario,
        manifest.vary[0].key,
        designs.len(),
        fmt_g(w.rtol * 100.0)
    );
    let root = root.titled(&title, ("sans-serif", 20)).map_err(e)?;
    let h = root.dim_in_pixel().1;
    let (main, strip) = root.split_vertically(h.saturating_sub(56));
    let (mut x0, mut x1) = designs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), d| {
            (a.min(d.0), b.max(d.0))
        });
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    if x1 <= x0 {
        // One design: a band around it.
        let d = if x0 != 0.0 { 0.1 * x0.abs() } else { 0.5 };
        (x0, x1) = (x0 - d, x1 + d);
    }
    let y_label = if w.unit.is_empty() {
        w.knob.clone()
    } else {
        format!("{} ({})", w.knob, w.unit)
    };
    // What no design has, said once (e.g. no compliant material: no bruise boundary).
    let mut caption =
        "dropped below g_hold, held and not bruised between, bruised above g_bruise".to_string();
    for b in [
        |d: &WindowResult| d.hold.clone(),
        |d: &WindowResult| d.bruise.clone(),
    ] {
        let all: Vec<Boundary> = designs.iter().map(|d| b(d.3)).collect();
        if !all.is_empty() && all.iter().all(|x| x.status == Status::NotApplicable) {
            caption = format!("{caption}; {}", all[0].note);
        }
    }
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .light_line_style(TRANSPARENT)
                .x_desc(x_label.as_str())
                .y_desc(y_label.as_str())
                .y_label_formatter(&|v| fmt_g(*v))
                .x_label_formatter(&|v| fmt_g(*v))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(e)?;
            regions(&mut chart, &designs, w, (x0, x1)).map_err(e)?;
            points(&mut chart, &designs, w).map_err(e)?;
        }};
    }
    let mut builder = ChartBuilder::on(&main);
    builder
        .caption(caption.as_str(), ("sans-serif", 15))
        .margin(16)
        .margin_right(40)
        .x_label_area_size(48)
        .y_label_area_size(80);
    let y = || {
        (w.lo..w.hi)
            .log_scale()
            .with_key_points(one_two_five(w.lo, w.hi))
    };
    if log_x {
        // A log axis labels the designs themselves (a few), else round 1-2-5 values.
        let ticks: Vec<f64> = if designs.len() <= 8 {
            designs.iter().map(|d| d.0).collect()
        } else {
            one_two_five(x0, x1)
        };
        body!(builder
            .build_cartesian_2d((x0..x1).log_scale().with_key_points(ticks), y())
            .map_err(e)?);
    } else {
        body!(builder.build_cartesian_2d(x0..x1, y()).map_err(e)?);
    }
    let odd = designs.iter().any(|d| d.1.is_none() || d.2.is_none());
    legend(&strip, w, odd).map_err(e)
}

/// Round values 1, 2, 5 × 10ⁿ in [lo, hi] (the knob axis's labels).
fn one_two_five(lo: f64, hi: f64) -> Vec<f64> {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let mut out: Vec<f64> = (a..=b)
        .flat_map(|d| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(d)))
        .filter(|v| *v >= lo * (1.0 - 1e-9) && *v <= hi * (1.0 + 1e-9))
        .collect();
    if out.len() < 3 {
        out = (0..=4)
            .map(|k| lo * (hi / lo).powf(k as f64 / 4.0))
            .collect();
    }
    out
}

/// The filled regions, one polygon per run of consecutive designs whose edges are known.
fn regions<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    designs: &[Design],
    w: &Resolved,
    (x0, x1): (f64, f64),
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let mut start = 0;
    while start < designs.len() {
        let mut end = start;
        while end < designs.len() && designs[end].1.is_some() && designs[end].2.is_some() {
            end += 1;
        }
        let run = &designs[start..end];
        if !run.is_empty() {
            // A lone design is drawn as a band across the plot.
            let xs: Vec<f64> = if run.len() == 1 && designs.len() == 1 {
                vec![x0, x1]
            } else {
                run.iter().map(|d| d.0).collect()
            };
            let hold: Vec<f64> = run.iter().map(|d| d.1.unwrap_or(w.lo)).collect();
            let bruise: Vec<f64> = run.iter().map(|d| d.2.unwrap_or(w.hi)).collect();
            let at = |v: &[f64], i: usize| v[i.min(v.len() - 1)];
            let n = xs.len();
            let band = |lower: &dyn Fn(usize) -> f64, upper: &dyn Fn(usize) -> f64| {
                let mut p: Vec<(f64, f64)> = (0..n).map(|i| (xs[i], lower(i))).collect();
                p.extend((0..n).rev().map(|i| (xs[i], upper(i))));
                p
            };
            let safe = band(&|i| at(&hold, i), &|i| at(&bruise, i).max(at(&hold, i)));
            let dropped = band(&|_| w.lo, &|i| at(&hold, i));
            let bruised = band(&|i| at(&bruise, i), &|_| w.hi);
            chart.draw_series(std::iter::once(Polygon::new(safe, SAFE.mix(0.55).filled())))?;
            chart.draw_series(std::iter::once(Polygon::new(
                dropped,
                DROPPED.mix(0.55).filled(),
            )))?;
            chart.draw_series(std::iter::once(Polygon::new(
                bruised,
                BRUISED.mix(0.45).filled(),
            )))?;
        }
        start = end + 1;
    }
    Ok(())
}

/// The boundaries found (filled markers on lines), designs not monotone (a cross), and the
/// scenario's own knob value (a dashed line).
fn points<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    designs: &[Design],
    w: &Resolved,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let found = |b: &Boundary| (b.status == Status::Found).then_some(b.value).flatten();
    let hold: Vec<(f64, f64)> = designs
        .iter()
        .filter_map(|d| found(&d.3.hold).map(|v| (d.0, v)))
        .collect();
    let bruise: Vec<(f64, f64)> = designs
        .iter()
        .filter_map(|d| found(&d.3.bruise).map(|v| (d.0, v)))
        .collect();
    let (xa, xb) = (
        designs.first().map_or(0.0, |d| d.0),
        designs.last().map_or(1.0, |d| d.0),
    );
    if w.scenario_value >= w.lo && w.scenario_value <= w.hi {
        let dash = 40;
        let segs = (0..dash).map(|k| {
            let f = |k: f64| xa + (xb - xa) * k / dash as f64;
            PathElement::new(
                vec![
                    (f(k as f64), w.scenario_value),
                    (f(k as f64 + 0.5), w.scenario_value),
                ],
                BLACK.mix(0.6).stroke_width(1),
            )
        });
        chart.draw_series(segs)?;
    }
    let dark_red = RGBColor(140, 20, 20);
    for (pts, col) in [(&hold, BLACK), (&bruise, dark_red)] {
        if pts.len() > 1 && pts.len() <= 200 {
            chart.draw_series(LineSeries::new(pts.iter().copied(), col.stroke_width(2)))?;
        }
        let r = if pts.len() > 100 { 2 } else { 4 };
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, r, col.filled())))?;
    }
    let odd: Vec<(f64, f64)> = designs
        .iter()
        .filter(|d| d.1.is_none() || d.2.is_none())
        .map(|d| (d.0, (w.lo * w.hi).sqrt()))
        .collect();
    chart.draw_series(odd.iter().map(|&p| Cross::new(p, 6, BLACK.stroke_width(2))))?;
    Ok(())
}

fn legend<DB: DrawingBackend>(
    strip: &DrawingArea<DB, Shift>,
    w: &Resolved,
    odd: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let style = ("sans-serif", 14);
    let mut x = 20;
    let y = 14;
    for (name, col) in [
        ("dropped (not held)", DROPPED.mix(0.55)),
        ("safe: held, not bruised", SAFE.mix(0.55)),
        ("bruised", BRUISED.mix(0.45)),
    ] {
        strip.draw(&Rectangle::new([(x, y), (x + 22, y + 16)], col.filled()))?;
        strip.draw(&Text::new(name, (x + 28, y), style))?;
        x += 50 + 8 * name.len() as i32;
    }
    strip.draw(&Circle::new((x + 6, y + 8), 4, BLACK.filled()))?;
    strip.draw(&Text::new("g_hold", (x + 16, y), style))?;
    x += 80;
    strip.draw(&Circle::new(
        (x + 6, y + 8),
        4,
        RGBColor(140, 20, 20).filled(),
    ))?;
    strip.draw(&Text::new("g_bruise", (x + 16, y), style))?;
    x += 96;
    strip.draw(&PathElement::new(
        vec![(x, y + 8), (x + 8, y + 8)],
        BLACK.mix(0.6).stroke_width(1),
    ))?;
    strip.draw(&PathElement::new(
        vec![(x + 14, y + 8), (x + 22, y + 8)],
        BLACK.mix(0.6).stroke_width(1),
    ))?;
    strip.draw(&Text::new(
        format!("scenario: {}", w.show(w.scenario_value)),
        (x + 28, y),
        style,
    ))?;
    if odd {
        strip.draw(&Text::new(
            "× a design whose outcome is not monotone along the knob (see window.csv)",
            (20, y + 22),
            ("sans-serif", 12),
        ))?;
    }
    Ok(())
}

/// Two varied keys: the window ratio g_bruise / g_hold of each design as a heat map (x: the
/// first key, y: the second); a ratio known only as a bound (a boundary outside the range)
/// is drawn at the bound.
fn ratio_map(
    manifest: &Manifest,
    records: &[&CaseRecord],
    w: &Resolved,
    base: &Path,
) -> Result<(), String> {
    let (kx, ky) = (&manifest.vary[0], &manifest.vary[1]);
    let (nx, ny) = (kx.values.len(), ky.values.len());
    let mut ratio = vec![vec![None; nx]; ny];
    let mut hold = vec![vec![None; nx]; ny];
    let mut bruise = vec![vec![None; nx]; ny];
    for (k, r) in records.iter().enumerate() {
        let (ix, iy) = (k / ny, k % ny);
        let Some(res) = r.window.as_deref() else {
            continue;
        };
        if ix < nx {
            ratio[iy][ix] = res.window_ratio.or(res.window_ratio_at_least);
            let found = |b: &Boundary| (b.status == Status::Found).then_some(b.value).flatten();
            hold[iy][ix] = found(&res.hold);
            bruise[iy][ix] = found(&res.bruise);
        }
    }
    // A panel with no value says why (from the first design).
    let first = records.iter().find_map(|r| r.window.as_deref());
    let why = |cells: &Vec<Vec<Option<f64>>>, b: fn(&WindowResult) -> &Boundary| match first {
        Some(f) if cells.iter().flatten().all(Option::is_none) => {
            let why = match (b(f).status, b(f).which) {
                (Status::NotApplicable, Which::Hold) => "no free body",
                (Status::NotApplicable, Which::Bruise) => "no compliant material",
                (Status::NotMonotone, _) => "not monotone",
                _ => "no boundary in the range",
            };
            format!(": none ({why})")
        }
        _ => String::new(),
    };
    let notes = [
        why(&ratio, |f| &f.bruise),
        why(&hold, |f| &f.hold),
        why(&bruise, |f| &f.bruise),
    ];
    let map = |title: &str, cells, colors, unit: &str| ValueMap {
        title: title.to_string(),
        x_label: kx.key.clone(),
        y_label: ky.key.clone(),
        x_ticks: kx.values.clone(),
        y_ticks: ky.values.clone(),
        cells,
        unit: unit.to_string(),
        colors,
    };
    let maps = vec![
        map(
            &format!("g_bruise / g_hold (green > 1: safe){}", notes[0]),
            ratio,
            MapColors::Ratio,
            "",
        ),
        map(
            &format!("g_hold{}", notes[1]),
            hold,
            MapColors::Sequential,
            &w.unit,
        ),
        map(
            &format!("g_bruise{}", notes[2]),
            bruise,
            MapColors::Sequential,
            &w.unit,
        ),
    ];
    let title = format!(
        "grasp window of {} over {} × {} (knob {}, {} designs; grey: no boundary in {}–{})",
        manifest.scenario,
        kx.key,
        ky.key,
        w.knob,
        records.len(),
        fmt_g(w.lo),
        w.show(w.hi)
    );
    value_maps(base, &title, &maps, 3, (560, 460))
}
