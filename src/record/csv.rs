//! The CSV sink: the run in tidy long format, one row per (step, rod, node).
//!
//! Columns: `step, t, rod, node, x, y, vx, vy, rx, ry, reaction, impulse, in_contact,
//! bending_stress, nx, ny, gap, dt, passes, indentation, half_width, peak_pressure,
//! bruise_half_width, obstacle` (see docs/recording-format.md). After a step's node rows, one
//! row per free body's own contact with a fixed obstacle (a fruit on the table): `rod` empty,
//! `node` the body. Floats are printed as the shortest text that reads back to the same f64,
//! so the file holds the exact numbers of the run.

use super::{node_norm, Finished, OutputFile, RecordError, RecordOptions, Recording};
use crate::events::{ContactView, Event, Observer};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Rows are collected in memory and written in whole lines: at every flush, and whenever this
/// much is waiting (at a step's end).
const WRITE_AT: usize = 1 << 20;

/// A killed process (SIGKILL) can stop inside a `write` to a regular file, but only where the
/// kernel moves from one page of the file to the next (it checks for a fatal signal before
/// each page it copies). So the rows are laid out so that every page boundary they cross falls
/// at the end of a row: the row before a boundary that the next row would straddle gets
/// leading zeros in its `step` field (the same number to every CSV reader), and each `write`
/// stays within one page. A killed run's file then ends with a whole row.
const PAGE: u64 = 4096;

/// `rows` (whole lines) laid out from file offset `offset` so that no row but one longer than
/// a page straddles a page boundary: appended to `out`. `next`: the length of the row that will
/// follow them (0 if none is known: the end of the run).
fn page_aligned(rows: &[u8], offset: u64, next: usize, out: &mut Vec<u8>) {
    let mut pos = offset;
    let mut rest = rows;
    while !rest.is_empty() {
        let len = rest
            .iter()
            .position(|&b| b == b'\n')
            .map_or(rest.len(), |i| i + 1);
        let (row, tail) = rest.split_at(len);
        let following = match tail.iter().position(|&b| b == b'\n') {
            Some(i) => i + 1,
            None if tail.is_empty() => next,
            None => tail.len(),
        };
        let end = (pos + len as u64) % PAGE;
        let pad = if end != 0 && end + following as u64 > PAGE && row[0].is_ascii_digit() {
            (PAGE - end) as usize
        } else {
            0
        };
        out.resize(out.len() + pad, b'0');
        out.extend_from_slice(row);
        pos += (pad + len) as u64;
        rest = tail;
    }
}

/// Whole rows to a file with the layout of [`page_aligned`], for a writer that formats its
/// own rows (the 3D run's CSV, src/rod3d/run3.rs): `write` collects bytes, [`PagedRows::rows_end`]
/// (after whole rows) writes all but the last row, one page at most per `write`, and `flush`
/// writes everything. A killed process leaves a file that ends with a whole row.
pub struct PagedRows<W: std::io::Write> {
    out: W,
    buf: Vec<u8>,
    scratch: Vec<u8>,
    offset: u64,
}

impl<W: std::io::Write> PagedRows<W> {
    pub fn new(out: W) -> Self {
        PagedRows {
            out,
            buf: Vec::new(),
            scratch: Vec::new(),
            offset: 0,
        }
    }

    /// The writer (after [`std::io::Write::flush`], everything is in it).
    pub fn into_inner(self) -> W {
        self.out
    }

    /// Write the collected whole rows but the last (which stays until the row after it is
    /// known).
    pub fn rows_end(&mut self) -> std::io::Result<()> {
        self.write_rows(false)
    }

    fn write_rows(&mut self, all: bool) -> std::io::Result<()> {
        write_paged(
            &mut self.out,
            &mut self.buf,
            &mut self.scratch,
            &mut self.offset,
            all,
        )
    }
}

/// Write the whole rows of `buf` to `out` at file offset `offset`, page-aligned ([`PAGE`]),
/// one page at most per `write`, and drop them from `buf`. Unless `all`, the last row stays
/// buffered: whether it needs the row before it padded is known only once the row after it is.
fn write_paged<W: std::io::Write>(
    out: &mut W,
    buf: &mut Vec<u8>,
    scratch: &mut Vec<u8>,
    offset: &mut u64,
    all: bool,
) -> std::io::Result<()> {
    let keep = if all {
        buf.len()
    } else {
        let body = &buf[..buf.len().saturating_sub(1)];
        body.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1)
    };
    let next = buf.len() - keep;
    scratch.clear();
    page_aligned(&buf[..keep], *offset, next, scratch);
    buf.drain(..keep);
    let mut at = 0;
    while at < scratch.len() {
        let room = (PAGE - *offset % PAGE) as usize;
        let n = room.min(scratch.len() - at);
        out.write_all(&scratch[at..at + n])?;
        at += n;
        *offset += n as u64;
    }
    Ok(())
}

impl<W: std::io::Write> std::io::Write for PagedRows<W> {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.buf.extend_from_slice(b);
        Ok(b.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.write_rows(true)?;
        self.out.flush()
    }
}

