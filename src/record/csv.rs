//! The CSV sink: the run in tidy long format, one row per (step, rod, node).
//!
//! Columns: `step, t, rod, node, x, y, vx, vy, rx, ry, reaction, impulse, in_contact,
//! bending_stress, nx, ny, gap, dt, passes` (see docs/recording-format.md). Floats are
//! printed as the shortest text that reads back to the same f64, so the file holds the exact
//! numbers of the run.

use super::{node_norm, Finished, OutputFile, RecordError, RecordOptions, Recording};
use crate::events::{Event, Observer};
use std::io::Write as _;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Rows are collected in memory and written in whole lines: at every flush, and whenever this
/// much is waiting (at a step's end). So a killed run's file ends with a whole row.
const WRITE_AT: usize = 1 << 20;

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
}

/// Writes a CSV file.
pub struct CsvSink {
    out: OutputFile,
    /// Whole rows not yet written to `file`.
    buf: Vec<u8>,
    /// None once writing failed.
    file: Option<std::fs::File>,
    header_written: bool,
    flush_every: u64,
    rods: Vec<String>,
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
            file: Some(file),
            header_written: false,
            out,
            flush_every: opts.flush_every.max(1),
            rods: Vec::new(),
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
        'rods: for (name, v) in self.rods.iter().zip(rods) {
            for i in 0..v.in_contact.len() {
                result = w.serialize(Row {
                    step,
                    t,
                    rod: name,
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
                });
                if result.is_err() {
                    break 'rods;
                }
            }
        }
        if let Err(e) = result {
            return self.fail(e);
        }
        match w.into_inner() {
            Ok(buf) => self.buf = buf,
            Err(e) => return self.fail(e.error()),
        }
        if step.is_multiple_of(self.flush_every) || self.buf.len() >= WRITE_AT {
            self.write_out();
        }
    }

    /// Write the buffered rows (whole lines) to the file.
    fn write_out(&mut self) {
        let Some(file) = self.file.as_mut() else {
            return;
        };
        let r = file.write_all(&self.buf);
        self.buf.clear();
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
            }
            Event::StepEnd {
                step,
                t,
                dt,
                passes,
                rods,
                ..
            } => self.write_step(*step, *t, *dt, *passes, rods),
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
        self.write_out();
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
