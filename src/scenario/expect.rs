//! `[expect]`: what a scenario is built to show, so that `replay check` and `run --check` judge a
//! run against it. A scenario that demonstrates a drop is not flagged for dropping; it is flagged
//! if the fruit is held instead.
//!
//! ```toml
//! [expect]
//! grasp = "dropped"   # "held" (the default with a free body), "slipped" or "dropped"
//! bruised = true      # a compliant fruit squeezed too hard on purpose (default false)
//! ```

use super::reader::{did_you_mean, TableReader};
use super::ScenarioError;
use serde::Serialize;

const EXPECT_KEYS: &[&str] = &["grasp", "bruised"];

/// The outcome a scenario expects of its grasp (the first free body in the gripper's lift).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GraspOutcome {
    /// Neither slip nor drop (what a gripper is for; the default).
    #[default]
    Held,
    /// The fruit slips beyond its hold tolerance during the lift but is not dropped.
    Slipped,
    /// The fruit leaves the prongs during the lift.
    Dropped,
}

impl GraspOutcome {
    pub const NAMES: [&'static str; 3] = ["held", "slipped", "dropped"];

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
}

/// What the scenario expects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct Expect {
    pub grasp: GraspOutcome,
    /// The fruit is meant to bruise: its bruises are reported, not flagged, and a run that
    /// does not bruise it is flagged.
    pub bruised: bool,
}

/// Read `[expect]` (absent: a held grasp).
pub fn parse(top: &TableReader) -> Result<Expect, ScenarioError> {
    let Some(e) = top.opt_table("expect", EXPECT_KEYS)? else {
        return Ok(Expect::default());
    };
    let grasp = match e.opt_str("grasp")? {
        None | Some("held") => GraspOutcome::Held,
        Some("slipped") => GraspOutcome::Slipped,
        Some("dropped") => GraspOutcome::Dropped,
        Some(other) => {
            let hint = match did_you_mean(other, &GraspOutcome::NAMES) {
                Some(m) => format!("did you mean \"{m}\"?"),
                None => "use \"held\", \"slipped\" or \"dropped\"".into(),
            };
            return Err(e.err_hint(
                "grasp",
                e.get("grasp"),
                format!("unknown grasp outcome {other:?}"),
                hint,
            ));
        }
    };
    let bruised = e.opt_bool("bruised")?.unwrap_or(false);
    e.finish()?;
    Ok(Expect { grasp, bruised })
}