#[derive(serde::Serialize)]
struct Row<'a> {
    step: u64,
    t: f64,
    rod: &'a str,
    node: usize,
    x: f64,
    y: f64,
    vx: f64,
    vy: f64,
    rx: f64,
    ry: f64,
    reaction: f64,
    impulse: f64,
    in_contact: u8,
    bending_stress: f64,
    nx: f64,
    ny: f64,
    /// Empty when the scenario has no obstacle.
    gap: Option<f64>,
    dt: f64,
    passes: u32,
    /// The node's contact with a compliant fruit (0 otherwise): indentation (m), contact
    /// half-width (m), peak pressure (Pa) and the half-width above the bruise threshold (m).
    indentation: f64,
    half_width: f64,
    peak_pressure: f64,
    bruise_half_width: f64,
    /// The obstacle the row's contact presses (empty when free).
    obstacle: &'a str,
}

/// Whether contact `c` covers node `i` of rod `r`: its node, or a node of its arc.
fn covers(c: &ContactView, r: usize, i: usize) -> bool {
    c.rod == r
        && if c.first == usize::MAX {
            c.node == i
        } else {
            (c.first..=c.last).contains(&i)
        }
}

/// The compliant contact a node's row carries: the most pressed one covering it.
fn pressed_at(contacts: &[ContactView], r: usize, i: usize) -> Option<&ContactView> {
    contacts
        .iter()
        .filter(|c| c.peak_pressure > 0.0 && covers(c, r, i))
        .fold(None, |best: Option<&ContactView>, c| match best {
            Some(b) if b.peak_pressure >= c.peak_pressure => Some(b),
            _ => Some(c),
        })
}

/// The row of a free body's own contact with a fixed obstacle: no rod, `node` the body, the
/// contact point, the force the obstacle puts on the body (normal and friction along
/// t = (−n_y, n_x)), the outward normal and the compliant fruit's numbers.
fn body_row<'a>(
    step: u64,
    t: f64,
    dt: f64,
    passes: u32,
    c: &ContactView,
    obstacle: &'a str,
) -> Row<'a> {
    let n = c.normal;
    let f = [
        c.normal_force * n[0] - c.friction_force * n[1],
        c.normal_force * n[1] + c.friction_force * n[0],
    ];
    Row {
        step,
        t,
        rod: "",
        node: c.node,
        x: c.point[0],
        y: c.point[1],
        vx: 0.0,
        vy: 0.0,
        rx: f[0],
        ry: f[1],
        reaction: f[0].hypot(f[1]),
        impulse: 0.0,
        in_contact: 1,
        bending_stress: 0.0,
        nx: n[0],
        ny: n[1],
        gap: None,
        dt,
        passes,
        indentation: c.indentation,
        half_width: c.half_width,
        peak_pressure: c.peak_pressure,
        bruise_half_width: c.bruise_half_width,
        obstacle,
    }
}

/// Writes a CSV file.
pub struct CsvSink {
    out: OutputFile,
    /// Whole rows not yet written to `file`.
    buf: Vec<u8>,
    /// The rows of `buf` as written (page-aligned; reused).
    scratch: Vec<u8>,
    /// Bytes written to `file`.
    offset: u64,
    /// None once writing failed.
    file: Option<std::fs::File>,
    header_written: bool,
    flush_every: u64,
    rods: Vec<String>,
    obstacles: Vec<String>,
    completed: bool,
    error: Option<RecordError>,
    failed: Arc<AtomicBool>,
}

impl CsvSink {
    /// Create `path` (as its `.partial` sibling until the run completes).
    pub fn create(path: &Path, opts: RecordOptions) -> Result<Self, RecordError> {
        let out = OutputFile::new(path);
        let file = out.create()?;
        Ok(Self {
            buf: Vec::with_capacity(WRITE_AT),
            scratch: Vec::new(),
            offset: 0,
            file: Some(file),
            header_written: false,
            out,
            flush_every: opts.flush_every.max(1),
            rods: Vec::new(),
            obstacles: Vec::new(),
            completed: false,
            error: None,
            failed: Arc::default(),
        })
    }

