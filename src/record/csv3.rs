//! The CSV sink of a 3D run: one row per (step, rod, node), with z and the twist.
//!
//! Columns: `step, t, rod, node, x, y, z, vx, vy, vz, theta, twist, m1x, m1y, m1z` — `theta`
//! the material angle of the edge that starts at the node and `m1` its first material
//! director (empty at the last node), `twist` the discrete twist at the node (0 at the ends).
//! Floats are printed as the shortest text that reads back to the same f64. Rows are kept in
//! memory and the file is written whole at [`Csv3::finish`] (nothing half written).

use crate::rod3d::events::{Event3, Observer3};
use std::fmt::Write as _;
use std::path::Path;

pub const HEADER: &str = "step,t,rod,node,x,y,z,vx,vy,vz,theta,twist,m1x,m1y,m1z\n";

/// Collects the rows of a 3D run.
#[derive(Debug, Clone)]
pub struct Csv3 {
    text: String,
    names: Vec<String>,
}

impl Default for Csv3 {
    fn default() -> Self {
        Csv3 {
            text: HEADER.to_string(),
            names: vec![],
        }
    }
}

impl Csv3 {
    pub fn new() -> Csv3 {
        Csv3::default()
    }

    /// The CSV text so far.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Write the file at once.
    pub fn finish(&self, path: &Path) -> std::io::Result<()> {
        super::write_atomic(path, self.text.as_bytes())
    }
}

impl Observer3 for Csv3 {
    fn on_event(&mut self, e: &Event3<'_>) {
        match e {
            Event3::Start { rods } => self.names = rods.iter().map(|r| r.name.clone()).collect(),
            Event3::Step {
                step, time, rods, ..
            } => {
                for (r, view) in rods.iter().enumerate() {
                    let name = self.names.get(r).cloned().unwrap_or_else(|| r.to_string());
                    let n = view.nodes();
                    for i in 0..n {
                        let (x, v) = (view.node(i), view.velocity(i));
                        let _ = write!(
                            self.text,
                            "{step},{time:?},{name},{i},{:?},{:?},{:?},{:?},{:?},{:?},",
                            x[0], x[1], x[2], v[0], v[1], v[2]
                        );
                        if i + 1 < n {
                            let (m1, _) = view.material_frame(i);
                            let _ = writeln!(
                                self.text,
                                "{:?},{:?},{:?},{:?},{:?}",
                                view.theta(i),
                                view.twist(i),
                                m1[0],
                                m1[1],
                                m1[2]
                            );
                        } else {
                            let _ = writeln!(self.text, ",{:?},,,", view.twist(i));
                        }
                    }
                }
            }
            Event3::End { .. } | Event3::Scene { .. } => {}
        }
    }
}
