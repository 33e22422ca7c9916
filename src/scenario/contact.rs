//! `[contact]`: where a prong touches.
//!
//! ```toml
//! [contact]
//! surface = "face"        # the prong's face: h/2 (or the section radius) off the centreline
//! # surface = "centreline" # the seed's contact: the centreline is held on the obstacle
//! points = "edges"        # every segment's closest point (between nodes too)
//! # points = "nodes"       # only the nodes are tested (the seed's model)
//! ```
//!
//! Absent, a prong touches with its face, at its segments as well as its nodes: the physical
//! model. The seed's model (centreline contact at the nodes only) is chosen explicitly, as the
//! seed-grasp scenarios and every scenario measured with it do.

use super::reader::{did_you_mean, TableReader};
use super::ScenarioError;

const CONTACT_KEYS: &[&str] = &["surface", "points"];

/// Which surface of a prong is held on an obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactSurface {
    /// The centreline (the seed's model: the prong's face sits h/2 inside the obstacle).
    Centreline,
    /// The face towards the obstacle: the centreline stays h/2 (a rectangle's half-height in
    /// the bending plane, or a circular section's radius) outside it. The default.
    #[default]
    Face,
}

/// Which points of a prong are tested against the obstacles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactPoints {
    /// The nodes only (the seed's model): a segment may cut into an obstacle between its
    /// nodes, and an obstacle smaller than a segment can pass between them.
    Nodes,
    /// The nodes and every segment's closest point (src/contact/edge.rs): a contact may lie
    /// between nodes, its reaction shared by the two with the barycentric weights. The
    /// default.
    #[default]
    Edges,
}

/// `[contact]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ContactSpec {
    pub surface: ContactSurface,
    pub points: ContactPoints,
}

/// Read `[contact]` (absent: the face, at segments and nodes).
pub fn parse(top: &TableReader) -> Result<ContactSpec, ScenarioError> {
    let Some(c) = top.opt_table("contact", CONTACT_KEYS)? else {
        return Ok(ContactSpec::default());
    };
    let mut spec = ContactSpec::default();
    if let Some(s) = c.opt_str("surface")? {
        spec.surface = match s {
            "centreline" | "centerline" => ContactSurface::Centreline,
            "face" => ContactSurface::Face,
            other => {
                let hint = match did_you_mean(other, &["centreline", "face"]) {
                    Some(m) => format!("did you mean \"{m}\"?"),
                    None => {
                        "use \"face\" (the prong's surface) or \"centreline\" (the seed's)".into()
                    }
                };
                return Err(c.err_hint(
                    "surface",
                    c.get("surface"),
                    format!("unknown contact surface {other:?}"),
                    hint,
                ));
            }
        };
    }
    if let Some(s) = c.opt_str("points")? {
        spec.points = match s {
            "nodes" => ContactPoints::Nodes,
            "edges" => ContactPoints::Edges,
            other => {
                let hint = match did_you_mean(other, &["nodes", "edges"]) {
                    Some(m) => format!("did you mean \"{m}\"?"),
                    None => "use \"edges\" (segments too) or \"nodes\" (the seed's)".into(),
                };
                return Err(c.err_hint(
                    "points",
                    c.get("points"),
                    format!("unknown contact points {other:?}"),
                    hint,
                ));
            }
        };
    }
    c.finish()?;
    Ok(spec)
}

/// Write the contact model into a scenario that chooses none (the defaults), so that the text
/// a run records says which model it ran with, whatever the defaults of a later version.
pub fn make_explicit(root: &mut toml::Table) {
    if !root.contains_key("contact") {
        let mut t = toml::Table::new();
        t.insert("surface".into(), "face".into());
        t.insert("points".into(), "edges".into());
        root.insert("contact".into(), toml::Value::Table(t));
    }
}

/// A recorded scenario without `[contact]` was recorded before the defaults became the face
/// at segments (every recording since says its model, [`make_explicit`]): it ran with the
/// seed's model, centreline contact at the nodes, and reads back with it.
pub fn recorded_defaults(root: &mut toml::Table) {
    if !root.contains_key("contact") {
        let mut t = toml::Table::new();
        t.insert("surface".into(), "centreline".into());
        t.insert("points".into(), "nodes".into());
        root.insert("contact".into(), toml::Value::Table(t));
    }
}

impl ContactSpec {
    /// How far rod `spec`'s contact surface lies off its centreline (m): 0 at the centreline
    /// and for particles, else the section's half-height in the bending plane.
    pub fn offset(&self, spec: &super::RodSpec) -> f64 {
        match self.surface {
            ContactSurface::Face if !spec.particle => spec.section.half_height(),
            _ => 0.0,
        }
    }
}
