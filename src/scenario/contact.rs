//! `[contact]`: where a prong touches.
//!
//! ```toml
//! [contact]
//! surface = "face"        # the prong's face: h/2 (or the section radius) off the centreline
//! # surface = "centreline" # the seed's contact: the centreline is held on the obstacle
//! ```
//!
//! Absent, contact is at the centreline (the seed's model, which every shipped scenario
//! written before `[contact]` existed was tuned on; the seed-grasp scenarios say so).

use super::reader::{did_you_mean, TableReader};
use super::ScenarioError;

const CONTACT_KEYS: &[&str] = &["surface"];

/// Which surface of a prong is held on an obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactSurface {
    /// The centreline (the seed's model: the prong's face sits h/2 inside the obstacle).
    #[default]
    Centreline,
    /// The face towards the obstacle: the centreline stays h/2 (a rectangle's half-height in
    /// the bending plane, or a circular section's radius) outside it.
    Face,
}

/// `[contact]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ContactSpec {
    pub surface: ContactSurface,
}

/// Read `[contact]` (absent: centreline contact).
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
    c.finish()?;
    Ok(spec)
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
