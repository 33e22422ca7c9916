//! Time of release: like the time of impact, the instant inside a step at which a held
//! contact lets go — its normal reaction crosses zero, or a stuck contact's reaction reaches
//! the friction cone — found by linear interpolation of the reaction between the end of the
//! last accepted step and the end of the step being solved (with the contact still held), so
//! that the step can be split there. Located only at step ends, the release happens up to a
//! whole step late or early, and the impulse the contact gives is first order in Δt; split at
//! the interpolated instant it is second order (the interpolation's error is O(Δt²)).

use super::Simulation;
use crate::contact::{friction, Grip};

/// The smallest fraction of a step a release split may cut: the step after a split ends
/// near the zero of the reaction, so its reaction there is O(Δt²) and the next step would
/// otherwise be split again at a fraction O(Δt) (a sliver for nothing).
const MIN_RELEASE_FRACTION: f64 = 0.02;

/// The fraction θ ∈ (0, 1) at which a quantity going from `before` > 0 to `after` < 0
/// crosses zero on the line between them.
#[inline]
fn crossing(before: f64, after: f64) -> Option<f64> {
    (before > 0.0 && after < 0.0).then(|| before / (before - after))
}

impl Simulation {
    /// After a pass: the earliest fraction θ of the step at which a node held at both ends of
    /// the step (same fixed surface, not in a corner, not locked) is released — its normal
    /// reaction, pressing at the start, pulls at the end — or, stuck at both ends, reaches
    /// the friction cone. With the rod and node. None when no such crossing lies inside the
    /// step by more than the smallest split.
    pub(super) fn release_fraction(&self, dt: f64) -> Option<(f64, usize, usize)> {
        let floor = self.min_split_dt(dt).max(MIN_RELEASE_FRACTION * dt);
        let mut best: Option<(f64, usize, usize)> = None;
        for (r, w) in self.work.iter().enumerate() {
            for i in 0..self.rods[r].n {
                let (Some(c), Some(c0)) = (w.contact[i], w.contact_saved[i]) else {
                    continue;
                };
                if c.locked
                    || c.law.is_some()
                    || c.body.is_some()
                    || c.second.is_some()
                    || c.obstacle != c0.obstacle
                    || w.edge_nodes[i]
                {
                    continue;
                }
                let (rn, rt) = friction::split(&c, [w.r[2 * i], w.r[2 * i + 1]]);
                let mut theta = crossing(w.rn_end[i], rn);
                let stuck = matches!((c.grip, c0.grip), (Grip::Stick { .. }, Grip::Stick { .. }));
                if stuck && c.switches == 0 && c.coulomb.mu_s > 0.0 {
                    let cone = crossing(w.cone_end[i], c.coulomb.mu_s * rn - rt.abs());
                    theta = match (theta, cone) {
                        (Some(a), Some(b)) => Some(a.min(b)),
                        (a, b) => a.or(b),
                    };
                }
                let Some(theta) = theta else { continue };
                if theta * dt >= floor
                    && theta < 1.0 - 1e-9
                    && best.is_none_or(|(t, _, _)| theta < t)
                {
                    best = Some((theta, r, i));
                }
            }
        }
        best
    }

    /// At the end of an accepted step: each held node's normal reaction and margin to the
    /// friction cone, for the next step's time of release.
    pub(super) fn remember_reactions(&mut self) {
        for w in &mut self.work {
            for i in 0..w.contact.len() {
                let (rn, cone) = match w.contact[i] {
                    Some(c)
                        if c.body.is_none()
                            && c.law.is_none()
                            && c.second.is_none()
                            && !w.edge_nodes[i] =>
                    {
                        let (rn, rt) = friction::split(&c, [w.r[2 * i], w.r[2 * i + 1]]);
                        let cone = match c.grip {
                            Grip::Stick { .. } if c.coulomb.mu_s > 0.0 => {
                                c.coulomb.mu_s * rn - rt.abs()
                            }
                            _ => f64::NAN,
                        };
                        (rn, cone)
                    }
                    _ => (f64::NAN, f64::NAN),
                };
                w.rn_end[i] = rn;
                w.cone_end[i] = cone;
            }
        }
    }
}
