//! Figures for benchmarks and studies: log-log line charts and a categorical heat map, each
//! written as PNG and SVG. Text uses a TrueType font read at run time (DejaVu Sans or
//! Liberation Sans from the system's font folders, or `GRIPSIM_FONT`).

use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

static FONT: OnceLock<Result<(), String>> = OnceLock::new();

/// Register a sans-serif font for PNG text once.
pub fn ensure_font() -> Result<(), String> {
    FONT.get_or_init(|| {
        let mut candidates: Vec<String> = Vec::new();
        if let Ok(p) = std::env::var("GRIPSIM_FONT") {
            candidates.push(p);
        }
        for p in [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
            "/Library/Fonts/Arial.ttf",
            "C:\\Windows\\Fonts\\arial.ttf",
        ] {
            candidates.push(p.to_string());
        }
        for c in candidates {
            if let Ok(bytes) = std::fs::read(&c) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err("no TrueType font found for PNG text: install fonts-dejavu-core or set GRIPSIM_FONT=/path/font.ttf".into())
    })
    .clone()
}

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// One panel: a titled log-log (or linear) chart with several series.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    pub series: Vec<Series>,
}

const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];

pub fn color(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

fn range(vals: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for v in vals {
        if !v.is_finite() || (log && v <= 0.0) {
            continue;
        }
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if log { (1e-3, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        let (a, b) = (lo.log10().floor(), hi.log10().ceil());
        let b = if b <= a { a + 1.0 } else { b };
        (10f64.powf(a), 10f64.powf(b))
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-12 * hi.abs().max(1.0));
        (lo - pad, hi + pad)
    }
}

/// Tick label on an axis from `lo` to `hi`: scientific on log axes and on axes whose values
/// are very large or small, else plain decimals; in both cases with as many digits as the tick
/// spacing (about an eighth of the span) needs.
fn tick(v: f64, log: bool, lo: f64, hi: f64) -> String {
    if log {
        return format!("{v:.0e}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let step = (hi - lo) / 8.0;
    if !(step > 0.0 && step.is_finite()) {
        return format!("{v:.2e}");
    }
    let big = lo.abs().max(hi.abs());
    if !(1e-3..1e5).contains(&big) || step < 1e-4 {
        let digits = (v.abs().log10().floor() - step.log10().floor()).clamp(0.0, 3.0) as usize;
        return format!("{v:.digits$e}");
    }
    let digits = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    format!("{v:.digits$}")
}

/// Draw one panel into a drawing area (for figures laid out by the caller). Series with an
/// empty name get no legend entry; with no named series there is no legend box.
pub fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let xs = p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0));
    let ys = p.series.iter().flat_map(|s| s.points.iter().map(|q| q.1));
    let (x0, x1) = range(xs, p.log_x);
    let (y0, y1) = range(ys, p.log_y);
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            let mut mesh = chart.configure_mesh();
            // Minor grid lines only on log charts, where they mark the 2…9 multiples; linear
            // charts (time histories, sweeps) stay light, and their PNGs small.
            if !(p.log_x || p.log_y) {
                mesh.light_line_style(TRANSPARENT);
            }
            mesh.x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .x_label_formatter(&|v| tick(*v, p.log_x, x0, x1))
                .y_label_formatter(&|v| tick(*v, p.log_y, y0, y1))
                .label_style(("sans-serif", 12))
                .draw()
                .map_err(e)?;
            for (i, s) in p.series.iter().enumerate() {
                let c = color(i);
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| {
                        x.is_finite()
                            && y.is_finite()
                            && (!p.log_x || *x > 0.0)
                            && (!p.log_y || *y > 0.0)
                    })
                    .collect();
                // Long series (time histories) get 1 px lines: a wider line is drawn as a polygon
                // with mitred joins, which turn a one-sample spike into a spear past the panel.
                let width = if pts.len() <= 60 { 2 } else { 1 };
                let drawn = chart
                    .draw_series(LineSeries::new(pts.clone(), c.stroke_width(width)))
                    .map_err(e)?;
                if !s.name.is_empty() {
                    drawn.label(s.name.as_str()).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(width))
                    });
                }
                // Markers only where they can be told apart (ladders, not time series).
                if pts.len() <= 60 {
                    chart
                        .draw_series(pts.iter().map(|&q| Circle::new(q, 4, c.filled())))
                        .map_err(e)?;
                }
            }
            if p.series.iter().any(|s| !s.name.is_empty()) {
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 12))
                    .draw()
                    .map_err(e)?;
            }
        }};
    }
    match (p.log_x, p.log_y) {
        (true, true) => body!(builder
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(e)?),
        (true, false) => body!(builder
            .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
            .map_err(e)?),
        (false, true) => body!(builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(e)?),
        (false, false) => body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(e)?),
    }
    Ok(())
}

