//! Edge (segment) contact: the closest point of a prong's segment to an obstacle may lie
//! between its nodes. A contact there holds the point p = (1 − s) x_i + s x_{i+1} at the
//! barycentric weight s ∈ (0, 1) of segment i on the obstacle's tangent line,
//!
//!   n·((1 − s) x_i + s x_{i+1}) = h,
//!
//! a single equation on two nodes, and its reaction λ n is shared by them: (1 − s) λ n on
//! node i and s λ n on node i + 1. The solver borders these rows onto the rod's banded system
//! as KKT multipliers (src/solver/newton.rs, `edges`). A closest point within [`END`] of a
//! node is left to the node's own contact (the modified-mass filter), so the two never hold
//! the same point twice.

use super::Surfaces;
use crate::obstacle::{Obstacle, Proximity};

/// A segment's closest point closer than this (as a fraction of the segment) to one of its
/// nodes is that node's contact, not the segment's.
pub const END: f64 = 1e-3;

/// An active contact constraint on the interior of a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeContact {
    pub obstacle: usize,
    /// The segment's first node i (the segment joins nodes i and i + 1).
    pub segment: usize,
    /// The barycentric weight s of the held point: (1 − s) x_i + s x_{i+1}.
    pub weight: f64,
    /// Outward normal of the obstacle's tangent line the point is held on.
    pub normal: [f64; 2],
    /// n·p must equal this.
    pub target: f64,
    /// Released once in this step and re-added: may not be released again in this step.
    pub locked: bool,
}

impl EdgeContact {
    /// The constraint holding segment `segment`'s point at weight `s` where `prox` says.
    pub fn at(obstacle: usize, segment: usize, s: f64, prox: &Proximity) -> Self {
        let n = prox.normal;
        Self {
            obstacle,
            segment,
            weight: s,
            normal: n,
            target: n[0] * prox.closest[0] + n[1] * prox.closest[1],
            locked: false,
        }
    }

    /// The held point at configuration `q`.
    #[inline]
    pub fn point(&self, q: &[f64]) -> [f64; 2] {
        point(q, self.segment, self.weight)
    }

    /// The constraint's violation n·p − h at `q` (negative: inside).
    #[inline]
    pub fn violation(&self, q: &[f64]) -> f64 {
        let p = self.point(q);
        self.normal[0] * p[0] + self.normal[1] * p[1] - self.target
    }

    /// The weights of its two nodes.
    #[inline]
    pub fn weights(&self) -> [f64; 2] {
        [1.0 - self.weight, self.weight]
    }

    /// Whether it holds node `i` (as one of its segment's two ends).
    #[inline]
    pub fn touches(&self, i: usize) -> bool {
        i == self.segment || i == self.segment + 1
    }
}

/// (1 − s) x_i + s x_{i+1}.
#[inline]
pub fn point(q: &[f64], i: usize, s: f64) -> [f64; 2] {
    [
        (1.0 - s) * q[2 * i] + s * q[2 * i + 2],
        (1.0 - s) * q[2 * i + 1] + s * q[2 * i + 3],
    ]
}

/// Whether a weight lies far enough inside the segment to be the segment's contact.
#[inline]
pub fn interior(s: f64) -> bool {
    s > END && s < 1.0 - END
}

/// A cheap lower bound on the signed distance of any point of segment a–b from obstacle `k`:
/// the bound at its midpoint less half its length (distances are 1-Lipschitz).
#[inline]
pub fn lower_bound(surf: &Surfaces, k: usize, a: [f64; 2], b: [f64; 2]) -> f64 {
    let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    let half = 0.5 * (b[0] - a[0]).hypot(b[1] - a[1]);
    surf.lower_bound(k, mid) - half
}

/// The point of segment a–b closest to (deepest into) obstacle `k`: its weight s ∈ [0, 1] and
/// the obstacle's answer there. Exact for a fixed circle (the foot of the perpendicular from
/// its centre); otherwise a golden-section search of the signed distance along the segment,
/// which is convex for the convex obstacles (circle, ellipse, polygon, plane; grown by the
/// face offset they stay convex) and finds a local minimum on a sine surface.
pub fn closest_on_segment(surf: &Surfaces, k: usize, a: [f64; 2], b: [f64; 2]) -> (f64, Proximity) {
    let e = [b[0] - a[0], b[1] - a[1]];
    let at = |s: f64| surf.query(k, [a[0] + s * e[0], a[1] + s * e[1]]);
    let ee = e[0] * e[0] + e[1] * e[1];
    if let (Obstacle::Circle(c), false) = (&surf.obstacles[k], surf.is_free(k)) {
        let s = if ee > 0.0 {
            (((c.center[0] - a[0]) * e[0] + (c.center[1] - a[1]) * e[1]) / ee).clamp(0.0, 1.0)
        } else {
            0.0
        };
        return (s, at(s));
    }
    crate::obstacle::deepest_along(at, |q| q.distance, 60)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{Circle, Plane};

    #[test]
    fn a_segment_across_a_small_disc_is_closest_at_the_foot_of_the_perpendicular() {
        let obs = [Obstacle::Circle(Circle::new([0.003, 0.0005], 0.002))];
        let surf = Surfaces::fixed(&obs);
        let (s, q) = closest_on_segment(&surf, 0, [-0.01, 0.0], [0.01, 0.0]);
        assert!((s - 0.65).abs() < 1e-15, "{s}");
        assert!(
            (q.distance - (0.0005 - 0.002)).abs() < 1e-15,
            "{}",
            q.distance
        );
        // The golden-section search on a 64-gon inscribed in the disc finds nearly the same point.
        let poly = crate::obstacle::Polygon::new(
            (0..64)
                .map(|j| {
                    let a = std::f64::consts::TAU * j as f64 / 64.0;
                    [0.003 + 0.002 * a.cos(), 0.0005 + 0.002 * a.sin()]
                })
                .collect(),
        );
        let obs = [Obstacle::Polygon(poly.unwrap())];
        let surf = Surfaces::fixed(&obs);
        let (s2, q2) = closest_on_segment(&surf, 0, [-0.01, 0.0], [0.01, 0.0]);
        assert!((s2 - 0.65).abs() < 0.01, "{s2}");
        assert!(q2.distance < -0.0014, "{}", q2.distance);
    }

    #[test]
    fn a_flat_obstacle_leaves_the_contact_to_the_nodes() {
        let obs = [Obstacle::Plane(Plane::new([0.0, 0.0], [0.0, 1.0]))];
        let surf = Surfaces::fixed(&obs);
        let (s, _) = closest_on_segment(&surf, 0, [0.0, 0.001], [0.01, 0.002]);
        assert_eq!(s, 0.0);
        let (s, _) = closest_on_segment(&surf, 0, [0.0, 0.001], [0.01, 0.001]);
        assert!(!interior(s), "{s}");
    }

    #[test]
    fn the_violation_and_weights_of_a_held_point() {
        let prox = Proximity {
            distance: -0.001,
            closest: [0.0, 0.0],
            normal: [0.0, 1.0],
        };
        let c = EdgeContact::at(0, 1, 0.25, &prox);
        let q = [0.0, 0.0, -0.01, -0.002, 0.01, 0.002];
        let p = c.point(&q);
        assert!(
            (p[0] + 0.005).abs() < 1e-17 && (p[1] + 0.001).abs() < 1e-17,
            "{p:?}"
        );
        assert!((c.violation(&q) + 0.001).abs() < 1e-17);
        assert_eq!(c.weights(), [0.75, 0.25]);
        assert!(c.touches(2) && !c.touches(0));
    }
}
