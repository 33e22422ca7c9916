//! The Rerun sink of a 3D run (`.rrd`, opened in a Spatial3D view): per step, each rod's
//! centre line as a line strip, its material frame as two short arrows per edge at the edge's
//! midpoint (m₁ red, m₂ green, length the section's half extent along it × `frame_scale`), and
//! the contacts' normals (blue), reactions (orange) and friction forces (purple) at their
//! points when there are any. Times: `step` (sequence) and `sim_time` (duration).
//! The world's obstacles and free bodies ([`Event3::Scene`]) are meshes
//! (`scene/shapes/<name>`, tessellated by [`super::shape3`]) placed by a Transform3D, static
//! for a fixed obstacle and logged at every step for a free body (the fruit moves with its
//! pose). Plots: `plots/finger_force/<rod>` (summed normal reaction of each rod),
//! `plots/grip_force` (their mean), `plots/fruit/<name>/z`, `solver/newton_iterations`,
//! `solver/corrector_passes`; contact made/lost as a text log under `events`. The file opens
//! with a blueprint: the Spatial3D scene beside the force and solver plots.
//! The file is written as the planar files are ([`super::OutputFile`]: `NAME.partial.rrd`,
//! renamed at [`Rrd3::finish`]; a failed run's file keeps the `.partial` name and ends with
//! the error in `events`; a device is written through, a symlink followed).

use crate::rod3d::events::{BodyPose3, Contact3, Event3, Observer3, Rod3Info, Rod3StepView};
use crate::rod3d::events::{ContactChange3, Shape3Info};
use ::rerun::blueprint::components::PanelState;
use ::rerun::blueprint::{
    Blueprint, BlueprintPanel, Horizontal, SelectionPanel, Spatial3DView, Tabs, TextLogView,
    TimePanel, TimeSeriesView, Vertical,
};
use ::rerun::{
    Arrows3D, Color, LineStrips3D, Mesh3D, Quaternion, RecordingStream, RecordingStreamBuilder,
    Scalars, TextLog, Transform3D,
};
use std::path::{Path, PathBuf};

/// The layout a 3D `.rrd` opens with.
pub fn blueprint3() -> Blueprint {
    blueprint3_with(vec![])
}

/// [`blueprint3`] with more views under the plots (the replay overlays' difference plots).
pub fn blueprint3_with(extra: Vec<::rerun::blueprint::ContainerLike>) -> Blueprint {
    let scene = Spatial3DView::new("Scene")
        .with_origin("/")
        .with_contents(["+ /scene/**"]);
    let mut rows: Vec<::rerun::blueprint::ContainerLike> = vec![
        TimeSeriesView::new("Finger forces (N)")
            .with_origin("/plots/finger_force")
            .into(),
        Tabs::new([
            TimeSeriesView::new("Grip force (N)")
                .with_origin("/plots/grip_force")
                .into(),
            TimeSeriesView::new("Fruit height (m)")
                .with_origin("/plots/fruit")
                .into(),
            TimeSeriesView::new("Newton its, passes")
                .with_origin("/solver")
                .into(),
        ])
        .into(),
    ];
    rows.extend(extra);
    rows.push(
        TextLogView::new("Contact events")
            .with_origin("/events")
            .into(),
    );
    let plots = Vertical::new(rows);
    Blueprint::new(Horizontal::new([scene.into(), plots.into()]).with_column_shares([0.62, 0.38]))
        .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Collapsed))
        .with_selection_panel(SelectionPanel::new().with_state(PanelState::Collapsed))
        .with_time_panel(
            TimePanel::new()
                .with_timeline("sim_time")
                .with_state(PanelState::Collapsed),
        )
}

