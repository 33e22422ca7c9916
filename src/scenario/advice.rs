//! What a scenario that reads fine still gets wrong: one line each, printed before a run
//! (and sent to the recordings as warnings).

use super::Scenario;
use crate::actuation::phase::Movement;

impl Scenario {
    /// Warnings about the scenario as given.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(w) = self.frictionless_lift() {
            out.push(w);
        }
        out
    }

    /// A free body that the actuators lift (a translation against gravity) while no prong has
    /// friction with it: frictionless prongs cannot hold a fruit.
    fn frictionless_lift(&self) -> Option<String> {
        let g = self.solve.gravity;
        let lifts = self.actuators.iter().any(|a| {
            a.program.phases.iter().any(|p| match &p.movement {
                Movement::Translate { direction, .. } => {
                    direction[0] * g[0] + direction[1] * g[1] < 0.0
                }
                _ => false,
            })
        });
        if !lifts {
            return None;
        }
        let body = self.bodies.iter().find(|b| {
            self.rods.iter().all(|r| {
                let c = self.friction.between(&r.name, &b.name);
                c.mu_s == 0.0 && c.mu_k == 0.0
            })
        })?;
        Some(format!(
            "the actuators lift, but no prong has friction with the free body {:?} ([friction] \
             absent or zero for it): frictionless prongs cannot hold a fruit (add e.g. \
             [friction] mu_s = 0.6, mu_k = 0.5)",
            body.name
        ))
    }
}