/// Draw panels in a grid of `cols` columns to `<base>.png` and `<base>.svg`.
pub fn panels(base: &Path, title: &str, panels: &[Panel], cols: usize) -> Result<(), String> {
    panels_sized(base, title, panels, cols, (560, 420))
}

/// [`panels`] with a chosen size (pixels) of each panel.
pub fn panels_sized(
    base: &Path,
    title: &str,
    panels: &[Panel],
    cols: usize,
    panel: (u32, u32),
) -> Result<(), String> {
    ensure_font()?;
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    let size = (panel.0 * cols as u32, panel.1 * rows as u32 + 40);
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    if let Some(d) = base.parent() {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw_grid(&root, title, panels, rows, cols)?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_grid(&root, title, panels, rows, cols)?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(())
}

fn draw_grid<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    panels: &[Panel],
    rows: usize,
    cols: usize,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| e.to_string())?;
    let areas = root.split_evenly((rows, cols));
    for (a, p) in areas.iter().zip(panels) {
        draw_panel(a, p)?;
    }
    Ok(())
}

/// A categorical heat map: `cells[r][c]` is a category index into `legend` (name, colour).
pub struct HeatMap {
    pub title: String,
    pub row_labels: Vec<String>,
    pub col_labels: Vec<String>,
    pub cells: Vec<Vec<usize>>,
    pub legend: Vec<(String, RGBColor)>,
}

/// Draw several heat maps side by side to `<base>.png` and `<base>.svg`.
pub fn heat_maps(base: &Path, title: &str, maps: &[HeatMap], cols: usize) -> Result<(), String> {
    ensure_font()?;
    let cols = cols.max(1);
    let rows = maps.len().div_ceil(cols).max(1);
    let size = (520 * cols as u32, 420 * rows as u32 + 80);
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw_maps(&root, title, maps, rows, cols)?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_maps(&root, title, maps, rows, cols)?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(())
}

fn draw_maps<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    maps: &[HeatMap],
    rows: usize,
    cols: usize,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(e)?;
    let (main, legend_area) = root.split_vertically(root.dim_in_pixel().1 - 40);
    let areas = main.split_evenly((rows, cols));
    for (a, m) in areas.iter().zip(maps) {
        let nr = m.row_labels.len();
        let nc = m.col_labels.len();
        let mut chart = ChartBuilder::on(a)
            .caption(&m.title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(
                (0..nc.max(1) - 1).into_segmented(),
                (0..nr.max(1) - 1).into_segmented(),
            )
            .map_err(e)?;
        let label = |labels: &[String], v: &SegmentValue<usize>| match v {
            SegmentValue::CenterOf(i) => labels.get(*i).cloned().unwrap_or_default(),
            _ => String::new(),
        };
        let (cl, rl) = (m.col_labels.clone(), m.row_labels.clone());
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(nc)
            .y_labels(nr)
            .x_label_formatter(&|v| label(&cl, v))
            .y_label_formatter(&|v| label(&rl, v))
            .label_style(("sans-serif", 11))
            .draw()
            .map_err(e)?;
        for r in 0..nr {
            for c in 0..nc {
                let k = m.cells[r][c];
                let col = m
                    .legend
                    .get(k)
                    .map(|l| l.1)
                    .unwrap_or(RGBColor(200, 200, 200));
                let corners = [
                    (SegmentValue::Exact(c), SegmentValue::Exact(r)),
                    (SegmentValue::Exact(c + 1), SegmentValue::Exact(r + 1)),
                ];
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        corners.clone(),
                        col.filled(),
                    )))
                    .map_err(e)?;
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        corners,
                        WHITE.stroke_width(1),
                    )))
                    .map_err(e)?;
            }
        }
    }
    // Legend along the bottom.
    let mut x = 20;
    for (name, col) in maps.first().map(|m| m.legend.clone()).unwrap_or_default() {
        legend_area
            .draw(&Rectangle::new([(x, 10), (x + 18, 28)], col.filled()))
            .map_err(e)?;
        legend_area
            .draw(&Text::new(name.clone(), (x + 24, 12), ("sans-serif", 14)))
            .map_err(e)?;
        x += 40 + 9 * name.len() as i32;
    }
    Ok(())
}