    fn write_step(
        &mut self,
        step: u64,
        t: f64,
        dt: f64,
        passes: u32,
        rods: &[crate::events::RodStepView<'_>],
        contacts: &[ContactView],
    ) {
        if self.file.is_none() {
            return;
        }
        // The step's rows are formatted into memory, whole.
        let mut w = ::csv::WriterBuilder::new()
            .has_headers(!self.header_written)
            .from_writer(std::mem::take(&mut self.buf));
        self.header_written = true;
        let mut result = Ok(());
        let name = |k: usize| self.obstacles.get(k).map_or("", String::as_str);
        'rods: for (r, (rod, v)) in self.rods.iter().zip(rods).enumerate() {
            for i in 0..v.in_contact.len() {
                let c = pressed_at(contacts, r, i);
                let of = |f: fn(&ContactView) -> f64| c.map_or(0.0, f);
                let on = c.map_or(v.contact_obstacle[i], |c| c.obstacle);
                result = w.serialize(Row {
                    step,
                    t,
                    rod,
                    node: i,
                    x: v.q[2 * i],
                    y: v.q[2 * i + 1],
                    vx: v.u[2 * i],
                    vy: v.u[2 * i + 1],
                    rx: v.reaction[2 * i],
                    ry: v.reaction[2 * i + 1],
                    reaction: node_norm(v.reaction, i),
                    impulse: node_norm(v.impulse, i),
                    in_contact: v.in_contact[i] as u8,
                    bending_stress: v.bending_stress[i],
                    nx: v.normal[2 * i],
                    ny: v.normal[2 * i + 1],
                    gap: Some(v.gap[i]).filter(|g| g.is_finite()),
                    dt,
                    passes,
                    indentation: of(|c| c.indentation),
                    half_width: of(|c| c.half_width),
                    peak_pressure: of(|c| c.peak_pressure),
                    bruise_half_width: of(|c| c.bruise_half_width),
                    obstacle: name(on),
                });
                if result.is_err() {
                    break 'rods;
                }
            }
        }
        for c in contacts.iter().filter(|c| c.rod == usize::MAX) {
            if result.is_err() {
                break;
            }
            result = w.serialize(body_row(step, t, dt, passes, c, name(c.obstacle)));
        }
        if let Err(e) = result {
            return self.fail(e);
        }
        match w.into_inner() {
            Ok(buf) => self.buf = buf,
            Err(e) => return self.fail(e.error()),
        }
        if step.is_multiple_of(self.flush_every) || self.buf.len() >= WRITE_AT {
            self.write_out(false);
        }
    }

    /// Write the buffered rows (whole lines) to the file ([`write_paged`]).
    fn write_out(&mut self, all: bool) {
        let Some(file) = self.file.as_mut() else {
            return;
        };
        let r = write_paged(
            file,
            &mut self.buf,
            &mut self.scratch,
            &mut self.offset,
            all,
        );
        if let Err(e) = r {
            self.fail(e);
        }
    }

    fn fail(&mut self, e: impl std::fmt::Display) {
        if self.error.is_none() {
            self.error = Some(RecordError::write(self.out.writing(), e));
        }
        self.file = None;
        self.buf = Vec::new();
        self.failed.store(true, Ordering::Relaxed);
    }
}

impl Observer for CsvSink {
    fn on_event(&mut self, event: &Event<'_>) {
        match event {
            Event::RunStart(info) => {
                self.rods = info.rods.iter().map(|r| r.name.clone()).collect();
                self.obstacles = info.obstacle_names.to_vec();
            }
            Event::StepEnd {
                step,
                t,
                dt,
                passes,
                rods,
                contacts,
                ..
            } => self.write_step(*step, *t, *dt, *passes, rods, contacts),
            Event::RunEnd { error, .. } => self.completed = error.is_none(),
            _ => {}
        }
    }
}

impl Recording for CsvSink {
    fn format(&self) -> &'static str {
        "csv"
    }

    fn finish(&mut self) -> Result<Finished, RecordError> {
        self.write_out(true);
        self.file = None;
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.settle(self.completed)
    }

    fn failure(&self) -> Option<Arc<AtomicBool>> {
        Some(self.failed.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::{page_aligned, PAGE};

    /// Every page boundary the laid-out rows cross is a row end, and the rows read back as the
    /// same numbers (padding is leading zeros of the first field).
    #[test]
    fn page_boundaries_fall_at_row_ends() {
        let mut rows = Vec::new();
        let mut lens = 0usize;
        for step in 0..3000u64 {
            // Rows of 40 to 180 bytes.
            let width = 30 + (step * 7919 % 140) as usize;
            let row = format!("{step},{:0>width$}\n", step * 3);
            lens += row.len();
            rows.extend_from_slice(row.as_bytes());
        }
        for offset in [0u64, 1, 4000, 4095, 123_456] {
            let mut out = Vec::new();
            page_aligned(&rows, offset, 0, &mut out);
            assert!(out.len() >= lens);
            let mut pos = offset;
            for (k, line) in out.split_inclusive(|&b| b == b'\n').enumerate() {
                let (start, end) = (pos, pos + line.len() as u64);
                // No boundary strictly inside a row (but the first: the row before it, which
                // would carry its padding, was written earlier — here there is none).
                if k > 0 {
                    assert_eq!(start / PAGE, (end - 1) / PAGE, "a row straddles at {start}");
                }
                pos = end;
            }
            let steps: Vec<u64> = out
                .split(|&b| b == b'\n')
                .filter(|l| !l.is_empty())
                .map(|l| {
                    let f = std::str::from_utf8(l).unwrap().split(',').next().unwrap();
                    f.parse().unwrap()
                })
                .collect();
            assert_eq!(steps, (0..3000).collect::<Vec<u64>>());
        }
    }
}
