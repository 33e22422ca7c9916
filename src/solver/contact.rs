//! Collision detection for the modified mass method: every non-driven node against every
//! obstacle, with a cheap lower bound first.

use super::newton::Constraint;
use crate::obstacle::{Obstacle, Proximity};

/// The deepest penetration of point `p` among all obstacles, if any (signed distance < `below`).
/// Returns the obstacle index and its proximity answer.
#[inline]
pub fn deepest(obstacles: &[Obstacle], p: [f64; 2], below: f64) -> Option<(usize, Proximity)> {
    let mut best: Option<(usize, Proximity)> = None;
    for (k, o) in obstacles.iter().enumerate() {
        if o.lower_bound(p) >= below {
            continue;
        }
        let q = o.query(p);
        if q.distance < below && best.map_or(true, |(_, b)| q.distance < b.distance) {
            best = Some((k, q));
        }
    }
    best
}

/// Signed distance to the nearest obstacle (∞ when there are none). Exact only where a lower
/// bound says the node may be within `exact_within`; elsewhere the bound is returned.
#[inline]
pub fn gap(obstacles: &[Obstacle], p: [f64; 2], exact_within: f64) -> f64 {
    let mut g = f64::INFINITY;
    for o in obstacles {
        let lb = o.lower_bound(p);
        let d = if lb < exact_within {
            o.query(p).distance
        } else {
            lb
        };
        g = g.min(d);
    }
    g
}

/// A constraint that holds node `p` on the surface described by `prox` (linearised there).
#[inline]
pub fn constraint_at(obstacle: usize, prox: &Proximity) -> Constraint {
    let n = prox.normal;
    Constraint {
        obstacle,
        normal: n,
        target: n[0] * prox.closest[0] + n[1] * prox.closest[1],
        locked: false,
    }
}