/// Collects a 3D run into an `.rrd` file.
pub struct Rrd3 {
    rec: Option<RecordingStream>,
    out: super::OutputFile,
    rods: Vec<Rod3Info>,
    shapes: Vec<Shape3Info>,
    /// Half size of a drawn plane (m).
    pub plane_half: f64,
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
        Self::create_with(path, name, blueprint3())
    }

    /// [`Rrd3::create`] with another layout (the replay overlays').
    pub fn create_with(path: &Path, name: &str, blueprint: Blueprint) -> Result<Rrd3, String> {
        let out = super::OutputFile::new(path);
        // Makes the folder and the partial file (a device is only opened); the
        // SDK's file sink opens what `writing` names: the partial file, or the device.
        drop(out.create().map_err(|e| e.to_string())?);
        let partial = out.writing().to_path_buf();
        let rec = RecordingStreamBuilder::new("gripsim")
            .recording_id(format!("{name}-3d"))
            .with_blueprint(blueprint)
            .save(&partial)
            .map_err(|e| {
                out.discard();
                format!("{}: {e}", partial.display())
            })?;
        rec.set_log_time_enabled(false);
        rec.set_log_tick_enabled(false);
        rec.send_recording_name(name.to_string()).map_err(|e| {
            out.discard();
            format!("{}: {e}", partial.display())
        })?;
        Ok(Rrd3 {
            rec: Some(rec),
            out,
            rods: vec![],
            shapes: vec![],
            plane_half: 0.1,
            frame_scale: 3.0,
            force_scale: 0.04,
            error: None,
        })
    }

    /// The stream, to log more on it at the time of the step just logged (None after an
    /// error).
    pub fn stream(&self) -> Option<&RecordingStream> {
        self.rec.as_ref().filter(|_| self.error.is_none())
    }

    /// The rods' static facts (after [`Event3::Start`]).
    pub fn rods(&self) -> &[Rod3Info] {
        &self.rods
    }

    /// Flush, close and move the file into place.
    pub fn finish(self) -> Result<(), String> {
        self.close(true).map(drop)
    }

    /// Flush and close the file of a run that failed: it keeps its `.partial` name, as a
    /// planar run's. Returns where it is.
    pub fn finish_failed(self) -> Result<PathBuf, String> {
        self.close(false)
    }

    fn close(mut self, complete: bool) -> Result<PathBuf, String> {
        if let Some(rec) = self.rec.take() {
            rec.flush_blocking().map_err(|e| e.to_string())?;
            drop(rec);
        }
        self.out.conclude(self.error.take(), complete)
    }

    /// Close and remove the unfinished file (a replay that stopped leaves nothing).
    pub fn abandon(mut self) -> Result<(), String> {
        if let Some(rec) = self.rec.take() {
            let _ = rec.flush_blocking();
            drop(rec);
        }
        self.out.discard();
        Ok(())
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

fn colour(k: usize, free: bool) -> Color {
    if free {
        Color::from_unmultiplied_rgba(230, 120, 60, 140)
    } else if k == 0 {
        Color::from_unmultiplied_rgba(150, 150, 150, 110)
    } else {
        Color::from_unmultiplied_rgba(120, 140, 170, 160)
    }
}

fn transform(position: [f64; 3], rotation: [f64; 4]) -> Transform3D {
    let q = rotation.map(|v| v as f32);
    Transform3D::from_translation(f32s(position)).with_quaternion(Quaternion::from_xyzw(q))
}

impl Rrd3 {
    fn shape_path(&self, k: usize) -> String {
        match self.shapes.get(k) {
            Some(s) => format!("scene/shapes/{}", s.name),
            None => format!("scene/shapes/{k}"),
        }
    }

    /// The shapes as static meshes (fixed ones placed once).
    fn scene(&self, rec: &RecordingStream) -> ::rerun::RecordingStreamResult<()> {
        for (k, s) in self.shapes.iter().enumerate() {
            let t = super::shape3::tessellate(&s.shape, self.plane_half);
            let path = self.shape_path(k);
            rec.log_static(
                format!("{path}/mesh"),
                &Mesh3D::new(t.vertices.iter().map(|v| f32s(*v)))
                    .with_vertex_normals(t.normals.iter().map(|v| f32s(*v)))
                    .with_triangle_indices(t.triangles.iter().copied())
                    .with_albedo_factor(colour(k, s.free).0),
            )?;
            let q = nalgebra::UnitQuaternion::from_rotation_matrix(&s.pose.rotation);
            let tf = transform(s.pose.position.into(), [q.i, q.j, q.k, q.w]);
            if s.free {
                rec.log(path, &tf)?;
            } else {
                rec.log_static(path, &tf)?;
            }
        }
        Ok(())
    }

    /// Free bodies' poses, the force plots, the solver counts and the contact changes.
    fn plots(
        &self,
        rec: &RecordingStream,
        bodies: &[BodyPose3],
        contacts: &[Contact3],
        changes: &[ContactChange3],
        counts: [u32; 2],
    ) -> ::rerun::RecordingStreamResult<()> {
        for b in bodies {
            rec.log(self.shape_path(b.shape), &transform(b.position, b.rotation))?;
            let name = self.shapes.get(b.shape).map_or("body", |s| s.name.as_str());
            rec.log(
                format!("plots/fruit/{name}/z"),
                &Scalars::single(b.position[2]),
            )?;
        }
        let mut forces = vec![0.0; self.rods.len()];
        for c in contacts {
            if let Some(f) = forces.get_mut(c.rod) {
                *f += c.normal_force();
            }
        }
        for (f, r) in forces.iter().zip(&self.rods) {
            rec.log(
                format!("plots/finger_force/{}", r.name),
                &Scalars::single(*f),
            )?;
        }
        if !forces.is_empty() {
            let mean = forces.iter().sum::<f64>() / forces.len() as f64;
            rec.log("plots/grip_force", &Scalars::single(mean))?;
        }
        rec.log(
            "solver/newton_iterations",
            &Scalars::single(counts[0] as f64),
        )?;
        rec.log(
            "solver/corrector_passes",
            &Scalars::single(counts[1] as f64),
        )?;
        // One row per step (rows logged at one time on one entity would hide each other).
        if !changes.is_empty() {
            let text: Vec<String> = changes
                .iter()
                .map(|c| {
                    let rod = self.rods.get(c.rod).map_or("rod", |r| r.name.as_str());
                    let what = if c.added { "contact" } else { "release" };
                    format!("{what}: {rod} node {}", c.node)
                })
                .collect();
            rec.log("events", &TextLog::new(text.join("; ")))?;
        }
        Ok(())
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
            Event3::Scene { shapes } => {
                self.shapes = shapes.to_vec();
                self.scene(&rec)
            }
            Event3::Step {
                step,
                time,
                rods,
                contacts,
                bodies,
                changes,
                newton_iterations,
                passes,
                ..
            } => {
                rec.set_time_sequence("step", *step as i64);
                rec.set_duration_secs("sim_time", *time);
                let mut r = Ok(());
                for (i, v) in rods.iter().enumerate() {
                    r = r.and(self.rod(&rec, i, v));
                }
                // Logged also when empty, so released contacts' arrows disappear.
                r = r.and(self.contacts(&rec, contacts));
                r.and(self.plots(
                    &rec,
                    bodies,
                    contacts,
                    changes,
                    [*newton_iterations, *passes],
                ))
            }
            Event3::End {
                steps,
                time,
                error: Some(e),
            } => {
                rec.set_duration_secs("sim_time", *time);
                rec.set_time_sequence("step", *steps as i64);
                rec.log(
                    "events",
                    &TextLog::new(format!("run failed after step {steps}: {e}"))
                        .with_level("ERROR"),
                )
            }
            Event3::End { .. } => Ok(()),
        };
        if let Err(err) = r {
            self.error.get_or_insert(err.to_string());
        }
    }
}
