//! Collision detection for the modified mass method: every non-driven node against every
//! surface, with a cheap lower bound first.

use super::constraint::{Constraint, Corner};
use super::Surfaces;
use crate::obstacle::Proximity;

/// The deepest penetration of point `p` among all surfaces, if any (signed distance < `below`).
/// Returns the obstacle index and its proximity answer.
#[inline]
pub fn deepest(s: &Surfaces, p: [f64; 2], below: f64) -> Option<(usize, Proximity)> {
    deepest_other(s, p, usize::MAX, below)
}

/// Signed distance to the nearest surface (∞ when there are none). Exact only where a lower
/// bound says the node may be within `exact_within`; elsewhere the bound is returned. A
/// surface whose bound is its distance ([`Surfaces::bound_is_distance`]) is not asked twice.
#[inline]
pub fn gap(s: &Surfaces, p: [f64; 2], exact_within: f64) -> f64 {
    let mut g = f64::INFINITY;
    for k in 0..s.len() {
        let lb = s.lower_bound(k, p);
        let d = if lb < exact_within && !s.bound_is_distance(k) {
            s.query(k, p).distance
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
    Constraint::on_surface(obstacle, n, n[0] * prox.closest[0] + n[1] * prox.closest[1])
}

/// The second surface of a corner, linearised like [`constraint_at`].
#[inline]
pub fn corner_at(obstacle: usize, prox: &Proximity) -> Corner {
    let c = constraint_at(obstacle, prox);
    Corner {
        obstacle,
        normal: c.normal,
        target: c.target,
    }
}

/// The deepest penetration of `p` below `below` among the surfaces other than `skip`.
#[inline]
pub fn deepest_other(
    s: &Surfaces,
    p: [f64; 2],
    skip: usize,
    below: f64,
) -> Option<(usize, Proximity)> {
    let mut best: Option<(usize, Proximity)> = None;
    for k in 0..s.len() {
        if k == skip || s.lower_bound(k, p) >= below {
            continue;
        }
        let q = s.query(k, p);
        if q.distance < below && best.is_none_or(|(_, b)| q.distance < b.distance) {
            best = Some((k, q));
        }
    }
    best
}

/// Surfaces whose normals differ by less than this (|n₁ × n₂|, about 0.06°) make no corner:
/// the deeper one is then the outer one near the node, and the node is held on it alone.
pub const PARALLEL: f64 = 1e-3;

/// A node held by `c` is also inside obstacle `k`: the constraint that holds it against both
/// (a corner), or on `k` alone when the two surfaces are nearly parallel; with the surface
/// added, for the event.
pub fn add_surface(c: &Constraint, k: usize, prox: &Proximity) -> (Constraint, Corner) {
    let corner = corner_at(k, prox);
    let cross = c.normal[0] * corner.normal[1] - c.normal[1] * corner.normal[0];
    if cross.abs() < PARALLEL {
        let mut held = constraint_at(k, prox);
        held.locked = c.locked;
        (held, corner)
    } else {
        (
            Constraint {
                second: Some(corner),
                ..*c
            },
            corner,
        )
    }
}

/// The normal parts of a constrained node's reaction: (n·R, 0) on one surface; in a corner,
/// the coefficients (a, b) of R = a n₁ + b n₂. A negative part pulls the node into that
/// surface (adhesive).
#[inline]
pub fn normal_parts(c: &Constraint, r: [f64; 2]) -> (f64, f64) {
    let n1 = c.normal;
    match c.second {
        None => (n1[0] * r[0] + n1[1] * r[1], 0.0),
        Some(s) => {
            let n2 = s.normal;
            let det = n1[0] * n2[1] - n1[1] * n2[0];
            (
                (r[0] * n2[1] - r[1] * n2[0]) / det,
                (n1[0] * r[1] - n1[1] * r[0]) / det,
            )
        }
    }
}
