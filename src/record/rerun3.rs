//! The Rerun sink of a 3D run (`.rrd`, opened in a Spatial3D view): per step, each rod's
//! centre line as a line strip, its material frame as two short arrows per edge at the edge's
//! midpoint (m₁ red, m₂ green, length the section's half extent along it × `frame_scale`), and
//! the contacts' normals (blue), reactions (orange) and friction forces (purple) at their
//! points when there are any. Times: `step` (sequence) and `sim_time` (duration).
//! The file is written as `<path>.partial` and renamed at [`Rrd3::finish`].

use crate::rod3d::events::{Contact3, Event3, Observer3, Rod3Info, Rod3StepView};
use ::rerun::{Arrows3D, Color, LineStrips3D, RecordingStream, RecordingStreamBuilder};
use std::path::{Path, PathBuf};

/// Collects a 3D run into an `.rrd` file.
pub struct Rrd3 {
    rec: Option<RecordingStream>,
    path: PathBuf,
    partial: PathBuf,
    rods: Vec<Rod3Info>,
    /// Material-frame arrows are this many section half extents long.
    pub frame_scale: f64,
    /// Force arrows: metres per newton.
    pub force_scale: f64,
    error: Option<String>,
}

fn f32s(a: [f64; 3]) -> [f32; 3] {
    [a[0] as f32, a[1] as f32, a[2] as f32]
}

impl Rrd3 {
    pub fn create(path: &Path, name: &str) -> Result<Rrd3, String> {
        let partial = PathBuf::from(format!("{}.partial", path.display()));
        let rec = RecordingStreamBuilder::new("gripsim")
            .recording_id(format!("{name}-3d"))
            .save(&partial)
            .map_err(|e| format!("{}: {e}", partial.display()))?;
        rec.set_log_time_enabled(false);
        rec.set_log_tick_enabled(false);
        rec.send_recording_name(name.to_string())
            .map_err(|e| format!("{}: {e}", partial.display()))?;
        Ok(Rrd3 {
            rec: Some(rec),
            path: path.to_path_buf(),
            partial,
            rods: vec![],
            frame_scale: 3.0,
            force_scale: 0.01,
            error: None,
        })
    }

    /// Flush, close and move the file into place.
    pub fn finish(mut self) -> Result<(), String> {
        if let Some(rec) = self.rec.take() {
            rec.flush_blocking().map_err(|e| e.to_string())?;
            drop(rec);
        }
        if let Some(e) = self.error.take() {
            let _ = std::fs::remove_file(&self.partial);
            return Err(format!("{}: {e}", self.path.display()));
        }
        std::fs::rename(&self.partial, &self.path)
            .map_err(|e| format!("{}: {e}", self.path.display()))
    }

    fn rod(
        &self,
        rec: &RecordingStream,
        r: usize,
        view: &Rod3StepView<'_>,
    ) -> ::rerun::RecordingStreamResult<()> {
        let (name, half) = match self.rods.get(r) {
            Some(i) => (i.name.clone(), i.half_extents),
            None => (format!("rod{r}"), [0.001, 0.001]),
        };
        let n = view.nodes();
        let line: Vec<[f32; 3]> = (0..n).map(|i| f32s(view.node(i))).collect();
        rec.log(
            format!("scene/{name}/centerline"),
            &LineStrips3D::new([line]),
        )?;
        let (mut origins, mut vectors, mut colors) = (vec![], vec![], vec![]);
        for i in 0..n - 1 {
            let (a, b) = (view.node(i), view.node(i + 1));
            let mid = [
                (a[0] + b[0]) / 2.0,
                (a[1] + b[1]) / 2.0,
                (a[2] + b[2]) / 2.0,
            ];
            let (m1, m2) = view.material_frame(i);
            for (m, h, c) in [
                (m1, half[0], Color::from_rgb(220, 40, 40)),
                (m2, half[1], Color::from_rgb(40, 170, 40)),
            ] {
                let s = h * self.frame_scale;
                origins.push(f32s(mid));
                vectors.push(f32s([m[0] * s, m[1] * s, m[2] * s]));
                colors.push(c);
            }
        }
        rec.log(
            format!("scene/{name}/material_frame"),
            &Arrows3D::from_vectors(vectors)
                .with_origins(origins)
                .with_colors(colors),
        )
    }

    fn contacts(
        &self,
        rec: &RecordingStream,
        contacts: &[Contact3],
    ) -> ::rerun::RecordingStreamResult<()> {
        let k = self.force_scale;
        let arrows = |f: &dyn Fn(&Contact3) -> [f64; 3], color: Color| {
            Arrows3D::from_vectors(contacts.iter().map(|c| f32s(f(c))))
                .with_origins(contacts.iter().map(|c| f32s(c.point)))
                .with_colors([color])
        };
        let s = 3.0
            * self
                .rods
                .iter()
                .map(|r| r.half_extents[0])
                .fold(0.001, f64::max);
        rec.log(
            "scene/contacts/normals",
            &arrows(&|c| c.normal.map(|v| v * s), Color::from_rgb(60, 90, 230)),
        )?;
        rec.log(
            "scene/contacts/reactions",
            &arrows(
                &|c| c.reaction.map(|v| v * k),
                Color::from_rgb(240, 150, 30),
            ),
        )?;
        rec.log(
            "scene/contacts/friction",
            &arrows(
                &|c| c.friction.map(|v| v * k),
                Color::from_rgb(160, 60, 200),
            ),
        )
    }
}

impl Observer3 for Rrd3 {
    fn on_event(&mut self, e: &Event3<'_>) {
        let Some(rec) = self.rec.clone() else { return };
        let r = match e {
            Event3::Start { rods } => {
                self.rods = rods.to_vec();
                Ok(())
            }
            Event3::Step {
                step,
                time,
                rods,
                contacts,
                ..
            } => {
                rec.set_time_sequence("step", *step as i64);
                rec.set_duration_secs("sim_time", *time);
                let mut r = Ok(());
                for (i, v) in rods.iter().enumerate() {
                    r = r.and(self.rod(&rec, i, v));
                }
                if !contacts.is_empty() {
                    r = r.and(self.contacts(&rec, contacts));
                }
                r
            }
            Event3::End { .. } => Ok(()),
        };
        if let Err(err) = r {
            self.error.get_or_insert(err.to_string());
        }
    }
}
